"""The error of every stage against the virtual laboratory's truth.

The metrics of seed 000 (section 6): detected points are first matched to
the true ones (an optimal one-to-one assignment), then the Euclidean distance
is measured, in pixels per camera (2D) and in metres (3D). The later stages
are compared in the motion frame, per axis. A noise-injection study replaces
the detections by the true projections plus Gaussian noise and follows the
noise through every later step of the pipeline.
"""
from __future__ import annotations


import numpy as np
from scipy.optimize import linear_sum_assignment

from .frames import angle_deg
from .params import AnalysisParams

AXES = ("x", "y", "z")


def match_points(detected: np.ndarray, true: np.ndarray):
    """Optimal one-to-one matching of detected to true points (seed 000, 6.1).

    Parameters
    ----------
    detected : (k, d) array, NaN rows ignored
    true : (m, d) array, NaN rows ignored

    Returns
    -------
    pairs : (p, 2) int array of (detected index, true index)
    distances : (p,) Euclidean distances of the pairs
    """
    det_ok = np.flatnonzero(np.all(np.isfinite(detected), axis=1))
    tru_ok = np.flatnonzero(np.all(np.isfinite(true), axis=1))
    if det_ok.size == 0 or tru_ok.size == 0:
        return np.zeros((0, 2), int), np.zeros(0)
    cost = np.linalg.norm(detected[det_ok, None, :] - true[None, tru_ok, :], axis=2)
    r, c = linear_sum_assignment(cost)
    return np.stack([det_ok[r], tru_ok[c]], axis=1), cost[r, c]


def _truth_rows(truth, frames_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the truth arrays for reference-camera frames; mask of those known."""
    idx = np.searchsorted(truth.ref_frames, frames_ref)
    idx = np.clip(idx, 0, len(truth.ref_frames) - 1)
    return idx, truth.ref_frames[idx] == frames_ref


def errors_2d(analysis, truth) -> dict:
    """Per camera: matched centroid errors (px) and identity swaps.

    Returns ``{camera: {"errors": (p,), "median", "p99", "max", "swaps", "found", "true_visible"}}``
    over every synchronised frame in which the truth has the marker visible.
    """
    det = analysis.detect.marker_px
    offsets = analysis.synchronisation.offsets
    out = {}
    for cam, px in det.items():
        m = px.shape[1]
        frames_cam = offsets[cam] + np.arange(px.shape[0])
        inside = frames_cam < truth.marker_px[cam].shape[0]
        errs, swaps, visible, found = [], 0, 0, 0
        for k in np.flatnonzero(inside):
            tp = truth.marker_px[cam][frames_cam[k], :m].copy()
            tp[~truth.marker_visible[cam][frames_cam[k], :m]] = np.nan
            visible += int(np.isfinite(tp[:, 0]).sum())
            pairs, d = match_points(px[k], tp)
            found += len(pairs)
            errs.extend(d)
            swaps += int(np.any(pairs[:, 0] != pairs[:, 1]))
        e = np.asarray(errs)
        out[cam] = {"errors": e, "median": float(np.median(e)) if e.size else np.nan,
                    "p99": float(np.percentile(e, 99)) if e.size else np.nan,
                    "max": float(e.max()) if e.size else np.nan,
                    "swaps": swaps, "found": found, "true_visible": visible}
    return out


def identification_errors(analysis, truth, wrong_px: float = 3.0) -> dict:
    """Identity and completeness of the detected markers against the truth (issue 17).

    Marker ``m`` of the detection is compared with marker ``m`` of the truth
    (both in the static shot's rear-to-front order) in every synchronised
    frame: a used centre further than ``wrong_px`` from its own marker's true
    projection is a wrong identity (another marker, a stirrup, a blob, or a
    centre ruined by a merge).

    Returns
    -------
    dict
        ``cameras``: per camera ``used``, ``wrong``, ``median_px``,
        ``p99_px``, ``visible`` (true visible), ``missed`` (visible, not
        used) and ``reasons`` (count of each reason among the missed);
        ``seen_by_two`` (marker-frames seen by two or more cameras in the
        truth), ``with_3d`` (those with a 3D position from the
        triangulation step, measured or interpolated), ``wrong_total``.
    """
    det = analysis.detect.marker_px
    reasons = analysis.detect.reason
    offsets = analysis.synchronisation.offsets
    n, m = next(iter(det.values())).shape[:2]
    out, visible_count = {}, np.zeros((n, m), int)
    for cam, px in det.items():
        rows = offsets[cam] + np.arange(n)
        inside = rows < truth.marker_px[cam].shape[0]
        tp = np.full((n, m, 2), np.nan)
        vis = np.zeros((n, m), bool)
        tp[inside] = truth.marker_px[cam][rows[inside], :m]
        vis[inside] = truth.marker_visible[cam][rows[inside], :m]
        visible_count += vis
        used = np.all(np.isfinite(px), axis=-1)
        err = np.linalg.norm(px - tp, axis=-1)
        wrong = used & ~(err <= wrong_px)
        e = err[used & ~wrong]
        missed = vis & ~used
        why = {}
        for r in np.asarray(reasons[cam], dtype=object)[missed]:
            why[str(r)] = why.get(str(r), 0) + 1
        out[cam] = {"used": int(used.sum()), "wrong": int(wrong.sum()),
                    "median_px": float(np.median(e)) if e.size else float("nan"),
                    "p99_px": float(np.percentile(e, 99)) if e.size else float("nan"),
                    "visible": int(vis.sum()), "missed": int(missed.sum()), "reasons": why}
    seen2 = visible_count >= 2
    pts = analysis.triangulate.points if analysis.triangulate is not None else np.full((n, m, 3), np.nan)
    have = np.all(np.isfinite(pts), axis=-1)
    return {"cameras": out, "seen_by_two": int(seen2.sum()), "with_3d": int((seen2 & have).sum()),
            "wrong_total": int(sum(c["wrong"] for c in out.values()))}


def analysed_truth(analysis, truth) -> dict:
    """The truth at the analysed frames, in the analysis' own motion frame.

    For comparing a notebook's estimates with the truth sample by sample:
    positions through :func:`horsemocap.frames.to_motion_frame` (origin and
    axes of the estimated frame), velocities, accelerations, omega and alpha
    rotated into its axes.

    Returns
    -------
    dict with ``frames`` (reference-camera frame numbers), ``known`` (mask of
    the frames the truth covers), ``marker_pos``/``marker_vel``/``marker_acc``
    (n, m, 3), ``saddle_pos``/``saddle_vel``/``saddle_acc`` (n, 3),
    ``omega``/``alpha`` (n, 3); rows the truth lacks are NaN.
    """
    from .frames import to_motion_frame

    a, b = analysis.triangulate.segment
    frames = analysis.synchronisation.offsets[analysis.session.reference_camera] + np.arange(a, b)
    rows, known = _truth_rows(truth, frames)
    mf = analysis.motion_frame.frame
    axes = analysis.motion_frame.axes

    def pick(arr, position=False):
        arr = np.asarray(arr, float)[rows]
        arr = to_motion_frame(arr, mf) if position else arr @ axes.T
        arr[~known] = np.nan
        return arr

    return {"frames": frames, "known": known,
            "marker_pos": pick(truth.marker_pos, True), "marker_vel": pick(truth.marker_vel),
            "marker_acc": pick(truth.marker_acc), "saddle_pos": pick(truth.saddle_pos, True),
            "saddle_vel": pick(truth.saddle_vel), "saddle_acc": pick(truth.saddle_acc),
            "omega": pick(truth.omega), "alpha": pick(truth.alpha)}


def rmse_axes(estimate: np.ndarray, true: np.ndarray) -> np.ndarray:
    """RMSE per last-axis component over every finite sample."""
    d = np.asarray(estimate, float) - np.asarray(true, float)
    d = d.reshape(-1, d.shape[-1])
    d = d[np.all(np.isfinite(d), axis=1)]
    return np.sqrt(np.mean(d ** 2, axis=0))


def rmse_pct_of_rms(estimate: np.ndarray, true: np.ndarray) -> float:
    """RMSE of a vector signal as a percentage of the true signal's rms.

    ``100 sqrt(mean |e_k - x_k|^2) / sqrt(mean |x_k|^2)`` over the samples ``k`` (rows; the last axis holds
    the vector's components); samples where the estimate is NaN (no pose) are left out of the error.

    Parameters
    ----------
    estimate, true : (n, d) arrays

    Returns
    -------
    float
    """
    e, x = np.asarray(estimate, float), np.asarray(true, float)
    if e.shape != x.shape:
        raise ValueError(f"estimate and true: expected the same shape, got {e.shape} and {x.shape}")
    return float(100 * np.sqrt(np.nanmean(np.sum((e - x) ** 2, -1))) / np.sqrt(np.mean(np.sum(x ** 2, -1))))


def second_difference_rmse(position, raw_acceleration, rate_hz: float, inside=None) -> float:
    """rms (m/s^2) of an estimate's second differences against a measured marker's own.

    A reference with no filter of its own: ``position`` (n, 3) of the
    estimated point is differenced twice at the frame rate and compared,
    frame by frame, with ``raw_acceleration`` (n - 2, 3), the measured
    marker's second differences (their noise is common to every method
    scored this way). Frames where either is not finite, or outside
    ``inside`` (n,) bool, are left out.

    Examples
    --------
    >>> t = np.arange(6) / 10.0
    >>> truth = np.c_[t ** 2, 0 * t, 0 * t]                       # 2 m/s^2 along x
    >>> raw = np.diff(truth, 2, axis=0) * 100.0
    >>> second_difference_rmse(truth + np.c_[0 * t, 0.001 * (-1) ** np.arange(6), 0 * t], raw, 10.0)
    0.4
    """
    est = np.diff(np.asarray(position, float), 2, axis=0) * rate_hz ** 2
    raw = np.asarray(raw_acceleration, float)
    ok = np.isfinite(est).all(1) & np.isfinite(raw).all(1)
    if inside is not None:
        ok &= np.asarray(inside, bool)[1:-1]
    return float(np.sqrt(np.mean(np.sum((est[ok] - raw[ok]) ** 2, 1))))


def offset_and_motion(estimate: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split a per-axis position error into its constant part and the rest.

    ``RMSE^2 = offset^2 + motion^2`` per axis. The constant part is where the
    whole reconstruction sits (the datum: a calibration that is slightly off
    shifts, turns and scales the reconstructed space as a whole; 7.7 m from
    the cameras that moves every point by nearly the same amount); the
    rest is the error of the motion itself, which velocities, accelerations
    and the comfort indicators see.

    Parameters
    ----------
    estimate, true : ndarray (..., 3)
        Positions in the same axes; non-finite samples are left out.

    Returns
    -------
    offset : ndarray (3,)
        Mean error per axis (estimate - true).
    motion_rmse : ndarray (3,)
        RMSE per axis once the offset is removed.

    Both are NaN (with NumPy's empty-mean warning) if no sample is finite.
    """
    d = np.asarray(estimate, float) - np.asarray(true, float)
    d = d.reshape(-1, d.shape[-1])
    d = d[np.all(np.isfinite(d), axis=1)]
    offset = d.mean(axis=0)
    return offset, np.sqrt(np.mean((d - offset) ** 2, axis=0))


def stage_errors(analysis, truth) -> dict:
    """Errors of the 3D stages against the truth, in the true motion frame.

    Keys: ``triangulated`` and ``smoothed`` (marker RMSE per axis, m),
    ``smoothed_offset`` and ``smoothed_motion`` (the smoothed RMSE split by
    :func:`offset_and_motion`),
    ``gravity_deg``, ``x_axis_deg`` (motion-frame axes), ``registered`` (m),
    ``velocity``/``acceleration`` of the markers, ``omega`` (rad/s),
    ``saddle_position`` (m), ``saddle_acceleration`` (m/s^2),
    ``saddle_acc_y_rmse_pct_of_rms``.
    """
    a, b = analysis.triangulate.segment
    frames = analysis.synchronisation.offsets[analysis.session.reference_camera] + np.arange(a, b)
    rows, known = _truth_rows(truth, frames)
    R_true = truth.motion_axes
    R_est = analysis.motion_frame.axes

    def true_motion(arr):
        return np.asarray(arr)[rows][known] @ R_true.T

    def est_world_to_true(arr):  # world-frame estimate seen in the true motion axes
        return np.asarray(arr)[known] @ R_true.T

    smoothed_est, smoothed_true = est_world_to_true(analysis.smooth.smoothed), true_motion(truth.marker_pos)
    offset, motion = offset_and_motion(smoothed_est, smoothed_true)
    out = {
        "frames": int(known.sum()),
        "triangulated": rmse_axes(est_world_to_true(analysis.triangulate.points[a:b]), true_motion(truth.marker_pos)),
        "smoothed": rmse_axes(smoothed_est, smoothed_true),
        "smoothed_offset": offset,
        "smoothed_motion": motion,
        "gravity_deg": angle_deg(analysis.plumb.gravity, truth.gravity),
        "x_axis_deg": angle_deg(R_est[0], R_true[0]),
    }
    rb = analysis.rigid_body
    if rb is not None:
        to_true = R_true @ R_est.T  # estimated motion frame -> world -> true motion frame

        def est(arr):
            return np.asarray(arr)[known] @ to_true.T

        out["registered"] = rmse_axes(est(rb.registered), true_motion(truth.marker_pos))
        out["velocity"] = rmse_axes(est(rb.velocity), true_motion(truth.marker_vel))
        out["acceleration"] = rmse_axes(est(rb.acceleration), true_motion(truth.marker_acc))
        out["omega"] = rmse_axes(est(rb.omega), true_motion(truth.omega))
        out["alpha"] = rmse_axes(est(rb.alpha), true_motion(truth.alpha))
        out["saddle_position"] = rmse_axes(est(rb.saddle_position), true_motion(truth.saddle_pos))
        out["saddle_acceleration"] = rmse_axes(est(rb.saddle_acceleration), true_motion(truth.saddle_acc))
        out["saddle_acc_y_rmse_pct_of_rms"] = saddle_acc_y_error_pct(analysis, truth)
    return out


def saddle_acc_y_error_pct(analysis, truth, frames=None) -> float:
    """The saddle's vertical acceleration error: rms over the analysed frames, % of the true rms there, in the
    true motion frame (:func:`stage_errors`' ``saddle_acc_y_rmse_pct_of_rms``). With ``frames``
    (reference-camera frame numbers) only the analysed frames among them count, so two analyses of one
    session compare on the same frames."""
    a, b = analysis.triangulate.segment
    ref = analysis.synchronisation.offsets[analysis.session.reference_camera] + np.arange(a, b)
    rows, known = _truth_rows(truth, ref)
    if frames is not None:
        known = known & np.isin(ref, frames)
    R_true = truth.motion_axes
    to_true = R_true @ analysis.motion_frame.axes.T
    acc_true = np.asarray(truth.saddle_acc)[rows][known] @ R_true.T
    err = rmse_axes(np.asarray(analysis.rigid_body.saddle_acceleration)[known] @ to_true.T, acc_true)
    return float(100 * err[1] / float(np.sqrt(np.mean(acc_true[:, 1] ** 2))))


def comfort_errors(indicators: dict, truth_indicators: dict, keys=None) -> dict:
    """Relative error (%) of each indicator against the truth's."""
    keys = [k for k in (keys or truth_indicators) if k in indicators and k in truth_indicators]
    return {k: 100 * (indicators[k] - truth_indicators[k]) / truth_indicators[k]
            for k in keys if truth_indicators[k] not in (0, None) and np.isfinite(truth_indicators[k])}


def noisy_projections(truth, offsets: dict, n_frames: int, n_markers: int, sigma_px: float, rng) -> dict:
    """True marker projections plus Gaussian noise, in the synchronised numbering.

    Markers the truth marks invisible stay NaN (never invented).
    """
    out = {}
    for cam, px in truth.marker_px.items():
        sl = slice(offsets[cam], offsets[cam] + n_frames)
        p = px[sl, :n_markers].copy()
        p[~truth.marker_visible[cam][sl, :n_markers]] = np.nan
        out[cam] = p + rng.normal(0.0, sigma_px, p.shape) if sigma_px > 0 else p
    return out


LATER_STEPS = ("triangulate", "smooth", "motion_frame", "rigid_body", "comfort")


def noisy_reruns(analysis, truth, sigmas_px, seed: int = 0, repeats: int = 3, params=None):
    """The steps after detection run again on noisy true projections: for each sigma, ``(sigma, reruns)``
    with ``repeats`` draws (one at sigma 0), each an :class:`~horsemocap.pipeline.Analysis` or the
    :class:`~horsemocap.pipeline.AnalysisError` that stopped it. One random stream (``seed``) over
    the sigmas in order, so the same ``seed`` and sigmas give the same draws (:func:`noise_study`).
    The period is the one found on the real detections."""
    from .pipeline import AnalysisError, run_steps

    sync = analysis.synchronisation
    rng = np.random.default_rng(seed)
    n = sync.n_frames
    # the period is the one found on the real detections: the study isolates what the noise
    # does to the later steps (the thesis user typed the period anyway)
    params = (params or analysis.params).updated({"motion_frame.period_frames": analysis.motion_frame.period_frames})
    for sigma in sigmas_px:
        reruns = []
        for _ in range(repeats if sigma > 0 else 1):
            px = noisy_projections(truth, sync.offsets, n, analysis.session.marker_count, sigma, rng)
            base = {k: getattr(analysis, k) for k in ("sync", "rig", "plumb", "static")}
            base["detect"] = analysis.detect.replace(marker_px=px)
            try:
                reruns.append(run_steps(analysis.session, params, base, LATER_STEPS))
            except AnalysisError as exc:
                reruns.append(exc)
        yield float(sigma), reruns


def noise_study(analysis, truth, sigmas_px=(0.0, 0.25, 0.5, 1.0, 2.0, 3.0), seed: int = 0,
                keys=("acc_y_Wk_rms", "VDV_y_Wk", "acc_y_max"), params=None, repeats: int = 3) -> list[dict]:
    """Follow detection noise through the pipeline (seed 000, section 6.3).

    For each sigma the detections are replaced by the true projections plus
    N(0, sigma^2) pixel noise; the steps from triangulation to the comfort
    indicators are run again with the analysis' own parameters and the same
    analysed frames (plumb, static shot and rig unchanged). ``params``
    replaces the analysis' parameters (e.g. :func:`with_params`
    ``(triangulation="thesis")``). Each sigma is repeated ``repeats`` times
    with different noise and the median of every error is reported (one
    draw is a poor guide: the automatic choices can flip with the noise).
    ``with_params(analysis, pose_weights="equal")``: the pose registered with
    equal marker weights, as before the covariances.

    Returns
    -------
    list of dict, one per sigma: ``sigma_px``, ``draws`` (analyses that ran),
    ``failed`` (the errors of those that stopped, e.g. too few frames
    triangulated consistently), median 3D RMSE per axis (m), saddle vertical
    acceleration error (% of rms), indicator errors (%).
    """
    rows = []
    for sigma, reruns in noisy_reruns(analysis, truth, sigmas_px, seed, repeats, params):
        draws, failed = [], []
        for rerun in reruns:
            if isinstance(rerun, Exception):
                failed.append(str(rerun))
                continue
            st = stage_errors(rerun, truth)
            draws.append((st, comfort_errors(rerun.comfort.indicators, truth.comfort, list(keys))))
        if not draws:
            rows.append({"sigma_px": float(sigma), "draws": 0, "failed": failed})
            continue
        med = lambda f: np.median([f(st, ce) for st, ce in draws], axis=0)  # noqa: E731
        rows.append({"sigma_px": float(sigma), "draws": len(draws), "failed": failed,
                     "triangulated_m": med(lambda st, ce: st["triangulated"]),
                     "smoothed_m": med(lambda st, ce: st["smoothed"]),
                     "saddle_position_m": med(lambda st, ce: st["saddle_position"]),
                     "saddle_acc_y_pct": float(med(lambda st, ce: st["saddle_acc_y_rmse_pct_of_rms"])),
                     "comfort_pct": {k: float(med(lambda st, ce: ce[k])) for k in draws[0][1]}})
    return rows


def with_params(analysis, **changes):
    """The analysis' parameters with some changed (for what-if studies)."""
    return analysis.params.updated(changes)


# ---------------------------------------------------------------------------
# other rigs: the thesis' limits and what a better rig buys
# ---------------------------------------------------------------------------

def scaled_rig(rig, resolution_factor: float = 1.0):
    """The same rig with every sensor ``resolution_factor`` times finer (K and size scaled)."""
    from .camera import Camera, Rig

    cams = []
    for c in rig:
        K = c.matrix.copy()
        K[:2] *= resolution_factor
        K[:2, 2] = (K[:2, 2] + 0.5) - 0.5  # pixel centres stay pixel centres to first order
        cams.append(Camera(c.name, (round(c.size[0] * resolution_factor), round(c.size[1] * resolution_factor)),
                           K, c.distortions, c.rotation, c.translation))
    return Rig(tuple(cams), dict(rig.metadata))


def wide_baseline_rig(rig, baseline_m: float = 1.5, target_depth_m: float = 7.5):
    """The rig with its cameras spread ``baseline_m`` apart along x, toed in.

    Every non-reference camera ``i`` is placed at ``x = i * baseline_m`` in
    the reference camera's frame and turned about the vertical axis so that
    its optical axis meets the reference camera's at ``target_depth_m``.
    """
    from .camera import Rig, rotation_vector

    cams = [rig.cameras[0]]
    for i, c in enumerate(rig.cameras[1:], start=1):
        centre = np.array([i * baseline_m, 0.0, 0.0])
        yaw = -np.arctan2(i * baseline_m, target_depth_m)  # turn left to look back at the centre line
        Ry = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
        R = Ry.T  # world -> camera
        cams.append(c.with_pose(rotation_vector(R), -R @ centre))
    return Rig(tuple(cams), dict(rig.metadata))


def simulate_rig(analysis, rig, fps: float, sigma_px: float, *, horse: str = "Horse 2",
                 gait: str = "canter", seed: int = 0) -> tuple:
    """Analyse a virtual ride seen through another rig, at the 2D level.

    The virtual laboratory's exact truth (:func:`horsemocap.virtuallab.build_truth`)
    is computed for ``rig`` at ``fps``; the detections are the true
    projections plus N(0, sigma_px^2) noise (markers the truth hides stay
    NaN), the plumb and static stills likewise; then the pipeline's steps
    from triangulation to the comfort indicators run with the parameters of
    ``analysis``. Images are not rendered: this isolates the geometry (pixel
    size, frame rate, baseline) from the detector.

    The ride is the virtual laboratory's ``horse`` at ``gait`` with *its*
    skin markers (three), whatever ``analysis`` measured: a session with
    four markers, or a recorded one without truth, lends only its
    parameters. The simulated cameras are genlocked and expose instantly,
    so the session's ``metadata.camera_timing`` (free-running cameras,
    exposure, rolling shutter) is not carried over.

    Returns
    -------
    (Analysis, Truth)

    Raises
    ------
    AnalysisError
        (step ``"detect"``) when no frame of the simulated ride has every
        skin marker seen by every camera of ``rig``: there is no segment to
        analyse.
    """
    from dataclasses import replace as dc_replace

    from .frames import gravity_from_plumb
    from .pipeline import AnalysisError, run_steps
    from .reconstruction import triangulate
    from .steps import (DetectResult, PlumbResult, RigResult, StaticResult, SyncResult, longest_run,
                        max_gap_frames)
    from .virtuallab import Scene, build_truth, saddle_motion
    from .virtuallab.session import plan_timeline

    rng = np.random.default_rng(seed)
    scene = Scene(rig=rig, motion=saddle_motion(horse, gait), seed=seed)
    _, n = plan_timeline(scene, fps, left_offset=0)
    offsets = {c: 0 for c in rig.names}
    truth = build_truth(scene, offsets, {c: n for c in rig.names}, fps)
    m = len(scene.motion.horse.marker_body)            # the virtual horse's skin markers, not the session's
    px = noisy_projections(truth, offsets, n, m, sigma_px, rng)
    seen = np.all([np.all(np.isfinite(p[..., 0]), axis=1) for p in px.values()], axis=0)
    segment = longest_run(seen)
    if segment is None:
        raise AnalysisError("detect", f"simulated {horse} {gait} at {fps:g} fps: no frame in which every camera "
                                      f"({', '.join(rig.names)}) sees all {m} skin markers, so there is no segment "
                                      "to analyse; check that the rig's cameras look at the riding track")

    def still(points):
        obs = {c: rig[c].project(points)[None] + rng.normal(0, sigma_px, (1, len(points), 2)) for c in rig.names}
        return triangulate(rig, obs, mode=analysis.params.triangulate.mode).points[0]

    plumb = still(truth.plumb_pos)
    params = _marker_choices_reset(analysis, m)
    metadata = {k: v for k, v in analysis.session.metadata.items() if k != "camera_timing"}
    session = dc_replace(analysis.session, fps=float(fps), cameras=tuple(rig.names), marker_count=m,
                         metadata=metadata)
    sync = SyncResult(offsets=offsets, frame_counts={c: n for c in rig.names}, n_frames=n,
                      offsets_from="simulated")
    hidden = {c: np.where(np.isfinite(p[..., 0]), "", "occluded") for c, p in px.items()}
    base = {
        "sync": sync,
        "rig": RigResult(rig=rig, rig_from="simulated"),
        "detect": DetectResult(marker_px=px, reason=hidden, segment=segment, detection={}, all_seen=seen,
                               method="simulated", method_note="", sync=sync,
                               max_gap_frames=max_gap_frames(session, params.detect)),
        "plumb": PlumbResult(plumb_points=plumb, plumb_px={}, gravity=gravity_from_plumb(plumb[0], plumb[1])),
        "static": StaticResult(static_points=still(truth.static_pos), static_px=None),
    }
    return run_steps(session, params, base, LATER_STEPS), truth


#: The parameters that name markers by index or count them: a simulated ride with another number of markers than
#: the session takes their defaults (``section.field``).
MARKER_CHOICES = ("motion_frame.x_marker", "rigid_body.fits.fourier_orders", "rigid_body.saddle_marker")


def _marker_choices_reset(analysis, n_markers: int):
    """``analysis.params``, with :data:`MARKER_CHOICES` at their defaults when the session has another marker count.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from horsemocap.params import AnalysisParams
    >>> four = SimpleNamespace(session=SimpleNamespace(marker_count=4),
    ...                        params=AnalysisParams().updated({"motion_frame.x_marker": 3}))
    >>> _marker_choices_reset(four, 3).motion_frame.x_marker, _marker_choices_reset(four, 4).motion_frame.x_marker
    (0, 3)
    """
    if analysis.session.marker_count == n_markers:
        return analysis.params
    default = AnalysisParams()
    return analysis.params.updated({key: default.value(key) for key in MARKER_CHOICES})


def rig_study(analysis, variants: dict, sigma_px: float, seed: int = 0,
              keys=("acc_y_Wk_rms", "VDV_y_Wk")) -> list[dict]:
    """:func:`simulate_rig` for named ``(rig, fps)`` variants; one row each."""
    from .pipeline import AnalysisError

    rows = []
    for name, (rig, fps) in variants.items():
        try:
            sim, truth = simulate_rig(analysis, rig, fps, sigma_px, seed=seed)
        except AnalysisError as exc:
            rows.append({"rig": name, "fps": fps, "size": rig.cameras[0].size, "failed": str(exc)})
            continue
        st = stage_errors(sim, truth)
        rows.append({"rig": name, "fps": fps, "size": rig.cameras[0].size,
                     "frames": st["frames"], "smoothed_m": st["smoothed"],
                     "saddle_position_m": st["saddle_position"],
                     "saddle_acc_y_pct": st["saddle_acc_y_rmse_pct_of_rms"],
                     "comfort_pct": comfort_errors(sim.comfort.indicators, truth.comfort, list(keys))})
    return rows


def calibration_draws(truth, seeds=range(5), n_views: int = 45, *, horse: str = "Horse 2",
                      gait: str = "canter", mode: str = "joint", protocol: str = "path") -> list[dict]:
    """How far the thesis' calibration puts the markers: one row per rendered calibration set.

    For every seed the virtual laboratory renders the checkerboard views a
    session of that seed would hold (same rig, board and poses as the
    sessions: all boards near the path, 7.5-8 m from the cameras, as in the
    thesis' section 8.2), the rig is calibrated from them as the pipeline
    does (:func:`~horsemocap.calibration.calibrate_rig`), and the *exact*
    projections of ``truth``'s markers are triangulated with it. The error
    is then the calibration's alone (no detection noise, no smoothing),
    split by :func:`offset_and_motion` in the true motion axes.

    Parameters
    ----------
    truth : Truth
        A virtual session's truth (its markers and rig).
    seeds : iterable of int
        Seeds of the calibration sets (the session's own seed, with its
        ``n_views`` and the ``"path"`` protocol, gives its own views).
    n_views : int
        Views per camera (the thesis used 90).
    horse, gait : str
        Which scene's background the boards are rendered on.
    mode : {"joint", "pairwise"}
        The calibration's rig (see :func:`~horsemocap.calibration.calibrate_rig`).
    protocol : str
        Where the boards stand: ``"path"`` (the thesis', the sessions') or
        ``"depths"`` (also nearer the cameras, turned further); see
        :data:`horsemocap.virtuallab.calibration.PROTOCOLS`.

    Returns
    -------
    list of dict
        ``seed``, ``n_views``, ``views_used`` per camera, ``intrinsic_error``
        per camera (``fx, fy, cx, cy`` minus the truth, px), ``sigma3`` per
        camera (the calibration's own three-sigma ``fx, fy, cx, cy``: the joint
        bundle adjustment's in ``"joint"`` mode, each camera's alone otherwise),
        ``baseline_error_pct`` per non-reference camera, ``offset_m`` and
        ``motion_rmse_m`` and ``rmse_m`` (per motion axis x, y, z).
    """
    import tempfile

    from .calibration import calibrate_rig
    from .reconstruction import triangulate
    from .virtuallab import render_calibration_set

    offsets = {c: int(o) for c, o in truth.offsets.items()}
    n = min(truth.marker_px[c].shape[0] - offsets[c] for c in offsets)
    n_markers = truth.marker_pos.shape[1]
    px = noisy_projections(truth, offsets, n, n_markers, 0.0, None)
    ref = truth.rig.cameras[0].name
    rows_idx, known = _truth_rows(truth, offsets[ref] + np.arange(n))
    true_m = truth.marker_pos[rows_idx][known] @ truth.motion_axes.T
    out = []
    for seed in seeds:
        with tempfile.TemporaryDirectory() as tmp:
            cal_set = render_calibration_set(tmp, int(seed), n_views, horse, gait, protocol=protocol)
            board = cal_set["board"]
            cal = calibrate_rig(cal_set["images"], tuple(board["inner_corners"]), board["square_size_m"],
                                reference=ref, mode=mode, pairs=mode == "pairwise")
        rig = cal.rig
        if tuple(cal_set["rig"].names) != tuple(truth.rig.names) or not all(
                np.allclose(cal_set["rig"][c].matrix, truth.rig[c].matrix) for c in truth.rig.names):
            raise ValueError("calibration_draws: the truth was not made with the virtual laboratory's thesis rig "
                             f"(cameras {list(truth.rig.names)}); its markers cannot be compared with views "
                             "rendered by that rig")
        points = triangulate(rig, {c: px[c] for c in rig.names}, mode="joint").points[known]
        est_m = points @ truth.motion_axes.T
        offset, motion = offset_and_motion(est_m, true_m)
        row = {"seed": int(seed), "n_views": int(n_views), "protocol": protocol,
               "views_used": {c: int(cal.singles[c].used.sum()) for c in rig.names},
               "intrinsic_error": {}, "sigma3": {}, "baseline_error_pct": {},
               "offset_m": offset, "motion_rmse_m": motion, "rmse_m": rmse_axes(est_m, true_m)}
        for cam in rig:
            t = truth.rig[cam.name]
            K, Kt = cam.matrix, t.matrix
            row["intrinsic_error"][cam.name] = np.array([K[0, 0] - Kt[0, 0], K[1, 1] - Kt[1, 1],
                                                         K[0, 2] - Kt[0, 2], K[1, 2] - Kt[1, 2]])
            own = cal.joint.intrinsics[cam.name] if mode == "joint" else cal.singles[cam.name]
            row["sigma3"][cam.name] = np.asarray(own.sigma3[:4], float)
            if cam.name != ref:
                b, bt = np.linalg.norm(cam.center), np.linalg.norm(t.center)
                row["baseline_error_pct"][cam.name] = 100 * (b - bt) / bt
        out.append(row)
    return out
