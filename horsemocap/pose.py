"""Pose-trajectory kinematics of a rigid body (not in the thesis; `kinematics="pose_spline"`).

The thesis (sections 5.4, 5.5 and 6) registers the static shot to the
markers, fits every marker coordinate with a polynomial (x) or a Fourier
series (y, z), differentiates the fits and recovers omega and alpha from
three markers (eq. 6.3/6.4, 6.38/6.39), then the saddle (eq. 6.54/6.55). That
chain needs a periodic record, fits each marker on its own (their relative
velocities, which carry omega, are then not those of a rigid body), and it
has the singularity of eq. 6.35. Here the rigid body is treated as one
object throughout:

1. **Per-frame pose** (:func:`register_pose`): the static-shot model is
   registered to *all visible* markers of the frame (weighted Horn / Besl-
   McKay, eq. 5.14-5.21 with weights), ``x_m(t) = R(t) X_m + t(t)``. A frame
   with a missing marker still has a pose while at least 3 non-collinear
   markers remain; otherwise it is NaN with the reason. Given each marker's
   3 x 3 covariance (the pipeline's: the triangulation's, whose depth along
   the viewing rays is several times less certain than the directions across
   them), Horn's pose is refined by Gauss-Newton on SE(3) with each marker
   weighted by its inverse covariance (plus an isotropic part estimated from
   the residuals, :func:`extra_marker_noise`), and the pose noise that the
   smoothing tests the rotation's harmonics against (:func:`pose_noise`)
   comes from the same covariances.
2. **Smoothing of the pose trajectory** (:func:`fit_pose_trajectory`): the
   position of the model's centroid ``c(t)`` and the rotation written as
   ``R(t) = Exp(phi(t)) R_ref(t)`` (``R_ref`` the mean rotation, or, for a
   body that turns far, a smooth reference that turns with it about its main
   axis, :func:`rotation_reference`; ``phi`` the rotation vector in the
   motion frame, unwrapped so that it is continuous: no singularity at any
   number of turns)
   are smoothed component by component with a smoothing spline whose
   smoothing parameter is chosen from the data by generalised
   cross-validation (:func:`horsemocap.splines.smoothing_spline`). With
   ``harmonics="auto"`` (default) each component is a partial spline: the
   harmonics of the stride frequency (estimated from the record,
   :func:`horsemocap.splines.estimate_fundamental`) are not penalised, and
   their number, zero for a record that is not periodic, is chosen with the
   smoothing; a steady gait keeps its higher harmonics and the spline's end
   effects act only on the non-periodic remainder. Nothing requires a
   period: a transition or a lift keeps the plain spline.
   Frames without a pose are bridged by the spline when the gap is short
   (``max_gap_s``) and NaN with the reason otherwise. Frames with only two
   markers (beyond the ends of a record, where a marker leaves the view)
   can join the smoothing (``partial_frames``, :func:`partial_pose`): two
   markers fix five of the six degrees of freedom, the rotation about
   their line comes from the smoothed trajectory, and the spline's natural
   boundary conditions, which bias the acceleration in a record's last
   frames, then act beyond the frames that are reported.
3. **Analytic derivatives** (:class:`PoseTrajectory`): ``v_c = c'``,
   ``a_c = c''``; ``omega = J_l(phi) phi'`` and ``alpha = J_l(phi) phi'' +
   J_l'(phi) phi'`` with the left Jacobian of SO(3) (plus the moving
   reference's own turning, :meth:`PoseTrajectory.omega`); any body point ``d``
   (model coordinates relative to the centroid) has ``r = R d``,
   ``v = v_c + omega x r``, ``a = a_c + alpha x r + omega x (omega x r)``
   (eq. 6.54/6.55 with the body's own omega and alpha).

The smoothing's choices (:class:`horsemocap.params.PoseParams`, read by
:func:`fit_pose_trajectory`):

- ``smoothing``: ``"auto"`` (:func:`choose_smoothing`: ``"gcv"`` with the
  stride harmonics on a periodic record, ``"adaptive"`` on a record without a
  fundamental or with known change points); ``"gcv"`` (generalised
  cross-validation); ``"gcv_cubic"`` (the same with a cubic spline; the
  quintic leaves the acceleration free at the record's ends); ``"adaptive"``
  (GCV, then a penalty weighted by the local roughness); ``"noise"``
  (unbiased risk with each component's noise from the registration
  residuals, :func:`pose_noise`: with 3 markers the residuals cannot see the
  noise normal to their plane, so it undersmooths; for 4 or more markers);
  ``"none"`` (interpolation).
- ``harmonics``: ``"auto"`` and ``"all"`` make each component a partial
  spline (unpenalised stride harmonics plus a smoothing spline of the
  remainder, their number chosen with the smoothing). ``"auto"`` tries, for
  the rotation vector, only the harmonics below the plain spline's cutoff
  frequency and keeps one only when its amplitude exceeds the rotation noise
  predicted from the registration residual and the marker geometry
  (:func:`pose_noise`): the rotation is seen through the markers' small
  differences, and a periodic error of the measurement (a detection bias,
  skin movement repeating with the stride) does not average out; the
  centroid keeps every harmonic below 0.4 of the sampling rate (the trots'
  higher harmonics of the vertical motion, which a plain spline flattens).
  ``"none"``: plain smoothing splines. Harmonics go with ``"gcv"`` or
  ``"noise"`` (quintic) only.
- ``partial_frames``: also smooth over the frames with exactly two markers.
- ``rotation_weights``: ``"auto"``: with a registration that carries the
  pose's information matrices (:func:`register_pose` with ``covariance``) and
  ``"gcv"`` (quintic; under correlated noise too where the smoothing is
  chosen by leaving markers out, four or more markers: a frame whose pose
  rests on fewer markers, one of four covered, weighs less; the parameters
  are those the left-out search chose with equal weights, the weights of
  mean 1), each rotation component is fitted twice, with every
  frame weighted by its predicted variance (:func:`frame_variances`,
  robustly: :func:`horsemocap.splines.robust_weighted_spline`, the
  harmonics' noise test at its calibrated noise level) and with equal
  weights, and the fit whose noise model explains its residuals better
  (:func:`horsemocap.splines.residual_log_likelihood`) is kept: the
  predicted rotation noise varies several-fold between frames, and where
  the prediction holds the weights take the few bad frames out; where it
  does not (roll and yaw under a thin marker triangle) the equal weights
  are kept. ``"equal"``: equal weights.
- ``events``: known change points (s; an impact's onset from a force plate
  or an accelerometer): an unpenalised ``(t - tau)_+^2`` at each, so that the
  acceleration may jump there (``events`` of
  :func:`horsemocap.splines.smoothing_spline`); with ``"gcv"`` without
  harmonics or ``"adaptive"``, quintic. Not detected from the data.
- ``correlated_noise_criterion``: how ``"auto"`` chooses the smoothing under
  correlated noise: ``"loo"`` (each marker left out in turn,
  :func:`marker_cross_validation_per_component`; four or more markers),
  ``"gcv"`` (the correlated-error GCV), ``"reml"`` or ``"risk"``
  (:class:`horsemocap.params.PoseParams` says what each does). ``"loo"``
  chooses the smoothing of plain splines and of partial splines with the
  stride's harmonics, and fits their blend (stacking,
  :data:`LEFT_OUT_STACK`, :func:`left_out_stacking_weights`): the weight
  minimises the same left-out loss. Settled on one record
  (:func:`settle_pose_smoothing`), the blend is reused whole on others of
  the same motion: both routes at their parameters, blended with its weight.

Conditioning (:func:`smallest_height`, :func:`check_model_conditioning`): a
rotation about the line through two markers is seen only through the third
marker's distance from that line; with a marker-position noise ``sigma`` the
rotation's noise is about ``sigma / h`` (``h`` the triangle's smallest
height). Collinear markers (``h`` zero, or below the noise) are refused.

Rotations are SciPy's :class:`scipy.spatial.transform.Rotation`; Horn's
quaternion comes from :mod:`horsemocap.registration`.

Symbols: ``R``, ``t`` pose (thesis ``RR^-1``, ``-RR^-1 Q_t``), ``phi``
rotation vector, ``omega``/``alpha`` (thesis ``omega``, ``alfa``) in the
motion frame, ``h`` smallest height of the marker triangle.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import make_lsq_spline
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from .params import PoseParams
from .probability import f_survival
from .registration import check_model, rotation_from_cross_covariance, skew
from .splines import (ChangePointError, blend_splines, estimate_fundamental, half_gain_frequency,
                      residual_log_likelihood, robust_weighted_spline, smoothing_spline)

__all__ = [
    "CollinearMarkersError",
    "PoseRegistration",
    "PoseTrajectory",
    "SettledPoseSmoothing",
    "settle_pose_smoothing",
    "PointKinematics",
    "smallest_height",
    "check_model_conditioning",
    "register_pose",
    "predicted_registration_rms",
    "marker_cross_validation",
    "left_out_noise_ratios",
    "marker_cross_validation_per_component",
    "stacking_weights",
    "left_out_stacking_weights",
    "refine_pose_covariance",
    "extra_marker_noise",
    "unwrap_rotvec",
    "RotationReference",
    "rotation_reference",
    "left_jacobian",
    "angular_velocity_from_rotvec",
    "angular_acceleration_from_rotvec",
    "fit_pose_trajectory",
    "rigidity_residual_correlation",
    "significant_noise_correlation",
    "conditioning_warnings",
    "ConditioningFigures",
    "conditioning_figures",
    "conditioning_messages",
    "ROTATION_NOISE_LIMIT_DEG",
    "frame_rotation_std",
    "rotation_noise_deg",
    "pose_noise",
    "frame_variances",
    "partial_pose",
    "two_marker_distance_departure",
    "static_body_axes",
    "saddle_angles_deg",
]


class CollinearMarkersError(ValueError):
    """The markers (static-shot model) are collinear: a rotation about their line is not observable."""


# --------------------------------------------------------------------------
# conditioning of a marker set
# --------------------------------------------------------------------------
def _triangle_heights(a, b, c):
    """Smallest height of triangles (..., 3) points a, b, c: 2 area / longest side."""
    ab, ac, bc = b - a, c - a, c - b
    area2 = np.linalg.norm(np.cross(ab, ac), axis=-1)
    longest = np.max(np.stack([np.linalg.norm(ab, axis=-1), np.linalg.norm(ac, axis=-1),
                               np.linalg.norm(bc, axis=-1)]), axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(longest > 0, area2 / longest, 0.0)


def smallest_height(points, mask=None) -> np.ndarray:
    """How far a marker set is from a line: the triangle's smallest height (m).

    For three markers it is the smallest of the triangle's three heights
    (``2 area / longest side``); for more markers, the largest such value
    over all triples (the best triangle the set holds). Rotations about the
    direction of a thin triangle are observed only through this height.

    Parameters
    ----------
    points : (m, 3) or (n, m, 3)
    mask : (m,) or (n, m) bool, optional
        Markers to use (visible ones); a set of fewer than 3 gives 0.

    Returns
    -------
    float or (n,) array

    Examples
    --------
    >>> round(smallest_height([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), 4)     # 1 / sqrt(2)
    0.7071
    """
    p = np.asarray(points, float)
    single = p.ndim == 2
    if single:
        p = p[None]
    n, m, _ = p.shape
    if mask is None:
        mask = np.all(np.isfinite(p), axis=-1)
    mask = np.broadcast_to(np.asarray(mask, bool), (n, m))
    out = np.zeros(n)
    for i, j, k in itertools.combinations(range(m), 3):
        ok = mask[:, i] & mask[:, j] & mask[:, k]
        if ok.any():
            h = _triangle_heights(p[ok, i], p[ok, j], p[ok, k])
            out[ok] = np.maximum(out[ok], h)
    return float(out[0]) if single else out


def check_model_conditioning(model, noise_m: float | None = None, name: str = "static shot") -> float:
    """Refuse a collinear marker model; return its smallest height (m).

    Raises :class:`CollinearMarkersError` when the model's best triangle has a
    smallest height below 1e-3 of its size (collinear to numerical
    precision) or, if ``noise_m`` (marker-position noise) is given, below 3
    times that noise (the triangle cannot be told from a line).

    Examples
    --------
    >>> round(check_model_conditioning([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), 4)
    0.7071
    >>> try:
    ...     check_model_conditioning([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    ... except CollinearMarkersError:
    ...     print("refused: collinear")
    refused: collinear
    """
    x = np.asarray(model, float)
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 3:
        raise ValueError(f"{name}: expected at least 3 markers (m, 3), got shape {x.shape}")
    h = smallest_height(x)
    size = float(np.max(np.linalg.norm(x[:, None] - x[None], axis=-1)))
    if size <= 0 or h < 1e-3 * size:
        raise CollinearMarkersError(
            f"{name}: the markers are collinear (smallest triangle height {1000 * h:.3g} mm over a size of "
            f"{1000 * size:.3g} mm); a rotation about their line cannot be measured; place one marker off the "
            "line through the others")
    if noise_m is not None and np.isfinite(noise_m) and h < 3 * noise_m:
        raise CollinearMarkersError(
            f"{name}: the markers are nearly collinear: smallest triangle height {1000 * h:.3g} mm is below 3 "
            f"times the marker noise ({1000 * noise_m:.3g} mm); a rotation about their line cannot be measured")
    return h


# --------------------------------------------------------------------------
# per-frame registration of all visible markers
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class PoseRegistration:
    """Per-frame pose of the model (:func:`register_pose`).

    Attributes
    ----------
    rotation : (n, 3, 3)
        ``R(t)``: ``registered = model @ R.T + translation``; NaN where no pose.
    translation : (n, 3)
    centre : (n, 3)
        The model's centroid moved by the pose, ``c = R mean(model) + t``.
    registered : (n, m, 3)
        The model moved by the pose (every marker, visible or not).
    residual : (n, m)
        Distance of each visible marker from its registered position (m); NaN
        where the marker is missing.
    rms : (n,)
        Weighted RMS residual of the visible markers (plain RMS with ``covariance``).
    n_markers : (n,) int
        Markers used in the frame.
    height : (n,)
        :func:`smallest_height` of the model markers used (m).
    reason : (n,) str
        ``""`` where a pose was found, otherwise why not.
    noise_m : float
        Marker-position noise estimated from the residuals, ``sqrt(sum w r^2 /
        sum dof)`` with ``3 k - 6`` degrees of freedom per frame of k markers
        (isotropic noise assumed), NaN if no frame has more than 2 markers.
    information : (n, 6, 6) or None
        With ``covariance``: the inverse of the pose's covariance per frame,
        ``sum_m A_m^T Sigma_m^-1 A_m`` with ``A_m = [I, -[r_m]x]`` (``r_m`` the
        marker about the model's centroid, rotated), for the centroid
        ``centre`` and a small rotation ``R -> Exp(dphi) R`` (motion frame);
        NaN where no pose. None without ``covariance``.
    covariance_scale : float
        With ``covariance``: ``sqrt(sum e^T Sigma^-1 e / sum (3 k - 6))`` over the
        frames with the given covariances, about 1 when they describe the markers'
        noise (their in-plane part: three markers cannot show the rest); NaN otherwise.
    extra_noise_m : float
        With ``covariance``: the isotropic noise ``s0`` (m) added to every
        marker's covariance, ``Sigma_m + s0^2 I`` (:func:`extra_marker_noise`;
        0 when the given covariances explain the residuals); NaN otherwise.
    """

    rotation: np.ndarray
    translation: np.ndarray
    centre: np.ndarray
    registered: np.ndarray
    residual: np.ndarray
    rms: np.ndarray
    n_markers: np.ndarray
    height: np.ndarray
    reason: np.ndarray
    noise_m: float
    information: np.ndarray | None = field(default=None, repr=False)
    covariance_scale: float = float("nan")
    extra_noise_m: float = float("nan")
    marker_covariance: np.ndarray | None = field(default=None, repr=False)


def _check_covariance(covariance, vis, n, m) -> np.ndarray:
    """Marker covariances (n, m, 3, 3), symmetric, the identity where a marker is missing; clear errors."""
    C = np.asarray(covariance, float)
    if C.shape != (n, m, 3, 3):
        raise ValueError(f"covariance: expected (frames, markers, 3, 3) = {(n, m, 3, 3)}, got shape {C.shape}")
    bad = vis & ~np.all(np.isfinite(C), axis=(2, 3))
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise ValueError(f"covariance: not finite for visible marker {j + 1} in frame {k} "
                         f"({int(bad.sum())} such marker position(s))")
    Cs = np.where(vis[..., None, None], C, np.eye(3))
    Cs = 0.5 * (Cs + np.swapaxes(Cs, -1, -2))
    ev = np.linalg.eigvalsh(Cs)
    bad = vis & ~(ev[..., 0] > 1e-12 * np.maximum(ev[..., -1], 1e-300))
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise ValueError(f"covariance: not positive definite for visible marker {j + 1} in frame {k} "
                         f"(eigenvalues {ev[k, j].tolist()})")
    return Cs


def _pose_normal_equations(p, d, W, R, c):
    """``sum A^T W A`` (k, 6, 6) and ``sum A^T W e`` (k, 6) of ``e_m = p_m - c - R d_m``, ``A_m = [I, -[R d_m]x]``."""
    r = np.einsum("kij,mj->kmi", R, d)
    e = _pose_residual(p, c, r)
    A = np.concatenate([np.broadcast_to(np.eye(3), r.shape + (3,)), -skew(r)], axis=-1)   # (k, m, 3, 6)
    WA = W @ A
    N = np.einsum("kmia,kmib->kab", A, WA)
    b = np.einsum("kmia,kmi->ka", WA, e)
    return N, b, e


def _pose_cost(p, d, W, R, c):
    """``sum_m e_m^T W_m e_m`` per frame (k,) of ``e_m = p_m - c - R d_m``."""
    e = _pose_residual(p, c, np.einsum("kij,mj->kmi", R, d))
    return np.einsum("kmi,kmij,kmj->k", e, W, e)


def _pose_residual(p, c, r):
    """``e_m = p_m - c - r_m`` (k, m, 3) with ``r_m = R d_m``; 0 in place of a missing marker's position."""
    return np.where(np.isfinite(p), p, 0.0) - c[:, None] - r


def refine_pose_covariance(points, model, information, rotation, centre, iterations: int = 10,
                           tolerance: float = 1e-12, halvings: int = 20):
    """Gauss-Newton on SE(3) for the pose that minimises ``sum_m e_m^T W_m e_m`` (all frames at once).

    ``e_m = p_m - c - R (X_m - mean(X))``: each marker weighted by its 3 x 3
    information matrix ``W_m`` (inverse covariance; zero for a missing
    marker), so a coordinate measured poorly (a camera rig's depth) counts
    less than a well-measured one. Each step solves the 6 x 6 normal
    equations ``(sum A^T W A) delta = sum A^T W e`` with ``A_m = [I, -[r_m]x]``
    and updates ``c += delta[:3]``, ``R = Exp(delta[3:]) R``; a step that
    raises the cost is halved (up to ``halvings`` times, else the frame keeps
    its pose), so the result is never worse than the start (Horn's) in the
    weighted cost, also where the errors are too large for the linearisation. A frame
    stops when its largest step is below ``tolerance`` (m or rad).

    Parameters
    ----------
    points : (k, m, 3)
    model : (m, 3)
    information : (k, m, 3, 3)
    rotation : (k, 3, 3), centre : (k, 3)
        The start (e.g. Horn's), ``centre`` the model's centroid moved by it.

    Returns
    -------
    rotation : (k, 3, 3), centre : (k, 3), normal : (k, 6, 6)
        The pose and ``sum A^T W A`` at it (the pose's information matrix).

    Examples
    --------
    Exact markers, started 0.1 rad off: the refined pose is the true one (the identity).

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> start = Rotation.from_rotvec([0, 0, 0.1]).as_matrix()[None]
    >>> R, c, _ = refine_pose_covariance(model[None], model, np.broadcast_to(np.eye(3), (1, 3, 3, 3)), start,
    ...                                  model.mean(0)[None])
    >>> bool(np.allclose(R[0], np.eye(3))), bool(np.allclose(c[0], model.mean(0)))
    (True, True)
    """
    p = np.asarray(points, float)
    x = np.asarray(model, float)
    d = x - x.mean(0)
    W = np.asarray(information, float)
    R = np.array(rotation, float)
    c = np.array(centre, float)
    cost = _pose_cost(p, d, W, R, c)
    active = np.ones(len(p), bool)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        N, b, _ = _pose_normal_equations(p[idx], d, W[idx], R[idx], c[idx])
        step = np.linalg.solve(N, b[..., None])[..., 0]
        todo = np.arange(idx.size)
        for _ in range(halvings + 1):
            k = idx[todo]
            Rn = Rotation.from_rotvec(step[todo, 3:]).as_matrix() @ R[k]
            cn = c[k] + step[todo, :3]
            new = _pose_cost(p[k], d, W[k], Rn, cn)
            better = new <= cost[k] * (1 + 1e-12) + 1e-300
            R[k[better]], c[k[better]], cost[k[better]] = Rn[better], cn[better], new[better]
            todo = todo[~better]
            if todo.size == 0:
                break
            step[todo] *= 0.5
        stuck = idx[todo]                                  # no descent along the step: converged
        small = np.max(np.abs(step), axis=1) < tolerance
        active[idx[small]] = False
        active[stuck] = False
    N, _, _ = _pose_normal_equations(p, d, W, R, c)
    return R, c, N


def extra_marker_noise(residuals, covariance, dof: float) -> float:
    """Isotropic marker noise ``s0`` (m) that the given covariances leave unexplained.

    The markers' error is the detection noise carried through the
    triangulation (``covariance``) plus errors that it does not hold: the
    static shot's own error, the calibration's, markers moving on the skin.
    With no preferred direction known for them they are modelled as
    ``s0^2 I``; ``s0`` is chosen so that the residuals' chi-square
    per degree of freedom is 1, ``sum_m e_m^T (Sigma_m + s0^2 I)^-1 e_m = dof``
    (a variance-component estimate; 0 when the covariances alone already
    explain the residuals). Solved by Brent's method on the eigenvalues of
    each ``Sigma_m``.

    Parameters
    ----------
    residuals : (K, 3)
        Residual vectors of the registered markers (the visible ones of the frames with a pose).
    covariance : (K, 3, 3)
        Their covariances.
    dof : float
        Residual degrees of freedom (``sum 3 k - 6`` over the frames).

    Returns
    -------
    float

    Examples
    --------
    Residuals of 1 mm that covariances of 1 um do not explain (4 residual degrees of freedom):

    >>> import numpy as np
    >>> e = np.tile([0.001, 0.0, 0.0], (4, 1))
    >>> round(1000 * extra_marker_noise(e, np.tile(1e-12 * np.eye(3), (4, 1, 1)), 4.0), 4)
    1.0
    """
    e = np.asarray(residuals, float)
    lam, U = np.linalg.eigh(np.asarray(covariance, float))
    z2 = np.einsum("kij,ki->kj", U, e) ** 2
    if dof <= 0 or not np.all(np.isfinite(z2)):
        return float("nan")

    def excess(s2):
        return float(np.sum(z2 / (lam + s2))) - dof

    if excess(0.0) <= 0:
        return 0.0
    hi = float(np.sum(z2)) / dof          # excess(hi) < 0: sum z2 / (lam + hi) < sum z2 / hi = dof
    return float(np.sqrt(brentq(excess, 0.0, hi, xtol=1e-12 * hi, rtol=1e-10)))


def predicted_registration_rms(registration: PoseRegistration) -> np.ndarray:
    """Each frame's registration RMS residual that the markers' own covariances predict (m).

    With ``k`` markers of covariances ``Sigma_m`` registered by a rigid pose
    (6 parameters), the residuals keep ``3 k - 6`` of the ``3 k`` degrees of
    freedom of the markers' noise, so the expected mean squared residual
    distance is about ``mean_m tr(Sigma_m) (3 k - 6) / (3 k)``: the residual
    the noise alone leaves when the markers are rigid. Compared with
    :attr:`PoseRegistration.rms` it tells a residual the triangulation's
    scatter explains from one it does not (a marker that moves on the body,
    a marker taken for another). The covariances come from the session's own
    reprojection residuals, so anything that makes the cameras' views
    disagree (a wrong sync offset) raises the prediction too.

    Parameters
    ----------
    registration : PoseRegistration
        A registration made with ``covariance`` (:func:`register_pose`).

    Returns
    -------
    (n,) array
        NaN where the frame has no pose, and everywhere without covariances.

    Examples
    --------
    Four markers with 2 mm of isotropic noise per axis: 2 x sqrt(3 x 6 / 12) = 2.45 mm.

    >>> import numpy as np
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1], [0.0, 0.0, 0.25]])
    >>> pts = np.repeat(model[None], 2, axis=0)
    >>> cov = np.tile(4e-6 * np.eye(3), (2, 4, 1, 1))
    >>> reg = register_pose(pts, model, covariance=cov)
    >>> np.round(1000 * predicted_registration_rms(reg), 2).tolist()
    [2.45, 2.45]
    """
    n = len(registration.rms)
    cov = registration.marker_covariance
    if cov is None:
        return np.full(n, np.nan)
    used = np.isfinite(registration.residual)
    k = used.sum(1)
    trace = np.where(used, np.trace(np.asarray(cov, float), axis1=2, axis2=3), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.sqrt(trace.sum(1) / k * (3 * k - 6) / (3 * k))
    out[(k < 3) | ~np.isfinite(registration.rms)] = np.nan
    return out


def register_pose(points, model, weights=None, min_height_m: float | None = None,
                  covariance=None, extra_noise: str | float = "estimate", names=None) -> PoseRegistration:
    """Register the static-shot model to every frame's visible markers.

    Weighted form of Horn's closed-form quaternion solution (eq. 5.14-5.21):
    with weights ``w_m`` (zero for a missing marker) the centroids are
    weighted means and the cross-covariance is ``S = sum_m w_m (X_m - mu_X)
    (x_m - mu_x)^T``; the eigenvector of the largest eigenvalue of ``Q(S)``
    is the optimal unit quaternion. With ``covariance`` (each marker's 3 x 3
    covariance, e.g. from the triangulation: a rig measures depth far worse
    than the directions across the rays) Horn's solution with the inverse
    mean variances as weights is refined by Gauss-Newton on SE(3) to the
    pose of smallest ``sum e^T Sigma^-1 e`` (:func:`refine_pose_covariance`);
    the pose's information matrix per frame is kept for :func:`pose_noise`.

    Parameters
    ----------
    points : (n, m, 3)
        Measured markers (NaN where missing).
    model : (m, 3)
        The same markers in the static shot (refused if collinear,
        :func:`check_model_conditioning`).
    weights : (m,) or (n, m), optional
        Inverse variances of the markers (larger = more trusted); equal by default.
    min_height_m : float, optional
        A frame whose visible markers' smallest height is below this is left
        NaN (reason ``"visible markers nearly collinear"``); default 1e-3 of
        the model's size.
    covariance : (n, m, 3, 3), optional
        Each marker's covariance (m^2, same frame as ``points``); finite and
        positive definite where the marker is visible. Not with ``weights``.
    extra_noise : "estimate" or float
        With ``covariance``: an isotropic noise ``s0`` (m) added to every
        marker's covariance, ``Sigma_m + s0^2 I``, for the errors the
        covariances do not hold (the static shot's, the calibration's);
        ``"estimate"`` (default) chooses it from the residuals
        (:func:`extra_marker_noise`, alternating with the registration until
        it changes by less than 1 %). With exact detections the residuals are
        such errors only and the weighting becomes Horn's; with detection
        noise well above them it is the covariances'.
    names : sequence of str, optional
        The markers' names, for the reasons of frames without a pose
        (default ``marker1``, ``marker2``, ...).

    Returns
    -------
    PoseRegistration

    Examples
    --------
    Four markers, the model turned by 90 degrees about z; in the second frame one
    marker is missing and the other three still give the pose:

    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0], [0.3, 0.1, 0.2]])
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> points = np.repeat((model @ turn.T)[None], 2, axis=0)
    >>> points[1, 3] = np.nan
    >>> reg = register_pose(points, model)
    >>> reg.n_markers.tolist(), bool(np.allclose(reg.rotation, turn))
    ([4, 3], True)
    """
    p = np.asarray(points, float)
    if p.ndim != 3 or p.shape[2] != 3:
        raise ValueError(f"points: expected an array (frames, markers, 3), got shape {p.shape}")
    n, m, _ = p.shape
    x = check_model(model, m)
    check_model_conditioning(x)
    size = float(np.max(np.linalg.norm(x[:, None] - x[None], axis=-1)))
    if min_height_m is None:
        min_height_m = 1e-3 * size
    vis = np.all(np.isfinite(p), axis=2)
    w, cov = _marker_weights(weights, covariance, extra_noise, vis)
    used = w > 0
    k = used.sum(1)
    height = smallest_height(np.broadcast_to(x, (n, m, 3)), used)
    ok = (k >= 3) & (height >= min_height_m)
    reason = _no_pose_reasons(ok, used, height, names)
    wn = np.where(ok[:, None], w, 1.0)
    wn = wn / wn.sum(1, keepdims=True)
    pp = np.where(used[:, :, None], p, 0.0)
    mu_p = np.einsum("km,kmi->ki", wn, pp)
    mu_x = wn @ x
    xc = x[None] - mu_x[:, None]
    pc = pp - mu_p[:, None]
    S = np.einsum("km,kmi,kmj->kij", wn, xc, pc)
    R = rotation_from_cross_covariance(S).as_matrix()      # Horn's method
    t = mu_p - np.einsum("kij,kj->ki", R, mu_x)
    normal = None
    s0 = float("nan")
    if cov is not None:
        normal = np.full((n, 6, 6), np.nan)
        if ok.any():
            R[ok], c1, normal[ok], s0 = _register_covariance(pp[ok], x, cov[ok], used[ok], R[ok], t[ok],
                                                             extra_noise)
            t[ok] = c1 - np.einsum("kij,j->ki", R[ok], x.mean(0))
        w = used.astype(float)                   # residual summaries: plain (unweighted) markers
        wn = np.where(ok[:, None], w, 1.0)
        wn = wn / wn.sum(1, keepdims=True)
    reg = np.einsum("kij,mj->kmi", R, x) + t[:, None]
    R[~ok] = np.nan
    t[~ok] = np.nan
    reg[~ok] = np.nan
    res = np.linalg.norm(np.where(used[:, :, None], p, np.nan) - reg, axis=-1)
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nansum(wn * res ** 2, axis=1))
    rms[~ok] = np.nan
    centre = np.einsum("kij,j->ki", R, x.mean(0)) + t
    dof = np.where(ok, 3 * k - 6, 0)
    wm = np.where(used, w / np.where(k > 0, w.sum(1), 1)[:, None] * k[:, None], 0.0)   # mean weight 1
    num = np.nansum(np.where(ok[:, None] & used, wm * res ** 2, 0.0))
    noise = float(np.sqrt(num / dof.sum())) if dof.sum() > 0 else float("nan")
    scale = float("nan")
    if cov is not None and dof.sum() > 0:
        sel = used & ok[:, None]
        e = (p - reg)[sel]
        scale = float(np.sqrt(np.einsum("ki,kij,kj->", e, np.linalg.inv(cov[sel]), e) / dof.sum()))
    return PoseRegistration(rotation=R, translation=t, centre=centre, registered=reg, residual=res,
                            rms=rms, n_markers=k.astype(int), height=height, reason=reason.astype(str),
                            noise_m=noise, information=normal, covariance_scale=scale, extra_noise_m=s0,
                            marker_covariance=cov)


def _marker_weights(weights, covariance, extra_noise, vis):
    """Each visible marker's weight (n, m) (0 where missing) and the checked covariances (or None):
    Horn's start with covariances weights each marker by its inverse mean variance."""
    n, m = vis.shape
    cov = None
    if covariance is not None:
        if weights is not None:
            raise ValueError("weights and covariance: give one (a covariance holds the marker's weight)")
        if not (extra_noise == "estimate" or (np.isscalar(extra_noise) and float(extra_noise) >= 0)):
            raise ValueError(f"extra_noise: expected 'estimate' or a noise >= 0 (m), got {extra_noise!r}")
        cov = _check_covariance(covariance, vis, n, m)
        weights = 1.0 / np.trace(cov, axis1=2, axis2=3)   # Horn's start: inverse mean variances
    if weights is None:
        return vis.astype(float), cov
    w = np.broadcast_to(np.asarray(weights, float), (n, m)).copy()
    if np.any(w[vis] < 0) or not np.all(np.isfinite(w[vis])):
        raise ValueError("weights: expected finite non-negative marker weights")
    return np.where(vis, w, 0.0), cov


def _no_pose_reasons(ok, used, height, names) -> np.ndarray:
    """Why each frame without a pose has none (``""`` where it has one), (n,) object."""
    k = used.sum(1)
    reason = np.full(ok.size, "", dtype=object)
    for i in np.flatnonzero(~ok):
        miss = np.flatnonzero(~used[i])
        if k[i] < 3:
            reason[i] = (f"only {k[i]} marker(s) visible (missing: "
                         + ", ".join(str(names[j]) if names is not None else f"marker{j + 1}" for j in miss)
                         + "); a pose needs 3 non-collinear markers")
        else:
            reason[i] = f"visible markers nearly collinear (smallest height {1000 * height[i]:.2g} mm)"
    return reason


def _register_covariance(points, model, cov, used, rotation, translation, extra_noise, rounds: int = 6):
    """Horn's pose refined with the markers' covariances plus the isotropic ``s0^2 I`` (given or estimated).

    Returns rotation, centre, the information matrices and ``s0``.
    """
    x = np.asarray(model, float)
    R = rotation
    c = np.einsum("kij,j->ki", R, x.mean(0)) + translation
    estimate = extra_noise == "estimate"
    s0 = 0.0 if estimate else float(extra_noise)
    dof = float(np.sum(3 * used.sum(1) - 6))
    d = x - x.mean(0)
    for _ in range(rounds):
        W = np.where(used[..., None, None], np.linalg.inv(cov + s0 ** 2 * np.eye(3)), 0.0)
        R, c, N = refine_pose_covariance(points, x, W, R, c)
        if not estimate:
            break
        e = _pose_residual(points, c, np.einsum("kij,mj->kmi", R, d))
        s_new = extra_marker_noise(e[used], cov[used], dof)
        if not np.isfinite(s_new) or abs(s_new - s0) <= 0.01 * s_new:
            break
        s0 = s_new
    return R, c, N, s0


# --------------------------------------------------------------------------
# SO(3): rotation vectors, left Jacobian and its derivative
# --------------------------------------------------------------------------
def unwrap_rotvec(phi) -> np.ndarray:
    """Make a sequence of rotation vectors (n, 3) continuous (NaN rows kept).

    ``phi`` and ``phi + 2 pi k phi/|phi|`` (any integer ``k``) are the same
    rotation; for each frame the representative closest to the previous
    finite frame is kept, so a rotation about a fixed axis stays continuous
    through 180 degrees and over any number of turns.

    Examples
    --------
    A rotation passing through 180 degrees about z:

    >>> unwrap_rotvec([[0.0, 0, 3.1], [0.0, 0, -3.1]])[:, 2].round(4)
    array([3.1   , 3.1832])

    Ten turns in steps of 0.5 rad stay one straight line:

    >>> from scipy.spatial.transform import Rotation
    >>> raw = Rotation.from_rotvec(np.outer(np.arange(130) * 0.5, [0, 0, 1])).as_rotvec()
    >>> float(unwrap_rotvec(raw)[-1, 2])
    64.5
    """
    phi = np.array(phi, float)
    prev = None
    for i in range(len(phi)):
        if not np.all(np.isfinite(phi[i])):
            continue
        if prev is not None:
            th = np.linalg.norm(phi[i])
            if th > 1e-12:
                u = phi[i] / th
                k0 = np.round((prev @ u - th) / (2 * np.pi))
                cands = [phi[i] + 2 * np.pi * (k0 + j) * u for j in (-1, 0, 1)]
                phi[i] = min(cands, key=lambda c: np.linalg.norm(c - prev))
        prev = phi[i]
    return phi


#: The six pose components, in the order of the splines (centroid, then rotation vector).
POSE_COMPONENTS = ("cx", "cy", "cz", "phix", "phiy", "phiz")


#: The largest rotation (rad) from the record's mean rotation for which the
#: rotation vector is taken about that one fixed reference; beyond it the
#: reference turns with the body (:func:`rotation_reference`).
FIXED_REFERENCE_MAX_ANGLE = np.pi / 2
#: The largest rotation (rad) of a frame from the moving reference that
#: :func:`rotation_reference` accepts before it gives the reference's angle more knots.
MOVING_REFERENCE_MAX_ANGLE = np.pi / 4
#: The moving reference is taken only where it at least halves the frames' median rotation from it.
MOVING_REFERENCE_GAIN = 0.5
#: The fewest frames per knot interval of the moving reference's angle.
MOVING_REFERENCE_MIN_FRAMES = 8


@dataclass(frozen=True)
class RotationReference:
    """The rotation ``R_ref(t) = Exp(theta(t) u) R_0`` about which the pose's rotation vector is taken.

    A fixed reference (``axis`` None) is ``R_0``; a moving one turns about
    the fixed axis ``u`` (motion frame) by the smooth angle ``theta(t)`` (a
    quintic spline), so that a body turning any number of times stays close to
    it and its rotation vector ``phi`` in ``R(t) = Exp(phi(t)) R_ref(t)``
    stays small, far from the singularities of ``Exp`` at ``|phi| = 2 pi k``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.interpolate import make_interp_spline
    >>> ref = RotationReference(np.eye(3), np.array([0, 0, 1.0]),
    ...                         make_interp_spline([0, 1, 2, 3], [0, 2.0, 4.0, 6.0], k=3))
    >>> ref.omega([1.5]).round(6)
    array([[0., 0., 2.]])
    """

    base: np.ndarray
    axis: np.ndarray | None = None
    angle: object = None

    def rotation(self, t) -> Rotation:
        """``R_ref(t)`` as a :class:`~scipy.spatial.transform.Rotation` of ``len(t)`` rotations."""
        t = np.atleast_1d(np.asarray(t, float))
        base = Rotation.from_matrix(np.broadcast_to(self.base, (t.size, 3, 3)))
        if self.axis is None:
            return base
        return Rotation.from_rotvec(np.outer(self.angle(t), self.axis)) * base

    def omega(self, t) -> np.ndarray:
        """The reference's angular velocity (rad/s, motion frame) (n, 3)."""
        t = np.atleast_1d(np.asarray(t, float))
        if self.axis is None:
            return np.zeros((t.size, 3))
        return np.outer(self.angle(t, 1), self.axis)

    def alpha(self, t) -> np.ndarray:
        """The reference's angular acceleration (rad/s^2, motion frame) (n, 3)."""
        t = np.atleast_1d(np.asarray(t, float))
        if self.axis is None:
            return np.zeros((t.size, 3))
        return np.outer(self.angle(t, 2), self.axis)


def _turning_axis(rots: Rotation) -> np.ndarray:
    """The axis (3,) about which a sequence of rotations mostly turns: the sum of its frame-to-frame
    rotation vectors, or, where they cancel (a back-and-forth motion), their principal direction."""
    step = (rots[1:] * rots[:-1].inv()).as_rotvec()
    total = step.sum(0)
    if np.linalg.norm(total) > 0.5 * np.linalg.norm(step, axis=1).sum():
        return total / np.linalg.norm(total)
    w, v = np.linalg.eigh(step.T @ step)
    axis = v[:, -1]
    return axis if axis @ total >= 0 else -axis


def rotation_reference(t, rots: Rotation) -> tuple[RotationReference, np.ndarray]:
    """The reference rotation of a pose trajectory and each frame's rotation vector about it.

    ``(reference, phi)`` with ``R_k = Exp(phi_k) R_ref(t_k)``, ``phi``
    continuous (:func:`unwrap_rotvec`). A record whose rotations stay within
    :data:`FIXED_REFERENCE_MAX_ANGLE` of their mean keeps the mean as a
    fixed reference; so does one where a turning reference would not at
    least halve the frames' median rotation from it
    (:data:`MOVING_REFERENCE_GAIN`: frames registered far off by noise, not a
    body that turns). Otherwise the reference turns with the body about its
    main turning axis ``u`` (:func:`_turning_axis`) by an angle ``theta(t)``:
    the frame-to-frame rotations projected on ``u`` and summed, fitted by a
    least-squares quintic spline (as smooth as the
    pose's own splines, so that its knots leave no kink in ``phi``) with as few knots as keep every frame within
    :data:`MOVING_REFERENCE_MAX_ANGLE` of the reference (one quintic over the
    record at a constant or steadily changing speed; at least
    :data:`MOVING_REFERENCE_MIN_FRAMES` frames per knot interval). The
    reference is smooth and slow, and what the smoothing of ``phi`` sees is
    the motion about it.

    Parameters
    ----------
    t : (n,)
        Times of the frames with a rotation (s), increasing.
    rots : Rotation of n rotations

    Examples
    --------
    Four turns about z at 3 rad/s: the reference turns with the body.

    >>> t = np.arange(200) / 25.0
    >>> ref, phi = rotation_reference(t, Rotation.from_rotvec(np.outer(3 * t, [0, 0, 1])))
    >>> float(np.abs(phi).max()) < 1e-9, ref.omega([2.0]).round(6)
    (True, array([[0., 0., 3.]]))
    """
    t = np.asarray(t, float)
    mean = rots.mean()
    phi = unwrap_rotvec((rots * mean.inv()).as_rotvec())
    if np.linalg.norm(phi, axis=1).max() <= FIXED_REFERENCE_MAX_ANGLE or len(rots) < 4:
        return RotationReference(mean.as_matrix()), phi
    ref, moving = _moving_reference(t, rots)
    # a body that turns: about the moving reference its rotations are much smaller; frames that noise
    # registered far off (a thin marker triangle, pixels of noise) are not made smaller by it
    if np.median(np.linalg.norm(moving, axis=1)) > MOVING_REFERENCE_GAIN * np.median(np.linalg.norm(phi, axis=1)):
        return RotationReference(mean.as_matrix()), phi
    return ref, moving


def _moving_reference(t, rots: Rotation) -> tuple[RotationReference, np.ndarray]:
    """The reference turning with the body about its main axis, and the rotation vectors about it."""
    axis = _turning_axis(rots)
    step = (rots[1:] * rots[:-1].inv()).as_rotvec() @ axis
    theta = np.concatenate([[0.0], np.cumsum(step)])
    intervals = 1
    while True:
        knots = np.quantile(t, np.linspace(0, 1, intervals + 1))
        spline = make_lsq_spline(t, theta, np.r_[[t[0]] * 5, knots, [t[-1]] * 5], k=5)
        turn = Rotation.from_rotvec(np.outer(spline(t), axis))
        base = (turn.inv() * rots).mean()
        ref = RotationReference(base.as_matrix(), axis, spline)
        phi = unwrap_rotvec((rots * ref.rotation(t).inv()).as_rotvec())
        finer = 2 * intervals
        if (np.linalg.norm(phi, axis=1).max() <= MOVING_REFERENCE_MAX_ANGLE
                or len(t) / finer < MOVING_REFERENCE_MIN_FRAMES):
            return ref, phi
        intervals = finer


def _jac_coeffs(th):
    """b = (1 - cos th)/th^2, c = (th - sin th)/th^3, b'/th, c'/th (series near 0)."""
    th = np.asarray(th, float)
    small = th < 1e-2
    ts = np.where(small, 1.0, th)
    t2 = th * th
    b = np.where(small, 0.5 - t2 / 24 + t2 * t2 / 720, (1 - np.cos(ts)) / ts ** 2)
    c = np.where(small, 1 / 6 - t2 / 120 + t2 * t2 / 5040, (ts - np.sin(ts)) / ts ** 3)
    db = np.where(small, -1 / 12 + t2 / 180, (ts * np.sin(ts) - 2 * (1 - np.cos(ts))) / ts ** 4)
    dc = np.where(small, -1 / 60 + t2 / 1260, (1 - np.cos(ts)) / ts ** 4 - 3 * (ts - np.sin(ts)) / ts ** 5)
    return b, c, db, dc


def left_jacobian(phi) -> np.ndarray:
    """Left Jacobian of SO(3), ``J_l(phi) = I + b [phi]x + c [phi]x^2`` (..., 3, 3).

    For ``R = Exp(phi) R_ref``: ``R' R^T = [J_l(phi) phi']x`` (the spatial
    angular velocity).

    Examples
    --------
    >>> import numpy as np
    >>> bool(np.allclose(left_jacobian(np.zeros(3)), np.eye(3)))
    True
    >>> left_jacobian([0, 0, 1.0]) @ [0, 0, 1.0]      # along the axis: the identity
    array([0., 0., 1.])
    """
    phi = np.asarray(phi, float)
    th = np.linalg.norm(phi, axis=-1)
    b, c, _, _ = _jac_coeffs(th)
    K = skew(phi)
    return np.eye(3) + b[..., None, None] * K + c[..., None, None] * (K @ K)


def angular_velocity_from_rotvec(phi, dphi) -> np.ndarray:
    """``omega = J_l(phi) phi'`` (..., 3) for ``R(t) = Exp(phi(t)) R_ref``.

    Examples
    --------
    About a fixed axis, omega is the rotation vector's rate:

    >>> angular_velocity_from_rotvec([0, 0, 1.0], [0, 0, 0.5])
    array([0. , 0. , 0.5])
    """
    phi, dphi = np.asarray(phi, float), np.asarray(dphi, float)
    th = np.linalg.norm(phi, axis=-1)
    b, c, _, _ = _jac_coeffs(th)
    pxd = np.cross(phi, dphi)
    return dphi + b[..., None] * pxd + c[..., None] * np.cross(phi, pxd)


def angular_acceleration_from_rotvec(phi, dphi, ddphi) -> np.ndarray:
    """``alpha = d/dt (J_l(phi) phi') = J_l phi'' + J_l' phi'`` (..., 3).

    With ``th' = phi . phi' / th``:
    ``J_l' phi' = (b'/th)(phi . phi') (phi x phi') + (c'/th)(phi . phi')
    phi x (phi x phi') + c phi' x (phi x phi')``.

    Examples
    --------
    >>> angular_acceleration_from_rotvec([0, 0, 1.0], [0, 0, 0.5], [0, 0, 0.2])
    array([0. , 0. , 0.2])
    """
    phi, dphi, ddphi = (np.asarray(a, float) for a in (phi, dphi, ddphi))
    th = np.linalg.norm(phi, axis=-1)
    b, c, db, dc = _jac_coeffs(th)
    pd = np.einsum("...i,...i->...", phi, dphi)[..., None]
    pxd = np.cross(phi, dphi)
    return (angular_velocity_from_rotvec(phi, ddphi) + db[..., None] * pd * pxd
            + dc[..., None] * pd * np.cross(phi, pxd) + c[..., None] * np.cross(dphi, pxd))


# --------------------------------------------------------------------------
# the smoothed pose trajectory
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class PointKinematics:
    """Position, velocity and acceleration (n, 3) of a body point."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass(frozen=True)
class PoseTrajectory:
    """A rigid body's smoothed pose over time and its analytic derivatives.

    ``R(t) = Exp(phi(t)) R_ref(t)``, centroid ``c(t)``; both smoothed
    (:func:`fit_pose_trajectory`). Evaluate at any times inside the record.

    Attributes
    ----------
    t : (n,)
        The frames' times.
    reference : (3, 3)
        ``R_ref``: the mean of the registered rotations; for a body that
        turns far, ``R_0`` of the moving reference.
    model_centroid : (3,)
        Mean of the model (static shot): body points are given relative to it.
    centre_splines, rotvec_splines : tuple of 3 smoothing splines
        ``c_x, c_y, c_z`` and ``phi_x, phi_y, phi_z`` (:mod:`horsemocap.splines`).
    valid : (n,) bool
        Frames with a value (a pose, or inside a short gap); others NaN.
    reason : (n,) str
        Why a frame is NaN, or ``"bridged gap ..."`` for interpolated frames.
    registration : PoseRegistration
    rotvec_data : (n, 3)
        The rotation vectors the splines were fitted to.
    moving_reference : RotationReference or None
        ``R_ref(t)`` of a body that turns far (:func:`rotation_reference`);
        None: the fixed ``reference``.
    """

    t: np.ndarray
    reference: np.ndarray
    model_centroid: np.ndarray
    centre_splines: tuple
    rotvec_splines: tuple
    valid: np.ndarray
    reason: np.ndarray
    registration: PoseRegistration
    rotvec_data: np.ndarray = field(repr=False, default=None)
    moving_reference: RotationReference | None = field(repr=False, default=None)

    def _reference(self) -> RotationReference:
        return self.moving_reference or RotationReference(self.reference)

    @property
    def smoothing(self) -> dict:
        """Smoothing chosen per component: lambda, effective degrees of freedom, noise (data units)."""
        names = POSE_COMPONENTS
        return {nm: s.info for nm, s in zip(names, self.centre_splines + self.rotvec_splines)}

    @property
    def smoothing_choice(self) -> dict | None:
        """What ``smoothing="auto"`` ran and why (:func:`choose_smoothing`): ``{"method", "reason"}``;
        for a smoothing asked for by name, its name and whether the frames' temporal aperture was modelled
        (None when there was no aperture to model)."""
        info = self.centre_splines[0].info
        if "smoothing_method" not in info:
            return None
        out = {"method": info["smoothing_method"], "reason": info["smoothing_reason"]}
        if "noise_correlation" in info:
            out["noise_correlation"] = info["noise_correlation"]
        if "cross_validation" in info:
            out["cross_validation"] = info["cross_validation"]
        if info.get("correlated_harmonics"):
            out["correlated_harmonics"] = True
        out["half_gain_hz"] = self.half_gain_hz
        return out

    @property
    def half_gain_hz(self) -> dict:
        """Per component, the frequency (Hz) its smoothing passes at half amplitude
        (:func:`horsemocap.splines.half_gain_frequency`; stride harmonics, where fitted, pass whole);
        None where the penalty is not one filter over the record (adaptive, per-frame weights, none).

        Examples
        --------
        A pose smoothed with the penalty of a 5 Hz half-gain filter (50 frames a second):

        >>> import numpy as np
        >>> from horsemocap.params import PoseParams
        >>> t = np.arange(200) / 50.0
        >>> model = np.array([[0.3, 0.0, 0.0], [-0.2, 0.1, 0.0], [-0.1, -0.2, 0.05]])
        >>> pts = np.broadcast_to(model + np.array([0.0, 0.0, 1.0]), (200, 3, 3)).copy()
        >>> pts[:, :, 0] += 0.5 * t[:, None]
        >>> reg = register_pose(pts, model)
        >>> lam = 1 / (0.02 * (2 * np.pi * 5.0) ** 6)
        >>> traj = fit_pose_trajectory(t, reg, model, PoseParams(smoothing="gcv", harmonics="none"), lam=[lam] * 6)
        >>> traj.half_gain_hz["phiz"]
        5.0
        """
        dt = float(np.median(np.diff(self.t)))
        out = {}
        for name, info in self.smoothing.items():
            lam = info.get("lam")
            uniform = (info.get("order") == 5 and info.get("method") in ("gcv", "noise")
                       and info.get("weights", "equal") == "equal"
                       and lam is not None and np.isfinite(lam) and lam > 0)
            out[name] = round(half_gain_frequency(lam, dt), 3) if uniform else None
        return out

    @property
    def windows(self) -> None:
        """None: fitted whole (a long pass smoothed in windows says how,
        :attr:`horsemocap.pose_windows.WindowedPoseTrajectory.windows`)."""
        return None

    def _inside(self, t):
        t = np.asarray(t, float)
        if t is self.t or (t.shape == self.t.shape and np.array_equal(t, self.t)):
            return self.valid
        lo, hi = self.t[self.valid].min(), self.t[self.valid].max()
        ok = (t >= lo - 1e-9) & (t <= hi + 1e-9)
        # times inside a long gap stay NaN
        bad = ~self.valid
        if bad.any():
            idx = np.clip(np.searchsorted(self.t, t), 0, len(self.t) - 1)
            idx0 = np.clip(idx - 1, 0, len(self.t) - 1)
            exact = np.isclose(self.t[idx], t)
            ok &= np.where(exact, self.valid[idx], self.valid[idx] | self.valid[idx0])
        return ok

    def _eval(self, splines, t, d):
        t = np.asarray(t, float)
        out = np.stack([s(t, d) for s in splines], -1)
        out[~self._inside(t)] = np.nan
        return out

    def rotvec(self, t, derivative: int = 0) -> np.ndarray:
        """``phi(t)`` or its derivatives (n, 3)."""
        return self._eval(self.rotvec_splines, t, derivative)

    def rotation(self, t) -> np.ndarray:
        """``R(t)`` (n, 3, 3), NaN outside the valid frames."""
        phi = self.rotvec(t)
        ok = np.all(np.isfinite(phi), axis=1)
        R = np.full((len(phi), 3, 3), np.nan)
        if ok.any():
            R[ok] = (Rotation.from_rotvec(phi[ok]) * self._reference().rotation(np.asarray(t, float)[ok])).as_matrix()
        return R

    def _turned_reference_rate(self, t, phi, rate) -> np.ndarray:
        """``Exp(phi) rate``: the reference's angular velocity or acceleration seen through ``Exp(phi)``."""
        out = np.full(phi.shape, np.nan)
        ok = np.all(np.isfinite(phi), axis=1)
        if ok.any():
            out[ok] = Rotation.from_rotvec(phi[ok]).apply(rate[ok])
        return out

    def omega(self, t) -> np.ndarray:
        """Angular velocity (rad/s) in the motion frame, analytic:
        ``J_l(phi) phi' + Exp(phi) omega_ref``."""
        phi = self.rotvec(t)
        w = angular_velocity_from_rotvec(phi, self.rotvec(t, 1))
        if self.moving_reference is None:
            return w
        return w + self._turned_reference_rate(t, phi, self.moving_reference.omega(t))

    def alpha(self, t) -> np.ndarray:
        """Angular acceleration (rad/s^2) in the motion frame, analytic:
        ``alpha_phi + omega_phi x (Exp(phi) omega_ref) + Exp(phi) alpha_ref``."""
        phi, dphi = self.rotvec(t), self.rotvec(t, 1)
        a = angular_acceleration_from_rotvec(phi, dphi, self.rotvec(t, 2))
        if self.moving_reference is None:
            return a
        w_phi = angular_velocity_from_rotvec(phi, dphi)
        w_ref = self._turned_reference_rate(t, phi, self.moving_reference.omega(t))
        return a + np.cross(w_phi, w_ref) + self._turned_reference_rate(t, phi, self.moving_reference.alpha(t))

    def centre(self, t, derivative: int = 0) -> np.ndarray:
        """The model centroid's smoothed position, velocity or acceleration (n, 3)."""
        return self._eval(self.centre_splines, t, derivative)

    def point(self, t, body_point) -> PointKinematics:
        """Kinematics of a body point given in the static shot (model) frame.

        ``r = R(t) (X - mean(model))``, ``p = c + r``, ``v = c' + omega x r``,
        ``a = c'' + alpha x r + omega x (omega x r)`` (eq. 6.54, 6.55).
        """
        X = np.asarray(body_point, float)
        if X.shape != (3,):
            raise ValueError(f"body_point: expected (3,) in the static shot's frame, got {X.shape}")
        r = np.einsum("kij,j->ki", self.rotation(t), X - self.model_centroid)
        w, al = self.omega(t), self.alpha(t)
        return PointKinematics(self.centre(t) + r, self.centre(t, 1) + np.cross(w, r),
                               self.centre(t, 2) + np.cross(al, r) + np.cross(w, np.cross(w, r)))

    def points(self, t, body_points) -> PointKinematics:
        """:meth:`point` for several points (k, 3) -> arrays (n, k, 3)."""
        ks = [self.point(t, X) for X in np.asarray(body_points, float)]
        return PointKinematics(*(np.stack([getattr(k, a) for k in ks], 1)
                                 for a in ("position", "velocity", "acceleration")))


def _gap_lengths(ok: np.ndarray) -> np.ndarray:
    """For each frame not ok, the length of the run of not-ok frames it belongs to (0 if ok)."""
    out = np.zeros(ok.size, int)
    i = 0
    while i < ok.size:
        if ok[i]:
            i += 1
            continue
        j = i
        while j < ok.size and not ok[j]:
            j += 1
        out[i:j] = j - i
        i = j
    return out


def pose_noise(registration: PoseRegistration, points, model) -> np.ndarray:
    """Noise (standard deviation) of the six pose components, from the registration residuals.

    The markers' noise covariance ``Sigma`` (3 x 3, anisotropic: a camera rig
    measures depth worse than the image directions) is estimated from the
    residual vectors pooled over frames, ``sum r r^T / sum (k - 2)`` (a frame
    of k markers leaves ``3k - 6`` residual degrees of freedom). Linearised
    registration then gives the centroid's noise ``Sigma / k`` and the
    rotation vector's ``H^-1 (sum_m [d_m]x^T Sigma [d_m]x) H^-1`` with
    ``H = sum_m [d_m]x^T [d_m]x`` and ``d_m`` the markers about the centroid
    (mean pose). With ``points`` None the marker noise is taken isotropic,
    ``Sigma = noise_m^2 I`` (the registration's own estimate): with three
    markers the residuals cannot see the noise normal to their plane, so the
    pooled covariance underestimates it there. A registration with the
    markers' covariances (:func:`register_pose` with ``covariance``) carries
    the pose's information matrix per frame; with ``points`` None the noise
    is then the RMS over the frames of the square roots of the diagonal of
    its inverse (the same linearisation, with each marker's own covariance).

    Returns
    -------
    (6,)
        ``cx, cy, cz`` (m) and ``phix, phiy, phiz`` (rad).

    Examples
    --------
    With isotropic marker noise the centroid's noise is the markers' over the square root of their number:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0], [0.3, 0.1, 0.2]])
    >>> reg = register_pose(model + rng.normal(0, 1e-3, (50, 4, 3)), model)
    >>> bool(np.allclose(pose_noise(reg, None, model)[:3], reg.noise_m / 2))
    True
    """
    reg = registration
    ok = np.isfinite(reg.rotation[:, 0, 0])
    if points is None and reg.information is not None:
        good = ok & np.all(np.isfinite(reg.information), axis=(1, 2))
        if not good.any():
            return np.full(6, np.nan)
        return np.sqrt(np.mean(frame_variances(reg)[good], axis=0))
    if points is None:
        if not (ok.any() and np.isfinite(reg.noise_m)):
            return np.full(6, np.nan)
        Sig = reg.noise_m ** 2 * np.eye(3)
    else:
        Sig = _pooled_residual_covariance(reg, points)
        if Sig is None:
            return np.full(6, np.nan)
    R0 = Rotation.from_matrix(reg.rotation[ok]).mean().as_matrix()
    return np.sqrt(_geometric_pose_variance(np.asarray(model, float), R0, Sig))


def partial_pose(points, model, rotation, centre):
    """Pose of frames in which exactly two markers are visible, completed by a prediction.

    Two markers fix five of the pose's six degrees of freedom: the direction
    of the line through them (two rotation angles) and the position along
    and across it. The rotation *about* that line is not seen; it is taken
    from the predicted pose ``(rotation, centre)`` (the smoothed trajectory
    extrapolated to the frame). The predicted rotation is turned by the
    smallest rotation that carries the predicted marker-to-marker direction
    onto the measured one (:meth:`scipy.spatial.transform.Rotation.align_vectors`),
    and the centroid is placed so that the two markers' midpoint matches.

    Parameters
    ----------
    points : (n, m, 3)
        Measured markers, exactly two finite per frame.
    model : (m, 3)
        The static-shot model.
    rotation : (n, 3, 3), centre : (n, 3)
        Predicted ``R(t)`` and model-centroid position ``c(t)``.

    Returns
    -------
    rotation : (n, 3, 3), centre : (n, 3)

    Examples
    --------
    Two markers seen and a prediction that is right: the pose is kept.

    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> points = model.copy()[None]
    >>> points[0, 2] = np.nan
    >>> R, c = partial_pose(points, model, np.eye(3)[None], model.mean(0)[None])
    >>> bool(np.allclose(R[0], np.eye(3))), bool(np.allclose(c[0], model.mean(0)))
    (True, True)
    """
    p = np.asarray(points, float)
    x = np.asarray(model, float)
    d = x - x.mean(0)
    Rp = np.asarray(rotation, float)
    cp = np.asarray(centre, float)
    vis = np.all(np.isfinite(p), axis=2)
    if np.any(vis.sum(1) != 2):
        raise ValueError("points: partial_pose expects exactly two visible markers per frame, got "
                         f"{sorted(set(vis.sum(1).tolist()))}")
    R_out = np.empty_like(Rp)
    c_out = np.empty_like(cp)
    for k in range(p.shape[0]):
        i, j = np.flatnonzero(vis[k])
        u_pred = Rp[k] @ (d[j] - d[i])
        u_meas = p[k, j] - p[k, i]
        turn, _ = Rotation.align_vectors(u_meas[None], u_pred[None])
        R = turn.as_matrix() @ Rp[k]
        R_out[k] = R
        c_out[k] = 0.5 * (p[k, i] + p[k, j]) - R @ (0.5 * (d[i] + d[j]))
    return R_out, c_out


def fit_pose_trajectory(t, registration: PoseRegistration, model, params: PoseParams = PoseParams(), *,
                        points=None, fundamental_hz: float | None = None,
                        expected_fundamental_hz: float | None = None, max_gap_s: float | None = None,
                        lam=None, iterations: int = 3, rotation_noise_test: bool = True,
                        settled: SettledPoseSmoothing | None = None, aperture=None) -> PoseTrajectory:
    """Smooth a registered pose trajectory (centroid and rotation vector).

    The centroid ``c(t)`` and the rotation vector ``phi(t)`` of ``R(t) = Exp(phi(t)) R_ref`` are
    smoothed component by component (:func:`horsemocap.splines.smoothing_spline`; the module's step 2).

    Parameters
    ----------
    t : (n,)
        Time of each frame (s), increasing.
    registration : PoseRegistration
        From :func:`register_pose`.
    model : (m, 3)
        The static-shot model (for its centroid).
    params : horsemocap.params.PoseParams
        ``smoothing``, ``harmonics``, ``partial_frames``, ``rotation_weights``,
        ``events`` and ``correlated_noise_criterion`` (the module docstring
        says what each choice does);
        what ``smoothing="auto"`` ran and why is in each component's ``info``
        (``smoothing_method``, ``smoothing_reason``). ``weights`` is not read
        here (it says whether :func:`register_pose` was given covariances).
        When ``"auto"`` takes the correlated-noise smoothing, the fit is checked
        for motion taken as noise (with the correlated-error GCV a component
        smoothed to the penalty's null space; with any criterion the stride's
        harmonics left in a component's residual,
        :func:`stride_harmonics_left` at the stride frequency of
        ``expected_fundamental_hz``, else ``fundamental_hz``; without either
        it is not tested) and smoothed again with the noise taken as white if
        it did; the reason says what was tested and found.
    points : (n, m, 3), optional
        The measured markers that were registered: needed by ``"noise"``; with ``partial_frames``
        its frames with exactly two visible markers join the smoothing (:func:`partial_pose`, the
        module's step 2), ``iterations`` times.
    fundamental_hz : float, optional
        The stride frequency (Hz) of the harmonics; None: estimated from the six pose components
        (:func:`horsemocap.splines.estimate_fundamental`; under 2 cycles: no harmonics).
    expected_fundamental_hz : float, optional
        A stride frequency found by another estimator (the pipeline: the motion frame's period):
        when the record's own search finds none, it searches down to :data:`SHORT_RECORD_CYCLES`
        cycles and keeps a result within :data:`FUNDAMENTAL_AGREEMENT` of this one.
    max_gap_s : float, optional
        Longest run of frames without a pose that the spline bridges; longer
        gaps stay NaN with the reason. Default: 5 frame intervals.
    lam : None or (6,) floats
        Smoothing parameters given instead of chosen (``cx, cy, cz, phix, phiy, phiz``).
    iterations : int
        Re-smoothings with the partial frames' poses updated.
    rotation_noise_test : bool
        With ``harmonics="auto"``: the rotation harmonics' test against the
        predicted rotation noise (default on; off for comparison).
    settled : SettledPoseSmoothing, optional
        The smoothing's choices settled on another record of the same body
        and motion (:func:`settle_pose_smoothing`, e.g. on a long recording's
        longest pass): its method, noise correlation, stride frequency,
        smoothing parameters, most harmonics per component and rotation
        weighting are taken instead of chosen here; only which of the first
        harmonics each component keeps is chosen (at the given smoothing
        parameter). A settled blend of the fits without and with the
        stride's harmonics (``blend_weights``) fits both routes at their
        settled parameters and blends them with the settled weights.
        ``lam`` and ``fundamental_hz``, when given, still take precedence
        over its values (``lam`` over the plain route's). Nothing of the
        settled choice is checked again (the record it was settled on was).
    aperture : horsemocap.aperture.Aperture, optional
        Each frame's pose is the motion averaged over this temporal aperture
        (the cameras' exposure, an interlaced frame's two fields;
        :func:`horsemocap.aperture.session_aperture`): the six components are
        fitted through it (``aperture`` of
        :func:`horsemocap.splines.smoothing_spline`), so the trajectory is the
        motion itself (:func:`_aperture_options`).

    Returns
    -------
    PoseTrajectory

    Raises
    ------
    ValueError
        Naming the input or the choice that cannot be used.
    horsemocap.splines.ChangePointError
        ``events`` with a smoothing that cannot fit them.

    Examples
    --------
    A body turning at a constant 0.5 rad/s about z: interpolated
    (``smoothing="none"``), the analytic angular velocity is that rate.

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> from horsemocap.params import PoseParams
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> t = np.arange(30) / 25.0
    >>> R = Rotation.from_rotvec(np.outer(0.5 * t, [0, 0, 1])).as_matrix()
    >>> reg = register_pose(np.einsum("kij,mj->kmi", R, model), model)
    >>> tr = fit_pose_trajectory(t, reg, model, PoseParams(smoothing="none"))
    >>> np.round(tr.omega(t)[10], 9)
    array([0. , 0. , 0.5])
    """
    t = np.asarray(t, float)
    reg = registration
    ok = _check_pose_frames(t, reg)
    n = t.size
    lam = _check_smoothing_choices(params, lam)
    if fundamental_hz is not None and not (np.isfinite(fundamental_hz) and fundamental_hz > 0):
        raise ValueError(f"fundamental_hz: expected a stride frequency above 0 Hz, or None, got {fundamental_hz!r}")
    if settled is not None:
        lam = [s if g is None else g for g, s in zip(lam, settled.lam)]
        fundamental_hz = settled.fundamental_hz if fundamental_hz is None else fundamental_hz
    method = params.smoothing if settled is None else settled.method
    smoothing, order = ("gcv", 3) if method == "gcv_cubic" else (method, 5)
    ref, phi_ok = rotation_reference(t[ok], Rotation.from_matrix(reg.rotation[ok]))
    phi = np.full((n, 3), np.nan)
    phi[ok] = phi_ok
    sig = np.full(6, None)
    if smoothing == "noise":
        if points is None:
            raise ValueError("points: smoothing 'noise' needs the measured markers (for the residuals)")
        sig = pose_noise(reg, points, model)
    rho = significant_noise_correlation(points, reg) if smoothing == "auto" and points is not None else None
    two, departure = _two_marker_frames(points, ok, n) if params.partial_frames else (np.zeros(n, bool), None)
    fit = dict(params=params, fundamental_hz=fundamental_hz, expected_hz=expected_fundamental_hz, lam=lam, sig=sig,
               points=points, rotation_noise_test=rotation_noise_test, iterations=iterations, settled=settled,
               aperture=aperture, two=two)
    fitted = _fit_components(t, reg, model, phi.copy(), ok, ref, smoothing, order, rho, **fit)
    if settled is None and fitted[4] is not None and "noise_correlation" in fitted[4]:
        # the correlated-error choice is checked here once; settled records and named methods take it as it is
        fitted = _white_if_motion_lost(fitted, t, reg, model, phi, ok, ref, smoothing, order, rho, fit,
                                       expected_fundamental_hz)
    centre, phi, cs, ps, choice, two = fitted
    if choice is not None:
        for s in cs + ps:
            s.info.update(choice)
    valid, reason = _frame_validity(t, reg.reason, ok | two, two, max_gap_s)
    reason = _refused_partial_reasons(reason, departure, ok, two)
    return PoseTrajectory(t=t, reference=ref.base, model_centroid=np.asarray(model, float).mean(0),
                          centre_splines=cs, rotvec_splines=ps, valid=valid, reason=reason,
                          registration=reg, rotvec_data=phi,
                          moving_reference=None if ref.axis is None else ref)


#: Effective degrees of freedom of the quintic spline's penalty null space (a quadratic): a component smoothed
#: down to it has had all its motion taken for noise.
NULL_SPACE_EDF = 3.0
#: How near :data:`NULL_SPACE_EDF` counts as at it.
NULL_SPACE_TOLERANCE = 0.05

#: Below this p-value (per pose component; six are tested) the smoothed pose's residual is taken to hold the
#: stride's harmonics: motion the smoothing took for noise (:func:`stride_harmonics_left`). The intended
#: false-alarm rate is for the family of six: at most 6 x 1e-4 = 6e-4 per record (Bonferroni), about one record
#: of noise alone in 1700 smoothed again as white for nothing; a missed stride motion costs more than that.
STRIDE_RESIDUAL_LEVEL = 1e-4
#: The harmonics tested lie below this fraction of the frame rate (a gait's pose motion; far from Nyquist).
STRIDE_RESIDUAL_MAX_FRACTION = 0.2
#: Consecutive frames the F test needs beyond twice its harmonic terms (q): the residual's variance is then
#: measured on at least q + 7 degrees of freedom, more than the harmonics take, so that its own scatter does not
#: fatten the F distribution's tail at :data:`STRIDE_RESIDUAL_LEVEL`.
STRIDE_RESIDUAL_SPARE_FRAMES = 8


def stride_harmonics_left(trajectory: PoseTrajectory, fundamental_hz: float) -> np.ndarray:
    """Per pose component, the p-value that its smoothing residual holds no harmonics of the stride.

    The residual of each of the six smoothed components (``cx, cy, cz,
    phix, phiy, phiz``: the per-frame registration minus the spline, over
    the frames with a pose) is regressed on the cosines and sines of the
    stride frequency's harmonics below :data:`STRIDE_RESIDUAL_MAX_FRACTION`
    of the frame rate. Noise left by a smoothing, white or correlated, has
    no preferred phase in the stride; motion the smoothing took for noise
    returns every stride at the same phase. The regression is prewhitened
    with the residual's lag-1 correlation over pairs of consecutive frames
    with a pose (a gap is never bridged) (an AR(1) noise; measured before
    the harmonics are fitted: after a fit of that many terms to a short
    record it reads low and the test would find harmonics in noise) and
    judged by the F test of the harmonics' terms.

    Parameters
    ----------
    trajectory : horsemocap.pose.PoseTrajectory
    fundamental_hz : float
        The stride frequency.

    Returns
    -------
    (6,) array of p-values (NaN for a component with too few frames).

    Examples
    --------
    A stride motion smoothed away entirely (the "spline" is the mean) is found; a fit that follows it is not.

    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> t = np.arange(150) / 50.0
    >>> rng = np.random.default_rng(0)
    >>> y = 0.01 * np.sin(2 * np.pi * 1.5 * t) + rng.normal(0, 1e-3, (6, t.size))
    >>> const = lambda v: (lambda tt: np.full_like(tt, v.mean()))
    >>> reg = SimpleNamespace(rotation=np.tile(np.eye(3), (t.size, 1, 1)), centre=y[:3].T)
    >>> flat = SimpleNamespace(t=t, registration=reg, rotvec_data=y[3:].T,
    ...                        centre_splines=[const(v) for v in y[:3]], rotvec_splines=[const(v) for v in y[3:]])
    >>> bool(np.all(stride_harmonics_left(flat, 1.5) < 1e-6))
    True
    >>> follow = lambda v: (lambda tt: 0.01 * np.sin(2 * np.pi * 1.5 * tt))
    >>> fits = SimpleNamespace(t=t, registration=reg, rotvec_data=y[3:].T,
    ...                        centre_splines=[follow(v) for v in y[:3]], rotvec_splines=[follow(v) for v in y[3:]])
    >>> bool(np.all(stride_harmonics_left(fits, 1.5) > 1e-3))
    True
    """
    return _stride_p_values(trajectory.t, trajectory.registration, trajectory.rotvec_data,
                            tuple(trajectory.centre_splines) + tuple(trajectory.rotvec_splines), fundamental_hz)


def _stride_p_values(t, registration, rotvec_data, splines, fundamental_hz: float) -> np.ndarray:
    """:func:`stride_harmonics_left` of the per-frame poses (``registration``'s centres, ``rotvec_data``) and
    the six components' ``splines``: what a pose trajectory holds, before one is made of them."""
    # the whole grid of frames, NaN where there is no pose: the AR(1) prewhitening pairs only consecutive frames
    ok = np.all(np.isfinite(np.asarray(registration.rotation, float)), axis=(1, 2))
    t = np.asarray(t, float)
    data = np.column_stack([np.asarray(registration.centre, float), np.asarray(rotvec_data, float)])
    data[~ok] = np.nan
    fitted = np.column_stack([getattr(s, "observed", s)(t) for s in splines])   # what each frame observed
    rate = 1.0 / float(np.median(np.diff(t))) if t.size > 1 else 0.0
    orders = np.arange(1, max(1, int(STRIDE_RESIDUAL_MAX_FRACTION * rate // fundamental_hz)) + 1)
    phase = 2 * np.pi * fundamental_hz * np.outer(t - t[0] if t.size else t, orders)
    X = np.column_stack([np.cos(phase), np.sin(phase)])
    p_values = np.full(6, np.nan)
    for i in range(6):
        y = data[:, i] - fitted[:, i]
        keep = np.isfinite(y)
        pairs = keep[1:] & keep[:-1]                     # frame k and k - 1 both with a pose
        if pairs.sum() < 2 * X.shape[1] + STRIDE_RESIDUAL_SPARE_FRAMES:
            continue   # too few consecutive frames for the prewhitened F test
        y = np.where(keep, y - y[keep].mean(), 0.0)
        rho = float(np.sum((y[1:] * y[:-1])[pairs]) / np.sum(y * y)) if np.sum(y * y) > 0 else 0.0
        yw, Xw = (y[1:] - rho * y[:-1])[pairs], (X[1:] - rho * X[:-1])[pairs]
        rss1 = float(np.sum((yw - Xw @ np.linalg.lstsq(Xw, yw, rcond=None)[0]) ** 2))
        rss0 = float(np.sum(yw ** 2))
        q, dof = Xw.shape[1], yw.size - Xw.shape[1] - 1
        p_values[i] = 1.0 if rss1 <= 0 else float(f_survival(((rss0 - rss1) / q) / (rss1 / dof), q, dof))
    return p_values



def _white_if_motion_lost(fitted, t, reg: PoseRegistration, model, phi, ok, ref, smoothing: str, order: int, rho,
                          fit: dict, expected_hz):
    """:func:`_fit_components`' ``fitted`` of the correlated-noise smoothing, or the fit again with the noise
    taken as white when that criterion took motion for noise; the choice's reason says which and why.

    Two checks, in turn: a component smoothed down to the penalty's null space (:data:`NULL_SPACE_EDF`: its
    whole motion taken for noise, a short record; the correlated-error GCV only: leaving markers out measures
    the error of a component flattened directly, and a component whose motion is below the noise is rightly
    flattened), then the stride's harmonics left in a component's residual
    (:func:`stride_harmonics_left` below :data:`STRIDE_RESIDUAL_LEVEL`; periodic motion taken for noise). The
    stride frequency tested is ``expected_hz`` (another estimator's, the motion-frame step's period), else the
    given ``fundamental_hz`` (:func:`_stride_test_frequency`); without either the residual is not tested, and
    the reason says so."""
    cs, ps, choice = fitted[2], fitted[3], fitted[4]
    ar1 = (f"the smoothing chosen by leaving markers out (AR(1) {choice['noise_correlation']:.2f} from the "
           "rigidity residual)" if "cross_validation" in choice else
           f"the correlated-error GCV (AR(1) {choice['noise_correlation']:.2f} from the rigidity residual)")
    stride_hz, source = _stride_test_frequency(fit["fundamental_hz"], expected_hz)
    if "cross_validation" not in choice and any(s.info["edf"] < NULL_SPACE_EDF + NULL_SPACE_TOLERANCE
                                                for s in cs + ps):
        lost = (f"{ar1} took a component's whole motion for noise (smoothed to the penalty's null space, a "
                "quadratic)")
        refit = _correlated_harmonic_refit(t, reg, model, phi, ok, ref, order, choice, fit, expected_hz, stride_hz,
                                           source, lost)
        if refit is not None:
            return refit
        fitted = _fit_components(t, reg, model, phi.copy(), ok, ref, smoothing, order, None, **fit)
        fitted[4]["smoothing_reason"] += f"; {lost}: noise taken as white"
        return fitted
    if stride_hz is None:
        choice["smoothing_reason"] += ("; its residual not tested for the stride's harmonics: no stride frequency "
                                       "given or found by another estimator (the record's own is not tested "
                                       "against itself)")
        return fitted
    p_values = _stride_p_values(t, reg, fitted[1], tuple(cs) + tuple(ps), stride_hz)
    tested = f"at {stride_hz:.4g} Hz ({source})"
    if not np.isfinite(p_values).any():
        choice["smoothing_reason"] += f"; its residual too short to test for the stride's harmonics {tested}"
        return fitted
    worst = int(np.nanargmin(p_values))
    name = POSE_COMPONENTS[worst]
    if p_values[worst] >= STRIDE_RESIDUAL_LEVEL:
        choice["smoothing_reason"] += (f"; no stride harmonics {tested} left in its residual (F test, smallest p = "
                                       f"{p_values[worst]:.2g} in {name}, >= {STRIDE_RESIDUAL_LEVEL:g})")
        return fitted
    lost = (f"{ar1} left the stride's harmonics {tested} in the residual of {name} (F test p = "
            f"{p_values[worst]:.1g} < {STRIDE_RESIDUAL_LEVEL:g}): it took periodic motion for noise")
    refit = _correlated_harmonic_refit(t, reg, model, phi, ok, ref, order, choice, fit, expected_hz, stride_hz,
                                       source, lost)
    if refit is not None:
        return refit
    fitted = _fit_components(t, reg, model, phi.copy(), ok, ref, "gcv", order, None, **fit)
    f0 = fitted[2][0].info.get("fundamental_hz")
    reason = (f"periodic record: fundamental {f0:.4g} Hz" if f0 else "gcv") + f"; {lost}; noise taken as white"
    if fit["aperture"] is not None:
        reason += "; " + _aperture_note(fit["aperture"], order, "gcv")
    return fitted[:4] + ({"smoothing_method": "gcv", "smoothing_reason": reason},) + fitted[5:]



#: Whether a correlated-error choice that took motion for noise (:func:`_white_if_motion_lost`) is first fitted
#: again under the same AR(1) noise with the stride's harmonics unpenalised (the partial spline's correlated-error
#: GCV, :func:`_correlated_harmonic_refit`) before the noise is taken as white.
CORRELATED_HARMONIC_REFIT = True


def _correlated_harmonic_refit(t, reg: PoseRegistration, model, phi, ok, ref, order: int, choice: dict, fit: dict,
                               expected_hz, stride_hz, source: str, lost: str):
    """The pose fitted again under the correlated choice's AR(1) noise with the stride's harmonics unpenalised,
    or None when it cannot stand (then :func:`_white_if_motion_lost` takes the noise as white).

    The correlated-error GCV without harmonics takes a stride's slow, regular motion for correlated noise: the
    two look alike to a criterion that knows only the noise's correlation. With the harmonics of the record's
    fundamental (the search the white-noise refit runs; none found: None) unpenalised, the criterion charges
    each harmonic what AR(1) noise at its frequency could imitate (``tr(H C)``,
    :func:`horsemocap.splines.smoothing_spline` with ``fundamental_hz`` and ``noise_correlation``) and smooths
    only the rest. The refit stands unless the stride's harmonics are still in a residual (``stride_hz``, when
    known; the same F test). A component left flat here (no harmonic, the penalty's null space) is one whose
    stride harmonics the noise can imitate, so it is not taken as motion lost: with the harmonics unpenalised
    the criterion was free to keep them (what refusing such refits costs is measured in benchmarks/README.md).
    Not for the left-out choice (four or more markers: it tries the harmonic route itself) nor for a record
    whose smoothing parameters are given or whose harmonics are switched off."""
    if (not CORRELATED_HARMONIC_REFIT or "cross_validation" in choice or order != 5
            or fit["params"].harmonics == "none" or any(v is not None for v in fit["lam"])):
        return None
    rho = float(choice["noise_correlation"])
    refit = _fit_components(t, reg, model, phi.copy(), ok, ref, "gcv", order, None, harmonic_correlation=rho, **fit)
    splines = refit[2] + refit[3]
    f0 = splines[0].info.get("fundamental_hz")
    if f0 is None or not np.isfinite(f0):
        return None
    note = ""
    if stride_hz is not None:
        p_values = _stride_p_values(t, reg, refit[1], splines, stride_hz)
        if np.isfinite(p_values).any() and np.nanmin(p_values) < STRIDE_RESIDUAL_LEVEL:
            return None
        if np.isfinite(p_values).any():
            note = (f"; no stride harmonics at {stride_hz:.4g} Hz ({source}) left in its residual (smallest p = "
                    f"{np.nanmin(p_values):.2g})")
    reason = (f"periodic record: fundamental {f0:.4g} Hz; {lost}; fitted again under the same AR(1) {rho:.2f} "
              f"noise with the stride's harmonics unpenalised (correlated-error GCV of the partial spline){note}")
    if fit["aperture"] is not None:
        reason += "; " + _aperture_note(fit["aperture"], order, "gcv")
    kept = {"smoothing_method": "gcv_ar1", "smoothing_reason": reason, "noise_correlation": rho,
            "correlated_harmonics": True}
    return refit[:4] + (kept,) + refit[5:]


def _stride_test_frequency(fundamental_hz, expected_hz) -> tuple:
    """``(stride frequency or None, where it comes from)`` for :func:`_white_if_motion_lost`: another
    estimator's or the given one, never the record's own (found in the data tested, a slow dominant period
    puts dozens of harmonics in the tested band, and the test then finds any colour the AR(1) leaves)."""
    if expected_hz is not None and np.isfinite(expected_hz) and expected_hz > 0:
        return float(expected_hz), "the stride period of the motion-frame step"
    if fundamental_hz is not None:
        return float(fundamental_hz), "the given fundamental"
    return None, ""


def _fit_components(t, reg: PoseRegistration, model, phi, ok, ref, smoothing: str, order: int, rho, *, params,
                    fundamental_hz, expected_hz, lam, sig, points, rotation_noise_test: bool, iterations: int,
                    settled: SettledPoseSmoothing | None = None, aperture=None, two, harmonic_correlation=None):
    """:func:`fit_pose_trajectory`'s choice and its six splines for the noise correlation ``rho`` (None: white),
    the two-marker frames ``two`` completed: ``(centre, phi, centre splines, rotation splines, choice, two)``.
    ``harmonic_correlation``: with ``smoothing`` "gcv" and a stride frequency, the AR(1) correlation under which
    the partial spline with the stride's harmonics is fitted (:func:`_correlated_harmonic_refit`)."""
    n = t.size
    if settled is not None:
        return _fit_settled_components(t, reg, model, phi, ok, ref, order, settled, params=params,
                                       fundamental_hz=fundamental_hz, lam=lam, sig=sig, points=points,
                                       iterations=iterations, aperture=aperture, two=two)
    components = np.column_stack([reg.centre[ok], phi[ok]])
    smoothing, f0, choice = _smoothing_choice(t[ok], components, smoothing, order,
                                              params, fundamental_hz, expected_hz,
                                              lam_given=all(v is not None for v in lam),
                                              weighted=reg.information is not None, noise_correlation=rho)
    correlated = choice is not None and "noise_correlation" in choice
    stack = None
    # the rotation components' noise, against which their harmonics are tested: predicted from the
    # registration residual and the marker geometry (isotropic marker noise; pose_noise without the points)
    rot_noise = [None] * 3
    if f0 is not None and params.harmonics == "auto" and rotation_noise_test:
        rot_noise = _rotation_noise(reg, model)
    var = None
    harmonic_correlated = harmonic_correlation is not None and f0 is not None
    if (params.rotation_weights == "auto" and smoothing == "gcv" and order == 5 and reg.information is not None
            and (not correlated or _left_out_route_runs(params, model, points, lam)) and not harmonic_correlated):
        var = frame_variances(reg)[:, 3:]
    spline_options = dict(method=smoothing, order=order, fundamental_hz=f0,
                          events=_pose_events(params.events, smoothing, order, f0))
    if harmonic_correlated:
        spline_options["noise_correlation"] = float(harmonic_correlation)
    if correlated:
        spline_options["noise_correlation"] = choice["noise_correlation"]
        criterion = params.correlated_noise_criterion
        if criterion == "loo":
            stride_hz = fundamental_hz
            if (LEFT_OUT_HARMONICS and stride_hz is None and params.harmonics != "none" and order == 5
                    and points is not None and np.asarray(model).shape[0] >= 4):
                stride_hz = _record_fundamental(t[ok], components, expected_hz)[0]
            lam, harmonic, stacked = _left_out_marker_smoothing(t, reg, model, points, lam, choice, aperture,
                                                                stride_hz)
            if stacked is not None:
                # the plain route's splines blended with the harmonic route's (made as below)
                harmonic_options = _harmonic_route_options(spline_options, params, smoothing, order,
                                                           stacked.fundamental_hz)
                harmonic_noise = (_rotation_noise(reg, model) if params.harmonics == "auto" and rotation_noise_test
                                  else [None] * 3)
                stack = (harmonic_options, stacked.lam, harmonic_noise, stacked.weights, var)
            elif harmonic is not None:
                # the stride's harmonics fitted unpenalised: the spline of white noise with the chosen parameters
                spline_options = _harmonic_route_options(spline_options, params, smoothing, order, harmonic)
                if params.harmonics == "auto" and rotation_noise_test:
                    rot_noise = _rotation_noise(reg, model)
        elif criterion == "reml":
            spline_options["method"] = "reml"
        elif criterion == "risk":
            sig = _correlated_risk_noise(reg, model, points, choice)
            spline_options["method"] = "noise" if sig[0] is not None else smoothing
    choice = _aperture_options(spline_options, aperture, order, choice)
    if stack is not None:   # the harmonic part through the same aperture (the choice's reason already says it)
        _aperture_options(stack[0], aperture, order, {})
    centre, phi, cs, ps = _smooth_pose(t, reg.centre.copy(), phi, ok, two, ref, points, model, spline_options, lam,
                                       sig, var, rot_noise, params.harmonics != "all", iterations, stack=stack)
    return centre, phi, cs, ps, choice, two


def _harmonic_route_options(spline_options: dict, params, smoothing: str, order: int, harmonic: float) -> dict:
    """The left-out choice's spline options with the stride's harmonics at ``harmonic`` Hz unpenalised: white
    noise (no correlation) with the chosen parameters, as white-noise GCV with harmonics fits them."""
    options = {k: v for k, v in spline_options.items() if k != "noise_correlation"}
    options.update(fundamental_hz=harmonic, events=_pose_events(params.events, smoothing, order, harmonic))
    return options


def _rotation_noise(reg: PoseRegistration, model) -> list:
    """The three rotation components' noise (None where not finite) predicted from the registration residual
    and the marker geometry (:func:`pose_noise` without the points): what their harmonics are tested against."""
    return [float(v) if np.isfinite(v) else None for v in pose_noise(reg, None, model)[3:]]


def _aperture_options(spline_options: dict, aperture, order: int, choice):
    """Fit the components through the frames' temporal ``aperture`` (``spline_options["aperture"]``) where the
    spline can (the quintic GCV, unbiased risk and adaptive splines), and return the choice with a reason that
    says it, or why not: a smoothing asked for by name (``choice`` None) gets a choice naming its method and
    the note, so the record says either way whether the aperture was modelled."""
    if aperture is None:
        return choice
    method = spline_options["method"]
    if order == 5 and method in ("gcv", "noise", "adaptive"):
        spline_options["aperture"] = aperture
    note = _aperture_note(aperture, order, method)
    if choice is None:
        named = "gcv_cubic" if (method, order) == ("gcv", 3) else method
        return {"smoothing_method": named, "smoothing_reason": f"{named} asked for by name; {note}"}
    if note not in choice.get("smoothing_reason", ""):
        choice["smoothing_reason"] = choice.get("smoothing_reason", "") + "; " + note
    return choice


def _aperture_note(aperture, order: int, method: str) -> str:
    """What a reason says of the frames' temporal ``aperture`` for a ``method`` spline of ``order``: fitted
    through it, or why not; "" without an aperture."""
    if aperture is None:
        return ""
    if order == 5 and method in ("gcv", "noise", "adaptive"):
        return f"fitted through the frames' temporal aperture ({aperture.description})"
    return (f"the frames' temporal aperture ({aperture.description}) not modelled: the {method} "
            f"order-{order} spline has no aperture")


#: The criteria ``correlated_noise_criterion`` of :class:`horsemocap.params.PoseParams` may name.
CORRELATED_NOISE_CRITERIA = PoseParams.__dataclass_fields__["correlated_noise_criterion"].metadata["choices"]
#: The candidate exponents ``s`` (the GCV smoothing parameters times ``10^s``) that the correlated-noise choice
#: by leaving markers out tries (:func:`_left_out_marker_smoothing`).
LEFT_OUT_DECADES = np.arange(-1.0, 6.01, 0.5)
#: How :func:`marker_cross_validation_per_component` picks among the candidates: ``"min"`` the lowest left-out
#: score, ``"one_se"`` the most smoothing within one standard error of it.
LEFT_OUT_RULES = ("min", "one_se")
#: The rule :func:`_left_out_marker_smoothing` uses.
LEFT_OUT_RULE = "min"
#: Whether :func:`_left_out_marker_smoothing` also tries the candidates with the stride's harmonics
#: (partial splines at white-noise GCV with harmonics' parameters times ``10^s``) and keeps the route whose
#: left-out score is lower (``"always"``: the harmonic route whatever its score, for measuring it).
LEFT_OUT_HARMONICS = True
#: Whether :func:`_left_out_marker_smoothing`, having both routes, fits their blend instead of the lower-scoring
#: one (stacking, :func:`left_out_stacking_weights`): ``w`` times the harmonic route's fit plus ``1 - w`` times
#: the plain route's, ``w`` in [0, 1] minimising the same left-out loss. ``"pose"`` (default): one weight for
#: the whole pose; ``True``: one weight per pose component; a number in [0, 1]: that weight for every
#: component (for measuring); ``False``: one route, the lower-scoring.
LEFT_OUT_STACK = "pose"


@dataclass(frozen=True)
class _StackedRoutes:
    """The harmonic route of the left-out choice blended with the plain one (:func:`_left_out_marker_smoothing`):
    its six smoothing parameters ``lam``, the stride frequency of its harmonics, the harmonic route's weight
    per component and whether those weights minimise the left-out loss (else they are given)."""

    lam: list
    fundamental_hz: float
    weights: np.ndarray
    weights_by_loss: bool = True


def _left_out_route_runs(params: PoseParams, model, points, lam) -> bool:
    """Does the smoothing under correlated noise get chosen by leaving markers out
    (:func:`_left_out_marker_smoothing`): the criterion ``"loo"``, four or more markers, their points, no
    smoothing parameter given? (With three the same criterion is the correlated-error GCV.)"""
    return (params.correlated_noise_criterion == "loo" and points is not None and np.asarray(model).shape[0] >= 4
            and all(v is None for v in lam))


def _left_out_marker_smoothing(t, reg: PoseRegistration, model, points, lam, choice: dict, aperture=None,
                               fundamental_hz: float | None = None
                               ) -> tuple[list, float | None, _StackedRoutes | None]:
    """The six smoothing parameters under correlated noise chosen by leaving each marker out in turn
    (:func:`marker_cross_validation_per_component` on white-noise GCV's parameters; without the stride's
    harmonics and, given ``fundamental_hz``, with them, the lower left-out score kept, or both blended with
    :data:`LEFT_OUT_STACK`), with four or more markers; ``lam`` unchanged (the correlated-error GCV, its reason
    as it is) with three. ``choice`` gets the reason and the cross-validation's scores (``cross_validation``).
    With the frames' temporal ``aperture`` both the white-noise GCV and the left-out fits are made through it,
    as the pose smoothing is. Returns ``(lam, stride frequency of the harmonic route kept or None, the routes
    stacked or None)``: stacked, ``lam`` is the plain route's.

    The candidates (:data:`LEFT_OUT_DECADES`, ``s`` from -1 to 6 by halves) reach far above white-noise GCV's
    parameters and only one decade below: GCV takes noise correlated over frames for motion, so it
    undersmooths it; the half-decade step moves a quintic spline's cutoff frequency (which goes as
    ``lam^(-1/6)``) by about 21 % from one candidate to the next."""
    markers = np.asarray(model).shape[0]
    if points is None or markers < 4 or any(v is not None for v in lam):
        return lam, None, None
    chosen, info, plain, plain_index = _left_out_route(t, reg, model, points, aperture, None)
    harmonic, routes = None, {"plain": (info["cross_validation_score"], info["cross_validation_component_decades"])}
    stacked = None
    if LEFT_OUT_HARMONICS and fundamental_hz is not None:
        with_h, info_h, harmonics, harmonic_index = _left_out_route(t, reg, model, points, aperture, fundamental_hz)
        routes["harmonics"] = (info_h["cross_validation_score"], info_h["cross_validation_component_decades"])
        if LEFT_OUT_STACK is not False:
            stacked = _stacked_routes(plain, plain_index, harmonics, harmonic_index, with_h, fundamental_hz)
            routes["stack"] = _stack_record(stacked, plain, plain_index, harmonics, harmonic_index,
                                            float(np.median(np.diff(np.asarray(t, float)))))
            if np.all(stacked.weights == 1.0):     # every component the harmonic route's: that route's fit
                chosen, info, harmonic, stacked = with_h, info_h, float(fundamental_hz), None
            elif np.all(stacked.weights == 0.0):   # every component the plain route's: that route's fit
                stacked = None
        elif LEFT_OUT_HARMONICS == "always" or info_h["cross_validation_score"] < info["cross_validation_score"]:
            chosen, info, harmonic = with_h, info_h, float(fundamental_hz)
    choice["smoothing_reason"] = _left_out_reason(choice, markers, info, harmonic, stacked, routes)
    choice["cross_validation"] = {"decades": [float(v) for v in LEFT_OUT_DECADES], **info}
    if LEFT_OUT_HARMONICS:
        choice["cross_validation"].update(fundamental_hz=harmonic, routes=routes)
    if stacked is not None:
        # the fit is the blend: its score, its harmonics' frequency (the plain route's s stays in
        # cross_validation_component_decades, the harmonic route's in routes)
        choice["cross_validation"].update(cross_validation_score=routes["stack"][0],
                                          stack_fundamental_hz=stacked.fundamental_hz)
    return [float(v) for v in chosen], harmonic, stacked


def _stacked_routes(plain, plain_index, harmonics, harmonic_index, harmonic_lam, fundamental_hz: float
                    ) -> _StackedRoutes:
    """The harmonic route's weight per component: :data:`LEFT_OUT_STACK` itself when it is a number, else
    :func:`left_out_stacking_weights` (one weight for the whole pose with ``"pose"``)."""
    by_loss = LEFT_OUT_STACK is True or LEFT_OUT_STACK == "pose"
    if by_loss:
        weights = left_out_stacking_weights(plain, plain_index, harmonics, harmonic_index,
                                            common=LEFT_OUT_STACK == "pose")[0]
    else:
        fixed = float(LEFT_OUT_STACK) if isinstance(LEFT_OUT_STACK, (int, float)) else np.nan
        if not 0.0 <= fixed <= 1.0:
            raise ValueError(f"pose.LEFT_OUT_STACK: expected True, False or a weight in [0, 1], got {LEFT_OUT_STACK!r}")
        weights = np.full(6, fixed)
    return _StackedRoutes([float(v) for v in harmonic_lam], float(fundamental_hz), weights, by_loss)


def _stack_record(stacked: _StackedRoutes, plain, plain_index, harmonics, harmonic_index, dt: float) -> tuple:
    """``(left-out score of the blend, m/s^2 rms; the harmonic route's weight per component)`` for the record."""
    loss = _stacked_score(plain, plain.chosen(plain_index), harmonics.chosen(harmonic_index), stacked.weights)
    return float(np.sqrt(loss) / dt ** 2), [round(float(v), 4) for v in stacked.weights]


def _left_out_reason(choice: dict, markers: int, info: dict, harmonic, stacked, routes: dict) -> str:
    """The left-out choice's reason: the noise correlation, the route (or the blend) and the chosen ``s``."""
    decades = ", ".join(f"{c} {v:g}" for c, v in zip(POSE_COMPONENTS, info["cross_validation_component_decades"]))
    if stacked is not None:
        weights = blend_weights_text(stacked.weights)
        how = "minimising the left-out score" if stacked.weights_by_loss else "fixed"
        route = (f"the fits without and with the stride's harmonics at {stacked.fundamental_hz:.4g} Hz unpenalised "
                 f"blended, the harmonic fit's weight {weights} ({how}; left-out scores "
                 + ", ".join(f"{k} {v[0]:.5g}" for k, v in routes.items()) + " m/s^2 rms)")
        decades += "; with the harmonics s = " + ", ".join(
            f"{c} {v:g}" for c, v in zip(POSE_COMPONENTS, routes["harmonics"][1]))
    elif harmonic is None:
        route = "no harmonics" + (" (the blend's weights of the fit with the stride's harmonics all 0)"
                                  if "stack" in routes else "")
    else:
        route = (f"the stride's harmonics at {harmonic:.4g} Hz unpenalised ("
                 + ("the blend's weights of this fit all 1" if "stack" in routes else
                    "a lower left-out score than without") + ")")
    return (f"AR(1) {choice['noise_correlation']:.2f} noise correlation from the rigidity residual, {route}: "
            f"smoothing chosen by leaving each of the {markers} markers out in turn (its acceleration predicted from "
            f"the others' pose, which holds none of its noise, so the choice holds whatever the noise's correlation "
            f"over frames): white-noise GCV's parameters times 10^s, s = {decades}"
            + ("" if LEFT_OUT_RULE == "min" else f" ({LEFT_OUT_RULE} rule)"))


def blend_weights_text(weights) -> str:
    """A blend's weights of the harmonic fit in words: one for the whole pose, or one per component.

    Examples
    --------
    >>> blend_weights_text([0.25] * 6)
    '0.25 for the whole pose'
    >>> blend_weights_text([0, 0, 0, 1, 1, 0.5])
    'per component cx 0.00, cy 0.00, cz 0.00, phix 1.00, phiy 1.00, phiz 0.50'
    """
    w = np.asarray(weights, float)
    if np.all(w == w[0]):
        return f"{w[0]:.2f} for the whole pose"
    return "per component " + ", ".join(f"{c} {v:.2f}" for c, v in zip(POSE_COMPONENTS, w))


def _left_out_route(t, reg: PoseRegistration, model, points, aperture, fundamental_hz) -> tuple:
    """:func:`marker_cross_validation_per_component` on white-noise GCV's parameters, both without the stride's
    harmonics (``fundamental_hz`` None) or both with them: ``(lam, info, left-out predictions, chosen index)``."""
    harmonics = "none" if fundamental_hz is None else "auto"
    white = fit_pose_trajectory(t, reg, model, PoseParams(smoothing="gcv", harmonics=harmonics,
                                                          rotation_weights="equal", partial_frames=False),
                                iterations=0, aperture=aperture, fundamental_hz=fundamental_hz)
    base = np.array([s.info["lam"] for s in white.centre_splines + white.rotvec_splines])
    return _left_out_choice(t, reg, points, model, base, LEFT_OUT_DECADES, 3, aperture, LEFT_OUT_RULE,
                            fundamental_hz)


def _correlated_risk_noise(reg: PoseRegistration, model, points, choice: dict) -> np.ndarray:
    """The six pose components' noise for the correlated-error unbiased risk, measured by the rigidity residual
    (all None, the correlated-error GCV kept, with fewer than four markers or no residual); ``choice``'s reason
    says which."""
    markers = np.asarray(model).shape[0]
    level = pose_noise(reg, points, model) if points is not None and markers >= 4 else np.full(6, np.nan)
    if not np.all(np.isfinite(level) & (level > 0)):
        why = (f"{markers} markers: their residual does not measure the noise normal to their plane" if markers < 4
               else "no noise level measurable from the rigidity residual")
        choice["smoothing_reason"] += f"; {why}: the correlated-error GCV kept"
        return np.full(6, None)
    choice["smoothing_reason"] += ("; smoothing by the unbiased risk with the noise's covariance known (its level "
                                   "and AR(1) correlation from the rigidity residual)")
    return level.astype(object)


def _fit_settled_components(t, reg: PoseRegistration, model, phi, ok, ref, order: int,
                            settled: SettledPoseSmoothing, *, params, fundamental_hz, lam, sig, points,
                            iterations: int, aperture=None, two):
    """:func:`_fit_components` with the choices of ``settled``: no method, stride frequency, noise correlation
    or rotation weighting chosen; each component keeps the first 0 .. ``settled.harmonics`` harmonics that
    the criterion prefers at the given smoothing parameter (neither the plain spline's cutoff nor the rotation
    noise test is run again: the settled count passed them)."""
    if settled.blend_weights is not None:
        return _fit_settled_blend(t, reg, model, phi, ok, ref, order, settled, params=params,
                                  fundamental_hz=fundamental_hz, lam=lam, sig=sig, points=points,
                                  iterations=iterations, aperture=aperture, two=two)
    f0 = fundamental_hz if settled.method in ("gcv", "noise") and order == 5 else None
    choice = None if settled.choice is None else dict(settled.choice)
    var, = _settled_rotation_variances(reg, choice, settled.rotation_weighted)
    spline_options = dict(method="gcv" if settled.method == "gcv_cubic" else settled.method, order=order,
                          fundamental_hz=f0, events=_pose_events(params.events, settled.method, order, f0))
    if settled.noise_correlation is not None:
        spline_options["noise_correlation"] = settled.noise_correlation
    choice = _aperture_options(spline_options, aperture, order, choice)
    most = settled.harmonics if f0 is not None else None
    centre, phi, cs, ps = _smooth_pose(t, reg.centre.copy(), phi, ok, two, ref, points, model, spline_options, lam,
                                       sig, var, [None] * 3, False, iterations, most_harmonics=most,
                                       compare_weights=False)
    return centre, phi, cs, ps, choice, two


def _settled_rotation_variances(reg: PoseRegistration, choice: dict | None, *weightings) -> list:
    """Per settled weighting (3 bool each: which rotation components a route weights), the frames' rotation
    variances (n, 3; NaN columns: equal weights there), None for a route that weights none; all None without
    marker covariances in ``reg``, and ``choice``'s reason then says the settled weighting could not be
    applied."""
    if not any(any(w) for w in weightings):
        return [None] * len(weightings)
    if reg.information is None:
        if choice is not None:
            choice["smoothing_reason"] = (choice.get("smoothing_reason", "") + "; the settled rotation weighting "
                                          "is not applied: this record's registration has no marker covariances, "
                                          "so the rotation is weighted equally")
        return [None] * len(weightings)
    full = frame_variances(reg)[:, 3:]
    out = []
    for w in weightings:
        var = None
        if any(w):
            var = full.copy()
            var[:, ~np.asarray(w, bool)] = np.nan
        out.append(var)
    return out


def _fit_settled_blend(t, reg: PoseRegistration, model, phi, ok, ref, order: int, settled: SettledPoseSmoothing, *,
                       params, fundamental_hz, lam, sig, points, iterations: int, aperture=None, two):
    """:func:`_fit_settled_components` of a settled blend: each component's plain route (the spline at ``lam``,
    with the settled noise correlation) and harmonic route (white noise, the stride's harmonics at
    ``fundamental_hz`` unpenalised, the spline at ``settled.harmonic_lam``, the first 0 .. ``settled.harmonics``
    harmonics kept by GCV at that parameter) fitted once each and blended with ``settled.blend_weights``
    (:func:`_blended_component`); nothing searched, nothing tested again."""
    if order != 5 or fundamental_hz is None:
        raise ValueError("settled: a blend of the fits without and with the stride's harmonics needs the quintic "
                         f"spline and a stride frequency, got order {order}, fundamental_hz {fundamental_hz!r}")
    plain = dict(method="gcv", order=order, fundamental_hz=None, events=_pose_events(params.events, "gcv", order, None))
    if settled.noise_correlation is not None:
        plain["noise_correlation"] = settled.noise_correlation
    harmonic = _harmonic_route_options(plain, params, "gcv", order, fundamental_hz)
    choice = _aperture_options(plain, aperture, order, None if settled.choice is None else dict(settled.choice))
    _aperture_options(harmonic, aperture, order, {})
    var, harmonic_var = _settled_rotation_variances(reg, choice, settled.rotation_weighted,
                                                    settled.harmonic_rotation_weighted or settled.rotation_weighted)
    stack = (harmonic, list(settled.harmonic_lam), [None] * 3, tuple(settled.blend_weights), harmonic_var)
    centre, phi, cs, ps = _smooth_pose(t, reg.centre.copy(), phi, ok, two, ref, points, model, plain, lam, sig,
                                       var, [None] * 3, False, iterations, most_harmonics=settled.harmonics,
                                       compare_weights=False, stack=stack)
    for s in cs + ps:
        s.info["blended"]["settled"] = True     # the parameters and the weight given, not chosen on this record
    return centre, phi, cs, ps, choice, two


@dataclass(frozen=True)
class SettledPoseSmoothing:
    """The pose smoothing's choices made once, to be reused on other records of the same body and motion.

    A long recording's passes film the same horse in the same gait: the
    smoothing's choices (which method ``"auto"`` runs, the noise correlation,
    the stride frequency, each component's smoothing parameter, how many
    stride harmonics it may keep and whether the rotation is weighted by its
    predicted variance) are settled on the longest pass
    (:func:`settle_pose_smoothing`) and given to :func:`fit_pose_trajectory`
    (``settled``) for the others, which then fit each component once instead
    of searching. A smoothing parameter of the quintic spline is a bandwidth
    (:func:`horsemocap.splines.half_gain_frequency`, weights of mean 1), so
    it keeps its meaning on a record of another length.

    Attributes
    ----------
    method : str
        The method run: ``"gcv"``, ``"adaptive"``, ``"noise"``, ``"gcv_cubic"`` or ``"none"``.
    noise_correlation : float or None
        The AR(1) noise correlation of the correlated-error GCV, None for white noise.
    fundamental_hz : float or None
        The stride frequency of the harmonics (None: no harmonics).
    lam : tuple of 6 (float or None)
        The smoothing parameters ``cx, cy, cz, phix, phiy, phiz``; None where they are chosen again
        (the adaptive penalty, whose scale belongs to its record's roughness).
    harmonics : tuple of 6 int
        The most stride harmonics each component may keep (its largest harmonic's order; 0: none).
    rotation_weighted : tuple of 3 bool
        Whether each rotation component is smoothed with every frame weighted by its predicted variance (in a
        blend: its plain route).
    choice : dict or None
        What ``smoothing="auto"`` ran and why (copied into each component's ``info``), None if the
        method was named.
    harmonic_lam : tuple of 6 float or None
        A blend's harmonic route (the partial splines with the stride's harmonics, white noise): its
        smoothing parameters. None: no blend.
    blend_weights : tuple of 6 float or None
        A blend's weight of the harmonic route per component, in [0, 1]: each component is
        ``w * harmonic route + (1 - w) * plain route`` (:func:`horsemocap.splines.blend_splines`).
        With a blend, ``lam`` and ``noise_correlation`` are the plain route's, ``fundamental_hz`` and
        ``harmonics`` the harmonic route's. None: no blend.
    harmonic_rotation_weighted : tuple of 3 bool or None
        A blend's harmonic route: whether each rotation component is weighted by its frames' predicted
        variances (each route chose for itself). None: as ``rotation_weighted``.

    Examples
    --------
    >>> s = SettledPoseSmoothing("gcv", None, 1.5, (1e-6,) * 6, (2, 2, 1, 1, 0, 1), (False, True, False))
    >>> s.harmonics[2], s.rotation_weighted[1], s.blend_weights is None
    (1, True, True)

    A blend: the plain route's parameters under AR(1) 0.8 noise, the harmonic route's and its weight:

    >>> b = SettledPoseSmoothing("gcv", 0.8, 1.5, (1e-5,) * 6, (2,) * 6, (False,) * 3,
    ...                          harmonic_lam=(1e-7,) * 6, blend_weights=(0.4,) * 6)
    >>> b.noise_correlation, b.blend_weights[0]
    (0.8, 0.4)
    """

    method: str
    noise_correlation: float | None
    fundamental_hz: float | None
    lam: tuple
    harmonics: tuple
    rotation_weighted: tuple
    choice: dict | None = None
    harmonic_lam: tuple | None = None
    blend_weights: tuple | None = None
    harmonic_rotation_weighted: tuple | None = None

    def __post_init__(self):
        if (self.harmonic_lam is None) != (self.blend_weights is None):
            raise ValueError("SettledPoseSmoothing: a blend needs both harmonic_lam and blend_weights, got "
                             f"harmonic_lam {self.harmonic_lam!r}, blend_weights {self.blend_weights!r}")
        if self.blend_weights is not None:
            w = np.asarray(self.blend_weights, float)
            if w.shape != (6,) or not np.all((w >= 0) & (w <= 1)):
                raise ValueError(f"blend_weights: expected 6 weights in [0, 1], got {self.blend_weights!r}")
            lams = list(self.lam) + list(self.harmonic_lam)
            if len(lams) != 12 or not all(v is not None and np.isfinite(v) and v > 0 for v in lams):
                raise ValueError("lam, harmonic_lam: a blend needs the six positive smoothing parameters of each "
                                 f"route, got {self.lam!r} and {self.harmonic_lam!r}")


def settle_pose_smoothing(trajectory: PoseTrajectory, params: PoseParams = PoseParams()) -> SettledPoseSmoothing:
    """The choices :func:`fit_pose_trajectory` made for ``trajectory`` (smoothed with ``params``), to reuse.

    A trajectory whose components blend the fits without and with the
    stride's harmonics (the left-out choice's stack) gives both routes'
    smoothing parameters, the harmonics each keeps and the weights
    (:class:`SettledPoseSmoothing`'s ``harmonic_lam`` and ``blend_weights``):
    a record smoothed with them fits both routes and blends them, searching
    nothing.

    Examples
    --------
    A body swaying at 1 Hz; the settled choices smooth a second record of it
    with the same smoothing parameters, searching none:

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> rng = np.random.default_rng(0)
    >>> def record(n):
    ...     t = np.arange(n) / 50.0
    ...     R = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * t), [0, 0, 1])).as_matrix()
    ...     pts = np.einsum("kij,mj->kmi", R, model) + rng.normal(0, 1e-3, (n, 3, 3))
    ...     return t, pts, register_pose(pts, model)
    >>> t, pts, reg = record(400)
    >>> first = fit_pose_trajectory(t, reg, model, points=pts)
    >>> settled = settle_pose_smoothing(first)
    >>> settled.method, round(settled.fundamental_hz, 2)
    ('gcv', 1.0)
    >>> t2, pts2, reg2 = record(200)
    >>> second = fit_pose_trajectory(t2, reg2, model, points=pts2, settled=settled)
    >>> second.smoothing["phiz"]["lam"] == first.smoothing["phiz"]["lam"]
    True
    """
    info = trajectory.smoothing
    names = POSE_COMPONENTS
    choice = trajectory.smoothing_choice
    method = params.smoothing if choice is None else choice["method"]
    rho = None
    if method == "gcv_ar1":
        method, rho = "gcv", float(choice["noise_correlation"])
    f0 = info["cx"].get("fundamental_hz")
    f0 = float(f0) if f0 is not None and np.isfinite(f0) and method in ("gcv", "noise") else None
    blended = all("blended" in info[c] for c in names)
    lam = tuple(float(info[c]["lam"]) if method != "adaptive" and info[c].get("lam") is not None
                and np.isfinite(info[c]["lam"]) and info[c]["lam"] > 0 else None for c in names)
    harmonics = tuple(int(max(info[c].get("harmonic_indices") or [0])) if f0 is not None else 0 for c in names)
    weighted = _weighted_rotation(info[c] for c in names[3:])
    harmonic_lam = weights = harmonic_weighted = None
    if blended and f0 is not None:
        # a blend of two fits: each route's parameters, rotation weighting and the harmonic route's weight, reused
        lam = tuple(float(info[c]["blended"]["plain"]["lam"]) for c in names)
        harmonic_lam = tuple(float(info[c]["blended"]["harmonics"]["lam"]) for c in names)
        weights = tuple(float(info[c]["blend_weights"][1]) for c in names)
        weighted = _weighted_rotation(info[c]["blended"]["plain"] for c in names[3:])
        harmonic_weighted = _weighted_rotation(info[c]["blended"]["harmonics"] for c in names[3:])
    elif f0 is not None and rho is not None and not choice.get("correlated_harmonics"):
        # the left-out choice's fits with the stride's harmonics are white-noise fits: the harmonic route's
        # parameters are reused as such (the correlated-error refit with harmonics keeps its correlation)
        rho = None
    kept = None
    if choice is not None:
        kept = {"smoothing_method": choice["method"], "smoothing_reason": choice["reason"]}
        if weights is not None:
            kept["smoothing_reason"] += ("; reused on another record of the same motion (a long recording's other "
                                         "passes, a long record's windows): both fits made at these parameters and "
                                         f"blended with the harmonic fit's weight {blend_weights_text(weights)}, "
                                         "nothing chosen again")
        if "noise_correlation" in choice:
            kept["noise_correlation"] = choice["noise_correlation"]
        if choice.get("correlated_harmonics"):
            kept["correlated_harmonics"] = True
    return SettledPoseSmoothing(method, rho, f0, lam, harmonics, weighted, kept, harmonic_lam, weights,
                                harmonic_weighted)


def _weighted_rotation(infos) -> tuple:
    """Per rotation component's fit ``info``, whether its frames were weighted by their predicted variances."""
    return tuple((i.get("weights") or "equal") != "equal" for i in infos)


def _check_smoothing_choices(params: PoseParams, lam) -> list:
    """The six smoothing parameters (None: chosen) as a list; a clear error for a choice not known."""
    lam = [None] * 6 if lam is None else list(lam)
    if len(lam) != 6:
        raise ValueError(f"lam: expected 6 smoothing parameters (cx, cy, cz, phix, phiy, phiz), got {len(lam)}")
    if params.harmonics not in ("none", "auto", "all"):
        raise ValueError(f"harmonics: expected 'none', 'auto' or 'all', got {params.harmonics!r}")
    if params.rotation_weights not in ("auto", "equal"):
        raise ValueError(f"rotation_weights: expected 'auto' or 'equal', got {params.rotation_weights!r}")
    if params.correlated_noise_criterion not in CORRELATED_NOISE_CRITERIA:
        raise ValueError(f"correlated_noise_criterion: expected one of {', '.join(CORRELATED_NOISE_CRITERIA)}, "
                         f"got {params.correlated_noise_criterion!r}")
    return lam


def _check_pose_frames(t, reg: PoseRegistration) -> np.ndarray:
    """The frames with a pose (n,) bool; a clear error if the times or the poses cannot be smoothed."""
    n = t.size
    if reg.rotation.shape != (n, 3, 3):
        raise ValueError(f"registration: expected {n} frames to match t, got {reg.rotation.shape[0]}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t: times must increase")
    ok = np.all(np.isfinite(reg.rotation), axis=(1, 2))
    if ok.sum() < 4:
        raise ValueError(f"registration: a pose trajectory needs at least 4 frames with a pose, got {int(ok.sum())} "
                         f"(reasons: {sorted(set(reg.reason[~ok]))})")
    return ok


def _smoothing_choice(t, Y, smoothing: str, order: int, params: PoseParams, fundamental_hz, expected_hz, *,
                      lam_given: bool, weighted: bool, noise_correlation: float | None = None):
    """``(smoothing, fundamental or None, choice)``: ``"auto"`` settled (:func:`choose_smoothing`; ``choice``
    says what ran and why, else None) and the stride frequency whose harmonics are fitted, if any."""
    def with_harmonics(method):
        return params.harmonics != "none" and method in ("gcv", "noise") and order == 5

    found_f0, confirmed, choice = fundamental_hz, "", None
    if (smoothing == "auto" or with_harmonics(smoothing)) and found_f0 is None:
        found_f0, confirmed = _record_fundamental(t, Y, expected_hz)
    if smoothing == "auto":
        smoothing, reason = choose_smoothing(found_f0, params.events, order, lam_given=lam_given,
                                             noise_correlation=noise_correlation,
                                             criterion=params.correlated_noise_criterion)
        choice = {"smoothing_method": smoothing, "smoothing_reason": reason}
        if smoothing == "gcv_ar1":
            smoothing = "gcv"
            choice["noise_correlation"] = min(float(noise_correlation), 0.99)
            return smoothing, None, choice
        choice["smoothing_reason"] += confirmed
        if smoothing == "adaptive" and weighted and params.rotation_weights == "auto":
            choice["smoothing_reason"] += "; the rotation's per-frame variance weights are a GCV option and not applied"
    return smoothing, (found_f0 if with_harmonics(smoothing) else None), choice


def _two_marker_frames(points, ok, n) -> tuple[np.ndarray, np.ndarray | None]:
    """``(two, departure)``: the frames without a pose in which exactly two markers of ``points`` are seen and
    their distance is the rigid body's (:func:`two_marker_distance_departure` within
    :data:`PARTIAL_POSE_RIGIDITY_LIMIT`), and every frame's departure; none and None without ``points``."""
    if points is None:
        return np.zeros(n, bool), None
    pts = np.asarray(points, float)
    if pts.shape[:1] != (n,):
        raise ValueError(f"points: expected {n} frames to match t, got shape {pts.shape}")
    departure = two_marker_distance_departure(pts, ok)
    two = ~ok & (np.all(np.isfinite(pts), axis=2).sum(1) == 2)
    return two & ~_refused_partial(departure), departure


def _refused_partial(departure) -> np.ndarray:
    """The frames whose two markers' distance departs more than :data:`PARTIAL_POSE_RIGIDITY_LIMIT` (NaN:
    not tested, not refused)."""
    return np.isfinite(departure) & (np.abs(departure) > PARTIAL_POSE_RIGIDITY_LIMIT)


#: How far (in robust standard deviations) the distance between a two-marker frame's markers may depart from
#: the same pair's distance in the frames with a pose before the frame is refused a partial pose: the same
#: six-sigma scale as the rigid-body step's test of a marker moving against the others' rigid motion. A partial
#: pose takes its rotation about the two markers' line from the trajectory and its remaining five degrees of
#: freedom from the two markers alone, so a pair whose distance is wrong (a marker half out of a view, a blob
#: merged with another) moves the pose by as much, and a frame that far off would steer the smoothing's choice.
PARTIAL_POSE_RIGIDITY_LIMIT = 6.0
#: The fewest frames with a pose and both markers of a pair from which their distance's scatter is measured;
#: with fewer the pair's frames are not tested (kept): the scaled median absolute deviation of eight normal
#: distances already scatters by about 40 % of itself, and less data would make the six-sd test a guess.
PARTIAL_POSE_RIGIDITY_MIN_FRAMES = 8


def two_marker_distance_departure(points, ok) -> np.ndarray:
    """Per frame in which exactly two markers are seen, how far their distance departs from the rigid body's.

    A rigid marker set keeps the distance between any two of its markers.
    The pair's usual distance and scatter are measured over the frames
    with a pose (``ok``) in which both are seen: the median and the
    median absolute deviation (times 1.4826, a normal error's standard
    deviation). The departure is the frame's distance minus the median,
    over that scatter. A frame seen with more or fewer than two markers, in
    ``ok``, or whose pair has fewer than
    :data:`PARTIAL_POSE_RIGIDITY_MIN_FRAMES` such frames, gets NaN.

    Parameters
    ----------
    points : (n, m, 3)
        The markers per frame, NaN where not seen.
    ok : (n,) bool
        The frames with a pose (three or more markers registered).

    Returns
    -------
    (n,) array of departures (robust standard deviations, signed: positive when further apart).

    Examples
    --------
    Two markers 0.25 m apart with a 1 mm scatter; the last frame sees only two of them, 20 mm too far apart.

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.1, 0.2, 0]])
    >>> pts = model + rng.normal(0, 7e-4, (30, 3, 3))
    >>> pts[-1, 2] = np.nan
    >>> pts[-1, 1, 0] += 0.02
    >>> ok = np.r_[np.ones(29, bool), False]
    >>> z = two_marker_distance_departure(pts, ok)
    >>> bool(np.all(np.isnan(z[:-1]))), bool(z[-1] > PARTIAL_POSE_RIGIDITY_LIMIT)
    (True, True)
    """
    pts = np.asarray(points, float)
    ok = np.asarray(ok, bool)
    seen = np.all(np.isfinite(pts), axis=2)
    out = np.full(pts.shape[0], np.nan)
    for k in np.flatnonzero(~ok & (seen.sum(1) == 2)):
        i, j = np.flatnonzero(seen[k])
        usual = np.linalg.norm(pts[ok & seen[:, i] & seen[:, j], i] - pts[ok & seen[:, i] & seen[:, j], j], axis=1)
        if usual.size < PARTIAL_POSE_RIGIDITY_MIN_FRAMES:
            continue
        centre = float(np.median(usual))
        # a floor of a nanometre per metre keeps exact distances (no scatter) from dividing by zero, far
        # below any camera's error, so a real departure is still refused and an exact frame kept
        scatter = max(1.4826 * float(np.median(np.abs(usual - centre))), 1e-9 * centre)
        out[k] = (float(np.linalg.norm(pts[k, i] - pts[k, j])) - centre) / scatter
    return out


def _refused_partial_reasons(reason, departure, ok, two) -> np.ndarray:
    """``reason`` with the frames refused a partial pose (two markers seen, departure past the limit, so not
    in ``two``) saying why; ``departure`` from :func:`_two_marker_frames` (None: no partial frames tried)."""
    if departure is None:
        return reason
    refused = np.flatnonzero(_refused_partial(departure) & ~np.asarray(two, bool) & ~np.asarray(ok, bool))
    reason = np.array(reason, dtype=object)
    for k in refused:
        reason[k] = (f"{reason[k]}; no partial pose: its two markers' distance departs from the rigid body's by "
                     f"{departure[k]:+.1f} robust sd (more than {PARTIAL_POSE_RIGIDITY_LIMIT:g})")
    return reason.astype(str)


def _smooth_pose(t, centre, phi, ok, two, ref, points, model, options: dict, lam, sig, var, rot_noise,
                 harmonic_cutoff: bool, iterations: int, most_harmonics=None, compare_weights: bool = True,
                 stack=None):
    """The six components' splines; with partial frames (``two``) smoothed again with their completed poses.

    ``most_harmonics``: (6,) the most harmonics each component tries (None: the spline's default);
    ``compare_weights`` False: a rotation component with variances is fitted weighted only; ``stack``:
    ``(options, lam, rotation noise, weights, rotation variances)`` of a second fit of the same frames (its own
    rotation variances, as ``var`` for the first), each component the blend ``weights * second + (1 - weights)
    * first`` (:func:`horsemocap.splines.blend_splines`).
    Returns the centroid and rotation vectors the splines were fitted to and the splines (3 + 3).
    """
    use = ok
    x_model = np.asarray(model, float)
    extra = [{} if most_harmonics is None else {"max_harmonics": int(k)} for k in (most_harmonics or [0] * 6)]

    def fit(options, lam, rot_noise, var):
        cs = tuple(smoothing_spline(t[use], centre[use, i], lam=lam[i], noise=sig[i], **options, **extra[i])
                   for i in range(3))
        ps = tuple(_rotation_component(t[use], phi[use, i], None if var is None else var[use, i],
                                       lam=lam[3 + i], noise=sig[3 + i], harmonic_cutoff=harmonic_cutoff,
                                       harmonic_noise=rot_noise[i], compare=compare_weights, **options,
                                       **extra[3 + i]) for i in range(3))
        return cs + ps

    for it in range(iterations + 1 if two.any() else 1):
        splines = fit(options, lam, rot_noise, var)
        if stack is not None:
            second = fit(*stack[:3], stack[4])
            splines = tuple(_blended_component(a, b, w) for a, b, w in zip(splines, second, stack[3]))
        cs, ps = splines[:3], splines[3:]
        if it == iterations or not two.any():
            break
        tk = t[two]
        # the prediction is what the frame observes (the trajectory averaged over its aperture, if any), as
        # its two markers are
        Rp = (Rotation.from_rotvec(np.stack([s.observed(tk) for s in ps], -1)) * ref.rotation(tk)).as_matrix()
        cp = np.stack([s.observed(tk) for s in cs], -1)
        R2, c2 = partial_pose(np.asarray(points, float)[two], x_model, Rp, cp)
        centre[two] = c2
        phi[two] = (Rotation.from_matrix(R2) * ref.rotation(tk).inv()).as_rotvec()
        phi = unwrap_rotvec(phi)
        use = ok | two
    return centre, phi, cs, ps


#: A blended rotation component's ``weights`` when only one of its two routes weighted its frames
#: (:func:`_blended_component`).
ONE_ROUTE_WEIGHTS = "inverse variance in one route"


def _blended_component(plain, harmonic, weight: float):
    """One pose component's blend of the plain route's spline and the harmonic route's
    (:func:`horsemocap.splines.blend_splines`), its ``info`` also naming the harmonic part's stride frequency and
    harmonics (what the trajectory's readers look up: the fit holds them at this weight)."""
    blend = blend_splines(plain, harmonic, weight)
    for key in ("fundamental_hz", "harmonics", "harmonic_indices"):
        if harmonic.info.get(key) is not None:
            blend.info[key] = harmonic.info[key]
    blend.info["blended"] = {"plain": {k: plain.info.get(k) for k in ("lam", "edf", "weights")},
                             "harmonics": {k: harmonic.info.get(k) for k in ("lam", "edf", "harmonics", "weights")}}
    weighted = [part.info.get("weights", "equal") != "equal" for part in (plain, harmonic)]
    if any(weighted):     # a rotation component weighted by its frames' predicted variance in either route
        blend.info["weights"] = "inverse variance, Huber" if all(weighted) else ONE_ROUTE_WEIGHTS
    return blend


def _frame_validity(t, reg_reason, have, two, max_gap_s):
    """``(valid, reason)`` per frame: a pose, a partial pose, a bridged short gap, or NaN and why."""
    dt = float(np.median(np.diff(t)))
    max_gap = 5 * dt if max_gap_s is None else float(max_gap_s)
    gaps = _gap_lengths(have)
    first, last = np.flatnonzero(have)[[0, -1]]
    valid = have.copy()
    reason = np.array(reg_reason, dtype=object)
    reason[two] = "partial pose: 2 markers; the rotation about their line from the smoothed trajectory"
    for i in np.flatnonzero(~have):
        if i < first or i > last:
            reason[i] = f"no pose ({reg_reason[i]}); outside the frames with a pose"
        elif gaps[i] * dt <= max_gap + 1e-9:
            valid[i] = True
            reason[i] = f"bridged gap of {gaps[i]} frame(s) ({reg_reason[i]})"
        else:
            reason[i] = f"gap of {gaps[i]} frames longer than {max_gap:.3g} s ({reg_reason[i]})"
    return valid, reason.astype(str)


#: The fewest cycles a record's own fundamental search goes down to when another estimator's
#: fundamental is there to confirm it (:func:`fit_pose_trajectory`'s ``expected_fundamental_hz``).
SHORT_RECORD_CYCLES = 1.5
#: How near (relative) the two estimates must be for the shorter search's result to be kept.
FUNDAMENTAL_AGREEMENT = 0.05


def _record_fundamental(t, Y, expected_hz=None) -> tuple:
    """``(fundamental or None, note)``: :func:`horsemocap.splines.estimate_fundamental` over at least 2
    cycles; if it finds none and ``expected_hz`` is given, over :data:`SHORT_RECORD_CYCLES`, kept only
    when within :data:`FUNDAMENTAL_AGREEMENT` of ``expected_hz`` (the note says so)."""
    try:
        return estimate_fundamental(t, Y)[0], ""
    except ValueError:
        if expected_hz is None or not np.isfinite(expected_hz) or expected_hz <= 0:
            return None, ""
    try:
        f, _ = estimate_fundamental(t, Y, min_cycles=SHORT_RECORD_CYCLES)
    except ValueError:
        return None, ""
    if abs(f / expected_hz - 1) > FUNDAMENTAL_AGREEMENT:
        return None, ""
    return f, (f" (a record of under 2 cycles: found searching down to {SHORT_RECORD_CYCLES:g} cycles, "
               f"confirmed by the stride period of the motion-frame step, {expected_hz:.4g} Hz)")


#: The lag-1 autocorrelation of the markers' rigidity residual (:func:`rigidity_residual_correlation`)
#: from which ``smoothing="auto"`` treats the noise as correlated (:func:`choose_smoothing`).
NOISE_CORRELATION_THRESHOLD = 0.3
#: The fewest pairs of consecutive residuals :func:`rigidity_residual_correlation` measures from.
NOISE_CORRELATION_MIN_PAIRS = 30


def rigidity_residual_correlation(points, registration: PoseRegistration) -> float:
    """The lag-1 autocorrelation ``rho`` of the markers' rigidity residual as an AR(1) noise; NaN if none.

    The residual (each frame's markers minus the registered model) is noise
    the rigid motion does not contain. Real residuals also hold slow parts
    (skin and tape movement, a cluster that bends) whose correlation is near
    1 at one frame: taken as the noise of an AR(1) model they would make
    everything noise. ``rho`` is therefore estimated from the residual's
    frame-to-frame differences, which the slow parts hardly reach: for an
    AR(1) noise the differences have lag-1 correlation ``-(1 - rho)/2``, so
    ``rho = 1 + 2 corr(d_k, d_(k+1))``, pooled over the markers' coordinates
    and the frames where three consecutive residuals are finite. NaN with
    fewer than :data:`NOISE_CORRELATION_MIN_PAIRS` pairs, no residual beyond
    round-off (exact data), or an estimate outside (-1, 1) (differences
    positively correlated: a residual smooth at the frame scale, which an
    AR(1) noise does not describe).

    Examples
    --------
    Four markers with AR(1) noise of correlation 0.6 on a still body:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> model = np.array([[0.0, 0, 0], [0.2, 0, 0], [0.0, 0.15, 0.05], [0.1, 0.1, 0.1]])
    >>> e = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(0, 1e-3, (3000, 4, 3)), axis=0)
    >>> pts = model + e
    >>> round(rigidity_residual_correlation(pts, register_pose(pts, model)), 1)
    0.6
    """
    if points is None:
        return float("nan")
    pts = np.asarray(points, float)
    if pts.shape != registration.registered.shape:
        raise ValueError(f"points: expected shape {registration.registered.shape} to match the registration, "
                         f"got {pts.shape}")
    d = np.diff((pts - registration.registered).reshape(pts.shape[0], -1), axis=0)
    a, b = d[:-1], d[1:]
    both = np.isfinite(a) & np.isfinite(b)
    den = 0.5 * np.sum(np.where(both, a * a + b * b, 0.0))
    size = np.nanmax(np.abs(pts)) if np.isfinite(pts).any() else 0.0
    if both.sum() < NOISE_CORRELATION_MIN_PAIRS or not den > (1e-10 * size) ** 2 * both.sum():
        return float("nan")
    rho = 1 + 2 * float(np.sum(np.where(both, a * b, 0.0)) / den)
    return rho if -1 < rho < 1 else float("nan")


#: How many standard errors above zero the rigidity residual's correlation must stand before ``"auto"``
#: treats the noise as correlated (:func:`significant_noise_correlation`).
NOISE_CORRELATION_SIGNIFICANCE = 2.0


def significant_noise_correlation(points, registration: PoseRegistration) -> float:
    """:func:`rigidity_residual_correlation` where it stands clear of white noise; NaN otherwise.

    The estimate ``rho = 1 + 2 r`` from ``n`` frames of residual differences
    has a standard error of about ``2 / sqrt(n)`` (that of a lag-1
    correlation ``r``, doubled). A short record's estimate is mostly that
    error: white detection noise through the tracker and the gap bridging
    reads as 0.3-0.5 on 40 frames. Only an estimate more than
    :data:`NOISE_CORRELATION_SIGNIFICANCE` standard errors above zero is
    returned, so a short record keeps the white-noise choice and a long
    record of a real system's filtered trajectories (hundreds of frames) gets
    the correlated one.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> model = np.array([[0.0, 0, 0], [0.2, 0, 0], [0.0, 0.15, 0.05], [0.1, 0.1, 0.1]])
    >>> e = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(0, 1e-3, (3000, 4, 3)), axis=0)
    >>> round(significant_noise_correlation(model + e, register_pose(model + e, model)), 1)
    0.6
    >>> e = lfilter([1.0], [1.0, -0.6], np.random.default_rng(0).normal(0, 1e-3, (20, 4, 3)), axis=0)
    >>> bool(np.isnan(significant_noise_correlation(model + e, register_pose(model + e, model))))
    True
    """
    rho = rigidity_residual_correlation(points, registration)
    if not np.isfinite(rho):
        return rho
    residual = np.asarray(points, float) - registration.registered
    frames = int(np.sum(np.all(np.isfinite(residual.reshape(residual.shape[0], -1)), axis=1))) - 2
    if frames < 1 or rho < NOISE_CORRELATION_SIGNIFICANCE * 2.0 / np.sqrt(frames):
        return float("nan")
    return rho


#: The common factors (powers of ten) on the GCV smoothing parameters that :func:`marker_cross_validation` tries.
CROSS_VALIDATION_DECADES = np.arange(-1.0, 6.01, 0.5)
#: The part of the record at each end (a fraction of its frames) left out of the cross-validation's error:
#: there the acceleration of any smoothing spline rests on a few frames.
CROSS_VALIDATION_MARGIN = 0.05


def _left_out_registration(registration: PoseRegistration, points, model, i: int):
    """``(registration, model)`` of the cluster without marker ``i``: registered anew from three or more
    others (with their covariances and the same extra noise where ``registration`` was registered with the
    markers' covariances); with two others their partial pose (:func:`partial_pose`) completed by the full registration
    (the rotation about their line, which moves marker ``i`` only across the cluster's plane)."""
    keep = [j for j in range(model.shape[0]) if j != i]
    if len(keep) >= 3 and registration.marker_covariance is not None:
        s0 = registration.extra_noise_m
        return register_pose(points[:, keep], model[keep], covariance=registration.marker_covariance[:, keep],
                             extra_noise=float(s0) if np.isfinite(s0) else "estimate"), model[keep]
    if len(keep) >= 3:
        return register_pose(points[:, keep], model[keep]), model[keep]
    p = points.copy()
    p[:, i] = np.nan
    ok = np.isfinite(registration.rotation[:, 0, 0]) & np.all(np.isfinite(p[:, keep]), axis=(1, 2))
    rot = np.full_like(registration.rotation, np.nan)
    cen = np.full_like(registration.centre, np.nan)
    if ok.any():
        rot[ok], cen[ok] = partial_pose(p[ok], model, registration.rotation[ok], registration.centre[ok])
    reason = np.where(ok, "", "no pose of the other markers").astype(object)
    return replace(registration, rotation=rot, centre=cen, information=None, reason=reason), model


def _geometric_pose_variance(model, rotation, covariance) -> np.ndarray:
    """The six pose components' variance (6,) from markers ``model`` (k, 3) with independent noise of
    ``covariance`` (3, 3, world), turned by ``rotation`` (3, 3): the linearised registration of
    :func:`pose_noise`, ``diag(covariance) / k`` for the centroid and ``diag(H^-1 M H^-1)`` for the rotation
    vector."""
    d = (model - model.mean(0)) @ rotation.T
    D = skew(d)
    Hi = np.linalg.inv(np.einsum("mji,mjk->ik", D, D))
    M = np.einsum("mji,jl,mlk->ik", D, covariance, D)
    return np.r_[np.diag(covariance) / model.shape[0], np.diag(Hi @ M @ Hi)]


def left_out_noise_ratios(registration: PoseRegistration, model, points=None) -> np.ndarray:
    """Per marker left out (m, 6): how much larger each pose component's noise variance is when the pose is
    registered from the other markers than from all (the linearised registration at the record's mean rotation,
    the markers' noise covariance pooled from the rigidity residual of ``points``, isotropic without them);
    four or more markers.

    A smoothing spline's best smoothing parameter grows in proportion to the noise's variance (the penalty
    weighs the roughness against the noise), so the pose of the other markers is smoothed with the
    parameters scaled by these ratios to stand for the smoothing of the whole cluster.

    Examples
    --------
    Four markers at the corners of a square: leaving any one out leaves three, whose centroid is noisier
    by 4/3.

    >>> import numpy as np
    >>> model = np.array([[0.1, 0.1, 0], [-0.1, 0.1, 0], [-0.1, -0.1, 0], [0.1, -0.1, 0]])
    >>> reg = register_pose(np.repeat(model[None], 5, axis=0), model)
    >>> np.round(left_out_noise_ratios(reg, model)[0, :3], 4)
    array([1.3333, 1.3333, 1.3333])
    """
    x = np.asarray(model, float)
    m = x.shape[0]
    if m < 4:
        raise ValueError(f"model: the pose of the other markers needs four or more markers, got {m}")
    ok = np.isfinite(registration.rotation[:, 0, 0])
    R0 = Rotation.from_matrix(registration.rotation[ok]).mean().as_matrix()
    cov = np.eye(3) if points is None else _residual_covariance(registration, points)
    full = _geometric_pose_variance(x, R0, cov)
    return np.array([_geometric_pose_variance(np.delete(x, i, axis=0), R0, cov) / full for i in range(m)])


def _information_variance_ratio(left_out: PoseRegistration, full: PoseRegistration, fallback) -> np.ndarray:
    """The six pose components' mean variance ratio (6,) of two registrations with the markers' covariances
    (:func:`frame_variances`, over the frames both have a pose); ``fallback`` where none is finite."""
    a, b = frame_variances(left_out), frame_variances(full)
    both = np.all(np.isfinite(a) & np.isfinite(b) & (b > 0), axis=1)
    if not both.any():
        return fallback
    # the centroid's variance is about each registration's own centroid; its ratio is taken as such
    return np.mean(a[both], axis=0) / np.mean(b[both], axis=0)


def _pooled_residual_covariance(registration: PoseRegistration, points) -> np.ndarray | None:
    """The markers' noise covariance (3, 3) pooled from the rigidity residual over the frames with a pose,
    ``sum r r^T / sum (k - 2)`` (:func:`pose_noise`); None when no residual degree of freedom is left."""
    p = np.asarray(points, float)
    ok = np.isfinite(registration.rotation[:, 0, 0])
    vis = np.all(np.isfinite(p), axis=2) & ok[:, None]
    r = np.where(vis[..., None], p - registration.registered, 0.0)
    dof = np.sum(np.where(ok, np.maximum(vis.sum(1) - 2, 0), 0))
    return np.einsum("kmi,kmj->ij", r, r) / dof if dof > 0 else None


def _residual_covariance(registration: PoseRegistration, points) -> np.ndarray:
    """:func:`_pooled_residual_covariance`, or the identity when there is none to pool or it is singular."""
    cov = _pooled_residual_covariance(registration, points)
    return cov if cov is not None and np.all(np.isfinite(cov)) and np.linalg.det(cov) > 0 else np.eye(3)


def _cross_validation_inputs(t, points, model, base_lam, fewest: int, what: str):
    """The marker cross-validations' inputs as arrays, checked (``fewest`` markers at least), and the inner
    second differences they score (:func:`_inner_second_differences`)."""
    t = np.asarray(t, float)
    pts = np.asarray(points, float)
    x = np.asarray(model, float)
    m, n = x.shape[0], t.size
    if m < fewest or pts.shape != (n, m, 3):
        raise ValueError(f"points: {what} needs (n, m >= {fewest}, 3) markers matching t and the model, got "
                         f"{pts.shape} for {n} frames and {m} model markers")
    return t, pts, x, np.asarray(base_lam, float), _inner_second_differences(n)


def _inner_second_differences(n: int) -> np.ndarray:
    """Which of a record's ``n - 2`` second differences lie inside it: :data:`CROSS_VALIDATION_MARGIN` of the
    record is left out at each end, where a smoothing spline's end conditions, not the data, decide it."""
    edge = int(np.ceil(CROSS_VALIDATION_MARGIN * n))
    inner = np.zeros(n - 2, bool)
    inner[edge:n - 2 - edge] = True
    return inner


def marker_cross_validation(t, registration: PoseRegistration, points, model, base_lam,
                            decades=CROSS_VALIDATION_DECADES) -> tuple[np.ndarray, dict]:
    """The smoothing that predicts each left-out marker's acceleration best, and the criterion.

    Each marker in turn is left out, the pose is registered from the others
    and smoothed with the six smoothing parameters ``base_lam * 10^s`` (one
    common ``s`` per candidate), and the left-out marker's position is
    predicted from it. The criterion is the mean squared difference between
    the second differences (frame-to-frame acceleration) of the prediction
    and of the measured marker, over the frames inside the record
    (:data:`CROSS_VALIDATION_MARGIN` at each end). A marker's noise is not
    in the pose that predicts it, so the criterion is the prediction's
    acceleration error plus a constant (the marker's own noise, second
    differenced), whatever the noise's correlation over frames: only the
    markers' noises must be independent of each other. With three markers
    the other two leave the rotation about their line unseen; it is taken
    from the full registration, and only the left-out marker's movement in
    the cluster's plane (which that rotation does not reach) is compared.

    Parameters
    ----------
    t : (n,)
    registration : PoseRegistration
        Of all the markers (:func:`register_pose`).
    points : (n, m, 3)
        The measured markers, m >= 3.
    model : (m, 3)
    base_lam : (6,)
        The smoothing parameters scaled (e.g. those GCV chose).
    decades : sequence of float
        The candidate ``s``.

    Returns
    -------
    lam : (6,)
        ``base_lam * 10^s`` of the best candidate.
    info : dict
        ``cross_validation_decades`` (the best ``s``), ``cross_validation_scores`` (per candidate,
        m/s^2 rms), ``cross_validation_markers``.

    Examples
    --------
    Four markers of a body turning slowly, with noise correlated over frames: the choice
    smooths far more than the GCV parameters it scales.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from scipy.spatial.transform import Rotation
    >>> rng = np.random.default_rng(1)
    >>> model = np.array([[0.0, 0, 0], [0.2, 0, 0], [0.0, 0.15, 0.05], [0.1, 0.1, 0.1]])
    >>> t = np.arange(300) / 100.0
    >>> R = Rotation.from_rotvec(np.outer(0.4 * np.sin(2 * t), [0, 0, 1])).as_matrix()
    >>> e = lfilter([1.0], [1.0, -0.7], rng.normal(0, 3e-4, (300, 4, 3)), axis=0)
    >>> pts = np.einsum("kij,mj->kmi", R, model) + e
    >>> reg = register_pose(pts, model)
    >>> lam, info = marker_cross_validation(t, reg, pts, model, np.full(6, 1e-8))
    >>> bool(info["cross_validation_decades"] > 0)
    True
    """
    t, pts, x, base, inner = _cross_validation_inputs(t, points, model, base_lam, 3, "marker cross-validation")
    m, n = x.shape[0], t.size
    normal = None
    if m == 3:
        nrm = np.cross(x[1] - x[0], x[2] - x[0])
        normal = np.einsum("kij,j->ki", registration.rotation, nrm / np.linalg.norm(nrm))[1:-1]
    params = PoseParams(smoothing="gcv", harmonics="none", rotation_weights="equal", partial_frames=False)
    scores = np.zeros(len(decades))
    count = np.zeros(len(decades))
    for i in range(m):
        reg_i, model_i = _left_out_registration(registration, pts, x, i)
        measured = np.diff(pts[:, i], 2, axis=0)
        for j, s in enumerate(decades):
            tr = fit_pose_trajectory(t, reg_i, model_i, params, lam=base * 10.0 ** s, iterations=0)
            err = np.diff(tr.point(t, x[i]).position, 2, axis=0) - measured
            if normal is not None:
                err = err - np.sum(err * normal, axis=1, keepdims=True) * normal
            use = inner & np.all(np.isfinite(err), axis=1)
            scores[j] += np.sum(err[use] ** 2)
            count[j] += use.sum()
    if not np.all(count > 0):
        raise ValueError("points: no frame inside the record where a left-out marker and the others' pose are seen")
    dt = float(np.median(np.diff(t)))
    rms = np.sqrt(scores / count) / dt ** 2
    best = int(np.argmin(rms))
    return base * 10.0 ** decades[best], {"cross_validation_decades": float(decades[best]),
                                          "cross_validation_scores": [float(v) for v in rms],
                                          "cross_validation_markers": m}


def _observed_pose(trajectory: PoseTrajectory, t, aperture) -> np.ndarray:
    """(n, 6) the centroid and rotation vector as frames at ``t`` observe them: the smoothed pose itself, or
    its average over the frames' ``aperture``; NaN outside the trajectory's frames."""
    values = np.column_stack([trajectory.centre(t), trajectory.rotvec(t)])
    if aperture is not None:
        seen = np.all(np.isfinite(values), axis=1)
        values[seen] = np.stack([s.observed(t[seen]) for s in trajectory.centre_splines
                                 + trajectory.rotvec_splines], -1)
    return values


def marker_cross_validation_per_component(t, registration: PoseRegistration, points, model, base_lam,
                                          decades=CROSS_VALIDATION_DECADES, sweeps: int = 3, aperture=None,
                                          rule: str = "min", fundamental_hz: float | None = None
                                          ) -> tuple[np.ndarray, dict]:
    """Leaving each marker out in turn, as :func:`marker_cross_validation`, with one ``s`` per pose component.

    Each marker in turn is left out and the pose registered from the
    others (with the markers' covariances where the registration has them,
    :func:`_left_out_registration`); that pose is smoothed once per
    candidate ``s`` with the parameters ``base_lam * 10^s`` times
    :func:`left_out_noise_ratios` (the other markers' pose is noisier than
    the whole cluster's, and a smoothing parameter's best value grows in
    proportion to the noise's variance: so the candidate stands for the
    whole cluster's smoothing). The criterion is the mean squared
    difference between the left-out markers' predicted and measured second
    differences (frame-to-frame acceleration) inside the record
    (:data:`CROSS_VALIDATION_MARGIN`), as :func:`marker_cross_validation`'s;
    it holds under noise correlated over frames as long as the markers'
    noises are independent of each other. The six components' ``s`` are
    chosen in turn, each at the candidate that predicts best with the
    others held (coordinate descent from the best common ``s``, at most
    ``sweeps`` rounds): a component whose noise is small against its motion
    keeps a lighter smoothing than a noisy one. The fits are made once
    per candidate; the descent only recombines them.

    Parameters
    ----------
    t : (n,)
    registration : PoseRegistration
        Of all the markers (:func:`register_pose`).
    points : (n, m, 3)
        The measured markers, m >= 4.
    model : (m, 3)
    base_lam : (6,)
        The smoothing parameters scaled (``cx, cy, cz, phix, phiy, phiz``; e.g. white-noise GCV's).
    decades : sequence of float
        The candidate ``s``.
    sweeps : int
        The most rounds of the coordinate descent (a bound on its cost; it stops earlier when a round
        changes no component's ``s``, and every round only recombines the fits already made).
    aperture : Aperture, optional
        The frames' temporal aperture (:mod:`horsemocap.aperture`): the left-out poses are smoothed through
        it, and a left-out marker is predicted as its frames observe it (the pose averaged over the aperture).
    rule : str
        ``"min"`` (default): the candidates of the lowest score. ``"one_se"``: from there, each component in
        turn takes the most smoothing whose score stays within one standard error of the lowest
        (:func:`left_out_score_difference`; the one-standard-error rule, which prefers the smoother of
        candidates the data cannot tell apart).
    fundamental_hz : float, optional
        The stride frequency (Hz): each candidate is then a partial spline, the stride's harmonics
        unpenalised (kept as white-noise GCV with harmonics keeps them, ``harmonics="auto"``) plus the
        smoothing spline of ``base_lam * 10^s``. None (default): plain smoothing splines.

    Returns
    -------
    lam : (6,)
        ``base_lam * 10^s`` per component.
    info : dict
        ``cross_validation_decades`` (the common ``s``), ``cross_validation_scores`` (per common candidate,
        m/s^2 rms), ``cross_validation_component_decades`` (6,, the chosen ``s``),
        ``cross_validation_minimum_decades`` (6,, those of the lowest score: the same with ``"min"``),
        ``cross_validation_score`` (at the chosen, m/s^2 rms), ``cross_validation_markers``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from scipy.spatial.transform import Rotation
    >>> rng = np.random.default_rng(1)
    >>> model = np.array([[0.0, 0, 0], [0.2, 0, 0], [0.0, 0.15, 0.05], [0.1, 0.1, 0.1]])
    >>> t = np.arange(300) / 100.0
    >>> R = Rotation.from_rotvec(np.outer(0.4 * np.sin(2 * t), [0, 0, 1])).as_matrix()
    >>> e = lfilter([1.0], [1.0, -0.7], rng.normal(0, 3e-4, (300, 4, 3)), axis=0)
    >>> pts = np.einsum("kij,mj->kmi", R, model) + e
    >>> lam, info = marker_cross_validation_per_component(t, register_pose(pts, model), pts, model, np.full(6, 1e-8))
    >>> len(info["cross_validation_component_decades"]), bool(info["cross_validation_score"]
    ...                                                        <= min(info["cross_validation_scores"]))
    (6, True)
    """
    return _left_out_choice(t, registration, points, model, base_lam, decades, sweeps, aperture, rule,
                            fundamental_hz)[:2]


def _left_out_choice(t, registration, points, model, base_lam, decades, sweeps: int, aperture, rule: str,
                     fundamental_hz) -> tuple[np.ndarray, dict, "_LeftOutPredictions", list]:
    """:func:`marker_cross_validation_per_component`'s ``(lam, info)`` and the left-out predictions it chose
    among with the chosen candidate per component (what :func:`left_out_stacking_weights` blends)."""
    t, pts, x, base, inner = _cross_validation_inputs(t, points, model, base_lam, 4,
                                                      "per-component marker cross-validation")
    if rule not in LEFT_OUT_RULES:
        raise ValueError(f"rule: expected one of {', '.join(LEFT_OUT_RULES)}, got {rule!r}")
    decades = np.asarray(decades, float)
    m = x.shape[0]
    predictions = _left_out_predictions(t, registration, pts, x, base, decades, inner, aperture, fundamental_hz)
    dt = float(np.median(np.diff(t)))
    index, common = _left_out_descent(predictions.score, decades.size, sweeps)
    minimum = list(index)
    if rule == "one_se":
        index = _one_standard_error_smoothing(index, predictions.losses, decades.size)
    chosen = decades[index]
    info = {"cross_validation_decades": float(decades[int(np.argmin(common))]),
            "cross_validation_scores": [float(v) for v in np.sqrt(common) / dt ** 2],
            "cross_validation_component_decades": [float(v) for v in chosen],
            "cross_validation_minimum_decades": [float(v) for v in decades[minimum]],
            "cross_validation_score": float(np.sqrt(predictions.score(index)) / dt ** 2),
            "cross_validation_rule": rule,
            "cross_validation_markers": m}
    return base * 10.0 ** chosen, info, predictions, list(index)


@dataclass(frozen=True)
class _LeftOutPredictions:
    """Each left-out marker's predicted pose per candidate and what it is scored against
    (:func:`marker_cross_validation_per_component`): ``values[i]`` (candidates, n, 6) the pose the other markers
    give, ``turned[i]`` (n, 3) marker ``i``'s lever turned by the reference rotation, ``measured[i]`` (n - 2, 3)
    its measured second differences, ``inner`` the scored second differences."""

    values: list
    turned: list
    measured: list
    inner: np.ndarray

    def chosen(self, index) -> list:
        """Per marker, the others' pose (n, 6) at the candidates ``index`` (one per pose component)."""
        return [v_all[index, :, np.arange(6)].T for v_all in self.values]

    def errors(self, index, values=None) -> list:
        """Per marker, the left-out prediction's second-difference errors at the candidates ``index`` (one per
        pose component; or of the poses ``values``, one (n, 6) per marker) and the inner frames where it is
        scored."""
        out = []
        for v, turned, measured in zip(self.chosen(index) if values is None else values, self.turned,
                                       self.measured):
            err = np.diff(_left_out_position(v, turned), 2, axis=0) - measured
            out.append((err, self.inner & np.all(np.isfinite(err), axis=1)))
        if not any(use.any() for _, use in out):
            raise ValueError("points: no frame inside the record where a left-out marker and the others' pose are "
                             "seen")
        return out

    def losses(self, index) -> tuple[np.ndarray, np.ndarray]:
        """Per inner second difference the left-out markers' summed squared error (NaN where none is seen) and
        how many markers it sums."""
        total, frames = np.zeros(self.inner.size), np.zeros(self.inner.size, int)
        for err, use in self.errors(index):
            total[use] += np.sum(err[use] ** 2, axis=1)
            frames[use] += 1
        return np.where(frames > 0, total, np.nan), frames

    def score(self, index, values=None) -> float:
        """The mean squared left-out error over the scored (marker, frame) pairs, summed marker by marker (at the
        candidates ``index``, or of the poses ``values`` as :meth:`errors`)."""
        total, frames = 0.0, 0
        for err, use in self.errors(index, values):
            total, frames = total + float(np.sum(err[use] ** 2)), frames + int(use.sum())
        return total / frames


def _left_out_position(values, turned) -> np.ndarray:
    """(n, 3) a left-out marker's position ``c + Exp(phi) lever`` from the others' pose ``values`` (n, 6) and its
    lever turned by the reference rotation ``turned`` (n, 3); NaN where either is not seen."""
    seen = np.all(np.isfinite(values), axis=1) & np.all(np.isfinite(turned), axis=1)
    position = np.full((values.shape[0], 3), np.nan)
    if seen.any():
        position[seen] = values[seen, :3] + Rotation.from_rotvec(values[seen, 3:]).apply(turned[seen])
    return position


def stacking_weights(residual, directions) -> np.ndarray:
    """The weights ``w`` in ``[0, 1]^k`` that minimise ``|residual + directions @ w|^2``, exactly.

    Stacking (Wolpert 1992; Breiman 1996, "Stacked regressions"): two
    predictors of the same data blended, ``w * second + (1 - w) * first``,
    with ``w`` chosen to minimise the left-out error of the blend. With the
    first predictor's left-out errors ``residual`` (p,) and, per blended
    part, the change of those errors from the first predictor to the second
    ``directions`` (p, k), the loss is a quadratic in ``w``:
    ``w^T A w + 2 b^T w + const`` with ``A = D^T D``, ``b = D^T r``. Its
    minimum over the box lies on one face: each weight at 0, at 1 or free,
    the free ones solving the normal equations with the others held. Every
    one of the ``3^k`` faces is solved (a least-squares solve where the free
    part is singular) and the feasible solution of the lowest loss kept: a
    closed form, for the few weights a pose has (k <= 8).

    Parameters
    ----------
    residual : (p,)
        The first predictor's errors.
    directions : (p, k)
        Per weight, the second predictor's errors less the first's.

    Returns
    -------
    (k,) weights in [0, 1]. A weight whose direction is zero (the two predictors agree there) is 0.

    Raises
    ------
    ValueError
        Shapes that do not match, values not finite, or more than 8 weights.

    Examples
    --------
    The second predictor's errors a third of the first's, opposite in sign: a quarter of the first and three
    quarters of the second cancel them; a second predictor that only adds error gets no weight.

    >>> import numpy as np
    >>> r = np.array([3.0, -3.0, 6.0])
    >>> stacking_weights(r, (-r / 3 - r)[:, None])
    array([0.75])
    >>> stacking_weights(r, (2 * r)[:, None])
    array([0.])
    """
    r = np.asarray(residual, float)
    D = np.asarray(directions, float)
    if r.ndim != 1 or D.ndim != 2 or D.shape[0] != r.size:
        raise ValueError(f"residual, directions: expected (p,) and (p, k), got {r.shape} and {D.shape}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(D))):
        raise ValueError("residual, directions: expected finite values")
    k = D.shape[1]
    if k > 8:
        raise ValueError(f"directions: the exact box minimum enumerates 3^k faces; expected k <= 8, got {k}")
    A, b = D.T @ D, D.T @ r
    best, best_loss = np.zeros(k), 0.0
    for face in itertools.product((0.0, 1.0, None), repeat=k):
        w = np.array([0.0 if f is None else f for f in face])
        free = np.array([f is None for f in face])
        if free.any():
            rhs = -(b[free] + A[np.ix_(free, ~free)] @ w[~free])
            w[free] = np.linalg.lstsq(A[np.ix_(free, free)], rhs, rcond=None)[0]
            if np.any(w[free] < 0.0) or np.any(w[free] > 1.0):
                continue
        loss = float(w @ A @ w + 2.0 * b @ w)
        if loss < best_loss - 1e-12 * max(1.0, abs(best_loss)):
            best, best_loss = w, loss
    return best


def left_out_stacking_weights(first: "_LeftOutPredictions", first_index, second: "_LeftOutPredictions",
                              second_index, common: bool = False) -> tuple[np.ndarray, float]:
    """Per pose component, the weight of the ``second`` route's left-out predictions (at its chosen candidates
    ``second_index``) blended with the ``first``'s that minimises the left-out loss, and that loss (mean
    squared second-difference error, as :meth:`_LeftOutPredictions.score`); ``common``: one weight for the
    whole pose (returned six times).

    The left-out marker's position is linear in the centroid's weights and, the two routes' rotation vectors
    differing by small angles, linear to first order in the rotation's: the directions of
    :func:`stacking_weights` are each component's (or the whole pose's) change from the first route's pose to
    the second's; the loss returned is the blend's own (not linearised).

    Examples
    --------
    One left-out marker at the centroid; one route predicts its path with a bias, the other with the opposite
    bias: half of each is the path itself.

    >>> import numpy as np
    >>> n = 40
    >>> t = np.arange(n) / 50.0
    >>> truth, bias = np.zeros((n, 6)), np.zeros((n, 6))
    >>> truth[:, 0], bias[:, 0] = np.sin(3 * t), 0.01 * t ** 3
    >>> def route(values):
    ...     return _LeftOutPredictions([values[None]], [np.zeros((n, 3))], [np.diff(truth[:, :3], 2, axis=0)],
    ...                                np.ones(n - 2, bool))
    >>> w, loss = left_out_stacking_weights(route(truth + bias), [0] * 6, route(truth - bias), [0] * 6,
    ...                                     common=True)
    >>> float(np.round(w[0], 12)), bool(loss < 1e-20)
    (0.5, True)
    """
    residual, directions = [], []
    firsts, seconds = first.chosen(first_index), second.chosen(second_index)
    switched = [np.arange(6)] if common else [[c] for c in range(6)]
    for v1, v2, turned, measured in zip(firsts, seconds, first.turned, first.measured):
        base = np.diff(_left_out_position(v1, turned), 2, axis=0) - measured
        cols = []
        for components in switched:
            v = v1.copy()
            v[:, components] = v2[:, components]
            cols.append(np.diff(_left_out_position(v, turned), 2, axis=0) - measured - base)
        cols = np.stack(cols, -1)
        use = first.inner & np.all(np.isfinite(base), axis=1) & np.all(np.isfinite(cols), axis=(1, 2))
        residual.append(base[use].ravel())
        directions.append(cols[use].reshape(-1, len(switched)))
    weights = np.broadcast_to(stacking_weights(np.concatenate(residual), np.concatenate(directions)), 6).copy()
    return weights, _stacked_score(first, firsts, seconds, weights)


def _stacked_score(predictions: "_LeftOutPredictions", firsts, seconds, weights) -> float:
    """The left-out loss of the poses ``(1 - w) first + w second`` per component (one (n, 6) per marker each)."""
    return predictions.score(None, [v1 + weights * (v2 - v1) for v1, v2 in zip(firsts, seconds)])


def _left_out_predictions(t, registration, pts, x, base, decades, inner, aperture, fundamental_hz
                          ) -> _LeftOutPredictions:
    """Each marker left out in turn: the others' pose smoothed at every candidate ``base * 10^s`` (scaled by the
    left-out registration's noise ratio), observed through the ``aperture``."""
    n = t.size
    params = PoseParams(smoothing="gcv", harmonics="none" if fundamental_hz is None else "auto",
                        rotation_weights="equal", partial_frames=False)
    ratios = left_out_noise_ratios(registration, x, pts)
    values, turned, measured = [], [], []
    for i in range(x.shape[0]):
        reg_i, model_i = _left_out_registration(registration, pts, x, i)
        if reg_i.information is not None and registration.information is not None:
            ratios[i] = _information_variance_ratio(reg_i, registration, ratios[i])
        measured.append(np.diff(pts[:, i], 2, axis=0))
        fits = [fit_pose_trajectory(t, reg_i, model_i, params, lam=base * ratios[i] * 10.0 ** s, iterations=0,
                                    aperture=aperture, fundamental_hz=fundamental_hz) for s in decades]
        # per candidate the six components' values (n, 6), and the left-out marker's lever turned by the
        # reference rotation (the same for every candidate): its position is c + Exp(phi) (R_ref lever)
        values.append(np.stack([_observed_pose(f, t, aperture) for f in fits]))
        seen = np.all(np.isfinite(values[-1][0]), axis=1)
        lever = np.full((n, 3), np.nan)
        if seen.any():
            lever[seen] = fits[0]._reference().rotation(t[seen]).apply(x[i] - fits[0].model_centroid)
        turned.append(lever)
    return _LeftOutPredictions(values, turned, measured, np.asarray(inner, bool))


def _left_out_descent(score, size: int, sweeps: int) -> tuple[list, np.ndarray]:
    """The candidate per pose component of the lowest ``score``: the best common candidate, then coordinate
    descent over the components (at most ``sweeps`` rounds); also the common candidates' scores."""
    common = np.array([score([j] * 6) for j in range(size)])
    index = [int(np.argmin(common))] * 6
    best = common[index[0]]
    for _ in range(sweeps):
        before = list(index)
        for c in range(6):
            trial = [score(index[:c] + [j] + index[c + 1:]) for j in range(size)]
            if min(trial) < best:
                index[c], best = int(np.argmin(trial)), min(trial)
        if index == before:
            break
    return index, common


#: How many contiguous blocks of the record's frames give the standard error of a difference of left-out
#: scores (:func:`left_out_score_difference`): the squared errors are correlated over neighbouring frames, the
#: blocks' means far less. Ten blocks give the standard error nine degrees of freedom; a block must stay longer
#: than the noise's correlation (a few frames), so a record needs some tens of scored frames (fewer are refused).
LEFT_OUT_SCORE_BLOCKS = 10


def left_out_score_difference(losses, reference) -> tuple[float, float]:
    """The mean difference of two candidates' left-out losses per scored frame and its standard error.

    ``losses`` and ``reference`` (n,) hold, per frame, the left-out markers' summed squared prediction error of
    two candidate smoothings (NaN where not scored). The frames' differences are correlated over neighbouring
    frames (the noise is), so the standard error is that of the means of :data:`LEFT_OUT_SCORE_BLOCKS`
    contiguous blocks of frames (batch means), not of the frames themselves.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> a = rng.normal(1.0, 0.1, 400) ** 2
    >>> diff, se = left_out_score_difference(a + 0.5, a)
    >>> round(diff, 3), round(se, 3)
    (0.5, 0.0)
    """
    d = np.asarray(losses, float) - np.asarray(reference, float)
    d = d[np.isfinite(d)]
    if d.size < 2 * LEFT_OUT_SCORE_BLOCKS:
        raise ValueError(f"the one-standard-error rule: the standard error of a left-out score difference needs "
                         f"at least {2 * LEFT_OUT_SCORE_BLOCKS} scored frames, got {d.size}")
    means = np.array([b.mean() for b in np.array_split(d, LEFT_OUT_SCORE_BLOCKS)])
    return float(d.mean()), float(means.std(ddof=1) / np.sqrt(means.size))


def _one_standard_error_smoothing(index, losses, size: int) -> list:
    """From the left-out minimum ``index`` (six candidate indices), each component in turn moved to the most
    smoothing (the highest candidate index below ``size``) whose left-out losses stay within one standard error
    of the minimum's (:func:`left_out_score_difference`); ``losses(index)`` gives the per-frame losses."""
    minimum = losses(index)[0]
    chosen = list(index)
    for c in range(6):
        for j in range(size - 1, chosen[c], -1):
            trial = chosen[:c] + [j] + chosen[c + 1:]
            diff, se = left_out_score_difference(losses(trial)[0], minimum)
            if diff <= se:
                chosen = trial
                break
    return chosen


def choose_smoothing(fundamental_hz, events, order: int = 5, lam_given: bool = False,
                     noise_correlation: float | None = None, criterion: str = "loo") -> tuple[str, str]:
    """The smoothing ``"auto"`` of :func:`fit_pose_trajectory` runs, and why.

    A periodic record (``fundamental_hz`` found or given) keeps ``"gcv"`` with the stride harmonics;
    a record without a fundamental, or with known change points (``events``, which are fitted without
    harmonics), gets ``"adaptive"`` (GCV, then a penalty weighted by the local roughness), which
    follows an acceleration that is calm in one part of a record and rings in another better than one
    penalty can (``benchmarks/README.md`` has the comparison). A cubic spline (``order`` 3) has no
    adaptive form and keeps ``"gcv"``; so do given smoothing parameters (``lam_given``: nothing is
    chosen from the data, and ``lam`` keeps the meaning of the plain penalty).

    Parameters
    ----------
    fundamental_hz : float or None
        The record's stride frequency (:func:`horsemocap.splines.estimate_fundamental`), None if none.
    events : sequence of float or None
        Known change points.
    order : int
        The spline's order.
    lam_given : bool
        All six smoothing parameters are given.
    noise_correlation : float, optional
        The lag-1 autocorrelation of the markers' rigidity residual
        (:func:`rigidity_residual_correlation`). At or above
        :data:`NOISE_CORRELATION_THRESHOLD` (a real system's filtering, marker
        wobble, skin), without events, the choice is ``"gcv_ar1"``: the
        smoothing chosen under that AR(1) error correlation
        (``noise_correlation`` of :func:`horsemocap.splines.smoothing_spline`;
        the criterion is ``criterion``),
        without harmonics, since plain GCV and the adaptive penalty both take
        slow noise for motion.
        Below it the reason records the value.
    criterion : str
        The criterion under correlated noise
        (``correlated_noise_criterion`` of
        :class:`horsemocap.params.PoseParams`): ``"loo"`` (default: leaving
        each marker out in turn with four or more markers, the
        correlated-error GCV with three), ``"gcv"``, ``"reml"`` or
        ``"risk"``. Only ``"reml"`` changes the reason here; the others are
        told apart when the splines are fitted (:func:`fit_pose_trajectory`).

    Returns
    -------
    method : str
        ``"gcv"``, ``"adaptive"`` or ``"gcv_ar1"``.
    reason : str

    Examples
    --------
    >>> choose_smoothing(1.4, None)
    ('gcv', 'periodic record: fundamental 1.4 Hz')
    >>> choose_smoothing(None, None)[0]
    'adaptive'
    >>> choose_smoothing(None, None, noise_correlation=0.62)
    ('gcv_ar1', 'gcv with AR(1) 0.62 noise correlation from the rigidity residual (correlated-error GCV, no harmonics)')
    >>> choose_smoothing(None, None, noise_correlation=0.62, criterion="reml")[1][:4]
    'REML'
    """
    rho = float("nan") if noise_correlation is None else float(noise_correlation)
    method, reason = _choose_white_noise_smoothing(fundamental_hz, events, order, lam_given)
    if lam_given or order != 5:
        return method, reason
    if not np.isfinite(rho):
        return method, reason + ("" if noise_correlation is None else
                                 "; no AR(1) noise correlation measurable from the rigidity residual, or none significant for "
                                 "the record's length: noise taken as white")
    if rho >= NOISE_CORRELATION_THRESHOLD and not (events is not None and len(events)):
        if criterion == "reml":
            return "gcv_ar1", (f"REML with AR(1) {min(rho, 0.99):.2f} noise correlation from the rigidity residual "
                               "(correlated-error smoothing, no harmonics)")
        return "gcv_ar1", (f"gcv with AR(1) {min(rho, 0.99):.2f} noise correlation from the rigidity residual "
                           "(correlated-error GCV, no harmonics)")
    return method, reason + (f"; AR(1) noise correlation {rho:.2f} from the rigidity residual"
                             + (" (events: kept)" if rho >= NOISE_CORRELATION_THRESHOLD else
                                f", below {NOISE_CORRELATION_THRESHOLD:g}: noise taken as white"))


def _choose_white_noise_smoothing(fundamental_hz, events, order: int, lam_given: bool) -> tuple[str, str]:
    """:func:`choose_smoothing` for white noise."""
    if order != 5:
        return "gcv", f"order {order}: the adaptive smoothing is quintic only"
    if lam_given:
        return "gcv", "smoothing parameters given: nothing chosen from the data"
    if events is not None and len(events):
        found = "" if fundamental_hz is None else f"; fundamental {float(fundamental_hz):.4g} Hz found, not used"
        return "adaptive", f"{len(events)} known change point(s), fitted without harmonics{found}"
    if fundamental_hz is not None:
        return "gcv", f"periodic record: fundamental {float(fundamental_hz):.4g} Hz"
    return "adaptive", "no fundamental found: a non-periodic record"


def frame_variances(registration: PoseRegistration) -> np.ndarray:
    """Each frame's predicted variance of the six pose components (n, 6): ``cx, cy, cz`` (m^2), ``phix,
    phiy, phiz`` (rad^2), the diagonal of the inverse of the pose's information matrix
    (:func:`register_pose` with ``covariance``; the linearised registration, as :func:`pose_noise`
    uses it). A frame without its own information (no pose, or a partial pose of two markers) gets
    the largest variance of the record (the least weight); all NaN without information matrices.

    Examples
    --------
    Exact markers, each with a covariance of (1 mm)^2 I: the centroid's variance is (1 mm)^2 / 3.

    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> cov = np.broadcast_to(1e-6 * np.eye(3), (5, 3, 3, 3))
    >>> reg = register_pose(np.repeat(model[None], 5, axis=0), model, covariance=cov)
    >>> bool(np.allclose(frame_variances(reg)[:, :3], 1e-6 / 3))
    True
    """
    reg = registration
    n = reg.rotation.shape[0]
    if reg.information is None:
        return np.full((n, 6), np.nan)
    good = np.isfinite(reg.rotation[:, 0, 0]) & np.all(np.isfinite(reg.information), axis=(1, 2))
    var = np.full((n, 6), np.nan)
    if good.any():
        var[good] = np.diagonal(np.linalg.inv(reg.information[good]), axis1=1, axis2=2)
        var[~good] = np.max(var[good], axis=0)
    return var


def _rotation_component(t, y, variance, *, harmonic_noise=None, compare: bool = True, **kwargs):
    """One rotation component's spline: with ``variance`` (predicted per frame) the robust weighted fit
    and the equal-weight fit, the one whose noise model explains its residuals better kept
    (:func:`horsemocap.splines.residual_log_likelihood`); without, the equal-weight fit. The weighted
    fit's harmonic test uses the noise of a unit-weight frame, calibrated by the fit's standardised residuals
    (``harmonic_noise="calibrated"`` of :func:`horsemocap.splines.robust_weighted_spline`, which also lifts the
    plain spline's cutoff), when ``harmonic_noise`` is given. ``compare`` False: with ``variance`` the
    weighted fit only (the weighting settled elsewhere)."""
    usable = variance is not None and np.all(np.isfinite(variance) & (variance > 0))
    if not usable or compare:
        equal = smoothing_spline(t, y, harmonic_noise=harmonic_noise, **kwargs)
    if not usable:
        return equal
    weighted = robust_weighted_spline(t, y, variance, harmonic_noise=None if harmonic_noise is None else "calibrated",
                                      **kwargs)
    if not compare:
        return weighted
    lw = residual_log_likelihood(weighted, t, y, variance)
    le = residual_log_likelihood(equal, t, y)
    best = weighted if lw > le else equal
    best.info.update(log_likelihood_weighted=lw, log_likelihood_equal=le,
                     weights=best.info.get("weights", "equal"))
    return best


def _pose_events(events, smoothing: str, order: int, f0):
    """The change points :func:`fit_pose_trajectory` fits (``events`` checked), or None."""
    if events is None or len(events) == 0:
        return None
    if order != 5 or smoothing not in ("gcv", "adaptive") or (smoothing == "gcv" and f0 is not None):
        raise ChangePointError("events: change points need smoothing 'gcv' (with harmonics='none') or 'adaptive', "
                         f"order 5; got smoothing={smoothing!r}, order={order}"
                         + (", harmonics fitted" if f0 is not None else ""))
    return sorted(float(e) for e in events)


#: The marker-geometry warning's threshold: the predicted rotation noise of one frame's pose (deg, the RMS over
#: the frames of its worst-observed component, :func:`rotation_noise_deg`) above which
#: :func:`conditioning_warnings` warns of a thin marker triangle.
ROTATION_NOISE_LIMIT_DEG = 1.0


def frame_rotation_std(registration: PoseRegistration) -> np.ndarray:
    """Each frame's predicted standard deviation of the rotation vector's components (n, 3), rad.

    The linearised registration (as :func:`pose_noise`): a small rotation
    ``dphi`` moves a marker at ``d`` from the visible markers' centroid by
    ``dphi x d``, so the rotation's information is ``sum_m [d_m]x^T
    Sigma_m^-1 [d_m]x``. With the markers' covariances (``registration``
    made with ``covariance``) it is the registration's own information
    matrix; without, ``Sigma_m = noise_m^2 I`` with the registration's
    isotropic noise estimate. Either way a rotation about the long direction
    of a thin triangle (height ``h``) gets a standard deviation of about
    ``noise / h``. NaN where a frame has no pose of three or more markers.

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.5, 0.03, 0]])     # 30 mm high
    >>> cov = np.broadcast_to(1e-6 * np.eye(3), (4, 3, 3, 3))             # 1 mm per marker
    >>> reg = register_pose(np.repeat(model[None], 4, axis=0), model, covariance=cov)
    >>> np.round(np.degrees(frame_rotation_std(reg)[0]), 2).tolist()      # about x: ~ 1 mm / 30 mm
    [2.34, 0.08, 0.08]
    """
    reg = registration
    n = reg.rotation.shape[0]
    full = np.isfinite(reg.rotation[:, 0, 0]) & (reg.n_markers >= 3)
    if reg.information is not None:
        good = full & np.all(np.isfinite(reg.information), axis=(1, 2))
        var = np.full((n, 6), np.nan)
        if good.any():
            var[good] = np.diagonal(np.linalg.inv(reg.information[good]), axis1=1, axis2=2)
        return np.sqrt(var[:, 3:])
    out = np.full((n, 3), np.nan)
    if not (full.any() and np.isfinite(reg.noise_m) and reg.noise_m > 0):
        return out
    vis = np.isfinite(reg.residual[full])
    pts = reg.registered[full]
    centroid = np.sum(np.where(vis[..., None], pts, 0.0), axis=1) / vis.sum(1)[:, None]
    d = np.where(vis[..., None], pts - centroid[:, None], 0.0)
    # [d]x^T [d]x = |d|^2 I - d d^T, summed over the visible markers
    H = np.einsum("km,ij->kij", np.sum(d * d, axis=2), np.eye(3)) - np.einsum("kmi,kmj->kij", d, d)
    ok = np.linalg.cond(H) < 1e12
    idx = np.flatnonzero(full)[ok]
    out[idx] = reg.noise_m * np.sqrt(np.diagonal(np.linalg.inv(H[ok]), axis1=1, axis2=2))
    return out


def rotation_noise_deg(registration: PoseRegistration) -> float:
    """The figure the thin-triangle warning judges: predicted rotation noise of one frame's pose (deg).

    Per frame the standard deviation of each rotation component
    (:func:`frame_rotation_std`); over the frames with a pose the RMS of
    each component, and of the three the largest (the rotation the
    markers observe worst: about the long direction of a thin triangle).
    NaN without a frame of three markers or a noise estimate.

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.5, 0.03, 0]])
    >>> cov = np.broadcast_to(1e-6 * np.eye(3), (4, 3, 3, 3))
    >>> round(rotation_noise_deg(register_pose(np.repeat(model[None], 4, axis=0), model, covariance=cov)), 2)
    2.34

    The same figure from the isotropic noise the residuals give, when the covariances say that noise:

    >>> rng = np.random.default_rng(1)
    >>> noisy = model + rng.normal(0, 1e-3, (200, 3, 3))
    >>> plain = register_pose(noisy, model)
    >>> cov = np.broadcast_to(plain.noise_m ** 2 * np.eye(3), (200, 3, 3, 3))
    >>> a, b = rotation_noise_deg(plain), rotation_noise_deg(register_pose(noisy, model, covariance=cov))
    >>> bool(abs(a - b) < 0.01 * a)
    True
    """
    std = frame_rotation_std(registration)
    seen = np.all(np.isfinite(std), axis=1)
    if not seen.any():
        return float("nan")
    return float(np.degrees(np.max(np.sqrt(np.mean(std[seen] ** 2, axis=0)))))


def conditioning_warnings(registration: PoseRegistration, lever_m: float | None = None,
                          rotation_noise_limit_deg: float = ROTATION_NOISE_LIMIT_DEG) -> list[str]:
    """Messages when the marker geometry makes the result unreliable.

    One rule judges the marker triangle, wherever the pose comes from (the
    pipeline's registration with the markers' triangulation covariances, or
    a trajectory file's with their isotropic noise): the predicted rotation
    noise of one frame's pose, :func:`rotation_noise_deg`, above
    ``rotation_noise_limit_deg`` (:data:`ROTATION_NOISE_LIMIT_DEG`). The
    triangle's height alone does not decide: a rotation about the long
    direction of a triangle of height ``h`` is observed through markers
    ``h`` apart, so its noise is about the markers' noise over ``h``; a thin
    triangle of precise markers can be better than a wide one of noisy
    markers. The message gives the smallest height, the noise, and, with
    ``lever_m`` (the saddle's distance from the markers' centroid), how far
    that noise moves a point ``lever_m`` away in one frame (before smoothing):
    the angular results and the paths of far points carry it. Frames left
    without a pose give a message of their own.

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> conditioning_warnings(register_pose(np.repeat(model[None], 5, axis=0), model))
    []
    """
    return conditioning_messages(conditioning_figures(registration), lever_m, rotation_noise_limit_deg)


@dataclass(frozen=True)
class ConditioningFigures:
    """What :func:`conditioning_messages` judges: the smallest triangle height (m, NaN: no frame with a
    pose), the predicted rotation noise (deg, :func:`rotation_noise_deg`), the marker noise (m), whether
    that came from triangulation covariances, the frames, those without a pose and the first reason."""

    smallest_height_m: float
    rotation_noise_deg: float
    noise_m: float
    from_covariances: bool
    frames: int
    frames_without_pose: int
    first_reason: str


def conditioning_figures(registration: PoseRegistration) -> ConditioningFigures:
    """The figures of :func:`conditioning_warnings` of a registration held whole.

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> conditioning_figures(register_pose(np.repeat(model[None], 5, axis=0), model)).smallest_height_m
    0.3
    """
    reg = registration
    h = reg.height[np.isfinite(reg.rotation[:, 0, 0]) & (reg.n_markers >= 3)]
    bad = reg.reason[reg.reason != ""]
    return ConditioningFigures(float(np.min(h)) if h.size else float("nan"), float(rotation_noise_deg(reg)),
                               float(reg.noise_m), reg.information is not None, int(reg.reason.size),
                               int(bad.size), str(min(bad.tolist())) if bad.size else "")


def conditioning_messages(figures: ConditioningFigures, lever_m: float | None = None,
                          rotation_noise_limit_deg: float = ROTATION_NOISE_LIMIT_DEG) -> list[str]:
    """The messages of :func:`conditioning_warnings` from its figures (however they were taken).

    Examples
    --------
    >>> f = ConditioningFigures(0.004, 3.0, 0.001, False, 100, 2, "fewer than 3 markers")
    >>> for message in conditioning_messages(f, lever_m=0.5):
    ...     print(message[:60])
    thin marker triangle: smallest height 4 mm; a marker noise o
    2 of 100 frames have no pose (fewer than 3 markers ...)
    """
    f = figures
    out = []
    rot_noise = f.rotation_noise_deg
    if np.isfinite(f.smallest_height_m) and np.isfinite(rot_noise) and rot_noise > rotation_noise_limit_deg:
        basis = ("the markers' triangulation covariances give" if f.from_covariances
                 else f"a marker noise of {1000 * f.noise_m:.2f} mm gives")
        extra = "" if lever_m is None else (f"; a point {lever_m:.2f} m away moves by about "
                                            f"{1000 * lever_m * np.radians(rot_noise):.1f} mm per frame")
        out.append(f"thin marker triangle: smallest height {1000 * f.smallest_height_m:.0f} mm; {basis} about "
                   f"{rot_noise:.1f} deg of rotation noise per frame (above {rotation_noise_limit_deg:g} deg)"
                   f"{extra}; the smoothing removes part of it, but angular results and far points are unreliable")
    if f.frames_without_pose:
        out.append(f"{f.frames_without_pose} of {f.frames} frames have no pose ({f.first_reason} ...)")
    return out


# --------------------------------------------------------------------------
# body axes from the static shot, and the saddle's angles
# --------------------------------------------------------------------------
def static_body_axes(static_points, down=(0.0, 1.0, 0.0), forward=(1.0, 0.0, 0.0)) -> np.ndarray:
    """Body axes of the horse's back from the static shot (the default pose).

    As seed 004 takes the body planes from a default pose (the frontal plane
    the best fit through the joints, the transverse plane the one whose normal
    is closest to the global vertical, the sagittal plane orthogonal to both),
    here the horse stands still in the static shot: the body's vertical is
    the motion frame's ``down`` (gravity, y); its longitudinal axis is the
    principal direction of the static-shot markers (they lie along the back)
    made horizontal and turned to point along ``forward`` (x-motion, the
    direction of travel); the lateral axis completes a right-handed frame.

    Parameters
    ----------
    static_points : (k, 3)
        Static-shot markers (and the saddle marker) in the motion frame.

    Returns
    -------
    (3, 3)
        Columns: longitudinal, vertical (down), lateral axis in the motion frame.

    Examples
    --------
    Markers along x, the motion frame's direction of travel: the body's axes are the motion frame's.

    >>> import numpy as np
    >>> bool(np.allclose(static_body_axes([[-1.0, 0, 0], [1, 0, 0], [0, 0.1, 0]]), np.eye(3)))
    True
    """
    p = np.asarray(static_points, float)
    p = p[np.all(np.isfinite(p), axis=1)]
    if p.shape[0] < 2:
        raise ValueError("static_points: need at least two finite markers for the body's long axis")
    d = np.asarray(down, float) / np.linalg.norm(down)
    _, _, vt = np.linalg.svd(p - p.mean(0))
    long_axis = vt[0] - (vt[0] @ d) * d
    if np.linalg.norm(long_axis) < 1e-9:
        long_axis = np.asarray(forward, float) - (np.asarray(forward, float) @ d) * d
    long_axis /= np.linalg.norm(long_axis)
    if long_axis @ np.asarray(forward, float) < 0:
        long_axis = -long_axis
    lateral = np.cross(long_axis, d)
    return np.column_stack([long_axis, d, lateral])


def saddle_angles_deg(rotation, body_axes) -> np.ndarray:
    """Roll, pitch and yaw (deg) of the saddle in the motion frame (n, 3).

    The saddle's axes at time t are ``R(t) @ body_axes`` (the body's pose
    applied to the static-shot axes of :func:`static_body_axes`); written as
    ``Ry(yaw) Rz(pitch) Rx(roll)`` about the motion frame's axes (x
    forward, y down, z = x cross y; right-hand rule): roll about the
    longitudinal axis, pitch about the lateral one, yaw about the vertical.
    At the static shot's pose all three are the static axes' own angles
    (zero when the back's markers line up with x-motion). NaN where no pose.

    Examples
    --------
    A yaw of 10 degrees about the vertical (y):

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> R = Rotation.from_euler("y", [[10.0]], degrees=True).as_matrix()
    >>> saddle_angles_deg(R, np.eye(3)).round(9) + 0.0
    array([[ 0.,  0., 10.]])
    """
    R = np.asarray(rotation, float)
    A = R @ np.asarray(body_axes, float)
    out = np.full((R.shape[0], 3), np.nan)
    ok = np.all(np.isfinite(A), axis=(1, 2))
    if ok.any():
        yaw, pitch, roll = Rotation.from_matrix(A[ok]).as_euler("YZX").T
        out[ok] = np.degrees(np.column_stack([roll, pitch, yaw]))
    return out
