"""Controls for the angular kinematics (thesis section 6.1-6.2, 8.4.1,
Appendix A step 11): which of the six omega / alpha versions enter the
average ("Is omega1_ver1 to be in the calculation of final omega? y/n"),
and the method."""
from __future__ import annotations

import ipywidgets as W
import numpy as np

from ..params import FitsParams
from ..rigid import VERSION_LABELS
from ._text import ControlText

__all__ = ["ui_versions", "ui_angular_method", "ui_saddle_method"]


def ui_versions(name: str = "omega", value=None):
    """Six checkboxes; ``.value`` is the (6,) bool ``use`` of
    :func:`horsemocap.rigid.average_versions` (default: all six, the pipeline's automatic choice)."""
    value = np.ones(6, bool) if value is None else np.asarray(value, bool)
    layout, style = W.Layout(width="auto", margin="0 12px 0 0"), W.widgets.widget_bool.CheckboxStyle()
    boxes = [W.Checkbox(value=bool(v), description=lab.replace("omega", name), indent=False,
                        layout=layout, style=style)
             for lab, v in zip(VERSION_LABELS, value)]

    class _Box(ControlText, W.HBox):
        """The versions that enter the average"""

        @property
        def value(self):
            return np.array([b.value for b in boxes], bool)

    box = _Box(boxes)
    box.checkboxes = boxes
    return box


def ui_angular_method(value: str | None = None):
    """``method`` of :func:`horsemocap.rigid.analyse_rigid_body`: the average of
    the chosen thesis versions, the least-squares solution from all markers,
    or the Fourier fit of the registered orientation. Default: the pipeline's
    ``rigid_body.fits.angular_method`` (pass ``analysis.params.rigid_body.fits.angular_method``
    to follow a run's choice)."""
    if value is None:
        value = FitsParams().angular_method
    return W.ToggleButtons(options=[("thesis versions (6.3/6.4)", "thesis"), ("least squares", "lstsq"),
                                    ("fit of the orientation", "rotation")],
                           value=value, description="omega, alfa", style={"button_width": "auto", "description_width": "initial"})


def ui_saddle_method(value: str | None = None):
    """``saddle_method`` of :func:`horsemocap.rigid.analyse_rigid_body` (default: the
    pipeline's ``rigid_body.fits.saddle_method``)."""
    if value is None:
        value = FitsParams().saddle_method
    return W.ToggleButtons(options=[("eq. 6.54/6.55 mean", "thesis"), ("fit of eq. 6.48 path", "direct"),
                                    ("fit of the smoothed-pose path", "pose")],
                           value=value, description="saddle v, a", style={"button_width": "auto", "description_width": "initial"})
