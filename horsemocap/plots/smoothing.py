"""Figures of thesis 5.2.2: smoothing comparison (Figure 5.2) and smoothed positions (Figure 8.9 b)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .. import smoothing as sm

__all__ = ["plot_smoothing_comparison", "plot_smoothed_marker"]


def plot_smoothing_comparison(y, span=0.1, x=None, methods=("moving", "lowess", "rloess"), truth=None,
                              outliers=None, fig=None):
    """Thesis Figure 5.2: the data with outliers, then each smoother's result.

    Parameters
    ----------
    y : ndarray (n,)
    span : float, the span of every smoother (for the moving average, at least 3 points).
    methods : names understood by :func:`horsemocap.smoothing.smooth`.
    truth : ndarray (n,), optional, the clean signal.
    outliers : indices of injected outliers, optional (circled).
    """
    y = np.asarray(y, float)
    x = np.arange(y.size) if x is None else np.asarray(x)
    panels = 1 + len(methods)
    fig = fig or plt.figure(figsize=(10, 2.3 * panels))
    axes = fig.subplots(panels, 1, sharex=True)
    axes[0].plot(x, y, "o", ms=3, color="C0", label="data")
    if outliers is not None:
        axes[0].plot(x[outliers], y[outliers], "o", ms=9, mfc="none", color="C3", label="outliers")
    axes[0].set_title("data")
    for ax, meth in zip(axes[1:], methods):
        ys = sm.smooth(y, span if meth != "moving" else max(3, sm.span_points(span, y.size)), meth)
        ax.plot(x, y, "o", ms=2, color="0.7")
        ax.plot(x, ys, "-", color="C1", lw=1.5, label=meth)
        ax.set_title(f"{meth} (span {span})")
    for ax in axes:
        if truth is not None:
            ax.plot(x, truth, "k--", lw=0.8, label="truth")
        lo, hi = np.percentile(y, [1, 99])
        pad = 0.4 * (hi - lo)
        ax.set_ylim(lo - pad, hi + pad)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("sample")
    fig.tight_layout()
    return fig


def plot_smoothed_marker(raw, smoothed, marker: int = 0, t=None, truth=None, title: str = "", fig=None,
                         label: str = "smoothed", errors: bool = False):
    """Thesis Figure 8.9 (b): one marker's X, Y, Z before and after smoothing (``CM_L``).

    Parameters
    ----------
    raw, smoothed : ndarray (frames, markers, 3), metres
    marker : int, 0-based
    t : ndarray (frames,), optional, time axis (default: frame numbers)
    truth : ndarray (frames, markers, 3), optional, drawn dashed
    label : str, legend of the smoothed curve (e.g. ``"rloess 0.1"``)
    errors : bool
        With ``truth``: a second row with the errors (mm) of the raw and
        smoothed positions against the truth.
    """
    raw = np.asarray(raw, float)
    smoothed = np.asarray(smoothed, float)
    x = np.arange(raw.shape[0]) if t is None else np.asarray(t)
    rows = 2 if (errors and truth is not None) else 1
    fig = fig or plt.figure(figsize=(10, 3.4 * rows))
    axes = np.atleast_2d(fig.subplots(rows, 3, squeeze=False))
    for a in range(3):
        ax = axes[0, a]
        ax.plot(x, raw[:, marker, a], "o", ms=3, color="C0", label="triangulated")
        ax.plot(x, smoothed[:, marker, a], "-", color="C1", label=label)
        if truth is not None:
            ax.plot(x, np.asarray(truth)[:, marker, a], "k--", lw=0.8, label="truth")
        ax.set_title(f"marker {marker + 1}: {'XYZ'[a]} (left camera)")
        ax.set_xlabel("frame" if t is None else "t (s)")
        ax.set_ylabel("m")
        ax.grid(True, alpha=0.3)
        if rows == 2:
            tr = np.asarray(truth, float)[:, marker, a]
            ax = axes[1, a]
            ax.plot(x, 1000 * (raw[:, marker, a] - tr), "o-", ms=3, lw=0.6, color="C0", label="triangulated")
            ax.plot(x, 1000 * (smoothed[:, marker, a] - tr), "-", color="C1", label=label)
            ax.axhline(0, color="k", lw=0.6)
            ax.set_title(f"error in {'XYZ'[a]} vs truth")
            ax.set_xlabel("frame" if t is None else "t (s)")
            ax.set_ylabel("mm")
            ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    if rows == 2:
        axes[1, 0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
