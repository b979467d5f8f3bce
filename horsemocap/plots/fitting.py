"""Figures of the curve fits (thesis Figures 5.7-5.9, 8.13)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_fit", "plot_fit_choice", "plot_marker_fits"]

_AXIS = ("x", "y", "z")


def _gof_text(fit) -> str:
    g = fit.gof
    txt = (f"{fit.label}\nSSE {g.sse:.3g}  R² {g.rsquare:.4f}\nadj R² {g.adjrsquare:.4f}  "
           f"RMSE {g.rmse:.3g}")
    if fit.kind == "fourier":
        lo, hi = fit.confint[:, -1]
        txt += f"\nw {fit.frequency:.3f} ({lo:.3f}, {hi:.3f}) rad/s"
    return txt


def plot_fit(fit, axes=None, t_dense=None, truth=None, unit="m", title=None):
    """Data, fitted curve, residuals, velocity and acceleration of one fit
    (Figures 5.8, 5.9: the user judges a fit from these and its numbers).

    Parameters
    ----------
    fit : horsemocap.fitting.Fit
    axes : sequence of 4 Axes, optional
    t_dense : (k,), optional
        Where to draw the curves (default 300 points over the data).
    truth : dict, optional
        ``{"t": ..., "pos": ..., "vel": ..., "acc": ...}`` drawn dashed.
    """
    if axes is None:
        fig, axes = plt.subplots(4, 1, figsize=(5, 8), sharex=True)
    else:
        fig = axes[0].figure
    t = fit.t
    td = np.linspace(t.min(), t.max(), 300) if t_dense is None else t_dense
    axes[0].plot(t, fit.y, "k.", label="data")
    axes[0].plot(td, fit.evaluate(td), "C0-", label=fit.label)
    axes[0].set_ylabel(f"position ({unit})")
    axes[0].text(0.02, 0.97, _gof_text(fit), transform=axes[0].transAxes, va="top", fontsize=7,
                 bbox=dict(fc="w", alpha=0.8, lw=0))
    axes[1].axhline(0, color="0.6", lw=0.8)
    axes[1].plot(t, fit.residuals, "C3.-", lw=0.8)
    axes[1].set_ylabel("residual")
    axes[2].plot(td, fit.evaluate(td, 1), "C0-")
    axes[2].set_ylabel(f"velocity ({unit}/s)")
    axes[3].plot(td, fit.evaluate(td, 2), "C0-")
    axes[3].set_ylabel(f"acceleration ({unit}/s²)")
    axes[3].set_xlabel("t (s)")
    if truth is not None:
        for ax, key in ((axes[0], "pos"), (axes[2], "vel"), (axes[3], "acc")):
            if key in truth:
                ax.plot(truth["t"], truth[key], "k--", lw=0.8, label="truth")
        axes[0].legend(fontsize=7, loc="lower right")
    if title:
        axes[0].set_title(title, fontsize=9)
    return fig


def plot_fit_choice(fit_a, fit_b, truth=None, unit="m", suptitle=None):
    """The two proposed Fourier fits side by side (orders E/2 and E/2+1, Figures 5.8, 5.9)."""
    fig, axes = plt.subplots(4, 2, figsize=(9, 8), sharex=True, sharey="row")
    for col, f in enumerate((fit_a, fit_b)):
        plot_fit(f, axes[:, col], truth=truth, unit=unit, title=f"choice {col + 1}: {f.label}")
    if suptitle:
        fig.suptitle(suptitle)
    fig.tight_layout()
    return fig


def plot_marker_fits(t, registered, motion_fit, marker: int = 0, truth=None):
    """Figure 8.13: position (registered data and fit), velocity and
    acceleration of one marker in x, y, z.

    Parameters
    ----------
    t : (n,) ; registered : (n, m, 3)
    motion_fit : horsemocap.fitting.MotionFit
    truth : dict of (n, m, 3) arrays ``pos``, ``vel``, ``acc``, optional
    """
    fig, axes = plt.subplots(3, 3, figsize=(11, 7), sharex=True)
    td = np.linspace(t.min(), t.max(), 300)
    for ax_i in range(3):
        f = motion_fit.fits[marker][ax_i]
        axes[ax_i, 0].plot(t, registered[:, marker, ax_i], "k.", ms=4, label="registered")
        for col, d in enumerate((0, 1, 2)):
            axes[ax_i, col].plot(td, f.evaluate(td, d), "C0-", label=f.label)
            if truth is not None:
                key = ("pos", "vel", "acc")[col]
                axes[ax_i, col].plot(t, truth[key][:, marker, ax_i], "k--", lw=0.8, label="truth")
        axes[ax_i, 0].set_ylabel(f"{_AXIS[ax_i]}-motion")
    for col, name in enumerate(("position (m)", "velocity (m/s)", "acceleration (m/s²)")):
        axes[0, col].set_title(name, fontsize=9)
        axes[2, col].set_xlabel("t (s)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"marker {marker + 1}")
    fig.tight_layout()
    return fig
