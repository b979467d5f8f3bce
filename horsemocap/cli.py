"""The ``horsemocap`` command line.

``horsemocap analyze SESSION --out DIR``  every step of the thesis, automatically
``horsemocap demo [--out DIR]``           the same on the bundled riding session
``horsemocap calibrate DIR [DIR ...]``    calibrate a rig once for many sessions
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

DESCRIPTION = """\
horsemocap: saddle motion analysis of horses with a 3-camera vision system
(a reproduction of G. Dogan, METU 2009). Every step chooses its parameters
automatically; any choice can be given in a parameter file or on the line."""


def _add_choice_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("analysis choices (default: automatic, as recorded in analysis.json)")
    g.add_argument("--preset", choices=["default", "thesis"],
                   help="a named set of choices; thesis: the thesis' own chain end to end (pairwise "
                        "calibration, per-camera detection, pairs triangulation, rloess 0.1, the E/2 order, "
                        "the averaged versions, one scalar weight); the options below still override it")
    g.add_argument("--offsets", metavar="CAM=FRAME,...",
                   help="sync offsets instead of the flashlight, e.g. left=0,middle=53,right=126")
    g.add_argument("--recalibrate", action="store_true", default=None,
                   help="calibrate from the session's checkerboard views even if it has a rig")
    g.add_argument("--threshold", type=int, metavar="LEVEL",
                   help="gray-level threshold for every camera (thesis eq. 4.5; default Otsu-based)")
    g.add_argument("--first-frame", type=int, dest="first_frame", metavar="FRAME",
                   help="frame (0-based, synchronised) in which the markers are picked for every camera "
                        "(Appendix A step 4; default found automatically)")
    g.add_argument("--exclude-views", dest="exclude_views", metavar="CAM=VIEW[+VIEW],...",
                   help="checkerboard views left out of the calibration, e.g. left=view03.png+view07.png,"
                        "right=view03.png")
    g.add_argument("--plumb-threshold", type=int, dest="plumb_threshold", metavar="LEVEL",
                   help="gray-level threshold of the plumb stills, every camera (Appendix A 7a)")
    g.add_argument("--static-threshold", type=int, dest="static_threshold", metavar="LEVEL",
                   help="gray-level threshold of the static-shot stills, every camera (Appendix A 8a, 12a)")
    g.add_argument("--saddle-marker", type=int, dest="saddle_marker", metavar="INDEX",
                   help="which static-shot point (0-based, left to right in the reference camera) is the "
                        "saddle marker (Appendix A 12a; default: the one the ride's markers leave over)")
    g.add_argument("--detection", choices=["multiview", "thesis"], dest="detection_method",
                   help="multiview: markers identified by all cameras together and followed in 3D "
                        "(default); thesis: each camera alone with the filters of chapter 4")
    g.add_argument("--max-gap", type=int, dest="max_gap_frames", metavar="FRAMES",
                   help="longest gap of a marker's 3D position bridged by interpolation "
                        "(default 0.1 s of frames, at least 2; 0: none)")
    g.add_argument("--triangulation", choices=["joint", "thesis"],
                   help="joint: all cameras at once (default); thesis: three pairs averaged (eq. 5.5)")
    g.add_argument("--span", type=float, dest="smoothing_span", metavar="FRACTION",
                   help="smoothing span of the 3D positions as a fraction of the points (default 0.1, the "
                        "thesis' value)")
    g.add_argument("--period", type=float, dest="period_frames", metavar="FRAMES",
                   help="motion period in frames (thesis typed 18; default estimated)")
    g.add_argument("--x-marker", type=int, dest="x_marker", metavar="INDEX",
                   help="marker (0-based) whose net displacement defines x-motion (default 0)")
    g.add_argument("--x-degree", type=int, dest="x_degree", metavar="N",
                   help="degree of the polynomial fitted to the x-motion (Appendix A 9.i, fit_type_x; thesis "
                        "poly1: 1)")
    g.add_argument("--fourier-orders", metavar="Y,Z",
                   help="Fourier orders of the y and z fits (default: order rule of 5.5.2.2)")
    g.add_argument("--smoothing", choices=["none", "rloess", "loess", "lowess", "rlowess", "moving"],
                   dest="smoothing_method", help="smoothing of the 3D positions (default loess; thesis: rloess)")
    g.add_argument("--angular", choices=["rotation", "lstsq", "thesis"], dest="angular_method",
                   help="omega/alpha from the fitted orientation (default), least squares over all "
                        "markers, or the average of the thesis versions")
    g.add_argument("--omega-versions", dest="omega_versions", metavar="N,N,...",
                   help="with --angular thesis: which of the six thesis versions of omega (1-6, eq. 6.3/6.4) "
                        "are averaged, e.g. 1,2,4 (default all)")
    g.add_argument("--alpha-versions", dest="alpha_versions", metavar="N,N,...",
                   help="with --angular thesis: which of the six versions of alpha (1-6, eq. 6.38/6.39) are "
                        "averaged (default all)")
    g.add_argument("--saddle", choices=["pose", "direct", "thesis"], dest="saddle_method",
                   help="saddle velocity/acceleration from the fitted pose (default), the fitted eq. 6.48 "
                        "path, or the thesis' eq. 6.54/6.55")
    g.add_argument("--kinematics", choices=["fits", "pose_spline"],
                   help="pose_spline: the smoothed pose trajectory of all markers (default; no period, "
                        "no eq. 6.35 singularity); fits: the thesis' chain of fits")
    g.add_argument("--pose-harmonics", choices=["auto", "all", "none"], dest="pose_harmonics",
                   help="with pose_spline: unpenalised harmonics of the stride (frequency found in the record) "
                        "in the pose smoothing, their number chosen with the smoothing (none on a record that is "
                        "not periodic); auto (default): the rotation keeps a harmonic only below the plain "
                        "spline's cutoff and when it stands above the noise the registration residual and the "
                        "marker triangle predict; all: every harmonic up to 0.4 of the frame rate, rotation "
                        "too; none: plain smoothing splines")
    g.add_argument("--pose-weights", choices=["covariance", "equal"], dest="pose_weights",
                   help="with pose_spline: each marker weighted by its triangulation covariance in the pose "
                        "registration (default), or all alike (Horn, the thesis' eq. 5.14-5.21)")
    g.add_argument("--pose-rotation-weights", choices=["auto", "equal"], dest="pose_rotation_weights",
                   help="with pose_spline and covariance weights: the rotation smoothed with each frame weighted "
                        "by its predicted variance where that explains the residuals better (auto, default), "
                        "or every frame alike (equal)")
    g.add_argument("--pose-events", dest="pose_events", action="append", metavar="SECONDS",
                   help="with pose_spline: known instants (s, the time_s of trajectories.csv) where the "
                        "acceleration may jump, such as impacts timed by a force plate; 2.8,3.35 (or the option "
                        "repeated; not found from the data)")
    g.add_argument("--motion-frame", choices=["auto", "period", "record"], dest="motion_frame",
                   help="x-motion from one or two periods (thesis), from the whole record's net "
                        "displacement (no period needed), or auto (default: period if one is found)")
    g.add_argument("--weighting", choices=["iso", "thesis"], dest="weighting_mode",
                   help="iso: each harmonic weighted at its frequency (default); thesis: one scalar W")
    g.add_argument("--set", action="append", dest="set", metavar="NAME=VALUE",
                   help="any parameter by its (dotted) name, the value in JSON, applied after the options "
                        "above; repeatable. Every prompt of one camera, e.g. --set detection.left.labels=[3,4,5] "
                        "--set detection.left.first_frame=36 --set detection.all.area_min=5 "
                        "--set detection.right.window=[180,140] --set detection.middle.distance_tolerance=0.2 "
                        "--set stills.static.left.threshold=150 (names as in analysis.json and choices.json)")


def _params_from_args(args, base):
    from .params import ParamsError

    if getattr(args, "preset", None):
        base = base.with_preset(args.preset)
    changes = {k: getattr(args, k, None) for k in
               ("recalibrate", "detection_method", "max_gap_frames", "triangulation", "smoothing_span",
                "smoothing_method", "period_frames", "x_marker", "angular_method", "saddle_method", "weighting_mode",
                "kinematics", "pose_harmonics", "pose_weights", "pose_rotation_weights", "motion_frame",
                "x_degree")}
    if args.offsets:
        try:
            changes["sync_offsets"] = {k: int(v) for k, v in (kv.split("=") for kv in args.offsets.split(","))}
        except ValueError:
            raise ParamsError(f"--offsets: expected CAM=FRAME,... (frame indices), got {args.offsets!r}") from None
    if args.fourier_orders:
        try:
            y, z = (int(v) for v in args.fourier_orders.split(","))
        except ValueError:
            raise ParamsError(f"--fourier-orders: expected Y,Z (two integers), got {args.fourier_orders!r}") from None
        changes["fourier_orders"] = {"y": y, "z": z}
    det = dict(base.detection)
    for name, key in (("threshold", "threshold"), ("first_frame", "first_frame")):
        if getattr(args, name, None) is not None:
            det["all"] = {**det.get("all", {}), key: getattr(args, name)}
            changes["detection"] = det
    if getattr(args, "exclude_views", None):
        try:
            pairs = [kv.split("=", 1) for kv in args.exclude_views.split(",")]
            changes["calibration_exclude"] = {c.strip(): [v for v in views.split("+") if v]
                                              for c, views in pairs}
        except ValueError:
            raise ParamsError(f"--exclude-views: expected CAM=VIEW[+VIEW],..., got {args.exclude_views!r}") from None
    stills = {k: dict(v) for k, v in base.stills.items()}
    for kind in ("plumb", "static"):
        level = getattr(args, f"{kind}_threshold", None)
        if level is not None:
            stills[kind] = {**stills.get(kind, {}), "all": {**stills.get(kind, {}).get("all", {}), "threshold": level}}
            changes["stills"] = stills
    changes["saddle_marker"] = getattr(args, "saddle_marker", None)
    for name in ("omega_versions", "alpha_versions"):
        text = getattr(args, name, None)
        if text:
            try:
                picked = {int(v) for v in text.split(",")}
            except ValueError:
                picked = set()
            if not picked or not picked <= set(range(1, 7)):
                raise ParamsError(f"--{name.replace('_', '-')}: expected version numbers 1-6 separated by commas, "
                                  f"got {text!r}")
            changes[name] = [k in picked for k in range(1, 7)]
    if getattr(args, "pose_events", None):
        changes["pose_events"] = parse_seconds(args.pose_events, "--pose-events")
    params = base.updated(**changes)
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
    from .params import ParamsError

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
    """``--set NAME=VALUE``: one parameter by its dotted name (JSON value, else the text as a string)."""
    from .params import AnalysisParams, ParamsError

    name, sep, text = item.partition("=")
    keys = name.strip().split(".")
    if not sep or not all(keys):
        raise ParamsError(f"--set: expected NAME=VALUE such as detection.left.threshold=140, got {item!r}")
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        value = text
    data = params.to_dict()
    if keys[0] not in data:
        AnalysisParams.from_dict({keys[0]: value}, f"--set {item}")   # names the unknown parameter
    node = data
    for k in keys[:-1]:
        if not isinstance(node.get(k), dict):
            if k in node and node[k] is not None:
                raise ParamsError(f"--set {item}: parameter '{k}' is not an object of named values")
            node[k] = {}
        node = node[k]
    node[keys[-1]] = value
    return AnalysisParams.from_dict(data, f"--set {item}")


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
    from .session import load_session

    _no_nul(("SESSION", str(session_dir)), ("--out", str(out_dir)), ("--params", args.params))
    session = load_session(session_dir)
    board_views = _early_board_detection(session, out_dir, args)
    try:
        return _analyse_session(session, session_dir, out_dir, args, board_views)
    finally:
        if board_views is not None:
            board_views.close()


def _analyse_session(session, session_dir: Path, out_dir: Path, args, board_views) -> int:
    from .params import read_params
    from .pipeline import resolve_params
    from .run import run_analysis

    # a parameter file gives overrides on top of the session's own 'analysis' object: an earlier
    # run's analysis.json (every parameter) or a notebooks' choices.json (only the choices made)
    base = resolve_params(session, read_params(args.params)) if args.params else resolve_params(session)
    params = _params_from_args(args, base)
    params.check_session(session, f"{args.params}" if args.params else "parameters")
    outcome = run_analysis(session_dir, out_dir, params, report=not getattr(args, "no_report", False),
                           board_views=board_views)
    if outcome.error is not None:
        if getattr(args, "debug", False):   # the step's own exception, with the error it was raised from
            import traceback

            traceback.print_exception(outcome.error)
        print(f"horsemocap: error: {_one_line(outcome.error)}", file=sys.stderr)
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
    ind = outcome.analysis.results.get("comfort", {}).get("indicators")
    if ind:
        print(f"comfort [quality {outcome.verdict}]: Wk-weighted rms {ind['acc_y_Wk_rms']:.3f} m/s², "
              f"VDV {ind['VDV_y_Wk']:.3f} m/s^1.75, 8-h action value reached in {ind['TA_8_action_Wk']:.3f} h "
              f"at {ind['vel_x_avg']:.1f} km/h (vertical axis, the thesis)"
              + (f"; by the EU Directive's three axes in {ind['TA_8_action_directive']:.3f} h"
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
    whole when the files are written.
    """
    from .io3d import TrajectoryFileError, kinematics_from_trajectories, read_trajectories
    from .pose import CollinearMarkersError, conditioning_warnings
    from .runfolder import RunFolder
    from .store import atomic_write_json, atomic_write_text

    _no_nul(("TRAJECTORIES", args.trajectories), ("--static", args.static))
    folder = RunFolder(args.out, "kinematics")        # the target checked here, before the computation
    target = folder.out
    _check_inputs_outside(target, args)
    try:
        traj = read_trajectories(args.trajectories)
        static = read_trajectories(args.static)
        events = parse_seconds(args.events, "--events") if args.events else None
        res = kinematics_from_trajectories(traj, static, smoothing=args.smoothing, events=events)
    except (TrajectoryFileError, CollinearMarkersError, ValueError) as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        return 2
    tables = _kinematics_tables(traj, res)
    tr, reg = res["trajectory"], res["registration"]
    source = _kinematics_input(traj)
    with folder as tmp:
        for name, text in tables.items():
            atomic_write_text(tmp / name, text)
        atomic_write_json(tmp / "kinematics-run.json", _kinematics_record(args, events, res, list(tables), source))
        folder.commit()
    for msg in _kinematics_notes(traj, static, res, source):
        print(f"[horsemocap] kinematics: {msg}", file=sys.stderr)
    for msg in conditioning_warnings(reg):
        print(f"[horsemocap] kinematics: WARNING: {msg}", file=sys.stderr)
    print(f"[horsemocap] kinematics: {len(res['markers'])} markers {res['markers']}, hidden points "
          f"{res['hidden']}; marker noise from the registration {1000 * reg.noise_m:.3f} mm", file=sys.stderr)
    ran = tr.smoothing_choice
    if ran:
        print(f"[horsemocap] kinematics: {ran['method']} smoothing ({args.smoothing}: {ran['reason']})",
              file=sys.stderr)
    print(f"results: {target}")
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
        return {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}

    return {"format": KINEMATICS_FORMAT, "command": "kinematics", "horsemocap_version": __version__,
            "inputs": {"trajectories": source(args.trajectories), "static": source(args.static)},
            "options": {"smoothing": args.smoothing, "events": events},
            "smoothing_ran": res["trajectory"].smoothing_choice or None,
            "markers": list(res["markers"]), "hidden": list(res["hidden"]),
            "unmatched": list(res["unmatched"]), "matched_loosely": res["matched_loosely"],
            "input": input_summary, "files": files}


def _kinematics_tables(traj, res) -> dict:
    """File name -> text of trajectories.csv, kinematics.csv and angular.csv of a kinematics run.

    Written with the csv module: a point name holding a comma or a quote is quoted.
    """
    tr, t = res["trajectory"], traj.time_s
    names = res["markers"] + res["hidden"]
    mk, hk = res["marker_kinematics"], res["hidden_kinematics"]
    pos = mk.position if hk is None else np.concatenate([mk.position, hk.position], 1)
    vel = mk.velocity if hk is None else np.concatenate([mk.velocity, hk.velocity], 1)
    acc = mk.acceleration if hk is None else np.concatenate([mk.acceleration, hk.acceleration], 1)

    def num(v):
        return "" if not np.isfinite(v) else f"{float(v):.9g}"

    lines = [["frame", "time_s", "point", "x_m", "y_m", "z_m"]]
    klines = [["frame", "time_s", "point", "vx_mps", "vy_mps", "vz_mps", "ax_mps2", "ay_mps2", "az_mps2"]]
    for k in range(t.size):
        for j, nm in enumerate(names):
            lines.append([traj.frame[k], num(t[k]), nm, *(num(v) for v in pos[k, j])])
            klines.append([traj.frame[k], num(t[k]), nm, *(num(v) for v in (*vel[k, j], *acc[k, j]))])
    w, al = tr.omega(t), tr.alpha(t)
    reg = res["registration"]
    alines = [["frame", "time_s", "wx_radps", "wy_radps", "wz_radps", "alphax_radps2", "alphay_radps2",
               "alphaz_radps2", "triangle_height_m", "registration_rms_m", "note"]]
    for k in range(t.size):
        alines.append([traj.frame[k], num(t[k]), *(num(v) for v in (*w[k], *al[k])),
                       num(reg.height[k] if reg.n_markers[k] >= 3 else np.nan), num(reg.rms[k]),
                       tr.reason[k].replace(",", ";")])
    return {"trajectories.csv": _csv_text(lines), "kinematics.csv": _csv_text(klines),
            "angular.csv": _csv_text(alines)}


def _csv_text(rows) -> str:
    """Rows -> CSV text (csv module, ``\\n`` line ends, fields quoted only where needed)."""
    import csv
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def cmd_export(args) -> int:
    """trajectories.csv -> TRC or C3D (first frame number kept; ``--rate`` for a one-frame file)."""
    from .io3d import TrajectoryFileError, read_trajectories_csv, write_c3d, write_trc

    _no_nul(("trajectories.csv", args.trajectories), ("--out", args.out))
    out = Path(args.out)
    writers = {".trc": write_trc, ".c3d": write_c3d}
    if out.suffix.lower() not in writers:
        print(f"horsemocap: error: --out {out}: expected a .trc or .c3d file name", file=sys.stderr)
        return 2
    try:
        traj = read_trajectories_csv(args.trajectories)
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
                                   "markers_2d.csv, rig.toml, analysis.json, quality.json, report.html) into DIR. "
                                   "DIR is replaced whole when the run ends (it must be new, empty or an earlier "
                                   "run's results); a second run into the same DIR stops at once.")
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

    p = sub.add_parser("kinematics", help="rigid-body kinematics from 3D markers of any system (CSV or C3D)", parents=[common],
                       description="Pose-trajectory kinematics (horsemocap.pose) of 3D markers in the "
                                   "trajectories.csv layout or a C3D file (units from POINT:UNITS), with a "
                                   "static shot (same formats) whose extra points are the hidden points. "
                                   "Writes trajectories.csv, kinematics.csv and angular.csv in the file's frame. "
                                   "Give UNFILTERED markers: the smoothing chosen from the data assumes white "
                                   "noise (a Butterworth 8 Hz pre-filter took the demo's saddle acceleration "
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
                        "adaptive on a non-periodic one), gcv, adaptive, none")
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


def _one_line(exc: BaseException) -> str:
    """A one-line description of an error for a person."""
    import errno

    if isinstance(exc, OSError) and exc.strerror:
        hint = {errno.ENOSPC: "the disk is full: free some space or choose another --out",
                errno.EDQUOT: "the disk quota is used up: free some space or choose another --out",
                errno.EACCES: "permission denied: choose a folder you can write to",
                errno.EPERM: "not permitted: choose a folder you can write to",
                errno.EROFS: "read-only file system: choose a folder you can write to",
                errno.ENAMETOOLONG: "the path is too long: choose a shorter --out"}.get(exc.errno, "")
        from .store import WriteError

        if isinstance(exc, WriteError):   # "cannot write FILE: text (hint)[; DIR is as it was before the run]"
            text = exc.describe(hint)
        else:
            where = f"{exc.filename}: " if exc.filename else ""
            text = f"{where}{exc.strerror}" + (f" ({hint})" if hint else "")
    else:
        from .camera import RigError
        from .params import ParamsError
        from .pipeline import AnalysisError
        from .session import SessionError
        from .sources import SourceError
        from .store import StoreError

        known = (SessionError, ParamsError, AnalysisError, StoreError, RigError, SourceError)
        try:
            from .calibration import CalibrationError
            known += (CalibrationError,)
        except ImportError:  # pragma: no cover
            pass
        text = str(exc) if isinstance(exc, known) else \
            f"{type(exc).__name__}: {exc} (an unexpected error; --debug shows where, please report it)"
        if isinstance(exc, AnalysisError) and exc.__cause__ is not None:   # a step's unexpected error
            text += " (--debug shows where)"
    return " ".join(text.split())


class _Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, handled like Ctrl-C."""


def main(argv=None) -> int:
    """The ``horsemocap`` command. Every failure ends with one line on stderr and
    exit status 2 (``--debug``: the traceback too); Ctrl-C and SIGTERM leave the
    results folder as it was before the run; 3 = results written, verdict unreliable."""
    import signal
    import traceback

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
        print(f"horsemocap: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
