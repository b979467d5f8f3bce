"""Step ``rigid_body``: registration, kinematics and the hidden saddle marker (thesis 5.4-5.5, chapter 6)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..aperture import session_aperture
from ..frames import time_axis, to_motion_frame
from ..params import RigidBodyParams
from ..pose import ONE_ROUTE_WEIGHTS, CollinearMarkersError, SettledPoseSmoothing
from ..rigid import (Conditioning, FourierOrders, PoseInput, RigidBodyAnalysis, analyse_rigid_body, conditioning,
                     saddle_angles)
from ..session import Session
from ..splines import ChangePointError
from .base import AnalysisError, StepResult, frames_text
from .motion_frame import MotionFrameResult
from .triangulate import TriangulateResult


@dataclass(frozen=True)
class RigidBodyResult(StepResult):
    """The markers' and the saddle's kinematics in the motion frame.

    Attributes
    ----------
    body : RigidBodyAnalysis
        Everything the rigid-body analysis computed (both chains where the record allows).
    t : (n,) array
        Time (s) from the first analysed frame (eq. 5.13).
    registered : (n, m, 3) array
        The markers' registered positions (section 5.4).
    model : (m, 3) array
        The static shot's markers (the rigid model).
    saddle_static : (3,) array
        The saddle marker in the static shot.
    static_order : list of int
        Static-shot point of each marker; ``saddle_index`` the saddle's.
    velocity, acceleration : (n, m, 3) arrays
        The markers' velocity and acceleration passed on.
    orders : (m, 2) array or None
        The Fourier orders (y, z) per marker of the thesis' chain.
    omega, alpha : (n, 3) arrays
        Angular velocity and acceleration (chapter 6).
    saddle_position, saddle_velocity, saddle_acceleration : (n, 3) arrays
        The hidden saddle marker (eq. 6.48-6.55 or the pose trajectory).
    conditioning : horsemocap.rigid.Conditioning
        The eq. 6.35 angle, the marker triangle's height and the registration residual per frame,
        and the warnings they give (:attr:`singularity_deg`, :attr:`warnings`).
    saddle_angles_deg : (n, 3) array
        Roll, pitch, yaw of the saddle.
    """

    body: RigidBodyAnalysis
    t: np.ndarray
    registered: np.ndarray
    model: np.ndarray
    saddle_static: np.ndarray
    static_order: list
    saddle_index: int
    velocity: np.ndarray
    acceleration: np.ndarray
    orders: np.ndarray | None
    omega: np.ndarray
    alpha: np.ndarray
    saddle_position: np.ndarray
    saddle_velocity: np.ndarray
    saddle_acceleration: np.ndarray
    conditioning: Conditioning
    saddle_angles_deg: np.ndarray

    @property
    def singularity_deg(self) -> np.ndarray:
        """The eq. 6.35 angle per frame (:attr:`horsemocap.rigid.Conditioning.singularity_deg`)."""
        return self.conditioning.singularity_deg

    @property
    def warnings(self) -> list:
        """Messages when the conditioning makes the result unreliable (:attr:`horsemocap.rigid.Conditioning.warnings`)."""
        return self.conditioning.warnings


def step_rigid_body(session: Session, section: RigidBodyParams, triangulated: TriangulateResult,
                    raw: np.ndarray, motion: MotionFrameResult, offsets: dict, progress,
                    settled: SettledPoseSmoothing | None = None, thesis_chain: bool = True) -> RigidBodyResult:
    """Registration, pose trajectory, fits, omega/alpha and the hidden saddle marker (5.4-5.5, 6).

    One call of :func:`horsemocap.rigid.analyse_rigid_body`. With
    ``kinematics="pose_spline"`` the markers' poses are registered frame by
    frame to the static shot and smoothed (:mod:`horsemocap.pose`), and
    omega, alpha, the markers' and the saddle's kinematics come from that
    pose trajectory; the thesis' chain (poly x, Fourier y/z with the order
    rule of 5.5.2.2, the six versions, eq. 6.48-6.55) is computed too and is
    what ``kinematics="fits"`` passes on. ``raw``: the analysed frames'
    unsmoothed positions (world frame), from which the pose trajectory is
    smoothed; ``offsets``: the synchronisation, to name frames in messages.
    Per-frame conditioning (the eq. 6.35 angle, the marker triangle's
    smallest height, the registration residual) is kept, and a warning is
    printed when it makes the result unreliable. ``settled``: the pose
    smoothing's choices made on another pass of the same record
    (:func:`horsemocap.pose.settle_pose_smoothing`), reused instead of chosen;
    ``thesis_chain`` False: with ``kinematics="pose_spline"``, the thesis'
    chain (which nothing passed on uses there) is not computed. Where
    ``session.json`` gives the cameras' ``camera_timing`` (exposure,
    interlaced fields), the pose trajectory is fitted through the frames'
    temporal aperture (:func:`horsemocap.aperture.session_aperture`), so it
    estimates the motion, not its average over each exposure. A pass longer
    than :data:`horsemocap.streaming.WHOLE_RECORD_FRAMES` frames is smoothed in
    windows (:mod:`horsemocap.pose_windows`), said in a progress line and in
    ``analysis.json`` (``chosen.pose_windows``).
    """
    fits, pose = section.fits, section.pose
    positions, static, mframe = motion.positions, motion.static, motion.frame
    t = time_axis(len(positions), session.fps)
    pose_t, pose_points = None, to_motion_frame(raw, mframe)
    lo, hi = a, b = triangulated.segment
    name = lambda first, last: frames_text(session.reference_camera, offsets, first, last)  # noqa: E731
    if section.kinematics == "pose_spline" and pose.partial_frames:
        lo, hi = pose_margin(triangulated.points, triangulated.segment)
        if (lo, hi) != (a, b):
            pose_points = to_motion_frame(triangulated.points[lo:hi], mframe)
            pose_t = np.arange(lo - a, hi - a) / float(session.fps)
            progress("rigid_body", f"pose trajectory smoothed over {name(lo, hi - 1)}: {a - lo} before and "
                                   f"{hi - b} after the analysed frames have two markers (reported: {name(a, b - 1)})")
    cov = triangulated.covariance if pose.weights == "covariance" else None
    if cov is not None:   # the markers' covariances in the motion frame (x_M = A (x - o): A C A^T)
        cov = motion.axes @ cov[lo:hi] @ motion.axes.T
    period = motion.period_frames
    if section.kinematics == "fits" and positions.shape[1] != 3:
        raise AnalysisError("rigid_body", f"parameter 'kinematics': 'fits' is the thesis' chain of three markers "
                                          f"(eq. 6.3-6.55), {session.json_path} 'markers.count' says "
                                          f"{positions.shape[1]}: use 'pose_spline' (registration over every "
                                          "marker seen in a frame)")
    try:     # the parameter file's form parsed once (markers, orientation, saddle path)
        given_orders = FourierOrders.from_param(fits.fourier_orders, positions.shape[1])
    except ValueError as exc:   # "fourier_orders: expected ...", named as every parameter is
        raise AnalysisError("rigid_body", f"parameter 'fourier_orders'{str(exc).removeprefix('fourier_orders')}") from None
    _check_pose_events(pose.events, t if pose_t is None else pose_t)
    try:
        rb = analyse_rigid_body(
            t, positions, static, section, period_s=None if period is None else period / session.fps,
            fourier_orders=given_orders,
            pose_input=PoseInput(points=pose_points, t=pose_t, covariance=cov, settled=settled,
                                 aperture=session_aperture(session.fps, {c: session.camera_timing(c)
                                                                         for c in session.cameras})),
            thesis_chain=thesis_chain)
    except CollinearMarkersError as exc:
        raise AnalysisError("rigid_body", f"{exc} (static shot of {session.json_path})") from None
    except ChangePointError as exc:
        raise AnalysisError("rigid_body", f"parameter 'pose_events': {exc}") from None
    orders = np.asarray(rb.motion_fit.orders)[:, 1:] if rb.motion_fit is not None else None
    pos, vel, acc = rb.marker_kinematics
    cond = conditioning(rb)
    _report(section, rb, cond, orders, progress)
    _report_left_out(rb.left_out, lo, name, progress)
    if rb.model_choice is not None:
        progress("rigid_body", f"marker model: {rb.model_choice.source} ({rb.model_choice.reason})")
    return RigidBodyResult(
        body=rb, t=t, registered=pos, model=rb.model, saddle_static=rb.static_saddle,
        static_order=[int(i) for i in rb.static_index], saddle_index=int(rb.saddle_index),
        velocity=vel, acceleration=acc, orders=orders, omega=rb.omega, alpha=rb.alpha,
        saddle_position=rb.saddle_position,
        saddle_velocity=rb.saddle_velocity, saddle_acceleration=rb.saddle_acceleration, conditioning=cond,
        saddle_angles_deg=saddle_angles(rb))


def _report(section: RigidBodyParams, rb: RigidBodyAnalysis, cond: Conditioning, orders, progress) -> None:
    """The step's progress lines: the smoothing chosen (pose) or the orders (fits), the conditioning, warnings."""
    fits, pose = section.fits, section.pose
    if section.kinematics == "pose_spline":
        sm = rb.pose.smoothing
        ran = rb.pose.smoothing_choice
        how = (f"{ran['method']} smoothing ({pose.smoothing}: {ran['reason']})" if ran
               else f"{pose.smoothing} smoothing")
        progress("rigid_body", f"pose trajectory ({how}, effective degrees of "
                 f"freedom per component " + ", ".join(f"{k} {v['edf']:.1f}" for k, v in sm.items())
                 + f"); registration residual median {1000 * np.nanmedian(cond.registration_rms_m):.2f} mm")
        weighted = [k + (" (in one of the two blended fits)" if v.get("weights") == ONE_ROUTE_WEIGHTS
                         else "") for k, v in sm.items() if v.get("weights", "equal") != "equal"]
        if weighted:
            progress("rigid_body", "rotation smoothed with each frame weighted by its predicted variance (its noise "
                                   f"model explains the residuals better) in {', '.join(weighted)}")
        f0 = [v["fundamental_hz"] for v in sm.values() if v.get("fundamental_hz")]
        if f0:
            blend = [v["blend_weights"][1] for v in sm.values() if v.get("blend_weights")]
            held = (f" in a fit blended with the plain one at weight {blend[0]:.2f}" if blend and
                    len(set(blend)) == 1 else " in fits blended with the plain ones" if blend else "")
            progress("rigid_body", f"stride harmonics of {f0[0]:.3f} Hz kept unpenalised{held}, per component "
                     + ", ".join(f"{k} {_harmonics_text(v)}" for k, v in sm.items()))
        if pose.events:
            progress("rigid_body", "acceleration free to jump at the known change points (pose_events) "
                     + ", ".join(f"{e:g}" for e in sorted(pose.events)) + " s")
        if rb.pose.windows is not None:
            progress("rigid_body", f"pose trajectory of a long pass: {rb.pose.windows.text()}; the degrees of "
                                   "freedom above are the middle window's, the windows blended over their overlaps")
        if rb.chain_error:
            progress("rigid_body", f"the thesis' chain of fits was not computed: {rb.chain_error}")
    else:
        progress("rigid_body", f"Fourier orders (y, z) per marker {orders.tolist()}; omega by {fits.angular_method}, "
                               f"saddle by {fits.saddle_method}")
    sing = float(np.nanmin(np.abs(90 - cond.singularity_deg)))
    progress("rigid_body", f"closest approach to the eq. 6.35 singularity {sing:.1f} deg; smallest marker "
                           f"triangle height {1000 * np.nanmin(cond.triangle_height_m):.1f} mm")
    for w in cond.warnings:
        progress("rigid_body", "WARNING: " + w)


def _report_left_out(left_out, first: int, name, progress) -> None:
    """A progress line per marker left out of the pose for moving against the others' rigid motion.

    ``left_out``: (N, m) bool of the pose frames, the first of which is synchronised frame ``first``;
    ``name(a, b)`` names frames a..b.
    """
    if left_out is None or not np.any(left_out):
        return
    for m in np.flatnonzero(left_out.any(axis=0)):
        rows = np.flatnonzero(left_out[:, m])
        progress("rigid_body", f"marker {m} left out of the pose in {rows.size} frames of "
                               f"{name(first + int(rows[0]), first + int(rows[-1]))}: its position moved against "
                               "the other markers' rigid motion (partly covered alike in every view that sees it?); "
                               "the others gave the pose there")


def _harmonics_text(info: dict) -> str:
    """How many stride harmonics a pose component kept, with their orders when they are not 1..K."""
    n = int(info.get("harmonics", 0))
    orders = [int(k) for k in info.get("harmonic_indices", range(1, n + 1))]
    return str(n) if orders == list(range(1, n + 1)) else f"{n} (order {', '.join(map(str, orders))})"


def _check_pose_events(events, times) -> None:
    """Refuse ``pose_events`` outside the smoothed record (:class:`AnalysisError` naming the parameter)."""
    if not events:
        return
    lo, hi = float(times[0]), float(times[-1])
    outside = [e for e in events if not lo < e < hi]
    if outside:
        raise AnalysisError("rigid_body", f"parameter 'pose_events': {outside} s outside the smoothed record: expected "
                                          f"times strictly inside ({lo:.6g}, {hi:.6g}) s, the time_s axis of "
                                          "trajectories.csv (0 = the first analysed frame)")


def pose_margin(points: np.ndarray, segment, min_markers: int = 2) -> tuple[int, int]:
    """Frames next to the analysed segment in which at least ``min_markers`` markers have a 3D position.

    The analysed segment ends where a marker is lost; the frames just beyond
    it in which two markers are still triangulated carry five of the pose's
    six degrees of freedom (:func:`horsemocap.pose.partial_pose`). Returns
    ``(lo, hi)``: the segment ``(a, b)`` widened over the contiguous runs of
    such frames on both sides.

    Examples
    --------
    >>> pts = np.zeros((5, 3, 3)); pts[0, :2] = np.nan; pts[4, :] = np.nan
    >>> pose_margin(pts, (1, 4))
    (1, 4)
    >>> pts[0, 1] = 0.0
    >>> pose_margin(pts, (1, 4))
    (0, 4)
    """
    count = np.all(np.isfinite(np.asarray(points, float)), axis=2).sum(1)
    lo, hi = segment
    while lo > 0 and count[lo - 1] >= min_markers:
        lo -= 1
    while hi < count.size and count[hi] >= min_markers:
        hi += 1
    return int(lo), int(hi)
