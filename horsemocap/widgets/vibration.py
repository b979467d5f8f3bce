"""Controls for the comfort indicators (thesis chapter 7)."""
from __future__ import annotations

import ipywidgets as W

__all__ = ["ui_weighting_mode", "ui_periods"]


def ui_weighting_mode(value: str = "iso"):
    """Choose how the weighting is applied: ``"iso"`` (per harmonic, the
    standards; default) or ``"thesis"`` (one scalar at the dominant harmonic,
    Table 8.7). ``.value`` is the ``mode`` of ``vibration.comfort_indicators``."""
    return W.ToggleButtons(options=[("ISO 2631 (per harmonic)", "iso"),
                                    ("thesis (scalar W)", "thesis")],
                           value=value, description="weighting", style={"button_width": "auto", "description_width": "initial"})


def ui_periods(value: int = 2):
    """tau in gait periods (the thesis: 2). ``.value`` is ``n_periods``."""
    return W.IntSlider(value=value, min=1, max=10, description="tau (periods)", style={"description_width": "initial"})
