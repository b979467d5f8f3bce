"""How uncertain the saddle's vertical acceleration is, from what the run itself measured.

The static shot (:func:`static_shot_uncertainty`)
    The saddle's point is placed once, in a single still per camera: one draw of the detection noise, the
    same offset in every frame. Its pixel noise (measured on the moving frames) goes through the cameras'
    Jacobians to each still point's covariance (:func:`still_point_covariance`), through the linear map
    from the still's errors to the saddle's offset from the markers' rigid fit (:func:`saddle_offset_map`),
    and through the chain that wrote the saddle's acceleration, run on unit offsets of the saddle point
    (:func:`written_saddle_sensitivity`), to every frame's acceleration: exact where the chain is linear in
    that point (the pose trajectory; the thesis' eq. 6.55), to first order where it fits the saddle's path
    again (a Fourier series with a fitted frequency). For a body carried by a rotation ``R`` the map is
    ``([alpha]x + [omega]x^2) R`` (:func:`saddle_acceleration_sensitivity`); :func:`weighted_rms_sd_pct`
    gives the offset's share of a frequency-weighted rms.

The moving frames' noise at the saddle (:func:`saddle_scatter`)
    Each frame's registration carries the saddle as the markers place it in that frame alone; the written
    trajectory is the smoothing's. Their difference is the frame-to-frame noise the markers carry to the
    saddle (a thin triangle's tilt swings a far saddle point), correlated over frames or not, plus any motion
    the smoothing took for noise. Against the saddle's own vertical motion it says whether the record
    resolves that motion at all: when the scatter is as large as the motion, the acceleration is the
    smoothing's guess more than a measurement, whatever criterion chose the smoothing.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import fitting
from .reconstruction import point_covariance
from .rigid import (RigidBodyAnalysis, chain_saddle_path, saddle_in_body, saddle_in_body_versions,
                    saddle_kinematics, saddle_position)
from .vibration import fft_weighting

#: Condition number of the markers' second-moment matrix (:func:`saddle_offset_map`) above which the markers are
#: taken as collinear: inverting it would keep fewer than 4 of float64's 16 significant digits. Its condition
#: grows as (length / height)^2 of a thin triangle, so this is a triangle of 0.7 m about 1 um high: a degenerate
#: still, not a thin triangle (those are the rigid-body step's conditioning warnings).
COLLINEAR_CONDITION = 1e12
#: Fewest consecutive finite frames for a weighted rms's share (:func:`weighted_rms_sd_pct`): the weighting is
#: applied by the DFT over those frames, and fewer than 8 resolve at most four frequencies, too few for a
#: weighting curve to shape.
MIN_WEIGHTED_FRAMES = 8
#: Half the step (m) of the central difference through a fitted saddle path (:func:`written_saddle_sensitivity`):
#: a millimetre, the size of the static shot's errors, so the difference is the fit's response to such an
#: error; the fit's frequency search stops at a relative change of 1e-6, far below what a millimetre moves it.
FIT_STEP_M = 1e-3


class StaticShotRefused(ValueError):
    """The static shot gives no figure to carry: markers collinear, a point not finite or seen by fewer than
    two cameras, or no frame with a finite sensitivity and acceleration (the check is skipped with this reason).

    Examples
    --------
    >>> issubclass(StaticShotRefused, ValueError)
    True
    """


# ---------------------------------------------------------------------------
# the static shot's uncertainty carried to the saddle's acceleration
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class StaticShotUncertainty:
    """How far the static shot's pixel noise may move the saddle's acceleration.

    Attributes
    ----------
    noise_px : float
        The detection noise per image coordinate the still is taken to carry (px).
    offset_covariance : (3, 3) array
        Covariance (m^2, motion frame of the static shot) of the saddle's point relative to the markers' rigid
        fit: the offset every frame's saddle carries.
    offset_sd_m : (3,) array
        Its standard deviations.
    acceleration_sd : (n,) array
        Standard deviation of the saddle's vertical acceleration per frame (m/s^2) that offset causes.
    sd : float
        Its rms over the frames (m/s^2): the expected rms error of the vertical acceleration from the still.
    rms : float
        The vertical acceleration's rms (m/s^2, the values the error is relative to).
    pct_of_rms : float
        ``sd`` as a percentage of ``rms``.
    weighted_pct : dict
        Weighting name (``Wb``, ``Wk``) -> standard deviation (%) of the weighted rms that offset causes,
        to first order (:func:`weighted_rms_sd_pct`); empty without a sampling rate.
    independent_frames : float
        The independent frames the static shot's points are the mean of (1: one still per camera; a clip
        averaged, :func:`horsemocap.steps.stills.effective_frame_count`): the pixel noise's variance is
        divided by it.
    """

    noise_px: float
    offset_covariance: np.ndarray
    offset_sd_m: np.ndarray
    acceleration_sd: np.ndarray
    sd: float
    rms: float
    pct_of_rms: float
    weighted_pct: dict
    independent_frames: float = 1.0


def still_point_covariance(rig, points_world, noise_px: float, seen: dict | None = None) -> np.ndarray:
    """Covariance (k, 3, 3) (m^2, world frame) of the k points of one still.

    The still is a single image per camera, one draw of the detection noise: each point's covariance is
    ``noise_px^2 (J^T J)^-1`` with ``J`` the Jacobian of its pixels in the cameras that saw it
    (:func:`horsemocap.reconstruction.point_covariance`), nothing averaged. ``seen``: camera -> (k,) bool,
    which points each camera saw (default: every camera of ``rig`` every point); a point seen by fewer than
    two cameras gets NaN.

    Examples
    --------
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> rig = Rig((Camera("left", (640, 480), K), Camera("right", (640, 480), K, translation=[-0.5, 0, 0])))
    >>> cov = still_point_covariance(rig, np.array([[0.0, 0.0, 2.0]]), 0.5)
    >>> np.sqrt(np.diag(cov[0])).round(4)          # depth, along the rays, the least certain
    array([0.0012, 0.0009, 0.0071])
    """
    pts = np.asarray(points_world, float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points_world: expected (k, 3), got {pts.shape}")
    if not (np.isfinite(noise_px) and noise_px >= 0):
        raise ValueError(f"noise_px: expected a finite pixel noise >= 0, got {noise_px!r}")
    if seen is None:
        seen = {c: np.ones(len(pts), bool) for c in rig.names}
    used = {}
    for c in rig.names:
        mask = np.asarray(seen.get(c, np.zeros(len(pts), bool)), bool)
        if mask.shape != (len(pts),):
            raise ValueError(f"seen[{c!r}]: expected ({len(pts)},) booleans, one per point, got {mask.shape}")
        used[c] = mask[None]
    return point_covariance(rig, pts[None], used, noise_px)[0]


def saddle_offset_map(markers, saddle) -> np.ndarray:
    """The linear map (3, 3 (m + 1)) from the static shot's errors to the saddle's offset from the markers.

    The saddle is seen only in the static shot, placed relative to its m markers; every frame's pose is the
    markers' rigid fit, so an error ``d_i`` of the static markers moves the body frame by the rigid motion
    that fits them best (a translation ``dc``, the mean error, and a small rotation ``dtheta``, least
    squares of ``d_i - dc - dtheta x p_i`` with ``p_i`` the markers about their centroid), and an error
    ``d_s`` of the saddle point stays in it. The saddle's offset in the body frame is
    ``d_s - dc - dtheta x q``, ``q`` the saddle about the markers' centroid: a thin marker triangle tilted
    about its long axis swings a far saddle point. The error vector is ordered as the markers' errors
    (x, y, z each), then the saddle's.

    Examples
    --------
    A triangle 0.1 m high, the saddle 0.3 m from its long axis; the two end markers moved 1 mm along y
    (the third stays) turn the triangle 0.01 rad about that axis, and the saddle, seen only in the still,
    ends 3 mm off across and 1 mm along:

    >>> markers = np.array([[-0.3, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.0, 0.1]])
    >>> L = saddle_offset_map(markers, [0.0, 0.3, 0.0])
    >>> d = np.zeros(12); d[1] = d[4] = 1e-3     # markers 0 and 1 moved 1 mm along y
    >>> (1000 * L @ d).round(2)
    array([ 0., -1., -3.])
    """
    m = np.asarray(markers, float)
    s = np.asarray(saddle, float)
    if m.ndim != 2 or m.shape[1] != 3 or len(m) < 3 or s.shape != (3,):
        raise ValueError(f"markers (m >= 3, 3) and saddle (3,): got {m.shape} and {s.shape}")
    k = len(m)
    p = m - m.mean(0)
    q = s - m.mean(0)
    cross = np.stack([_skew(v) for v in p])                 # [p_i]x
    H = -np.einsum("kij,kjl->il", cross, cross)             # sum -[p_i]x^2
    if np.linalg.cond(H) > COLLINEAR_CONDITION:
        raise StaticShotRefused("markers: collinear, the static shot defines no body frame")
    Hinv = np.linalg.inv(H)
    L = np.zeros((3, 3 * (k + 1)))
    L[:, 3 * k:] = np.eye(3)
    centred = np.eye(k) - 1.0 / k                           # d_i - dc as a map of the marker errors
    for j in range(k):
        # dtheta = H^-1 sum_i [p_i]x (d_i - dc), its part from marker j's error
        dtheta_j = Hinv @ np.einsum("i,ikl->kl", centred[:, j], cross)
        L[:, 3 * j:3 * j + 3] = -np.eye(3) / k + _skew(q) @ dtheta_j
    return L


def _skew(v) -> np.ndarray:
    """``[v]x``: the matrix with ``[v]x w = v x w``."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def saddle_acceleration_sensitivity(omega, alpha, rotation) -> np.ndarray:
    """``G(t)`` (n, 3, 3): the change of a rigid body point's acceleration per metre of its body-frame offset.

    A point carried by the body's rotation ``R(t)`` has the acceleration
    ``a(t) = a_c(t) + ([alpha(t)]x + [omega(t)]x^2) R(t) r``, affine in its body-frame point ``r``, so an
    offset ``dr`` changes it by exactly ``G(t) dr`` with ``G = ([alpha]x + [omega]x^2) R`` (motion frame).
    This is the pose trajectory's saddle; a chain that fits the saddle's path again or takes its rotation
    from elsewhere has its own map (:func:`written_saddle_sensitivity`).

    Examples
    --------
    Turning at a steady 2 rad/s about z, a point 1 cm out along x pulls 4 cm/s^2 towards the axis:

    >>> G = saddle_acceleration_sensitivity([[0, 0, 2.0]], [[0, 0, 0.0]], np.eye(3)[None])
    >>> (G[0] @ [0.01, 0, 0]).round(3)
    array([-0.04,  0.  ,  0.  ])
    """
    w = np.asarray(omega, float)
    al = np.asarray(alpha, float)
    R = np.asarray(rotation, float)
    if w.shape != al.shape or w.ndim != 2 or w.shape[1] != 3 or R.shape != (len(w), 3, 3):
        raise ValueError(f"omega, alpha (n, 3) and rotation (n, 3, 3): got {w.shape}, {al.shape}, {R.shape}")
    W = np.stack([_skew(v) for v in w]) if len(w) else np.zeros((0, 3, 3))
    A = np.stack([_skew(v) for v in al]) if len(al) else np.zeros((0, 3, 3))
    return (A + W @ W) @ R


def written_saddle_sensitivity(body: RigidBodyAnalysis, static_model, step_m: float = FIT_STEP_M) -> np.ndarray:
    """``G(t)`` (n, 3, 3): the written saddle acceleration's change per metre of the static shot's saddle point,
    by the chain's own saddle computation.

    Every chain carries the static saddle point ``s`` linearly into a path or an acceleration, so column ``j``
    of ``G`` is that computation run at ``s + e_j`` less at ``s``: the pose trajectory
    (``kinematics="pose_spline"``, :meth:`horsemocap.pose.PoseTrajectory.point`) and the thesis' eq. 6.55
    (``saddle_method="thesis"``, :func:`horsemocap.rigid.saddle_kinematics` of the registered markers) are
    linear in ``s``, so this is exact. With ``saddle_method`` ``"direct"`` or ``"pose"`` the path
    (eq. 6.48 per frame, or :func:`horsemocap.rigid.chain_saddle_path`) is then fitted again
    (:attr:`horsemocap.rigid.RigidBodyAnalysis.saddle_fit`), a Fourier series whose frequency is fitted too: a
    central difference of that fit (the orders it chose kept, each frequency's search started where it
    ended) with the path moved ``step_m`` either way, exact to first order.

    Parameters
    ----------
    body : horsemocap.rigid.RigidBodyAnalysis
        The rigid-body analysis whose ``saddle_acceleration`` is written.
    static_model : (3, 3) array
        The static shot's markers the thesis' chain placed the saddle against (the static shot's points of
        ``body.static_index``; ``body.model`` may be the ride's mean shape).
    step_m : float
        Half the central difference's step (m), for the fitted paths.

    Examples
    --------
    A body pitching ``0.1 sin(2 pi t)`` rad about x: a saddle point moved along z rises and falls with the
    pitch's angular acceleration, up to ``0.1 (2 pi)^2`` m/s^2 per metre, in either chain:

    >>> from scipy.spatial.transform import Rotation
    >>> from horsemocap.params import PoseParams, RigidBodyParams
    >>> from horsemocap.rigid import analyse_rigid_body
    >>> t = np.arange(50) / 25.0
    >>> body = np.array([[-0.3, 0.0, 0.0], [0.0, 0.05, 0.1], [0.3, 0.0, 0.0], [0.0, -0.2, 0.0]])
    >>> R = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * t), [1, 0, 0])).as_matrix()
    >>> moved = np.einsum("kij,mj->kmi", R, body) + np.outer(4 * t, [1, 0, 0])[:, None]
    >>> for params in (RigidBodyParams(pose=PoseParams(smoothing="none")), RigidBodyParams(kinematics="fits")):
    ...     res = analyse_rigid_body(t, moved[:, :3], body, params, period_s=1.0)
    ...     G = written_saddle_sensitivity(res, body[:3])
    ...     print(res.kinematics, round(float(np.abs(G[:, 1, 2]).max()), 2))
    pose_spline 3.92
    fits 3.92
    """
    s = np.asarray(body.static_saddle, float)
    model = np.asarray(static_model, float)
    if body.kinematics == "pose_spline":
        return _unit_columns(lambda x: body.pose.point(body.t, x).acceleration, s)
    if body.saddle_method == "thesis":
        return _unit_columns(lambda x: saddle_kinematics(body.pos, body.vel, body.acc, body.omega, body.alpha,
                                                         saddle_in_body_versions(model, x)).acceleration, s)
    if body.saddle_method == "pose":
        def path(x):
            return chain_saddle_path(body.t, body.pos, model, x, body.rotation_fit)
    else:
        def path(x):
            return saddle_position(body.pos, saddle_in_body(model, x, 0), 0)
    ok = np.all(np.isfinite(body.pos), axis=(1, 2))[:, None]
    fits = body.saddle_fit.fits[0]
    columns = []
    for step in step_m * np.eye(3):
        ahead, behind = np.where(ok, path(s + step), np.nan), np.where(ok, path(s - step), np.nan)
        columns.append((_refitted_acceleration(fits, body.t, ahead) - _refitted_acceleration(fits, body.t, behind))
                       / (2 * step_m))
    return np.stack(columns, -1)


def _unit_columns(acceleration, point) -> np.ndarray:
    """(n, 3, 3): ``acceleration(point + e_j) - acceleration(point)`` as column j (a map affine in ``point``)."""
    base = acceleration(point)
    return np.stack([acceleration(point + e) - base for e in np.eye(3)], -1)


def _refitted_acceleration(fits, t, path) -> np.ndarray:
    """(n, 3): the second derivative of ``path`` fitted again as ``fits`` (x, y, z) were: the same polynomial
    degree and Fourier orders, each frequency's search started at the frequency it found."""
    out = []
    for axis, fit in enumerate(fits):
        if fit.kind == "poly":
            refit = fitting.fit_polynomial(t, path[:, axis], fit.order)
        else:
            refit = fitting.fit_fourier(t, path[:, axis], fit.order, w0=fit.frequency, start="matlab",
                                        trend=fit.trend)
        out.append(refit.evaluate(t, 2))
    return np.stack(out, -1)


def weighted_rms_sd_pct(rows, offset_covariance, vertical_acceleration, fs: float, weighting: str) -> float:
    """Standard deviation (%) of the frequency-weighted rms of the vertical acceleration for a random offset.

    ``rows`` (n, 3): the vertical acceleration's change per metre of offset (the vertical row of
    :func:`saddle_acceleration_sensitivity`); the offset has covariance ``offset_covariance``. With ``W`` the
    weighting (:func:`horsemocap.vibration.fft_weighting`, by the DFT over the frames), the weighted mean
    square ``<(W a + W g dr)^2>`` changes by ``2 <W a W g> dr`` to first order, so the weighted rms changes by
    ``h dr / <(W a)^2>`` of itself, ``h = <W a W g>``; its standard deviation is ``sqrt(h C h) / <(W a)^2>``.
    Frames with a NaN are left out (the longest finite run is used; NaN when it is shorter than
    :data:`MIN_WEIGHTED_FRAMES`).

    Examples
    --------
    An offset of 1 cm sd along x that adds ``20 sin`` m/s^2 per metre to a signal of ``5 sin``: 4 % of it.

    >>> t = np.arange(200) / 50
    >>> wave = np.sin(2 * np.pi * 2 * t)
    >>> g = np.zeros((200, 3)); g[:, 0] = 20 * wave
    >>> round(weighted_rms_sd_pct(g, np.diag([1e-4, 0, 0]), 5 * wave, 50.0, "Wb"), 3)
    4.0
    """
    g = np.asarray(rows, float)
    ay = np.asarray(vertical_acceleration, float)
    ok = np.isfinite(ay) & np.isfinite(g).all(1)
    start, stop = _longest_true_run(ok)
    if stop - start < MIN_WEIGHTED_FRAMES:
        return float("nan")
    wa = fft_weighting(ay[start:stop], fs, weighting)
    wg = fft_weighting(g[start:stop], fs, weighting, axis=0)
    ms = float(np.mean(wa ** 2))
    h = np.mean(wa[:, None] * wg, axis=0)
    return 100.0 * float(np.sqrt(max(h @ np.asarray(offset_covariance, float) @ h, 0.0))) / ms


def _longest_true_run(ok) -> tuple[int, int]:
    """``(start, stop)`` of the longest run of True in a boolean array."""
    best, start = (0, 0), None
    for i, v in enumerate(list(ok) + [False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            best = max(best, (start, i), key=lambda r: r[1] - r[0])
            start = None
    return best


def static_shot_uncertainty(rig, static_world, marker_rows, saddle_row: int, to_motion, noise_px: float,
                            sensitivity, vertical_acceleration, axis: int = 1,
                            fs: float | None = None, seen: dict | None = None,
                            independent_frames: float = 1.0) -> StaticShotUncertainty:
    """The vertical acceleration's error that the static shot's pixel noise leaves in the saddle.

    Parameters
    ----------
    rig : horsemocap.camera.Rig
        The cameras that took the still.
    static_world : (k, 3) array
        The still's triangulated points (world frame).
    marker_rows : sequence of int
        The rows of the markers the pose is fitted to; ``saddle_row`` the saddle's row.
    to_motion : (3, 3) array
        The rotation from the world to the motion frame (``MotionFrame.axes``).
    noise_px : float
        The detection noise per image coordinate (px), measured on the session (the moving frames'
        reprojection residuals, :func:`horsemocap.reconstruction.pixel_noise`).
    sensitivity : (n, 3, 3) array
        The acceleration's change per metre of the saddle's offset, per frame
        (:func:`written_saddle_sensitivity`, or :func:`saddle_acceleration_sensitivity` of a rigid body).
    vertical_acceleration : (n,) array
        The saddle's vertical acceleration as written (m/s^2).
    axis : int
        The vertical axis of the motion frame.
    fs : float, optional
        The frame rate: with it, the Wb- and Wk-weighted rms's share too (:func:`weighted_rms_sd_pct`).
    seen : dict, optional
        Camera -> (k,) bool: which of the still's points each camera saw (default: all of them).
    independent_frames : float
        The static shot averaged over a clip: the independent frames it is worth (1: one still). The
        points' covariance is divided by it. Only the noise that changes from frame to frame averages
        away: an error that each camera makes the same in every frame (a marker's centroid seen off its
        centre) is not in ``noise_px``'s frame-to-frame part and is not reduced.

    Returns
    -------
    StaticShotUncertainty
        Propagated linearly: pixels -> the still's points (:func:`still_point_covariance`) -> the saddle's
        body-frame offset (:func:`saddle_offset_map`) -> each frame's vertical acceleration (``sensitivity``).

    Examples
    --------
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> rig = Rig((Camera("left", (640, 480), K), Camera("right", (640, 480), K, translation=[-0.5, 0, 0])))
    >>> still = np.array([[-0.3, 0, 3.0], [0.3, 0, 3.0], [0, -0.05, 3.0], [0, 0.3, 3.0]])
    >>> n = 50; t = np.arange(n) / 50
    >>> alpha = np.zeros((n, 3)); alpha[:, 0] = 20 * np.sin(2 * np.pi * 2 * t)   # pitching about x
    >>> G = saddle_acceleration_sensitivity(np.zeros((n, 3)), alpha, np.repeat(np.eye(3)[None], n, 0))
    >>> shot = static_shot_uncertainty(rig, still, [0, 1, 2], 3, np.eye(3), 0.2, G, 5 * np.sin(2 * np.pi * 2 * t))
    >>> 1000 * shot.offset_sd_m.round(4)         # the thin triangle's tilt: the saddle's depth (z) 5 cm
    array([ 1. ,  0.9, 49.9])
    >>> round(shot.pct_of_rms)                      # of the vertical acceleration's rms
    20
    """
    world = np.asarray(static_world, float)
    rows = [int(i) for i in marker_rows]
    if not np.isfinite(world[rows + [int(saddle_row)]]).all():
        raise StaticShotRefused("static_world: the static shot's markers and saddle must be finite")
    axes = np.asarray(to_motion, float)
    used_rows = rows + [int(saddle_row)]
    seen_used = None if seen is None else {c: np.asarray(v, bool)[used_rows] for c, v in seen.items()}
    if not (np.isfinite(independent_frames) and independent_frames >= 1):
        raise ValueError(f"independent_frames: expected a number of frames >= 1, got {independent_frames!r}")
    cov_world = still_point_covariance(rig, world[used_rows], noise_px, seen_used) / float(independent_frames)
    if not np.isfinite(cov_world).all():
        raise StaticShotRefused("static_world: a marker or the saddle of the static shot was seen by fewer than two "
                         "cameras; its place has no covariance")
    cov = axes @ cov_world @ axes.T                          # motion frame, per point
    motion = world[rows + [int(saddle_row)]] @ axes.T
    L = saddle_offset_map(motion[:-1], motion[-1])
    k = len(rows) + 1
    block = np.zeros((3 * k, 3 * k))
    for i in range(k):
        block[3 * i:3 * i + 3, 3 * i:3 * i + 3] = cov[i]
    offset_cov = L @ block @ L.T
    g = np.asarray(sensitivity, float)[:, axis, :]           # (n, 3): the vertical row
    var = np.einsum("ni,ij,nj->n", g, offset_cov, g)
    sd_t = np.sqrt(np.clip(var, 0.0, None))
    ay = np.asarray(vertical_acceleration, float)
    ok = np.isfinite(sd_t) & np.isfinite(ay)
    if not ok.any():
        raise StaticShotRefused("sensitivity, vertical_acceleration: no frame with both finite")
    sd = float(np.sqrt(np.mean(var[ok])))
    rms = float(np.sqrt(np.mean(ay[ok] ** 2)))
    weighted = ({w: weighted_rms_sd_pct(g, offset_cov, ay, fs, w) for w in ("Wb", "Wk")} if fs else {})
    return StaticShotUncertainty(noise_px=float(noise_px), offset_covariance=offset_cov,
                                 offset_sd_m=np.sqrt(np.clip(np.diag(offset_cov), 0, None)),
                                 acceleration_sd=np.where(ok, sd_t, np.nan), sd=sd, rms=rms,
                                 pct_of_rms=100.0 * sd / rms if rms > 0 else float("inf"), weighted_pct=weighted,
                                 independent_frames=float(independent_frames))


# ---------------------------------------------------------------------------
# the moving frames' noise at the saddle, against the saddle's motion
# ---------------------------------------------------------------------------

#: Fewest frames with both a per-frame pose and a written saddle for :func:`saddle_scatter`: as the spline basis'
#: own floor (fewer frames than this leave an rms of a handful of values, no figure to judge by).
MIN_SCATTER_FRAMES = 8
#: The least vertical motion (m rms) of the written saddle :func:`saddle_scatter` compares against: below it the
#: horse is standing (a ridden gait moves the saddle by centimetres) and there is no motion to resolve.
MIN_SCATTER_MOTION_M = 1e-3


@dataclass(frozen=True)
class SaddleScatter:
    """The per-frame pose's scatter at the saddle about the written trajectory, against the saddle's motion.

    Examples
    --------
    >>> SaddleScatter(0.003, 0.03, 10.0, 200).pct_of_motion
    10.0

    Attributes
    ----------
    scatter_m : float
        Rms (m) of each frame's saddle height (the frame's own registration carrying the static shot's saddle
        point) minus the written height, over the frames with both (their mean removed).
    motion_m : float
        Rms (m) of the written saddle height about its mean over the same frames.
    pct_of_motion : float
        ``scatter_m`` as a percentage of ``motion_m``.
    frames : int
        The frames compared.
    """

    scatter_m: float
    motion_m: float
    pct_of_motion: float
    frames: int


def saddle_scatter(rotation, translation, static_saddle, written_position, axis: int = 1) -> SaddleScatter:
    """How large the moving frames' noise is at the saddle, against the saddle's own vertical motion.

    The per-frame saddle is ``R_k s + d_k`` (each frame's registration ``R_k``, ``d_k`` carrying the static
    shot's saddle ``s``: the thesis' eq. 6.48 frame by frame, before any smoothing); the written saddle is
    what kinematics.csv holds (the smoothed chain's). Their difference along ``axis`` (1: the motion frame's
    vertical) is the noise the markers carry to the saddle in each frame plus any motion the smoothing
    removed; the written height's own variation is the motion the acceleration comes from.

    What it measures is what the smoothing removed, so it judges in one direction only: a record whose noise
    at the saddle is the size of its motion (the smoothing had to remove that much), or whose smoothing took
    motion for noise, shows a large figure; a smoothing that follows the noise removes less of it and looks
    better than it is (no smoothing at all gives 0).

    Parameters
    ----------
    rotation : (n, 3, 3) array
        Each frame's registration rotation (NaN: no pose in that frame).
    translation : (n, 3) array
        Each frame's registration translation (m).
    static_saddle : (3,) array
        The saddle in the static shot (model frame, m).
    written_position : (n, 3) array
        The written saddle position per frame (m, the same frames).
    axis : int
        The coordinate compared (1: vertical, y down, of the motion frame).

    Returns
    -------
    SaddleScatter

    Raises
    ------
    ValueError
        Shapes that do not match, fewer than :data:`MIN_SCATTER_FRAMES` frames with both, or a written saddle
        moving less than :data:`MIN_SCATTER_MOTION_M` rms (a standing horse: no motion to compare with).

    Examples
    --------
    A saddle moving 30 mm rms, its per-frame pose scattered by 3 mm: 10 % of its motion.

    >>> import numpy as np
    >>> t = np.arange(200) / 50.0
    >>> written = np.zeros((200, 3))
    >>> written[:, 1] = 0.03 * np.sqrt(2) * np.sin(2 * np.pi * 1.5 * t)
    >>> scatter = np.where(np.arange(200) % 2, 0.003, -0.003)
    >>> rotation = np.tile(np.eye(3), (200, 1, 1))
    >>> translation = written + np.column_stack([0 * t, scatter, 0 * t])
    >>> out = saddle_scatter(rotation, translation, np.zeros(3), written)
    >>> round(out.pct_of_motion, 1), out.frames
    (10.0, 200)
    """
    R = np.asarray(rotation, float)
    d = np.asarray(translation, float)
    w = np.asarray(written_position, float)
    if R.shape[1:] != (3, 3) or d.shape != (R.shape[0], 3) or w.shape != d.shape:
        raise ValueError(f"rotation, translation, written_position: expected (n, 3, 3), (n, 3), (n, 3), got "
                         f"{R.shape}, {d.shape}, {w.shape}")
    per_frame = np.einsum("kij,j->ki", R, np.asarray(static_saddle, float)) + d
    both = np.isfinite(per_frame[:, axis]) & np.isfinite(w[:, axis])
    if both.sum() < MIN_SCATTER_FRAMES:
        raise ValueError(f"written_position: {int(both.sum())} frames with a per-frame pose and a written saddle, "
                         f"at least {MIN_SCATTER_FRAMES} needed")
    residual = per_frame[both, axis] - w[both, axis]
    motion = w[both, axis] - w[both, axis].mean()
    scatter = float(np.sqrt(np.mean((residual - residual.mean()) ** 2)))
    moves = float(np.sqrt(np.mean(motion ** 2)))
    if moves < MIN_SCATTER_MOTION_M:
        raise ValueError(f"written_position: the saddle moves {1000 * moves:.3g} mm rms vertically, less than "
                         f"{1000 * MIN_SCATTER_MOTION_M:g} mm: no motion to compare the frames' scatter with")
    return SaddleScatter(scatter, moves, 100 * scatter / moves, int(both.sum()))
