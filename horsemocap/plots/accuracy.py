"""Figures of the accuracy study (notebook 14)."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ._layout import legend_below

__all__ = ["plot_errors_2d", "plot_stage_rmse", "plot_noise_study"]


def plot_errors_2d(errors: dict, ax=None):
    """Histogram of matched 2D centroid errors per camera (Guchin et al., 6.1)."""
    ax = ax or plt.figure(figsize=(6, 3)).add_subplot(1, 1, 1)
    top = max(float(np.max(e["errors"])) for e in errors.values() if len(e["errors"]))
    bins = np.linspace(0, top * 1.05, 30)
    for cam, e in errors.items():
        ax.hist(e["errors"], bins=bins, histtype="step", lw=1.5, label=f"{cam} (median {e['median']:.3f} px)")
    ax.set_xlabel("centroid error (px)")
    ax.set_ylabel("markers x frames")
    ax.set_title("2D: detected vs true centres")
    ax.legend(fontsize=8)
    return ax.figure


def plot_stage_rmse(stages: dict, keys=("triangulated", "smoothed", "registered", "saddle_position"), ax=None):
    """RMSE per motion axis (mm) for the position stages of the pipeline."""
    ax = ax or plt.figure(figsize=(7, 3)).add_subplot(1, 1, 1)
    x = np.arange(len(keys))
    for k, axis in enumerate(("x-motion", "y-motion", "z-motion")):
        ax.bar(x + (k - 1) * 0.27, [1000 * stages[s][k] for s in keys], width=0.27, label=axis)
    ax.set_xticks(x, [s.replace("_", " ") for s in keys])
    ax.set_ylabel("RMSE (mm)")
    ax.set_title("Position error after each stage")
    ax.legend(fontsize=8)
    return ax.figure


def plot_noise_study(rows: list, fig=None):
    """Detection noise (px) against 3D error and saddle acceleration error."""
    fig = fig or plt.figure(figsize=(11, 3.2))
    rows = [r for r in rows if r["draws"]]
    s = [r["sigma_px"] for r in rows]
    ax = fig.add_subplot(1, 3, 1)
    for k, axis in enumerate(("x", "y", "z")):
        ax.plot(s, [1000 * r["smoothed_m"][k] for r in rows], "o-", label=f"{axis}-motion")
    ax.set_xlabel("detection noise sigma (px)")
    ax.set_ylabel("marker RMSE after smoothing (mm)")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(1, 3, 2)
    ax.plot(s, [r["saddle_acc_y_pct"] for r in rows], "o-", color="C3")
    ax.set_xlabel("detection noise sigma (px)")
    ax.set_ylabel("saddle A_y RMSE (% of rms)")
    ax = fig.add_subplot(1, 3, 3)
    for key in rows[0]["comfort_pct"]:
        ax.plot(s, [abs(r["comfort_pct"][key]) for r in rows], "o-", label=key)
    ax.set_xlabel("detection noise sigma (px)")
    ax.set_ylabel("|indicator error| (%)")
    legend_below(ax, ncol=2)
    fig.suptitle("How detection noise propagates to the saddle and the comfort indicators")
    fig.tight_layout()
    return fig
