"""Figures of thesis 5.3 and 8.3: positions in the motion frame (Figure 8.10), the period
estimate, and the ball's free fall (Figure 8.5)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_motion_positions", "plot_period_estimate", "plot_free_fall"]


def plot_motion_positions(points_motion, t, marker: int = 0, truth=None, title: str = "", fig=None):
    """Thesis Figure 8.10: a marker's x-, y- (gravity, down) and z-motion against time.

    Parameters
    ----------
    points_motion : ndarray (n, m, 3) in the motion frame (``MM``), metres.
    t : ndarray (n,) seconds (eq. 5.13).
    truth : ndarray (n, m, 3), optional, in the same frame.
    """
    p = np.asarray(points_motion, float)
    fig = fig or plt.figure(figsize=(10, 3.4))
    axes = fig.subplots(1, 3)
    names = ("x-motion", "y-motion (gravity, down)", "z-motion")
    for a, ax in enumerate(axes):
        ax.plot(t, p[:, marker, a], "o-", ms=3, lw=1, color="C0", label="measured")
        if truth is not None:
            ax.plot(t, np.asarray(truth)[:, marker, a], "k--", lw=0.8, label="truth")
        ax.set_title(f"marker {marker + 1}: {names[a]}")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("m")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_period_estimate(acf, period: float | None, fps: float | None = None, ax=None):
    """Autocorrelation of the vertical motion against the lag, with the chosen period (None: none found, the
    autocorrelation alone under the title "no period found")."""
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3))
    lags = np.arange(len(acf))
    ax.plot(lags, acf, "o-", ms=3)
    if period is None:
        ax.set_title("no period found")
    else:
        ax.axvline(period, color="C3", ls="--",
                   label=f"T = {period:.2f} frames" + (f" = {period / fps:.3f} s" if fps else ""))
        ax.legend(fontsize=8)
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xlabel("lag (frames)")
    ax.set_ylabel("autocorrelation")
    ax.grid(True, alpha=0.3)
    return ax


def plot_free_fall(result: dict, fig=None, title: str = ""):
    """Thesis Figure 8.5: the ball along gravity, its fitted quadratic, velocity and acceleration.

    ``result`` is the dict of :func:`horsemocap.frames.free_fall_g`.
    """
    t = result["t"]
    fig = fig or plt.figure(figsize=(10, 3.3))
    a1, a2, a3 = fig.subplots(1, 3)
    a1.plot(t, result["position"], "o", ms=4, label="measured")
    a1.plot(t, result["fitted"], "-", label="quadratic fit")
    a1.set_ylabel("position along gravity, down (m)")
    a1.set_title("position")
    a2.plot(t, result["velocity"], "-", color="C1")
    a2.set_ylabel("velocity (m/s)")
    a2.set_title("velocity (fit)")
    a3.plot(t, result["acceleration"], "-", color="C2", label=f"g = {result['g']:.3f} m/s$^2$")
    a3.axhline(result["g_reference"], color="k", ls="--", lw=0.8, label=f"{result['g_reference']:.2f} m/s$^2$")
    a3.set_ylim(0, 1.3 * max(result["g_reference"], result["g"]))
    a3.set_ylabel("acceleration (m/s$^2$)")
    a3.set_title("acceleration (fit)")
    for ax in (a1, a2, a3):
        ax.set_xlabel("t (s)")
        ax.grid(True, alpha=0.3)
    a1.legend(fontsize=7)
    a3.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
