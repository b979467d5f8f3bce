"""The text a notebook shows in place of a control before it runs or is trusted.

JupyterLab draws a saved widget only in a trusted notebook (the widget
renderer is not "safe"); otherwise it shows the output's ``text/plain``,
which ipywidgets fills with the widget's ``repr`` (cut at 110 characters).
The controls of this package say what they are and how to see them instead
of ``ThresholdPicker(children=(HBox(...``.
"""
from __future__ import annotations


class ControlText:
    """Mixin for a control: its ``repr`` names it and says how to see it."""

    def __repr__(self) -> str:
        doc = (type(self).__doc__ or type(self).__name__).strip().splitlines()[0].rstrip(".;:")
        if len(doc) > 48:
            doc = doc[:47].rsplit(" ", 1)[0] + " ..."
        return f"[{doc}: run the cell, or trust the notebook, to see it]"
