"""The whole analysis of a riding session, one step after another.

Every arrow of DESIGN.md is a step of :mod:`horsemocap.steps`: each takes its
parameter section and the typed results it needs and returns one typed,
frozen result. :func:`analyze` runs the steps in order into an
:class:`Analysis`, saves each result whole in the results store (so the steps
before a failure stay written) and writes the files of ``docs/sessions.md``.
Notebooks call :func:`horsemocap.workspace.results_for`, which loads what
earlier steps computed (computing it with the defaults when absent).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from . import results as result_files
from .passes import PassesResult, analyse_passes
from .fingerprint import run_key
from .params import STEP_SECTIONS, AnalysisParams, resolve_params  # noqa: F401 - pipeline.resolve_params is public
from .progress import ProgressPrinter
from .session import Session, SessionError, load_session
from .steps import (STEPS, AnalysisError, ComfortResult, DetectResult, MotionFrameResult, PlumbResult, RigidBodyResult,
                    RigResult, SmoothResult, StaticResult, SyncResult, TriangulateResult, step_comfort, step_detect,
                    step_motion_frame, step_plumb, step_rig, step_rigid_body, step_smooth, step_static, step_sync,
                    step_triangulate)
from .store import ResultsStore, check_outside
from .threads import blas_single_threaded

__all__ = ["STEPS", "AnalysisError", "Analysis", "analyze", "run_steps", "resolve_params", "step_keys"]


@dataclass
class Analysis:
    """The typed results of the steps run so far, with the session and the parameters.

    Each step's result is an attribute named as the step (None until it ran);
    results are frozen, the record of a run (``chosen``, ``timings``) grows
    as the steps run.

    Attributes
    ----------
    session : Session
    params : AnalysisParams
        The parameters given (automatic fields are chosen by the steps and recorded in their results).
    sync, rig, plumb, static, detect, triangulate, smooth, motion_frame, rigid_body, comfort
        The steps' results (:mod:`horsemocap.steps`), or None.
    passes : PassesResult or None
        Every pass of the horse through the views, each analysed from the smoothing on
        (:mod:`horsemocap.passes`), when the record holds more than one; None otherwise. The steps'
        results above are those of the longest pass.
    chosen : dict
        Automatic choices recorded for ``analysis.json``.
    timings : dict
        Seconds spent per step.

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> an = analyze(default_session_dir(), until="sync", progress=lambda *a: None)
    >>> an.steps_done
    ('sync',)
    """

    session: Session
    params: AnalysisParams
    sync: SyncResult | None = None
    rig: RigResult | None = None
    plumb: PlumbResult | None = None
    static: StaticResult | None = None
    detect: DetectResult | None = None
    triangulate: TriangulateResult | None = None
    smooth: SmoothResult | None = None
    motion_frame: MotionFrameResult | None = None
    rigid_body: RigidBodyResult | None = None
    comfort: ComfortResult | None = None
    passes: PassesResult | None = None
    chosen: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    @property
    def steps_done(self) -> tuple:
        """The names of the steps that have a result, in pipeline order."""
        return tuple(name for name in STEPS if getattr(self, name) is not None)

    @property
    def synchronisation(self) -> SyncResult | None:
        """The synchronisation the results are in: the detect step's (the markers may have corrected the
        flash offsets) once it ran, else the sync step's."""
        return self.detect.sync if self.detect is not None else self.sync

    def result(self, step: str):
        """The result of ``step`` (one of :data:`STEPS`), or None."""
        if step not in STEPS:
            raise ValueError(f"step: expected one of {STEPS}, got {step!r}")
        return getattr(self, step)

    def with_result(self, step: str, value) -> None:
        """Record ``step``'s result (once: a result already recorded is never replaced)."""
        if getattr(self, step) is not None:
            raise ValueError(f"step '{step}' already has a result")
        setattr(self, step, value)


def _progress_printer(stream=None):
    """``[horsemocap] step: message`` lines; counts inside long steps as a bar on a terminal."""
    return ProgressPrinter(stream)


def _comfort_f0(a: Analysis):
    period = a.motion_frame.period_frames
    return None if period is None else a.session.fps / period


# How each step is called: its section and the typed results it needs (the arrows of DESIGN.md).
STEP_CALLS = {
    "sync": lambda a, pr, **kw: step_sync(a.session, a.params.sync, pr, **kw),
    "rig": lambda a, pr, **kw: step_rig(a.session, a.params.rig, pr, **kw),
    "plumb": lambda a, pr, **kw: step_plumb(a.session, a.params.stills, a.rig.rig,
                                            a.params.triangulate.mode, pr, **kw),
    "static": lambda a, pr, **kw: step_static(a.session, a.params.stills, a.rig.rig,
                                              a.params.triangulate.mode, pr, **kw),
    "detect": lambda a, pr, **kw: step_detect(a.session, a.params.detect, a.sync, a.rig.rig,
                                              a.static.static_points, pr, **kw),
    "triangulate": lambda a, pr, **kw: step_triangulate(a.params.triangulate, a.rig.rig, a.detect, pr, **kw),
    "smooth": lambda a, pr, **kw: step_smooth(a.params.smooth, a.triangulate, pr, **kw),
    "motion_frame": lambda a, pr, **kw: step_motion_frame(a.session, a.params.motion_frame, a.smooth.smoothed,
                                                          a.plumb.gravity, a.static.static_points,
                                                          a.triangulate.segment, pr,
                                                          static_missing=a.static.missing, **kw),
    "rigid_body": lambda a, pr, **kw: step_rigid_body(a.session, a.params.rigid_body, a.triangulate,
                                                      a.smooth.raw, a.motion_frame, a.detect.sync.offsets, pr,
                                                      **kw),
    "comfort": lambda a, pr, **kw: step_comfort(a.params.comfort, a.rigid_body, _comfort_f0(a), pr, **kw),
}


# ---------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------

def analyze(session_dir, out_dir=None, params: AnalysisParams | dict | None = None, *,
            until: str | None = None, progress=None, write_outputs: bool = True,
            reuse: bool = False, previous_results=None, board_views=None, flash_search=None,
            after_step=None) -> Analysis:
    """Run the analysis of a session, step by step.

    Parameters
    ----------
    session_dir : path
        The session folder (``session.json`` inside).
    out_dir : path, optional
        Results folder (outside the session). None: nothing is written.
    params : AnalysisParams or dict, optional
        Overrides; the session's own ``analysis`` object is applied first.
    until : str, optional
        Stop after this step (one of :data:`STEPS`).
    progress : callable(step, message), optional
        Progress reports; default prints to stderr.
    write_outputs : bool
        Write the spec's result files into ``out_dir`` as steps finish.
    reuse : bool
        Keep each step's result in ``out_dir``'s results store and reuse the
        stored ones computed for the same session, parameters and code.
    previous_results : path, optional
        An earlier run's results folder (``horsemocap analyze`` writes into a
        new folder that replaces it): its cached calibration
        (``calibration.json``) is reused when the views, board, cameras and
        code are the same, as one in ``out_dir`` is.
    board_views : horsemocap.calibration.cache.BoardDetectionJob, optional
        The board detection of the session's views, started earlier by the
        caller (``horsemocap analyze`` starts it as soon as the session is
        read); its views are used when they are those of the session.
    flash_search : horsemocap.sync.FlashSearch, optional
        The flash search of the session's videos, started earlier by the
        caller (as ``board_views``); the sync step takes its detections.
    after_step : callable(analysis, step), optional
        Called after each step's result is recorded (the report's figures
        of that step are drawn while the next steps run).

    Returns
    -------
    Analysis

    Raises
    ------
    SessionError, AnalysisError
        Naming the input to look at; the steps before stay written.

    Notes
    -----
    When the rig is calibrated from checkerboard views, the rig step starts
    in a thread at once and runs while the sync step reads the videos (it
    needs nothing of it), followed there by the plumb line's and the static
    shot's steps (:data:`EARLY_STEPS`); the rig's progress lines may come
    before the sync's, the others' come at their step.
    ``timings`` of these steps are their own durations. The whole run then has
    one BLAS thread (:data:`horsemocap.threads.blas_single_threaded`).
    """
    session = load_session(session_dir)
    params = resolve_params(session, params)
    params.check_session(session)
    progress = progress or _progress_printer()
    if until is not None and until not in STEPS:
        raise ValueError(f"until must be one of {STEPS}, got {until!r}")
    analysis = Analysis(session, params)
    if out_dir is not None:
        check_outside(out_dir, session.root)
        Path(out_dir).mkdir(parents=True, exist_ok=True)
    store = ResultsStore(out_dir) if (reuse and out_dir is not None) else None
    keys = step_keys(session, params) if store else {}
    early = store is None and session.calibrates_from_views(params.rig.recalibrate) and until != "sync"
    # the calibration's one BLAS thread (horsemocap.threads) set here, in the main thread, before
    # the rig's thread starts: its own blocks inside then leave the setting alone
    with blas_single_threaded() if early else contextlib.nullcontext():
        early_steps = None
        if early:
            progress = _serialised(progress)
            early_steps = _EarlySteps(analysis, _early_step_names(until), progress,
                                      cache_dirs=(out_dir, previous_results), board_views=board_views)
        try:
            _run_steps(analysis, store, keys, until, out_dir, write_outputs, progress, previous_results,
                       early_steps, board_views, flash_search, after_step)
        except BaseException:
            if board_views is not None:
                board_views.stop()  # an error or Ctrl-C: the rig step waiting for the views ends at once
            if early_steps is not None:
                early_steps.stop()  # no step after the one running
            raise
        finally:
            if early_steps is not None:
                early_steps.wait()  # never left running: the rig step writes calibration.json into out_dir
    return analysis


#: The steps that need nothing of the sync step's result, in the order they run: with a rig calibrated from
#: checkerboard views they run in a thread while the sync step reads the videos (:class:`_EarlySteps`).
EARLY_STEPS = ("rig", "plumb", "static")


def _early_step_names(until) -> tuple:
    """The :data:`EARLY_STEPS` a run stopping after ``until`` (None: the whole run) needs."""
    if until is None or until not in EARLY_STEPS:
        return EARLY_STEPS
    return EARLY_STEPS[:EARLY_STEPS.index(until) + 1]


class _EarlySteps:
    """The steps that need nothing of the sync step's result (``names``, of :data:`EARLY_STEPS`), run one
    after another in a thread while the sync step reads the videos.

    The rig's calibration (the board detection's threads, the bundle
    adjustment) and the plumb line's and static shot's markers then share
    the processors with the flash search, or take the core left idle while
    the sync step waits for it. The rig reports its progress as it goes;
    the other steps' lines are kept and given when the run reaches the step
    (:meth:`result`), so they come in the steps' order (a warning they
    raise is shown as it comes). A step's error ends the thread there and
    is given by :meth:`result` of that step, to be raised as the step run in
    the main thread would raise it; :meth:`stop` ends the thread before its
    next step. The seconds :meth:`result` gives are the step's own
    duration, not the wait for it.
    """

    def __init__(self, analysis: Analysis, names: tuple, progress, **rig_kwargs):
        self.names = tuple(names)
        self._analysis = Analysis(analysis.session, analysis.params)   # the thread's own record
        self._progress, self._rig_kwargs = progress, rig_kwargs
        self._done: dict = {}                   # step -> (value, error, seconds, kept progress lines)
        self._stop = threading.Event()
        self._changed = threading.Condition()
        self._finished = False
        self._thread = threading.Thread(target=self._run, name="horsemocap-early-steps", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        for name in self.names:
            if self._stop.is_set():
                break
            lines: list = []
            report = self._progress if name == "rig" else _kept(lines, self._progress)
            value, error, t0 = None, None, time.perf_counter()
            try:
                value = STEP_CALLS[name](self._analysis, report, **(self._rig_kwargs if name == "rig" else {}))
                self._analysis.with_result(name, value)
            except BaseException as exc:  # raised by result() of this step
                error = exc
            with self._changed:
                self._done[name] = (value, error, time.perf_counter() - t0, lines)
                self._changed.notify_all()
            if error is not None:
                break
        with self._changed:
            self._finished = True
            self._changed.notify_all()

    def result(self, name: str, progress):
        """``(value, error, seconds)`` of step ``name`` once the thread has run it (``error`` None or what the
        step raised), its kept progress lines given to ``progress`` first; None for a step the thread does
        not run or ended without (stopped)."""
        if name not in self.names:
            return None
        with self._changed:
            self._changed.wait_for(lambda: name in self._done or self._finished)
            done = self._done.get(name)
        if done is None:
            return None
        value, error, seconds, lines = done
        for args in lines:
            progress(*args)
        return value, error, seconds

    def stop(self) -> None:
        """No step after the one running (if any)."""
        self._stop.set()

    def wait(self) -> None:
        self._thread.join()


def _kept(lines: list, progress):
    """A progress callback that keeps its calls in ``lines`` (to be given later), taking counts as ``progress``."""
    def keep(*args):
        lines.append(args)
    keep.counts = getattr(progress, "counts", False)
    return keep


def _serialised(progress):
    """``progress`` called by one thread at a time (the rig step reports from its own thread)."""
    lock = threading.Lock()

    def report(*args):
        with lock:
            progress(*args)
    report.counts = getattr(progress, "counts", False)
    return report




def _run_steps(analysis: Analysis, store, keys: dict, until, out_dir, write_outputs: bool, progress,
               previous_results, early_steps, board_views, flash_search=None, after_step=None) -> None:
    """:func:`analyze`'s loop over the steps (``early_steps``: :class:`_EarlySteps` already running, or None;
    ``flash_search``, ``after_step``: as :func:`analyze`'s)."""
    session, params = analysis.session, analysis.params
    for name in STEPS:
        t0 = time.perf_counter()
        key = keys.get(name, "")
        try:
            stored = store.load(name, key) if store else None
            if stored is not None:
                analysis.with_result(name, stored)
            elif early_steps is not None and (done := early_steps.result(name, progress)) is not None:
                value, error, seconds = done
                t0 = time.perf_counter() - seconds                # the step's own time, not the wait
                if error is not None:
                    raise error
                analysis.with_result(name, value)
            else:
                if name == "rig":
                    value = step_rig(session, params.rig, progress,
                                     cache_dirs=(out_dir, previous_results), board_views=board_views)
                elif name == "sync":
                    value = STEP_CALLS[name](analysis, progress, flash_search=flash_search)
                else:
                    value = STEP_CALLS[name](analysis, progress)
                analysis.with_result(name, value)
                if store:
                    store.save(name, value, key)
        except (AnalysisError, SessionError) as exc:
            exc.partial = analysis  # the steps that finished (horsemocap.run marks them partial)
            raise
        except Exception as exc:  # a step's own error: say which step and input
            err = AnalysisError(name, f"{type(exc).__name__}: {exc}")
            err.partial = analysis
            raise err from exc
        finally:
            analysis.timings[name] = time.perf_counter() - t0
            if out_dir is not None and write_outputs:
                result_files.write_available(Path(out_dir), analysis)
            if name == "sync" and flash_search is not None:
                # taken by the step, or not (its result reused from the store, a different search): either way
                # nobody reads it any more, so it does not decode beside the later steps
                flash_search.close(wanted=False)
        if after_step is not None:
            after_step(analysis, name)
        if name == until:
            break
    if analysis.comfort is not None:
        _run_passes(analysis, out_dir, write_outputs, progress)


def _run_passes(analysis: Analysis, out_dir, write_outputs: bool, progress) -> None:
    """Every other pass of the record through the later steps (:func:`horsemocap.passes.analyse_passes`)."""
    t0 = time.perf_counter()
    quiet = lambda *a: None  # noqa: E731  (one line per pass instead of every step's)
    passes = analyse_passes(analysis, lambda given, steps, overrides: run_steps(
        analysis.session, analysis.params, given, steps, quiet, overrides), progress)
    if passes is None:
        return
    analysis.passes = passes
    analysis.timings["passes"] = time.perf_counter() - t0
    if out_dir is not None and write_outputs:
        result_files.write_available(Path(out_dir), analysis)


def run_steps(session: Session, params: AnalysisParams, results, steps, progress=None,
              overrides: dict | None = None) -> Analysis:
    """Run ``steps`` (names, in pipeline order) on top of given ``results``.

    For studies that replace one step's output (e.g. noisy detections) and
    follow the change through the later steps. ``results``: an
    :class:`Analysis` or a mapping step name -> typed result; the steps named
    in ``steps`` are computed anew, the others taken as given. ``overrides``:
    step name -> keyword arguments its step function is given besides those
    of :data:`STEP_CALLS` (e.g. ``{"rigid_body": {"thesis_chain": False}}``).
    Nothing is written.
    """
    progress = progress or (lambda *a: None)
    given = {n: getattr(results, n) for n in STEPS} if isinstance(results, Analysis) else dict(results)
    analysis = Analysis(session, params)
    for name in STEPS:
        if name not in steps and given.get(name) is not None:
            setattr(analysis, name, given[name])
    for name in steps:
        t0 = time.perf_counter()
        setattr(analysis, name, None)
        analysis.with_result(name, STEP_CALLS[name](analysis, progress, **(overrides or {}).get(name, {})))
        analysis.timings[name] = time.perf_counter() - t0
    return analysis


def step_keys(session: Session, params: AnalysisParams) -> dict:
    """The results-store key of every step: :func:`run_key` with the parameter sections it depends on.

    A step's key covers the session's files, the package's code, the preset,
    its own parameter section and those of every earlier step (the stills are
    triangulated as the triangulate section says). So a threshold chosen in
    notebook 04 recomputes the steps from detection on and keeps the
    calibration, the plumb line and the static shot; a change of the
    calibration mode recomputes the rig and everything after it.
    """
    base = run_key(session, None)
    values = params.to_dict()
    keys, used = {}, ["preset"]
    for name in STEPS:
        needs = (STEP_SECTIONS[name], "triangulate") if name in ("plumb", "static") else (STEP_SECTIONS[name],)
        used += [sec for sec in needs if sec not in used]
        h = hashlib.sha256(base.encode())
        h.update(json.dumps({sec: values.get(sec) for sec in used}, sort_keys=True, default=str).encode())
        keys[name] = h.hexdigest()
    return keys
