"""Widgets for marker detection (thesis chapter 4, Appendix A step 4).

They stand in for the prompts of ``left_level_info_from_all_images_1.m``
(threshold, checked through the whole motion) and
``left_data_from_first_image_2.m`` (labels, area range, window, distance
tolerance). Each builder returns a control whose ``.value`` is the parameter
of :func:`horsemocap.detection.detect_markers`; defaults are the automatic
choices (pass ``track.params`` of an automatic run). The previews only draw;
they never print (nbval stores prints of callbacks).
"""
from __future__ import annotations

import time
from dataclasses import replace

import cv2
import ipywidgets as W

from ._text import ControlText
import numpy as np

from .. import detection as det
from ..detection import GENERIC_AREA

__all__ = ["ThresholdPicker", "LabelPicker", "WindowPicker", "DetectionControls",
           "ui_threshold", "ui_label_picker", "ui_area_range", "ui_window", "ui_distance_tolerance",
           "ui_detection"]


def _png(img: np.ndarray) -> bytes:
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    return buf.tobytes()


def threshold_preview(gray: np.ndarray, threshold: int, params: det.DetectionParams | None = None):
    """Binary image of eq. (4.5) with regions that pass the area filter in green.

    Returns ``(rgb image, number of regions, number in the area range)``.
    """
    bw = det.binarize(gray, threshold)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(bw, connectivity=8)
    out = np.repeat(bw[..., None], 3, axis=-1)
    n_ok = n - 1
    if params is not None and params.area_min is not None and params.area_max is not None:
        ok = det.filter_area(stats[:, 4], params.area_min, params.area_max)
        ok[0] = False
        n_ok = int(ok.sum())
        out[ok[lab]] = (60, 230, 60)
    return out, n - 1, n_ok


class ThresholdPicker(ControlText, W.VBox):
    """Threshold slider with a live binary preview and region count.

    ``.value`` is the threshold ``l`` of eq. (4.5). The frame slider lets one
    check, as Appendix A step 4.a.i asks, that the markers stay visible and
    isolated through the whole motion. ``last_ms`` holds the time of the
    last redraw (threshold + labelling + PNG encoding).
    """

    def __init__(self, frames, threshold: int, frame: int = 0, params=None):
        self._frames = frames
        self._params = params
        self._gray = {}
        self.slider = W.IntSlider(value=int(threshold), min=0, max=254, description="threshold l", style={"description_width": "initial"},
                                  continuous_update=True)
        self.frame_slider = W.IntSlider(value=int(frame), min=0, max=len(frames) - 1, description="frame")
        self.image = W.Image(format="png")
        self.info = W.HTML()
        self.n_regions = 0
        self.n_in_area = 0
        self.last_ms = float("nan")
        super().__init__([W.HBox([self.slider, self.frame_slider]), self.info, self.image])
        self.slider.observe(self._redraw, "value")
        self.frame_slider.observe(self._redraw, "value")
        self._redraw()

    @property
    def value(self) -> int:
        return int(self.slider.value)

    def gray(self, k: int) -> np.ndarray:
        g = self._gray.get(k)
        if g is None:
            g = det.to_gray(np.asarray(self._frames[k]))
            self._gray[k] = g
        return g

    def _redraw(self, *_):
        t0 = time.perf_counter()
        k = int(self.frame_slider.value)
        img, n, n_ok = threshold_preview(self.gray(k), self.value, self._params)
        self.image.value = _png(img)
        self.n_regions, self.n_in_area = n, n_ok
        self.last_ms = 1e3 * (time.perf_counter() - t0)
        extra = f", {n_ok} in the area range (green)" if self._params is not None and self._params.area_min else ""
        self.info.value = f"frame {k}: {n} white regions at l = {self.value}{extra}"


def draw_labels(image, regions: det.Regions, index=None, chosen=(), scale: int = 2) -> np.ndarray:
    """The labelled binary image with regions outlined and numbered (label picker).

    ``index`` selects the regions to number (default all); ``chosen`` labels
    are drawn in green, the others in yellow. The image is enlarged by
    ``scale`` so that the numbers stay legible.
    """
    h, w = np.asarray(image).shape[:2]
    rgb = np.zeros((h, w, 3), np.uint8)              # the labelled binary image, as the thesis shows it
    lab = regions.labels
    u0, v0 = regions.origin
    rgb[v0:v0 + lab.shape[0], u0:u0 + lab.shape[1]][lab > 0] = (170, 170, 170)
    if scale != 1:
        rgb = cv2.resize(rgb, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    idx = np.arange(len(regions)) if index is None else np.asarray(index, dtype=int)
    chosen = set(int(c) for c in chosen)
    for i in idx:
        rid = int(regions.ids[i])
        u, v = regions.centroid[i]
        col = (60, 230, 60) if rid in chosen else (255, 220, 0)
        x, y, w, h = regions.bbox[i]
        cv2.rectangle(rgb, (int(x * scale) - 2, int(y * scale) - 2),
                      (int((x + w) * scale) + 1, int((y + h) * scale) + 1), col, 1)
        cv2.putText(rgb, str(rid), (int(u * scale) + 6, int(v * scale) - 6), cv2.FONT_HERSHEY_SIMPLEX,
                    0.4, col, 1, cv2.LINE_AA)
    return rgb


class LabelPicker(ControlText, W.VBox):
    """Pick the marker labels on the labelled first image (``left_labels``).

    Shows the regions of the chosen frame at the threshold with their label
    numbers (those within ``area_range``, round or not); ``.value`` is the
    tuple of selected labels, by default the automatic choice.
    """

    def __init__(self, image, threshold: int, labels=(), area_range=(3, np.inf), scale: int = 2):
        self._area_range = area_range
        self._scale = scale
        self.select = W.SelectMultiple(options=[], rows=3, description="labels")
        self.picture = W.Image(format="png")
        super().__init__([self.select, self.picture])
        self.relabel(image, threshold, labels)
        self.select.observe(self._redraw, "value")

    def relabel(self, image, threshold: int, labels=()) -> None:
        """Label ``image`` at ``threshold`` again; the selection becomes those of ``labels`` that exist.

        The options and the selection always name regions of the image shown
        (a threshold change renumbers the regions, so a selection is not
        carried over to another threshold or frame).
        """
        self.threshold = int(threshold)
        self.regions = det.label_regions(det.binarize(det.to_gray(np.asarray(image)), threshold))
        r = self.regions
        idx = np.flatnonzero(det.filter_area(r.area, *self._area_range))
        if len(idx) > 60:                       # keep the picture legible
            idx = idx[np.argsort(-r.area[idx])[:60]]
            idx = np.union1d(idx, [i for i in range(len(r)) if int(r.ids[i]) in set(labels)]).astype(int)
        self.index = idx
        opts = [(f"{int(r.ids[i])}: area {int(r.area[i])} px at ({r.centroid[i, 0]:.0f}, {r.centroid[i, 1]:.0f})",
                 int(r.ids[i])) for i in idx]
        self._image = np.asarray(image)
        self.select.value = ()
        self.select.options = opts
        self.select.rows = min(12, max(3, len(opts)))
        self.select.value = tuple(int(x) for x in labels if int(x) in {o[1] for o in opts})
        self._redraw()

    @property
    def value(self) -> tuple:
        return tuple(int(x) for x in self.select.value)

    def _redraw(self, *_):
        self.picture.value = _png(draw_labels(self._image, self.regions, self.index, self.value, self._scale))


class WindowPicker(ControlText, W.HBox):
    """Window size ``(W_du, W_dv)`` of thesis 4.5.4; ``.value`` is the tuple."""

    def __init__(self, window=(100, 60), max_size=(640, 480)):
        self.du = W.IntSlider(value=int(window[0]), min=4, max=int(max_size[0]), description="W_du")
        self.dv = W.IntSlider(value=int(window[1]), min=4, max=int(max_size[1]), description="W_dv")
        super().__init__([self.du, self.dv])

    @property
    def value(self) -> tuple:
        return int(self.du.value), int(self.dv.value)


def ui_threshold(frames, params: det.DetectionParams | None = None, frame: int | None = None) -> ThresholdPicker:
    """Threshold slider (default: ``params.threshold``, else the automatic level)."""
    frames = np.asarray(frames) if not isinstance(frames, (list, tuple)) else frames
    thr = params.threshold if params is not None and params.threshold is not None else None
    if thr is None:
        k = np.unique(np.linspace(0, len(frames) - 1, min(len(frames), 8)).round().astype(int))
        thr = det.auto_threshold([det.to_gray(np.asarray(frames[i])) for i in k],
                                 params.threshold_method if params else "otsu3")
    if frame is None:
        frame = params.first_frame if params is not None and params.first_frame is not None else 0
    return ThresholdPicker(frames, thr, frame, params)


def ui_label_picker(image, params: det.DetectionParams, scale: int = 1) -> LabelPicker:
    """Label picker on ``image`` (the first frame) at ``params.threshold``."""
    if params.threshold is None:
        raise ValueError("ui_label_picker: params.threshold is needed (use track.params of an automatic run)")
    rng = (GENERIC_AREA[0], np.inf)
    return LabelPicker(image, params.threshold, params.labels or (), rng, scale)


def ui_area_range(params: det.DetectionParams, max_area: int | None = None) -> W.IntRangeSlider:
    """Area range ``[area_min, area_max]`` in pixels (thesis 4.5.3)."""
    lo = int(params.area_min if params.area_min is not None else 3)
    hi = int(params.area_max if params.area_max is not None else 400)
    top = int(max_area or max(4 * hi, 100))
    return W.IntRangeSlider(value=(lo, hi), min=1, max=top, description="area px")


def ui_window(params: det.DetectionParams, image_size=(640, 480)) -> WindowPicker:
    """Window size sliders (thesis 4.5.4)."""
    return WindowPicker(params.window or (100, 60), image_size)


TOLERANCE_STEP = 0.005   # the distance tolerance slider's grid


def ui_distance_tolerance(params: det.DetectionParams) -> W.FloatSlider:
    """Distance tolerance ``DT`` of eq. (4.11), as a fraction.

    The automatic tolerance is rarely on the slider's 0.005 grid, and a
    browser snaps a slider to its grid when it draws it; with
    ``continuous_update=False`` that snapped value is not sent back to the
    kernel until the slider is moved, so drawing the control never changes
    the choice.
    """
    v = params.distance_tolerance if params.distance_tolerance is not None else 0.15
    return W.FloatSlider(value=float(v), min=0.01, max=0.5, step=TOLERANCE_STEP, readout_format=".3f",
                         description="DT", continuous_update=False)



class DetectionControls(ControlText, W.VBox):
    """All detection prompts together; ``.value`` is a :class:`DetectionParams`.

    The first frame (the frame whose regions the labels name, ``first_frame``)
    has its own slider; the label picker follows the threshold and the first
    frame (moving either relabels the image and clears the selection, back to
    the automatic one at the automatic threshold and frame), so its options,
    its selection and ``.value.labels`` always agree.
    """

    def __init__(self, frames, params: det.DetectionParams, scale: int = 1):
        self.base = params
        self.threshold = ui_threshold(frames, params)
        f0 = params.first_frame or 0
        self.first_frame = W.IntSlider(value=int(f0), min=0, max=len(frames) - 1, description="first frame",
                                       style={"description_width": "initial"})
        self.labels = ui_label_picker(np.asarray(frames[f0]), params, scale)
        self.area = ui_area_range(params)
        size = (np.asarray(frames[0]).shape[1], np.asarray(frames[0]).shape[0])
        self.window = ui_window(params, size)
        self.tolerance = ui_distance_tolerance(params)
        self._frames = frames
        super().__init__([self.threshold, self.first_frame, self.labels, self.area, self.window, self.tolerance])
        self.threshold.slider.observe(self._relabel, "value")
        self.first_frame.observe(self._relabel, "value")

    def _relabel(self, *_):
        """The label picker follows the threshold and the first frame (its labels name their regions)."""
        thr, f0 = int(self.threshold.value), int(self.first_frame.value)
        same = thr == self.base.threshold and f0 == (self.base.first_frame or 0)
        self.labels.relabel(np.asarray(self._frames[f0]), thr, (self.base.labels or ()) if same else ())

    @property
    def value(self) -> det.DetectionParams:
        dt = float(self.tolerance.value)
        if self.base.distance_tolerance is not None and abs(dt - self.base.distance_tolerance) <= TOLERANCE_STEP / 2:
            dt = float(self.base.distance_tolerance)   # the slider's grid point of the automatic value
        return replace(self.base, threshold=self.threshold.value,
                       labels=self.labels.value or None,   # regions at this threshold and first frame
                       first_frame=int(self.first_frame.value),
                       area_min=float(self.area.value[0]), area_max=float(self.area.value[1]),
                       window=self.window.value, distance_tolerance=dt)


def ui_detection(frames, params: det.DetectionParams, scale: int = 1) -> DetectionControls:
    """Every prompt of ``left_data_from_first_image_2.m`` in one control.

    The label picker follows the threshold and the first frame (labels name
    regions of one binary image).
    """
    return DetectionControls(frames, params, scale)
