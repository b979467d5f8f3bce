"""Every pass of the horse through the cameras' view in one recording.

A long session films the horse circling the arena: it crosses the views
again and again, and between the crossings the cameras see the empty
arena. The detect step follows the markers through the whole record
(:attr:`horsemocap.steps.DetectResult.all_seen` marks the frames in which
every marker is seen) and the analysis proper runs on its longest run of
such frames. This module finds every run long enough to analyse (a *pass*),
follows each through the later steps (smoothing .. comfort) by replacing
the analysed frames of the detect and triangulate results
(:meth:`~horsemocap.steps.base.StepResult.replace`), gives each pass its
verdict (the checks of :func:`horsemocap.quality.post_checks` on the pass'
results) and combines the comfort indicators of all passes, weighted by
their durations (:func:`combined_comfort`).

Nothing is recomputed before the smoothing: the markers' 2D centres and 3D
positions of every frame are those of the whole record; only the frames
analysed change.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import quality
from .forking import run_beside
from .pose import SettledPoseSmoothing, settle_pose_smoothing
from .steps import AnalysisError, ComfortResult
from .steps.base import longest_run
from .steps.detect import MIN_SEGMENT_FRAMES
from .vibration import COMFORT_KEYS, exposure_times

#: Passes named one by one in the progress line (more are counted by verdict).
MAX_PASSES_LISTED = 8
#: The steps run again for every pass (those after the triangulation).
PASS_STEPS = ("smooth", "motion_frame", "rigid_body", "comfort")
#: A pass other than the main one shorter than this many stride periods is not analysed: a record's ends, where a
#: short record's pose spline is least held, are checked against the stride one period inwards, which needs two
#: (:func:`horsemocap.quality.stride_repeat`), and the comfort indicators stand for two periods (tau, thesis 8.4.1;
#: :func:`horsemocap.vibration.saddle_comfort`). The main pass is the session's own result and is analysed however
#: short (its ``record_ends`` check is then skipped, and says why).
MIN_PASS_STRIDES = 2


def shortest_pass_frames(period_frames) -> int:
    """The fewest analysed frames a pass other than the main one needs: :data:`MIN_PASS_STRIDES` stride periods
    (the period rounded as :func:`horsemocap.quality.stride_repeat` rounds it), at least ``MIN_SEGMENT_FRAMES``;
    ``MIN_SEGMENT_FRAMES`` when the period is unknown.

    Examples
    --------
    >>> shortest_pass_frames(17.99), shortest_pass_frames(None), shortest_pass_frames(2.5)
    (36, 8, 8)
    """
    if period_frames is None or not np.isfinite(float(period_frames)) or float(period_frames) <= 0:
        return MIN_SEGMENT_FRAMES
    return max(MIN_SEGMENT_FRAMES, MIN_PASS_STRIDES * int(round(float(period_frames))))


def find_runs(mask, min_frames: int = MIN_SEGMENT_FRAMES) -> list[tuple[int, int]]:
    """Every run of True in ``mask`` at least ``min_frames`` long, as ``(start, stop)``, in order.

    Examples
    --------
    >>> find_runs([True] * 9 + [False] + [True] * 3 + [False] + [True] * 8, min_frames=8)
    [(0, 9), (14, 22)]
    """
    m = np.concatenate([[False], np.asarray(mask, bool), [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_frames]


def pass_segment(points: np.ndarray, run: tuple[int, int]) -> tuple[int, int] | None:
    """The analysed frames of one pass: the longest run inside ``run`` in which every marker has a 3D
    position (as the triangulate step chooses them inside the detection's segment), or None.

    Examples
    --------
    >>> p = np.ones((12, 3, 3)); p[5, 1] = np.nan
    >>> pass_segment(p, (2, 12))
    (6, 12)
    """
    a, b = run
    ok = np.zeros(len(points), bool)
    ok[a:b] = np.all(np.isfinite(points[a:b]), axis=(1, 2))
    return longest_run(ok)


_MAX_KEYS = ("acc_y_max",)


def combined_comfort(indicators: list[dict], durations_s) -> dict:
    """The comfort indicators of several passes taken as one exposure, each pass weighted by its duration.

    The rms accelerations are those of the passes' records put end to end
    (``sqrt(sum(tau_i a_i^2) / sum(tau_i))``), the vibration dose values
    add by their fourth powers (``(sum VDV_i^4)^(1/4)``, eq. 7.4) over the
    total duration, and the times to the action and limit values (eq. 7.10-
    7.17) and the distances (eq. 7.18-7.25) are computed again from those
    and the mean speed; the peak is the largest; every other indicator
    (speed, amplitude, crest factor, frequency, period) is the mean weighted
    by the durations. ``duration_s`` is the total. Passes without
    indicators (None) are left out; the result holds the indicators every pass has.

    Examples
    --------
    Two passes of equal length, rms 1 and 2 m/s^2:

    >>> one = {"acc_y_Wb_rms": 1.0, "VDV_y_Wb": 1.0, "vel_x_avg": 10.0, "TA_8_action_Wb": 2.0, "duration_s": 2.0}
    >>> two = {"acc_y_Wb_rms": 2.0, "VDV_y_Wb": 2.0, "vel_x_avg": 20.0, "TA_8_action_Wb": 0.5, "duration_s": 2.0}
    >>> c = combined_comfort([one, two], [2.0, 2.0])
    >>> round(c["acc_y_Wb_rms"], 4), round(c["VDV_y_Wb"], 4), c["vel_x_avg"], c["duration_s"]
    (1.5811, 2.0305, 15.0, 4.0)
    >>> round(c["TA_8_action_Wb"], 3)    # 8 h (0.5 / 1.5811)^2
    0.8
    """
    kept = [(ind, float(d)) for ind, d in zip(indicators, durations_s) if ind is not None and d > 0]
    if not kept:
        return {}
    tau = np.array([d for _, d in kept])
    total = float(tau.sum())
    keys = [k for k in kept[0][0] if all(k in ind for ind, _ in kept)]
    values = {k: np.array([float(ind[k]) for ind, _ in kept]) for k in keys}
    out = {}
    for k, v in values.items():
        if k.endswith("_rms") or k.endswith("_rms_iso") or k == "A_w_directive":
            out[k] = float(np.sqrt(np.sum(tau * v ** 2) / total))
        elif k.startswith("VDV_"):
            out[k] = float(np.sum(v ** 4) ** 0.25)
        elif k in _MAX_KEYS:
            out[k] = float(np.max(v))
        else:
            out[k] = float(np.sum(tau * v) / total)
    out["duration_s"] = total
    speed = out.get("vel_x_avg")
    for weighting in ("Wb", "Wk"):
        a_rms, vdv = out.get(f"acc_y_{weighting}_rms"), out.get(f"VDV_y_{weighting}")
        times = exposure_times(a_rms=a_rms, vdv_value=vdv, duration_s=total if vdv is not None else None)
        for name, hours in times.items():
            out[f"{name}_{weighting}"] = float(hours)
            if speed is not None:
                out[f"Distance_{name}_{weighting}"] = float(speed * hours)
    if speed is not None:       # the Directive's times (extension rows) from their own combined values
        times = exposure_times(a_rms=out.get("A_w_directive"), vdv_value=out.get("VDV_directive"),
                               duration_s=total if "VDV_directive" in out else None)
        for name, hours in times.items():
            if f"{name}_directive" in out:
                out[f"{name}_directive"] = float(hours)
                out[f"Distance_{name}_directive"] = float(speed * hours)
    return {k: out[k] for k in keys}


@dataclass(frozen=True)
class PassResult:
    """One pass of the horse through the views, analysed.

    Attributes
    ----------
    index : int
        1-based, in the order of the record.
    run : (int, int)
        Synchronised frames ``[start, stop)`` in which every marker is seen.
    segment : (int, int) or None
        The analysed frames (every marker triangulated), None if fewer than the analysis needs.
    analysis : Analysis or None
        The pass' results: the session's own results up to the triangulation, the later steps of this
        pass (None when the pass could not be analysed).
    verdict : str
        ``ok``, ``warning`` or ``unreliable``: the worst level of the checks of the pass' results.
    error : str
        Why the pass could not be analysed ("" when it was).
    main : bool
        The pass the session's own result files (trajectories.csv, comfort.csv, ...) hold.
    """

    index: int
    run: tuple
    segment: tuple | None
    analysis: object
    verdict: str
    error: str = ""
    main: bool = False

    @property
    def indicators(self) -> dict | None:
        """The pass' comfort indicators, or None."""
        c = self.analysis.comfort if self.analysis is not None else None
        return c.indicators if isinstance(c, ComfortResult) else None

    @property
    def duration_s(self) -> float:
        """The analysed time (s), 0 when the pass was not analysed."""
        ind = self.indicators
        return float(ind["duration_s"]) if ind and "duration_s" in ind else 0.0


@dataclass(frozen=True)
class PassesResult:
    """Every pass of a recording and the comfort over all of them.

    Attributes
    ----------
    passes : tuple of PassResult
    combined : dict
        :func:`combined_comfort` of the passes with indicators (empty if none).
    """

    passes: tuple
    combined: dict

    @property
    def verdict(self) -> str:
        """The worst verdict of the analysed passes, and at least ``warning`` when a pass could not be analysed
        (its time is missing from the combined comfort; no number of it is reported): the level of
        :func:`passes_check` and of ``passes.csv``'s row ``all``."""
        levels = [p.verdict for p in self.passes if p.analysis is not None]
        levels += ["warning"] if any(p.analysis is None for p in self.passes) else []
        return quality.verdict([_Level(v) for v in levels])


@dataclass(frozen=True)
class _Level:
    level: str


def pass_runs(analysis) -> list[tuple[int, int]]:
    """The runs of the detection that are passes: every run of :attr:`DetectResult.all_seen` long enough."""
    return find_runs(analysis.detect.all_seen, MIN_SEGMENT_FRAMES)


def analyse_passes(analysis, run_later, progress) -> PassesResult | None:
    """Every pass of ``analysis`` (an :class:`~horsemocap.pipeline.Analysis` that ran to the comfort step).

    ``run_later(results, steps, overrides)`` runs ``steps`` on top of the
    given results, each step's function given its ``overrides`` keywords
    besides its own (:func:`horsemocap.pipeline.run_steps` with the session
    and the parameters). The pass that holds the analysis' own segment keeps its
    results; every other is analysed anew from the smoothing on, its pose
    smoothing with the choices settled on the analysis' own pass
    (:func:`pass_smoothing`). A pass shorter than two strides of the analysis' own pass
    (:func:`shortest_pass_frames`) is not analysed: its ends could not be checked, and its comfort would
    stand for two periods it does not hold; it is said (``error``) and left out of the combined comfort.
    Returns None when the record holds one pass only (nothing to add).
    """
    runs = pass_runs(analysis)
    if len(runs) < 2:
        return None
    tri, det = analysis.triangulate, analysis.detect
    main_a, main_b = tri.segment
    period = analysis.motion_frame.period_frames if analysis.motion_frame is not None else None
    shortest = shortest_pass_frames(period)
    out, jobs = {}, {}
    for i, run in enumerate(runs, 1):
        if run[0] <= main_a and main_b <= run[1]:
            out[i] = PassResult(i, run, tri.segment, analysis, _verdict(analysis), main=True)
            continue
        segment = pass_segment(tri.points, run)
        if segment is None or segment[1] - segment[0] < MIN_SEGMENT_FRAMES:
            out[i] = PassResult(i, run, segment, None, "unreliable",
                                error=f"fewer than {MIN_SEGMENT_FRAMES} consecutive frames with every marker "
                                      "triangulated")
            continue
        if segment[1] - segment[0] < shortest:
            out[i] = PassResult(i, run, segment, None, "unreliable",
                                error=f"{segment[1] - segment[0]} frames with every marker triangulated, under two "
                                      f"strides ({shortest} frames at the stride period of {period:.1f} frames): too "
                                      "short for its ends to be checked and for the comfort's two periods")
            continue
        given = {name: getattr(analysis, name) for name in ("sync", "rig", "plumb", "static")}
        given["detect"] = det.replace(segment=run)
        given["triangulate"] = tri.replace(segment=segment)
        jobs[i] = (run, segment, given)
    settled = pass_smoothing(analysis)
    later = run_beside([lambda given=given: _later_steps(run_later, given, settled)
                        for _, _, given in jobs.values()])
    for (i, (run, segment, given)), (results, error) in zip(jobs.items(), later):
        if error:
            out[i] = PassResult(i, run, segment, None, "unreliable", error=error)
            continue
        an = analysis.__class__(analysis.session, analysis.params)
        for name, value in {**given, **results}.items():
            setattr(an, name, value)
        out[i] = PassResult(i, run, segment, an, _verdict(an))
    out = [out[i] for i in sorted(out)]
    result = PassesResult(tuple(out), combined_comfort([p.indicators for p in out], [p.duration_s for p in out]))
    analysed = sum(p.analysis is not None for p in out)
    progress("passes", f"{len(out)} passes of the horse through the views, {analysed} analysed; "
                       + summary_text(out))
    return result


def pass_smoothing(analysis) -> SettledPoseSmoothing | None:
    """The pose smoothing's choices of ``analysis`` (its longest pass), for the other passes of the record.

    The passes film the same horse in the same gait: the method, stride
    frequency, smoothing parameters, harmonics and rotation weighting chosen
    on the longest pass (:func:`horsemocap.pose.settle_pose_smoothing`) serve
    the others, which then search none of them; a blend of the fits without
    and with the stride's harmonics is served whole (both routes' parameters
    and the blend's weight). None when the analysis has
    no pose trajectory (``kinematics="fits"``).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from horsemocap.params import AnalysisParams
    >>> fits = AnalysisParams.from_dict({"rigid_body": {"kinematics": "fits"}})
    >>> print(pass_smoothing(SimpleNamespace(rigid_body=None, params=fits)))
    None
    """
    rb = analysis.rigid_body
    trajectory = None if rb is None else getattr(rb.body, "pose", None)
    if trajectory is None or analysis.params.rigid_body.kinematics != "pose_spline":
        return None
    return settle_pose_smoothing(trajectory, analysis.params.rigid_body.pose)


def _later_steps(run_later, given, settled: SettledPoseSmoothing | None = None) -> tuple[dict, str]:
    """The results of :data:`PASS_STEPS` on ``given`` and "", or {} and why they could not be computed.

    The rigid-body step is given the ``settled`` pose smoothing and runs without the thesis' chain of fits
    (a pass' comfort and verdict come from the pose trajectory; the chain is the main pass' own, in its
    result files).
    """
    try:
        an = run_later(given, PASS_STEPS, {"rigid_body": {"settled": settled, "thesis_chain": False}})
    except (AnalysisError, ValueError, np.linalg.LinAlgError) as exc:
        return {}, str(exc)
    return {name: getattr(an, name) for name in PASS_STEPS}, ""


def summary_text(passes) -> str:
    """The passes in words: each one when there are at most :data:`MAX_PASSES_LISTED`, else the count per
    verdict and the first of those not ``ok``.

    Examples
    --------
    >>> many = [PassResult(i, (10 * i, 10 * i + 9), None, None, "unreliable", error="too short") for i in range(1, 11)]
    >>> summary_text(many[:1])
    'pass 1 (frames 10..18): not analysed (too short)'
    >>> summary_text(many)[:60]
    '10 unreliable (passes.csv has each); pass 1 (frames 10..18):'
    """
    passes = list(passes)
    if len(passes) <= MAX_PASSES_LISTED:
        return "; ".join(_pass_text(p) for p in passes)
    counts = {v: sum(p.verdict == v for p in passes) for v in ("ok", "warning", "unreliable")}
    text = ", ".join(f"{n} {v}" for v, n in counts.items() if n) + " (passes.csv has each)"
    flagged = [p for p in passes if p.verdict != "ok"][:MAX_PASSES_LISTED]
    return text + "".join(f"; {_pass_text(p)}" for p in flagged)


def passes_check(passes: PassesResult) -> quality.Check:
    """The check ``passes`` of a recording with several passes, for the session's overall verdict.

    The session's own checks judge the pass its result files hold (the
    longest); this one judges the others, whose comfort is in the combined
    indicators (``passes.csv``, row ``all``). Its level is the worst verdict
    of the analysed passes (an unreliable pass makes the combined comfort
    unreliable), and at least ``warning`` when a pass could not be analysed
    (its time is missing from the combined comfort; no number of it is
    reported). The figure is the number of passes analysed.

    Examples
    --------
    >>> ok = PassResult(1, (0, 40), (0, 40), object(), "ok")
    >>> short = PassResult(2, (60, 69), None, None, "unreliable", error="too short")
    >>> check = passes_check(PassesResult((ok, short), {}))
    >>> check.level, check.figure
    ('warning', 1)
    >>> check.message
    '2 passes, 1 analysed: 1 ok; 1 not analysed (left out of the combined comfort): pass 2 (frames 60..68): not analysed (too short)'
    """
    analysed = [p for p in passes.passes if p.analysis is not None]
    missing = [p for p in passes.passes if p.analysis is None]
    level = passes.verdict
    counts = ", ".join(f"{n} {v}" for v, n in ((v, sum(p.verdict == v for p in analysed)) for v in quality.LEVELS)
                       if n)
    message = f"{len(passes.passes)} passes, {len(analysed)} analysed" + (f": {counts}" if counts else "")
    if missing:
        message += (f"; {len(missing)} not analysed (left out of the combined comfort): "
                    + "; ".join(_pass_text(p) for p in missing[:MAX_PASSES_LISTED]))
    flagged = [p for p in analysed if p.verdict != "ok"][:MAX_PASSES_LISTED]
    if flagged and level != "ok":
        message += "; " + "; ".join(_pass_text(p) for p in flagged)
    return quality.Check("passes", len(analysed), "passes", level, (None, None), (None, None),
                         "the worst verdict of the analysed passes; a pass not analysed: warning",
                         "passes.csv", message)


def _verdict(analysis) -> str:
    return quality.verdict(quality.post_checks(analysis))


def _pass_text(p: PassResult) -> str:
    where = f"pass {p.index} (frames {p.run[0]}..{p.run[1] - 1})"
    if p.analysis is None:
        return f"{where}: not analysed ({p.error})"
    ind = p.indicators
    rms = f", Wb rms {ind['acc_y_Wb_rms']:.3g} m/s^2" if ind and "acc_y_Wb_rms" in ind else ""
    return f"{where}: {p.verdict}{rms}"


PASS_COLUMNS = ("pass", "main", "first_frame", "last_frame", "start_s", "duration_s", "verdict", "error")
"""The leading columns of ``passes.csv``; the comfort indicators follow (docs/sessions.md)."""


def passes_rows(passes: PassesResult, reference_offset: int, fps: float) -> tuple[list, list]:
    """Header and rows of ``passes.csv``: a row per pass, then the row ``all`` (the combined comfort).

    ``first_frame``/``last_frame`` are the analysed frames in the reference camera's own numbering
    (``reference_offset`` = its sync offset), ``start_s`` the time of the first from the synchronised
    start; the indicators are ``comfort.csv``'s, empty for a pass without them.
    """
    keys = [k for k in COMFORT_KEYS if k != "duration_s"]
    extra = [k for p in passes.passes if p.indicators for k in p.indicators if k not in COMFORT_KEYS]
    keys += list(dict.fromkeys(extra))
    rows = []
    for p in passes.passes:
        seg = p.segment if p.segment is not None else p.run
        ind = p.indicators or {}
        rows.append([p.index, int(p.main), seg[0] + reference_offset, seg[1] - 1 + reference_offset,
                     _num(seg[0] / fps), _num(p.duration_s) if p.analysis is not None else "", p.verdict,
                     p.error, *(_num(ind.get(k)) for k in keys)])
    c = passes.combined
    rows.append(["all", "", "", "", "", _num(c.get("duration_s")), passes.verdict, "",
                 *(_num(c.get(k)) for k in keys)])
    return [*PASS_COLUMNS, *keys], rows


def _num(v, digits: int = 9) -> str:
    return "" if v is None or not np.isfinite(float(v)) else f"{float(v):.{digits}g}"
