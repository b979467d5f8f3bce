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


def cmd_kinematics(args) -> int:
    """3D markers from another system + a static shot -> trajectories/kinematics/angular CSV."""
    from .io3d import TrajectoryFileError, kinematics_from_trajectories, read_trajectories, write_c3d, write_trc
    from .pose import CollinearMarkersError, conditioning_warnings
    from .store import atomic_write_text

    out = Path(args.out)
    try:
        traj = read_trajectories(args.trajectories)
        static = read_trajectories(args.static)
        res = kinematics_from_trajectories(traj, static, smoothing=args.smoothing)
    except (TrajectoryFileError, CollinearMarkersError, ValueError) as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    tr, t = res["trajectory"], traj.time_s
    names = res["markers"] + res["hidden"]
    mk, hk = res["marker_kinematics"], res["hidden_kinematics"]
    pos = mk.position if hk is None else np.concatenate([mk.position, hk.position], 1)
    vel = mk.velocity if hk is None else np.concatenate([mk.velocity, hk.velocity], 1)
    acc = mk.acceleration if hk is None else np.concatenate([mk.acceleration, hk.acceleration], 1)

    def num(v):
        return "" if not np.isfinite(v) else f"{float(v):.9g}"

    lines = ["frame,time_s,point,x_m,y_m,z_m"]
    klines = ["frame,time_s,point,vx_mps,vy_mps,vz_mps,ax_mps2,ay_mps2,az_mps2"]
    for k in range(t.size):
        for j, nm in enumerate(names):
            lines.append(f"{traj.frame[k]},{num(t[k])},{nm}," + ",".join(num(v) for v in pos[k, j]))
            klines.append(f"{traj.frame[k]},{num(t[k])},{nm}," + ",".join(num(v) for v in (*vel[k, j], *acc[k, j])))
    w, al = tr.omega(t), tr.alpha(t)
    reg = res["registration"]
    alines = ["frame,time_s,wx_radps,wy_radps,wz_radps,alphax_radps2,alphay_radps2,alphaz_radps2,"
              "triangle_height_m,registration_rms_m,note"]
    for k in range(t.size):
        alines.append(f"{traj.frame[k]},{num(t[k])}," + ",".join(num(v) for v in (*w[k], *al[k]))
                      + f",{num(reg.height[k] if reg.n_markers[k] >= 3 else np.nan)},{num(reg.rms[k])},"
                      + tr.reason[k].replace(",", ";"))
    atomic_write_text(out / "trajectories.csv", "\n".join(lines) + "\n")
    atomic_write_text(out / "kinematics.csv", "\n".join(klines) + "\n")
    atomic_write_text(out / "angular.csv", "\n".join(alines) + "\n")
    for msg in conditioning_warnings(reg):
        print(f"[horsemocap] kinematics: WARNING: {msg}", file=sys.stderr)
    print(f"[horsemocap] kinematics: {len(res['markers'])} markers {res['markers']}, hidden points "
          f"{res['hidden']}; marker noise from the registration {1000 * reg.noise_m:.3f} mm", file=sys.stderr)
    print(f"results: {out.resolve()}")
    return 0


def cmd_export(args) -> int:
    """trajectories.csv -> TRC or C3D."""
    from .io3d import TrajectoryFileError, read_trajectories_csv, write_c3d, write_trc

    try:
        traj = read_trajectories_csv(args.trajectories)
    except TrajectoryFileError as exc:
        print(f"horsemocap: error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    if out.suffix.lower() == ".trc":
        write_trc(out, traj)
    elif out.suffix.lower() == ".c3d":
        write_c3d(out, traj)
    else:
        print(f"horsemocap: error: {out}: expected a .trc or .c3d file name", file=sys.stderr)
        return 2
    print(f"written: {out.resolve()}")
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

    p = sub.add_parser("kinematics", help="rigid-body kinematics from 3D markers of any system (CSV or C3D)",
                       description="Pose-trajectory kinematics (horsemocap.pose) of 3D markers in the "
                                   "trajectories.csv layout or a C3D file (units from POINT:UNITS), with a "
                                   "static shot (same formats) whose extra points are the hidden points. "
                                   "Writes trajectories.csv, kinematics.csv and angular.csv in the file's frame.")
    p.add_argument("trajectories", metavar="TRAJECTORIES", help="trajectories.csv layout or .c3d")
    p.add_argument("--static", required=True, metavar="STATIC", help="static shot (.csv or .c3d)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--smoothing", default="gcv", choices=["gcv", "adaptive", "none"],
                   help="pose smoothing: gcv (default), adaptive, none")
    p.set_defaults(func=cmd_kinematics)

    p = sub.add_parser("export", help="export trajectories.csv as TRC (OpenSim) or C3D (Mokka, Visual3D)",
                       description="Convert a trajectories.csv to OUT.trc or OUT.c3d (millimetres).")
    p.add_argument("trajectories", metavar="trajectories.csv")
    p.add_argument("--out", required=True, metavar="OUT.trc|OUT.c3d")
    p.set_defaults(func=cmd_export)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
