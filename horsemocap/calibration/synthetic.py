"""Virtual checkerboard views with exact truth, to test the calibration.

A board of ``cols x rows`` inner corners is drawn (anti-aliased by
super-sampling, through the camera's lens distortion, eq. 3.7-3.10) as a
camera of a known rig sees it; the true corner pixels are the projections of
the board points. Used by the tests and, when the virtual laboratory's
session is absent, by the calibration notebook (caliscope's approach: test
against synthetic scenes with known truth).
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..camera import Camera, Rig, rotation_matrix, rotation_vector
from .board import board_points


def _undistort(xd: np.ndarray, kc: np.ndarray, iterations: int = 12) -> np.ndarray:
    k1, k2, p1, p2, k3 = kc
    x = xd.copy()
    for _ in range(iterations):
        r2 = (x**2).sum(-1)
        rad = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
        dx = 2 * p1 * x[..., 0] * x[..., 1] + p2 * (r2 + 2 * x[..., 0] ** 2)
        dy = p1 * (r2 + 2 * x[..., 1] ** 2) + 2 * p2 * x[..., 0] * x[..., 1]
        x = np.stack([(xd[..., 0] - dx) / rad, (xd[..., 1] - dy) / rad], -1)
    return x


def render_board(camera: Camera, rvec, tvec, inner_corners, square_m: float, *, ss: int = 3,
                 blur_sigma: float = 0.6, noise_sigma: float = 2.0, seed: int = 0,
                 background: int = 60) -> np.ndarray:
    """Gray image ``(h, w)`` of a checkerboard at pose ``(rvec, tvec)`` in the camera's world frame.

    The board's squares span ``(-1 .. cols) x (-1 .. rows)`` squares around the
    inner corners, with a white margin of half a square; corner ``(i, j)`` is
    at ``(i, j) * square_m`` (:func:`~.board.board_points`).
    """
    w, h = camera.size
    cols, rows = inner_corners
    # board pose in the camera frame
    Rw, tw = rotation_matrix(rvec), np.asarray(tvec, float)
    R = camera.rotation_matrix @ Rw
    t = camera.rotation_matrix @ tw + camera.translation
    # render only the board's bounding box (plus a margin), super-sampled
    cw = np.array([[-1.5, -1.5], [cols + 0.5, -1.5], [cols + 0.5, rows + 0.5], [-1.5, rows + 0.5]]) * square_m
    outline = np.column_stack([cw, np.zeros(4)])
    edge = np.concatenate([outline[i] + np.linspace(0, 1, 20)[:, None] * (outline[(i + 1) % 4] - outline[i])
                           for i in range(4)])
    px = camera.project(edge @ Rw.T + tw)
    img = np.full((h, w), float(background))
    if not np.all(np.isfinite(px)):
        raise ValueError("board crosses the camera plane")
    x0, y0 = np.clip(np.floor(px.min(0)).astype(int) - 3, 0, [w, h])
    x1, y1 = np.clip(np.ceil(px.max(0)).astype(int) + 4, 0, [w, h])
    if x1 > x0 and y1 > y0:
        u = x0 + (np.arange((x1 - x0) * ss) + 0.5) / ss - 0.5
        v = y0 + (np.arange((y1 - y0) * ss) + 0.5) / ss - 0.5
        uu, vv = np.meshgrid(u, v)
        K = camera.matrix
        yd = (vv - K[1, 2]) / K[1, 1]
        xd = (uu - K[0, 2] - K[0, 1] * yd) / K[0, 0]
        xn = _undistort(np.stack([xd, yd], -1), camera.distortions)
        d = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], -1)      # ray directions (camera)
        nrm = R[:, 2]                                                    # board normal
        lam = (nrm @ t) / (d @ nrm)
        B = (d * lam[..., None] - t) @ R                                 # board coordinates
        bx, by = B[..., 0] / square_m, B[..., 1] / square_m
        inside = (lam > 0) & (bx > -1.5) & (bx < cols + 0.5) & (by > -1.5) & (by < rows + 0.5)
        squares = (bx > -1) & (bx < cols) & (by > -1) & (by < rows)
        black = (np.floor(bx).astype(int) + np.floor(by).astype(int)) % 2 == 0
        sub = np.full(bx.shape, float(background))
        sub[inside] = 235.0
        sub[inside & squares & black] = 25.0
        img[y0:y1, x0:x1] = sub.reshape(y1 - y0, ss, x1 - x0, ss).mean(axis=(1, 3))
    if blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma)
    if noise_sigma > 0:
        img = img + np.random.default_rng(seed).normal(0, noise_sigma, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def random_board_poses(rig: Rig, inner_corners, square_m: float, n: int, *, seed: int = 0,
                       distance: tuple = (4.0, 7.0), tilt_deg: float = 35.0, margin_px: float = 15.0,
                       max_tries: int = 5000) -> list:
    """Board poses ``(rvec, tvec)`` in the rig's world frame, seen whole by every camera.

    Board centres are drawn at depths ``distance`` (metres) across the
    cameras' common field of view, tilted up to ``tilt_deg`` about both board
    axes, like the thesis' calibration mechanism (section 3.6).
    """
    rng = np.random.default_rng(seed)
    pts = board_points(inner_corners, square_m)
    centre = pts.mean(axis=0)
    poses = []
    for _ in range(max_tries):
        if len(poses) == n:
            break
        z = rng.uniform(*distance)
        ref = rig.cameras[0]
        target = np.array([rng.uniform(-0.3, 0.3) * z * 640 / ref.focal[0] + 0.15,
                           rng.uniform(-0.25, 0.25) * z * 480 / ref.focal[1], z])
        ax, ay, az = np.deg2rad(rng.uniform(-tilt_deg, tilt_deg, 2).tolist() + [rng.uniform(-20, 20)])
        Rb = rotation_matrix([ax, 0, 0]) @ rotation_matrix([0, ay, 0]) @ rotation_matrix([0, 0, az])
        t = target - Rb @ centre
        Xw = pts @ Rb.T + t
        ok = True
        for cam in rig:
            px = cam.project(Xw)
            if not np.all(np.isfinite(px)) or not np.all(cam.in_image(px, margin_px)):
                ok = False
                break
        if ok:
            poses.append((rotation_vector(Rb), t))
    if len(poses) < n:
        raise RuntimeError(f"found only {len(poses)} of {n} board poses visible in every camera")
    return poses


def write_board_views(rig: Rig, poses, inner_corners, square_m: float, folder, *, seed: int = 0, **kw) -> dict:
    """Render every pose in every camera into ``folder/<camera>/view_<k>.png``.

    Returns ``{camera: ndarray (views, N, 2)}`` of the true corner pixels.
    """
    folder = Path(folder)
    pts = board_points(inner_corners, square_m)
    truth = {}
    for ci, cam in enumerate(rig):
        d = folder / cam.name
        d.mkdir(parents=True, exist_ok=True)
        tr = []
        for k, (r, t) in enumerate(poses):
            img = render_board(cam, r, t, inner_corners, square_m, seed=seed + 1000 * ci + k, **kw)
            cv2.imwrite(str(d / f"view_{k + 1:02d}.png"), img)
            tr.append(cam.project(pts @ rotation_matrix(r).T + np.asarray(t)))
        truth[cam.name] = np.array(tr)
    return truth
