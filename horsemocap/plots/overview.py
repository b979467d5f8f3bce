"""The pipeline of the thesis as one figure (notebook 00, report)."""
from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

__all__ = ["plot_pipeline"]

PIPELINE = (
    ("videos", "3 cameras\n640x480 @ 30 fps", "App. A"),
    ("sync", "flashlight\nframe offsets", "3.5"),
    ("calibrate", "checkerboard\nrig (K, kc, R, t)", "3.3-3.6, 8.2"),
    ("detect", "threshold, labels,\narea, window, filters", "4"),
    ("triangulate", "3D markers in\nleft camera frame", "5.1"),
    ("smooth", "robust loess\nspan 0.1", "5.2"),
    ("motion frame", "displacement +\nplumb line", "5.3"),
    ("register", "rigid body vs\nstatic shot", "5.4"),
    ("fit", "poly x, Fourier y/z\nv, a", "5.5"),
    ("omega, alpha", "angular velocity\nand acceleration", "6.1-6.2"),
    ("saddle", "hidden marker\np, v, a", "6.3-6.4"),
    ("comfort", "rms, VDV, exposure\ntimes and distances", "7, 8.5"),
)


def plot_pipeline(ax=None, steps=PIPELINE):
    """Draw the thesis pipeline: one box per step with its thesis section.

    Parameters
    ----------
    ax : matplotlib Axes, optional
    steps : sequence of (name, description, section)

    Returns
    -------
    matplotlib.figure.Figure
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(12, 4.2))
    per_row = 6
    w, h, gx, gy = 1.7, 1.05, 0.35, 0.7
    centres = []
    for i, (name, desc, sec) in enumerate(steps):
        row, col = divmod(i, per_row)
        if row % 2:
            col = per_row - 1 - col  # snake so arrows stay short
        x, y = col * (w + gx), -row * (h + gy)
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.03",
                                    fc="#e8f0fa" if i % 2 else "#f7f1e3", ec="#34495e"))
        ax.text(x + w / 2, y + h - 0.2, name, ha="center", va="center", weight="bold", fontsize=10)
        ax.text(x + w / 2, y + 0.45, desc, ha="center", va="center", fontsize=8)
        ax.text(x + w / 2, y + 0.1, f"thesis {sec}", ha="center", va="center", fontsize=7, color="#7f8c8d")
        centres.append((x, y))
    for (x0, y0), (x1, y1) in zip(centres, centres[1:]):
        if y0 == y1:
            a, b = ((x0 + w, y0 + h / 2), (x1, y1 + h / 2)) if x1 > x0 else ((x0, y0 + h / 2), (x1 + w, y1 + h / 2))
        else:
            a, b = (x0 + w / 2, y0), (x1 + w / 2, y1 + h)
        ax.add_patch(FancyArrowPatch(a, b, arrowstyle="-|>", mutation_scale=12, color="#34495e"))
    ax.set_xlim(-0.2, per_row * (w + gx))
    ax.set_ylim(-((len(steps) - 1) // per_row) * (h + gy) - 0.2, h + 0.2)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title("The thesis pipeline: each box is one function of horsemocap, each arrow one notebook")
    return ax.figure
