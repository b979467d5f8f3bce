"""3D reconstruction of markers from several calibrated cameras (thesis 5.1).

Two ways are offered, both returning points in the world frame (the
reference camera's frame, thesis ``CM_L``) in metres:

``mode="thesis"``
    Thesis section 5.1, Appendix A step 5 (``combine_image_centroids_and_calibration.m``):
    stereo triangulation of each camera pair with Bouguet's
    ``stereo_triangulation`` (the midpoint of the common perpendicular of the
    two rays), giving ``CM_LM,L``, ``CM_LR,L`` (left frame) and ``CM_MR,M``
    (middle frame); the latter moved into the left frame with
    ``x_L = R_ML^-1 (x_M - t_ML)`` (eq. 5.1-5.4), and the three averaged
    (eq. 5.5). Needs the three cameras of the thesis rig (or explicit ``pairs``).
``mode="joint"``
    All cameras that see the point at once: linear DLT on the undistorted
    normalised coordinates, refined by minimising the sum of squared
    reprojection errors in (distorted) pixels with damped Gauss-Newton.
    Works with two cameras or more than three, and with any subset seeing a
    given point (at least two).

Pixel inputs are the distorted detections (thesis ``PM_L``, ``PM_M``,
``PM_R``, chapter 4), NaN where a marker was not found; they are undistorted
with :meth:`horsemocap.camera.Camera.pixels_to_normalized`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from .camera import Camera, Rig

__all__ = [
    "Triangulation",
    "PairTriangulation",
    "triangulate",
    "stereo_triangulation",
    "relative_pose",
    "camera_to_world",
    "reprojection_residuals",
    "point_covariance",
    "nearest_covariance",
    "pixel_noise",
    "REASON_FEW_CAMERAS",
    "REASON_BEHIND",
    "REASON_FAILED",
    "REASON_INCONSISTENT",
    "DEFAULT_MAX_RESIDUAL_PX",
]

REASON_FEW_CAMERAS = "seen_by_fewer_than_two_cameras"
REASON_BEHIND = "behind_a_camera"
REASON_FAILED = "triangulation_failed"
REASON_INCONSISTENT = "inconsistent_views"
DEFAULT_MAX_RESIDUAL_PX = 2.0
_REASON_NAMES = np.array(["", REASON_FEW_CAMERAS, REASON_FAILED, REASON_INCONSISTENT, REASON_BEHIND])
_OK, _FEW, _FAILED, _INCONSISTENT = 0, 1, 2, 3


@dataclass(frozen=True)
class PairTriangulation:
    """Stereo triangulation of one camera pair (thesis ``CM_LM,L`` ...).

    Attributes
    ----------
    cameras : tuple of str
        ``(a, b)``: locally left and right cameras of the pair.
    points_local : ndarray, shape (n, m, 3)
        In camera ``a``'s frame (e.g. ``CM_MR,M`` for the middle-right pair).
    points : ndarray, shape (n, m, 3)
        In the world (reference camera) frame, eq. 5.3-5.4 (e.g. ``CM_MR,L``).

    Examples
    --------
    See :func:`triangulate` (``mode="thesis"``).
    """

    cameras: tuple[str, str]
    points_local: np.ndarray
    points: np.ndarray


@dataclass(frozen=True)
class Triangulation:
    """Result of :func:`triangulate`.

    Attributes
    ----------
    points : ndarray, shape (n_frames, n_markers, 3)
        World (reference camera) frame, metres; thesis ``CM_L`` (eq. 5.5).
        NaN where no position could be computed, with ``reason``.
    residual_px : dict of str -> ndarray (n_frames, n_markers)
        Reprojection error (pixels, distance between the projection of
        ``points`` and the detection) per camera; NaN where that camera did
        not see the marker or the point is NaN.
    reason : ndarray of str, shape (n_frames, n_markers)
        ``""`` when ``points`` is valid, else why not
        (``"seen_by_fewer_than_two_cameras"``, ``"behind_a_camera"``,
        ``"triangulation_failed"``).
    n_views : ndarray of int, shape (n_frames, n_markers)
        Number of cameras whose detection was used.
    mode : str
        ``"thesis"`` or ``"joint"``.
    cameras : tuple of str
        Cameras used, in rig order.
    pairs : dict of str -> PairTriangulation
        Thesis mode: each pair's result keyed ``"left-middle"``...; empty in
        joint mode.
    rejected : dict of str -> ndarray of bool (n_frames, n_markers)
        Joint mode: detections left out as inconsistent with the other
        cameras (see ``max_residual_px``); their ``residual_px`` is still
        reported (it shows how far off they were).
    covariance : ndarray, shape (n_frames, n_markers, 3, 3), or None
        Only with ``triangulate(..., covariance=True)``: each point's
        covariance (m^2, world frame) for white detection noise of
        ``noise_px`` pixels (:func:`point_covariance`); NaN where ``points``
        is NaN. None when the residuals give no noise to propagate (all zero:
        exact detections, or no point seen by two cameras).
    noise_px : float or None
        The detection noise (pixels) estimated from the reprojection
        residuals (:func:`pixel_noise`), with ``covariance``.

    Examples
    --------
    See :func:`triangulate`.
    """

    points: np.ndarray
    residual_px: dict
    reason: np.ndarray
    n_views: np.ndarray
    mode: str
    cameras: tuple
    pairs: dict = field(default_factory=dict)
    rejected: dict = field(default_factory=dict)
    covariance: np.ndarray | None = None
    noise_px: float | None = None

    @property
    def valid(self) -> np.ndarray:
        """Boolean (n_frames, n_markers): a position was computed."""
        return self.reason == ""

    def rms_residual_px(self) -> dict:
        """RMS reprojection error per camera over the valid observations (pixels)."""
        out = {}
        for cam, r in self.residual_px.items():
            ok = np.isfinite(r)
            out[cam] = float(np.sqrt(np.mean(r[ok] ** 2))) if ok.any() else float("nan")
        return out


# ---------------------------------------------------------------------------
# building blocks
# ---------------------------------------------------------------------------

def relative_pose(cam_a: Camera, cam_b: Camera) -> tuple[np.ndarray, np.ndarray]:
    """``R, T`` with ``x_b = R x_a + T`` (thesis eq. 5.1, ``R_RL, t_RL``).

    From the rig's extrinsics ``x_c = R_c x_w + t_c``:
    ``R = R_b R_a^T``, ``T = t_b - R t_a``.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> R, T = relative_pose(left, right)
    >>> R, T
    (array([[1., 0., 0.],
           [0., 1., 0.],
           [0., 0., 1.]]), array([-0.5,  0. ,  0. ]))
    """
    Ra, Rb = cam_a.rotation_matrix, cam_b.rotation_matrix
    R = Rb @ Ra.T
    return R, cam_b.translation - R @ cam_a.translation


def camera_to_world(points_cam: np.ndarray, cam: Camera) -> np.ndarray:
    """Points ``(..., 3)`` from ``cam``'s frame to the world frame.

    ``x_w = R_c^T (x_c - t_c)``; for the middle camera of the thesis rig
    (world = left camera) this is eq. 5.3, ``x_L = R_ML^-1 (x_M - t_ML)``.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> camera_to_world(np.array([0.6, 0.0, 2.0]), right)      # 0.6 m right of the right camera's axis
    array([1.1, 0. , 2. ])
    """
    p = np.asarray(points_cam, float)
    return (p - cam.translation) @ cam.rotation_matrix


def stereo_triangulation(xn_left: np.ndarray, xn_right: np.ndarray, R: np.ndarray, T: np.ndarray):
    """Bouguet's ``stereo_triangulation``: midpoint of the two rays.

    Parameters
    ----------
    xn_left, xn_right : ndarray, shape (..., 2)
        Undistorted normalised coordinates in the (locally) left and right cameras.
    R, T : ndarray
        ``x_right = R x_left + T`` (eq. 5.1).

    Returns
    -------
    XL, XR : ndarray, shape (..., 3)
        The point in the left and right camera frames: the midpoint of the
        shortest segment joining the two viewing rays. NaN where an input is
        NaN or the rays are parallel.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> points = np.array([[[0.1, 0.0, 2.0], [-0.2, 0.1, 3.0]]])     # 1 frame, 2 markers (m)
    >>> px = rig.project(points)
    >>> R, T = relative_pose(left, right)
    >>> XL, XR = stereo_triangulation(left.pixels_to_normalized(px["left"]),
    ...                               right.pixels_to_normalized(px["right"]), R, T)
    >>> XL.round(6)
    array([[[ 0.1,  0. ,  2. ],
            [-0.2,  0.1,  3. ]]])
    """
    xl = np.asarray(xn_left, float)
    xr = np.asarray(xn_right, float)
    shape = np.broadcast_shapes(xl.shape, xr.shape)[:-1]
    xt = np.concatenate([xl, np.ones(xl.shape[:-1] + (1,))], axis=-1).reshape(-1, 3)
    xtt = np.concatenate([xr, np.ones(xr.shape[:-1] + (1,))], axis=-1).reshape(-1, 3)
    T = np.asarray(T, float).reshape(3)
    u = xt @ R.T
    n_xt2 = np.sum(xt * xt, axis=1)
    n_xtt2 = np.sum(xtt * xtt, axis=1)
    dot_uxtt = np.sum(u * xtt, axis=1)
    DD = n_xt2 * n_xtt2 - dot_uxtt**2
    dot_uT = u @ T
    dot_xttT = xtt @ T
    with np.errstate(divide="ignore", invalid="ignore"):
        Zt = (dot_uxtt * dot_xttT - n_xtt2 * dot_uT) / DD
        Ztt = (n_xt2 * dot_xttT - dot_uT * dot_uxtt) / DD
    bad = ~(np.abs(DD) > 1e-15)
    Zt[bad] = np.nan
    Ztt[bad] = np.nan
    X1 = xt * Zt[:, None]
    X2 = (xtt * Ztt[:, None] - T) @ R  # R^T (.) for row vectors
    XL = 0.5 * (X1 + X2)
    XR = XL @ R.T + T
    return XL.reshape(shape + (3,)), XR.reshape(shape + (3,))


def reprojection_residuals(rig: Rig, points: np.ndarray, marker_px: dict) -> dict:
    """Pixel distance between ``rig`` projections of ``points`` and ``marker_px`` per camera.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> points = np.array([[[0.1, 0.0, 2.0], [-0.2, 0.1, 3.0]]])     # 1 frame, 2 markers (m)
    >>> reprojection_residuals(rig, points, rig.project(points))
    {'left': array([[0., 0.]]), 'right': array([[0., 0.]])}
    """
    out = {}
    for cam, px in marker_px.items():
        proj = rig[cam].project(points)
        out[cam] = np.linalg.norm(proj - np.asarray(px, float), axis=-1)
    return out


def _check_inputs(rig: Rig, marker_px: dict) -> tuple[list[str], tuple[int, int]]:
    if not isinstance(marker_px, dict) or not marker_px:
        raise ValueError("marker_px: expected a dict {camera name: (frames, markers, 2) pixels}")
    unknown = [c for c in marker_px if c not in rig.names]
    if unknown:
        raise ValueError(f"marker_px: camera(s) {unknown} are not in the rig (it has {rig.names})")
    shape = None
    for cam, px in marker_px.items():
        a = np.asarray(px, float)
        if a.ndim != 3 or a.shape[-1] != 2:
            raise ValueError(f"marker_px[{cam!r}]: expected shape (frames, markers, 2), got {a.shape}")
        if shape is None:
            shape = a.shape[:2]
        elif a.shape[:2] != shape:
            raise ValueError(
                f"marker_px[{cam!r}]: shape {a.shape[:2]} (frames, markers) differs from the other cameras' {shape}; "
                "synchronise the cameras first (same frames, same marker order)")
    cams = [c for c in rig.names if c in marker_px]
    return cams, shape


def _observed(px: np.ndarray) -> np.ndarray:
    return np.isfinite(px[..., 0]) & np.isfinite(px[..., 1])


# ---------------------------------------------------------------------------
# joint triangulation
# ---------------------------------------------------------------------------

# OpenCV's iterative undistortion: 20 iterations reach the house inverse
# (Camera.pixels_to_normalized, 30 fixed-point and 3 Gauss-Newton steps in
# NumPy) to 1e-15 on the rigs of the virtual laboratory, at a small fraction of
# its cost for a few points (identification calls it per frame and camera).
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-15)
#: The joint triangulation's linear start: 10 fixed-point iterations (no error check per iteration, which
#: costs as much as an iteration) agree with the 20 above to 3e-15 in normalised units; the refinement
#: starting there ends within 4e-14 m of the start from the precise inverse (bundled and hard 1080p sessions).
_START_CRITERIA = (cv2.TERM_CRITERIA_COUNT, 10, 0)
#: A point leaves the refinement when its Gauss-Newton step is below this
#: (10 nm, five orders below the calibration's millimetres; the next step
#: of the quadratically converging iteration would be far smaller still).
STEP_TOLERANCE_M = 1e-8
#: A Gauss-Newton step below this (0.1 mm) is taken as the last one, without
#: evaluating the cost again: the iteration converges quadratically, and on the
#: bundled session the step after a first step of up to 0.2 mm is below 4e-9 m.
FINAL_STEP_M = 1e-4


def _undistort(cam: Camera, px: np.ndarray, ok: np.ndarray | None = None,
               criteria=_UNDISTORT_CRITERIA) -> np.ndarray:
    """Undistorted normalised coordinates (N, 2) of pixels (N, 2); NaN stays NaN.

    Same model as :meth:`~horsemocap.camera.Camera.pixels_to_normalized`
    (eq. 3.7-3.9 inverted; skew handled here, OpenCV is given the identity
    camera matrix), solved by ``cv2.undistortPoints``. ``ok``: the finite
    pixels, if known.
    """
    out = np.full(px.shape, np.nan)
    if ok is None:
        ok = _observed(px)
    if ok.any():
        K = cam.matrix
        yd = (px[ok, 1] - K[1, 2]) / K[1, 1]
        xd = (px[ok, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
        xy = np.ascontiguousarray(np.stack([xd, yd], axis=-1)).reshape(-1, 1, 2)
        out[ok] = cv2.undistortPoints(xy, np.eye(3), np.asarray(cam.distortions, float), None, None, None,
                                      criteria).reshape(-1, 2)
    return out


def _cofactors3(h):
    """Cofactors ``(A00, A01, A02, A11, A12, A22)``, determinant and the cube of the largest diagonal
    entry (a scale for the singularity test) of symmetric 3x3 matrices ``h = (h00, h01, h02, h11, h12, h22)``."""
    a, bb, c, d, e, f = h
    A00, A01, A02 = d * f - e * e, c * e - bb * f, bb * e - c * d
    A11, A12, A22 = a * f - c * c, bb * c - a * e, a * d - bb * bb
    det = a * A00 + bb * A01 + c * A02
    scale = np.maximum(np.maximum(np.abs(a), np.abs(d)), np.abs(f)) ** 3
    return (A00, A01, A02, A11, A12, A22), det, scale


def _solve3(h, b, rows: bool = False):
    """Batched solve of symmetric 3x3 systems by cofactors; NaN where singular.

    ``h`` = ``(h00, h01, h02, h11, h12, h22)`` arrays (N,), ``b`` = ``(b0, b1, b2)``.
    Returns (N, 3), or (3, N) with ``rows``.
    """
    (A00, A01, A02, A11, A12, A22), det, scale = _cofactors3(h)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(np.abs(det) > 1e-13 * scale, 1.0 / det, np.nan)
        x0 = (A00 * b[0] + A01 * b[1] + A02 * b[2]) * inv
        x1 = (A01 * b[0] + A11 * b[1] + A12 * b[2]) * inv
        x2 = (A02 * b[0] + A12 * b[1] + A22 * b[2]) * inv
    return np.stack([x0, x1, x2], axis=0 if rows else -1)


#: The entries ``(i, j)`` of a symmetric 3 x 3 matrix stored as six: ``h00, h01, h02, h11, h12, h22``.
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
_PI, _PJ = np.array(_PAIRS).T

#: Up to this many points :func:`_dlt` sums the normal equations with Python floats: the same
#: operations in the same order as the array sums (the same bits), without NumPy's cost per call,
#: which dominates the identification's triangulations of one to a few points.
FEW_POINTS = 8


def _dlt(xn: np.ndarray, seen: np.ndarray, Ps: np.ndarray, rows: bool = False) -> np.ndarray:
    """Linear triangulation of all points at once; xn (C, N, 2), seen (C, N), Ps (C, 3, 4) -> (N, 3).

    The DLT equations ``x (P_3 X) - P_1 X = 0``, ``y (P_3 X) - P_2 X = 0``
    of every camera that saw the point, with ``X = (x, y, z, 1)``, solved in
    the least-squares sense (3 x 3 normal equations per point, solved
    together). NaN where the views do not fix the point (fewer than two, or
    parallel rays). ``rows``: the points as (3, N).
    """
    if seen.shape[1] <= FEW_POINTS:
        h, b = _dlt_normal_equations_few(xn, seen, Ps)
        return _solve3([np.array(v) for v in h], [np.array(v) for v in b], rows)
    return _solve3(*_dlt_normal_equations(xn, seen, Ps), rows)


def _dlt_normal_equations(xn: np.ndarray, seen: np.ndarray, Ps: np.ndarray):
    """The DLT normal equations of :func:`_dlt`, ``h`` (six arrays (N,)) and ``b`` (three), summed over the
    cameras for all points at once."""
    C, N = seen.shape
    h = [np.zeros(N) for _ in range(6)]
    b = [np.zeros(N) for _ in range(3)]
    for c in range(C):
        w = seen[c]
        if not w.any():
            continue
        P = Ps[c]
        for coord in (0, 1):
            v = np.where(w, xn[c, :, coord], 0.0)
            wf = w.astype(float)
            a = [(v * P[2, k] - P[coord, k]) * wf for k in range(4)]
            for n, (i, j) in enumerate(_PAIRS):
                h[n] += a[i] * a[j]
            for i in range(3):
                b[i] -= a[i] * a[3]
    return h, b


def _dlt_normal_equations_few(xn: np.ndarray, seen: np.ndarray, Ps: np.ndarray):
    """The DLT normal equations of :func:`_dlt` (``h`` six lists, ``b`` three lists, one entry per point)
    summed point by point with Python floats."""
    C, N = seen.shape
    h = [[0.0] * N for _ in range(6)]
    b = [[0.0] * N for _ in range(3)]
    coords, flags, matrices = xn.tolist(), seen.tolist(), Ps.tolist()
    for c in range(C):
        if not any(flags[c]):
            continue
        P = matrices[c]
        for coord in (0, 1):
            for n in range(N):
                wf = 1.0 if flags[c][n] else 0.0
                v = coords[c][n][coord] if flags[c][n] else 0.0
                a = [(v * P[2][k] - P[coord][k]) * wf for k in range(4)]
                for m, (i, j) in enumerate(_PAIRS):
                    h[m][n] += a[i] * a[j]
                for i in range(3):
                    b[i][n] -= a[i] * a[3]
    return h, b


# The joint triangulation works on points stored as rows (3, N): NumPy's
# reductions and products over a short last axis of (N, 3) arrays cost up to
# ten times the same work on contiguous rows.


def _finite_rows(X: np.ndarray) -> np.ndarray:
    """Columns of X (3, N) with every coordinate finite."""
    return np.isfinite(X[0]) & np.isfinite(X[1]) & np.isfinite(X[2])


def _project_jacobian(cam: Camera, X: np.ndarray, seen: np.ndarray):
    """Distorted pixels ``u, v`` (N,) of world points X (3, N) and their gradients (two (3, N) arrays).

    Thesis eq. 3.1-3.10 as :meth:`~horsemocap.camera.Camera.project`
    (NaN at or behind the camera plane), differentiated analytically.
    Where ``seen`` is False the gradients are 0 (the camera is left out).
    """
    R = cam.rotation_matrix
    Xc = R @ X + cam.translation[:, None]              # (3, N)
    z = Xc[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        iz = np.where(seen, np.where(z > 1e-9, 1.0 / z, np.nan), 0.0)
    x, y = Xc[0] * iz, Xc[1] * iz
    k1, k2, p1, p2, k3 = np.asarray(cam.distortions, float)
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + k3 * r2))
    dr = k1 + r2 * (2 * k2 + 3 * k3 * r2)             # d radial / d r2
    xy = x * y
    xd = radial * x + 2 * p1 * xy + p2 * (r2 + 2 * x * x)
    yd = radial * y + p1 * (r2 + 2 * y * y) + 2 * p2 * xy
    K = cam.matrix
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    u, v = fx * xd + s * yd + cx, fy * yd + cy
    dxx = radial + 2 * x * x * dr + 2 * p1 * y + 6 * p2 * x
    dxy = 2 * xy * dr + 2 * p1 * x + 2 * p2 * y        # = d yd / dx
    dyy = radial + 2 * y * y * dr + 6 * p1 * y + 2 * p2 * x
    J = np.empty((2, 3, len(z)))                       # d(u, v)/d(camera frame point)
    J[0, 0], J[0, 1] = (fx * dxx + s * dxy) * iz, (fx * dxy + s * dyy) * iz
    J[1, 0], J[1, 1] = fy * dxy * iz, fy * dyy * iz
    J[0, 2], J[1, 2] = -(J[0, 0] * x + J[0, 1] * y), -(J[1, 0] * x + J[1, 1] * y)
    G = _rt(cam) @ J                                   # times R for the world point
    return u, v, G[0], G[1]


def _rt(cam: Camera) -> np.ndarray:
    """``R^T`` of a camera, contiguous (a transposed view makes the product several times slower)."""
    return np.ascontiguousarray(cam.rotation_matrix.T)


def _normal_equations(cams, X, px, seen):
    """Cost (N,), ``J^T J`` (6, N) (upper triangle) and ``J^T r`` (3, N) of the pixel residuals; X (3, N)."""
    N = X.shape[1]
    cost = np.zeros(N)
    h = np.zeros((6, N))
    g = np.zeros((3, N))
    for c, cam in enumerate(cams):
        w = seen[c]
        u, v, gu, gv = _project_jacobian(cam, X, w)
        ru = np.where(w, u - px[c, :, 0], 0.0)
        rv = np.where(w, v - px[c, :, 1], 0.0)
        cost += ru * ru + rv * rv
        h += gu[_PI] * gu[_PJ] + gv[_PI] * gv[_PJ]
        g += gu * ru + gv * rv
    return cost, h, g


def _refine(cams, X0, px, seen, iterations=20):
    """Levenberg-Marquardt on the pixel reprojection error, all points at once; X0 (3, N).

    Minimises ``sum_c |project_c(X) - p_c|^2`` over the cameras that saw the
    point, from the linear solution, with the analytic Jacobian (damping
    only when a step raises the cost). A point leaves the iteration as soon
    as its step is below :data:`STEP_TOLERANCE_M`, or its first step (from
    the linear solution) below :data:`FINAL_STEP_M` (that last step is taken
    without evaluating the cost again), or its cost stops changing (relative
    change below 1e-12): the refinement works only where it still changes
    the result (on the bundled session it moves the linear solution by
    0.03 mm median, 0.2 mm at most, and converges in two steps). A point
    whose projection is undefined (behind a camera) keeps its linear
    solution.
    """
    X = X0.copy()
    N = X.shape[1]
    cost, h, g = _normal_equations(cams, X, px, seen)
    lam = np.full(N, 1e-6)
    active = np.isfinite(cost) & np.isfinite(h).all(axis=0)
    first = True
    for _ in range(iterations):
        if active.all():
            idx, sub = np.arange(N), slice(None)
        else:
            idx = np.flatnonzero(active)
            sub = idx
        if idx.size == 0:
            break
        hs = h[:, sub].copy()
        hs[[0, 3, 5]] *= 1 + lam[sub]
        delta = -_solve3(hs, g[:, sub], rows=True)
        with np.errstate(invalid="ignore"):
            big = np.maximum(np.maximum(np.abs(delta[0]), np.abs(delta[1])), np.abs(delta[2]))
            tiny = big < (FINAL_STEP_M if first else STEP_TOLERANCE_M)
        first = False
        last = idx[tiny]
        X[:, last] += delta[:, tiny]           # converged: the last (tiny) step needs no check
        active[last] = False
        go = ~tiny & _finite_rows(delta)
        active[idx[~tiny & ~go]] = False
        if go.all() and idx.size == N:
            sub = slice(None)                  # every point steps: no copies
        else:
            idx, delta = idx[go], delta[:, go]
            sub = idx
        if idx.size == 0:
            continue
        Xn = X[:, sub] + delta
        cn, hn, gn = _normal_equations(cams, Xn, px[:, sub], seen[:, sub])
        # a step that raises the cost by rounding only (1e-12 relative) is a converged one
        c0 = cost[sub]
        better = np.isfinite(cn) & (cn <= c0 * (1 + 1e-12) + 1e-20) & np.isfinite(hn).all(axis=0)
        if better.all():
            X[:, sub], h[:, sub], g[:, sub], cost[sub] = Xn, hn, gn, cn
        else:
            b = idx[better]
            X[:, b], h[:, b], g[:, b], cost[b] = Xn[:, better], hn[:, better], gn[:, better], cn[better]
        lam[sub] = np.where(better, np.maximum(lam[sub] / 10, 1e-9), np.minimum(lam[sub] * 10, 1e9))
        done = np.zeros(idx.size, bool)
        done[better] = np.abs(c0[better] - cn[better]) <= 1e-12 * np.maximum(cn[better], 1e-12)
        active[idx[done]] = False
    return X


def _solve_views(cam_objs, xn, px, seen, Ps):
    """DLT + refinement of points (N) with the given seen mask (C, N); (3, N), NaN where it fails."""
    X0 = _dlt(xn, seen, Ps, rows=True)
    good = _finite_rows(X0)
    if good.all():
        return _refine(cam_objs, X0, px, seen)
    X = np.full_like(X0, np.nan)
    if good.any():
        X[:, good] = _refine(cam_objs, X0[:, good], px[:, good], seen[:, good])
    return X


def _residuals(cam_objs, X, px):
    """Reprojection error (C, N) pixels of points X (3, N), as :func:`reprojection_residuals`.

    :meth:`~horsemocap.camera.Camera.project` (eq. 3.1-3.10) written out on
    coordinate rows, in the same order of operations, without its
    intermediate (N, 2) arrays; NaN where the point is behind the camera or
    the pixel is NaN.
    """
    r = np.empty(px.shape[:2])
    for c, cam in enumerate(cam_objs):
        pc = cam.rotation_matrix @ X + cam.translation[:, None]     # (3, N)
        z = pc[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(z > 1e-9, z, np.nan)
            x, y = pc[0] / z, pc[1] / z
        k1, k2, p1, p2, k3 = np.asarray(cam.distortions, float)
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
        xd = radial * x + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = radial * y + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        K = cam.matrix
        du = K[0, 0] * xd + K[0, 1] * yd + K[0, 2] - px[c, :, 0]
        dv = K[1, 1] * yd + K[1, 2] - px[c, :, 1]
        r[c] = np.sqrt(du * du + dv * dv)
    return r


def _worst(r, seen):
    """Largest residual over the cameras in ``seen`` (C, N); a point behind a camera (NaN) counts as inf."""
    r = np.where(seen, np.where(np.isfinite(r), r, np.inf), 0.0)  # behind a camera: inconsistent
    return np.max(r, axis=0)


def _max_residual(cam_objs, X, px, seen):
    return _worst(_residuals(cam_objs, X, px), seen)


def _triangulate_joint(rig, cams, px_all, seen_all, max_residual_px=None):
    """Points (n, m, 3), reasons, views, rejected (C, n, m) and residuals (C, n, m) of the joint mode."""
    C, n, m, _ = px_all.shape
    N = n * m
    px = px_all.reshape(C, N, 2)
    seen = seen_all.reshape(C, N)
    cam_objs = [rig[c] for c in cams]
    xn = np.stack([_undistort(cam, px[i], seen[i], _START_CRITERIA) for i, cam in enumerate(cam_objs)])
    seen = seen & _observed(xn)
    n_views = seen.sum(axis=0)
    points = np.full((3, N), np.nan)            # rows x, y, z
    reason = np.full(N, _FEW, np.int8)          # codes into _REASON_NAMES
    rejected = np.zeros((C, N), bool)
    todo = np.flatnonzero(n_views >= 2)
    if todo.size:
        Ps = np.stack([np.hstack([cam.rotation_matrix, cam.translation[:, None]]) for cam in cam_objs])
        if todo.size == N:
            X = _solve_views(cam_objs, xn, px, seen, Ps)
        else:
            X = _solve_views(cam_objs, xn[:, todo], px[:, todo], seen[:, todo], Ps)
        points[:, todo] = X
        reason[todo] = _OK
        reason[todo[~_finite_rows(X)]] = _FAILED
    # every camera's residuals of every point, once: the consistency check's first round and the result's
    # residuals (recomputed below only where the check changed a point)
    resid = _residuals(cam_objs, points, px)
    changed = False
    if max_residual_px is not None and todo.size:
        used = seen.copy()
        for k in range(C):
            idx = todo[reason[todo] == _OK]
            if idx.size == 0:
                break
            worst = (_worst(resid[:, idx], used[:, idx]) if k == 0
                     else _max_residual(cam_objs, points[:, idx], px[:, idx], used[:, idx]))
            bad = idx[worst > max_residual_px]
            if bad.size == 0:
                break
            changed = True
            few = bad[used[:, bad].sum(axis=0) <= 2]
            reason[few] = _INCONSISTENT
            points[:, few] = np.nan
            multi = bad[used[:, bad].sum(axis=0) > 2]
            if multi.size == 0:
                break
            # leave each camera out in turn; keep the subset with the smallest largest residual
            best_r = np.full(multi.size, np.inf)
            best_c = np.full(multi.size, -1)
            best_X = np.full((3, multi.size), np.nan)
            for c in range(C):
                cand = used[c, multi]
                if not cand.any():
                    continue
                sub = used[:, multi[cand]].copy()
                sub[c] = False
                Xc = _solve_views(cam_objs, xn[:, multi[cand]], px[:, multi[cand]], sub, Ps)
                rc_ = _max_residual(cam_objs, Xc, px[:, multi[cand]], sub)
                rc_ = np.where(_finite_rows(Xc), rc_, np.inf)
                pos = np.flatnonzero(cand)
                better = rc_ < best_r[pos]
                best_r[pos[better]] = rc_[better]
                best_c[pos[better]] = c
                best_X[:, pos[better]] = Xc[:, better]
            ok = best_c >= 0
            points[:, multi[ok]] = best_X[:, ok]
            used[best_c[ok], multi[ok]] = False
            rejected[best_c[ok], multi[ok]] = True
            points[:, multi[~ok]] = np.nan
            reason[multi[~ok]] = _INCONSISTENT
        n_views = used.sum(axis=0)
    if changed:
        resid = _residuals(cam_objs, points, px)
    return (np.ascontiguousarray(points.T).reshape(n, m, 3), _REASON_NAMES[reason].reshape(n, m),
            n_views.reshape(n, m), rejected.reshape(C, n, m), resid.reshape(C, n, m))


# ---------------------------------------------------------------------------
# uncertainty of the triangulated points
# ---------------------------------------------------------------------------

def pixel_noise(residual_px: dict, used: dict) -> float:
    """Detection noise (pixels, per image coordinate) estimated from reprojection residuals.

    A point fitted to the ``2 k`` pixel coordinates of the ``k`` cameras that
    saw it leaves ``2 k - 3`` degrees of freedom, and for white detection
    noise of ``sigma`` pixels per coordinate ``E sum_c |r_c|^2 = (2 k - 3)
    sigma^2``. Pooled over every point with ``k >= 2``:
    ``sigma = sqrt(sum |r|^2 / sum (2 k - 3))``.

    Parameters
    ----------
    residual_px : dict of str -> (n, m)
        Reprojection distances (pixels) per camera (:attr:`Triangulation.residual_px`).
    used : dict of str -> (n, m) bool
        The detections the points were computed from (a rejected one is not).

    Returns
    -------
    float
        NaN when no point has two cameras.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> rig3 = Rig((left, Camera("middle", (640, 480), K, translation=[-0.25, 0.0, 0.0]), right))
    >>> points = np.array([[[0.1, 0.0, 2.0], [-0.2, 0.1, 3.0]]])     # 1 frame, 2 markers (m)
    >>> px = rig3.project(points)
    >>> px["left"] = px["left"] + [0.5, 0.0]             # the left camera's detections half a pixel off
    >>> result = triangulate(rig3, px)
    >>> used = {name: np.ones((1, 2), bool) for name in rig3.names}
    >>> round(pixel_noise(result.residual_px, used), 4)
    0.1179
    """
    cams = list(residual_px)
    r = np.stack([np.asarray(residual_px[c], float) for c in cams])
    u = np.stack([np.asarray(used[c], bool) for c in cams]) & np.isfinite(r)
    k = u.sum(axis=0)
    both = k >= 2
    dof = float(np.sum(2 * k[both] - 3))
    if dof <= 0:
        return float("nan")
    return float(np.sqrt(np.sum(np.where(u & both, r, 0.0) ** 2) / dof))


def point_covariance(rig: Rig, points: np.ndarray, used: dict, noise_px: float = 1.0) -> np.ndarray:
    """Covariance (m^2, world frame) of triangulated points for white detection noise.

    Linearised least squares: with ``J`` the Jacobian of the pixels of the
    cameras that saw the point with respect to the point (eq. 3.1-3.10
    differentiated, as the joint refinement's normal equations), a noise of
    ``noise_px`` pixels per image coordinate gives ``noise_px^2 (J^T J)^-1``.
    Depth, along the viewing rays, comes out far less certain than the
    directions across them. For the thesis' pairwise average (eq. 5.5) this
    is the covariance of the best estimate from the same pixels, a little
    smaller than the average's own.

    Parameters
    ----------
    rig : Rig
    points : (n, m, 3)
        Triangulated points (world frame), NaN where missing.
    used : dict of str -> (n, m) bool
        For each camera, the detections the points were computed from.
    noise_px : float
        Detection noise per image coordinate (:func:`pixel_noise`).

    Returns
    -------
    (n, m, 3, 3)
        NaN where the point is missing or seen by fewer than two of the cameras.

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> rig3 = Rig((left, Camera("middle", (640, 480), K, translation=[-0.25, 0.0, 0.0]), right))
    >>> points = np.array([[[0.1, 0.0, 2.0], [-0.2, 0.1, 3.0]]])     # 1 frame, 2 markers (m)
    >>> used = {name: np.ones((1, 2), bool) for name in rig3.names}
    >>> cov = point_covariance(rig3, points, used, noise_px=1.0)
    >>> np.sqrt(np.diag(cov[0, 0])).round(5)           # standard deviations (m): depth (z) the largest
    array([0.00179, 0.00144, 0.01414])
    """
    p = np.asarray(points, float)
    shape = p.shape[:-1]
    X = np.ascontiguousarray(p.reshape(-1, 3).T)
    h = np.zeros((6, X.shape[1]))
    k = np.zeros(X.shape[1], int)
    ok = _finite_rows(X)
    Xs = np.where(ok, X, 0.0)
    for c, w in used.items():
        seen = np.asarray(w, bool).reshape(-1) & ok
        _, _, gu, gv = _project_jacobian(rig[c], Xs, seen)
        h += gu[_PI] * gu[_PJ] + gv[_PI] * gv[_PJ]
        k += seen
    # (J^T J)^-1 by cofactors, all points at once (as _solve3)
    cof, det, scale = _cofactors3(h)
    A = np.stack(cof)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where((k >= 2) & (np.abs(det) > 1e-13 * scale), noise_px ** 2 / det, np.nan)
    cov = np.empty((X.shape[1], 3, 3))
    for n, (i, j) in enumerate(_PAIRS):
        cov[:, i, j] = cov[:, j, i] = A[n] * inv
    return cov.reshape(shape + (3, 3))


def nearest_covariance(covariance: np.ndarray, fill: np.ndarray) -> np.ndarray:
    """Covariances (n, m, 3, 3) with the ``fill`` entries (n, m) taken from the marker's nearest frame that has one.

    For positions that were not triangulated but interpolated over a short
    gap: their error is the interpolation's, which the neighbouring
    measurements' covariance stands for (an approximation; the frames just
    before and after the gap are measured with the same geometry). An entry
    whose marker has no covariance in any frame stays NaN.

    Examples
    --------
    >>> import numpy as np
    >>> cov = np.full((3, 1, 3, 3), np.nan)
    >>> cov[0, 0] = np.eye(3)                            # frame 0 measured; frames 1-2 interpolated
    >>> filled = nearest_covariance(cov, fill=np.array([[False], [True], [True]]))
    >>> float(filled[2, 0, 0, 0])
    1.0
    """
    cov = np.array(covariance, float, copy=True)
    fill = np.asarray(fill, bool)
    have = np.all(np.isfinite(cov), axis=(2, 3)) & ~fill
    for j in range(cov.shape[1]):
        src = np.flatnonzero(have[:, j])
        dst = np.flatnonzero(fill[:, j])
        if src.size == 0 or dst.size == 0:
            continue
        pos = np.searchsorted(src, dst)
        left = src[np.maximum(pos - 1, 0)]
        right = src[np.minimum(pos, src.size - 1)]
        near = np.where(np.abs(dst - left) <= np.abs(right - dst), left, right)
        cov[dst, j] = cov[near, j]
    return cov


# ---------------------------------------------------------------------------
# thesis triangulation
# ---------------------------------------------------------------------------

def _triangulate_thesis(rig, cams, px_all, seen_all, pairs):
    C, n, m, _ = px_all.shape
    index = {c: i for i, c in enumerate(cams)}
    xn = {c: rig[c].pixels_to_normalized(px_all[index[c]]) for c in cams}
    results = {}
    for a, b in pairs:
        R, T = relative_pose(rig[a], rig[b])
        XA, _ = stereo_triangulation(xn[a], xn[b], R, T)
        world = camera_to_world(XA, rig[a])
        results[f"{a}-{b}"] = PairTriangulation((a, b), XA, world)
    stack = np.stack([p.points for p in results.values()])  # (P, n, m, 3)
    finite = np.all(np.isfinite(stack), axis=-1)
    count = finite.sum(axis=0)
    with np.errstate(invalid="ignore"):
        points = np.where(count[..., None] > 0,
                          np.nansum(np.where(finite[..., None], stack, 0.0), axis=0) / np.maximum(count, 1)[..., None],
                          np.nan)  # eq. 5.5 (over the pairs that saw the point)
    used_cams = np.zeros((C, n, m), bool)
    for (a, b), f in zip(pairs, finite):
        used_cams[index[a]] |= f
        used_cams[index[b]] |= f
    used = used_cams.sum(axis=0)
    n_seen = seen_all.sum(axis=0)
    reason = np.full((n, m), "", dtype=object)
    reason[count == 0] = REASON_FAILED
    reason[n_seen < 2] = REASON_FEW_CAMERAS
    points[count == 0] = np.nan
    return points, reason, used, results


# ---------------------------------------------------------------------------
# public entry point
# ---------------------------------------------------------------------------

def triangulate(rig: Rig, marker_px: dict, mode: str = "joint", pairs=None,
                max_residual_px: float | None = DEFAULT_MAX_RESIDUAL_PX,
                covariance: bool = False) -> Triangulation:
    """3D marker positions from the synchronised detections of several cameras.

    Parameters
    ----------
    rig : Rig
        Calibrated cameras; world frame = the reference camera's frame.
    marker_px : dict of str -> array_like, shape (n_frames, n_markers, 2)
        Distorted pixel centroids per camera (thesis ``PM_L``, ``PM_M``,
        ``PM_R``), same frames (synchronised) and marker order in every
        camera; NaN where the marker was not detected.
    mode : {"joint", "thesis"}
        ``"thesis"``: pairwise stereo triangulation and averaging (eq.
        5.1-5.5); ``"joint"``: DLT over all cameras refined by reprojection
        error (see module docstring).
    pairs : sequence of (str, str), optional
        Thesis mode only: the stereo pairs, each ``(locally left, locally
        right)``. Default: the three pairs of a three-camera rig in rig order,
        ``(left, middle), (left, right), (middle, right)``; a rig with another
        number of cameras needs explicit pairs.
    max_residual_px : float or None
        Joint mode only: a point whose largest reprojection error exceeds this
        (default 2 px, ten times a good calibration's error) is inconsistent
        (e.g. a marker swapped in one camera). With three or more views the
        camera whose removal leaves the smallest largest residual is left out
        (recorded in ``rejected``), repeatedly; with two views left the point
        becomes NaN with reason ``"inconsistent_views"``. ``None``: no check
        (the thesis mode never checks).
    covariance : bool
        Also return each point's covariance (:attr:`Triangulation.covariance`,
        :func:`point_covariance` over the detections used) for the detection
        noise estimated from the residuals (:func:`pixel_noise`). Off by
        default (it costs one more Jacobian per camera and point).

    Returns
    -------
    Triangulation
        ``points`` (n, m, 3) world frame in metres (thesis ``CM_L``),
        ``residual_px`` per camera, ``reason`` per frame and marker.

    Notes
    -----
    A marker seen by fewer than two cameras in a frame is NaN with reason
    ``"seen_by_fewer_than_two_cameras"``. In thesis mode a point seen by
    exactly two cameras is the result of the one pair that saw it (the thesis
    averages three pairs, eq. 5.5; ``n_views`` tells how many cameras were used).

    Examples
    --------
    >>> import numpy as np
    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> rig3 = Rig((left, Camera("middle", (640, 480), K, translation=[-0.25, 0.0, 0.0]), right))
    >>> points = np.array([[[0.1, 0.0, 2.0], [-0.2, 0.1, 3.0]]])     # 1 frame, 2 markers (m)
    >>> result = triangulate(rig3, rig3.project(points))            # joint: all cameras at once
    >>> result.points.round(6)
    array([[[ 0.1,  0. ,  2. ],
            [-0.2,  0.1,  3. ]]])
    >>> result.n_views, result.valid
    (array([[3, 3]]), array([[ True,  True]]))

    The thesis' chain: each pair triangulated, the three averaged (eq. 5.5):

    >>> thesis = triangulate(rig3, rig3.project(points), mode="thesis",
    ...                      pairs=[("left", "middle"), ("left", "right"), ("middle", "right")])
    >>> sorted(thesis.pairs), bool(np.allclose(thesis.points, points))
    (['left-middle', 'left-right', 'middle-right'], True)

    A marker one camera did not see is triangulated from the other two; one
    seen by a single camera has no position, and says why:

    >>> px = rig3.project(points)
    >>> px["left"][0, 0] = np.nan
    >>> px["middle"][0, 1] = px["right"][0, 1] = np.nan
    >>> result = triangulate(rig3, px)
    >>> result.n_views.tolist(), result.reason.tolist()
    ([[2, 1]], [['', 'seen_by_fewer_than_two_cameras']])
    """
    if mode not in ("joint", "thesis"):
        raise ValueError(f"mode must be 'joint' or 'thesis', got {mode!r}")
    cams, (n, m) = _check_inputs(rig, marker_px)
    if len(cams) < 2:
        raise ValueError(f"triangulate: need detections from at least two cameras, got {cams}")
    px_all = np.stack([np.asarray(marker_px[c], float) for c in cams])
    seen_all = _observed(px_all)
    pair_results = {}
    rejected = {c: np.zeros((n, m), bool) for c in cams}
    if mode == "joint":
        if pairs is not None:
            raise ValueError("pairs is only used in mode='thesis'")
        points, reason, n_views, rejected_arr, resid = _triangulate_joint(rig, cams, px_all, seen_all,
                                                                          max_residual_px)
        rejected = {c: rejected_arr[i] for i, c in enumerate(cams)}
    else:
        if pairs is None:
            if len(cams) != 3:
                raise ValueError(
                    f"thesis mode (eq. 5.1-5.5) needs the three cameras of the thesis rig, got {len(cams)} "
                    f"({cams}); pass pairs=[(a, b), ...] explicitly or use mode='joint'")
            pairs = [(cams[0], cams[1]), (cams[0], cams[2]), (cams[1], cams[2])]
        pairs = [tuple(p) for p in pairs]
        for p in pairs:
            if len(p) != 2 or p[0] not in cams or p[1] not in cams or p[0] == p[1]:
                raise ValueError(f"pairs: {p!r} is not a pair of two different cameras among {cams}")
        points, reason, n_views, pair_results = _triangulate_thesis(rig, cams, px_all, seen_all, pairs)
        reason = reason.astype(_REASON_NAMES.dtype)
        resid = None
    # points behind a camera that saw them are not physical
    valid = reason == ""
    dropped = np.zeros(valid.shape, bool)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    for i, c in enumerate(cams):
        cam = rig[c]
        r, t = cam.rotation_matrix[2], cam.translation[2]
        depth = x * r[0] + y * r[1] + z * r[2] + t
        with np.errstate(invalid="ignore"):
            behind = seen_all[i] & valid & ~(depth > 0)
        reason[behind] = REASON_BEHIND
        valid &= ~behind
        dropped |= behind
    points = np.where(valid[..., None], points, np.nan)
    if resid is None:
        residuals = reprojection_residuals(rig, points, {c: px_all[i] for i, c in enumerate(cams)})
    elif dropped.any():   # the joint solve's residuals, NaN where the point was dropped (behind a camera)
        residuals = {c: np.where(dropped, np.nan, resid[i]) for i, c in enumerate(cams)}
    else:
        residuals = {c: resid[i] for i, c in enumerate(cams)}
    cov = noise = None
    if covariance:
        used = {c: seen_all[i] & ~rejected[c] & valid for i, c in enumerate(cams)}
        noise = pixel_noise(residuals, used)
        if np.isfinite(noise) and noise > 0:      # else no point has a residual: no noise to propagate
            cov = point_covariance(rig, points, used, noise)
    return Triangulation(
        points=points,
        residual_px=residuals,
        reason=reason,
        n_views=np.asarray(n_views, int),
        mode=mode,
        cameras=tuple(cams),
        pairs=pair_results,
        rejected=rejected,
        covariance=cov,
        noise_px=noise,
    )
