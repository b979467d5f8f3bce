"""The report's figures drawn as PNG: the only part of ``report.html`` that needs matplotlib.

:mod:`horsemocap.report` describes each figure as data (which plotting
function of :mod:`horsemocap.plots.summary`, its arrays and options) and
has the figures drawn here, usually by a copy of the process forked before
the analysis (:class:`horsemocap.forking.EarlyCalls`), which loads
matplotlib while the analysis runs and draws each step's figures as the
step ends: the analysis itself never loads it. This module loads no other
plotting module than the one it draws with.
"""
from __future__ import annotations

import base64
import io

import matplotlib.pyplot as plt

from ..forking import run_beside
from . import summary

__all__: list[str] = []     # nothing to re-export from horsemocap.plots

#: The plotting functions a figure description may name.
FIGURE_FUNCTIONS = {
    "marker_tracks": summary.plot_marker_tracks,
    "reprojection_residuals": summary.plot_reprojection_residuals,
    "axes_timeseries": summary.plot_axes_timeseries,
}


def png(fig) -> str:
    """``fig`` as a base64 PNG at 90 dpi, as laid out (no tight bounding box), and closed.

    Examples
    --------
    >>> fig, ax = plt.subplots(figsize=(2, 1))
    >>> png(fig)[:8]
    'iVBORw0K'
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def render_pngs(makers) -> list[str]:
    """Draw every figure of ``makers`` (callables returning a figure) as a base64 PNG, in order.

    Where it is safe, a forked copy of this process draws figures beside this
    one (:func:`horsemocap.forking.run_beside`: matplotlib's text layout is
    the slowest part on one core). The copy draws with the same code and
    data, so the PNGs are the same bytes either way.
    """
    return run_beside([lambda make=make: png(make()) for make in makers])


def draw_pngs(descriptions) -> list[str]:
    """The figures described by ``descriptions``, each ``(function, args, kwargs)`` with ``function``
    a key of :data:`FIGURE_FUNCTIONS`, as base64 PNGs in order.

    Raises
    ------
    KeyError
        A description names no known plotting function.
    """
    makers = [lambda f=FIGURE_FUNCTIONS[name], a=args, k=kwargs: f(*a, **k) for name, args, kwargs in descriptions]
    return render_pngs(makers)

