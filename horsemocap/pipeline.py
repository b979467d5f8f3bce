"""The whole analysis of a riding session, one step after another.

Every arrow of DESIGN.md is a step here: each takes the session, the
parameters and the results of the steps before it, calls the package
function of its module, and returns a small dict of arrays and chosen values.
:func:`analyze` runs the steps in order, saves each one whole in the results
store (so the steps before a failure stay written) and writes the files of
``shared/spec/sessions.md``. Notebooks call :func:`results_for` to load what
earlier steps computed (computing it with the defaults when absent).
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .camera import Rig, read_rig
from .params import AnalysisParams
from .session import Session, SessionError, check_frame_counts, load_session
from .sources import FrameSource, read_image
from .store import ResultsStore, check_outside

STEPS = ("sync", "rig", "detect", "triangulate", "plumb", "static", "smooth",
         "motion_frame", "register", "fit", "angular", "saddle", "comfort")


class AnalysisError(RuntimeError):
    """A step that cannot go on; the message names the input to look at."""

    def __init__(self, step: str, message: str):
        super().__init__(f"step '{step}': {message}")
        self.step = step


@dataclass
class Analysis:
    """Results of the steps run so far.

    Attributes
    ----------
    session : Session
    params : AnalysisParams
        The parameters given (``None`` fields are filled in ``chosen``).
    results : dict
        Step name -> dict of arrays and values.
    chosen : dict
        Every automatic choice made, by step (written to ``analysis.json``).
    timings : dict
        Seconds spent per step.
    """

    session: Session
    params: AnalysisParams
    results: dict = field(default_factory=dict)
    chosen: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    def __getitem__(self, step: str) -> dict:
        return self.results[step]


def _progress_printer(stream=sys.stderr):
    def report(step: str, message: str):
        print(f"[horsemocap] {step}: {message}", file=stream, flush=True)
    return report


# ---------------------------------------------------------------------------
# the steps
# ---------------------------------------------------------------------------

def step_sync(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Frame offsets (eq. 3.11-3.14) and the synchronised frame count."""
    from . import sync

    sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
    if params.sync_offsets:
        offsets, how = dict(params.sync_offsets), "given in parameters"
    elif session.sync_offsets:
        offsets, how = dict(session.sync_offsets), "given in session.json"
    else:
        offsets, how = sync.flash_offsets(sources), "flashlight"
        offsets = {c: int(v) for c, v in offsets.items()}
    counts = {c: len(s) for c, s in sources.items()}
    n = check_frame_counts(session, counts, offsets)
    progress("sync", f"offsets {offsets} ({how}); {n} synchronised frames")
    return {"offsets": offsets, "frame_counts": counts, "n_frames": n, "offsets_from": how}


def step_rig(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """The calibrated rig: the session's ``rig.toml`` or a calibration of its views."""
    if session.rig_path is not None and not params.recalibrate:
        rig, how = read_rig(session.rig_path), f"read {session.rig_path.name}"
    elif session.calibration_images is not None:
        from .calibration import calibrate_rig

        progress("rig", "calibrating from checkerboard views ...")
        cal = calibrate_rig(session.calibration_images, session.board.inner_corners,
                            session.board.square_size_m, reference=session.reference_camera)
        rig, how = cal.rig, "calibrated from checkerboard views"
    else:
        raise AnalysisError("rig", f"{session.json_path}: 'calibration' gives neither a rig nor views")
    missing = [c for c in session.cameras if c not in rig.names]
    if missing:
        raise AnalysisError("rig", f"the rig has no camera {missing[0]!r} (it has {rig.names}); "
                                   f"check 'calibration' in {session.json_path}")
    rig = rig.subset(session.cameras)
    progress("rig", how)
    return {"rig": rig, "rig_from": how}


def _detection_params(params: AnalysisParams, camera: str):
    from .detection import DetectionParams

    given = dict(params.detection.get("all", {}))
    given.update(params.detection.get(camera, {}))
    return DetectionParams.from_dict(given) if given else None


def step_detect(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Marker centroids per camera in the synchronised numbering (chapter 4)."""
    from .detection import detect_markers

    offsets, n = res["sync"]["offsets"], res["sync"]["n_frames"]
    marker_px, reasons, chosen = {}, {}, {}
    for cam in session.cameras:
        progress("detect", f"camera '{cam}': {n} frames ...")
        frames = FrameSource(session.motion[cam]).read(offsets[cam], offsets[cam] + n, color=False)
        track = detect_markers(frames, session.marker_count, params=_detection_params(params, cam))
        marker_px[cam], reasons[cam] = track.marker_px, track.reason
        chosen[cam] = track.params.to_dict()
        del frames
    seen = np.all([np.all(np.isfinite(marker_px[c][..., 0]), axis=1) for c in session.cameras], axis=0)
    segment = _longest_run(seen)
    if segment is None or segment[1] - segment[0] < 8:
        counts = {c: int(np.all(np.isfinite(marker_px[c][..., 0]), axis=1).sum()) for c in session.cameras}
        raise AnalysisError("detect", "fewer than 8 consecutive frames in which every camera sees every "
                            f"marker (frames with all markers, per camera: {counts}); check the motion "
                            "videos, the threshold and the marker count in session.json")
    progress("detect", f"frames {segment[0]}..{segment[1] - 1} seen by every camera")
    return {"marker_px": marker_px, "reason": reasons, "all_seen": seen,
            "segment": segment, "detection": chosen}


def _longest_run(mask: np.ndarray):
    best, start = None, None
    for i, v in enumerate(list(mask) + [False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if best is None or i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return best


def step_triangulate(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """3D marker positions in the reference camera frame (section 5.1)."""
    from .reconstruction import triangulate

    tri = triangulate(res["rig"]["rig"], res["detect"]["marker_px"], mode=params.triangulation)
    med = {c: float(np.nanmedian(r)) for c, r in tri.residual_px.items()}
    progress("triangulate", f"{params.triangulation} mode; median reprojection residual (px) "
                            + ", ".join(f"{c} {v:.3f}" for c, v in med.items()))
    return {"points": tri.points, "residual_px": tri.residual_px, "reason": tri.reason}


def _still_points(session: Session, rig: Rig, images: dict, count: int, step: str, mode: str):
    from .detection import detect_still
    from .reconstruction import triangulate

    px = {}
    for cam in session.cameras:
        try:
            px[cam] = detect_still(read_image(images[cam]), count)[None]
        except ValueError as exc:
            raise AnalysisError(step, f"{images[cam]}: {exc}") from None
    return triangulate(rig, px, mode=mode).points[0], {c: p[0] for c, p in px.items()}


def step_plumb(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Gravity from the plumb line's two markers (section 5.3)."""
    from .frames import gravity_from_plumb

    if session.plumb is None:
        raise AnalysisError("plumb", f"{session.json_path}: no 'plumb' stills; gravity cannot be found")
    pts, px = _still_points(session, res["rig"]["rig"], session.plumb, 2, "plumb", params.triangulation)
    # detect_still orders the two plumb markers top first (image v): the upper one is
    # the tail, the lower one the tip, and gravity points from tail to tip (down).
    gravity = gravity_from_plumb(tip_world=pts[1], tail_world=pts[0])
    progress("plumb", f"gravity {np.round(gravity, 4).tolist()}")
    return {"plumb_points": pts, "plumb_px": px, "gravity": gravity}


def step_static(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Static shot: the markers and the saddle marker, all visible (section 6.3)."""
    if session.static is None:
        raise AnalysisError("static", f"{session.json_path}: no 'static' stills; the saddle marker cannot be placed")
    pts, px = _still_points(session, res["rig"]["rig"], session.static, session.marker_count + 1,
                            "static", params.triangulation)
    return {"static_points": pts, "static_px": px}


def step_smooth(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Robust loess smoothing of every coordinate (section 5.2)."""
    from .smoothing import smooth_positions

    a, b = res["detect"]["segment"]
    raw = res["triangulate"]["points"][a:b]
    smoothed = smooth_positions(raw, span=params.smoothing_span, method=params.smoothing_method)
    return {"raw": raw, "smoothed": smoothed}


def step_motion_frame(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Motion reference frame: x along net displacement, y along gravity (5.3)."""
    from .frames import motion_frame, to_motion_frame

    smoothed = res["smooth"]["smoothed"]
    mf = motion_frame(smoothed, res["plumb"]["gravity"], marker=params.x_marker,
                      period=params.period_frames, n_periods=params.n_periods)
    progress("motion_frame", f"period {mf.period_frames:.2f} frames")
    return {"frame": mf, "axes": mf.axes, "period_frames": float(mf.period_frames),
            "positions": to_motion_frame(smoothed, mf),
            "static": to_motion_frame(res["static"]["static_points"], mf)}


def step_register(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Rigid registration of every frame to the static shot (5.4)."""
    from .rigid import match_static_markers, register

    positions, static = res["motion_frame"]["positions"], res["motion_frame"]["static"]
    order, saddle_index = match_static_markers(static, positions)
    model = static[np.asarray(order)]
    reg = register(positions, model)
    return {"model": model, "saddle_static": static[saddle_index], "registration": reg,
            "registered": reg.registered, "static_order": [int(i) for i in order],
            "saddle_index": int(saddle_index)}


def _fourier_orders(given, n_markers):
    """``{"y": N, "z": N}`` or per-marker ``[[Ny, Nz], ...]`` -> array (m, 2) or None."""
    if given is None:
        return None
    if isinstance(given, dict):
        return np.tile([int(given["y"]), int(given["z"])], (n_markers, 1))
    arr = np.asarray(given, int)
    if arr.shape != (n_markers, 2):
        raise AnalysisError("fit", f"parameter 'fourier_orders': expected {{'y': N, 'z': N}} or "
                                   f"{n_markers} pairs [Ny, Nz], got {given!r}")
    return arr


def step_fit(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Polynomial x-motion and Fourier y/z fits; v and a from them (5.5).

    The registered positions are kept as the positions (section 5.5.2);
    velocity and acceleration are the analytic derivatives of the fits.
    """
    from .fitting import fit_motion
    from .frames import time_axis

    registered = res["register"]["registered"]
    t = time_axis(len(registered), session.fps)
    orders = _fourier_orders(params.fourier_orders, registered.shape[1])
    mfit = fit_motion(t, registered, x_degree=params.x_degree, orders=orders)
    progress("fit", "Fourier orders (y, z) per marker " + str(mfit.orders[:, 1:].tolist()))
    return {"t": t, "motion_fit": mfit, "position": registered, "fitted_position": mfit.position(t),
            "velocity": mfit.velocity(t), "acceleration": mfit.acceleration(t),
            "orders": np.asarray(mfit.orders)[:, 1:]}


def step_angular(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Angular velocity and acceleration of the body (6.1-6.2)."""
    from . import rigid

    pos, vel, acc = (res["fit"][k] for k in ("position", "velocity", "acceleration"))
    w_versions = rigid.angular_velocity_versions(pos, vel)
    w_lstsq = rigid.angular_velocity_lstsq(pos, vel)
    if params.angular_method == "lstsq":
        omega = w_lstsq
    else:
        omega = rigid.average_versions(w_versions, use=params.omega_versions)
    a_versions = rigid.angular_acceleration_versions(pos, vel, acc, omega)
    a_lstsq = rigid.angular_acceleration_lstsq(pos, acc, omega)
    alpha = a_lstsq if params.angular_method == "lstsq" else rigid.average_versions(a_versions, use=params.omega_versions)
    sing = rigid.singularity_angle(pos, omega)
    return {"omega": omega, "alpha": alpha, "omega_versions": w_versions, "alpha_versions": a_versions,
            "omega_lstsq": w_lstsq, "alpha_lstsq": a_lstsq, "singularity_deg": sing}


def step_saddle(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """The hidden saddle marker's position, velocity, acceleration (6.3-6.4)."""
    from . import rigid

    saddle_body = rigid.saddle_in_body(res["register"]["model"], res["register"]["saddle_static"])
    sk = rigid.saddle_kinematics(res["fit"]["position"], res["fit"]["velocity"], res["fit"]["acceleration"],
                                 res["angular"]["omega"], res["angular"]["alpha"], saddle_body)
    return {"saddle": sk, "position": sk.position, "velocity": sk.velocity, "acceleration": sk.acceleration}


def step_comfort(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Whole-body vibration indicators of the saddle's vertical motion (chapter 7)."""
    from .vibration import saddle_comfort

    ind = saddle_comfort(res["fit"]["t"], res["saddle"]["position"], res["saddle"]["acceleration"],
                         res["saddle"]["velocity"], mode=params.weighting_mode)
    progress("comfort", f"Wk rms {ind['acc_y_Wk_rms']:.3f} m/s^2, VDV {ind['VDV_y_Wk']:.3f} m/s^1.75")
    return {"indicators": ind}


STEP_FUNCTIONS = {name: globals()[f"step_{name}"] for name in STEPS}


# ---------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------

def analyze(session_dir, out_dir=None, params: AnalysisParams | dict | None = None, *,
            until: str | None = None, progress=None, write_outputs: bool = True,
            reuse: bool = False) -> Analysis:
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

    Returns
    -------
    Analysis

    Raises
    ------
    SessionError, AnalysisError
        Naming the input to look at; the steps before stay written.
    """
    from . import results as result_files

    session = load_session(session_dir)
    params = resolve_params(session, params)
    progress = progress or _progress_printer()
    if until is not None and until not in STEPS:
        raise ValueError(f"until must be one of {STEPS}, got {until!r}")
    analysis = Analysis(session, params)
    if out_dir is not None:
        check_outside(out_dir, session.root)
        Path(out_dir).mkdir(parents=True, exist_ok=True)
    store = ResultsStore(out_dir) if (reuse and out_dir is not None) else None
    key = run_key(session, params) if store else ""
    for name in STEPS:
        t0 = time.perf_counter()
        try:
            stored = store.load(name, key) if store else None
            if stored is not None:
                analysis.results[name] = stored
            else:
                analysis.results[name] = STEP_FUNCTIONS[name](session, params, analysis.results, progress)
                if store:
                    store.save(name, analysis.results[name], key)
        except (AnalysisError, SessionError):
            raise
        except Exception as exc:  # a step's own error: say which step and input
            raise AnalysisError(name, f"{type(exc).__name__}: {exc}") from exc
        finally:
            analysis.timings[name] = time.perf_counter() - t0
            if out_dir is not None and write_outputs:
                result_files.write_available(Path(out_dir), analysis)
        if name == until:
            break
    return analysis


def run_steps(session: Session, params: AnalysisParams, results: dict, steps, progress=None) -> Analysis:
    """Run ``steps`` (names, in pipeline order) on top of given ``results``.

    For studies that replace one step's output (e.g. noisy detections) and
    follow the change through the later steps. Nothing is written.
    """
    progress = progress or (lambda *a: None)
    analysis = Analysis(session, params, dict(results))
    for name in steps:
        t0 = time.perf_counter()
        analysis.results[name] = STEP_FUNCTIONS[name](session, params, analysis.results, progress)
        analysis.timings[name] = time.perf_counter() - t0
    return analysis


def resolve_params(session: Session, params=None) -> AnalysisParams:
    """Defaults, then the session's ``analysis`` object, then ``params``."""
    base = AnalysisParams.from_dict(session.analysis, f"{session.json_path}: 'analysis'")
    if params is None:
        return base
    if isinstance(params, AnalysisParams):
        return params
    merged = base.to_dict()
    merged.update(params)
    return AnalysisParams.from_dict(merged)


def run_key(session: Session, params: AnalysisParams) -> str:
    """Fingerprint of a run: session.json, the parameters and the package's code."""
    h = hashlib.sha256(session.json_path.read_bytes())
    h.update(json.dumps(params.to_dict(), sort_keys=True, default=str).encode())
    for src in sorted(Path(__file__).parent.rglob("*.py")):
        h.update(src.read_bytes())
    return h.hexdigest()


def notebook_results_dir(session: Session | Path) -> Path:
    """Where notebooks keep a session's results (``$HORSEMOCAP_RESULTS``)."""
    from .data import cache_dir

    name = session.name if isinstance(session, Session) else load_session(session, open_sources=False).name
    root = Path(os.environ.get("HORSEMOCAP_RESULTS") or (cache_dir() / "results"))
    return root / name


def results_for(session_dir=None, until: str = "comfort", params=None) -> Analysis:
    """The analysis of a session up to a step, for notebooks.

    Runs the steps with the default (automatic) choices, quietly, and writes
    the spec's files to :func:`notebook_results_dir` (a clean folder per test
    run under nbval). Steps an earlier notebook computed for the same
    session, parameters and code are loaded from the results store, so each
    notebook runs alone and none repeats another's work.
    """
    from .data import default_session_dir

    session_dir = Path(session_dir or default_session_dir()).resolve()
    return analyze(session_dir, notebook_results_dir(session_dir), params, until=until,
                   progress=lambda *a: None, reuse=True)
