"""Figures of thesis section 8.5: indicators per gait and horse, and against grades."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .. import herd as _herd
from ..vibration import COMFORT_UNITS

__all__ = ["plot_indicators_by_gait", "plot_indicators_vs_grades", "plot_saddle_by_gait"]


def _label(key):
    if key in _herd.INDICATOR_LABELS:
        return _herd.INDICATOR_LABELS[key]
    u = COMFORT_UNITS.get(key, "")
    return f"{key} ({u})" if u and u != "1" else key


def plot_indicators_by_gait(table: dict, indicators=("acc_y_max", "acc_y_Wb_rms"),
                            horses=_herd.HORSES, gaits=_herd.GAITS, fig=None):
    """Thesis Figures 8.29-8.32: each indicator per gait, one line per horse.

    Rising trot is drawn hatched-grey in the background: the rider leaves
    the saddle every other beat (section 8.5 caveat).
    """
    fig = fig or plt.figure(figsize=(5 * len(indicators), 3.4))
    axs = np.atleast_1d(fig.subplots(1, len(indicators)))
    x = np.arange(len(gaits))
    for ax, key in zip(axs, indicators):
        m = _herd.indicator_matrix(table, key, horses, gaits)
        for j, h in enumerate(horses):
            ax.plot(x, m[:, j], "o-", label=h)
        if "rising_trot" in gaits:
            i = list(gaits).index("rising_trot")
            ax.axvspan(i - 0.4, i + 0.4, color="0.85", zorder=0)
        ax.set_xticks(x, [_herd.GAIT_LABELS.get(g, g) for g in gaits], fontsize=8)
        ax.set_ylabel(_label(key))
        ax.grid(True, alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def plot_indicators_vs_grades(table: dict, gait: str, correlations=None,
                              indicators=_herd.THESIS_INDICATORS, grades=None, fig=None):
    """Thesis Figures 8.33-8.36: indicators against the riders' mean grade in one gait.

    One panel per indicator, one point per horse (labelled), with the
    Spearman rho of :func:`herd.compare` in the title when given.
    """
    mg = _herd.mean_grades(grades)
    rho = {c.indicator: c for c in (correlations or []) if c.gait == gait}
    n = len(indicators)
    cols = 4 if n > 4 else n
    rows = int(np.ceil(n / cols))
    fig = fig or plt.figure(figsize=(3.2 * cols, 2.8 * rows))
    axs = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    horses = [h for h in _herd.HORSES if (h, gait) in table]
    g = np.array([mg[(gait, h)] for h in horses])
    for ax, key in zip(axs, indicators):
        v = np.array([table[(h, gait)][key] for h in horses])
        ax.plot(g, v, "o")
        for gi, vi, h in zip(g, v, horses):
            ax.annotate(h.replace("Horse ", "H"), (gi, vi), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
        c = rho.get(key)
        ttl = _label(key) if c is None or not np.isfinite(c.rho) else f"{_label(key)}\nrho = {c.rho:+.2f}"
        ax.set_title(ttl, fontsize=8)
        ax.set_xlabel("mean grade", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    for ax in axs[n:]:
        ax.set_visible(False)
    fig.suptitle(f"{_herd.GAIT_LABELS.get(gait, gait)}: indicators vs riders' grades", fontsize=10)
    fig.tight_layout()
    return fig


def plot_saddle_by_gait(series: dict, gait: str = "", fig=None):
    """Thesis Figures 8.25-8.28: the saddle marker of each horse in one gait.

    Two rows (position, acceleration) by three columns (x-, y-, z-motion),
    one line per horse, each against its own time from the first analysed
    frame.

    Parameters
    ----------
    series : dict horse -> (t, position, acceleration)
        ``t`` (n,) in s, ``position`` (n, 3) in m and ``acceleration`` (n, 3)
        in m/s² of the saddle marker in the motion frame (the pipeline's
        ``rigid_body`` step: ``t``, ``saddle_position``, ``saddle_acceleration``).
        A horse whose session did not complete may be given as None: it is
        named in the legend as missing, never left out silently.
    gait : str
        Used in the title.
    """
    fig = fig or plt.figure(figsize=(13, 6))
    axs = fig.subplots(2, 3, sharex=True)
    names = ("x-motion", "y-motion (down)", "z-motion")
    for horse, s in series.items():
        if s is None:
            axs[0, 0].plot([], [], label=f"{horse} (not analysed)")
            continue
        t, pos, acc = (np.asarray(v, float) for v in s)
        t = t - t[0]
        for k in range(3):
            # x position relative to its start: the horse travels metres along x
            p = pos[:, k] - pos[0, k] if k == 0 else pos[:, k]
            axs[0, k].plot(t, p, lw=1.2, label=horse)
            axs[1, k].plot(t, acc[:, k], lw=1.2, label=horse)
    for k in range(3):
        axs[0, k].set_title(f"{names[k]}: position (m)" + (" from the start" if k == 0 else ""))
        axs[1, k].set_title(f"{names[k]}: acceleration (m/s²)")
        axs[1, k].set_xlabel("t (s)")
        for r in range(2):
            axs[r, k].grid(True, alpha=0.3)
    axs[0, 0].set_ylabel("position (m)")
    axs[1, 0].set_ylabel("acceleration (m/s²)")
    axs[0, 0].legend(fontsize=7)
    fig.suptitle(f"Saddle marker of the four horses{': ' + gait if gait else ''}")
    fig.tight_layout()
    return fig
