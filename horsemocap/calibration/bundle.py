"""Intrinsic calibration of one camera and bundle adjustment of several.

Thesis section 3.4: the camera model of Heikkilä and Silvén that Bouguet's
toolbox (and OpenCV) implement, eq. 3.4-3.10: ``x_c = R_CW X + t_CW``
(eq. 3.4), pinhole projection (3.5), radial ``k1, k2 (, k3)`` and tangential
``p1, p2`` distortion (3.7-3.9), pixels through ``fc, cc`` (3.6, 3.10).

* :func:`calibrate_camera`: one camera, its views of the board (Appendix A
  step 2, the toolbox's ``calib_gui``), with OpenCV's Levenberg-Marquardt
  (``calibrateCameraExtended``); uncertainties from its Jacobian.
* :func:`bundle_adjust`: any number of cameras that see the same board views,
  all intrinsics, the camera poses relative to the reference camera and the
  board poses refined together by minimising the reprojection error. With two
  cameras it is the toolbox's ``stereo_gui`` (Appendix A step 3, Table 8.4);
  with all three it is the joint calibration of the whole rig.

Uncertainties follow the toolbox: ``3 * sigma * sqrt(diag((J^T J)^-1))``,
three standard deviations, with ``sigma`` the residual standard deviation.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..camera import Camera, Rig, rotation_matrix, rotation_vector
from ..threads import blas_single_threaded, opencv_single_threaded
from .board import BoardViews, CalibrationError, excluded_view_keys

#: Names of the 9 intrinsic parameters, in OpenCV's order.
INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


@dataclass(frozen=True)
class IntrinsicResult:
    """Calibrated intrinsics of one camera (thesis Tables 8.1-8.3).

    Attributes
    ----------
    camera : str
    size : (width, height)
    matrix : ndarray (3, 3)
        ``KK``.
    distortions : ndarray (5,)
        ``kc = [k1, k2, p1, p2, k3]``.
    sigma3 : ndarray (9,)
        Three standard deviations of ``fx, fy, cx, cy, k1, k2, p1, p2, k3``
        (the toolbox's ``fc_error, cc_error, kc_error``); 0 for a fixed one.
    view_names : tuple of str
    used : ndarray of bool (views,)
        Views that took part in the calibration.
    reasons : tuple of str
        Why a view did not take part (``"excluded"``, board not found), ``""``
        if it did.
    per_view_rms : ndarray (views,)
        RMS reprojection error of each view, pixels (NaN for unused views).
    rms : float
        RMS reprojection error over all used views, pixels.
    err_std : ndarray (2,)
        Standard deviation of the x and y residuals (the toolbox's ``err_std``).
    rvecs, tvecs : ndarray (views, 3)
        Board pose in this camera's frame per view (``omc_i``, ``Tc_i``; metres).
    """

    camera: str
    size: tuple
    matrix: np.ndarray
    distortions: np.ndarray
    sigma3: np.ndarray
    view_names: tuple
    used: np.ndarray
    reasons: tuple
    per_view_rms: np.ndarray
    rms: float
    err_std: np.ndarray
    rvecs: np.ndarray
    tvecs: np.ndarray

    @property
    def fc(self) -> np.ndarray:
        return np.array([self.matrix[0, 0], self.matrix[1, 1]])

    @property
    def cc(self) -> np.ndarray:
        return np.array([self.matrix[0, 2], self.matrix[1, 2]])

    @property
    def kc(self) -> np.ndarray:
        return np.asarray(self.distortions, float)

    @property
    def fc_error(self) -> np.ndarray:
        return self.sigma3[0:2]

    @property
    def cc_error(self) -> np.ndarray:
        return self.sigma3[2:4]

    @property
    def kc_error(self) -> np.ndarray:
        return self.sigma3[4:9]

    def as_camera(self, rotation=(0, 0, 0), translation=(0, 0, 0)) -> Camera:
        """This camera as a :class:`~horsemocap.camera.Camera` with the given pose."""
        return Camera(self.camera, self.size, self.matrix, self.distortions, rotation, translation)


def _usable(views: BoardViews, exclude) -> tuple[np.ndarray, list[str]]:
    try:      # a view named by its key or by its file
        exclude = excluded_view_keys(views.camera, views.names, views.files, list(exclude or ()))
    except ValueError as exc:
        raise CalibrationError(str(exc)) from None
    used, reasons = [], []
    for name, why in zip(views.names, views.reasons):
        if name in exclude:
            used.append(False)
            reasons.append("excluded")
        else:
            used.append(why == "")
            reasons.append(why)
    return np.array(used, bool), reasons


def calibrate_camera(views: BoardViews, board_pts: np.ndarray, exclude=(), *, fix_k3: bool = True,
                     fix_tangential: bool = False) -> IntrinsicResult:
    """Calibrate one camera from its checkerboard views (thesis 3.4, Appendix A step 2).

    Parameters
    ----------
    views : BoardViews
        Detected corners (``x_i``) of every view.
    board_pts : ndarray (cols*rows, 3)
        Board-frame corners (``X_i``), metres.
    exclude : iterable of str
        View names to leave out (a bad view; the calibration is redone without it).
    fix_k3 : bool
        Keep ``k3 = 0`` (the thesis' model of section 3.4 has ``k1, k2`` only,
        and so does the toolbox's default). Skew is always 0 (OpenCV has none).
    fix_tangential : bool
        Keep ``p1 = p2 = 0``.

    Returns
    -------
    IntrinsicResult
    """
    used, reasons = _usable(views, exclude)
    if used.sum() < 3:
        raise CalibrationError(
            f"camera {views.camera!r}: only {int(used.sum())} usable views of the board "
            f"(need at least 3); not found: {views.missing()}")
    idx = np.flatnonzero(used)
    obj = [board_pts.astype(np.float32)] * len(idx)
    img = [views.corners[k].astype(np.float32).reshape(-1, 1, 2) for k in idx]
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    if fix_tangential:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    # OpenCV's parallel sums change the last digits from run to run; its BLAS threads only wait
    with opencv_single_threaded(), blas_single_threaded():
        rms, K, dist, rv, tv, std_i, _std_e, per_view = cv2.calibrateCameraExtended(
            obj, img, tuple(views.size), None, None, flags=flags, criteria=crit)
    dist = np.asarray(dist, float).ravel()[:5]
    sigma3 = 3.0 * np.asarray(std_i, float).ravel()[:9]
    nv = len(views.names)
    per = np.full(nv, np.nan)
    per[idx] = np.asarray(per_view, float).ravel()
    rvecs = np.full((nv, 3), np.nan)
    tvecs = np.full((nv, 3), np.nan)
    res = []
    for j, k in enumerate(idx):
        rvecs[k] = np.asarray(rv[j]).ravel()
        tvecs[k] = np.asarray(tv[j]).ravel()
        proj, _ = cv2.projectPoints(board_pts, rvecs[k], tvecs[k], K, dist)
        res.append(proj.reshape(-1, 2) - views.corners[k])
    res = np.concatenate(res)
    return IntrinsicResult(views.camera, tuple(views.size), np.asarray(K, float), dist, sigma3,
                           tuple(views.names), used, tuple(reasons), per,
                           float(np.sqrt(np.mean(np.sum(res**2, axis=1)))), res.std(axis=0, ddof=0),
                           rvecs, tvecs)


# ---------------------------------------------------------------------------
# bundle adjustment of several cameras
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class BundleResult:
    """Cameras calibrated together (a stereo pair, or the whole rig).

    Attributes
    ----------
    cameras : tuple of str
        Camera names; ``cameras[0]`` is the reference (world frame).
    intrinsics : dict[str, IntrinsicResult]
        Intrinsics refined in the bundle, with their 3-sigma uncertainties and
        the per-view RMS of this camera in the bundle.
    rotations, translations : ndarray (cameras, 3)
        Pose of every camera relative to the reference, ``x_c = R x_ref + t``
        (Rodrigues vector, metres). For a pair, row 1 is the toolbox's
        ``om, T`` (Table 8.4's ``R_ML, t_ML``).
    rotation_sigma3, translation_sigma3 : ndarray (cameras, 3)
        Three standard deviations of those (``om_error``, ``T_error``).
    view_names : tuple of str
    view_rvecs, view_tvecs : ndarray (views, 3)
        Board pose in the reference frame (NaN for unused views).
    rms : float
        RMS reprojection error over every camera and view, pixels.
    sigma : float
        Residual standard deviation per coordinate, pixels.
    iterations : int
    """

    cameras: tuple
    intrinsics: dict
    rotations: np.ndarray
    translations: np.ndarray
    rotation_sigma3: np.ndarray
    translation_sigma3: np.ndarray
    view_names: tuple
    view_rvecs: np.ndarray
    view_tvecs: np.ndarray
    rms: float
    sigma: float
    iterations: int

    @property
    def om(self) -> np.ndarray:
        """Rodrigues vector of the second camera relative to the first (a pair's ``om``)."""
        return self.rotations[1]

    @property
    def T(self) -> np.ndarray:
        """Translation of the second camera relative to the first (a pair's ``T``), metres."""
        return self.translations[1]

    def rig(self, metadata: dict | None = None) -> Rig:
        """The calibrated cameras as a :class:`~horsemocap.camera.Rig` (world = reference)."""
        cams = tuple(self.intrinsics[n].as_camera(self.rotations[i], self.translations[i])
                     for i, n in enumerate(self.cameras))
        meta = {"adjusted": True, "error": round(float(self.rms), 6)}
        meta.update(metadata or {})
        return Rig(cams, meta)


def _pose_mean(rvecs, tvecs):
    """Robust mean pose: keep the poses within 2 degrees of the medoid rotation."""
    Rs = np.array([rotation_matrix(r) for r in rvecs])
    n = len(Rs)
    if n > 2:
        # every pair's angle at once: trace(Ra^T Rb) is the sum of the elementwise products
        ang = np.arccos(np.clip((np.einsum("aij,bij->ab", Rs, Rs) - 1) / 2, -1, 1))
        med = int(np.argmin(ang.sum(axis=1)))
        keep = ang[med] < np.deg2rad(2.0)
        Rs, tvecs = Rs[keep], np.asarray(tvecs)[keep]
    return rotation_vector(Rs.mean(axis=0)), np.median(np.asarray(tvecs), axis=0)


def flip_view(corners, rvec, tvec, board_pts):
    """Reverse a view's corner order and move its board pose to match.

    Reversing the order is turning the board by 180 degrees about its normal:
    ``X' = Rz(pi) X + [W, H, 0]``, so ``x_cam = (R Rz) X + (R [W, H, 0] + t)``.
    """
    W, H = float(np.max(board_pts[:, 0])), float(np.max(board_pts[:, 1]))
    R = rotation_matrix(rvec)
    Rz = np.diag([-1.0, -1.0, 1.0])
    return (np.asarray(corners)[::-1].copy(), rotation_vector(R @ Rz),
            R @ np.array([W, H, 0.0]) + np.asarray(tvec))


def harmonize_views(views: list[BoardViews], singles: list[IntrinsicResult], board_pts: np.ndarray):
    """Make every camera number the corners of each view like the reference camera.

    OpenCV may return a board's corners in either of two opposite orders
    (:func:`~horsemocap.calibration.board.canonical_order` settles most, not
    all). With the relative pose of the cameras estimated robustly from the
    views that agree, each view of each camera is predicted from the other
    cameras, and its corner order is reversed when the reversed order fits the
    prediction better. Returns corrected ``(views, singles)`` and a list of
    ``(camera, view)`` that were reversed.
    """
    from dataclasses import replace

    views, singles = list(views), list(singles)
    used = np.array([s.used for s in singles])
    flipped = []
    for c in range(1, len(views)):
        common = np.flatnonzero(used[c] & used[0])
        if common.size == 0:
            continue
        rs, ts = [], []
        for v in common:
            rinv, tinv = _invert(singles[0].rvecs[v], singles[0].tvecs[v])
            r_cp, t_cp = _compose(rinv, tinv, singles[c].rvecs[v], singles[c].tvecs[v])
            rs.append(r_cp)
            ts.append(t_cp)
        r_c0, t_c0 = _pose_mean(rs, ts)
        corners = views[c].corners.copy()
        rv, tv = singles[c].rvecs.copy(), singles[c].tvecs.copy()
        changed = False
        for v in common:
            r_pred, t_pred = _compose(singles[0].rvecs[v], singles[0].tvecs[v], r_c0, t_c0)
            proj, _ = cv2.projectPoints(board_pts, r_pred, t_pred, singles[c].matrix, singles[c].distortions)
            proj = proj.reshape(-1, 2)
            e_keep = np.median(np.linalg.norm(proj - corners[v], axis=1))
            e_flip = np.median(np.linalg.norm(proj - corners[v][::-1], axis=1))
            if e_flip < e_keep:
                corners[v], rv[v], tv[v] = flip_view(corners[v], rv[v], tv[v], board_pts)
                flipped.append((views[c].camera, views[c].names[v]))
                changed = True
        if changed:
            views[c] = replace(views[c], corners=corners)
            singles[c] = replace(singles[c], rvecs=rv, tvecs=tv)
    return views, singles, flipped


def _compose(r1, t1, r2, t2):
    """Pose ``x -> R2 (R1 x + t1) + t2`` as (rvec, tvec)."""
    R = rotation_matrix(r2) @ rotation_matrix(r1)
    return rotation_vector(R), rotation_matrix(r2) @ np.asarray(t1) + np.asarray(t2)


def _invert(r, t):
    R = rotation_matrix(r)
    return rotation_vector(R.T), -R.T @ np.asarray(t)


def initial_poses(singles: list[IntrinsicResult], used: np.ndarray):
    """Starting camera and board poses from single-camera calibrations.

    Every camera is placed relative to the reference (``singles[0]``) through
    the views both saw (mean rotation, median translation), breadth-first
    through other cameras when it shares no view with the reference.
    """
    nc, nv = used.shape
    cam_r = [None] * nc
    cam_t = [None] * nc
    cam_r[0], cam_t[0] = np.zeros(3), np.zeros(3)
    placed = {0}
    while len(placed) < nc:
        progress = False
        for c in range(nc):
            if c in placed:
                continue
            for p in sorted(placed):
                common = np.flatnonzero(used[c] & used[p])
                if common.size == 0:
                    continue
                rs, ts = [], []
                for v in common:
                    # board -> p, then p -> c : x_c = T_cb T_pb^-1 x_p
                    rinv, tinv = _invert(singles[p].rvecs[v], singles[p].tvecs[v])
                    r_cp, t_cp = _compose(rinv, tinv, singles[c].rvecs[v], singles[c].tvecs[v])
                    rs.append(r_cp)
                    ts.append(t_cp)
                r_cp, t_cp = _pose_mean(rs, ts)
                cam_r[c], cam_t[c] = _compose(cam_r[p], cam_t[p], r_cp, t_cp)
                placed.add(c)
                progress = True
                break
        if not progress:
            missing = [singles[c].camera for c in range(nc) if c not in placed]
            raise CalibrationError(f"cameras {missing} share no board view with camera "
                                   f"{singles[0].camera!r} (directly or through another camera)")
    view_r = np.full((nv, 3), np.nan)
    view_t = np.full((nv, 3), np.nan)
    for v in range(nv):
        for c in range(nc):
            if used[c, v]:
                rinv, tinv = _invert(cam_r[c], cam_t[c])
                view_r[v], view_t[v] = _compose(singles[c].rvecs[v], singles[c].tvecs[v], rinv, tinv)
                break
    return np.array(cam_r), np.array(cam_t), view_r, view_t


@blas_single_threaded()
def bundle_adjust(views: list[BoardViews], singles: list[IntrinsicResult], board_pts: np.ndarray,
                  *, fix_k3: bool = True, fix_intrinsics: bool = False, max_iter: int = 100,
                  tol: float = 1e-10) -> BundleResult:
    """Refine several cameras, their relative poses and the board poses together.

    Minimises ``sum_c sum_v || x_cv - proj_c(R_c (R_v X + t_v) + t_c) ||^2``
    over the intrinsics of every camera (eq. 3.5-3.10), the poses ``(R_c,
    t_c)`` of cameras ``c > 0`` relative to the reference camera 0 and the
    board poses ``(R_v, t_v)`` in the reference frame, by Levenberg-Marquardt
    with the analytic Jacobian (``cv2.projectPoints`` and ``cv2.composeRT``).
    Two cameras: the toolbox's stereo calibration (Table 8.4). All cameras:
    the joint calibration that gives one consistent rig.

    Parameters
    ----------
    views : list of BoardViews
        Corners per camera; the same index is the same instant in every camera.
    singles : list of IntrinsicResult
        Single-camera calibrations (starting values; their ``used`` masks say
        which views take part).
    board_pts : ndarray (N, 3)
        ``X_i`` in metres.
    fix_k3 : bool
        Keep ``k3 = 0``.
    fix_intrinsics : bool
        Refine poses only (intrinsics as given).

    Returns
    -------
    BundleResult

    Notes
    -----
    Runs with one BLAS thread (:data:`horsemocap.threads.blas_single_threaded`): its normal
    equations have a few hundred columns, where a second BLAS thread costs more processor time
    than it saves (:mod:`horsemocap.threads`).
    """
    nv = len(views[0].names)
    if any(len(v.names) != nv for v in views):
        raise CalibrationError("bundle_adjust: every camera needs the same list of views")
    used = np.array([s.used for s in singles])
    cam_r, cam_t, view_r, view_t = initial_poses(singles, used)
    free_int = np.ones(9, bool)
    if fix_k3:
        free_int[8] = False
    if fix_intrinsics:
        free_int[:] = False
    layout = _BundleLayout(len(views), nv, free_int, np.flatnonzero(used.any(axis=0)),
                           np.array([[s.matrix[0, 0], s.matrix[1, 1], s.matrix[0, 2], s.matrix[1, 2], *s.distortions]
                                     for s in singles]))
    obs = [(c, v) for c in range(layout.nc) for v in layout.active if used[c, v]]

    def residuals_normal(x, want_normal=True):
        return _normal_equations(layout, x, views, obs, board_pts, want_normal)

    x0 = layout.pack(layout.intr0, cam_r, cam_t, view_r, view_t)
    x, r, A, cost, it = _levenberg_marquardt(residuals_normal, x0, max_iter, tol)
    return _bundle_result(layout, x, r, A, cost, it, views, singles, used, obs)


@dataclass(frozen=True)
class _BundleLayout:
    """Where the unknowns of :func:`bundle_adjust` sit in its parameter vector:
    ``[free intrinsics of each camera] [pose of cameras 1..] [pose of each active view]``."""

    nc: int
    nv: int
    free_int: np.ndarray
    active: np.ndarray
    intr0: np.ndarray

    @property
    def nfi(self) -> int:
        """Free intrinsics per camera."""
        return int(self.free_int.sum())

    @property
    def off_cam(self) -> int:
        """Index of the first camera pose."""
        return self.nc * self.nfi

    @property
    def off_view(self) -> int:
        """Index of the first view pose."""
        return self.off_cam + 6 * (self.nc - 1)

    @property
    def vpos(self) -> dict:
        """Index of each active view's pose."""
        return {v: self.off_view + 6 * j for j, v in enumerate(self.active)}

    @property
    def npar(self) -> int:
        return self.off_view + 6 * len(self.active)

    def pack(self, intr, cr, ct, vr, vt) -> np.ndarray:
        nc, nfi, off_cam = self.nc, self.nfi, self.off_cam
        x = np.empty(self.npar)
        for c in range(nc):
            x[c * nfi:(c + 1) * nfi] = intr[c][self.free_int]
        for c in range(1, nc):
            x[off_cam + 6 * (c - 1): off_cam + 6 * c] = np.r_[cr[c], ct[c]]
        for v, p in self.vpos.items():
            x[p:p + 6] = np.r_[vr[v], vt[v]]
        return x

    def unpack(self, x):
        nc, nfi, off_cam = self.nc, self.nfi, self.off_cam
        intr = self.intr0.copy()
        for c in range(nc):
            intr[c][self.free_int] = x[c * nfi:(c + 1) * nfi]
        cr, ct = np.zeros((nc, 3)), np.zeros((nc, 3))
        for c in range(1, nc):
            seg = x[off_cam + 6 * (c - 1): off_cam + 6 * c]
            cr[c], ct[c] = seg[:3], seg[3:]
        vr, vt = np.full((self.nv, 3), np.nan), np.full((self.nv, 3), np.nan)
        for v, p in self.vpos.items():
            vr[v], vt[v] = x[p:p + 6][:3], x[p:p + 6][3:]
        return intr, cr, ct, vr, vt


def _camera_matrix(intr_c) -> np.ndarray:
    """``KK`` of one camera's intrinsics ``fx, fy, cx, cy, ...``."""
    return np.array([[intr_c[0], 0, intr_c[2]], [0, intr_c[1], intr_c[3]], [0, 0, 1.0]])


def _normal_equations(layout: _BundleLayout, x, views, obs, board_pts, want_normal=True):
    """Residuals, and the Gauss-Newton normal equations ``(J^T J, J^T r)``: each observation's
    Jacobian is dense in its own columns (its camera's intrinsics and pose, its view's pose),
    so its block ``J_k^T J_k`` is added where those columns meet (no sparse ``J`` is built)."""
    intr, cr, ct, vr, vt = layout.unpack(x)
    nfi, off_cam, vpos, npar = layout.nfi, layout.off_cam, layout.vpos, layout.npar
    npts = board_pts.shape[0]
    res = np.empty(2 * npts * len(obs))
    A, g = (np.zeros((npar, npar)), np.zeros(npar)) if want_normal else (None, None)
    for k, (c, v) in enumerate(obs):
        (r3, t3, dr3dr1, dr3dt1, dr3dr2, dr3dt2, dt3dr1, dt3dt1, dt3dr2, dt3dt2) = cv2.composeRT(
            vr[v], vt[v], cr[c], ct[c])
        proj, jac = cv2.projectPoints(board_pts, r3, t3, _camera_matrix(intr[c]), intr[c, 4:9])
        rk = (proj.reshape(-1, 2) - views[c].corners[v]).ravel()
        res[2 * npts * k:2 * npts * (k + 1)] = rk
        if not want_normal:
            continue
        Jr, Jt = jac[:, 0:3], jac[:, 3:6]
        Jint = jac[:, 6:15]  # fx fy cx cy k1 k2 p1 p2 k3
        blocks, cols = [], []
        if nfi:
            blocks.append(Jint[:, layout.free_int])
            cols.append(c * nfi + np.arange(nfi))
        if c > 0:
            blocks += [Jr @ dr3dr2 + Jt @ dt3dr2, Jr @ dr3dt2 + Jt @ dt3dt2]
            cols.append(off_cam + 6 * (c - 1) + np.arange(6))
        blocks += [Jr @ dr3dr1 + Jt @ dt3dr1, Jr @ dr3dt1 + Jt @ dt3dt1]
        cols.append(vpos[v] + np.arange(6))
        Jk, cols = np.hstack(blocks), np.concatenate(cols)
        A[np.ix_(cols, cols)] += Jk.T @ Jk
        g[cols] += Jk.T @ rk
    return res, (A, g)


def _levenberg_marquardt(residuals_normal, x, max_iter: int, tol: float):
    """Levenberg-Marquardt on the scaled normal equations; returns ``x, r, A, cost, iterations``."""
    r, (A, g) = residuals_normal(x)
    npar = x.size
    cost = float(r @ r)
    lam = 1e-3
    it = 0
    for it in range(1, max_iter + 1):
        d = np.sqrt(np.maximum(np.diag(A), 1e-300))
        As = A / d[:, None] / d[None, :]
        gs = g / d
        improved = False
        for _ in range(20):
            try:
                step = -np.linalg.solve(As + lam * np.eye(npar), gs) / d
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            x_new = x + step
            r_new, _ = residuals_normal(x_new, want_normal=False)
            cost_new = float(r_new @ r_new)
            if cost_new < cost:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        rel = (cost - cost_new) / max(cost, 1e-300)
        x, lam = x_new, max(lam / 10, 1e-12)
        r, (A, g) = residuals_normal(x)
        cost = float(r @ r)
        if rel < tol:
            break
    return x, r, A, cost, it


def _bundle_result(layout: _BundleLayout, x, r, A, cost, it, views, singles, used, obs) -> BundleResult:
    """The :class:`BundleResult` at the solution: intrinsics per camera with their 3-sigma, poses, RMS."""
    nc, nv, nfi, off_cam = layout.nc, layout.nv, layout.nfi, layout.off_cam
    intr, cr, ct, vr, vt = layout.unpack(x)
    dof = max(r.size - layout.npar, 1)
    sigma = float(np.sqrt(cost / dof))
    try:
        cov = np.linalg.inv(A) * sigma**2
        sd3 = 3 * np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        sd3 = np.full(layout.npar, np.nan)
    intrinsics = {}
    resid = r.reshape(len(obs), -1, 2)
    for c in range(nc):
        s3 = np.zeros(9)
        if nfi:
            s3[layout.free_int] = sd3[c * nfi:(c + 1) * nfi]
        per = np.full(nv, np.nan)
        rc = []
        rv_c, tv_c = np.full((nv, 3), np.nan), np.full((nv, 3), np.nan)
        for k, (cc_, v) in enumerate(obs):
            if cc_ != c:
                continue
            per[v] = float(np.sqrt(np.mean(np.sum(resid[k] ** 2, axis=1))))
            rc.append(resid[k])
            rv_c[v], tv_c[v] = _compose(vr[v], vt[v], cr[c], ct[c])
        rc = np.concatenate(rc)
        intrinsics[views[c].camera] = IntrinsicResult(
            views[c].camera, tuple(views[c].size), _camera_matrix(intr[c]), intr[c, 4:9].copy(), s3,
            tuple(views[c].names), used[c].copy(), singles[c].reasons, per,
            float(np.sqrt(np.mean(np.sum(rc**2, axis=1)))), rc.std(axis=0), rv_c, tv_c)
    rs3, ts3 = np.zeros((nc, 3)), np.zeros((nc, 3))
    for c in range(1, nc):
        seg = sd3[off_cam + 6 * (c - 1): off_cam + 6 * c]
        rs3[c], ts3[c] = seg[:3], seg[3:]
    rms = float(np.sqrt(np.mean(np.sum(resid**2, axis=2))))
    return BundleResult(tuple(v.camera for v in views), intrinsics, cr, ct, rs3, ts3,
                        tuple(views[0].names), vr, vt, rms, sigma, it)
