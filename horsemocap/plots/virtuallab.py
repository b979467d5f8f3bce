"""Plots of the virtual laboratory: rig layout, frames with truth, saddle motion."""
from __future__ import annotations

import numpy as np

__all__ = ["plot_rig_top_view", "plot_frame_truth", "plot_saddle_truth", "plot_pseudo_markers"]


def _ax(ax, **kw):
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(**kw)
    return ax


def plot_rig_top_view(rig, path_points=None, depth: float = 8.0, ax=None):
    """Top view (x-z plane of the left camera) of the cameras, their fields of
    view down to ``depth`` metres, and optional path points ``(n, 3)``."""
    ax = _ax(ax, figsize=(7, 5))
    colors = {"left": "tab:blue", "middle": "tab:green", "right": "tab:red"}
    for cam in rig:
        c = cam.center
        w = cam.size[0]
        K = cam.matrix
        for u in (0.0, w - 1.0):
            d_cam = np.array([(u - K[0, 2]) / K[0, 0], 0.0, 1.0])
            d = cam.rotation_matrix.T @ d_cam
            p = c + d * (depth - c[2]) / d[2]
            ax.plot([c[0], p[0]], [c[2], p[2]], color=colors.get(cam.name, "k"), lw=0.8)
        axis = cam.rotation_matrix.T @ np.array([0, 0, 1.0])
        ax.annotate("", xy=(c[0] + axis[0], c[2] + axis[2]), xytext=(c[0], c[2]),
                    arrowprops=dict(arrowstyle="->", color=colors.get(cam.name, "k")))
        ax.plot(c[0], c[2], "o", color=colors.get(cam.name, "k"), label=cam.name)
    if path_points is not None:
        p = np.asarray(path_points).reshape(-1, 3)
        ax.plot(p[:, 0], p[:, 2], ".", ms=2, color="0.3", label="markers")
    ax.set_xlabel("x (m, left camera frame)")
    ax.set_ylabel("z (m, depth)")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=8)
    return ax


def plot_frame_truth(frame, marker_px, visible=None, ax=None, zoom=None, title=None):
    """An image with the true marker centres (+; saddle marker o).

    ``zoom``: half-size in pixels of a crop around the visible markers.
    """
    ax = _ax(ax, figsize=(7, 5))
    ax.imshow(frame, cmap="gray" if frame.ndim == 2 else None, vmin=0, vmax=255)
    px = np.asarray(marker_px, float)
    vis = np.ones(len(px), bool) if visible is None else np.asarray(visible, bool)
    for j, (u, v) in enumerate(px):
        if not np.all(np.isfinite([u, v])):
            continue
        style = dict(color="lime" if vis[j] else "orange", ms=9, mew=1.2)
        ax.plot(u, v, "+" if j < 3 else "o", mfc="none", **style)
        ax.text(u + 4, v - 5, str(j + 1) if j < 3 else "S", color=style["color"], fontsize=8)
    if zoom is not None and np.any(np.isfinite(px[:3])):
        cu, cv = np.nanmean(px[:3], axis=0)
        ax.set_xlim(cu - zoom, cu + zoom)
        ax.set_ylim(cv + zoom * 0.75, cv - zoom * 0.75)
    if title:
        ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    return ax


def plot_saddle_truth(time_s, saddle_pos_m, saddle_acc_m, axes_labels=("x-motion", "y-motion", "z-motion"), fig=None):
    """True saddle position (detrended x) and acceleration in the motion frame."""
    import matplotlib.pyplot as plt

    fig = fig or plt.figure(figsize=(9, 4.5))
    axs = fig.subplots(2, 3, sharex=True)
    p = np.asarray(saddle_pos_m)
    for i in range(3):
        y = p[:, i] - (np.polyval(np.polyfit(time_s, p[:, i], 1), time_s) if i == 0 else 0)
        axs[0, i].plot(time_s, y, color="tab:blue")
        axs[0, i].set_title(axes_labels[i] + (" (detrended)" if i == 0 else ""), fontsize=9)
        axs[1, i].plot(time_s, saddle_acc_m[:, i], color="tab:red")
        axs[1, i].set_xlabel("time (s)")
    axs[0, 0].set_ylabel("position (m)")
    axs[1, 0].set_ylabel("acceleration (m/s$^2$)")
    fig.tight_layout()
    return fig


def plot_pseudo_markers(gray, threshold: int, area_range, marker_px, ax=None):
    """What a naive detector keeps: thresholded regions in the area range
    (red boxes) versus the true markers (green +)."""
    import cv2

    ax = _ax(ax, figsize=(7, 5))
    n, lab, st, cen = cv2.connectedComponentsWithStats((gray > threshold).astype(np.uint8), connectivity=8)
    ax.imshow(gray, cmap="gray", vmin=0, vmax=255)
    kept = 0
    for i in range(1, n):
        if area_range[0] <= st[i, 4] <= area_range[1]:
            x, y, w, h = st[i, :4]
            ax.add_patch(__import__("matplotlib").patches.Rectangle((x - 1.5, y - 1.5), w + 2, h + 2, fill=False, ec="red", lw=0.8))
            kept += 1
    px = np.asarray(marker_px)
    ax.plot(px[:3, 0], px[:3, 1], "+", color="lime", ms=8)
    ax.set_title(f"threshold {threshold}, area {area_range[0]}-{area_range[1]} px: {kept} regions kept, 3 are markers", fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    return ax
