"""Shared types of :mod:`horsemocap.detection`: parameters, results, errors.

:class:`DetectionParams` (every prompt of thesis Appendix A step 4),
:class:`MarkerTrack` (``PM`` of one camera, Figure 4.14), :class:`Regions`
(labelled regions of one image, 4.5.2), the reason strings :data:`REASONS`
of a marker not found, :class:`DetectionError`, and the candidate rules used when
none is given (:data:`GENERIC_AREA`, :data:`GENERIC_MAX_AREA_FRACTION`,
:data:`AUTO_MIN_CIRCULARITY`). Every other module of the
package imports from here; this one imports none of them.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

import numpy as np

__all__ = [
    "GENERIC_AREA",
    "GENERIC_MAX_AREA_FRACTION",
    "AUTO_MIN_CIRCULARITY",
    "REASONS",
    "DetectionError",
    "DetectionParams",
    "MarkerTrack",
    "Regions",
]


#: Reason strings of :attr:`MarkerTrack.reason` ("" = found).
REASONS = {
    "": "found",
    "occluded": "not seen near its predicted position inside the image",
    "left_image": "predicted outside the image, or its region is cut by the image border",
    "partly_occluded": "region much smaller than the marker's recent area (centre would be biased)",
    "ambiguous": "two or more regions fit equally well; no guess is made",
    "not_tracked": "no marker of the set could be followed to this frame",
}


#: Area range (px) of a candidate region when none is given: 3 px up to ``GENERIC_MAX_AREA_FRACTION``
#: of the image (``None``).
GENERIC_AREA = (3, None)
#: The largest candidate region when no ``area_max`` is given, as a fraction of the image (0.5 %).
GENERIC_MAX_AREA_FRACTION = 0.005
#: The smallest circularity of a candidate region when none is given.
AUTO_MIN_CIRCULARITY = 0.5


class DetectionError(ValueError):
    """Markers that cannot be found with the given data and parameters."""


# --------------------------------------------------------------------------
# parameters and results
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class DetectionParams:
    """Every prompt of thesis Appendix A step 4; ``None`` = chosen automatically.

    Attributes
    ----------
    threshold : int or None
        Gray level ``l`` of eq. (4.5) (``left_levelinput``); a pixel is white
        when ``I > l``. Automatic: three-class Otsu (or Otsu, see
        ``threshold_method``) on frames sampled over the whole motion.
    threshold_method : {"otsu3", "otsu"}
        Automatic threshold rule.
    first_frame : int or None
        The frame in which the markers are chosen (the thesis' "first
        image"). Automatic: the frame nearest the middle of the sequence in
        which a consistent cluster of ``n_markers`` regions is found.
    labels : tuple of int or None
        Labels (:func:`label_regions` numbering of ``first_frame`` at
        ``threshold``) of the markers (``left_labels``). Automatic:
        :func:`choose_markers`. Their order does not matter: markers are
        numbered by ascending ``u`` in the first frame where all are seen.
    area_min, area_max : float or None
        Area range in pixels (``left_area_threshold_min/max``, 4.5.3).
        Automatic: a quarter of the smallest and four times the largest
        marker area in ``first_frame``.
    window : tuple (W_du, W_dv) or None
        Full width and height of the sliding window in pixels
        (``left_window_dx/dy``, 4.5.4). Automatic: the markers' extent in
        ``first_frame`` plus, on each side, half their largest spacing, two
        marker diameters, 4 px and twice the largest marker displacement
        between ``first_frame`` and its neighbour frame.
    distance_tolerance : float or None
        ``DT`` of eq. (4.11) as a fraction (``left_distance_percent_error``).
        Automatic: 0.10 plus 2 px of centre noise over the smallest spacing.
    min_circularity : float or None
        Lowest circularity ``A / (2 pi (var_u + var_v))`` kept (1 for a disc,
        0.5 for a 3.6:1 bar). ``None`` = 0.5 where the automatic choice is
        made, and no filter while tracking; give a number for rounder markers.
    centroid : {"weighted", "binary"}
        Intensity-weighted centroid above the local background (default,
        sub-pixel) or the thesis' geometric centre of the binary region.
    distance_reference : {"previous", "first"}
        ``DM_ij`` of eq. (4.6) taken from the last frame where all markers
        were found (default, follows perspective changes) or, as in the
        thesis, from the first image only.
    window_predict : bool
        Centre the window on the constant-velocity prediction of the marker
        centre (default) instead of the previous centre ``W_c^e(k)``.
    """

    threshold: int | None = None
    threshold_method: str = "otsu3"
    first_frame: int | None = None
    labels: tuple | None = None
    area_min: float | None = None
    area_max: float | None = None
    window: tuple | None = None
    distance_tolerance: float | None = None
    min_circularity: float | None = None
    centroid: str = "weighted"
    distance_reference: str = "previous"
    window_predict: bool = True

    def __post_init__(self):
        if self.threshold is not None:
            t = int(self.threshold)
            if t != self.threshold or not 0 <= t <= 254:
                raise ValueError(f"DetectionParams.threshold: expected an integer in 0..254, got {self.threshold!r}")
            object.__setattr__(self, "threshold", t)
        if self.threshold_method not in ("otsu3", "otsu"):
            raise ValueError(f"DetectionParams.threshold_method: expected 'otsu3' or 'otsu', got {self.threshold_method!r}")
        if self.centroid not in ("weighted", "binary"):
            raise ValueError(f"DetectionParams.centroid: expected 'weighted' or 'binary', got {self.centroid!r}")
        if self.distance_reference not in ("previous", "first"):
            raise ValueError(f"DetectionParams.distance_reference: expected 'previous' or 'first', got {self.distance_reference!r}")
        if self.labels is not None:
            object.__setattr__(self, "labels", tuple(int(x) for x in self.labels))
        if self.window is not None:
            w = tuple(int(round(x)) for x in self.window)
            if len(w) != 2 or min(w) <= 0:
                raise ValueError(f"DetectionParams.window: expected (W_du, W_dv) > 0, got {self.window!r}")
            object.__setattr__(self, "window", w)
        if self.distance_tolerance is not None and not self.distance_tolerance > 0:
            raise ValueError(f"DetectionParams.distance_tolerance: expected > 0, got {self.distance_tolerance!r}")
        if (self.area_min is not None and self.area_max is not None
                and self.area_min > self.area_max):
            raise ValueError(f"DetectionParams: area_min {self.area_min} > area_max {self.area_max}")

    def to_dict(self) -> dict:
        """Plain JSON-able dict (for ``analysis.json``)."""
        d = asdict(self)
        for k in ("labels", "window"):
            if d[k] is not None:
                d[k] = [int(x) for x in d[k]]
        for k in ("area_min", "area_max", "distance_tolerance", "min_circularity"):
            if d[k] is not None:
                d[k] = float(d[k])
        return d

    @classmethod
    def from_dict(cls, d: dict | None) -> "DetectionParams":
        """Inverse of :meth:`to_dict`; unknown keys raise a clear error."""
        d = dict(d or {})
        names = {f.name for f in fields(cls)}
        bad = sorted(set(d) - names)
        if bad:
            raise ValueError(f"detection parameters: unknown field(s) {bad}; expected some of {sorted(names)}")
        for k in ("labels", "window"):
            if d.get(k) is not None:
                d[k] = tuple(d[k])
        return cls(**d)


@dataclass(frozen=True)
class MarkerTrack:
    """Markers of one camera through a sequence (thesis ``PM``, Figure 4.14).

    Attributes
    ----------
    marker_px : ndarray (frames, markers, 2)
        ``(u, v)`` image centres, NaN where not found (``PM_L`` transposed).
    reason : ndarray (frames, markers) of str
        ``""`` when found, else a key of :data:`REASONS`.
    params : DetectionParams
        The parameters actually used, automatic choices filled in.
    area : ndarray (frames, markers)
        Area in pixels of each found region (NaN where not found).
    """

    marker_px: np.ndarray
    reason: np.ndarray
    params: DetectionParams
    area: np.ndarray | None = None

    @property
    def found(self) -> np.ndarray:
        """Boolean (frames, markers): marker found."""
        return self.reason == ""

    @property
    def all_found(self) -> np.ndarray:
        """Boolean (frames,): every marker found in the frame."""
        return self.found.all(axis=1)


@dataclass(frozen=True)
class Regions:
    """Labelled regions of one image (thesis 4.5.2).

    Attributes
    ----------
    labels : ndarray (h, w) int32
        Label image (0 = black) of the labelled area.
    ids : ndarray (C,)
        Label number of each region.
    area : ndarray (C,)
        Pixel count.
    bbox : ndarray (C, 4)
        ``u0, v0, width, height`` in full-image pixels.
    centroid : ndarray (C, 2)
        Geometric centre ``(u, v)`` of the binary region (thesis).
    origin : tuple (u0, v0)
        Offset of ``labels`` in the full image (a window crop).
    image_size : tuple (width, height)
        Size of the full image.
    """

    labels: np.ndarray
    ids: np.ndarray
    area: np.ndarray
    bbox: np.ndarray
    centroid: np.ndarray
    origin: tuple = (0, 0)
    image_size: tuple = (0, 0)

    def __len__(self):
        return len(self.ids)

    def subset(self, keep) -> "Regions":
        """The regions where boolean or index ``keep`` selects."""
        return replace(self, ids=self.ids[keep], area=self.area[keep], bbox=self.bbox[keep],
                       centroid=self.centroid[keep])

    @property
    def touches_border(self) -> np.ndarray:
        """Boolean (C,): region touches the full image border (cut by it); for a few regions in Python
        floats, :func:`boxes_touch_border`."""
        w, h = self.image_size
        b = self.bbox
        return (b[:, 0] <= 0) | (b[:, 1] <= 0) | (b[:, 0] + b[:, 2] >= w) | (b[:, 1] + b[:, 3] >= h)


def boxes_touch_border(boxes: list, W: int, H: int) -> list:
    """:attr:`Regions.touches_border` of a few boxes ``[[x, y, w, h], ...]`` (a list), in Python: one
    comparison per box instead of NumPy's per-call cost (the per-frame detection's few regions)."""
    return [x <= 0 or y <= 0 or x + w >= W or y + h >= H for x, y, w, h in boxes]
