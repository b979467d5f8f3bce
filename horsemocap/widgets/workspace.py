"""The session picker of the notebooks' first cell (:mod:`horsemocap.workspace`)."""
from __future__ import annotations

from pathlib import Path

import ipywidgets as W

from ..params import ParamsError
from ..workspace import Workspace, clear_choices, sample_sessions
from ._text import ControlText

WIDE = {"description_width": "initial"}
OTHER = "another folder ..."


class SessionPicker(ControlText, W.VBox):
    """A dropdown of the ``data_samples/`` sessions and a field for any session folder.

    ``.value`` is the chosen session folder. Choosing one makes it the
    session of every notebook (``workspace.json``); run the cells below (or
    the next notebooks) again to analyse it. The message line says what the
    workspace holds, or why a folder cannot be used.
    """

    def __init__(self, workspace):
        self.workspace = workspace
        samples = sample_sessions()
        current = workspace.session_dir
        options = [(name, str(path)) for name, path in samples.items()]
        if str(current) not in [v for _, v in options]:
            options.append((current.name, str(current)))
        options.append((OTHER, ""))
        self.dropdown = W.Dropdown(options=options, value=str(current), description="session",
                                   style=WIDE, layout=W.Layout(width="360px"))
        self.path = W.Text(value="", placeholder="/path/to/session folder (holding session.json)",
                           description="folder", style=WIDE, layout=W.Layout(width="520px", display="none"))
        self.use = W.Button(description="use this folder", layout=W.Layout(width="auto", display="none"))
        self.reset = W.Button(description="forget this session's choices", layout=W.Layout(width="auto"),
                              tooltip="back to the automatic choice of every prompt (deletes choices.json)")
        self.message = W.HTML()
        super().__init__([W.HBox([self.dropdown, self.reset]), W.HBox([self.path, self.use]), self.message])
        self.reset.on_click(self._on_reset)
        self.dropdown.observe(self._on_dropdown, "value")
        self.use.on_click(self._on_use)
        self._say()

    @property
    def value(self) -> Path:
        return self.workspace.session_dir

    def _say(self, error: str = ""):
        if error:
            self.message.value = f"<span style='color:#b00'>{error}</span>"
            return
        ch = self.workspace.choices
        what = ", ".join(sorted(ch)) if ch else "none: every choice automatic"
        caveat = (" <b>Every notebook's numbers follow these choices; the numbers quoted in the notebooks' text "
                  "are those of the automatic run</b> (the button below takes the choices back)." if ch else "")
        self.message.value = (f"analysing <b>{self.workspace.name}</b>; choices made in the notebooks: {what}.{caveat} "
                              "After changing the session, run the cells below again.")

    def _on_dropdown(self, change):
        show = "" if change.new == "" else "none"
        self.path.layout.display = self.use.layout.display = ("" if show == "" else "none")
        if change.new:
            self._choose(change.new)

    def _on_reset(self, *_):
        clear_choices(self.workspace.session_dir)
        self._say()

    def _on_use(self, *_):
        self._choose(self.path.value.strip())

    def _choose(self, folder: str):
        try:
            self.workspace.use(folder)
        except ParamsError as exc:
            self._say(str(exc))
            return
        self._say()


def ui_session(workspace=None) -> SessionPicker:
    """The session picker of a :class:`~horsemocap.workspace.Workspace` (default: the current one)."""
    ws = workspace or Workspace()
    ws.picker = SessionPicker(ws)
    return ws.picker


PRESET_OPTIONS = (("the automatic choices", "default"), ("the thesis' own chain (--preset thesis)", "thesis"))


class PresetSwitch(ControlText, W.ToggleButtons):
    """The chain every notebook runs: the automatic choices, or the thesis' own chain end to end.

    ``.value`` is the preset's name (``"default"`` or ``"thesis"``). The
    thesis' chain is ``--preset thesis`` of the command line: stereo pairs
    with the left camera, each camera alone, the pairs averaged, rloess, the
    E/2 order, the averaged omega/alpha versions, one weight per record.
    Choosing it writes ``"preset": "thesis"`` into the session's choices;
    the widgets of the later notebooks then start from the thesis' values,
    and a choice made with them still overrides the preset's.
    """


def ui_preset(workspace=None) -> PresetSwitch:
    """The preset switch (:class:`PresetSwitch`), bound to the session's choices."""
    ws = workspace or Workspace()
    switch = PresetSwitch(options=PRESET_OPTIONS, value="default", description="analysis",
                          style={"description_width": "initial", "button_width": "auto"},
                          tooltips=["every choice automatic (the default pipeline)",
                                    "the thesis' chain: pairwise calibration, per-camera detection, pairs "
                                    "averaged, rloess, order E/2, averaged versions, one scalar weight"])
    ws.bind(switch, "preset", automatic=None, convert=lambda v: None if v == "default" else v)
    return switch
