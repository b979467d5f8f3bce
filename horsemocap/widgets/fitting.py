"""Controls for the curve fits (thesis section 5.5.2, Appendix A step 9).

They replace the prompts ``fit_type_x`` (default poly1), ``no_of_extreme``
and ``fit_choice`` (1: Fourier E/2, 2: Fourier E/2+1). Defaults are the
automatic choices of :mod:`horsemocap.fitting`.
"""
from __future__ import annotations

import ipywidgets as W

from ._text import ControlText

from .. import fitting

__all__ = ["ui_x_degree", "ui_fourier_order"]


def ui_x_degree(value: int = 1):
    """Degree of the x-motion polynomial (thesis ``fit_type_x``; poly1 recommended)."""
    return W.BoundedIntText(value=value, min=0, max=5, description="x poly deg", style={"description_width": "initial"})


def ui_fourier_order(t, y, label: str = "", rule: str = "significant", w0=None, *,
                     trend: bool = False, start: str = "matlab", value: int | None = None,
                     n_extremes: int | None = None):
    """Number of extremes E and the choice between Fourier E/2 and E/2+1.

    Parameters
    ----------
    t, y : (n,)
        Time and the (registered) coordinate being fitted.
    label : str
        Shown in front of the controls (e.g. ``"marker 1, y"``).
    rule, w0, trend, start
        As in :func:`horsemocap.fitting.fit_motion` (the pipeline passes its
        ``order_rule``, ``w0 = 2 pi / period``, ``fourier_trend``): the
        default choice is then the order the pipeline chose.
    value, n_extremes : int, optional
        Give the defaults directly (e.g. ``MotionFit.orders[m, ax]`` and
        ``MotionFit.n_extremes[m, ax]`` of the pipeline's fit) instead of
        recomputing them; ``value`` must be one of the two proposed orders.

    Returns
    -------
    ipywidgets.HBox with ``.value`` = the chosen Fourier order N, and
    attributes ``extremes`` (BoundedIntText, default: E counted as
    :func:`horsemocap.fitting.fit_motion` counts it, on the detrended data
    when ``trend``) and ``choice`` (ToggleButtons).
    Changing E updates the two proposed orders (E/2, E/2+1) and keeps the
    same position of the choice. No output is produced by the callbacks.
    """
    import numpy as np

    if n_extremes is None:
        yy = np.asarray(y, float)
        if trend:
            tt = np.asarray(t, float)
            ok = np.isfinite(yy)
            yy = yy[ok] - np.polyval(np.polyfit(tt[ok], yy[ok], 1), tt[ok])
        n_extremes = fitting.count_extremes(yy)
    e0 = int(n_extremes)
    if value is None:
        n_auto = fitting.choose_order(t, y, e0, rule=rule, w0=w0, start=start, trend=trend)
    else:
        n_auto = int(value)
        if n_auto not in fitting.proposed_orders(e0):
            raise ValueError(f"value: fourier{n_auto} is not one of the orders proposed for E = {e0} "
                             f"({fitting.proposed_orders(e0)})")
    ext = W.BoundedIntText(value=e0, min=0, max=40, description="extremes E", style={"description_width": "initial"},
                           layout=W.Layout(width="170px"))

    def options(e):
        n1, n2 = fitting.proposed_orders(e)
        return [(f"fourier{n1} (E/2)", n1), (f"fourier{n2} (E/2+1)", n2)]

    choice = W.ToggleButtons(options=options(e0), value=n_auto, tooltips=["E/2", "E/2+1"],
                             style={"button_width": "auto", "description_width": "initial"},
                             layout=W.Layout(width="auto", flex="0 0 auto"))

    def on_e(change):
        idx = [v for _, v in choice.options].index(choice.value) if choice.value is not None else 0
        opts = options(change["new"])
        choice.options = opts
        choice.value = opts[idx][1]

    ext.observe(on_e, names="value")

    class _Box(ControlText, W.HBox):
        """Fourier order of one coordinate"""

        @property
        def value(self):
            return int(choice.value)

    box = _Box([W.Label(label, layout=W.Layout(width="110px")), ext, choice],
               layout=W.Layout(flex_flow="row nowrap", align_items="center"))
    box.extremes, box.choice = ext, choice
    return box
