"""One whole run of ``horsemocap analyze``: checks, analysis, verdict, one swap.

:func:`run_analysis` validates the session and the parameters, runs the
plausibility checks that need no analysis (:mod:`horsemocap.quality`),
analyses the session into a temporary folder beside the results folder
(:class:`horsemocap.runfolder.RunFolder`), checks the results, writes
``quality.json`` and ``report.html`` and puts the folder in place in one
rename. Nothing is written before the session and the parameters are
valid; nothing is ever written into the session.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from . import quality
from .camera import read_rig
from .pipeline import _progress_printer, AnalysisError, analyze, resolve_params
from .passes import passes_check
from .plots import figure_painter
from .report import step_figures, write_report
from .runfolder import check_results_target, RunFolder
from .session import load_session, SessionError
from .store import atomic_write_json, atomic_write_text, check_outside

EXIT_OK = 0
EXIT_ERROR = 2
EXIT_UNRELIABLE = 3


@dataclass
class RunOutcome:
    """What a run left in ``out``.

    Attributes
    ----------
    out : Path
    analysis : Analysis or None
        The steps that ran (partial when ``error`` is set).
    checks : list of quality.Check
    verdict : str
        ``"ok"``, ``"warning"`` or ``"unreliable"`` (a failed run is ``"unreliable"``).
    report : Path or None
    error : Exception or None
        The step failure; the finished steps' files are in ``out``, marked partial.
    """

    out: Path
    analysis: object
    checks: list = field(default_factory=list)
    verdict: str = "ok"
    report: Path | None = None
    error: Exception | None = None

    @property
    def exit_code(self) -> int:
        if self.error is not None:
            return EXIT_ERROR
        return EXIT_UNRELIABLE if self.verdict == "unreliable" else EXIT_OK


def _session_rig(session, params):
    """The rig the run will read from ``rig.toml`` (None if it calibrates)."""
    if session.rig_path is None or params.rig.recalibrate:
        return None
    rig = read_rig(session.rig_path)
    if not all(c in rig.names for c in session.cameras):
        return None  # step 'rig' says which camera is missing
    return rig.subset(session.cameras)


def _mark_record(folder: Path, **fields) -> None:
    path = folder / "analysis.json"
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        record = {}
    record.update(fields)
    atomic_write_json(path, record)


def _figures_drawn_after(painter):
    """The pipeline's ``after_step``: each step's report figures (:func:`horsemocap.report.step_figures`)
    given to ``painter`` as the step ends.

    An error in describing a step's figures does not stop the analysis: no
    more figures are given during it, and the report describes them all at
    its end (:func:`horsemocap.report.report_html`: a figure that cannot be
    described there either is left out with the reason).
    """
    failed = []

    def after_step(analysis, step):
        if failed:
            return
        try:
            descriptions = [description for description, _ in step_figures(analysis, step)]
        except Exception as exc:    # noqa: BLE001 - the figures are described again, and reported, at the end
            failed.append((step, exc))
            return
        if descriptions:
            painter.submit(descriptions)
    return after_step


def run_analysis(session_dir, out, params=None, *, progress=None, report: bool = True,
                 board_views=None, flash_search=None, painter=None) -> RunOutcome:
    """Analyse ``session_dir`` into ``out`` as one whole run.

    Parameters
    ----------
    session_dir : path
    out : path
        The results folder: absent, empty or an earlier run's (replaced whole).
    params : AnalysisParams or dict, optional
        Overrides of the session's ``analysis`` object.
    progress : callable(step, message), optional
    report : bool
        Write ``report.html``.
    board_views : horsemocap.calibration.cache.BoardDetectionJob, optional
        Board detection already under way (:func:`horsemocap.pipeline.analyze`).
    flash_search : horsemocap.sync.FlashSearch, optional
        The flash search already under way (:func:`horsemocap.pipeline.analyze`).
    painter : horsemocap.forking.EarlyCalls, optional
        The report's figure painter (:func:`horsemocap.plots.figure_painter`), made earlier by the
        caller (before its threads started, so that it could fork); closed here. Default: made here.

    Returns
    -------
    RunOutcome

    Raises
    ------
    SessionError, ParamsError, StoreError, RigError
        Before anything is written. KeyboardInterrupt and any other error
        leave ``out`` as it was.
    horsemocap.runfolder.RunWriteError
        A file that could not be written (disk full, quota, read-only,
        permission, I/O error), in any step or after: ``out`` is as it was.
    """
    progress = progress or _progress_printer()
    session = load_session(session_dir)
    params = resolve_params(session, params)
    params.check_session(session)
    target = check_results_target(out)
    check_outside(target, session.root)
    rig = _session_rig(session, params)
    checks = quality.pre_checks(session, rig)
    for c in checks:
        if c.level in ("warning", "unreliable"):
            progress("quality", f"{c.level}: {c.message} [{c.input}]")

    folder = RunFolder(out)
    # the report's figures: a copy of the process forked now loads matplotlib while the analysis runs and
    # draws each step's figures while the next steps run
    painter = painter if painter is not None else figure_painter(fork=report)
    with painter, folder as tmp:
        outcome = RunOutcome(Path(target), None)
        try:
            analysis = analyze(session_dir, tmp, params, progress=progress, previous_results=target,
                               board_views=board_views, flash_search=flash_search,
                               after_step=_figures_drawn_after(painter) if report else None)
        except (AnalysisError, SessionError) as exc:
            if folder.write_failure(exc) is not None:
                raise   # the disk, not the step: DIR stays as it was (RunFolder names the file)
            analysis = getattr(exc, "partial", None)
            outcome.error = exc
        outcome.analysis = analysis
        if analysis is not None:
            if rig is None and analysis.rig is not None:
                checks += quality.rig_checks(session, analysis.rig.rig)
            checks += quality.post_checks(analysis)
            if getattr(analysis, "passes", None) is not None:     # the other passes of a long recording
                checks.append(passes_check(analysis.passes))
        if outcome.error is not None:
            checks.append(quality.Check("run_complete", None, "", "unreliable", (None, None), (None, None),
                                        "every step ran", "the step named in the message",
                                        f"the run stopped: {outcome.error}"))
        outcome.checks = checks
        outcome.verdict = quality.verdict(checks)
        record = quality.quality_record(checks)
        atomic_write_json(tmp / "quality.json", record)
        if outcome.error is not None:
            _mark_record(tmp, complete=False, error=str(outcome.error), quality_verdict=outcome.verdict)
            atomic_write_text(tmp / "PARTIAL.txt",
                              "PARTIAL RESULTS: the run stopped before its end, so this folder holds only the "
                              f"files of the steps that finished.\n{outcome.error}\n")
        else:
            _mark_record(tmp, complete=True, quality_verdict=outcome.verdict)
            if report:
                write_report(tmp / "report.html", analysis, quality=record, painter=painter)
                outcome.report = outcome.out / "report.html"
        folder.commit()
    return outcome
