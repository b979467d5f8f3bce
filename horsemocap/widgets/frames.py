"""Controls for triangulation, smoothing and the motion frame (thesis 5.1-5.3).

They replace the thesis' prompts (Appendix A steps 6-7: "enter the period",
"enter marker number (1, 2 or 3) which defines the x-motion direction").
Defaults are the automatic choices of the pipeline.
"""
from __future__ import annotations

import ipywidgets as W

from ..params import SmoothParams

from ._text import ControlText

__all__ = ["ui_triangulation_mode", "ui_smoothing", "ui_motion_marker", "ui_period", "ui_n_periods"]


def ui_triangulation_mode(value: str = "joint"):
    """``.value`` is the ``mode`` of :func:`horsemocap.reconstruction.triangulate`."""
    return W.ToggleButtons(options=[("joint (all cameras)", "joint"), ("thesis (3 pairs, eq. 5.5)", "thesis")],
                           value=value, description="mode", style={"button_width": "auto", "description_width": "initial"})


class SmoothingControls(ControlText, W.VBox):
    """Method dropdown and span box; ``.value`` is ``{"method": ..., "span": ...}``.

    ``"none"`` keeps the triangulated positions (the pipeline's default, see
    :class:`horsemocap.params.AnalysisParams`); the span is then unused.
    """

    METHODS = ("none", "rloess", "loess", "rlowess", "lowess", "moving")

    def __init__(self, method: str = "none", span: float = 0.1):
        if method not in self.METHODS:
            raise ValueError(f"ui_smoothing: method must be one of {self.METHODS}, got {method!r}")
        self.method = W.Dropdown(options=list(self.METHODS), value=method, description="method")
        self.span = W.BoundedFloatText(value=span, min=0.01, max=0.99, step=0.01, description="span")
        super().__init__([self.method, self.span])

    @property
    def value(self) -> dict:
        return {"method": self.method.value, "span": float(self.span.value)}


def ui_smoothing(method: str | None = None, span: float | None = None):
    """Method and span of the pipeline's smoothing step (thesis: rloess, 0.1).

    Defaults are the pipeline's automatic choice,
    ``SmoothParams().method`` (``"loess"``, a deviation from the thesis
    explained in notebook 06) and ``SmoothParams().span`` (0.1). ``.value``
    is ``{"method": ..., "span": ...}``, the ``smooth`` section's fields.
    """
    defaults = SmoothParams()
    return SmoothingControls(defaults.method if method is None else method,
                             defaults.span if span is None else float(span))


def ui_motion_marker(n_markers: int, value: int = 0):
    """Marker whose net displacement defines x-motion (thesis: typed 1, 2 or 3).

    ``.value`` is the 0-based ``marker`` of :func:`horsemocap.frames.motion_frame`.
    """
    if n_markers < 1:
        raise ValueError(f"ui_motion_marker: need at least one marker, got {n_markers}")
    return W.Dropdown(options=[(f"marker {m + 1}", m) for m in range(n_markers)], value=value,
                      description="x-motion")


def ui_period(value: float, max_frames: int):
    """Gait period in frames (thesis: ``period = 18`` typed); default the automatic estimate.

    ``.value`` is the ``period`` of :func:`horsemocap.frames.motion_frame`,
    kept exact (the readout shows it to 0.01 frame, not as 17.988538425613434;
    no continuous updates, so a browser drawing the slider on its grid never
    sends a rounded period back as a choice).
    """
    return W.FloatSlider(value=float(value), min=2.0, max=float(max_frames), step=0.01, readout_format=".2f",
                         continuous_update=False, description="period (frames)",
                         style={"description_width": "initial"})


def ui_n_periods(value: int = 2):
    """1 (eq. 5.6) or 2 (eq. 5.7) periods for the net displacement."""
    return W.ToggleButtons(options=[("one period (5.6)", 1), ("two periods (5.7)", 2)], value=value,
                           description="u1 over", style={"button_width": "auto", "description_width": "initial"})
