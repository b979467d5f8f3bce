"""Checkerboard views for calibration (thesis 3.3-3.5, 8.2).

The thesis' board is 800 x 1500 mm with 50 mm squares (16 x 30 squares,
15 x 29 inner corners), slid six times through the 500 x 700 x 6450 mm
calibration volume at the path, ~7.5-8 m from the cameras; Bouguet's toolbox
was given the corners by hand. Here the board is rendered exactly (per-pixel
ray-plane intersection, 3 x 3 supersampling, lens distortion), mounted on a
light carrier with a 60 mm quiet margin (OpenCV's detector needs it), and
posed by a seeded generator. :func:`detect_board` reports whether OpenCV
finds the inner corners; :func:`board_detection_study` measures it against
distance (see the notebook and the report).
"""
from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from ..calibration.board import detect_board as find_board
from ..camera import Camera, rotation_matrix
from .render import finish, pixel_rays, render_arena

BOARD_SQUARES = (16, 30)          # rows x columns of squares
SQUARE_M = 0.05
MARGIN_M = 0.06
BOARD_SLIDES = (-2.3, -1.4, -0.45, 0.45, 1.4, 2.3)
#: The board the virtual lab actually uses: OpenCV does not find the
#: thesis' 50 mm corners (~4.5 px) at 8 m (see board_detection_study), so,
#: as a lab would, the same 0.8 x 1.5 m carrier gets 100 mm squares
#: (8 x 15 squares, 7 x 14 inner corners) and stays in the volume at the path.
LAB_BOARD_SQUARES = (8, 15)
LAB_SQUARE_M = 0.10


def board_corners(inner=(15, 29), square=SQUARE_M) -> np.ndarray:
    """Inner corners in the board frame (x along the columns, y down), (rows*cols, 3).

    Order: row-major, as OpenCV returns them for ``patternSize = (cols, rows)``.
    """
    r, c = inner
    yy, xx = np.mgrid[1:r + 1, 1:c + 1]
    return np.column_stack([xx.ravel() * square, yy.ravel() * square, np.zeros(r * c)])


def render_board(img: np.ndarray, cam: Camera, R_wb: np.ndarray, t_wb: np.ndarray, squares=BOARD_SQUARES,
                 square=SQUARE_M, margin=MARGIN_M, ss: int = 3) -> None:
    """Draw the checkerboard (board frame: origin at the outer top-left square
    corner, x along columns, y down the rows, z into the board) in place."""
    rows, cols = squares
    W, H = cols * square, rows * square
    outline = np.array([[-margin, -margin, 0], [W + margin, -margin, 0], [W + margin, H + margin, 0], [-margin, H + margin, 0]])
    # dense outline to bound the distorted image
    edge = np.concatenate([np.linspace(outline[i], outline[(i + 1) % 4], 20) for i in range(4)])
    px = cam.project(edge @ R_wb.T + t_wb)
    if not np.all(np.isfinite(px)):
        return
    w, h = cam.size
    x0, x1 = max(int(px[:, 0].min()) - 2, 0), min(int(px[:, 0].max()) + 3, w - 1)
    y0, y1 = max(int(px[:, 1].min()) - 2, 0), min(int(px[:, 1].max()) + 3, h - 1)
    if x1 <= x0 or y1 <= y0:
        return
    off = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(x0, x1 + 1)[:, None] + off).ravel()
    vs = (np.arange(y0, y1 + 1)[:, None] + off).ravel()
    U, V = np.meshgrid(us, vs)
    d = pixel_rays(cam, np.stack([U, V], -1))
    o = cam.center
    n = R_wb[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = ((t_wb - o) @ n) / (d @ n)
    P = o + s[..., None] * d
    B = (P - t_wb) @ R_wb                       # board coordinates
    bx, by = B[..., 0], B[..., 1]
    on_carrier = (bx >= -margin) & (bx <= W + margin) & (by >= -margin) & (by <= H + margin) & (s > 0)
    on_squares = (bx >= 0) & (bx < W) & (by >= 0) & (by < H)
    black = on_squares & (((np.floor(bx / square) + np.floor(by / square)) % 2) == 0)
    val = np.where(black, 28.0, 205.0)
    hh, ww = y1 - y0 + 1, x1 - x0 + 1
    cov = on_carrier.reshape(hh, ss, ww, ss).mean(axis=(1, 3))
    col = (val * on_carrier).reshape(hh, ss, ww, ss).sum(axis=(1, 3)) / np.maximum(on_carrier.reshape(hh, ss, ww, ss).sum(axis=(1, 3)), 1)
    sub = img[y0:y1 + 1, x0:x1 + 1]
    sub *= 1 - cov[..., None]
    sub += (cov * col)[..., None] * np.array([1.0, 0.99, 0.95])


#: Calibration protocols: where the boards stand and how far they turn, as
#: ``((near, far) fractions of the path's depth, max yaw deg, max pitch deg)``.
#: ``"path"``: the thesis' (section 8.2), boards slid along the horse's path
#: (depth +-0.25 m), turned up to 35 deg about the vertical and 20 deg about
#: the horizontal axis. ``"depths"``: a lab that also brings the board nearer
#: the cameras (60-100 % of the path's depth) and turns it further (50 / 35 deg).
PROTOCOLS = {"path": ((1.0, 1.0), 35.0, 20.0), "depths": ((0.6, 1.0), 50.0, 35.0)}


def board_poses(n_views: int, motion, seed: int, depth_m: float | None = None, squares=None, square=None,
                protocol: str = "path"):
    """``n_views`` board poses ``(R_wb, t_wb)`` in six slides along the path.

    Parameters
    ----------
    n_views : int
    motion : SaddleMotion
        Gives the path's depth and the ground frame.
    seed : int
        Seeds the poses (the same for every protocol).
    depth_m : float, optional
        Depth of the path (default: the horse's).
    squares, square
        The board (default: the thesis' 16 x 30 squares of 50 mm).
    protocol : str
        A key of :data:`PROTOCOLS`; ``"path"`` is the thesis' and the sessions'.
        With ``"depths"`` the depth steps through four levels from ``near``
        to ``far`` every six views.

    Returns
    -------
    list of (ndarray (3, 3), ndarray (3,))
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol: expected one of {sorted(PROTOCOLS)}, got {protocol!r}")
    (near, far), max_yaw, max_pitch = PROTOCOLS[protocol]
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 77]))
    rows, cols = squares or BOARD_SQUARES
    W, H = cols * (square or SQUARE_M), rows * (square or SQUARE_M)
    path_depth = motion.horse.path_depth_m if depth_m is None else depth_m
    poses = []
    for i in range(n_views):
        depth = path_depth * (far if near == far else near + (far - near) * ((i // len(BOARD_SLIDES)) % 4) / 3)
        z = depth + rng.uniform(-0.25, 0.25)
        x = (BOARD_SLIDES[i % len(BOARD_SLIDES)] + rng.uniform(-0.15, 0.15)) * min(1.0, depth / 8.0)
        yc = -1.25 + rng.uniform(-0.15, 0.15)         # board centre height ~1.25 m
        yaw = rng.uniform(-max_yaw, max_yaw) * math.pi / 180
        pitch = rng.uniform(-max_pitch, max_pitch) * math.pi / 180
        roll = rng.uniform(-8, 8) * math.pi / 180
        R_gb = rotation_matrix([0, yaw, 0]) @ rotation_matrix([pitch, 0, 0]) @ rotation_matrix([0, 0, roll])
        centre_g = np.array([x, yc, z])
        t_g = centre_g - R_gb @ np.array([W / 2, H / 2, 0])
        R_wb = motion.R_wg @ R_gb
        t_wb = motion.ground_to_world_points(t_g[None])[0]
        poses.append((R_wb, t_wb))
    return poses


def detect_board(gray: np.ndarray, inner=(15, 29)):
    """The package's board detector on a rendered view: corners ``(rows*cols, 2)`` or ``None``.

    The virtual laboratory names a board by its inner corners as ``(rows, cols)``; this is
    :func:`horsemocap.calibration.board.detect_board` (the detector every calibration uses: classic,
    then sector-based, refined with the shrinking sub-pixel window) with ``(cols, rows)``, so what
    :func:`board_detection_study` measures is what the pipeline finds. The corners come in its
    canonical order (row-major, or its reverse).
    """
    corners, _, _ = find_board(gray, (int(inner[1]), int(inner[0])))
    return corners


def render_calibration_views(folder, scene, bgs, n_views: int, *, noise: bool = True, compress: bool = True,
                             squares=LAB_BOARD_SQUARES, square=LAB_SQUARE_M, protocol: str = "path"):
    """Write ``<folder>/<cam>/<cam><i>.jpg|png`` synchronised board views.

    Returns a dict with the board description and truth extras (board poses).
    """
    folder = Path(folder)
    poses = board_poses(n_views, scene.motion, scene.seed, squares=squares, square=square, protocol=protocol)
    inner = (squares[0] - 1, squares[1] - 1)
    for ci, cam in enumerate(scene.rig):
        d = folder / cam.name
        d.mkdir(parents=True, exist_ok=True)
        for i, (R_wb, t_wb) in enumerate(poses):
            img = bgs[cam.name].copy()
            render_board(img, cam, R_wb, t_wb, squares=squares, square=square)
            rng = np.random.default_rng(np.random.SeedSequence([int(scene.seed), 5, ci, i]))
            out = cv2.cvtColor(finish(img, rng, noise=noise), cv2.COLOR_RGB2BGR)
            if compress:
                cv2.imwrite(str(d / f"{cam.name}{i + 1}.jpg"), out, [cv2.IMWRITE_JPEG_QUALITY, 90])
            else:
                cv2.imwrite(str(d / f"{cam.name}{i + 1}.png"), out)
    return {"board": {"inner_corners": list(inner), "square_size_m": square},
            "truth_extras": {"board_R_wb": np.array([p[0] for p in poses]),
                             "board_t_wb": np.array([p[1] for p in poses]),
                             "board_margin_m": MARGIN_M}}


def board_detection_study(cam: Camera, motion, distances=(4.0, 5.0, 6.0, 7.0, 8.0), n: int = 6,
                          seed: int = 0, squares=BOARD_SQUARES, square=SQUARE_M):
    """Fraction of boards OpenCV detects at each distance (fronto-parallel-ish poses)."""
    bg = render_arena(cam, motion.R_wg, motion.c_g, seed=seed)
    res = {}
    inner = (squares[0] - 1, squares[1] - 1)
    for dist in distances:
        poses = board_poses(n, motion, seed, depth_m=dist, squares=squares, square=square)
        found = 0
        for i, (R, t) in enumerate(poses):
            img = bg.copy()
            render_board(img, cam, R, t, squares=squares, square=square)
            gray = cv2.cvtColor(finish(img, np.random.default_rng(i), noise=True), cv2.COLOR_RGB2GRAY)
            found += detect_board(gray, inner) is not None
        res[float(dist)] = found / n
    return res
