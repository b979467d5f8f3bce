"""Figures that summarise a whole analysis (report, notebook 14)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_marker_tracks", "plot_axes_timeseries", "plot_reprojection_residuals"]

AXES = ("x-motion", "y-motion (down)", "z-motion")


def _fixed_layout(fig, left: float, bottom: float, top: float, right: float = 0.15, wspace: float = 0.25) -> None:
    """Margins given in inches (room for the tick labels, axis labels and titles), set once.

    A fixed layout instead of ``tight_layout``: measuring every text to fit
    the panels costs more than drawing the figure. The panels' titles are
    placed at a fixed height too (``set_title(..., y=1.0)``: just above the
    panel, where matplotlib would put them after measuring the tick labels).
    """
    width, height = fig.get_size_inches()
    fig.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height,
                        top=1 - top / height, wspace=wspace)


def plot_marker_tracks(marker_px: dict, image_size=(640, 480), fig=None):
    """Detected marker paths in each camera's image (one panel per camera).

    Parameters
    ----------
    marker_px : dict of ndarray (frames, markers, 2)
        Pixel centroids per camera (thesis ``PM_L``, ``PM_M``, ``PM_R``).
    """
    cams = list(marker_px)
    fig = fig or plt.figure(figsize=(4 * len(cams), 3.2))
    for i, cam in enumerate(cams):
        ax = fig.add_subplot(1, len(cams), i + 1)
        px = marker_px[cam]
        for m in range(px.shape[1]):
            ax.plot(px[:, m, 0], px[:, m, 1], ".-", ms=2, lw=0.8, label=f"marker {m + 1}")
        ax.set_xlim(0, image_size[0])
        ax.set_ylim(image_size[1], 0)
        ax.set_aspect("equal")
        ax.set_title(f"{cam} camera", y=1.0)
        ax.set_xlabel("u (px)")
        if i == 0:
            ax.set_ylabel("v (px)")
            ax.legend(fontsize=7)
    _fixed_layout(fig, left=0.7, bottom=0.55, top=0.35, wspace=0.2)
    return fig


def plot_axes_timeseries(t, series: dict, unit: str, title: str, fig=None, quantity: str | None = None):
    """One panel per motion axis; ``series`` maps a label to an ``(n, 3)`` array.

    Each panel's title names its axis and ``unit`` (e.g. ``x-motion (m)``);
    with ``quantity`` it names what the panel shows about or along that
    axis (``quantity="angular velocity about"``: ``angular velocity about x
    (rad/s)``), the axes being the motion frame's (x forward, y down).
    """
    fig = fig or plt.figure(figsize=(12, 3))
    for k in range(3):
        ax = fig.add_subplot(1, 3, k + 1)
        for label, arr in series.items():
            ax.plot(t, np.asarray(arr)[:, k], label=label, lw=1.2)
        name = f"{quantity} {'xyz'[k]}" if quantity else AXES[k]
        ax.set_title(f"{name} ({unit})" if unit else name, y=1.0)
        ax.set_xlabel("t (s)")
        if k == 0:
            ax.set_ylabel(unit)
            ax.legend(fontsize=7)
    fig.suptitle(title)
    _fixed_layout(fig, left=0.75, bottom=0.5, top=0.65, wspace=0.22)
    return fig


def plot_reprojection_residuals(residual_px: dict, fig=None):
    """Reprojection residual per camera and frame (median over markers)."""
    fig = fig or plt.figure(figsize=(6, 3))
    ax = fig.add_subplot(1, 1, 1)
    for cam, r in residual_px.items():
        r = np.asarray(r, float)
        if r.ndim > 1:  # median over the markers seen in each frame (NaN where none)
            seen = np.isfinite(r).any(axis=1)
            med = np.full(len(r), np.nan)
            med[seen] = np.nanmedian(r[seen], axis=1)
            r = med
        ax.plot(r, label=cam, lw=1)
    ax.set_xlabel("synchronised frame")
    ax.set_ylabel("residual (px)")
    ax.set_title("Reprojection residuals", y=1.0)
    ax.legend(fontsize=7)
    _fixed_layout(fig, left=0.75, bottom=0.5, top=0.35)
    return fig
