"""The ``horsemocap`` command line.

``horsemocap analyze SESSION --out DIR``  every step of the thesis, automatically
``horsemocap demo [--out DIR]``           the same on the bundled riding session
``horsemocap calibrate DIR [DIR ...]``    calibrate a rig once for many sessions
``horsemocap batch SESSION... --out DIR`` many sessions side by side into one table
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .params import ParamField, params_fields, ParamsError, PoseParams, read_params, resolve_params, section_title
from .plots import figure_painter
from .readable import hours_minutes

#: The pose parameters' fields: the kinematics command's options take their defaults and choices.
_POSE_FIELDS = PoseParams.__dataclass_fields__

#: Allocations between two collections of the garbage collector's youngest generation in the command's
#: process (Python's default is 700): a run loads about a thousand modules and builds few reference
#: cycles; with the default the collector walks the loaded modules' objects again and again.
COMMAND_GC_ALLOCATIONS = 10_000

DESCRIPTION = """\
horsemocap: saddle motion analysis of horses with a 3-camera vision system
(a reproduction of G. Dogan, METU 2009). Every step chooses its parameters
automatically; any choice can be given in a parameter file or on the line."""


@dataclass(frozen=True)
class AnalysisOption:
    """One analysis option of the command line and the one parameter it sets.

    Attributes
    ----------
    flag : str
        The option, e.g. ``"--span"``.
    dest : str
        Its attribute in argparse's namespace (the names of the options before
        the sections were generated are kept, e.g. ``"smoothing_span"``).
    target : str
        The dotted parameter it sets: a field (``"smooth.span"``) or one value
        inside a dict field (``"detect.cameras.all.threshold"``).
    name : str
        The name it is applied by, the flat one where the field has one
        (``"smoothing_span"``), so a bad value is reported by the names of
        ``analysis.json`` files.
    field : horsemocap.params.ParamField
        The parameter field (its help, choices, kind, default).
    metavar, help : str or None
        As shown by ``--help``.
    """

    flag: str
    dest: str
    target: str
    name: str
    field: ParamField
    metavar: str | None = None
    help: str | None = None


def analysis_options() -> list[AnalysisOption]:
    """Every analysis option of ``analyze`` and ``demo``, generated from the parameter fields' metadata.

    A field with a ``cli`` flag gets one option setting it whole; its
    ``cli_values`` (e.g. ``--threshold``: ``detect.cameras.all.threshold``)
    one option each setting one value inside it.

    Examples
    --------
    >>> next(o for o in analysis_options() if o.flag == "--span").target
    'smooth.span'
    """
    options = []
    for f in params_fields():
        if f.cli:
            dest = f.legacy if f.legacy and f.kind not in ("offsets", "exclude") else _flag_dest(f.cli)
            options.append(AnalysisOption(f.cli, dest, f.path, f.legacy or f.path, f, f.metavar, f.help))
        for flag, inside, metavar, text in f.cli_values:
            name = f"{f.legacy}.{inside}" if f.legacy else f"{f.path}.{inside}"
            options.append(AnalysisOption(flag, _flag_dest(flag), f"{f.path}.{inside}", name, f, metavar, text))
    return options


def _flag_dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def _add_choice_options(p: argparse.ArgumentParser) -> None:
    """The analysis options (:func:`analysis_options`), one argument group per section, plus ``--set``."""
    g = p.add_argument_group("analysis choices (default: automatic, as recorded in analysis.json)",
                             "Every option below sets one parameter of analysis.json (its section and name "
                             "are the group's); --set sets any of them by name.")
    groups = {}
    for opt in analysis_options():
        section = opt.field.section
        if opt.target == "preset":
            group = g
        else:
            if section not in groups:
                groups[section] = p.add_argument_group(section, section_title(section))
            group = groups[section]
        group.add_argument(opt.flag, dest=opt.dest, help=_option_help(opt), **_option_kind(opt))
    g.add_argument("--set", action="append", dest="set", metavar="NAME=VALUE",
                   help="any parameter by its dotted name, the value in JSON, applied after the options; "
                        "repeatable. Every prompt of one camera, e.g. --set detect.cameras.left.labels=[3,4,5] "
                        "--set detect.cameras.left.first_frame=36 --set detect.cameras.all.area_min=5 "
                        "--set detect.cameras.right.window=[180,140] --set smooth.span=0.2 "
                        "--set stills.static.left.threshold=150 (names as in analysis.json; the flat names of "
                        "earlier files too, e.g. detection.left.threshold or smoothing_span)")


def _option_kind(opt: AnalysisOption) -> dict:
    """argparse's arguments for an option's value (type, choices, action, metavar)."""
    f = opt.field
    if opt.target != f.path:                  # one value inside a dict field: a gray level or a frame
        return {"type": int, "metavar": opt.metavar}
    if f.choices is not None:
        return {"choices": list(f.choices)}
    if f.kind == "bool":
        return {"action": "store_true", "default": None}
    if f.kind == "events":
        return {"action": "append", "metavar": opt.metavar}
    if f.kind in ("int", "number"):
        return {"type": int if f.kind == "int" else float, "metavar": opt.metavar}
    return {"metavar": opt.metavar}           # text with a syntax of its own (_OPTION_PARSERS)


def _option_help(opt: AnalysisOption) -> str:
    """The option's help with its default, unless the help says it (a flag, the preset, an automatic choice)."""
    f = opt.field
    if opt.target != f.path or f.kind == "bool" or f.path == "preset" or "automatic" in opt.help:
        return opt.help
    if f.kind == "versions":
        shown = "all"
    elif f.default == {} or (f.default is None and f.kind == "events"):
        shown = "none"
    else:
        shown = "automatic" if f.default is None else f.default
    return f"{opt.help} (default {shown})"


def _parse_offsets(text: str, flag: str) -> dict:
    try:
        return {k: _frame_number(v) for k, v in (kv.split("=") for kv in text.split(","))}
    except ValueError:
        raise ParamsError(f"{flag}: expected CAM=FRAME,... (frame indices, with a fraction for free-running "
                          f"cameras: middle=53.4), got {text!r}") from None


def _frame_number(text: str):
    """A frame index: an int when whole (``53``), else a float (``53.4``)."""
    value = float(text)
    return int(value) if value.is_integer() and "." not in text else value


def _parse_exclude(text: str, flag: str) -> dict:
    try:
        pairs = [kv.split("=", 1) for kv in text.split(",")]
        return {c.strip(): [v for v in views.split("+") if v] for c, views in pairs}
    except ValueError:
        raise ParamsError(f"{flag}: expected CAM=VIEW[+VIEW],..., got {text!r}") from None


def _parse_fourier_orders(text: str, flag: str) -> dict:
    try:
        y, z = (int(v) for v in text.split(","))
    except ValueError:
        raise ParamsError(f"{flag}: expected Y,Z (two integers), got {text!r}") from None
    return {"y": y, "z": z}


def _parse_versions(text: str, flag: str) -> list[bool]:
    try:
        picked = {int(v) for v in text.split(",")}
    except ValueError:
        picked = set()
    if not picked or not picked <= set(range(1, 7)):
        raise ParamsError(f"{flag}: expected version numbers 1-6 separated by commas, got {text!r}")
    return [k in picked for k in range(1, 7)]


_OPTION_PARSERS = {"offsets": _parse_offsets, "exclude": _parse_exclude, "fourier_orders": _parse_fourier_orders,
                   "versions": _parse_versions, "events": lambda words, flag: parse_seconds(words, flag)}
"""Field kind -> the parser of its option's text (errors name the option)."""


def _params_from_args(args, base):
    """The parameters ``base`` with the preset, the analysis options and ``--set`` of the command line applied."""
    if getattr(args, "preset", None):
        base = base.with_preset(args.preset)
    changes = {}
    for opt in analysis_options():
        given = getattr(args, opt.dest, None)
        if given is None or opt.target == "preset":
            continue
        parse = _OPTION_PARSERS.get(opt.field.kind) if opt.target == opt.field.path else None
        changes[opt.name] = parse(given, opt.flag) if parse else given
    params = base.updated(changes, source="command line") if changes else base
    for item in getattr(args, "set", None) or []:
        params = _set_param(params, item)
    return params


def parse_seconds(values, option: str) -> list[float]:
    """Times in seconds given as ``0.5,0.8`` (or ``"0.5 0.8"``) to ``--pose-events`` and ``--events``.

    ``values`` is the option's values (argparse ``action="append"``: one word per
    occurrence of the option, so a time never swallows the SESSION that follows) or one string;
    raises :class:`horsemocap.params.ParamsError` naming ``option`` and the
    word that is not a finite number.
    """
    words = [values] if isinstance(values, str) else list(values)
    parts = [p for w in words for p in w.replace(",", " ").split()]
    if not parts:
        raise ParamsError(f"{option}: expected times in seconds, e.g. 0.5,0.8; got {' '.join(words)!r}")
    times = []
    for p in parts:
        try:
            v = float(p)
        except ValueError:
            v = float("nan")
        if not np.isfinite(v):
            raise ParamsError(f"{option}: {p!r} is not a time in seconds (expected numbers separated by commas, "
                              f"e.g. 0.5,0.8, or the option repeated)")
        times.append(v)
    return times


def _set_param(params, item: str):
    """``--set NAME=VALUE``: one parameter by its dotted name, new or flat (JSON value, else the text as a string)."""
    name, sep, text = item.partition("=")
    name = name.strip()
    if not sep or not name or not all(name.split(".")):
        raise ParamsError(f"--set: expected NAME=VALUE such as detect.cameras.left.threshold=140, got {item!r}")
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        value = text
    return params.with_path(name, value, source=f"--set {item}")


def _early_board_detection(session, out_dir: Path, args):
    """The board detection of the session's views, started before the analysis' modules are imported.

    Started when the rig is calibrated from views (no ``rig.toml``, or
    ``--recalibrate``) and the results folder's ``calibration.json`` does not
    already hold their corners; None otherwise. Issue 16: the views are
    detected by threads while this thread imports the analysis' modules and
    checks the parameters (about 1 s of the bundled analysis).
    """
    recalibrate = bool(getattr(args, "recalibrate", None))
    if not session.calibrates_from_views(recalibrate):
        return None
    from .calibration.cache import BoardDetectionJob, views_cached

    inner = session.board.inner_corners
    try:
        if not recalibrate and views_cached(session.calibration_images, inner, [out_dir]):
            return None
        return BoardDetectionJob(session.calibration_images, inner)
    except Exception:   # (a view folder that is a file, an unreadable view...): the rig step reports it
        return None


def _run_analysis(session_dir: Path, out_dir: Path, args) -> int:
    """Read the session and the parameters, start the early work, then load the analysis and run it.

    Before the analysis' modules are loaded (the longest part of a short run's start): the copy of the
    process that will draw the report's figures is forked (before any thread
    starts, see :func:`horsemocap.forking.can_fork`; it loads matplotlib
    meanwhile), then the flash search of the videos is started unless
    ``session.json`` gives the offsets (:func:`_early_flash_search`), then
    the parameters are read and checked (a bad one ends the run; when they
    give the offsets the search is cancelled, not waited for), then the board
    detection of the views starts (:func:`_early_board_detection`).
    Whatever early work nobody took is ended at the end, without being waited
    for (an error, Ctrl-C, a step's results reused from the results store).
    """
    # OpenCV (the session's videos, the flash search) is loaded only by the commands that read a session
    from .session import load_session

    _no_nul(("SESSION", str(session_dir)), ("--out", str(out_dir)), ("--params", args.params))
    session = load_session(session_dir)
    # forked first: before any thread, and before the parameters' check loads the detection's modules
    # held: matplotlib loads once the flash search is done (on two cores the search has the second one)
    painter = figure_painter(hold=True) if not getattr(args, "no_report", False) else None
    board_views = flash_search = None
    try:
        # the search first: reading the parameters loads the detection's modules (SciPy)
        flash_search = _early_flash_search(session, when_done=painter.start if painter is not None else None)
        if flash_search is None and painter is not None:
            painter.start()
        params = _analysis_params(session, args)
        if flash_search is not None and params.sync.offsets:
            flash_search.close(wanted=False)    # the parameters give the offsets: cancelled, not waited for
            flash_search = None
            if painter is not None:
                painter.start()
        board_views = _early_board_detection(session, out_dir, args)
        return _analyse_session(session, session_dir, out_dir, args, params, board_views, flash_search, painter)
    finally:
        if flash_search is not None:
            flash_search.close(wanted=False)    # taken by the sync step already, or nobody will
        for job in (painter, board_views):
            if job is not None:
                job.close()


def _analysis_params(session, args):
    """The run's parameters, checked against the session: the session's ``analysis`` object, the
    ``--params`` file over it, then the preset, the options and ``--set``.

    Made with the parameters module alone (:func:`horsemocap.params.resolve_params`), so that they are
    known before the analysis' modules load.
    """
    base = resolve_params(session, read_params(args.params)) if args.params else resolve_params(session)
    params = _params_from_args(args, base)
    params.check_session(session, f"{args.params}" if args.params else "parameters")
    return params


def _early_flash_search(session, when_done=None):
    """The flash search of the session's videos, started before the analysis' modules are imported.

    Started unless ``session.json`` gives the offsets (None then); the
    caller cancels it when the parameters (the session's ``analysis``
    object, ``--params``, ``--offsets``, ``--set``) give them. ``when_done``:
    as :class:`horsemocap.sync.FlashSearch`.
    """
    from .sync import FlashSearch     # OpenCV, as load_session

    if session.sync_offsets:
        return None
    return FlashSearch({c: session.motion[c] for c in session.cameras}, when_done=when_done)


def _analyse_session(session, session_dir: Path, out_dir: Path, args, params, board_views, flash_search=None,
                     painter=None) -> int:
    from .run import run_analysis

    outcome = run_analysis(session_dir, out_dir, params, report=painter is not None,
                           board_views=board_views, flash_search=flash_search, painter=painter)
    if outcome.error is not None:
        if getattr(args, "debug", False):   # the step's own exception, with the error it was raised from
            import traceback

            traceback.print_exception(outcome.error)
        print(f"horsemocap: error: {_error_line(outcome.error)}", file=sys.stderr)
        print(f"horsemocap: the files of the steps that finished are in {outcome.out} (marked PARTIAL.txt; "
              f"quality: {outcome.verdict})", file=sys.stderr)
        return outcome.exit_code
    print(f"results: {outcome.out}")
    if outcome.report:
        print(f"report:  {outcome.report}")
    bad = [c for c in outcome.checks if c.level in ("warning", "unreliable")]
    print(f"quality: {outcome.verdict.upper()}" + (f" ({len(bad)} check(s) with a warning or worse; "
                                                   "see quality.json)" if bad else " (every plausibility check passed)"))
    for c in bad:
        print(f"  {c.level}: {c.name}: {c.message}")
    comfort = outcome.analysis.comfort if outcome.analysis is not None else None
    ind = comfort.indicators if comfort is not None else None
    if ind:
        print(f"comfort [quality {outcome.verdict}]: Wk-weighted rms {ind['acc_y_Wk_rms']:.3f} m/s², "
              f"VDV {ind['VDV_y_Wk']:.3f} m/s^1.75, 8-h action value reached in "
              f"{hours_minutes(ind['TA_8_action_Wk'])} at {ind['vel_x_avg']:.1f} km/h (vertical axis, the thesis)"
              + (f"; by the EU Directive's three axes in {hours_minutes(ind['TA_8_action_directive'])}"
                 if "TA_8_action_directive" in ind else ""))
    if outcome.exit_code == 3:
        print(f"horsemocap: the quality verdict is UNRELIABLE (exit status {outcome.exit_code}): do not use these "
              "numbers before what the check above names is fixed (the input, or a method that fails on it: "
              "README, --preset thesis)", file=sys.stderr)
    return outcome.exit_code


def cmd_analyze(args) -> int:
    return _run_analysis(Path(args.session), Path(args.out), args)


def cmd_demo(args) -> int:
    from .data import default_session_dir

    session = default_session_dir()
    if not (session / "session.json").is_file():
        print(f"horsemocap: error: the bundled session is missing ({session})", file=sys.stderr)
        return 2
    out = Path(args.out)
    print(f"analysing the bundled session {session.name} (Horse 2, canter; thesis section 8.4.1)")
    return _run_analysis(session, out, args)


def cmd_batch(args) -> int:
    """Every session of ``args.sessions`` analysed as ``analyze`` would, into ``--out``, with one table."""
    from .batch import BatchError, run_batch

    _no_nul(("--out", args.out), ("--params", args.params), *(("SESSION", s) for s in args.sessions))
    if args.workers is not None and args.workers < 1:
        print(f"horsemocap: error: --workers {args.workers}: expected 1 or more worker processes", file=sys.stderr)
        return 2
    try:
        summary = run_batch(args.sessions, Path(args.out), workers=args.workers, scheduler=args.scheduler,
                            params_file=args.params)
    except BatchError as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        return 2
    for row in summary.rows:
        if row["error"]:
            print(f"  {row['name']}: {row['error']}", file=sys.stderr)
    print(f"table:   {summary.table}" + (f"\n         {summary.parquet}" if summary.parquet else ""))
    print(f"{len(summary.rows)} session(s) in {summary.seconds:.1f} s: "
          f"{sum(r['reused'] for r in summary.rows)} reused, {summary.failed} failed")
    return summary.exit_code


def _check_rig_target(out: Path) -> None:
    """``calibrate --out`` must be a file we can write: checked before the calibration runs."""
    import os
    import secrets

    from .store import StoreError

    if out.is_dir():
        raise StoreError(f"--out {out}: is a folder; give the path of the rig file to write, e.g. {out / 'rig.toml'}")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        probe = out.parent / f".{out.name}.{secrets.token_hex(4)}.probe"
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        os.unlink(probe)
    except OSError as exc:
        raise StoreError(f"--out {out}: cannot write there ({exc.strerror}); choose another path") from None


def cmd_calibrate(args) -> int:
    from .calibration import calibrate_command

    _no_nul(("--out", args.out), *(("CAMERA_DIR", d) for d in args.camera_dirs))
    _check_rig_target(Path(args.out))
    text = calibrate_command([Path(d) for d in args.camera_dirs], args.board, args.square, Path(args.out))
    print(text)
    return 0


EXIT_STATUS = """\
exit status:
  0  the results are written and every plausibility check is ok or a warning
  2  an error (a bad session, parameter or results folder, a step that failed,
     Ctrl-C): a one-line message names the file or field; --debug shows the traceback
  3  the results are written but the quality verdict is UNRELIABLE (quality.json
     and report.html say which check failed): do not use the numbers"""


def cmd_kinematics(args) -> int:
    """3D markers from another system + a static shot -> trajectories/kinematics/angular CSV.

    ``--out DIR`` follows analyze's rule (:mod:`horsemocap.runfolder`): DIR
    new, empty or an earlier ``kinematics`` run's output (it holds
    ``kinematics-run.json``), checked before the computation and replaced
    whole when the files are written. A record longer than
    :data:`horsemocap.streaming.WHOLE_RECORD_FRAMES` is smoothed in windows
    (:mod:`horsemocap.streaming`) and its tables written window by window.
    """
    from .io3d import TrajectoryFileError, check_trajectory_input, kinematics_verdict, read_trajectories, \
        read_trajectories_to_disk
    from .pose import CollinearMarkersError
    from .runfolder import RunFolder
    from .store import ScratchWriteError, atomic_write_json
    from .streaming import conditioning_warnings
    from .threads import blas_single_threaded

    _no_nul(("TRAJECTORIES", args.trajectories), ("--static", args.static))
    folder = RunFolder(args.out, "kinematics")        # the target checked here, before the computation
    target = folder.out
    _check_inputs_outside(target, args)
    # the smoothing's matrices are small: more BLAS threads only wait for each other; a long record's
    # points and registration are memory-mapped in a scratch folder, not held in memory
    with blas_single_threaded(), tempfile.TemporaryDirectory(prefix="horsemocap-kinematics-") as scratch:
        try:
            traj = read_trajectories_to_disk(args.trajectories, scratch)
            static = read_trajectories(args.static)
            check_trajectory_input(traj, static)
            events = parse_seconds(args.events, "--events") if args.events else None
            res = _kinematics_result(traj, static, args.smoothing, events, scratch, args.noise_criterion)
        except (TrajectoryFileError, CollinearMarkersError, ValueError, ScratchWriteError) as exc:
            print(f"horsemocap: error: {exc}", file=sys.stderr)
            return 2
        reg = res["registration"]
        source = _kinematics_input(traj)
        with folder as tmp:
            norms = _write_kinematics_tables(tmp, traj, res)
            checks = _kinematics_checks(traj, res, *norms)
            verdict = kinematics_verdict(checks)
            record = _kinematics_record(args, events, res, list(KINEMATICS_TABLES), source)
            record["quality"] = {"verdict": verdict, "checks": checks}
            atomic_write_json(tmp / "kinematics-run.json", record)
            folder.commit()
    for msg in _kinematics_notes(traj, static, res, source):
        print(f"[horsemocap] kinematics: {msg}", file=sys.stderr)
    for msg in conditioning_warnings(reg):
        print(f"[horsemocap] kinematics: WARNING: {msg}", file=sys.stderr)
    print(f"[horsemocap] kinematics: {len(res['markers'])} markers {res['markers']}, hidden points "
          f"{res['hidden']}; marker noise from the registration {1000 * reg.noise_m:.3f} mm", file=sys.stderr)
    ran = res["smoothing_choice"]
    if ran:
        print(f"[horsemocap] kinematics: {ran['method']} smoothing ({args.smoothing}: {ran['reason']})",
              file=sys.stderr)
    if res.get("windows"):
        w = res["windows"]
        print(f"[horsemocap] kinematics: {traj.frame.size} frames smoothed in {w['count']} windows of "
              f"{w['window_frames']} frames (margin {w['margin_frames']}; smoothing settled on frames "
              f"{w['settled_on'][0]}..{w['settled_on'][1]})", file=sys.stderr)
    print(f"results: {target}")
    return _kinematics_verdict_lines(verdict, checks)


KINEMATICS_TABLES = ("trajectories.csv", "kinematics.csv", "angular.csv")


def _kinematics_checks(traj, res, speed_p99, acceleration_p99) -> list:
    from .io3d import kinematics_checks_of_percentiles
    from .quality import check_spline_basis

    checks = kinematics_checks_of_percentiles(traj, res["markers"], speed_p99, acceleration_p99)
    if res.get("basis_resolution") is not None:       # a record smoothed whole with a knot every few frames
        c = check_spline_basis(res["basis_resolution"], point=res["basis_point"])
        checks.append({"name": c.name, "level": c.level, "value": c.figure, "limit": c.warning[1],
                       "message": c.message})
    return checks


def _kinematics_result(traj, static, smoothing: str, events, scratch=None, noise_criterion: str | None = None) -> dict:
    """What ``kinematics`` writes: the whole record's fit, or for a long record the smoothing settled
    on its middle and the windows' blocks to come (``blocks``, a generator)."""
    from . import streaming
    from .io3d import basis_point, kinematics_from_trajectories, kinematics_params, kinematics_setup
    from .progress import ProgressPrinter

    if traj.frame.size <= streaming.WHOLE_RECORD_FRAMES:
        res = kinematics_from_trajectories(traj, static, smoothing=smoothing, events=events,
                                           noise_criterion=noise_criterion)
        tr = res["trajectory"]
        mk, hk = res["marker_kinematics"], res["hidden_kinematics"]
        parts = [mk] if hk is None else [mk, hk]
        block = streaming.KinematicsBlock(0, traj.frame.size, *(np.concatenate([getattr(k, f) for k in parts], 1)
                                                                for f in ("position", "velocity", "acceleration")),
                                          tr.omega(traj.time_s), tr.alpha(traj.time_s), tr.reason)
        return {**res, "blocks": iter([block]), "smoothing_choice": tr.smoothing_choice}
    setup = kinematics_setup(traj, static, folder=scratch)
    name, point = basis_point(setup)
    params = kinematics_params(smoothing, events, noise_criterion)
    reg, model = setup["registration"], setup["model"]
    settled = streaming.settle_smoothing(traj.time_s, reg, setup["points"], model, params,
                                         window=streaming.WINDOW_FRAMES)
    blocks = streaming.windowed_kinematics(traj.time_s, reg, setup["points"], model, setup["model_all"], params,
                                           settled=settled, progress=ProgressPrinter())
    return {**setup, "blocks": blocks, "smoothing_choice": settled.choice,
            "windows": windows_record(settled, traj.frame),
            "basis_resolution": _middle_window_resolution(traj.time_s, setup, settled, point),
            "basis_point": name}


def _middle_window_resolution(t, setup: dict, settled, body_point):
    """The ``spline_basis`` figure of a long record's windows: the window holding the record's middle frame fitted
    as the windows are and checked (:func:`horsemocap.basis_check.basis_resolution`) on ``body_point``
    (:func:`horsemocap.io3d.basis_point`) with the window's own smoothing (:func:`horsemocap.streaming.window_params`),
    its times moved back onto the record's; None for a window that cannot be fitted (its frames say why in the
    tables)."""
    from .basis_check import basis_resolution
    from .streaming import slice_registration, window_fit, window_params, window_plan

    mid = t.size // 2
    lo, hi, core_lo, core_hi = next(w for w in window_plan(t.size, settled.window, settled.margin)
                                    if w[2] <= mid < w[3])
    reg, points, model = setup["registration"], setup["points"], setup["model"]
    fit, tl, _ = window_fit(t, reg, points, model, settled, lo, hi, float(np.median(np.diff(t))))
    if fit is None:
        return None
    found = basis_resolution(fit, slice_registration(reg, lo, hi), model, body_point,
                             window_params(settled, t, lo, hi),
                             points=None if points is None else np.asarray(points[lo:hi], float),
                             span=(core_lo - lo, core_hi - lo))
    return None if found is None else found.shifted(float(t[lo]) - float(tl[0]))


def windows_record(settled, frame) -> dict:
    """``kinematics-run.json``'s ``windows``: how a long record was smoothed in windows (``settled``, a
    :class:`horsemocap.streaming.SettledSmoothing`; ``frame``: the record's frame numbers). With a settled blend
    of the fits without and with the stride's harmonics, ``lam`` is the plain route's and ``harmonic_lam`` and
    ``blend_weights`` (the harmonic route's weight per component) say the rest.

    Examples
    --------
    >>> from horsemocap.params import PoseParams
    >>> from horsemocap.streaming import SettledSmoothing
    >>> s = SettledSmoothing(PoseParams(), (1e-6,) * 6, None, None, 40, {}, window=500)
    >>> rec = windows_record(s, np.arange(10_000))
    >>> rec["count"], rec["settled_on"], "blend_weights" in rec
    (20, [3000, 6999], False)
    """
    from . import streaming

    lo, hi = streaming.representative_range(len(frame))
    out = {"count": len(streaming.window_plan(len(frame), settled.window, settled.margin)),
           "window_frames": settled.window, "margin_frames": settled.margin,
           "settled_on": [int(frame[lo]), int(frame[hi - 1])],
           "lam": list(settled.lam), "fundamental_hz": settled.fundamental_hz}
    if settled.blend is not None:
        out["harmonic_lam"] = list(settled.blend.harmonic_lam)
        out["blend_weights"] = list(settled.blend.blend_weights)
    return out


def _kinematics_verdict_lines(verdict: str, checks) -> int:
    """Print the kinematics' quality verdict and its checks with a warning or worse; the exit status."""
    bad = [c for c in checks if c["level"] in ("warning", "unreliable")]
    print(f"quality: {verdict.upper()}" + (f" ({len(bad)} check(s) with a warning or worse; see "
                                           "kinematics-run.json)" if bad else " (every plausibility check passed)"))
    for c in bad:
        print(f"  {c['level']}: {c['name']}: {c['message']}")
    if verdict == "unreliable":
        print("horsemocap: the quality verdict is UNRELIABLE (exit status 3): do not use these numbers before "
              "what the check above names is fixed", file=sys.stderr)
        return 3
    return 0


def _check_inputs_outside(target: Path, args) -> None:
    """``kinematics --out`` replaces its folder whole: refuse one that holds an input file."""
    from .store import StoreError

    for what, given in (("TRAJECTORIES", args.trajectories), ("--static", args.static)):
        path = Path(given).expanduser().resolve()
        if path == target or target in path.parents:
            raise StoreError(f"--out {args.out}: holds the input {what} {given}, and horsemocap replaces the whole "
                             "folder; choose another --out")


def _kinematics_input(traj) -> dict:
    """What ``kinematics-run.json`` and the printout say of the TRAJECTORIES file: units, rate, times, axes."""
    from .io3d import TrajectoryFileError, frame_rate

    info = traj.info
    try:
        rate = info.get("rate_hz") or frame_rate(traj)
    except TrajectoryFileError:
        rate = None
    return {"format": info.get("format"), "units": info.get("units"), "scale_to_m": info.get("scale_to_m"),
            "rate_hz": rate, "rate_from": info.get("rate_from") or ("the times (median step)" if rate is not None
                                                                    else "unknown: a single frame"),
            "frames": [int(traj.frame[0]), int(traj.frame[-1])], "n_frames": int(traj.frame.size),
            "time_s": [float(traj.time_s[0]), float(traj.time_s[-1])], "time_origin": info.get("time_origin"),
            "axes": "the input file's axes; omega in those axes"}


def _kinematics_notes(traj, static, res, source) -> list:
    """Lines printed by ``kinematics``: the input's time range, loose name matches, points not used."""
    rate = "unknown" if source["rate_hz"] is None else f"{source['rate_hz']:.6g} Hz"
    notes = [f"{traj.source}: {source['n_frames']} frames {source['frames'][0]}..{source['frames'][1]}, time "
             f"{source['time_s'][0]:.6g} .. {source['time_s'][1]:.6g} s (origin: {source['time_origin']}), "
             f"{rate}, units {source['units']}"]
    for t_name, s_name in res["matched_loosely"]:
        notes.append(f"point {t_name!r} matched to the static shot's {s_name!r} (subject prefix / case ignored)")
    if res["unmatched"]:
        notes.append(f"points not in the static shot {static.source}, not used: {res['unmatched']}")
    return notes


def _kinematics_record(args, events, res, files, input_summary) -> dict:
    """``kinematics-run.json``: what made the folder (it marks an earlier kinematics run's output)."""
    import hashlib

    from . import __version__
    from .runfolder import KINEMATICS_FORMAT

    def source(given):
        path = Path(given).expanduser().resolve()
        digest = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):       # in blocks, not the whole file at once
                digest.update(block)
        return {"path": str(path), "sha256": digest.hexdigest()}

    return {"format": KINEMATICS_FORMAT, "command": "kinematics", "horsemocap_version": __version__,
            "inputs": {"trajectories": source(args.trajectories), "static": source(args.static)},
            "options": {"smoothing": args.smoothing, "events": events, "noise_criterion": args.noise_criterion},
            "smoothing_ran": res["smoothing_choice"] or None, "windows": res.get("windows"),
            "markers": list(res["markers"]), "hidden": list(res["hidden"]),
            "unmatched": list(res["unmatched"]), "matched_loosely": res["matched_loosely"],
            "input": input_summary, "files": files}


def _write_kinematics_tables(folder: Path, traj, res) -> tuple:
    """trajectories.csv, kinematics.csv and angular.csv of a kinematics run, written block by block
    (``res["blocks"]``); the 99th percentiles of the markers' smoothed speed and acceleration for the
    checks, taken block by block (:class:`horsemocap.io3d.RunningPercentile`: nothing per frame kept).

    Written with the csv module: a point name holding a comma or a quote is quoted.
    """
    import csv

    from .io3d import RunningPercentile
    from .store import StreamedTextFiles

    names = res["markers"] + res["hidden"]
    n, k = traj.frame.size, len(res["markers"])
    speed, accel = RunningPercentile(99, n * k), RunningPercentile(99, n * k)
    with StreamedTextFiles([folder / name for name in KINEMATICS_TABLES]) as files:
        pos_w, kin_w, ang_w = (csv.writer(fh, lineterminator="\n") for fh in files)
        pos_w.writerow(["frame", "time_s", "point", "x_m", "y_m", "z_m"])
        kin_w.writerow(["frame", "time_s", "point", "vx_mps", "vy_mps", "vz_mps", "ax_mps2", "ay_mps2", "az_mps2"])
        ang_w.writerow(["frame", "time_s", "wx_radps", "wy_radps", "wz_radps", "alphax_radps2", "alphay_radps2",
                        "alphaz_radps2", "triangle_height_m", "registration_rms_m", "note"])
        for block in res["blocks"]:
            _write_block(files, traj, names, res["registration"], block)
            speed.add(np.linalg.norm(block.velocity[:, :k], axis=2))
            accel.add(np.linalg.norm(block.acceleration[:, :k], axis=2))
    return speed.value(), accel.value()


def _write_block(files, traj, names, reg, block) -> None:
    """The rows of the frames of one :class:`horsemocap.streaming.KinematicsBlock`
    (:func:`horsemocap.io3d.kinematics_block_text`)."""
    from .io3d import kinematics_block_text

    a, b = block.start, block.stop
    height = np.where(reg.n_markers[a:b] >= 3, reg.height[a:b], np.nan)
    for fh, text in zip(files, kinematics_block_text(traj.frame[a:b], traj.time_s[a:b], names, block, height,
                                                     reg.rms[a:b])):
        fh.write(text)


def cmd_export(args) -> int:
    """trajectories.csv -> TRC or C3D (first frame number kept; ``--rate`` for a one-frame file)."""
    from .io3d import TrajectoryFileError, check_stated_rate, read_trajectories_csv, write_c3d, write_trc

    _no_nul(("trajectories.csv", args.trajectories), ("--out", args.out))
    out = Path(args.out)
    writers = {".trc": write_trc, ".c3d": write_c3d}
    if out.suffix.lower() not in writers:
        print(f"horsemocap: error: --out {out}: expected a .trc or .c3d file name", file=sys.stderr)
        return 2
    try:
        traj = read_trajectories_csv(args.trajectories)
        if args.rate is not None:
            check_stated_rate(traj, args.rate)
        writers[out.suffix.lower()](out, traj, rate=args.rate)
    except TrajectoryFileError as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        return 2
    print(f"written: {out.resolve()}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the traceback of an error instead of a one-line message")
    parser = argparse.ArgumentParser(prog="horsemocap", description=DESCRIPTION, epilog=EXIT_STATUS,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error instead of a one-line message")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("analyze", help="analyse a riding session (every step, automatic choices)",
                       parents=[common], epilog=EXIT_STATUS, formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Run every step on SESSION and write the result files of the session "
                                   "contract (trajectories.csv, kinematics.csv, angular.csv, comfort.csv, "
                                   "comfort.xlsx, markers_2d.csv, markers_3d.csv, rig.toml, calibration.json, "
                                   "analysis.json, quality.json, report.html; passes.csv for a long recording) into "
                                   "DIR. DIR is replaced whole when the run ends (it must be new, empty or an "
                                   "earlier run's results); a second run into the same DIR while one is running "
                                   "stops at once.")
    p.add_argument("session", metavar="SESSION", help="session folder holding session.json")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (outside the session)")
    p.add_argument("--params", metavar="analysis.json",
                   help="repeat a run exactly: the parameters recorded in an earlier analysis.json, or the "
                        "choices made in the notebooks (choices.json in the notebooks' results folder)")
    p.add_argument("--no-report", action="store_true", help="do not write report.html (faster batch runs)")
    _add_choice_options(p)
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser("demo", help="analyse the bundled riding session (Horse 2, canter)",
                       parents=[common], epilog=EXIT_STATUS, formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Analyse data_samples/horse2_canter and print where the results are.")
    p.add_argument("--out", default="horsemocap-demo", metavar="DIR",
                   help="results folder (default: ./horsemocap-demo)")
    p.add_argument("--params", metavar="analysis.json", help="parameters of an earlier run")
    _add_choice_options(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("calibrate", help="calibrate cameras from checkerboard views into rig.toml",
                       parents=[common], description="One folder of checkerboard views per camera (the same file name in "
                                   "each folder is the same instant); the folder name is the camera name "
                                   "and the first folder is the reference camera. Prints the tables of "
                                   "thesis 8.1-8.4 and writes the rig.")
    p.add_argument("camera_dirs", nargs="+", metavar="CAMERA_DIR")
    p.add_argument("--board", required=True, metavar="COLSxROWS", help="inner corners, e.g. 9x6")
    p.add_argument("--square", required=True, type=float, metavar="METRES", help="square size, e.g. 0.03")
    p.add_argument("--out", required=True, metavar="rig.toml",
                   help="the rig file to write (a session's calibration 'rig'); not a folder")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("batch", help="analyse many sessions side by side into one table (resumable)",
                       parents=[common], epilog=EXIT_STATUS, formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Analyse every SESSION exactly as 'analyze' would, into DIR/<name>/, on every "
                                   "local core (worker processes) or on a Dask cluster (--scheduler), and write "
                                   "DIR/sessions.csv (and sessions.parquet where pyarrow is installed): one row per "
                                   "session with its metadata, verdict, exit status, comfort indicators, time and "
                                   "error. A failing session is a row, not the end of the batch. Run again, a "
                                   "batch analyses only the sessions whose results are missing, incomplete or made "
                                   "from other inputs, parameters or code. Exit status: the worst session's.")
    p.add_argument("sessions", nargs="+", metavar="SESSION",
                   help="a session folder, a folder of session folders, or a text file listing session folders "
                        "(one per line, relative to the file)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder of the results and the table")
    p.add_argument("--workers", type=int, metavar="N", help="local worker processes (default: every core)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on the Dask cluster of this scheduler (e.g. tcp://127.0.0.1:8786); needs "
                        "pip install horsemocap[cluster]")
    p.add_argument("--params", metavar="analysis.json", help="parameters for every session (as analyze --params)")
    p.set_defaults(func=cmd_batch)

    p = sub.add_parser("kinematics", help="rigid-body kinematics from 3D markers of any system (CSV or C3D)", parents=[common],
                       description="Pose-trajectory kinematics (horsemocap.pose) of 3D markers in the "
                                   "trajectories.csv layout or a C3D file (units from POINT:UNITS), with a "
                                   "static shot (same formats) whose extra points are the hidden points. "
                                   "Writes trajectories.csv, kinematics.csv and angular.csv in the file's frame. "
                                   "Give UNFILTERED markers: the smoothing is chosen from the data's own noise, "
                                   "its correlation over frames measured from the markers' rigidity residual "
                                   "(a Butterworth 8 Hz pre-filter took the demo's saddle acceleration "
                                   "error from 2.4 % to 36 % in a QA measurement). Names: exact first, then, where unambiguous, "
                                   "without a subject prefix (Horse:m1) and case. C3D times: (1-based frame - 1) "
                                   "/ POINT:RATE, or HORSEMOCAP:FIRST_TIME when the file has it (horsemocap export "
                                   "writes it).")
    p.add_argument("trajectories", metavar="TRAJECTORIES", help="trajectories.csv layout or .c3d")
    p.add_argument("--static", required=True, metavar="STATIC", help="static shot (.csv or .c3d)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder of the results (trajectories.csv, kinematics.csv, angular.csv, kinematics-run.json); "
                        "it must be new, empty or an earlier kinematics run's output, and is replaced whole")
    p.add_argument("--smoothing", default="auto", choices=["auto", "gcv", "adaptive", "none"],
                   help="pose smoothing: auto (default: gcv with the stride harmonics on a periodic record, "
                        "adaptive on a non-periodic one; under correlated noise the choice of --noise-criterion), "
                        "gcv, adaptive, none")
    p.add_argument("--noise-criterion", default=_POSE_FIELDS["correlated_noise_criterion"].default,
                   choices=_POSE_FIELDS["correlated_noise_criterion"].metadata["choices"],
                   help="with --smoothing auto, when the markers' rigidity residual shows noise correlated over "
                        "frames: loo (default; four or more markers: each left out in turn and predicted from the "
                        "others' pose, three: as gcv), gcv (GCV with the noise's AR(1) correlation), reml or risk "
                        "(analyze's rigid_body.pose.correlated_noise_criterion)")
    p.add_argument("--events", "--pose-events", dest="events", action="append", metavar="SECONDS",
                   help="(--pose-events: the same option, analyze's name) "
                        "known times (s, the file's time axis: see the time range the command prints) where "
                        "the acceleration may jump, such as an "
                        "impact's onset timed by a force plate; 2.8,3.35 (or the option repeated). The smoothing lets the "
                        "acceleration jump there instead of rounding the jump off and ringing around it (gcv or "
                        "adaptive smoothing; the record is then smoothed without stride harmonics). The times "
                        "are not found from the data: give them to the frame. Measured effect: "
                        "benchmarks/README.md (change points)")
    p.set_defaults(func=cmd_kinematics)

    p = sub.add_parser("export", help="export trajectories.csv as TRC (OpenSim) or C3D (Mokka, Visual3D)", parents=[common],
                       description="Convert a trajectories.csv to OUT.trc or OUT.c3d (millimetres). Every "
                                   "frame number from the first to the last is written (missing ones empty / "
                                   "gaps); horsemocap frame k is the file's 1-based frame k+1 (C3D header, TRC "
                                   "Frame# and OrigDataStartFrame); the C3D keeps the exact time of the first "
                                   "frame and the rate in the parameters HORSEMOCAP:FIRST_TIME (s) and "
                                   "HORSEMOCAP:RATE (Hz), read back by horsemocap kinematics.")
    p.add_argument("trajectories", metavar="trajectories.csv")
    p.add_argument("--out", required=True, metavar="OUT.trc|OUT.c3d",
                   help="the file to write; its extension chooses the format (.trc or .c3d)")
    p.add_argument("--rate", type=float, metavar="HZ",
                   help="frame rate written into the file (default: from the time_s column; needed for a "
                        "one-frame file)")
    p.set_defaults(func=cmd_export)
    return parser


def _no_nul(*named) -> None:
    from .store import StoreError

    for what, value in named:
        if value is not None and "\0" in str(value):
            raise StoreError(f"{what} {str(value)!r}: a path cannot hold a NUL byte")


class _Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, handled like Ctrl-C."""


def _error_line(exc: BaseException) -> str:
    """:func:`horsemocap.errors.one_line` of ``exc``; that module (which names every step's errors, so loads
    the whole analysis) is imported only when an error is to be shown, so a run starts its early work
    (:func:`_run_analysis`) before the analysis' modules load."""
    from .errors import one_line

    return one_line(exc)


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning on the command line: one line ``horsemocap: warning: ...`` (``--debug``: Python's format,
    with the code's file and line)."""
    kind = "" if issubclass(category, UserWarning) else f"{category.__name__}: "
    text = str(message).replace("\n", " ")
    print(f"horsemocap: warning: {kind}{text}", file=sys.stderr if file is None else file)


def main(argv=None) -> int:
    """The ``horsemocap`` command. Every failure ends with one line on stderr and
    exit status 2 (``--debug``: the traceback too); Ctrl-C and SIGTERM leave the
    results folder as it was before the run; 3 = results written, verdict unreliable.

    ``argv`` None: the command line of the process, which ends when this
    returns (the garbage collector runs every :data:`COMMAND_GC_ALLOCATIONS`
    allocations, and at the end the objects are exempted from it:
    :func:`gc.freeze`); a list: a call from Python, which leaves the collector
    as it was."""
    import signal
    import traceback

    program = argv is None       # the command itself (not a call from Python): the process ends with it
    if program:
        gc.set_threshold(max(COMMAND_GC_ALLOCATIONS, gc.get_threshold()[0]), *gc.get_threshold()[1:])
        # FFmpeg's own log lines ("[mjpeg @ 0x...] overread 4") would come before the one line that names a
        # broken video: quiet unless the user sets the variable (read at the process's first video opened)
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)  # a bad option: argparse's usage line, exit status 2
    debug = bool(getattr(args, "debug", False))

    def terminate(signum, frame):
        raise _Terminated()

    previous = {}
    for sig in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)):
        if sig is not None:
            try:
                previous[sig] = signal.signal(sig, terminate)
            except ValueError:  # not the main thread
                pass
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.showwarning = _warning_line
            return args.func(args)
    except KeyboardInterrupt as exc:
        if debug:
            traceback.print_exc()
        what = "terminated" if isinstance(exc, _Terminated) else "interrupted (Ctrl-C)"
        print(f"horsemocap: {what}: nothing was written; the results folder is as it was before the run",
              file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the one place that turns errors into messages
        if debug:
            traceback.print_exc()
        print(f"horsemocap: error: {_error_line(exc)}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if program:
            # every file is written and closed: the interpreter's garbage collections at exit would only walk
            # the loaded modules' objects, which are freed with the process
            gc.freeze()


if __name__ == "__main__":
    sys.exit(main())
