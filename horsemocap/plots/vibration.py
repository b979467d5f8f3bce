"""Figures of thesis chapter 7: weightings (Figure 7.1), weighted signals, Table 8.7."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .. import vibration as vib
from ._layout import legend_below

__all__ = ["plot_weightings", "plot_weighted_acceleration", "plot_mode_comparison", "plot_marker_comfort"]


def plot_weightings(names=("Wb", "Wk"), f_range=(0.1, 100.0), zoom=(0.8, 1.8), table=None,
                    fig=None):
    """Thesis Figure 7.1: ``|W(f)|`` (a) over the full band and (b) zoomed.

    Parameters
    ----------
    names : weightings to draw ("Wb", "Wk", "Wd").
    f_range : (Hz, Hz) of panel (a), log axis.
    zoom : (Hz, Hz) of panel (b) (the thesis: 0.8-1.8 Hz, the saddle's range).
    table : dict name -> (freq_hz, factors), optional
        Tabulated factors to overlay as markers (e.g. ISO 2631-1 Table 3).
    """
    fig = fig or plt.figure(figsize=(10, 3.8))
    ax1, ax2 = fig.subplots(1, 2)
    f = np.geomspace(*f_range, 600)
    fz = np.linspace(*zoom, 200)
    for n in names:
        line, = ax1.semilogx(f, np.abs(vib.weighting(n, f)), label=n)
        ax2.plot(fz, np.abs(vib.weighting(n, fz)), color=line.get_color(), label=n)
        if table and n in table:
            ft, wt = table[n]
            ax1.semilogx(ft, wt, "o", ms=3, color=line.get_color(), label=f"{n} tabulated")
    ax1.set_xlabel("f (Hz)")
    ax1.set_ylabel("|W(f)|")
    ax1.set_title("(a) weighting factors")
    ax1.grid(True, which="both", alpha=0.3)
    legend_below(ax1)
    ax2.set_xlabel("f (Hz)")
    ax2.set_title(f"(b) {zoom[0]:g}-{zoom[1]:g} Hz")
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def plot_weighted_acceleration(histories: dict, title: str = "", ax=None):
    """``A_y``, ``A_wb``, ``A_wk`` over tau (eq. 7.1-7.2) from :func:`vibration.weighted_histories`."""
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3.2))
    t = histories["t"]
    ax.plot(t, histories["A_y"], color="0.5", lw=1, label="A_y (unweighted)")
    ax.plot(t, histories["A_wb"], label="A_wb (Wb)")
    ax.plot(t, histories["A_wk"], label="A_wk (Wk)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("vertical acceleration (m/s$^2$)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_mode_comparison(iso: dict, thesis: dict, keys=("acc_y_Wb_rms", "acc_y_Wk_rms",
                                                         "VDV_y_Wb", "VDV_y_Wk",
                                                         "TA_8_limit_Wb", "TA_8_limit_Wk"),
                         ax=None):
    """Relative difference thesis/iso - 1 of a few indicators (bar chart)."""
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3))
    d = [100 * (thesis[k] / iso[k] - 1) for k in keys]
    ax.bar(range(len(keys)), d, color=["C0" if x >= 0 else "C3" for x in d])
    ax.set_xticks(range(len(keys)), keys, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("thesis mode / iso mode - 1 (%)")
    ax.axhline(0, color="k", lw=0.8)
    ax.grid(True, axis="y", alpha=0.3)
    return ax


def plot_marker_comfort(rows: dict, keys=("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk"), fig=None):
    """Appendix A step 10: the comfort indicators of each visible marker (and the saddle).

    Parameters
    ----------
    rows : dict label -> indicators dict (or None: drawn as "not computed")
        E.g. ``{"marker 1": ..., "marker 2": ..., "saddle": ...}``.
    keys : indicators shown, one panel each, with their units.
    """
    fig = fig or plt.figure(figsize=(3.2 * len(keys), 3.2))
    axs = np.atleast_1d(fig.subplots(1, len(keys)))
    labels = list(rows)
    for ax, key in zip(axs, keys):
        vals = [np.nan if rows[l] is None else rows[l][key] for l in labels]
        bars = ax.bar(range(len(labels)), vals, color=["C0" if l != "saddle" else "C3" for l in labels])
        for b, v in zip(bars, vals):
            ax.annotate("not computed" if not np.isfinite(v) else f"{v:.2f}", (b.get_x() + b.get_width() / 2,
                        0 if not np.isfinite(v) else v), ha="center", va="bottom", fontsize=7)
        ax.set_xticks(range(len(labels)), labels, fontsize=8, rotation=20)
        ax.set_title(f"{key} ({vib.unit_text(vib.COMFORT_UNITS[key])})", fontsize=9)
        ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    return fig
