"""Plots of the calibration (thesis 3.4-3.6, 8.2-8.3)."""
from __future__ import annotations

import cv2
import matplotlib.pyplot as plt
import numpy as np

from ..calibration.board import board_points
from ..sources import read_image

__all__ = ["plot_distortion_field", "plot_board_view", "plot_view_errors", "plot_rig_top", "plot_grid_errors", "reprojected_corners",
           "draw_board_view"]


def reprojected_corners(result, camera: str, k: int, which: str = "alone") -> np.ndarray | None:
    """Corners of view ``k`` reprojected by the calibration (``"alone"`` or ``"joint"``); None if unused."""
    res = result.singles[camera] if which == "alone" or result.joint is None else result.joint.intrinsics[camera]
    if not np.all(np.isfinite(res.rvecs[k])):
        return None
    pts = board_points(result.inner_corners, result.square_m)
    proj, _ = cv2.projectPoints(pts, res.rvecs[k], res.tvecs[k], res.matrix, res.distortions)
    return proj.reshape(-1, 2)


def draw_board_view(result, camera: str, k: int, which: str = "alone") -> np.ndarray:
    """RGB image of view ``k`` with detected corners (green +) and reprojected ones (red x)."""
    v = result.views[camera]
    f = v.files[k]
    img = read_image(f) if f is not None else np.zeros((v.size[1], v.size[0], 3), np.uint8)
    img = img.copy()
    det = v.corners[k]
    if np.all(np.isfinite(det)):
        for p in det:
            cv2.drawMarker(img, tuple(int(round(x)) for x in p), (0, 255, 0), cv2.MARKER_CROSS, 6, 1)
        cv2.circle(img, tuple(int(round(x)) for x in det[0]), 6, (255, 255, 0), 1)
    rep = reprojected_corners(result, camera, k, which)
    if rep is not None:
        for p in rep:
            cv2.drawMarker(img, tuple(int(round(x)) for x in p), (255, 0, 0), cv2.MARKER_TILTED_CROSS, 5, 1)
    return img


def plot_board_view(result, camera: str, k: int, which: str = "alone", ax=None, zoom: int | None = None):
    """One checkerboard view: detected corners (+), reprojected corners (x), per-view error in the title."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.8))
    img = draw_board_view(result, camera, k, which)
    ax.imshow(img)
    v = result.views[camera]
    res = result.singles[camera] if which == "alone" or result.joint is None else result.joint.intrinsics[camera]
    err = res.per_view_rms[k]
    status = v.reasons[k] or res.reasons[k] or f"RMS {err:.3f} px"
    ax.set_title(f"{camera} view {v.names[k]}: {status}", fontsize=9)
    if zoom and np.all(np.isfinite(v.corners[k])):
        c = v.corners[k][0]
        ax.set_xlim(c[0] - zoom, c[0] + zoom)
        ax.set_ylim(c[1] + zoom, c[1] - zoom)
    ax.set_xticks([])
    ax.set_yticks([])
    return ax


def plot_view_errors(result, ax=None):
    """RMS reprojection error of every view and camera (alone: bars; joint: dots)."""
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3.2))
    names = result.view_names
    x = np.arange(len(names))
    n = len(result.cameras)
    w = 0.8 / n
    pv = result.per_view_errors()
    for i, cam in enumerate(result.cameras):
        bars = ax.bar(x + (i - (n - 1) / 2) * w, np.nan_to_num(pv[cam]["alone"]), w, label=f"{cam} alone")
        if "joint" in pv[cam]:
            ax.plot(x + (i - (n - 1) / 2) * w, pv[cam]["joint"], "o", ms=3, color=bars.patches[0].get_facecolor(),
                    mec="k", mew=0.5)
    ax.set_xticks(x)
    ax.set_xticklabels(names, rotation=90, fontsize=7)
    ax.set_ylabel("RMS reprojection error (px)")
    ax.set_title("Per-view reprojection error (bars: each camera alone; dots: joint)")
    ax.legend(fontsize=8)
    return ax


def plot_rig_top(rigs: dict, ax=None, axis_len: float = 0.3):
    """Top view (x-z plane of the reference camera) of one or more rigs: centres and optical axes."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    styles = ["o-", "s--", "^:", "d-."]
    for j, (label, rig) in enumerate(rigs.items()):
        for cam in rig:
            c = cam.center
            z = cam.rotation_matrix[2]  # optical axis in world
            line, = ax.plot([c[0], c[0] + axis_len * z[0]], [c[2], c[2] + axis_len * z[2]], styles[j % 4][1:] or "-",
                            lw=1)
            ax.plot(c[0], c[2], styles[j % 4][0], color=line.get_color(),
                    label=f"{label}: {cam.name}")
    ax.set_xlabel("x (m), reference camera frame")
    ax.set_ylabel("z (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))    # beside the axes, not on a camera
    ax.set_title("Camera centres and optical axes (top view)")
    return ax


def plot_grid_errors(checks: dict, ax=None):
    """Histogram of the signed error of every grid segment (section 8.3) for one or more rigs."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 3.2))
    for label, chk in checks.items():
        e = chk.segment_error_pct.ravel()
        e = e[np.isfinite(e)]
        ax.hist(e, bins=40, histtype="step", label=f"{label}: bias {e.mean():+.3f} %, RMS {np.sqrt(np.mean(e**2)):.3f} %")
    for v in (2.1797, 4.5946, 2.7514):
        ax.axvline(v, color="k", ls=":", lw=0.8)
    ax.set_xlabel("error of a measured grid distance (%)  (dotted: thesis Table 8.5)")
    ax.set_ylabel("segments")
    ax.legend(fontsize=8)
    return ax


def plot_distortion_field(camera, ax=None, n: int = 13, title: str = "", magnify: float | None = None):
    """The camera model (thesis 3.2, eq. 3.7-3.10): where the lens moves each pixel.

    For a grid of image points, an arrow from the pixel an ideal pinhole
    camera would give (``f x_n + c``) to the pixel of the calibrated camera
    with its radial and tangential distortion; the colour is the shift in
    pixels. The principal point is marked with a cross. A lens moves pixels
    by a few pixels on an image hundreds wide, so the arrows are drawn
    magnified (the title says by how much); the colour stays the true shift.

    Parameters
    ----------
    camera : horsemocap.camera.Camera
    n : int
        Grid points along the image width.
    magnify : float, optional
        Arrow length per pixel of shift; by default the longest arrow is
        drawn 0.8 of the grid's spacing long (never shorter than to scale;
        to scale when the lens moves no pixel by a thousandth of one).
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4.5))
    w, h = camera.size
    u, v = np.meshgrid(np.linspace(0, w, n), np.linspace(0, h, max(2, round(n * h / w))))
    K = camera.matrix
    xn = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]], axis=-1)   # ideal pinhole pixels
    moved = camera.normalized_to_pixels(xn) - np.stack([u, v], axis=-1)
    size = np.linalg.norm(moved, axis=-1)
    if magnify is None:
        longest = float(np.max(size))
        magnify = 1.0 if longest < 1e-3 else max(1.0, 0.8 * (w / max(n - 1, 1)) / longest)
    q = ax.quiver(u, v, moved[..., 0], moved[..., 1], size, angles="xy", scale_units="xy", scale=1.0 / magnify,
                  cmap="viridis")
    plt.colorbar(q, ax=ax, label="shift by the lens (px)")
    ax.plot(*camera.principal_point, "r+", ms=12, label="principal point")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_aspect("equal")
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    drawn = "to scale" if magnify == 1.0 else f"{magnify:.0f} times their length"
    ax.set_title(title or f"{camera.name}: distortion (arrows {drawn})", fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    return ax
