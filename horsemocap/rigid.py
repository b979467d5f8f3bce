"""Rigid-body kinematics of the saddle: registration, angular velocity and
acceleration, and the invisible saddle marker (thesis sections 5.4 and 6).

Symbols (thesis -> code)
------------------------
- ``x_m^m`` / ``MM^m`` (static-shot model, eq. 5.14, 5.21) -> ``model`` (m, 3)
- ``x_m`` measured, ``x_m^r`` / ``MM^r`` registered (eq. 5.19-5.21)
  -> ``points`` / ``Registration.registered`` (n, m, 3)
- ``R(q_R)``, ``q_t`` (eq. 5.14-5.18): the thesis maps the *measured* set onto
  the model, ``x^m = R x + q_t``. Here ``Registration.rotation`` and
  ``.translation`` are the *pose* of the model in each frame,
  ``registered = rotation @ model + translation``, so
  ``R_thesis = rotation.T`` and ``q_t = -rotation.T @ translation``
  (eq. 5.20 gives the same registered points).
- ``r_i``, ``v_i``, ``a_i`` (chapter 6): ``pos[:, i]``, ``vel[:, i]``,
  ``acc[:, i]`` (markers 1, 2, 3 are indices 0, 1, 2). The thesis writes
  ``v_1 = v_2 + omega x r_21`` (eq. 6.1), which holds with
  ``r_21 = r_1 - r_2`` (the vector *from* marker 2 *to* marker 1); we use
  that meaning: ``r_ji = pos_i - pos_j``.
- ``omega`` / ``alfa`` (eq. 6.3, 6.4, 6.38, 6.39) -> ``omega``, ``alpha``
  (n, 3) rad/s, rad/s^2, expressed in the motion frame.
- ``R_MB``, ``r_BS^(B)`` (eq. 6.41-6.47) -> :func:`body_frame`,
  :func:`saddle_in_body`; ``r_MS^(M)(t)`` (eq. 6.48-6.53) ->
  :func:`saddle_position`; ``v_S``, ``a_S`` (eq. 6.54, 6.55) ->
  :func:`saddle_kinematics`.

Version indexing (eq. 6.3/6.4 and 6.38/6.39 with three base markers)
---------------------------------------------------------------------
"Version i" (thesis: ``ver i``) expresses the motion of marker i through the
two others, taken in cyclic order ``(i, j, k) = (1, 2, 3), (2, 3, 1),
(3, 1, 2)``. With ``K1 = r_ji``, ``K2 = v_j - v_i``, ``K3 = r_ki``,
``K4 = v_k - v_i`` (eq. 6.15-6.18) the two solutions are
``omega^1 = K2 x K4 / (-K2 . K3)`` (eq. 6.13 = 6.3) and
``omega^2 = K2 x K4 / (K1 . K4)`` (eq. 6.14 = 6.4). The (6, n, 3) arrays are
ordered as the thesis lists them (section 6.1 and the prompts of 8.4.1)::

    0: omega1_ver1   1: omega2_ver1   2: omega1_ver2
    3: omega2_ver2   4: omega1_ver3   5: omega2_ver3

Note on eq. 6.38/6.39 as printed: there ``K2 = a_2 + omega x (omega x r_21)``
and ``K4 = a_3 + omega x (omega x r_31)``, without ``- a_1``. Rearranging
eq. 6.36 to the form of eq. 6.7 (``r_21 x alpha = K2``) gives
``K2 = a_2 - a_1 + omega x (omega x r_21)``, in the same way that eq. 6.3
uses ``v_2 - v_1``; the printed form is exact only when ``a_1 = 0``. We
implement the derived form (the property tests check it recovers alpha
exactly).

Beyond the thesis
-----------------
- :func:`angular_velocity_lstsq`, :func:`angular_acceleration_lstsq`: all
  markers at once, no ``omega . n = 0`` singularity (only collinear markers).
- :func:`fit_rotations`: omega and alpha from a Fourier fit of the
  registered orientation over time.
- :func:`singularity_angle`, :func:`singularity_report`: eq. 6.35 measured
  frame by frame, with a warning.
- :func:`analyse_rigid_body`: the whole step (App. A steps 8, 9, 11, 12),
  keeping every estimate; with the thesis' chain its saddle
  velocity/acceleration default to the fit of the saddle path built with the
  fitted orientation (``saddle_method="pose"``), because on the default
  canter session the thesis estimate (eq. 6.55 with the six-version
  omega/alpha) sits at the singularity of section 6.1, as in the thesis' own
  canter example.

The step's choices (:class:`horsemocap.params.RigidBodyParams`)
---------------------------------------------------------------
- ``kinematics``: what is passed on (:attr:`RigidBodyAnalysis.omega`,
  ``alpha``, ``saddle_*``, :attr:`RigidBodyAnalysis.marker_kinematics`):
  ``"pose_spline"``, the smoothed pose trajectory of :mod:`horsemocap.pose`
  (all markers registered per frame, position and rotation vector smoothed
  by splines chosen from the data, analytic derivatives; no period, no
  singularity), or ``"fits"``, the thesis' chain. The chain is computed in
  both cases when the record allows it; with ``"pose_spline"`` its failure
  is recorded in :attr:`RigidBodyAnalysis.chain_error` instead of stopping.
- ``saddle_marker``: the static-shot point that is the saddle marker
  (Appendix A step 12a); None: the one left over by :func:`match_static_markers`.
- ``fits.x_degree``, ``fits.order_rule``, ``fits.trend``: the fits of
  :func:`horsemocap.fitting.fit_motion` (``trend``, not in the thesis: a
  linear drift in y and z, since an estimated motion frame is always a little
  off).
- ``fits.omega_versions``, ``fits.alpha_versions``: the versions averaged
  (the thesis' prompts, section 8.4.1).
- ``fits.angular_method``: ``"thesis"``, the mean of the chosen smoothed
  versions (alpha's versions use that omega); ``"lstsq"``, the
  least-squares solutions from all markers, smoothed the same way;
  ``"rotation"``, the Fourier fit of the registered orientation
  (:func:`fit_rotations`). All three are always computed.
- ``fits.saddle_method``: the saddle velocity and acceleration passed on
  with ``"fits"``: the mean of eq. 6.54/6.55 over the three markers
  (``"thesis"``), or the derivatives of the fit
  (:attr:`RigidBodyAnalysis.saddle_fit`) of the saddle path, eq. 6.48 frame
  by frame (``"direct"``) or eq. 6.48 with the *fitted* orientation about the
  markers' centroid (``"pose"``: the roll about the markers' row, poorly
  observed by a thin marker triangle, is smoothed before it moves the
  saddle).
- ``pose``: the pose trajectory's smoothing
  (:func:`horsemocap.pose.fit_pose_trajectory`); ``pose.events`` only with
  ``"pose_spline"``.

Rotations are SciPy's :class:`scipy.spatial.transform.Rotation`; Horn's
quaternion (eq. 5.14-5.21) comes from :mod:`horsemocap.registration`.
"""
from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass, fields, replace
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from . import fitting, smoothing, streaming
from .forking import beside
from .aperture import Aperture
from .basis_check import basis_resolution
from .params import FitsParams, RigidBodyParams
from .probability import f_survival
from .pose import (PoseRegistration, PoseTrajectory, SettledPoseSmoothing, check_model_conditioning,
                   conditioning_warnings, fit_pose_trajectory, register_pose, saddle_angles_deg, static_body_axes)
from .pose_windows import windowed_pose_trajectory
from .registration import check_model, rotation_from_cross_covariance, skew

__all__ = [
    "VERSION_LABELS",
    "Registration",
    "SaddleKinematics",
    "match_static_markers",
    "register",
    "pairwise_distances",
    "angular_velocity_versions",
    "angular_acceleration_versions",
    "angular_velocity_lstsq",
    "angular_acceleration_lstsq",
    "average_versions",
    "smooth_versions",
    "compatibility_residual",
    "marker_plane_normal",
    "singularity_angle",
    "singularity_report",
    "body_frame",
    "body_frames",
    "saddle_in_body",
    "saddle_in_body_versions",
    "saddle_position",
    "saddle_kinematics",
    "RotationFit",
    "fit_rotations",
    "RigidBodyAnalysis",
    "FourierOrders",
    "PoseInput",
    "analyse_rigid_body",
    "ModelChoice",
    "body_coordinates",
    "mean_marker_shape",
    "choose_marker_model",
    "Conditioning",
    "conditioning",
    "saddle_angles",
]

VERSION_LABELS = ("omega1_ver1", "omega2_ver1", "omega1_ver2",
                  "omega2_ver2", "omega1_ver3", "omega2_ver3")
"""Thesis names of the six versions, in the order of the (6, n, 3) arrays."""

_CYCLIC = ((0, 1, 2), (1, 2, 0), (2, 0, 1))


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def _as_positions(name: str, a, markers: int | None = None) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"{name}: expected an array (frames, markers, 3), got shape {a.shape}")
    if markers is not None and a.shape[1] != markers:
        raise ValueError(f"{name}: expected {markers} markers on axis 1, got {a.shape[1]}")
    return a


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def pairwise_distances(points) -> np.ndarray:
    """Inter-marker distances ``|r_i - r_j|`` of (..., m, 3) points -> (..., m, m).

    Examples
    --------
    >>> pairwise_distances([[0.0, 0, 0], [3, 4, 0]])
    array([[0., 5.],
           [5., 0.]])
    """
    p = np.asarray(points, float)
    return np.linalg.norm(p[..., :, None, :] - p[..., None, :, :], axis=-1)


# --------------------------------------------------------------------------
# correspondence static shot <-> motion markers
# --------------------------------------------------------------------------
def match_static_markers(static_points, motion_points, tolerance: float = 0.004, saddle: int | None = None):
    """Which static-shot marker is which motion marker, and which is the saddle.

    The thesis picked the labels by hand (section 8.4.1, ``left_labels``).
    Here every injective assignment of the m motion markers to the k static
    markers is scored by the RMS difference between its inter-marker
    distances and the motion markers' (median over frames) distances.
    Distances alone cannot separate near-isosceles layouts (the skin markers
    lie in a row along the back: two assignments differ by only a few mm)
    nor a triangle from its mirror image, so among the assignments whose
    mismatch is within ``tolerance`` of the best one, the one whose
    registration needs the smallest rotation (median over frames) wins: the
    static shot and the ride are both expressed in the motion frame, with
    the horse heading along +x in both (thesis Figures 8.11, 8.21).

    Parameters
    ----------
    static_points : (k, 3)
        Markers of the static shot in the motion frame (the skin markers and
        the saddle marker), any order, k >= m + 1; NaN rows are ignored.
    motion_points : (n, m, 3)
        Marker trajectories during the ride in the motion frame (NaN allowed).
    tolerance : float
        Metres of RMS distance mismatch treated as measurement noise.
    saddle : int, optional
        The static marker the user named as the saddle marker (Appendix A
        step 12a, ``left_labels`` of the required marker); it is then never
        matched to a motion marker and is the one returned.

    Returns
    -------
    static_index : (m,) int
        ``static_points[static_index[j]]`` is motion marker j.
    saddle_index : int
        The static marker left over (if several are left over, the one
        nearest to the centroid of the matched markers).

    Examples
    --------
    The ride sees the static shot's markers 2, 0, 1 (moved forward); point 3 is never seen:

    >>> import numpy as np
    >>> static = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0], [0.25, -0.4, 0.1]])
    >>> motion = np.repeat(static[[2, 0, 1]][None] + [1.0, 0, 0], 5, axis=0)
    >>> index, saddle = match_static_markers(static, motion)
    >>> index.tolist(), saddle
    ([2, 0, 1], 3)
    """
    static = np.asarray(static_points, float)
    motion = _as_positions("motion_points", motion_points)
    if static.ndim != 2 or static.shape[1] != 3:
        raise ValueError(f"static_points: expected (k, 3), got shape {static.shape}")
    m = motion.shape[1]
    valid = np.flatnonzero(np.all(np.isfinite(static), axis=1))
    if valid.size < m + 1:
        raise ValueError(f"static_points: need at least {m + 1} finite markers "
                         f"({m} motion markers + the saddle marker), got {valid.size}")
    d_motion = np.nanmedian(pairwise_distances(motion), axis=0)
    if not np.all(np.isfinite(d_motion)):
        raise ValueError("motion_points: a marker has no finite frame")
    if saddle is not None:
        if not 0 <= int(saddle) < len(static) or int(saddle) not in set(valid.tolist()):
            raise ValueError(f"saddle marker: expected the index of a finite static-shot marker 0..{len(static) - 1}, "
                             f"got {saddle!r}")
        valid = valid[valid != int(saddle)]
        if valid.size < m:
            raise ValueError(f"static_points: need {m} finite markers besides the saddle marker, got {valid.size}")
    d_static = pairwise_distances(static)
    iu = np.triu_indices(m, 1)
    cands = []
    for perm in itertools.permutations(valid, m):
        perm = np.array(perm)
        diff = d_static[np.ix_(perm, perm)][iu] - d_motion[iu]
        cands.append((float(np.sqrt(np.mean(diff ** 2))), perm))
    best_rms = min(c[0] for c in cands)
    close = [c for c in cands if c[0] <= best_rms + tolerance]
    ok = np.all(np.isfinite(motion), axis=(1, 2))
    sample = motion[ok][:: max(1, ok.sum() // 20)]
    if len(close) > 1:
        def angle(perm):
            return float(np.median(Rotation.from_matrix(register(sample, static[perm]).rotation).magnitude()))
        best = min(close, key=lambda c: angle(c[1]))[1]
    else:
        best = close[0][1]
    if saddle is not None:
        return best.astype(int), int(saddle)
    rest = [i for i in valid if i not in set(best.tolist())]
    centroid = static[best].mean(axis=0)
    saddle = int(min(rest, key=lambda i: np.linalg.norm(static[i] - centroid)))
    return best.astype(int), saddle


# --------------------------------------------------------------------------
# registration (section 5.4)
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Registration:
    """Result of :func:`register` (thesis section 5.4).

    Attributes
    ----------
    rotation : (n, 3, 3)
        Pose rotation: ``registered[k] = model @ rotation[k].T + translation[k]``
        (thesis ``RR(:,:,k)^-1``, eq. 5.21).
    translation : (n, 3)
        Pose translation (thesis ``-RR^-1 Q_t``).
    registered : (n, m, 3)
        ``MM^r``: the model moved by the pose of each frame (rigid by
        construction: its inter-marker distances equal the model's).
    residual : (n, m)
        ``e_m`` of Figure 5.3: distance from each measured marker to its
        registered position (m).
    rms : (n,)
        ``sqrt(f(q))`` of eq. 5.14 at the optimum.
    reason : (n,) str
        ``""`` where registered, otherwise why the frame is NaN.
    """

    rotation: np.ndarray
    translation: np.ndarray
    registered: np.ndarray
    residual: np.ndarray
    rms: np.ndarray
    reason: np.ndarray


def register(points, model) -> Registration:
    """Register the model (static shot) onto the measured markers, every frame.

    Closed-form quaternion solution of Horn (1987) used by Besl and McKay
    (1992), eq. 5.14-5.21: with centred sets ``x_m - mu_x`` (model) and
    ``p_m - mu_p`` (measured), the cross-covariance ``S = sum (x - mu_x)(p - mu_p)^T``
    gives the symmetric 4x4 matrix ``Q(S)``; its eigenvector of the largest
    eigenvalue is the optimal unit quaternion ``q_R`` (eq. 5.15), ``R`` follows
    from eq. 5.16 and ``t = mu_p - R mu_x``.

    Parameters
    ----------
    points : (n, m, 3)
        Measured (smoothed) marker positions in the motion frame (``MM``).
    model : (m, 3)
        The same markers in the static shot (``MM^m``), same order.

    Returns
    -------
    Registration
        Frames where any marker is NaN stay NaN, with the reason.

    Examples
    --------
    Markers that are the model turned by 90 degrees about z and moved:

    >>> import numpy as np
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> reg = register((model @ turn.T + [2.0, 1, 0])[None], model)
    >>> bool(np.allclose(reg.rotation[0], turn)), bool(np.allclose(reg.translation[0], [2, 1, 0]))
    (True, True)
    """
    p = _as_positions("points", points)
    n, m, _ = p.shape
    x = check_model(model, m)
    if m < 3:
        raise ValueError(f"points: registration needs at least 3 markers, got {m}")
    ok = np.all(np.isfinite(p), axis=(1, 2))
    reason = np.full(n, "", dtype=object)
    for k in np.flatnonzero(~ok):
        miss = np.flatnonzero(~np.all(np.isfinite(p[k]), axis=1))
        reason[k] = "marker(s) " + ",".join(str(i + 1) for i in miss) + " missing"
    mu_x = x.mean(0)
    xc = x - mu_x
    pp = np.where(ok[:, None, None], p, 0.0)
    mu_p = pp.mean(1)
    pc = pp - mu_p[:, None]
    S = np.einsum("mi,kmj->kij", xc, pc)  # (n, 3, 3): sum_m xc_m pc_m^T
    R = rotation_from_cross_covariance(S).as_matrix()
    t = mu_p - np.einsum("kij,j->ki", R, mu_x)
    reg = np.einsum("kij,mj->kmi", R, x) + t[:, None]
    R[~ok] = np.nan
    t[~ok] = np.nan
    reg[~ok] = np.nan
    res = np.linalg.norm(np.where(ok[:, None, None], p, np.nan) - reg, axis=-1)
    rms = np.sqrt(np.mean(res ** 2, axis=1))
    return Registration(rotation=R, translation=t, registered=reg, residual=res,
                        rms=rms, reason=reason.astype(str))


# --------------------------------------------------------------------------
# angular velocity and acceleration (section 6.1, 6.2)
# --------------------------------------------------------------------------
def _check_three(name, a, n=None):
    a = _as_positions(name, a, markers=3)
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name}: expected {n} frames, got {a.shape[0]}")
    return a


def _two_solutions(K1, K2, K3, K4):
    """Eq. 6.13 and 6.14 for ``K1 x u = K2``, ``K3 x u = K4``."""
    num = np.cross(K2, K4)
    with np.errstate(divide="ignore", invalid="ignore"):
        u1 = num / (-_dot(K2, K3))[..., None]
        u2 = num / _dot(K1, K4)[..., None]
    return u1, u2


def angular_velocity_versions(pos, vel) -> np.ndarray:
    """The six thesis versions of the angular velocity (eq. 6.3, 6.4).

    Parameters
    ----------
    pos, vel : (n, 3, 3)
        Positions ``r_i`` (registered) and velocities ``v_i`` (from the fits)
        of markers 1..3 in the motion frame.

    Returns
    -------
    (6, n, 3)
        ``omega^{1,ver1}, omega^{2,ver1}, ..., omega^{2,ver3}`` (see the module
        docstring for the indexing). Frames at the singularity
        (``omega . n = 0``, eq. 6.35) give inf/NaN.

    Examples
    --------
    Three markers turning at 2 rad/s about z (``v = omega x r``): every version is omega.

    >>> import numpy as np
    >>> pos = np.array([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0]]])
    >>> vel = np.cross([0, 0, 2.0], pos)
    >>> bool(np.allclose(angular_velocity_versions(pos, vel), [0, 0, 2]))
    True
    """
    pos = _check_three("pos", pos)
    vel = _check_three("vel", vel, pos.shape[0])
    out = []
    for i, j, k in _CYCLIC:
        K1 = pos[:, i] - pos[:, j]          # r_ji (eq. 6.15)
        K2 = vel[:, j] - vel[:, i]          # v_j - v_i (6.16)
        K3 = pos[:, i] - pos[:, k]          # r_ki (6.17)
        K4 = vel[:, k] - vel[:, i]          # v_k - v_i (6.18)
        out.extend(_two_solutions(K1, K2, K3, K4))
    return np.stack(out)


def angular_acceleration_versions(pos, vel, acc, omega) -> np.ndarray:
    """The six versions of the angular acceleration (eq. 6.38, 6.39).

    Parameters
    ----------
    pos, vel, acc : (n, 3, 3)
        Marker positions, velocities (unused, kept for a uniform signature)
        and accelerations ``a_i``.
    omega : (n, 3)
        The angular velocity (the chosen average, section 6.1).

    Returns
    -------
    (6, n, 3)
        ``alfa^{1,ver1}, alfa^{2,ver1}, ..., alfa^{2,ver3}``, with
        ``K1 = r_ji``, ``K2 = a_j - a_i + omega x (omega x r_ji)``,
        ``K3 = r_ki``, ``K4 = a_k - a_i + omega x (omega x r_ki)`` (the
        ``- a_i`` is missing in the printed eq. 6.38/6.39; see module notes).

    Examples
    --------
    Markers with omega = 2 rad/s and alpha = 3 rad/s^2 about z
    (``a = alpha x r + omega x (omega x r)``):

    >>> import numpy as np
    >>> pos = np.array([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0]]])
    >>> w, al = np.array([[0, 0, 2.0]]), np.array([0, 0, 3.0])
    >>> acc = np.cross(al, pos) + np.cross(w[:, None], np.cross(w[:, None], pos))
    >>> bool(np.allclose(angular_acceleration_versions(pos, None, acc, w), al))
    True
    """
    pos = _check_three("pos", pos)
    acc = _check_three("acc", acc, pos.shape[0])
    w = np.asarray(omega, float)
    if w.shape != (pos.shape[0], 3):
        raise ValueError(f"omega: expected shape ({pos.shape[0]}, 3), got {w.shape}")
    out = []
    for i, j, k in _CYCLIC:
        r_ji = pos[:, i] - pos[:, j]
        r_ki = pos[:, i] - pos[:, k]
        K2 = acc[:, j] - acc[:, i] + np.cross(w, np.cross(w, r_ji))
        K4 = acc[:, k] - acc[:, i] + np.cross(w, np.cross(w, r_ki))
        out.extend(_two_solutions(r_ji, K2, r_ki, K4))
    return np.stack(out)


def compatibility_residual(pos, vel) -> np.ndarray:
    """Left minus right side of the compatibility condition eq. 6.19/6.20.

    ``r_21 . (v_3 - v_1) + (v_2 - v_1) . r_31`` for each version's base
    marker, shape (3, n). Zero for rigid motion (eq. 6.28): the two
    denominators of eq. 6.3 and 6.4 are equal.

    Examples
    --------
    >>> import numpy as np
    >>> pos = np.array([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0]]])
    >>> vel = np.cross([0.3, -1.0, 2.0], pos) + [1.0, 0, 0]       # a rigid motion
    >>> bool(np.allclose(compatibility_residual(pos, vel), 0))
    True
    """
    pos = _check_three("pos", pos)
    vel = _check_three("vel", vel, pos.shape[0])
    out = []
    for i, j, k in _CYCLIC:
        K1 = pos[:, i] - pos[:, j]
        K2 = vel[:, j] - vel[:, i]
        K3 = pos[:, i] - pos[:, k]
        K4 = vel[:, k] - vel[:, i]
        out.append(_dot(K1, K4) + _dot(K2, K3))
    return np.stack(out)


def angular_velocity_lstsq(pos, vel) -> np.ndarray:
    """Least-squares angular velocity from all markers (not in the thesis).

    Solves ``v_m - vbar = omega x (r_m - rbar)`` for all markers m in the
    least-squares sense, i.e. ``-[r_m - rbar]x omega = v_m - vbar``. The
    3M x 3 system has full rank whenever the markers are not collinear, so
    unlike eq. 6.3/6.4 there is no singularity at ``omega . n = 0``.

    Parameters
    ----------
    pos, vel : (n, m, 3), m >= 3

    Returns
    -------
    (n, 3) ; NaN where a marker is missing.

    Examples
    --------
    >>> import numpy as np
    >>> pos = np.array([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0], [0, 0, 0.5]]])
    >>> vel = np.cross([0.3, -1.0, 2.0], pos) + [1.0, 0, 0]
    >>> angular_velocity_lstsq(pos, vel).round(12) + 0.0
    array([[ 0.3, -1. ,  2. ]])
    """
    pos = _as_positions("pos", pos)
    vel = _as_positions("vel", vel, pos.shape[1])
    d = pos - pos.mean(1, keepdims=True)
    rhs = vel - vel.mean(1, keepdims=True)
    return _lstsq_cross(d, rhs)


def _lstsq_cross(d, rhs):
    """Solve ``u x d_m = rhs_m`` (all m) for u, per frame."""
    n, m, _ = d.shape
    A = -skew(d).reshape(n, 3 * m, 3)       # u x d = -[d]x u
    b = rhs.reshape(n, 3 * m)
    out = np.full((n, 3), np.nan)
    ok = np.all(np.isfinite(A), axis=(1, 2)) & np.all(np.isfinite(b), axis=1)
    if np.any(ok):
        AtA = np.einsum("kai,kaj->kij", A[ok], A[ok])
        Atb = np.einsum("kai,ka->ki", A[ok], b[ok])
        out[ok] = np.linalg.solve(AtA, Atb[..., None])[..., 0]
    return out


def angular_acceleration_lstsq(pos, acc, omega) -> np.ndarray:
    """Least-squares angular acceleration from all markers (not in the thesis).

    Solves ``a_m - abar - omega x (omega x d_m) = alpha x d_m`` with
    ``d_m = r_m - rbar`` (eq. 6.36 for every marker about the centroid).

    Parameters
    ----------
    pos, acc : (n, m, 3) ; omega : (n, 3)

    Returns
    -------
    (n, 3)

    Examples
    --------
    >>> import numpy as np
    >>> pos = np.array([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0], [0, 0, 0.5]]])
    >>> w, al = np.array([[0.3, -1.0, 2.0]]), np.array([0.0, 1.0, 3.0])
    >>> acc = np.cross(al, pos) + np.cross(w[:, None], np.cross(w[:, None], pos))
    >>> angular_acceleration_lstsq(pos, acc, w).round(12) + 0.0
    array([[0., 1., 3.]])
    """
    pos = _as_positions("pos", pos)
    acc = _as_positions("acc", acc, pos.shape[1])
    w = np.asarray(omega, float)[:, None, :]
    d = pos - pos.mean(1, keepdims=True)
    rhs = acc - acc.mean(1, keepdims=True) - np.cross(w, np.cross(w, d))
    return _lstsq_cross(d, rhs)


def average_versions(versions, use=None) -> np.ndarray:
    """Mean of the chosen versions (section 6.1: "overall value ... average of
    the selected values").

    Parameters
    ----------
    versions : (6, n, 3)
    use : (6,) bool, optional
        Which versions enter the mean (the thesis' y/n prompts); all by
        default. NaN/inf entries of a chosen version are skipped frame by
        frame.

    Examples
    --------
    >>> import numpy as np
    >>> versions = np.arange(6.0)[:, None, None] * np.ones((6, 1, 3))
    >>> average_versions(versions, [True, True, False, False, False, False])
    array([[0.5, 0.5, 0.5]])
    """
    v = np.asarray(versions, float)
    use = np.ones(v.shape[0], bool) if use is None else np.asarray(use, bool)
    if use.shape != (v.shape[0],):
        raise ValueError(f"use: expected {v.shape[0]} booleans, got shape {use.shape}")
    if not use.any():
        raise ValueError("use: choose at least one version")
    sel = v[use]
    sel = np.where(np.isfinite(sel), sel, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(sel, axis=0)


def smooth_versions(versions, smoother: Callable | None = None, span: float = 0.1) -> np.ndarray:
    """Smooth every version and component over time (Appendix A step 11,
    ``angular_vel_and_acc_all_avg_smooth.m``; the thesis shows "original and
    smoothed" versions, Figures 8.14-8.17).

    Parameters
    ----------
    versions : (6, n, 3)
    smoother : callable ``f(y (n,), span) -> (n,)``, optional
        Default: ``horsemocap.smoothing.smooth`` with ``method="rloess"``
        (MATLAB ``smooth(y, span, 'rloess')``). Non-finite values (a version
        at its singularity) are left out and stay NaN (the finite samples are
        smoothed with rloess as a function of the frame index).

    Examples
    --------
    >>> import numpy as np
    >>> bool(np.allclose(smooth_versions(np.ones((6, 20, 3))), 1.0))      # a constant stays
    True
    """
    v = np.asarray(versions, float)
    if smoother is None:
        def smoother(y, span):  # type: ignore[no-redef]
            return smoothing.smooth(y, span, method="rloess")
    out = np.full_like(v, np.nan)
    idx = np.arange(v.shape[1], dtype=float)
    for i in range(v.shape[0]):
        for c in range(v.shape[2]):
            y = v[i, :, c]
            ok = np.isfinite(y)
            if ok.all():
                out[i, :, c] = smoother(y, span)
            elif ok.sum() >= 3:
                # missing/singular frames: smooth the finite samples only
                out[i, ok, c] = smoothing.smooth(y[ok], span, method="rloess", x=idx[ok])
    return out


def marker_plane_normal(pos) -> np.ndarray:
    """Unit normal ``n`` of the plane of markers 1, 2, 3 (eq. 6.33), (n, 3).

    Examples
    --------
    >>> marker_plane_normal([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0]]]) + 0.0
    array([[0., 0., 1.]])
    """
    pos = _check_three("pos", pos)
    c = np.cross(pos[:, 0] - pos[:, 1], pos[:, 0] - pos[:, 2])  # r_21 x r_31
    return c / np.linalg.norm(c, axis=1, keepdims=True)


def singularity_angle(pos, omega) -> np.ndarray:
    """Angle between omega and the markers' plane normal, per frame (degrees).

    Eq. 6.31-6.35: the thesis solutions (6.3, 6.4, 6.38, 6.39) are 0/0 when
    ``omega . n = 0``, i.e. at 90 degrees; they are reliable near 0 or 180
    degrees. NaN where omega is zero or missing.

    Examples
    --------
    >>> pos = [[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0]]]
    >>> singularity_angle(pos, [[0, 0, 2.0]]), singularity_angle(pos, [[2.0, 0, 0]])
    (array([0.]), array([90.]))
    """
    nrm = marker_plane_normal(pos)
    w = np.asarray(omega, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = _dot(nrm, w) / np.linalg.norm(w, axis=-1)
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def singularity_report(angle_deg, tolerance_deg: float = 15.0, warn: bool = True) -> dict:
    """Summarise how close the thesis formulas come to their singularity.

    Parameters
    ----------
    angle_deg : (n,)
        From :func:`singularity_angle`.
    tolerance_deg : float
        A frame is flagged when ``|angle - 90| < tolerance_deg`` (then
        ``|cos| < sin(tolerance)``: the denominators of eq. 6.3/6.4 are below
        26 % of their largest possible value for 15 degrees, and errors in v
        are amplified accordingly).
    warn : bool
        Emit a ``RuntimeWarning`` if any frame is flagged.

    Returns
    -------
    dict with ``flagged`` (n,) bool, ``fraction`` flagged, ``min_margin_deg``
    (smallest ``|angle - 90|``), ``median_angle_deg``.

    Examples
    --------
    >>> rep = singularity_report([10.0, 85.0, 170.0], warn=False)
    >>> round(rep["fraction"], 3), rep["min_margin_deg"]
    (0.333, 5.0)
    """
    a = np.asarray(angle_deg, float)
    margin = np.abs(a - 90.0)
    flagged = margin < tolerance_deg
    fin = np.isfinite(margin)
    rep = {
        "flagged": flagged,
        "fraction": float(flagged[fin].mean()) if fin.any() else float("nan"),
        "min_margin_deg": float(np.nanmin(margin)) if fin.any() else float("nan"),
        "median_angle_deg": float(np.nanmedian(a)) if fin.any() else float("nan"),
    }
    if warn and flagged.any():
        warnings.warn(f"angular velocity: omega within {tolerance_deg:g} deg of the markers' plane "
                      f"in {flagged.sum()} of {fin.sum()} frames (closest {rep['min_margin_deg']:.1f} deg "
                      "from perpendicular to the normal): the thesis versions (eq. 6.3/6.4, "
                      "6.38/6.39) are unreliable there (eq. 6.35); use the pose trajectory (kinematics "
                      "'pose_spline', the default) or the orientation fit (angular_method 'rotation'), "
                      "which use all markers and the motion's smoothness", RuntimeWarning, stacklevel=2)
    return rep


@dataclass(frozen=True)
class RotationFit:
    """Fourier fits of the registered orientation (not in the thesis).

    ``R(t) = R_ref Exp(phi(t))`` with each component of the rotation vector
    ``phi`` fitted as in section 5.5.2.2. ``omega(t)``, ``alpha(t)`` (n, 3),
    motion frame, from central differences of the fitted (analytic) rotation
    with steps of 1e-5 s / 1e-4 s (truncation and rounding below 1e-7
    relative).
    """

    reference: np.ndarray
    fits: tuple
    orders: np.ndarray

    def rotation(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        phi = np.stack([f.evaluate(t) for f in self.fits], -1)
        return self.reference @ Rotation.from_rotvec(phi.reshape(-1, 3)).as_matrix().reshape(phi.shape + (3,))

    def omega(self, t, h: float = 1e-5) -> np.ndarray:
        t = np.asarray(t, float)
        Rp, Rm, R = self.rotation(t + h), self.rotation(t - h), self.rotation(t)
        W = ((Rp - Rm) / (2 * h)) @ np.swapaxes(R, -1, -2)
        W = (W - np.swapaxes(W, -1, -2)) / 2
        return np.stack([W[..., 2, 1], W[..., 0, 2], W[..., 1, 0]], -1)

    def alpha(self, t, h: float = 1e-4) -> np.ndarray:
        t = np.asarray(t, float)
        return (self.omega(t + h) - self.omega(t - h)) / (2 * h)


def fit_rotations(t, rotation, orders=None, rule: str = "significant", w0=None,
                  start: str = "matlab") -> RotationFit:
    """Fit the registered orientation over time: a smooth, rigid estimate of
    omega and alpha from all markers at once (not in the thesis).

    The per-marker fits of section 5.5 leave each marker its own frequency
    and order, and a poly1 in x discards the x-velocity differences that a
    rotation causes, so the relative velocities entering eq. 6.3/6.4 (and the
    least-squares solution) can be far off. Here the orientation
    ``R(t) = Registration.rotation`` is written as ``R_ref Exp(phi(t))``
    (``R_ref`` the orientation of the first registered frame) and each
    component of ``phi`` is fitted with a Fourier series
    (:func:`horsemocap.fitting.fit_fourier`, order by
    :func:`horsemocap.fitting.choose_order` with E counted on the
    rloess-smoothed angle, unless given).

    Parameters
    ----------
    t : (n,) ; rotation : (n, 3, 3) (NaN frames ignored)
    orders : None, int or (3,) ints
    rule, w0, start
        As in :func:`horsemocap.fitting.fit_motion`.

    Examples
    --------
    A rotation about z by ``0.3 sin(w t)``: the fit's omega is ``0.3 w cos(w t)``.

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> t, w = np.arange(40) / 25.0, 2 * np.pi
    >>> R = Rotation.from_rotvec(np.outer(0.3 * np.sin(w * t), [0, 0, 1])).as_matrix()
    >>> fit = fit_rotations(t, R, orders=1, w0=w)
    >>> bool(np.allclose(fit.omega(t)[:, 2], 0.3 * w * np.cos(w * t), atol=1e-6))
    True
    """
    t = np.asarray(t, float)
    R = np.asarray(rotation, float)
    ok = np.all(np.isfinite(R), axis=(1, 2))
    if ok.sum() < 8:
        raise ValueError(f"rotation: need at least 8 registered frames, got {ok.sum()}")
    ref = R[np.flatnonzero(ok)[0]]
    phi = Rotation.from_matrix(ref.T @ R[ok]).as_rotvec()
    o = None if orders is None else np.broadcast_to(np.asarray(orders, int), (3,))
    fits, used = [], []
    for c in range(3):
        if o is None:
            # E counted on the rloess-smoothed angle (section 5.5.2.2 counts on
            # smoothed data): the poorly observed roll angle is noisy.
            e = fitting.count_extremes(smoothing.smooth(phi[:, c], 0.1, method="rloess"))
            n = fitting.choose_order(t[ok], phi[:, c], e, rule=rule, w0=w0, start=start)
        else:
            n = int(o[c])
        fits.append(fitting.fit_fourier(t[ok], phi[:, c], n, w0=w0, start=start))
        used.append(n)
    return RotationFit(ref, tuple(fits), np.array(used))


# --------------------------------------------------------------------------
# body frame and the invisible saddle marker (sections 6.3, 6.4)
# --------------------------------------------------------------------------
def body_frames(pos, base: int = 0):
    """Body frames ``R_MB(t)`` and origins of three markers (eq. 6.49-6.53).

    Parameters
    ----------
    pos : (n, 3, 3)
        Markers 1..3 in the motion frame.
    base : 0, 1 or 2
        Origin marker i; the x axis points to marker ``i+1`` and the xy plane
        holds marker ``i+2`` (cyclic). ``base=0`` is the thesis' frame.

    Returns
    -------
    R_MB : (n, 3, 3)  columns ``u1 | u2 | u3`` (eq. 6.45, 6.49)
    origin : (n, 3)   ``r_MB^(M)`` = the base marker.

    Examples
    --------
    >>> R, origin = body_frames([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    >>> R[0], origin[0]
    (array([[1., 0., 0.],
           [0., 1., 0.],
           [0., 0., 1.]]), array([0., 0., 0.]))
    """
    pos = _check_three("pos", pos)
    i, j, k = _CYCLIC[base]
    u1 = pos[:, j] - pos[:, i]
    u1 = u1 / np.linalg.norm(u1, axis=1, keepdims=True)        # 6.41 / 6.50
    u2p = pos[:, k] - pos[:, i]
    u2p = u2p / np.linalg.norm(u2p, axis=1, keepdims=True)     # 6.42 / 6.51
    u3 = np.cross(u1, u2p)
    u3 = u3 / np.linalg.norm(u3, axis=1, keepdims=True)        # 6.43 / 6.52
    u2 = np.cross(u3, u1)                                      # 6.44 / 6.53
    return np.stack([u1, u2, u3], axis=-1), pos[:, i].copy()


def body_frame(static_points, base: int = 0):
    """Body frame of the static shot (eq. 6.41-6.45).

    Parameters
    ----------
    static_points : (3, 3)
        Markers 1, 2, 3 of the static shot in the motion frame.

    Returns
    -------
    R_MB : (3, 3), origin : (3,)

    Examples
    --------
    >>> R, origin = body_frame([[1.0, 1, 0], [1, 3, 0], [0, 1, 0]])     # marker 2 along +y
    >>> R[:, 0], origin
    (array([0., 1., 0.]), array([1., 1., 0.]))
    """
    s = np.asarray(static_points, float)
    if s.shape != (3, 3):
        raise ValueError(f"static_points: expected (3, 3) (markers 1-3), got {s.shape}")
    R, o = body_frames(s[None], base)
    return R[0], o[0]


def saddle_in_body(static_markers, static_saddle, base: int = 0) -> np.ndarray:
    """Saddle marker in the body frame, ``r_BS^(B)`` (eq. 6.46, 6.47).

    Parameters
    ----------
    static_markers : (3, 3)
        The three skin markers in the static shot (motion frame).
    static_saddle : (3,)
        The saddle marker in the static shot (motion frame), ``r_MS^(M)``.

    Examples
    --------
    >>> saddle_in_body([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [0.2, 0.3, 0.5])
    array([0.2, 0.3, 0.5])
    """
    R, o = body_frame(static_markers, base)
    s = np.asarray(static_saddle, float)
    if s.shape != (3,):
        raise ValueError(f"static_saddle: expected (3,), got {s.shape}")
    return R.T @ (s - o)


def saddle_in_body_versions(static_markers, static_saddle) -> np.ndarray:
    """``r_BS^(B)`` for the body frames based on markers 1, 2, 3, (3, 3).

    Examples
    --------
    >>> saddle_in_body_versions([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [0.2, 0.3, 0.5])[0]
    array([0.2, 0.3, 0.5])
    """
    return np.stack([saddle_in_body(static_markers, static_saddle, b) for b in range(3)])


def saddle_position(pos, saddle_body, base: int = 0) -> np.ndarray:
    """Position of the invisible marker during the ride (eq. 6.48).

    ``r_MS^(M)(t) = R_MB(t) r_BS^(B) + r_MB^(M)(t)``; ``saddle_body`` must have
    been computed with the same ``base``.

    Examples
    --------
    The markers moved 1 m along x carry the saddle with them:

    >>> import numpy as np
    >>> static = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> sb = saddle_in_body(static, [0.2, 0.3, 0.5])
    >>> saddle_position((static + [1.0, 0, 0])[None], sb)
    array([[1.2, 0.3, 0.5]])
    """
    R, o = body_frames(pos, base)
    return np.einsum("kij,j->ki", R, np.asarray(saddle_body, float)) + o


@dataclass(frozen=True)
class SaddleKinematics:
    """The invisible saddle marker (sections 6.3, 6.4).

    Attributes
    ----------
    position : (n, 3)
        ``r_MS^(M)(t)`` with the thesis body frame (marker 1 origin, eq. 6.48).
    position_versions : (3, n, 3)
        Eq. 6.48 with the body frame based on marker 1, 2, 3 (identical for
        registered markers; they differ for non-rigid input).
    velocity_versions, acceleration_versions : (3, n, 3)
        Eq. 6.54 and 6.55 with marker 1, 2, 3 as the known point.
    velocity, acceleration : (n, 3)
        Their means (``V^s``, ``A^s``, section 6.4).
    """

    position: np.ndarray
    position_versions: np.ndarray
    velocity_versions: np.ndarray
    acceleration_versions: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


def saddle_kinematics(pos, vel, acc, omega, alpha, saddle_body, base_versions: bool = True) -> SaddleKinematics:
    """Position, velocity and acceleration of the invisible saddle marker.

    Parameters
    ----------
    pos, vel, acc : (n, 3, 3)
        Registered positions and fitted velocities/accelerations of markers 1-3.
    omega, alpha : (n, 3)
    saddle_body : (3,) or (3, 3)
        ``r_BS^(B)`` from :func:`saddle_in_body` (``base=0``), or the three
        rows for bases 0, 1, 2 (:func:`saddle_in_body_versions`) to get
        independent per-base position versions.

    Notes
    -----
    ``v_S = v_i + omega x r_iS`` (eq. 6.54), ``a_S = a_i + omega x (omega x
    r_iS) + alpha x r_iS`` (eq. 6.55), ``r_iS = r_S - r_i`` for i = 1, 2, 3,
    then the mean.

    Examples
    --------
    A body turning at 2 rad/s about z: the saddle at ``r = (0.5, 0.5, 0.3)`` has
    ``v = omega x r = (-1, 1, 0)`` and ``a = omega x v = (-2, -2, 0)``.

    >>> import numpy as np
    >>> pos = np.array([[[1.0, 0, 0], [0, 1, 0], [-1, -1, 0]]])
    >>> w = np.array([[0, 0, 2.0]])
    >>> vel = np.cross(w[:, None], pos)
    >>> acc = np.cross(w[:, None], vel)
    >>> sk = saddle_kinematics(pos, vel, acc, w, np.zeros((1, 3)), saddle_in_body(pos[0], [0.5, 0.5, 0.3]))
    >>> sk.velocity.round(12) + 0.0, sk.acceleration.round(12) + 0.0
    (array([[-1.,  1.,  0.]]), array([[-2., -2.,  0.]]))
    """
    pos = _check_three("pos", pos)
    n = pos.shape[0]
    vel = _check_three("vel", vel, n)
    acc = _check_three("acc", acc, n)
    w = np.asarray(omega, float)
    al = np.asarray(alpha, float)
    for name, a in (("omega", w), ("alpha", al)):
        if a.shape != (n, 3):
            raise ValueError(f"{name}: expected shape ({n}, 3), got {a.shape}")
    sb = np.asarray(saddle_body, float)
    if sb.shape == (3,):
        # only the base-1 body coordinates are known: those of bases 2 and 3
        # are the same point expressed in their frames, averaged over frames
        p0 = saddle_position(pos, sb, 0)
        sbs = [sb]
        for b in (1, 2):
            Rb, ob = body_frames(pos, b)
            sbs.append(np.nanmean(np.einsum("kji,kj->ki", Rb, p0 - ob), axis=0))
    elif sb.shape == (3, 3):
        sbs = list(sb)
    else:
        raise ValueError(f"saddle_body: expected (3,) or (3, 3) (one row per base marker), got {sb.shape}")
    pv = np.stack([saddle_position(pos, sbs[b], b) for b in range(3)])
    p0 = pv[0]
    r_iS = p0[None] - np.moveaxis(pos, 1, 0)                  # (3, n, 3)
    vv = np.moveaxis(vel, 1, 0) + np.cross(w[None], r_iS)
    av = (np.moveaxis(acc, 1, 0) + np.cross(w[None], np.cross(w[None], r_iS))
          + np.cross(al[None], r_iS))
    return SaddleKinematics(position=p0, position_versions=pv, velocity_versions=vv,
                            acceleration_versions=av, velocity=vv.mean(0), acceleration=av.mean(0))


# --------------------------------------------------------------------------
# the whole rigid-body step (Appendix A steps 8, 9, 11, 12)
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class RigidBodyAnalysis:
    """Everything from the smoothed motion-frame markers to the saddle.

    Attributes
    ----------
    t : (n,)
    static_index : (3,) int ; saddle_index : int
        Correspondence of the static shot (:func:`match_static_markers`).
    model : (3, 3) ; static_saddle : (3,)
        Static-shot markers (same order as the motion markers) and saddle; the
        model of the pose registration is the moving frames' mean shape instead
        when the static shot's shape is off by more than a frame's noise
        (``model_choice``); the thesis' chain always uses the static shot's.
    registration : Registration
    motion_fit : horsemocap.fitting.MotionFit
    pos, vel, acc : (n, 3, 3)
        Registered positions, fitted velocities and accelerations of the markers.
    omega_versions, alpha_versions : (6, n, 3)
        Smoothed thesis versions (eq. 6.3/6.4, 6.38/6.39).
    omega_raw, alpha_raw : (6, n, 3)
        The same before smoothing.
    omega_lstsq, alpha_lstsq : (n, 3)
        Least-squares solutions from all markers.
    rotation_fit : RotationFit ; omega_rotation, alpha_rotation : (n, 3)
        From the fitted registered orientation (:func:`fit_rotations`).
    omega, alpha : (n, 3)
        The values used for the saddle (``method``).
    omega_use, alpha_use : (6,) bool ; method : str
    singularity_deg : (n,)
        :func:`singularity_angle` of ``omega``.
    saddle_body : (3, 3)
        ``r_BS^(B)`` for bases 1, 2, 3 (eq. 6.47).
    saddle : SaddleKinematics
        Thesis eq. 6.48-6.55 with ``omega``, ``alpha``.
    saddle_fit : horsemocap.fitting.MotionFit
        Not in the thesis: the section 5.5 fits applied to a saddle path
        (eq. 6.48 per frame, or with the fitted orientation: ``saddle_method``);
        their analytic derivatives give the saddle velocity and acceleration
        without omega and alpha, so they do not suffer from the singularity
        of section 6.1.
    saddle_path : (n, 3)
        The saddle path that was fitted (``saddle.position`` for "thesis" and
        "direct", the fitted-orientation path for "pose").
    left_out : (N, m) bool array or None
        Markers of the pose frames left out of the pose registration because
        they moved against the other markers' rigid motion
        (:func:`against_rigid_motion`; four or more markers only).
    model_choice : ModelChoice or None
        Whether ``model`` is the static shot's shape or the moving frames'
        mean shape, and why (:func:`choose_marker_model`).
    basis_resolution : BasisResolution or None
        A pose record longer than a spline fits with a knot at every frame:
        the saddle's acceleration against a fit of the record's middle with a
        knot at every frame (:func:`horsemocap.basis_check.basis_resolution`);
        None otherwise.
    """

    t: np.ndarray
    static_index: np.ndarray
    saddle_index: int
    model: np.ndarray
    static_saddle: np.ndarray
    registration: Registration
    motion_fit: object
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    omega_raw: np.ndarray
    omega_versions: np.ndarray
    alpha_raw: np.ndarray
    alpha_versions: np.ndarray
    omega_lstsq: np.ndarray
    alpha_lstsq: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    rotation_fit: RotationFit
    omega_rotation: np.ndarray
    alpha_rotation: np.ndarray
    omega_use: np.ndarray
    alpha_use: np.ndarray
    method: str
    singularity_deg: np.ndarray
    saddle_body: np.ndarray
    saddle: SaddleKinematics
    saddle_fit: object
    saddle_path: np.ndarray
    saddle_method: str = "pose"
    kinematics: str = "fits"
    pose: object = None
    pose_saddle: object = None
    pose_markers: object = None
    chain_error: str = ""
    pose_registration: object = None
    left_out: object = None
    model_choice: object = None
    basis_resolution: object = None

    @property
    def saddle_position(self) -> np.ndarray:
        """The saddle position passed on (n, 3): the pose trajectory's
        (``kinematics="pose_spline"``) or the path fitted by ``saddle_method``."""
        return self.pose_saddle.position if self.kinematics == "pose_spline" else self.saddle_path

    @property
    def saddle_velocity(self) -> np.ndarray:
        """The saddle velocity passed on (n, 3): the pose trajectory's, or chosen by ``saddle_method``."""
        if self.kinematics == "pose_spline":
            return self.pose_saddle.velocity
        return self.saddle.velocity if self.saddle_method == "thesis" else self.saddle_velocity_direct

    @property
    def saddle_acceleration(self) -> np.ndarray:
        """The saddle acceleration passed on (n, 3): the pose trajectory's, or chosen by ``saddle_method``."""
        if self.kinematics == "pose_spline":
            return self.pose_saddle.acceleration
        return self.saddle.acceleration if self.saddle_method == "thesis" else self.saddle_acceleration_direct

    @property
    def marker_kinematics(self):
        """Positions, velocities, accelerations (n, m, 3) of the markers passed on: the smoothed
        pose's (``kinematics="pose_spline"``) or the registered positions and the fits' derivatives."""
        if self.kinematics == "pose_spline":
            k = self.pose_markers
            return k.position, k.velocity, k.acceleration
        return self.pos, self.vel, self.acc

    @property
    def saddle_velocity_direct(self) -> np.ndarray:
        """Saddle velocity from :attr:`saddle_fit` (its path: ``saddle_method``), (n, 3)."""
        return self.saddle_fit.velocity(self.t)[:, 0]

    @property
    def saddle_acceleration_direct(self) -> np.ndarray:
        """Saddle acceleration from :attr:`saddle_fit` (its path: ``saddle_method``), (n, 3)."""
        return self.saddle_fit.acceleration(self.t)[:, 0]


@dataclass(frozen=True)
class FourierOrders:
    """Fourier orders of the thesis' chain given instead of chosen by the order rule (5.5.2.2).

    Attributes
    ----------
    markers : None, int or (m, 2) ints
        Orders (y, z) of each marker's fit (``orders`` of
        :func:`horsemocap.fitting.fit_motion`). A single int is one order for
        every fit of the chain: the markers', the orientation's and the saddle
        path's (unless ``rotation`` or ``saddle`` are given).
    rotation : None, int or (3,) ints
        Orders of the orientation's fit (:func:`fit_rotations`).
    saddle : None, int or (2,) ints
        Orders (y, z) of the saddle path's fit.

    Examples
    --------
    >>> FourierOrders(markers=3).rotation_orders().tolist()
    [3, 3, 3]
    >>> FourierOrders(markers=[[3, 2], [3, 2], [4, 2]]).rotation_orders() is None   # the order rule
    True
    """

    markers: object = None
    rotation: object = None
    saddle: object = None

    @classmethod
    def from_param(cls, given, n_markers: int) -> FourierOrders:
        """The orders a parameter file gives (``fits.fourier_orders`` of :class:`horsemocap.params.FitsParams`).

        Parameters
        ----------
        given : None, dict or list
            ``{"y": N, "z": N}`` (every marker; optionally ``"rotation"``: 3
            ints or one, ``"saddle"``: ``[Ny, Nz]`` or one), or ``[[Ny, Nz], ...]``
            one pair per marker; None (or a dict without ``"y"`` and ``"z"``
            for the markers): the order rule.
        n_markers : int

        Returns
        -------
        FourierOrders

        Raises
        ------
        ValueError
            Naming ``fourier_orders`` and the forms expected.

        Examples
        --------
        >>> o = FourierOrders.from_param({"y": 3, "z": 2, "rotation": 4}, 3)
        >>> o.markers.tolist(), o.rotation.tolist(), o.saddle
        ([[3, 2], [3, 2], [3, 2]], [4, 4, 4], None)
        """
        if given is None:
            return cls()
        if isinstance(given, dict):
            def extra(key, k):
                return None if given.get(key) is None else np.broadcast_to(np.asarray(given[key], int), (k,)).copy()

            markers = (np.tile([int(given["y"]), int(given["z"])], (n_markers, 1))
                       if "y" in given and "z" in given else None)
            return cls(markers, extra("rotation", 3), extra("saddle", 2))
        markers = np.asarray(given, int)
        if markers.shape != (n_markers, 2):
            raise ValueError(f"fourier_orders: expected {{'y': N, 'z': N}} or {n_markers} pairs [Ny, Nz], "
                             f"got {given!r}")
        return cls(markers)

    def rotation_orders(self):
        """Orders of :func:`fit_rotations`: ``rotation``, else ``markers`` if it is one int, else None (the rule)."""
        return self.rotation if self.rotation is not None else _uniform_orders(self.markers, 3)

    def saddle_orders(self):
        """Orders (y, z) of the saddle path's fit: ``saddle``, else ``markers`` if it is one int, else None."""
        return self.saddle if self.saddle is not None else _uniform_orders(self.markers, 2)


@dataclass(frozen=True)
class PoseInput:
    """The markers the pose trajectory is registered to, when they are not the analysed points.

    Attributes
    ----------
    points : (N, m, 3), optional
        The markers the pose trajectory is registered to (default: the
        analysed ``points``). Give the *unsmoothed* positions: the pose
        smoothing chooses its own smoothing from the data and the residuals,
        which an earlier smoothing would make correlated in time
        (cross-validation then undersmooths).
    t : (N,), optional
        Times of ``points`` when they cover more frames than the analysed
        ``t`` (a superset of it: frames beyond the analysed ones in which
        fewer markers are seen). The pose trajectory is smoothed over these
        times and evaluated at the analysed ones; everything else uses the
        analysed frames.
    covariance : (N, m, 3, 3), optional
        Each marker's covariance (m^2, motion frame) in the frames of
        ``points`` (e.g. the triangulation's, rotated into the motion frame):
        the pose is then registered with each marker weighted by its inverse
        covariance (:func:`horsemocap.pose.register_pose`), and the pose noise
        that the smoothing tests harmonics against comes from it. Not with
        ``weights``.
    weights : (m,) or (N, m), optional
        Marker weights (inverse variances) of the pose registration.
    settled : horsemocap.pose.SettledPoseSmoothing, optional
        The pose smoothing's choices settled on another record (``settled`` of
        :func:`horsemocap.pose.fit_pose_trajectory`); default: chosen here.
    aperture : horsemocap.aperture.Aperture, optional
        The frames' temporal aperture (the cameras' exposure, interlaced
        fields; :func:`horsemocap.aperture.session_aperture`) the pose
        trajectory is fitted through (``aperture`` of
        :func:`horsemocap.pose.fit_pose_trajectory`); default: none, each frame
        taken at its instant.

    Examples
    --------
    >>> PoseInput().points is None          # the analysed points, equal weights
    True
    """

    points: np.ndarray | None = None
    t: np.ndarray | None = None
    covariance: np.ndarray | None = None
    weights: np.ndarray | None = None
    settled: SettledPoseSmoothing | None = None
    aperture: Aperture | None = None


def analyse_rigid_body(t, points, static_points, params: RigidBodyParams = RigidBodyParams(), *,
                       period_s: float | None = None, fourier_orders: FourierOrders | None = None,
                       pose_input: PoseInput | None = None, static_index=None, smooth_span: float = 0.1,
                       fourier_start: str = "matlab", thesis_chain: bool = True) -> RigidBodyAnalysis:
    """Registration, fits, angular kinematics and the saddle in one call (the rigid-body step).

    The static shot is matched to the ride (:func:`match_static_markers`);
    its marker shape is the pose registration's model unless it is off the
    moving frames' mean shape by more than a frame's noise
    (:func:`choose_marker_model`; ``params.marker_model="static"`` keeps it
    always; the thesis' chain always uses the static shot); every frame's
    pose is registered (:func:`horsemocap.pose.register_pose`), and then, as
    ``params.kinematics`` asks, the smoothed pose trajectory
    (:func:`horsemocap.pose.fit_pose_trajectory`) and the thesis' chain
    (registration, fits, the six versions of omega and alpha, eq. 6.48-6.55)
    give the markers', the body's and the saddle's kinematics. A pose record
    longer than :data:`horsemocap.streaming.WHOLE_RECORD_FRAMES` frames (a
    long pass: a treadmill, a long straight) is smoothed in windows
    (:func:`horsemocap.pose_windows.windowed_pose_trajectory`: fitted whole,
    the spline's basis would be too coarse for its accelerations); ``pose``
    then says how (``pose.windows``). Every estimate is kept in the result.

    Parameters
    ----------
    t : (n,)
        Time (s), eq. 5.13.
    points : (n, m, 3), m >= 3
        Smoothed marker positions in the motion frame (``MM``). The thesis'
        chain takes three markers: with more, only the pose trajectory
        (registration over every marker seen in a frame) is computed, and
        ``kinematics="fits"`` is refused.
    static_points : (k, 3)
        Static-shot markers in the motion frame (the m skin markers and the
        saddle marker, any order).
    params : horsemocap.params.RigidBodyParams
        The step's choices (the module docstring, "The step's choices", says
        what each does); ``pose.weights`` is not read here (it is the
        caller's choice of ``pose_input.covariance``).
    period_s : float, optional
        Stride period (thesis ``period``); if given, every Fourier fit starts
        from ``w = 2 pi / period_s`` instead of MATLAB's spectral start point,
        and the pose smoothing takes it as the stride frequency another
        estimator found (``expected_fundamental_hz``).
    fourier_orders : FourierOrders, optional
        Orders of the chain's Fourier fits; default: those of
        ``params.fits.fourier_orders`` (:meth:`FourierOrders.from_param`;
        None there: the order rule for every fit).
    pose_input : PoseInput, optional
        The markers (times, covariances, weights) the pose trajectory is
        registered to; default: ``points``, equal weights.
    static_index : (3,) int, optional
        The static-shot correspondence (``static_points[static_index[j]]`` is
        marker j) instead of matching distances; needs ``params.saddle_marker``.
    smooth_span : float
        rloess span for the versions (Appendix A step 11).
    fourier_start : "matlab" or "all"
        ``start`` of every Fourier fit (:func:`horsemocap.fitting.fit_fourier`).
    thesis_chain : bool
        With ``kinematics="pose_spline"``: compute the thesis' chain beside the
        pose trajectory (False: the pose trajectory alone, as for a ride of
        other than three markers; nothing passed on depends on the chain).

    Returns
    -------
    RigidBodyAnalysis

    Raises
    ------
    ValueError
        A choice of ``params`` or an input array that cannot be used, named.
    horsemocap.pose.CollinearMarkersError
        The static shot's markers are collinear.

    Examples
    --------
    A body turning about the vertical (y) while it moves forward: the saddle,
    never seen during the ride, is found where the body carries it.

    >>> import numpy as np
    >>> from horsemocap.params import PoseParams, RigidBodyParams
    >>> from scipy.spatial.transform import Rotation
    >>> t = np.arange(50) / 25.0
    >>> body = np.array([[-0.3, 0.0, 0.0], [0.0, 0.05, 0.1], [0.3, 0.0, 0.0], [0.0, -0.2, 0.0]])
    >>> R = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * t), [0, 1, 0])).as_matrix()
    >>> moved = np.einsum("kij,mj->kmi", R, body) + np.outer(4 * t, [1, 0, 0])[:, None]
    >>> params = RigidBodyParams(pose=PoseParams(smoothing="none"))
    >>> res = analyse_rigid_body(t, moved[:, :3], body, params, period_s=1.0)
    >>> res.saddle_index, bool(np.allclose(res.saddle_position, moved[:, 3], atol=1e-9))
    (3, True)
    """
    _check_choices(params)
    t = np.asarray(t, float)
    pts = _marker_positions(points, t.size, params.kinematics)
    if fourier_orders is None:
        fourier_orders = FourierOrders.from_param(params.fits.fourier_orders, pts.shape[1])
    static = np.asarray(static_points, float)
    static_index, saddle_index = _static_correspondence(static, pts, static_index, params.saddle_marker)
    model = static[static_index]
    s_saddle = static[saddle_index]
    check_model_conditioning(model, name="static shot (the markers matched to the ride)")
    pose_input = PoseInput() if pose_input is None else pose_input
    ppts, pt, inside = _pose_frames(t, pts, pose_input)
    left_out = against_rigid_motion(ppts, model, pt)
    if left_out.any():
        ppts = np.where(left_out[..., None], np.nan, ppts)
    static_model = model
    model_choice = _marker_model_choice(ppts, static_model, params.marker_model)
    model = model_choice.model
    preg_all = register_pose(ppts, model, pose_input.weights, covariance=pose_input.covariance)
    preg = preg_all if pose_input.t is None else _registration_rows(preg_all, inside)
    common = dict(t=t, static_index=static_index, saddle_index=saddle_index, model=model, static_saddle=s_saddle,
                  method=params.fits.angular_method, saddle_method=params.fits.saddle_method,
                  kinematics=params.kinematics, pose_registration=preg, left_out=left_out,
                  model_choice=model_choice)
    # the thesis' chain (eq. 6.3-6.55) is written for the static shot's markers: never the mean shape
    chain_inputs = (t, pts, static_model, s_saddle, params.fits, fourier_orders, period_s, smooth_span,
                    fourier_start)
    if params.kinematics == "fits":
        chain = _thesis_chain(*chain_inputs)
        return RigidBodyAnalysis(**common, **chain, singularity_deg=singularity_angle(chain["pos"], chain["omega"]))
    def pose_trajectory():
        # a pass longer than a window's span loses its accelerations to the spline's basis fitted whole
        fit = windowed_pose_trajectory if pt.size > streaming.WHOLE_RECORD_FRAMES else fit_pose_trajectory
        return fit(pt, preg_all, model, params.pose, points=ppts, settled=pose_input.settled,
                   aperture=pose_input.aperture, expected_fundamental_hz=None if not period_s else 1.0 / period_s)

    skipped = None                       # why the chain is left out, if it is
    if pts.shape[1] != 3:
        skipped = f"it uses three markers (eq. 6.3-6.55); the ride has {pts.shape[1]}"
    elif not thesis_chain:
        skipped = "not asked for (thesis_chain False)"
    if skipped is None:
        # the chain needs nothing of the pose trajectory: a forked copy computes it meanwhile, where safe
        traj, chain = beside(pose_trajectory, lambda: _chain_or_error(chain_inputs))
    else:
        traj, chain = pose_trajectory(), None
    psaddle = traj.point(t, s_saddle)
    pmarkers = traj.points(t, model)
    # a record longer than a spline fits with a knot at every frame: does its basis hold the saddle's motion?
    resolution = basis_resolution(traj, preg_all, model, s_saddle, params.pose, points=ppts,
                                  aperture=pose_input.aperture, span=(int(inside[0]), int(inside[-1]) + 1))
    pose = dict(pose=traj, pose_saddle=psaddle, pose_markers=pmarkers, basis_resolution=resolution)
    if skipped is not None:
        return _pose_only(common, pose, pts, skipped)
    if isinstance(chain, Exception):
        return _pose_only(common, pose, pts, f"{type(chain).__name__}: {chain}")
    omega, alpha = traj.omega(t), traj.alpha(t)
    chain.update(omega=omega, alpha=alpha)
    return RigidBodyAnalysis(**common, **chain, **pose, singularity_deg=singularity_angle(chain["pos"], omega))


#: How far (in the marker's own robust noise scale) a marker's offset from the others' rigid pose may jump away
#: from its offset in the neighbouring frames before it is left out of the pose (a 3D normal error passes it
#: about once in ten million frames).
RIGID_MOTION_THRESHOLD = 6.0
#: Half-width (s) of the neighbouring frames whose median offset is the marker's expected one (a cover
#: shorter than the half-width's double is outvoted by the frames around it).
RIGID_MOTION_HALF_WINDOW_S = 0.5
#: Median of a chi distribution with three degrees of freedom (a 3D error's length over its per-axis sigma).
_CHI3_MEDIAN = 1.5382


def leave_one_out_offsets(points, model) -> np.ndarray:
    """Each marker's offset from the pose the other markers give, in the body (model) frame.

    For every frame and marker ``j`` the model is fitted (least squares,
    rotation and translation) to the other markers seen in that frame; the
    offset is the marker's measured position minus the fitted model's,
    rotated back into the model frame. A rigid marker set keeps every
    offset at the noise; a marker partly covered in the views that see it
    moves its centre against the others' rigid motion.

    Parameters
    ----------
    points : (n, m, 3) array
        The markers per frame (NaN where hidden), m >= 4.
    model : (m, 3) array
        The same markers in the model (static shot).

    Returns
    -------
    (n, m, 3) array
        NaN where the marker or fewer than three of the others are seen.

    Examples
    --------
    >>> model = np.array([[0., 0, 0], [0.3, 0, 0], [0, 0.2, 0], [0.1, 0.1, 0.15]])
    >>> R = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    >>> pts = np.stack([model @ R.T + 1.0, model @ R.T + 2.0])
    >>> pts[1, 3] += R @ [0.01, 0, 0]
    >>> np.round(leave_one_out_offsets(pts, model)[:, 3], 6) + 0.0
    array([[0.  , 0.  , 0.  ],
           [0.01, 0.  , 0.  ]])
    """
    return _leave_one_out(_as_positions("points", points), np.asarray(model, float))[0]


def _leave_one_out(pts, model) -> tuple[np.ndarray, np.ndarray]:
    """:func:`leave_one_out_offsets` and, per frame and marker ``j``, the rms residual (m) of the others' fit."""
    n, m = pts.shape[:2]
    seen = np.all(np.isfinite(pts), axis=2)
    x = np.nan_to_num(pts)
    out = np.full((n, m, 3), np.nan)
    others_rms = np.full((n, m), np.nan)
    for j in range(m):
        w = seen.copy()
        w[:, j] = False
        nw = w.sum(1)
        ok = (nw >= 3) & seen[:, j]
        if not ok.any():
            continue
        wf = w[ok].astype(float)[..., None]
        cx = (wf * x[ok]).sum(1) / nw[ok, None]
        cm = (wf * model[None]).sum(1) / nw[ok, None]
        H = np.einsum("kmi,kmj->kij", wf * (model[None] - cm[:, None]), x[ok] - cx[:, None])
        U, _, Vt = np.linalg.svd(H)
        d = np.sign(np.linalg.det(np.einsum("kji,klj->kil", Vt, U)))
        D = np.ones((len(d), 3))
        D[:, 2] = d
        R = np.einsum("kji,kj,klj->kil", Vt, D, U)          # model -> world: x = R (p - cm) + cx
        resid = x[ok, j] - cx - np.einsum("kij,kj->ki", R, model[j] - cm)
        out[ok, j] = np.einsum("kji,kj->ki", R, resid)
        fitted = cx[:, None] + np.einsum("kij,kmj->kmi", R, model[None] - cm[:, None])
        others_rms[ok, j] = np.sqrt((wf[..., 0] * np.sum((x[ok] - fitted) ** 2, axis=2)).sum(1) / nw[ok])
    return out, others_rms


def against_rigid_motion(points, model, t, threshold: float | None = None,
                         half_window_s: float | None = None) -> np.ndarray:
    """Markers that move against the other markers' rigid motion, per frame (four or more markers).

    A marker partly covered alike in every camera that sees it (a boot, a
    rein) triangulates consistently, its views agree, yet its centre moves
    against the others. Each marker's offset from the pose the others give
    (:func:`leave_one_out_offsets`) is compared with its median over the
    neighbouring frames (``half_window_s`` either side: skin motion and the
    static shot's own error stay in that median); the jump's length over the
    marker's robust noise scale (its median jump over the record, a chi
    distribution's with three degrees of freedom) above ``threshold`` marks
    it. One marker at most per frame, so that three or more others always
    keep the pose: the one whose removal leaves the others' fit to the model
    least above its usual residual (a wrong marker moves every other
    marker's leave-one-out offset too, a far one's most), marked when its
    own jump is above ``threshold``. With three markers the others cannot give a pose:
    nothing is marked.

    Parameters
    ----------
    points : (n, m, 3) array
    model : (m, 3) array
    t : (n,) array
        Times (s).
    threshold, half_window_s : float, optional
        Default :data:`RIGID_MOTION_THRESHOLD`, :data:`RIGID_MOTION_HALF_WINDOW_S`.

    Returns
    -------
    (n, m) bool array

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> model = np.array([[0., 0, 0], [0.3, 0, 0], [0, 0.2, 0], [0.1, 0.1, 0.15]])
    >>> t = np.arange(100) / 50.0
    >>> pts = model + np.outer(t, [2.0, 0, 0])[:, None] + rng.normal(0, 5e-4, (100, 4, 3))
    >>> pts[60:66, 2] += [0.0, 0.02, 0.0]
    >>> np.flatnonzero(against_rigid_motion(pts, model, t)[:, 2]).tolist()
    [60, 61, 62, 63, 64, 65]
    """
    pts = _as_positions("points", points)
    n, m = pts.shape[:2]
    flagged = np.zeros((n, m), bool)
    if m < 4 or n < 3:
        return flagged
    threshold = RIGID_MOTION_THRESHOLD if threshold is None else float(threshold)
    half_window_s = RIGID_MOTION_HALF_WINDOW_S if half_window_s is None else float(half_window_s)
    t = np.asarray(t, float)
    if t.shape != (n,):
        raise ValueError(f"t: expected {n} times (one per frame of points), got shape {t.shape}")
    dt = float(np.median(np.diff(t)))
    half = max(1, int(round(half_window_s / dt))) if dt > 0 else 1
    off, others_rms = _leave_one_out(pts, np.asarray(model, float))
    jump = np.linalg.norm(off - _running_nanmedian(off, half), axis=2)          # (n, m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)                         # a marker never seen: all-NaN
        scale = np.nanmedian(jump, axis=0) / _CHI3_MEDIAN
    score = jump / np.where(scale > 0, scale, np.nan)
    # which marker goes: the one whose removal leaves the others most rigid (their fit's residual the least
    # above its usual size) -- one wrong marker moves every other's leave-one-out offset too, far markers most
    excess = others_rms - _running_nanmedian(others_rms, half)
    finite = np.isfinite(score) & np.isfinite(excess)
    if not finite.any():
        return flagged
    culprit = np.argmin(np.where(finite, excess, np.inf), axis=1)
    rows = np.arange(n)
    flagged[rows, culprit] = finite[rows, culprit] & (score[rows, culprit] > threshold)
    return flagged


# --------------------------------------------------------------------------
# the marker model: the static shot's shape or the moving frames' mean shape

#: Significance level of the test that the static shot's marker shape differs from the moving frames' mean shape
#: by more than a frame's noise (:func:`choose_marker_model`).
MODEL_TEST_LEVEL = 0.01


@dataclass(frozen=True)
class ModelChoice:
    """The marker model the registration used, and why (:func:`choose_marker_model`).

    Attributes
    ----------
    model : (m, 3) array
        The model used (in the static shot's coordinates).
    source : str
        ``"static shot"`` or ``"moving frames"``.
    reason : str
        Why, in words.
    statistic, p_value : float
        Hotelling's T^2 of the static shot's shape against the moving frames'
        mean shape, and its p-value (NaN when the test could not be made).
    dof : int
        Degrees of freedom of the shape (3 m - 6).
    frames, effective_frames : int, float
        Frames with every marker seen, and as many independent ones as their
        noise's correlation over frames is worth.
    shift_m : (m,) array
        Distance of each marker of the mean shape from the static shot's, after
        the best rigid fit (m).
    """

    model: np.ndarray
    source: str
    reason: str
    statistic: float = float("nan")
    p_value: float = float("nan")
    dof: int = 0
    frames: int = 0
    effective_frames: float = 0.0
    shift_m: np.ndarray | None = None

    def to_dict(self) -> dict:
        """The choice for ``analysis.json`` (rounded; NaN as None).

        Examples
        --------
        >>> choice = ModelChoice(model=np.zeros((3, 3)), source="static shot", reason="too few frames", dof=3)
        >>> d = choice.to_dict()
        >>> d["source"], d["p_value"], d["dof"], d["shift_mm"]
        ('static shot', None, 3, None)
        """
        def num(x, d=6):
            return round(float(x), d) if np.isfinite(x) else None
        return {"source": self.source, "reason": self.reason, "hotelling_t2": num(self.statistic, 3),
                "p_value": num(self.p_value, 6), "test_level": MODEL_TEST_LEVEL, "dof": int(self.dof),
                "frames": int(self.frames), "effective_frames": num(self.effective_frames, 1),
                "shift_mm": None if self.shift_m is None else [num(1000 * s, 2) for s in self.shift_m]}


def _weighted_rigid_fit(model, x, w):
    """Per frame, the rotation ``R`` and centres with ``x ~ R (model - cm) + cx`` over the weighted markers
    (Horn's rotation, :func:`horsemocap.registration.rotation_from_cross_covariance`, of their cross-covariance).

    ``model`` (k, m, 3) or (m, 3), ``x`` (k, m, 3) with no NaN, ``w`` (k, m) weights (0 = not used).
    """
    model = np.broadcast_to(model, x.shape)
    wf = w[..., None]
    nw = w.sum(1)[:, None]
    cx = (wf * x).sum(1) / nw
    cm = (wf * model).sum(1) / nw
    H = np.einsum("kmi,kmj->kij", wf * (model - cm[:, None]), x - cx[:, None])
    return rotation_from_cross_covariance(H).as_matrix(), cm, cx


def body_coordinates(points, model) -> np.ndarray:
    """Each frame's markers in the model's coordinates: the model fitted to the frame, the frame moved back.

    Parameters
    ----------
    points : (n, m, 3) array
        Markers per frame (NaN where not seen).
    model : (m, 3) array

    Returns
    -------
    (n, m, 3) array
        NaN where a marker is not seen or fewer than three are.

    Examples
    --------
    >>> model = np.array([[0., 0, 0], [0.3, 0, 0], [0, 0.2, 0]])
    >>> R = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    >>> bool(np.allclose(body_coordinates((model @ R.T + 1.0)[None], model)[0], model))
    True
    """
    pts = _as_positions("points", points)
    model = np.asarray(model, float)
    seen = np.all(np.isfinite(pts), axis=2)
    ok = seen.sum(1) >= 3
    out = np.full(pts.shape, np.nan)
    if ok.any():
        x = np.nan_to_num(pts[ok])
        R, cm, cx = _weighted_rigid_fit(model, x, seen[ok].astype(float))
        body = np.einsum("kji,kmj->kmi", R, x - cx[:, None]) + cm[:, None]
        out[ok] = np.where(seen[ok][..., None], body, np.nan)
    return out


def mean_marker_shape(points, model, iterations: int = 50, tol_m: float = 1e-9):
    """The markers' mean shape over the frames (generalised Procrustes analysis), in the model's coordinates.

    Each frame is fitted by the current shape and moved back into its
    coordinates (:func:`body_coordinates`); their mean over the frames is the
    next shape, fitted back onto ``model`` (so that it keeps the model's
    place and orientation, and a point known in the model's coordinates --
    the saddle -- keeps its meaning). Per-frame noise averages out over the
    frames.

    Parameters
    ----------
    points : (n, m, 3) array
        Markers per frame (NaN where not seen).
    model : (m, 3) array
        The starting shape (the static shot's markers).

    Returns
    -------
    shape : (m, 3) array
    body : (n, m, 3) array
        Each frame's markers in the shape's coordinates (NaN where not seen).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> true = np.array([[0., 0, 0], [0.3, 0, 0], [0, 0.2, 0], [0.1, 0.1, 0.15]])
    >>> R = Rotation.from_rotvec(rng.normal(0, 0.3, (400, 3))).as_matrix()
    >>> pts = np.einsum("kij,mj->kmi", R, true) + rng.normal(0, 1e-3, (400, 4, 3))
    >>> shape, _ = mean_marker_shape(pts, true + rng.normal(0, 5e-3, (4, 3)))
    >>> float(np.abs(pairwise_distances(shape) - pairwise_distances(true)).max()) < 3e-4
    True
    """
    model = np.asarray(model, float)
    shape = model
    for _ in range(iterations):
        body = body_coordinates(points, shape)
        if not np.isfinite(body).any():
            return shape, body
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)               # a marker never seen: NaN
            mean = np.nanmean(body, axis=0)
        if not np.all(np.isfinite(mean)):
            return shape, body
        R, cm, cx = _weighted_rigid_fit(mean[None], model[None], np.ones((1, len(model))))
        new = (mean - cm[0]) @ R[0].T + cx[0]
        step = float(np.abs(new - shape).max())
        shape = new
        if step < tol_m:
            break
    return shape, body_coordinates(points, shape)


def _lag1_correlation(resid) -> float:
    """Mean lag-1 autocorrelation over the components of (n, k) residual series (consecutive rows), >= 0."""
    r = np.asarray(resid, float)
    if len(r) < 3:
        return 0.0
    r = r - r.mean(0)
    num = np.sum(r[1:] * r[:-1], axis=0)
    den = np.sum(r * r, axis=0)
    rho = num[den > 0] / den[den > 0]
    return float(np.clip(np.mean(rho), 0.0, 0.99)) if rho.size else 0.0


def choose_marker_model(points, static_model, level: float = MODEL_TEST_LEVEL) -> ModelChoice:
    """The static shot's marker shape, or the moving frames' mean shape when the static shot's is off.

    The static shot is one still per camera: its markers carry one frame's
    centroid noise and biases, never averaged. The moving frames' mean shape
    (:func:`mean_marker_shape`) averages many frames' noise. The static shot
    is kept unless it differs from that mean shape by more than a single
    frame's noise explains: with ``e_k`` the frames' deviations from the mean
    shape (every marker seen, in the shape's coordinates; rank 3 m - 6 after
    the rigid fit) and ``d`` the static shot's, Hotelling's
    ``T^2 = d^T (S (1 + 1/n_e))^+ d`` with ``S`` the frames' covariance and
    ``n_e = n (1 - rho) / (1 + rho)`` the independent frames their lag-1
    autocorrelation ``rho`` leaves; ``T^2 (n_e - r) / (r (n_e - 1))`` is
    F(r, n_e - r) when the static shot is a frame like the others. Below
    ``level`` the mean shape is used.

    Parameters
    ----------
    points : (n, m, 3) array
        The ride's markers per frame (unsmoothed; NaN where not seen).
    static_model : (m, 3) array
        The static shot's markers, in the same order.
    level : float
        Significance level of the test.

    Returns
    -------
    ModelChoice

    Examples
    --------
    >>> rng = np.random.default_rng(2)
    >>> true = np.array([[0., 0, 0], [0.3, 0, 0], [0, 0.2, 0], [0.1, 0.1, 0.15]])
    >>> R = Rotation.from_rotvec(rng.normal(0, 0.3, (300, 3))).as_matrix()
    >>> pts = np.einsum("kij,mj->kmi", R, true) + rng.normal(0, 1e-3, (300, 4, 3))
    >>> choose_marker_model(pts, true + rng.normal(0, 1e-3, (4, 3))).source
    'static shot'
    >>> off = true.copy(); off[3, 2] += 0.01
    >>> choice = choose_marker_model(pts, off)
    >>> choice.source, float(np.round(choice.shift_m[3], 2))
    ('moving frames', 0.01)
    """
    static_model = np.asarray(static_model, float)
    m = len(static_model)
    shape, body = mean_marker_shape(points, static_model)
    complete = np.all(np.isfinite(body), axis=(1, 2))
    n, r = int(complete.sum()), 3 * m - 6
    keep = ModelChoice(model=static_model, source="static shot", reason="", dof=r, frames=n)
    if n < r + 3:
        return replace(keep, reason=f"{n} frames with every marker seen: too few to measure the noise of the "
                                    "markers' shape")
    e = (body[complete] - shape).reshape(n, 3 * m)
    rho = _lag1_correlation(e)
    n_eff = n * (1 - rho) / (1 + rho)
    d = (body_coordinates(static_model[None], shape)[0] - shape).reshape(3 * m)
    shift = np.linalg.norm(d.reshape(m, 3), axis=1)
    keep = replace(keep, effective_frames=n_eff, shift_m=shift)
    if n_eff < r + 2:
        return replace(keep, reason=f"{n} frames with every marker seen, worth {n_eff:.1f} independent ones "
                                    f"(lag-1 correlation {rho:.2f}): too few to test the static shot's shape")
    cov = np.cov(e, rowvar=False) * (1 + 1 / n_eff)
    t2 = float(d @ np.linalg.pinv(cov, rcond=1e-10, hermitian=True) @ d)
    f = t2 * (n_eff - r) / (r * (n_eff - 1))
    p = float(f_survival(f, r, n_eff - r))
    what = (f"the static shot's marker shape is {1000 * shift.max():.1f} mm (largest) from the mean shape of {n} "
            f"moving frames (worth {n_eff:.0f} independent ones), Hotelling T^2 {t2:.1f} on {r} degrees of "
            f"freedom, p = {p:.2g}")
    if p < level:
        return replace(keep, model=shape, source="moving frames", statistic=t2, p_value=p,
                       reason=f"{what} < {level:g}: more than a frame's noise, so the static shot's noise or "
                              "biases are not averaged; the moving frames' mean shape is used, the saddle "
                              "placed by fitting the static shot's markers to it")
    return replace(keep, statistic=t2, p_value=p, reason=f"{what} >= {level:g}: within a frame's noise")


def _running_nanmedian(a, half: int) -> np.ndarray:
    """Median over frames ``k - half .. k + half`` (NaN ignored) of an (n, ...) array, frame by frame."""
    a = np.asarray(a, float)
    n = a.shape[0]
    pad = np.concatenate([np.full((half,) + a.shape[1:], np.nan), a, np.full((half,) + a.shape[1:], np.nan)])
    out = np.empty_like(a)
    step = max(1, 2_000_000 // max(1, (2 * half + 1) * int(np.prod(a.shape[1:]))))   # bounded memory
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)                          # windows with no value: NaN
        for s in range(0, n, step):
            e = min(n, s + step)
            win = np.lib.stride_tricks.sliding_window_view(pad[s:e + 2 * half], 2 * half + 1, axis=0)
            out[s:e] = np.nanmedian(win, axis=-1)
    return out


def _marker_model_choice(points, static_model, marker_model: str) -> ModelChoice:
    """:func:`choose_marker_model`'s choice (``"auto"``), or the static shot's shape when ``"static"`` is asked
    for (the test still made and reported, its choice not taken)."""
    choice = choose_marker_model(points, static_model)
    if marker_model == "auto" or choice.source == "static shot":
        return choice
    return replace(choice, model=np.asarray(static_model, float), source="static shot",
                   reason=f"asked for (rigid_body.marker_model 'static'); the test would have used the moving "
                          f"frames' mean shape: {choice.reason}")


def _check_choices(params: RigidBodyParams) -> None:
    """Refuse a choice of the section that :func:`analyse_rigid_body` does not know, naming the field."""
    fits = params.fits
    if fits.angular_method not in ("thesis", "lstsq", "rotation"):
        raise ValueError(f"fits.angular_method: expected 'thesis', 'lstsq' or 'rotation', got {fits.angular_method!r}")
    if fits.saddle_method not in ("thesis", "direct", "pose"):
        raise ValueError(f"fits.saddle_method: expected 'thesis', 'direct' or 'pose', got {fits.saddle_method!r}")
    if params.kinematics not in ("fits", "pose_spline"):
        raise ValueError(f"kinematics: expected 'fits' or 'pose_spline', got {params.kinematics!r}")
    if params.marker_model not in ("auto", "static"):
        raise ValueError(f"marker_model: expected 'auto' or 'static', got {params.marker_model!r}")
    events = params.pose.events
    if events is not None and len(events) and params.kinematics != "pose_spline":
        raise ValueError(f"pose.events: change points are a 'pose_spline' option, got kinematics={params.kinematics!r}")


def _marker_positions(points, n_frames: int, kinematics: str) -> np.ndarray:
    """The ride's markers (n, m, 3), m >= 3; the thesis' chain (``kinematics="fits"``) takes exactly three."""
    pts = _as_positions("points", points)
    if pts.shape[0] != n_frames:
        raise ValueError(f"points: expected {n_frames} frames, got {pts.shape[0]}")
    if pts.shape[1] < 3:
        raise ValueError(f"points: expected 3 or more markers on axis 1 (a pose needs three), got {pts.shape[1]}")
    if pts.shape[1] != 3 and kinematics == "fits":
        raise ValueError(f"kinematics: 'fits' is the thesis' chain of three markers (eq. 6.3-6.55), the ride has "
                         f"{pts.shape[1]}; use kinematics 'pose_spline' (registration over all the markers seen)")
    return pts


def _static_correspondence(static, pts, static_index, saddle_marker) -> tuple[np.ndarray, int]:
    """``(static_index, saddle_index)``: given, or matched by :func:`match_static_markers`."""
    if static_index is None:
        static_index, saddle_marker = match_static_markers(static, pts, saddle=saddle_marker)
    elif saddle_marker is None:
        raise ValueError("static_index given without saddle_marker: name the saddle marker too")
    return np.asarray(static_index, int), int(saddle_marker)


def _pose_frames(t, pts, pose_input: PoseInput):
    """The pose's markers and times (checked), and where the analysed times sit among them."""
    ppts = pts if pose_input.points is None else _as_positions("pose_input.points", pose_input.points,
                                                               pts.shape[1])
    pt = t if pose_input.t is None else np.asarray(pose_input.t, float)
    if ppts.shape[0] != pt.size:
        raise ValueError(f"pose_input.points: expected {pt.size} frames, got {ppts.shape[0]}")
    inside = np.searchsorted(pt, t - 1e-9)
    if pose_input.t is not None and (np.any(inside >= pt.size)
                                     or not np.allclose(pt[np.minimum(inside, pt.size - 1)], t)):
        raise ValueError("pose_input.t: expected every time of t among the pose frames' times")
    cov = pose_input.covariance
    if cov is not None and np.shape(cov) != ppts.shape + (3,):
        raise ValueError(f"pose_input.covariance: expected {ppts.shape + (3,)} (the pose frames' markers, 3, 3), "
                         f"got {np.shape(cov)}")
    return ppts, pt, inside


def _registration_rows(reg: PoseRegistration, rows) -> PoseRegistration:
    """A :class:`~horsemocap.pose.PoseRegistration` of some frames only (same noise estimate)."""
    per_frame = {f.name: getattr(reg, f.name)[rows] for f in fields(reg)
                 if isinstance(getattr(reg, f.name), np.ndarray)}
    return replace(reg, **per_frame)


def _pose_only(common: dict, pose: dict, pts, chain_error: str) -> RigidBodyAnalysis:
    """A :class:`RigidBodyAnalysis` holding only the pose trajectory (the thesis chain failed)."""
    t, model, s_saddle = common["t"], common["model"], common["static_saddle"]
    traj: PoseTrajectory = pose["pose"]
    n = t.size
    nan3 = np.full((n, 3), np.nan)
    nan6 = np.full((6, n, 3), np.nan)
    reg = register(pts, model)
    omega, alpha = traj.omega(t), traj.alpha(t)
    sk = SaddleKinematics(nan3, np.full((3, n, 3), np.nan), np.full((3, n, 3), np.nan),
                          np.full((3, n, 3), np.nan), nan3, nan3)
    return RigidBodyAnalysis(**{**common, "kinematics": "pose_spline"}, **pose, registration=reg, motion_fit=None,
                             pos=reg.registered, vel=np.full(pts.shape, np.nan), acc=np.full(pts.shape, np.nan),
                             omega_raw=nan6, omega_versions=nan6, alpha_raw=nan6, alpha_versions=nan6,
                             omega_lstsq=nan3, alpha_lstsq=nan3, omega=omega, alpha=alpha, rotation_fit=None,
                             omega_rotation=nan3, alpha_rotation=nan3, omega_use=np.ones(6, bool),
                             alpha_use=np.ones(6, bool),
                             singularity_deg=singularity_angle(pose["pose_markers"].position[:, :3], omega),
                             saddle_body=saddle_in_body_versions(model[:3], s_saddle), saddle=sk, saddle_fit=None,
                             saddle_path=pose["pose_saddle"].position, chain_error=chain_error)


def _uniform_orders(orders, k):
    """``orders`` as k equal ints if it is a single int (one order for every fit), else None."""
    if orders is None or np.ndim(orders) != 0:
        return None
    return np.full(k, int(orders))


def _chain_or_error(chain_inputs):
    """:func:`_thesis_chain` of ``chain_inputs``, or the ``ValueError`` / ``LinAlgError`` it raised (the chain
    then left out, the pose trajectory kept)."""
    try:
        return _thesis_chain(*chain_inputs)
    except (ValueError, np.linalg.LinAlgError) as exc:
        return exc


def _thesis_chain(t, pts, model, s_saddle, fits: FitsParams, orders: FourierOrders, period_s, smooth_span,
                  start) -> dict:
    """The thesis' chain (sections 5.4-5.5, 6): registration, fits, versions, eq. 6.48-6.55.

    Returns the fields of :class:`RigidBodyAnalysis` it fills, by name.
    """
    reg = register(pts, model)
    pos = reg.registered
    ok = np.all(np.isfinite(pos), axis=(1, 2))
    w0 = None if period_s is None else 2 * np.pi / period_s
    mf = fitting.fit_motion(t, np.where(ok[:, None, None], pos, np.nan), x_degree=fits.x_degree,
                            orders=orders.markers, rule=fits.order_rule, w0=w0, start=start, trend=fits.trend)
    vel, acc = mf.velocity(t), mf.acceleration(t)
    vel[~ok] = np.nan
    acc[~ok] = np.nan
    angular = _angular_chain(t, pos, vel, acc, reg.rotation, fits, orders.rotation_orders(), w0, smooth_span, start)
    sb = saddle_in_body_versions(model, s_saddle)
    sk = saddle_kinematics(pos, vel, acc, angular["omega"], angular["alpha"], sb)
    path = (chain_saddle_path(t, pos, model, s_saddle, angular["rotation_fit"])
            if fits.saddle_method == "pose" else sk.position)
    s_orders = orders.saddle_orders()
    sfit = fitting.fit_motion(t, np.where(ok[:, None], path, np.nan)[:, None, :], x_degree=fits.x_degree,
                              orders=None if s_orders is None else np.asarray(s_orders, int)[None],
                              rule=fits.order_rule, w0=w0, start=start, trend=fits.trend)
    return dict(registration=reg, motion_fit=mf, pos=pos, vel=vel, acc=acc, **angular, saddle_body=sb, saddle=sk,
                saddle_fit=sfit, saddle_path=path)


def chain_saddle_path(t, pos, model, static_saddle, rotation_fit: RotationFit) -> np.ndarray:
    """The saddle path (n, 3) the chain fits with ``saddle_method="pose"``: the fitted orientation and the markers'
    centroid, ``p_S = R_fit(t) (s - mean(model)) + mean_m r_m(t)`` (NaN where a marker is not registered); with
    ``"direct"`` the path is eq. 6.48 with the per-frame pose (:func:`saddle_position`).

    Examples
    --------
    A fixed orientation, the markers moving forward at 4 m/s: the saddle goes with them.

    >>> import numpy as np
    >>> t = np.arange(40) / 25.0
    >>> model = np.array([[-0.3, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.1, 0.05]])
    >>> fit = fit_rotations(t, np.repeat(np.eye(3)[None], 40, 0), orders=1, w0=2 * np.pi)
    >>> pos = model + np.outer(4 * t, [1, 0, 0])[:, None]
    >>> chain_saddle_path(t, pos, model, [0.0, 0.3, 0.0], fit)[-1].round(6)
    array([6.24, 0.3 , 0.  ])
    """
    pos = np.asarray(pos, float)
    ok = np.all(np.isfinite(pos), axis=(1, 2))
    lever = np.asarray(static_saddle, float) - np.asarray(model, float).mean(0)
    return (np.einsum("kij,j->ki", rotation_fit.rotation(t), lever)
            + np.where(ok[:, None], pos.mean(1), np.nan))


def _angular_chain(t, pos, vel, acc, rotation, fits: FitsParams, rotation_orders, w0, smooth_span, start) -> dict:
    """Omega and alpha of the chain: the six versions, least squares, the orientation's fit, and the chosen ones."""
    w_use = np.ones(6, bool) if fits.omega_versions is None else np.asarray(fits.omega_versions, bool)
    a_use = np.ones(6, bool) if fits.alpha_versions is None else np.asarray(fits.alpha_versions, bool)
    with np.errstate(all="ignore"):
        w_raw = angular_velocity_versions(pos, vel)
    w_s = smooth_versions(w_raw, span=smooth_span)
    w_ls = angular_velocity_lstsq(pos, vel)
    w_ls_s = smooth_versions(w_ls[None], span=smooth_span)[0]
    rfit = fit_rotations(t, rotation, orders=rotation_orders, rule=fits.order_rule, w0=w0, start=start)
    w_rot, a_rot = rfit.omega(t), rfit.alpha(t)
    omega = {"thesis": average_versions(w_s, w_use) if w_use.any() else w_ls_s,
             "lstsq": w_ls_s, "rotation": w_rot}[fits.angular_method]
    with np.errstate(all="ignore"):
        a_raw = angular_acceleration_versions(pos, vel, acc, omega)
    a_s = smooth_versions(a_raw, span=smooth_span)
    a_ls = angular_acceleration_lstsq(pos, acc, omega)
    a_ls_s = smooth_versions(a_ls[None], span=smooth_span)[0]
    alpha = {"thesis": average_versions(a_s, a_use), "lstsq": a_ls_s, "rotation": a_rot}[fits.angular_method]
    return dict(omega_raw=w_raw, omega_versions=w_s, alpha_raw=a_raw, alpha_versions=a_s, omega_lstsq=w_ls_s,
                alpha_lstsq=a_ls_s, omega=omega, alpha=alpha, rotation_fit=rfit, omega_rotation=w_rot,
                alpha_rotation=a_rot, omega_use=w_use, alpha_use=a_use)


# --------------------------------------------------------------------------
# how far the step's results can be trusted
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Conditioning:
    """Per-frame conditioning of a :class:`RigidBodyAnalysis` (:func:`conditioning`).

    Attributes
    ----------
    singularity_deg : (n,)
        Eq. 6.35: the angle between the omega passed on and the markers'
        plane normal (the thesis versions fail near 90 degrees).
    triangle_height_m : (n,)
        Smallest height of the marker triangle used by each frame's pose
        (:func:`horsemocap.pose.smallest_height`); NaN where fewer than 3 markers.
    registration_rms_m : (n,)
        RMS distance of the markers from the registered model.
    registration_n_markers : (n,) int
        Markers registered in each frame.
    noise_m : float
        Marker noise estimated from the registration residuals.
    warnings : list of str
        Messages when these make the result unreliable.
    """

    singularity_deg: np.ndarray
    triangle_height_m: np.ndarray
    registration_rms_m: np.ndarray
    registration_n_markers: np.ndarray
    noise_m: float
    warnings: list


def conditioning(analysis: RigidBodyAnalysis) -> Conditioning:
    """How well the marker geometry and the motion condition the step's results, frame by frame.

    The eq. 6.35 angle of the omega passed on (of the pose trajectory's
    markers with ``kinematics="pose_spline"``), the marker triangle's
    smallest height, the registration residual, and the warnings of
    :func:`horsemocap.pose.conditioning_warnings` (a thin triangle: the
    rotation about its long side is noisy, and the saddle far from the
    markers moves with it); with the thesis' own chain
    (``kinematics="fits"``, ``angular_method="thesis"``) also a warning when
    omega comes within 15 degrees of the markers' plane
    (:func:`singularity_report`).

    Parameters
    ----------
    analysis : RigidBodyAnalysis

    Returns
    -------
    Conditioning

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.params import PoseParams, RigidBodyParams
    >>> from scipy.spatial.transform import Rotation
    >>> t = np.arange(50) / 25.0
    >>> body = np.array([[-0.3, 0.0, 0.0], [0.0, 0.05, 0.1], [0.3, 0.0, 0.0], [0.0, -0.2, 0.0]])
    >>> R = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * t), [0, 1, 0])).as_matrix()
    >>> moved = np.einsum("kij,mj->kmi", R, body) + np.outer(4 * t, [1, 0, 0])[:, None]
    >>> res = analyse_rigid_body(t, moved[:, :3], body, RigidBodyParams(pose=PoseParams(smoothing="none")))
    >>> cond = conditioning(res)
    >>> cond.registration_n_markers[:3].tolist(), cond.warnings
    ([3, 3, 3], [])
    """
    rb = analysis
    preg = rb.pose_registration
    k = rb.pose_markers.position if rb.pose_markers is not None else rb.registration.registered
    sing = singularity_angle(k[:, :3], rb.omega)
    height = preg.height.copy()
    height[preg.n_markers < 3] = np.nan
    lever = float(np.linalg.norm(rb.static_saddle - rb.model.mean(0)))
    warn = conditioning_warnings(preg, lever)
    if rb.kinematics == "fits" and rb.method == "thesis":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rep = singularity_report(sing, warn=False)
        if rep["fraction"] > 0:
            warn.append(f"omega within 15 deg of the markers' plane in {100 * rep['fraction']:.0f} % of the frames "
                        f"(closest {rep['min_margin_deg']:.1f} deg): the thesis versions (eq. 6.3/6.4, 6.38/6.39) "
                        "are unreliable there (eq. 6.35); use kinematics 'pose_spline'")
    return Conditioning(singularity_deg=sing, triangle_height_m=height, registration_rms_m=preg.rms,
                        registration_n_markers=preg.n_markers, noise_m=preg.noise_m, warnings=warn)


def saddle_angles(analysis: RigidBodyAnalysis) -> np.ndarray:
    """Roll, pitch, yaw (deg) of the saddle in the motion frame, per frame (n, 3).

    Body axes from the static shot (:func:`horsemocap.pose.static_body_axes`:
    as seed 004 takes body planes from a default pose), then rotated by the
    body's pose in each frame: the smoothed pose trajectory's when there is
    one, else the per-frame registration's
    (:func:`horsemocap.pose.saddle_angles_deg`).

    Parameters
    ----------
    analysis : RigidBodyAnalysis

    Returns
    -------
    (n, 3) ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.params import PoseParams, RigidBodyParams
    >>> from scipy.spatial.transform import Rotation
    >>> t = np.arange(50) / 25.0
    >>> body = np.array([[-0.3, 0.0, 0.0], [0.0, 0.05, 0.1], [0.3, 0.0, 0.0], [0.0, -0.2, 0.0]])
    >>> yaw = 0.1 * np.sin(2 * np.pi * t)
    >>> R = Rotation.from_rotvec(np.outer(yaw, [0, 1, 0])).as_matrix()
    >>> moved = np.einsum("kij,mj->kmi", R, body) + np.outer(4 * t, [1, 0, 0])[:, None]
    >>> res = analyse_rigid_body(t, moved[:, :3], body, RigidBodyParams(pose=PoseParams(smoothing="none")))
    >>> bool(np.allclose(saddle_angles(res)[:, 2], np.degrees(yaw), atol=1e-6))
    True
    """
    rb = analysis
    axes0 = static_body_axes(np.vstack([rb.model, rb.static_saddle]))
    R = rb.pose.rotation(rb.t) if rb.pose is not None else rb.registration.rotation
    return saddle_angles_deg(R, axes0)
