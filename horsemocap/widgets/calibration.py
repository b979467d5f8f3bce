"""Widgets of the calibration: camera picker, view browser, views to exclude (thesis 8.2)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import ipywidgets as w

from ._text import ControlText
import numpy as np


def _png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    return buf.tobytes()


def ui_camera(cameras, value: str | None = None) -> w.Dropdown:
    """Pick a camera (default: the first, the reference camera)."""
    cameras = list(cameras)
    return w.Dropdown(options=cameras, value=value or cameras[0], description="camera")


class ViewBrowser(ControlText, w.VBox):
    """Browse the checkerboard views of a calibration: detected (green +) and reprojected (red x) corners.

    ``.value`` is ``(camera, view name)`` shown.
    """

    def __init__(self, result, camera: str | None = None, which: str = "alone"):
        self.result = result
        self.camera = ui_camera(result.cameras, camera)
        # the slider reads the view's own name (its key, as the label and the files say), its value the index
        self.view = w.SelectionSlider(options=[(name, k) for k, name in enumerate(result.view_names)], value=0,
                                      description="view")
        self.which = w.ToggleButtons(options=["alone", "joint"], value=which if result.joint else "alone",
                                     description="calibration", style={"button_width": "auto", "description_width": "initial"})
        self.zoom = w.IntSlider(value=0, min=0, max=200, step=10, description="zoom (px)", style={"description_width": "initial"})
        self.image = w.Image(format="png")
        self.label = w.HTML()
        for c in (self.camera, self.view, self.which, self.zoom):
            c.observe(self._redraw, "value")
        super().__init__([w.HBox([self.camera, self.which]), w.HBox([self.view, self.zoom]), self.label, self.image])
        self._redraw()

    @property
    def value(self):
        return self.camera.value, self.result.view_names[self.view.value]

    def _redraw(self, *_):
        from ..plots.calibration import draw_board_view

        cam, k = self.camera.value, self.view.value
        img = draw_board_view(self.result, cam, k, self.which.value)
        v = self.result.views[cam]
        z = self.zoom.value
        if z and np.all(np.isfinite(v.corners[k])):
            cx, cy = v.corners[k][0]
            y0, x0 = int(max(cy - z, 0)), int(max(cx - z, 0))
            img = cv2.resize(img[y0:int(cy + z), x0:int(cx + z)], (480, 480), interpolation=cv2.INTER_NEAREST)
        self.image.value = _png(np.ascontiguousarray(img))
        res = (self.result.singles[cam] if self.which.value == "alone" or self.result.joint is None
               else self.result.joint.intrinsics[cam])
        err = res.per_view_rms[k]
        status = v.reasons[k] or res.reasons[k] or f"RMS reprojection error {err:.3f} px, window {v.windows[k]}"
        self.label.value = f"<b>{cam}</b> view <b>{v.names[k]}</b>: {status}"


def ui_view_browser(result, camera: str | None = None) -> ViewBrowser:
    """Browse the views of a :class:`~horsemocap.calibration.RigCalibration`."""
    return ViewBrowser(result, camera)


class ViewExcluder(ControlText, w.VBox):
    """A checkbox per view and camera to leave the view out; labels give the per-view error.

    ``.value`` is ``{camera: [view names excluded]}``, the ``exclude`` of
    :func:`~horsemocap.calibration.calibrate_rig`. Default: nothing excluded
    (the automatic choice); views without a board cannot be ticked.
    """

    def __init__(self, result, excluded: dict | None = None):
        excluded = excluded or {}
        self.result = result
        self.boxes = {}
        rows = [w.HTML("<b>exclude</b> (RMS reprojection error of the view alone, px)")]
        # one layout and one style for every checkbox: a notebook saves each widget model once
        layout, style = w.Layout(width="auto", margin="0 12px 0 0"), w.widgets.widget_bool.CheckboxStyle()
        row_layout = w.Layout()
        for k, name in enumerate(result.view_names):
            items = []
            for cam in result.cameras:
                s = result.singles[cam]
                v = result.views[cam]
                e = s.per_view_rms[k]
                txt = f"{cam} {name}: " + (f"{e:.3f}" if np.isfinite(e) else (v.reasons[k] or s.reasons[k]))
                cb = w.Checkbox(value=name in excluded.get(cam, ()), description=txt, indent=False,
                                disabled=bool(v.reasons[k]), layout=layout, style=style)
                self.boxes[(cam, name)] = cb
                items.append(cb)
            rows.append(w.HBox(items, layout=row_layout))
        super().__init__(rows)

    @property
    def value(self) -> dict:
        out = {c: [] for c in self.result.cameras}
        for (cam, name), cb in self.boxes.items():
            if cb.value:
                out[cam].append(name)
        return out


def ui_exclude_views(result, excluded: dict | None = None) -> ViewExcluder:
    """Checkboxes to exclude views of a :class:`~horsemocap.calibration.RigCalibration`."""
    return ViewExcluder(result, excluded)


@dataclass(frozen=True)
class SessionCalibration:
    """What a session gives the calibration (:func:`session_calibration`).

    Attributes
    ----------
    views : dict or None
        Camera -> folder of checkerboard views, or None.
    board : tuple or None
        ``(inner_corners, square_size_m)``, or None.
    rig_path : Path or None
        The session's ``rig.toml``, or None.
    views_used : bool
        Whether the pipeline calibrates from the views (it reads a given rig file unless asked to recalibrate).
    note : str
        ``""`` when the pipeline calibrates from the views, else a plain sentence saying where the rig comes from.
    short : str
        The same in a few words, for the cells that skip a part.
    """

    views: dict | None
    board: tuple | None
    rig_path: Path | None
    views_used: bool
    note: str
    short: str


def session_calibration(session_dir) -> SessionCalibration:
    """What a session gives the calibration: its checkerboard views, or only a rig file.

    The notebooks that show the calibration (01, 03) ask this first: a session
    recorded by a lab that calibrated once (``calibration.rig`` in
    ``session.json``, no ``calibration.images``) has no views to detect or
    calibrate, and the pipeline reads its rig from the file instead.

    Parameters
    ----------
    session_dir : path
        A session folder (holding ``session.json``).

    Returns
    -------
    SessionCalibration

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> c = session_calibration(default_session_dir())
    >>> sorted(c.views), c.board, c.note
    (['left', 'middle', 'right'], ((7, 14), 0.1), '')

    A session with only ``calibration/rig.toml`` gives ``views`` None,
    ``note`` "no checkerboard views in this session: the pipeline reads the
    rig from calibration/rig.toml instead of calibrating it" and ``short``
    "no checkerboard views; the rig was read from rig.toml".
    """
    from ..session import load_session

    s = load_session(session_dir, open_sources=False)
    board = None if s.board is None else (tuple(s.board.inner_corners), float(s.board.square_size_m))
    views = None if s.calibration_images is None else {c: Path(p) for c, p in s.calibration_images.items()}
    used = s.calibrates_from_views()
    note = short = ""
    if not used:
        try:
            rel = s.rig_path.relative_to(s.root).as_posix()
        except ValueError:
            rel = str(s.rig_path)
        note = (f"the session gives its checkerboard views but also {rel}: the pipeline reads the rig from the file"
                if views is not None else
                f"no checkerboard views in this session: the pipeline reads the rig from {rel} instead of "
                "calibrating it")
        short = (f"{'views not used' if views is not None else 'no checkerboard views'}; "
                 f"the rig was read from {s.rig_path.name}")
    return SessionCalibration(views=views, board=board, rig_path=s.rig_path, views_used=used, note=note,
                              short=short)
