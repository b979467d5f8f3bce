"""The prompts of the still images: plumb, static shot, saddle marker (Appendix A 7a, 8a, 12a).

``one_image_centroids.m`` asked, for each camera's still, the threshold
(``left_levelinput``, ...) and the labels of the markers (``left_labels``,
...). :func:`ui_still` shows both per camera, at the automatic choice;
``.value`` is the ``stills[kind]`` object of
:class:`~horsemocap.params.AnalysisParams` (empty while nothing is changed).
"""
from __future__ import annotations

import ipywidgets as W

from ._text import ControlText
import numpy as np

from .. import detection as det
from .detection import LabelPicker

WIDE = {"description_width": "initial"}


def automatic_labels(image, threshold: int, marker_px) -> tuple:
    """Labels (:func:`~horsemocap.detection.label_regions` numbers at ``threshold``) of the regions
    holding the automatically found centres ``marker_px`` (k, 2); a centre in no region gets none."""
    regions = det.label_regions(det.binarize(det.to_gray(np.asarray(image)), threshold))
    u0, v0 = regions.origin
    out = []
    for u, v in np.asarray(marker_px, float):
        if not np.all(np.isfinite([u, v])):
            continue
        r, c = int(round(v)) - v0, int(round(u)) - u0
        lab = regions.labels
        if 0 <= r < lab.shape[0] and 0 <= c < lab.shape[1] and lab[r, c] > 0:
            out.append(int(lab[r, c]))
        elif len(regions):
            out.append(int(regions.ids[np.argmin(np.linalg.norm(regions.centroid - [u, v], axis=1))]))
    return tuple(out)


class StillControls(ControlText, W.VBox):
    """Threshold and labels of one still per camera (one tab per camera).

    ``.value``: ``{}`` while every camera is at its automatic choice;
    ``{camera: {"threshold": l}}`` for the cameras whose threshold was moved
    (the cameras are still matched automatically; a moved threshold starts
    with no labels picked); once labels are picked, ``{camera: {"threshold": l, "labels": [...]}}`` for every camera
    (labels are taken as they are, as the thesis did).
    """

    def __init__(self, images: dict, count: int, marker_px: dict | None = None, scale: int = 1):
        self.images = {c: np.asarray(im) for c, im in images.items()}
        self.count = int(count)
        self.auto, self.default_labels = {}, {}
        self._callbacks = []
        self.pickers, self.sliders, self.boxes = {}, {}, {}
        for cam, im in self.images.items():
            thr = int(det.auto_threshold([det.to_gray(im)], "otsu3"))
            labels = automatic_labels(im, thr, marker_px[cam]) if marker_px and cam in marker_px else ()
            self.auto[cam] = (thr, labels)
            self.default_labels[cam] = labels
            self.sliders[cam] = W.IntSlider(value=thr, min=0, max=254, description=f"threshold ({cam})",
                                            style=WIDE, continuous_update=False, layout=W.Layout(width="420px"))
            self.pickers[cam] = LabelPicker(im, thr, labels, scale=scale)
            self.boxes[cam] = W.VBox([self.sliders[cam], self.pickers[cam]])
            self.sliders[cam].observe(lambda ch, c=cam: self._rethreshold(c), "value")
            self.pickers[cam].select.observe(lambda ch: self._touch(), "value")
        self.tabs = W.Tab(children=list(self.boxes.values()))
        for k, cam in enumerate(self.boxes):
            self.tabs.set_title(k, cam)
        self.message = W.HTML(f"pick the {self.count} markers in every camera; the default is the automatic choice")
        super().__init__([self.tabs, self.message])

    def _rethreshold(self, cam):
        thr = int(self.sliders[cam].value)
        auto_thr, auto_labels = self.auto[cam]
        old = self.pickers[cam]
        self.default_labels[cam] = auto_labels if thr == auto_thr else ()
        new = LabelPicker(self.images[cam], thr, self.default_labels[cam], scale=old._scale)
        self.pickers[cam] = new
        self.boxes[cam].children = [self.sliders[cam], new]
        new.select.observe(lambda ch: self._touch(), "value")
        self._touch()

    def show(self, chosen: dict) -> None:
        """Put a stored choice (``stills[kind]``) into the tabs: thresholds, then labels."""
        for cam in self.images:
            given = {**chosen.get("all", {}), **chosen.get(cam, {})}
            if "threshold" in given:
                self.sliders[cam].value = int(given["threshold"])
            if given.get("labels"):
                opts = {o[1] for o in self.pickers[cam].select.options}
                self.pickers[cam].select.value = tuple(int(x) for x in given["labels"] if int(x) in opts)

    def on_change(self, callback):
        """Call ``callback()`` whenever ``.value`` may have changed (used by ``Workspace.bind``)."""
        self._callbacks.append(callback)

    def _touch(self):
        for cb in self._callbacks:
            cb()

    @property
    def value(self) -> dict:
        labels_changed = any(tuple(self.pickers[c].value) != self.default_labels[c] for c in self.images)
        if labels_changed:
            return {c: {"threshold": int(self.sliders[c].value), "labels": [int(x) for x in self.pickers[c].value]}
                    for c in self.images}
        return {c: {"threshold": int(self.sliders[c].value)} for c in self.images
                if int(self.sliders[c].value) != self.auto[c][0]}


def ui_still(images: dict, count: int, marker_px: dict | None = None, scale: int = 1) -> StillControls:
    """Threshold and label prompts of one still per camera (Appendix A 7a plumb, 8a/12a static shot).

    Parameters
    ----------
    images : dict camera -> image
    count : int
        Markers in the still (plumb 2; static shot: the markers + the saddle marker).
    marker_px : dict camera -> (count, 2), optional
        The automatically found centres (the pipeline's ``plumb_px`` /
        ``static_px``): their regions are the default labels.
    """
    return StillControls(images, count, marker_px, scale)


def ui_saddle_marker(static_px: dict, saddle_index: int, camera: str | None = None):
    """Which static-shot point is the saddle marker (Appendix A 12a); default the automatic one.

    Options are the static shot's points in their order (ascending ``u`` in
    the reference camera) with their pixel position in ``camera``.
    """
    cam = camera or next(iter(static_px))
    px = np.asarray(static_px[cam], float)
    opts = [(f"point {k}: ({u:.0f}, {v:.0f}) px in {cam}", k) for k, (u, v) in enumerate(px)]
    return W.Dropdown(options=opts, value=int(saddle_index), description="saddle marker", style=WIDE,
                      layout=W.Layout(width="420px"))
