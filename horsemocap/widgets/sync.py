"""Widget to check and override the flash offsets frame by frame (thesis 3.5, Figure 3.9)."""
from __future__ import annotations

import cv2
import ipywidgets as w

from ._text import ControlText
import numpy as np


def _png(img: np.ndarray) -> bytes:
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", img)
    return buf.tobytes()


def _frame(src, k):
    try:
        return src.frame(k) if hasattr(src, "frame") else np.asarray(src)[k]
    except Exception:
        return None


class SyncChooser(ControlText, w.VBox):
    """Offsets per camera (``IntText``) with a preview of the frames they align.

    ``.value`` is ``{camera: offset}`` (the session's ``sync.offsets``).
    """

    def __init__(self, frames: dict, offsets: dict, regions: dict | None = None, crop: int = 50):
        self.frames = frames
        self.regions = regions or {}
        self.crop = crop
        self.boxes = {c: w.IntText(value=int(o), description=c, layout=w.Layout(width="160px")) for c, o in offsets.items()}
        self.shift = w.IntSlider(value=0, min=-5, max=5, description="frame - flash",
                                 style={"description_width": "initial"})
        self.image = w.Image(format="png")
        self.label = w.HTML()
        for b in self.boxes.values():
            b.observe(self._redraw, "value")
        self.shift.observe(self._redraw, "value")
        super().__init__([w.HBox(list(self.boxes.values())), self.shift, self.label, self.image])
        self._redraw()

    @property
    def value(self) -> dict:
        return {c: int(b.value) for c, b in self.boxes.items()}

    def _redraw(self, *_):
        tiles = []
        for c, b in self.boxes.items():
            k = b.value + self.shift.value
            img = _frame(self.frames[c], k)
            if img is None:
                img = np.zeros((2 * self.crop, 2 * self.crop, 3), np.uint8)
            elif c in self.regions:
                ys, xs = np.nonzero(self.regions[c])
                cy, cx = int(ys.mean()), int(xs.mean())
                img = img[max(cy - self.crop, 0):cy + self.crop, max(cx - self.crop, 0):cx + self.crop]
            if img.ndim == 2:
                img = np.repeat(img[..., None], 3, axis=-1)
            img = cv2.resize(np.ascontiguousarray(img), (200, int(200 * img.shape[0] / max(img.shape[1], 1))),
                             interpolation=cv2.INTER_NEAREST)
            tiles.append(img)
        h = max(t.shape[0] for t in tiles)
        tiles = [np.pad(t, ((0, h - t.shape[0]), (0, 4), (0, 0))) for t in tiles]
        self.image.value = _png(np.hstack(tiles))
        frames = ", ".join(f"{c} {b.value + self.shift.value}" for c, b in self.boxes.items())
        self.label.value = f"<small>frames shown: {frames}</small>"


def ui_sync(frames: dict, offsets: dict, regions: dict | None = None) -> SyncChooser:
    """Check and override the flash offsets frame by frame.

    Parameters
    ----------
    frames : dict[str, FrameSource or ndarray]
        Motion frames per camera.
    offsets : dict[str, int]
        The automatic offsets (:func:`horsemocap.sync.flash_offsets`): the defaults.
    regions : dict[str, ndarray of bool], optional
        Flash regions (:attr:`FlashDetection.region`) to crop the preview around.
    """
    return SyncChooser(frames, offsets, regions)


def ui_phase(camera: str, value: float, uncertainty: float = 0.05) -> w.FloatSlider:
    """The fraction of a frame by which ``camera``'s frames fall after the reference camera's.

    Its default ``value`` is the pipeline's estimate (``analysis.detect.sync.phase_frames[camera]``); the
    slider spans half a frame either side, in steps of a hundredth of a frame (``uncertainty`` is shown).

    Examples
    --------
    >>> s = ui_phase("middle", -0.256, 0.02)
    >>> s.value, s.min, s.max
    (-0.256, -0.756, 0.244)
    """
    return w.FloatSlider(value=float(value), min=round(float(value) - 0.5, 6), max=round(float(value) + 0.5, 6),
                         step=0.01, readout_format=".3f",
                         description=f"{camera} phase", style={"description_width": "initial"},
                         layout=w.Layout(width="520px"),
                         tooltip=f"frames after the reference camera's; estimate {value:+.3f} +- {uncertainty:.3f}")
