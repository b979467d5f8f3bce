"""Figures of thesis 5.1 and 8.4.1: marker positions in the camera frame (Figure 8.9 a),
reprojection residuals, and the thesis-vs-joint triangulation comparison."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_camera_positions", "plot_triangulation_residuals", "plot_triangulation_modes"]

AXIS_NAMES = ("X", "Y", "Z")


def plot_camera_positions(points, t=None, truth=None, title: str = "", fig=None):
    """Thesis Figure 8.9 (a): X, Y, Z of every marker in the left camera frame (``CM_L``).

    Parameters
    ----------
    points : ndarray (n, m, 3), metres.
    t : ndarray (n,), optional
        Abscissa (default: frame number, as the thesis).
    truth : ndarray (n, m, 3), optional
        Drawn as thin black lines.
    """
    p = np.asarray(points, float)
    x = np.arange(p.shape[0]) if t is None else np.asarray(t)
    fig = fig or plt.figure(figsize=(10, 3.4))
    axes = fig.subplots(1, 3)
    for a, ax in enumerate(axes):
        for m in range(p.shape[1]):
            ax.plot(x, p[:, m, a], ".-", ms=3, lw=0.8, label=f"marker {m + 1}")
            if truth is not None:
                ax.plot(x, np.asarray(truth)[:, m, a], "k-", lw=0.6, alpha=0.7,
                        label="truth" if m == 0 else None)
        ax.set_title(f"{AXIS_NAMES[a]} (left camera)")
        ax.set_xlabel("frame" if t is None else "t (s)")
        ax.set_ylabel("m")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_triangulation_residuals(triangulation, ax=None):
    """Reprojection residual (px) per camera and frame, all markers (``Triangulation.residual_px``)."""
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3))
    for cam, r in triangulation.residual_px.items():
        r = np.asarray(r, float)
        for m in range(r.shape[1]):
            ax.plot(r[:, m], ".", ms=4, alpha=0.8, label=cam if m == 0 else None)
    ax.set_xlabel("frame")
    ax.set_ylabel("reprojection error (px)")
    ax.set_title(f"reprojection residuals, {triangulation.mode} mode")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_triangulation_modes(errors: dict, ax=None, unit: str = "mm", target: float | None = None):
    """Bar chart of the RMSE per motion axis for each mode.

    Parameters
    ----------
    errors : dict of label -> (3,) RMSE along x-, y-, z-motion, in ``unit``.
    target : float, optional
        A target RMSE (same unit), drawn as a dashed line.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 3.2))
    labels = list(errors)
    width = 0.8 / max(len(labels), 1)
    xs = np.arange(3)
    for i, lab in enumerate(labels):
        vals = np.asarray(errors[lab], float)
        bars = ax.bar(xs + (i - (len(labels) - 1) / 2) * width, vals, width, label=lab)
        for b, v in zip(bars, vals):
            ax.annotate(f"{v:.1f}", (b.get_x() + b.get_width() / 2, b.get_height()), ha="center",
                        va="bottom", fontsize=7)
    ax.set_xticks(xs, ["x-motion", "y-motion (gravity)", "z-motion (depth)"])
    if target is not None:
        ax.axhline(target, color="k", ls="--", lw=0.8, label=f"target {target:g} {unit}")
    ax.set_ylabel(f"RMSE ({unit})")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return ax
