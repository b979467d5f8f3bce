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

DESCRIPTION = """\
horsemocap: saddle motion analysis of horses with a 3-camera vision system
(a reproduction of G. Dogan, METU 2009). Every step chooses its parameters
automatically; any choice can be given in a parameter file or on the line."""


def _add_choice_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("analysis choices (default: automatic, as recorded in analysis.json)")
    g.add_argument("--offsets", metavar="CAM=FRAME,...",
                   help="sync offsets instead of the flashlight, e.g. left=0,middle=53,right=126")
    g.add_argument("--recalibrate", action="store_true", default=None,
                   help="calibrate from the session's checkerboard views even if it has a rig")
    g.add_argument("--threshold", type=int, metavar="LEVEL",
                   help="gray-level threshold for every camera (thesis eq. 4.5; default Otsu-based)")
    g.add_argument("--triangulation", choices=["joint", "thesis"],
                   help="joint: all cameras at once (default); thesis: three pairs averaged (eq. 5.5)")
    g.add_argument("--span", type=float, dest="smoothing_span", metavar="FRACTION",
                   help="rloess span as a fraction of the points (thesis 0.1)")
    g.add_argument("--period", type=float, dest="period_frames", metavar="FRAMES",
                   help="motion period in frames (thesis typed 18; default estimated)")
    g.add_argument("--x-marker", type=int, dest="x_marker", metavar="INDEX",
                   help="marker (0-based) whose net displacement defines x-motion")
    g.add_argument("--fourier-orders", metavar="Y,Z",
                   help="Fourier orders of the y and z fits (default: order rule of 5.5.2.2)")
    g.add_argument("--smoothing", choices=["none", "rloess", "loess", "lowess", "rlowess", "moving"],
                   dest="smoothing_method", help="smoothing of the 3D positions (thesis: rloess)")
    g.add_argument("--angular", choices=["rotation", "lstsq", "thesis"], dest="angular_method",
                   help="omega/alpha from the fitted orientation (default), least squares over all "
                        "markers, or the average of the thesis versions")
    g.add_argument("--saddle", choices=["pose", "direct", "thesis"], dest="saddle_method",
                   help="saddle velocity/acceleration from the fitted pose (default), the fitted eq. 6.48 "
                        "path, or the thesis' eq. 6.54/6.55")
    g.add_argument("--kinematics", choices=["fits", "pose_spline"],
                   help="fits: the thesis' chain of fits (default); pose_spline: the smoothed pose "
                        "trajectory of all markers (no period, no eq. 6.35 singularity)")
    g.add_argument("--motion-frame", choices=["auto", "period", "record"], dest="motion_frame",
                   help="x-motion from one or two periods (thesis), from the whole record's net "
                        "displacement (no period needed), or auto (default: period if one is found)")
    g.add_argument("--weighting", choices=["iso", "thesis"], dest="weighting_mode",
                   help="iso: each harmonic weighted at its frequency (default); thesis: one scalar W")


def _params_from_args(args, base):
    changes = {k: getattr(args, k, None) for k in
               ("recalibrate", "triangulation", "smoothing_span", "smoothing_method", "period_frames",
                "x_marker", "angular_method", "saddle_method", "weighting_mode", "kinematics",
                "motion_frame")}
    if args.offsets:
        try:
            changes["sync_offsets"] = {k: int(v) for k, v in (kv.split("=") for kv in args.offsets.split(","))}
        except ValueError:
            raise SystemExit(f"--offsets: expected CAM=FRAME,..., got {args.offsets!r}")
    if args.fourier_orders:
        try:
            y, z = (int(v) for v in args.fourier_orders.split(","))
        except ValueError:
            raise SystemExit(f"--fourier-orders: expected Y,Z (two integers), got {args.fourier_orders!r}")
        changes["fourier_orders"] = {"y": y, "z": z}
    if args.threshold is not None:
        det = dict(base.detection)
        det["all"] = {**det.get("all", {}), "threshold": args.threshold}
        changes["detection"] = det
    return base.updated(**changes)


def _run_analysis(session_dir: Path, out_dir: Path, args) -> int:
    from .params import AnalysisParams, ParamsError, load_params
    from .pipeline import AnalysisError, analyze, resolve_params
    from .session import SessionError, load_session
    from .store import StoreError

    try:
        session = load_session(session_dir)
        base = load_params(args.params) if args.params else resolve_params(session)
        params = _params_from_args(args, base)
        analysis = analyze(session_dir, out_dir, params)
    except (SessionError, AnalysisError, ParamsError, StoreError) as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        if out_dir.exists():
            print(f"horsemocap: the results of the steps before it are in {out_dir}", file=sys.stderr)
        return 2
    report = None
    try:
        from .report import write_report
        report = write_report(out_dir / "report.html", analysis)
    except ImportError:
        pass
    ind = analysis.results.get("comfort", {}).get("indicators")
    print(f"results: {out_dir.resolve()}")
    if report:
        print(f"report:  {Path(report).resolve()}")
    if ind:
        print(f"comfort: Wk-weighted rms {ind['acc_y_Wk_rms']:.3f} m/s^2, VDV {ind['VDV_y_Wk']:.3f} m/s^1.75, "
              f"8-h action value reached in {ind['TA_8_action_Wk']:.3f} h at {ind['vel_x_avg']:.1f} km/h")
    return 0


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


def cmd_calibrate(args) -> int:
    from .calibration import calibrate_command

    try:
        text = calibrate_command([Path(d) for d in args.camera_dirs], args.board, args.square, Path(args.out))
    except (ValueError, FileNotFoundError) as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        return 2
    print(text)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="horsemocap", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("analyze", help="analyse a riding session (every step, automatic choices)",
                       description="Run every step on SESSION and write the result files of the session "
                                   "contract (trajectories.csv, kinematics.csv, angular.csv, comfort.csv, "
                                   "markers_2d.csv, rig.toml, analysis.json, report.html) into DIR.")
    p.add_argument("session", metavar="SESSION", help="session folder holding session.json")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (outside the session)")
    p.add_argument("--params", metavar="analysis.json",
                   help="repeat a run exactly: the parameters recorded in an earlier analysis.json")
    _add_choice_options(p)
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser("demo", help="analyse the bundled riding session (Horse 2, canter)",
                       description="Analyse data_samples/horse2_canter and print where the results are.")
    p.add_argument("--out", default="horsemocap-demo", metavar="DIR",
                   help="results folder (default: ./horsemocap-demo)")
    p.add_argument("--params", metavar="analysis.json", help="parameters of an earlier run")
    _add_choice_options(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("calibrate", help="calibrate cameras from checkerboard views into rig.toml",
                       description="One folder of checkerboard views per camera (the same file name in "
                                   "each folder is the same instant); the folder name is the camera name "
                                   "and the first folder is the reference camera. Prints the tables of "
                                   "thesis 8.1-8.4 and writes the rig.")
    p.add_argument("camera_dirs", nargs="+", metavar="CAMERA_DIR")
    p.add_argument("--board", required=True, metavar="COLSxROWS", help="inner corners, e.g. 9x6")
    p.add_argument("--square", required=True, type=float, metavar="METRES", help="square size, e.g. 0.03")
    p.add_argument("--out", required=True, metavar="rig.toml")
    p.set_defaults(func=cmd_calibrate)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
