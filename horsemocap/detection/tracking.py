"""Marker detection on the image plane (thesis chapter 4, Appendix A step 4).

The thesis finds the passive (retroreflective) markers of one camera with a
chain of filters, each of which is a pure function here:

1. gray conversion, eq. (4.4): :func:`to_gray`;
2. global threshold ``l`` (``left_levelinput``), eq. (4.5): :func:`binarize`,
   with automatic starting values by Otsu's method (:func:`otsu_threshold`)
   and the three-class Otsu of seed 000 section 5.2.1 (:func:`otsu3_thresholds`);
3. 8-connected labelling and region centres (4.5.2): :func:`label_regions`;
4. area filter ``[area_min, area_max]`` (4.5.3): :func:`filter_area`, and
   the circularity filter by geometric moments of seed 000 (Hu's first
   invariant): :func:`region_circularity`, :func:`filter_circularity`;
5. the sliding window ``W_c(k+1) = W_c^e(k)`` of size ``(W_du, W_dv)``
   (4.5.4, Figure 4.11): :func:`filter_window`, :func:`window_center`;
6. the distance filter over combinations of regions, eq. (4.6)-(4.11):
   :func:`marker_distances`, :func:`filter_distance`;
7. the cross-product filter that keeps the marker order (Figure 4.13):
   :func:`cross_product_signs`, :func:`filter_cross_product`.

:func:`filter_stages` returns every stage for one frame (Figure 4.15).

:func:`detect_markers` runs the chain over a sequence (the thesis'
``left_image_centroids_3.m``) and returns ``marker_px`` (``PM_L``, Figure
4.14, transposed to the house layout ``(frames, markers, 2)``); every prompt
of ``left_data_from_first_image_2.m`` is a field of :class:`DetectionParams`
and is chosen automatically when left at ``None``. :func:`detect_still` serves
the plumb and static stills (Appendix A steps 7a, 8a, 12a) of one camera;
:func:`detect_still_views` finds them in all cameras at once, keeping only the
candidates that are projections of one 3D point in every camera (thesis 5.1)
and choosing among those the ones that look most like markers.

Pixel coordinates are ``(u, v)`` = (column, row), 0-based, with the centre of
pixel ``(i, j)`` at ``u = j, v = i`` (OpenCV convention; MATLAB's regionprops
is 1-based). Centres are, by default, intensity-weighted centroids of the gray
image above the local background (``centroid="weighted"``); the thesis'
geometric centre of the binary region is ``centroid="binary"``.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, fields, replace
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

__all__ = [
    "REASONS", "DetectionError", "DetectionParams", "MarkerTrack", "Regions",
    "to_gray", "binarize", "otsu_threshold", "otsu3_thresholds", "auto_threshold",
    "label_regions", "region_circularity", "filter_area", "filter_circularity",
    "filter_window", "window_center", "marker_distances", "filter_distance",
    "cross_product_signs", "filter_cross_product", "weighted_centroids",
    "find_candidates", "follow_cluster", "choose_markers", "cluster_persistence", "CandidateCache", "filter_stages", "detect_markers", "detect_still",
    "StillCandidates", "still_candidates", "StillViews", "match_still_views", "detect_still_views",
    "valid_frames", "usable_frames", "markers_2d_rows", "markers_2d_csv_text", "marker_label", "write_markers_2d_csv",
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

#: Gray weights of eq. (4.4) (MATLAB ``rgb2gray``).
GRAY_WEIGHTS = (0.2989, 0.5870, 0.1140)


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
        """Boolean (C,): region touches the full image border (cut by it)."""
        w, h = self.image_size
        b = self.bbox
        return (b[:, 0] <= 0) | (b[:, 1] <= 0) | (b[:, 0] + b[:, 2] >= w) | (b[:, 1] + b[:, 3] >= h)


# --------------------------------------------------------------------------
# 4.3: gray and binary images
# --------------------------------------------------------------------------
def to_gray(image: np.ndarray, exact: bool = False) -> np.ndarray:
    """Gray image of an RGB image, eq. (4.4).

    ``Gray = 0.2989 R + 0.5870 G + 0.1140 B``. By default OpenCV's fixed-point
    ``cvtColor`` is used (weights 0.299, 0.587, 0.114: at most 0.03 gray
    levels from eq. 4.4 before rounding, so within 0.53 after); ``exact=True`` applies eq. (4.4)
    in floating point and rounds. A 2-D image is returned unchanged.

    Parameters
    ----------
    image : ndarray (h, w, 3) uint8 RGB, or (h, w) gray

    Returns
    -------
    ndarray (h, w) uint8
    """
    image = np.asarray(image)
    if image.ndim == 2:
        return image
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"to_gray: expected an (h, w, 3) RGB or (h, w) gray image, got shape {image.shape}")
    if exact:
        g = image.astype(np.float64) @ np.array(GRAY_WEIGHTS)
        return np.clip(np.rint(g), 0, 255).astype(np.uint8)
    if image.dtype != np.uint8:
        raise ValueError(f"to_gray: expected uint8 pixels, got {image.dtype}")
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)


def binarize(gray: np.ndarray, level: int) -> np.ndarray:
    """Global threshold of eq. (4.5): 1 where ``I(u, v) > l``, else 0.

    Returns a uint8 image of 0/255 (OpenCV's binary convention).
    """
    if not 0 <= int(level) <= 255:
        raise ValueError(f"binarize: threshold level must be in 0..255, got {level}")
    return cv2.threshold(np.asarray(gray, dtype=np.uint8), int(level), 255, cv2.THRESH_BINARY)[1]


def _histogram(images) -> np.ndarray:
    hist = np.zeros(256)
    for im in images:
        hist += np.bincount(np.asarray(to_gray(im), dtype=np.uint8).ravel(), minlength=256)
    return hist


def otsu_threshold(gray_or_hist) -> int:
    """Otsu's threshold (Otsu 1979): maximises the between-class variance.

    Parameters
    ----------
    gray_or_hist : ndarray
        A gray image, or a 256-bin histogram.

    Returns
    -------
    int
        ``l`` such that ``I > l`` is the bright class (eq. 4.5 convention).
    """
    a = np.asarray(gray_or_hist)
    hist = a.astype(float) if (a.ndim == 1 and a.size == 256) else _histogram([a])
    p = hist / hist.sum()
    k = np.arange(256)
    w0 = np.cumsum(p)
    m0 = np.cumsum(p * k)
    mt = m0[-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        sb = (mt * w0 - m0) ** 2 / (w0 * (1 - w0))
    sb[~np.isfinite(sb)] = -1
    return _plateau_middle(sb, int(np.argmax(sb)))


def _plateau_middle(score, i, rtol=1e-9):
    """Middle of the run of maximal values around ``i``.

    Between two well separated modes every level in the empty gap gives the
    same class variances; the middle of the gap is taken (not its first
    level, just above the dark mode's tail).
    """
    top = score[i]
    lo = hi = i
    while lo > 0 and score[lo - 1] >= top - rtol * abs(top):
        lo -= 1
    while hi < len(score) - 1 and score[hi + 1] >= top - rtol * abs(top):
        hi += 1
    return (lo + hi) // 2


def otsu3_thresholds(gray_or_hist) -> tuple[int, int]:
    """Three-class Otsu (seed 000 section 5.2.1): two levels ``l1 < l2``.

    Maximises ``sum_c w_c (mu_c - mu_T)^2`` over the classes ``I <= l1``,
    ``l1 < I <= l2``, ``I > l2`` by exhaustive search (vectorised over
    ``l2`` for each ``l1``). The bright class ``I > l2`` holds the markers.
    """
    a = np.asarray(gray_or_hist)
    hist = a.astype(float) if (a.ndim == 1 and a.size == 256) else _histogram([a])
    p = hist / hist.sum()
    k = np.arange(256)
    P = np.concatenate([[0.0], np.cumsum(p)])          # P[i] = sum p[:i]
    S = np.concatenate([[0.0], np.cumsum(p * k)])
    # class sums for [a, b) : P[b]-P[a]
    best, arg = -1.0, (0, 1)
    t2 = np.arange(1, 255)
    for t1 in range(0, 254):
        j = t2[t2 > t1]
        w0, s0 = P[t1 + 1], S[t1 + 1]
        w1, s1 = P[j + 1] - w0, S[j + 1] - s0
        w2, s2 = 1.0 - P[j + 1], S[-1] - S[j + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where(w1 > 0, s1 ** 2 / w1, 0) + np.where(w2 > 0, s2 ** 2 / w2, 0)
        v = v + (s0 ** 2 / w0 if w0 > 0 else 0.0)
        i = int(np.argmax(v))
        if v[i] > best:
            best, arg = float(v[i]), (t1, int(j[i]))
    return _otsu3_centre(P, S, *arg)


def _otsu3_centre(P, S, t1, t2):
    """Move each level of the three-class Otsu to the middle of its plateau."""
    def score(a, b):
        w0, s0 = P[a + 1], S[a + 1]
        w1, s1 = P[b + 1] - w0, S[b + 1] - s0
        w2, s2 = 1.0 - P[b + 1], S[-1] - S[b + 1]
        return sum(s * s / w for s, w in ((s0, w0), (s1, w1), (s2, w2)) if w > 0)
    s2 = np.array([score(t1, b) if b > t1 else -np.inf for b in range(255)])
    t2 = _plateau_middle(s2, t2)
    s1 = np.array([score(a, t2) if a < t2 else -np.inf for a in range(255)])
    t1 = _plateau_middle(s1, t1)
    return int(t1), int(t2)


def auto_threshold(images, method: str = "otsu3") -> int:
    """Automatic starting threshold over one or several images.

    The histogram is summed over all given images (frames sampled over the
    whole motion, so that one level holds for all of them, as Appendix A
    step 4.a.i asks), then Otsu (``method="otsu"``) or the upper level of
    the three-class Otsu (``"otsu3"``) is taken.
    """
    if isinstance(images, np.ndarray) and (images.ndim == 2 or (images.ndim == 3 and images.shape[-1] == 3)):
        images = [images]
    hist = _histogram(images)
    if method == "otsu":
        return otsu_threshold(hist)
    if method == "otsu3":
        return otsu3_thresholds(hist)[1]
    raise ValueError(f"auto_threshold: method must be 'otsu' or 'otsu3', got {method!r}")


# --------------------------------------------------------------------------
# 4.5.2 - 4.5.3: labelling, area and shape
# --------------------------------------------------------------------------
def label_regions(binary: np.ndarray, connectivity: int = 8, origin=(0, 0),
                  image_size=None) -> Regions:
    """Label the white regions with 8- (or 4-) connectivity (thesis 4.5.2).

    Region centres are the geometric centres of the binary regions (the
    thesis' "geometrical center"). ``origin`` is the offset of ``binary`` in
    the full image when it is a window crop.
    """
    if connectivity not in (4, 8):
        raise ValueError(f"label_regions: connectivity must be 4 or 8, got {connectivity}")
    b = np.asarray(binary)
    if b.dtype != np.uint8:
        b = (b > 0).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(b, connectivity=connectivity, ltype=cv2.CV_32S)
    u0, v0 = int(origin[0]), int(origin[1])
    bbox = stats[1:, :4].astype(np.int64)
    bbox[:, 0] += u0
    bbox[:, 1] += v0
    size = tuple(image_size) if image_size is not None else (b.shape[1] + u0, b.shape[0] + v0)
    return Regions(labels=labels, ids=np.arange(1, n), area=stats[1:, 4].astype(np.int64), bbox=bbox,
                   centroid=cents[1:] + np.array([u0, v0], float), origin=(u0, v0), image_size=size)


def region_circularity(regions: Regions) -> np.ndarray:
    """Circularity from geometric moments (seed 000 section 5.2.1; Hu 1962).

    ``c = A / (2 pi (var_u + var_v))`` = ``1 / (2 pi phi_1)`` where
    ``phi_1 = eta_20 + eta_02`` is Hu's first moment invariant; the pixel
    variances include each pixel's own extent (1/12). ``c`` is 1 for a disc,
    ``2r / (1 + r^2)`` for an ellipse of axis ratio ``r`` and
    ``6k / (pi (1 + k^2))`` for a ``k``:1 bar.
    """
    C = len(regions)
    if C == 0:
        return np.zeros(0)
    lab = regions.labels
    u0, v0 = regions.origin
    out = np.empty(C)
    if C <= 8:
        for i, (rid, bb) in enumerate(zip(regions.ids, regions.bbox)):
            x, y = bb[0] - u0, bb[1] - v0
            sub = (lab[y:y + bb[3], x:x + bb[2]] == rid).astype(np.uint8)
            m = cv2.moments(sub, binaryImage=True)
            a = m["m00"]
            var = (m["mu20"] + m["mu02"]) / a + 1.0 / 6.0
            out[i] = a / (2 * np.pi * var)
        return out
    v, u = np.nonzero(lab)
    ll = lab[v, u]
    n = int(lab.max()) + 1
    a = np.bincount(ll, minlength=n).astype(float)
    su, sv = np.bincount(ll, u, n), np.bincount(ll, v, n)
    suu, svv = np.bincount(ll, u.astype(float) ** 2, n), np.bincount(ll, v.astype(float) ** 2, n)
    with np.errstate(invalid="ignore", divide="ignore"):
        var = (suu - su ** 2 / a + svv - sv ** 2 / a) / a + 1.0 / 6.0
        c = a / (2 * np.pi * var)
    return c[regions.ids]


def filter_area(area, area_min: float, area_max: float) -> np.ndarray:
    """Area filter of thesis 4.5.3: keep ``area_min <= A <= area_max``."""
    area = np.asarray(area)
    return (area >= area_min) & (area <= area_max)


def filter_circularity(circularity, min_circularity: float) -> np.ndarray:
    """Keep regions whose :func:`region_circularity` is at least ``min_circularity``."""
    return np.asarray(circularity) >= min_circularity


# --------------------------------------------------------------------------
# 4.5.4: the sliding window
# --------------------------------------------------------------------------
def window_center(marker_px: np.ndarray) -> np.ndarray:
    """Overall geometric centre ``W_c^e(k)`` of the markers (NaN ignored)."""
    p = np.asarray(marker_px, float).reshape(-1, 2)
    ok = np.isfinite(p).all(axis=1)
    if not ok.any():
        return np.full(2, np.nan)
    return p[ok].mean(axis=0)


def filter_window(centroid, center, window) -> np.ndarray:
    """Keep region centres inside the window (thesis 4.5.4, Figure 4.11).

    ``center`` is ``W_c(k)`` and ``window`` the full size ``(W_du, W_dv)``.
    """
    c = np.asarray(centroid, float).reshape(-1, 2)
    half = np.asarray(window, float) / 2
    return (np.abs(c - np.asarray(center, float)) <= half).all(axis=1)


# --------------------------------------------------------------------------
# 4.5.5: distance and cross-product filters
# --------------------------------------------------------------------------
def marker_distances(marker_px: np.ndarray) -> np.ndarray:
    """All distances ``DM_ij`` between marker centres, eq. (4.6), as an (M, M) matrix."""
    p = np.asarray(marker_px, float)
    return np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)


@lru_cache(maxsize=64)
def _permutations(c: int, m: int) -> np.ndarray:
    return np.array(list(itertools.permutations(range(c), m)), dtype=np.intp).reshape(-1, m)


def filter_distance(centroid, reference_distances, tolerance: float) -> np.ndarray:
    """Distance filter of eq. (4.6)-(4.11).

    Among the ``C`` region centres (``DC_ij``, eq. 4.8-4.9), keep every
    ordered choice of ``M`` regions (region ``a_i`` for marker ``i``) whose
    distances all fall in ``DI_ij`` of eq. (4.11):
    ``|DC_{a_i a_j} - DM_ij| <= DT * DM_ij``. The thesis counts the
    combinations of distances (eq. 4.10); testing ordered region choices
    is the same test with the marker identities kept.

    Parameters
    ----------
    centroid : (C, 2) region centres
    reference_distances : (M, M) ``DM`` from :func:`marker_distances`
    tolerance : ``DT`` as a fraction

    Returns
    -------
    ndarray (K, M) of int
        Region indices of the accepted choices, one row per choice.
    """
    c = np.asarray(centroid, float).reshape(-1, 2)
    dm = np.asarray(reference_distances, float)
    m = dm.shape[0]
    if len(c) < m:
        return np.zeros((0, m), dtype=np.intp)
    perms = _permutations(len(c), m)
    dc = marker_distances(c)
    ok = np.ones(len(perms), bool)
    for i in range(m):
        for j in range(i + 1, m):
            d = dc[perms[:, i], perms[:, j]]
            ok &= np.abs(d - dm[i, j]) <= tolerance * dm[i, j]
    return perms[ok]


def cross_product_signs(marker_px: np.ndarray, min_sine: float = 0.0) -> np.ndarray:
    """``sgn[(r_12 x r_23)_3]`` for each consecutive triple of markers (Figure 4.13).

    Returns (M-2,) values in {-1, 0, +1}; 0 where the triple is so nearly
    straight (``|sin| < min_sine``) that its sign says nothing.
    """
    p = np.asarray(marker_px, float)
    r1 = p[1:-1] - p[:-2]
    r2 = p[2:] - p[1:-1]
    z = r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]
    norm = np.linalg.norm(r1, axis=1) * np.linalg.norm(r2, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(np.abs(z) >= min_sine * norm, np.sign(z), 0.0)
    return s.astype(int)


def filter_cross_product(centroid, choices, reference_signs, min_sine: float = 0.05) -> np.ndarray:
    """Cross-product filter (thesis Figure 4.13): keep the marker order.

    A choice of regions is kept when, for every consecutive triple whose
    reference sign is not 0, ``sgn[(r_12 x r_23)_3]`` equals the sign in
    the reference (first) frame. Triples bent less than ``min_sine`` in the
    candidate are not tested either (their sign is noise).
    """
    choices = np.asarray(choices, dtype=np.intp)
    ref = np.asarray(reference_signs)
    if len(choices) == 0 or choices.shape[1] < 3 or not np.any(ref):
        return choices
    c = np.asarray(centroid, float)
    p = c[choices]                                  # (K, M, 2)
    r1 = p[:, 1:-1] - p[:, :-2]
    r2 = p[:, 2:] - p[:, 1:-1]
    z = r1[..., 0] * r2[..., 1] - r1[..., 1] * r2[..., 0]
    norm = np.linalg.norm(r1, axis=-1) * np.linalg.norm(r2, axis=-1)
    s = np.where(np.abs(z) >= min_sine * norm, np.sign(z), 0)
    ok = ((s == ref[None]) | (ref[None] == 0) | (s == 0)).all(axis=1)
    return choices[ok]


# --------------------------------------------------------------------------
# centres
# --------------------------------------------------------------------------
_K3 = np.ones((3, 3), np.uint8)


def weighted_centroids(gray: np.ndarray, regions: Regions, index=None, margin: int = 2) -> np.ndarray:
    """Intensity-weighted centres of regions, above the local background.

    For each region the mask is grown by ``margin`` pixels (to take in the
    anti-aliased rim below the threshold), pixels of other regions are
    excluded, the background ``b`` is the median of a 2-pixel ring outside
    the grown mask, and the centre is ``sum w (u, v) / sum w`` with
    ``w = max(I - b, 0)``. Unbiased for a uniform local background, and far
    more precise than the binary centre (which moves by whole pixels).

    Parameters
    ----------
    gray : (h, w) gray image of the labelled area (same crop as ``regions.labels``)
    regions : Regions
    index : indices into ``regions`` (default all)

    Returns
    -------
    (K, 2) centres ``(u, v)`` in full-image pixels.
    """
    idx = np.arange(len(regions)) if index is None else np.atleast_1d(np.asarray(index, dtype=np.intp))
    lab = regions.labels
    h, w = lab.shape
    u0, v0 = regions.origin
    out = np.full((len(idx), 2), np.nan)
    g = 2 * margin + 2
    for k, i in enumerate(idx):
        rid = regions.ids[i]
        bx, by, bw, bh = regions.bbox[i]
        bx, by = bx - u0, by - v0
        x0, y0 = max(bx - g, 0), max(by - g, 0)
        x1, y1 = min(bx + bw + g, w), min(by + bh + g, h)
        sl = lab[y0:y1, x0:x1]
        own = (sl == rid).astype(np.uint8)
        other = (sl != 0) & (own == 0)
        near = cv2.dilate(own, _K3, iterations=margin).astype(bool)
        far = cv2.dilate(own, _K3, iterations=margin + 2).astype(bool)
        if other.any():
            other = cv2.dilate(other.astype(np.uint8), _K3, iterations=1).astype(bool)
        sub = gray[y0:y1, x0:x1].astype(np.float64)
        ring = far & ~near & ~other
        b = float(np.median(sub[ring])) if ring.any() else float(sub[own.astype(bool)].min()) - 1
        wgt = np.where(near & ~(other & ~own.astype(bool)), np.maximum(sub - b, 0.0), 0.0)
        s = wgt.sum()
        if s <= 0:
            out[k] = regions.centroid[i]
            continue
        vv, uu = np.mgrid[y0:y1, x0:x1]
        out[k] = ((wgt * uu).sum() / s + u0, (wgt * vv).sum() / s + v0)
    return out


# --------------------------------------------------------------------------
# candidates of one image
# --------------------------------------------------------------------------
def find_candidates(gray: np.ndarray, threshold: int, area_range=(1, np.inf), min_circularity=None,
                    crop=None, connectivity: int = 8):
    """Threshold, label and area/shape-filter one gray image (or a window crop).

    Parameters
    ----------
    gray : (h, w) full gray image
    threshold : ``l`` of eq. (4.5)
    area_range : ``(area_min, area_max)``
    min_circularity : optional shape filter
    crop : ``(u0, v0, u1, v1)`` window in full-image pixels (None = whole image)

    Returns
    -------
    regions : Regions
        All labelled regions of the (cropped) image.
    keep : ndarray of int
        Indices of the regions that pass the filters and are not cut by the
        crop edge (a region cut by a crop edge that is not an image edge is
        incomplete; it is dropped).
    """
    H, W = gray.shape[:2]
    u0, v0, u1, v1 = _clip_crop(crop, W, H)
    return _candidates_in(gray[v0:v1, u0:u1], (u0, v0), (W, H), threshold, area_range,
                          min_circularity, connectivity)


def _clip_crop(crop, W, H):
    if crop is None:
        return 0, 0, W, H
    u0, v0 = max(int(crop[0]), 0), max(int(crop[1]), 0)
    u1, v1 = min(int(crop[2]), W), min(int(crop[3]), H)
    if u1 <= u0 or v1 <= v0:
        return 0, 0, 0, 0
    return u0, v0, u1, v1


def _candidates_in(sub, origin, size, threshold, area_range, min_circularity, connectivity=8):
    W, H = size
    u0, v0 = origin
    if sub.size == 0:
        empty = Regions(np.zeros((0, 0), np.int32), np.zeros(0, int), np.zeros(0, int), np.zeros((0, 4), int),
                        np.zeros((0, 2)), (u0, v0), (W, H))
        return empty, np.zeros(0, np.intp)
    u1, v1 = u0 + sub.shape[1], v0 + sub.shape[0]
    bw = cv2.threshold(sub, int(threshold), 255, cv2.THRESH_BINARY)[1]
    regions = label_regions(bw, connectivity, origin=(u0, v0), image_size=(W, H))
    ok = filter_area(regions.area, area_range[0], area_range[1])
    if (u0 > 0 or v0 > 0 or u1 < W or v1 < H) and len(regions):
        b = regions.bbox
        cut = (((b[:, 0] <= u0) & (u0 > 0)) | ((b[:, 1] <= v0) & (v0 > 0))
               | ((b[:, 0] + b[:, 2] >= u1) & (u1 < W)) | ((b[:, 1] + b[:, 3] >= v1) & (v1 < H)))
        ok &= ~cut
    keep = np.flatnonzero(ok)
    if min_circularity is not None and len(keep):
        circ = region_circularity(regions.subset(keep))
        keep = keep[circ >= min_circularity]
    return regions, keep


# --------------------------------------------------------------------------
# automatic choice of the markers in one frame
# --------------------------------------------------------------------------
GENERIC_AREA = (3, None)      # px; the upper bound is a fraction of the image
GENERIC_MAX_AREA_FRACTION = 0.005
AUTO_MIN_CIRCULARITY = 0.5
MAX_CANDIDATES = 24


def _generic_candidates(gray, threshold, min_circularity):
    H, W = gray.shape
    amax = max(50.0, GENERIC_MAX_AREA_FRACTION * H * W)
    regions, keep = find_candidates(gray, threshold, (GENERIC_AREA[0], amax), min_circularity)
    keep = keep[~regions.touches_border[keep]]
    if len(keep) > MAX_CANDIDATES:   # keep the largest ones
        keep = keep[np.argsort(-regions.area[keep])[:MAX_CANDIDATES]]
    return regions, keep


class CandidateCache:
    """Whole-image candidates of each frame, computed once (automatic choice).

    For frame ``k``: the :class:`Regions`, the indices of the candidates
    (3 px to 0.5 % of the image, circularity >= ``min_circularity``, not cut
    by the border), their circularity and their peak gray level. Each entry
    holds a label image of the whole frame (1.2 MB at 640 x 480), so only
    the ``max_frames`` most recently used frames are kept (a 3000-frame
    session kept 433 of them, 532 MB, before the bound).
    """

    def __init__(self, frames_gray, threshold: int, min_circularity: float = 0.5, max_frames: int = 96):
        self.frames = frames_gray
        self.threshold = int(threshold)
        self.min_circularity = min_circularity
        self.max_frames = max(1, int(max_frames))
        self._cache = {}

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, k):
        hit = self._cache.pop(k, None)
        if hit is not None:
            self._cache[k] = hit                    # most recently used last
        else:
            gray = self.frames[k]
            regions, keep = _generic_candidates(gray, self.threshold, None)
            circ = region_circularity(regions.subset(keep)) if len(keep) else np.zeros(0)
            ok = circ >= self.min_circularity
            keep, circ = keep[ok], circ[ok]
            peak = np.empty(len(keep))
            u0, v0 = regions.origin
            for j, i in enumerate(keep):
                x, y, w, h = regions.bbox[i]
                sl = (slice(y - v0, y - v0 + h), slice(x - u0, x - u0 + w))
                peak[j] = gray[sl][regions.labels[sl] == regions.ids[i]].max()
            hit = (regions, keep, circ, peak)
            self._cache[k] = hit
            while len(self._cache) > self.max_frames:
                self._cache.pop(next(iter(self._cache)))
        return hit


def _tuple_cost_static(cent, area, combos):
    """Area dispersion of each unordered combination (markers share one size)."""
    la = np.log(area[combos].astype(float))
    return la.max(axis=1) - la.min(axis=1)


def follow_cluster(px, centroid, tolerance: float = 0.10, max_shift: float | None = None):
    """Find a marker cluster again among region centres of another frame.

    The distance filter (eq. 4.6-4.11, ``DM`` from ``px``, tolerance
    ``tolerance``) and the cross-product filter (Figure 4.13) keep the
    choices of regions with the cluster's shape and order; the one whose
    largest marker displacement is smallest is returned, if it is below
    ``max_shift`` (default: no bound).

    Returns
    -------
    (M, 2) centres in the other frame, or None; and the displacement.
    """
    px = np.asarray(px, float)
    c = np.asarray(centroid, float).reshape(-1, 2)
    M = len(px)
    if M == 1:
        if not len(c):
            return None, np.inf
        d = np.linalg.norm(c - px[0], axis=1)
        j = int(np.argmin(d))
        return (c[[j]], float(d[j])) if max_shift is None or d[j] <= max_shift else (None, np.inf)
    if max_shift is not None:      # only regions that can belong to the moved cluster
        near = np.linalg.norm(c[:, None] - px[None], axis=-1).min(axis=1) <= max_shift
        c = c[near]
    ch = filter_distance(c, marker_distances(px), tolerance)
    ch = filter_cross_product(c, ch, cross_product_signs(px, 0.1))
    if not len(ch):
        return None, np.inf
    disp = np.linalg.norm(c[ch] - px[None], axis=-1).max(axis=1)
    j = int(np.argmin(disp))
    if max_shift is not None and disp[j] > max_shift:
        return None, np.inf
    return c[ch[j]], float(disp[j])


def choose_markers(frames_gray, n_markers: int, threshold: int, frame: int,
                   min_circularity: float = AUTO_MIN_CIRCULARITY, lookahead: int = 2,
                   max_combinations: int = 300, cache: CandidateCache | None = None):
    """Choose the marker regions in ``frame`` automatically.

    Candidates are the labelled regions of at least 3 px and at most 0.5 %
    of the image, round (:func:`region_circularity` >= ``min_circularity``)
    and not cut by the image border. Among the combinations of
    ``n_markers`` candidates of similar area (largest/smallest below 3: the
    markers are cut from one tape and seen from one distance), the chosen
    one is a *consistent cluster*: it is found again, by its shape
    (:func:`follow_cluster`, distances within 10 %), in each of the next
    ``lookahead`` frames (the previous ones at the end of the sequence); it
    must move (at least 0.5 px: the markers ride the horse, fixtures of the
    arena stay) unless no combination moves. Its cost adds what sets the
    markers apart (thesis 4.4: flat retroreflective discs, white under the
    lamp) to the largest relative change of the cluster's distances: the
    mean ``1 - circularity`` and the mean ``1 - peak/255`` of its regions. The best cost must beat the next best combination of
    other regions clearly (by 1.5 times + 0.01), else the frame is
    ambiguous.

    Returns
    -------
    regions : Regions of ``frame`` (whole-image labelling, for the label picker)
    chosen : ndarray (n_markers,) of indices into ``regions`` (None if none found)
    info : dict: candidates, costs, and ``motion_px`` (largest displacement
        of the chosen cluster between consecutive frames)
    """
    n = len(frames_gray)
    cache = cache or CandidateCache(frames_gray, threshold, min_circularity)
    regions, keep, circ, peak = cache[frame]
    info = {"candidates": int(len(keep))}
    if len(keep) < n_markers:
        return regions, None, {**info, "why": f"only {len(keep)} round candidates"}
    cent = regions.centroid[keep]
    area = regions.area[keep]
    combos = np.array(list(itertools.combinations(range(len(keep)), n_markers)), dtype=np.intp)
    cost_area = _tuple_cost_static(cent, area, combos)
    cost_look = (1 - circ[combos]).mean(axis=1) + (1 - peak[combos] / 255.0).mean(axis=1)
    good = np.flatnonzero(cost_area <= np.log(3.0))
    good = good[np.argsort(cost_look[good], kind="stable")][:max_combinations]
    if not len(good):
        return regions, None, {**info, "why": "no combination of similar areas"}
    step = 1 if frame + lookahead < n else -1
    later = []
    for j in range(1, lookahead + 1):
        f = frame + step * j
        if 0 <= f < n:
            r2, k2 = cache[f][:2]
            later.append(r2.centroid[k2])
    cost = np.full(len(combos), np.inf)
    motion = np.zeros(len(combos))
    step_px = np.zeros(len(combos))
    iu = np.triu_indices(n_markers, 1)
    for ci in good:
        pos = cent[combos[ci]]
        dref = marker_distances(pos)
        cur, change, ok = pos, 0.0, True
        for c2 in later:
            nxt, disp = follow_cluster(cur, c2, 0.10)
            if nxt is None:
                ok = False
                break
            if n_markers > 1:
                dd = marker_distances(nxt)
                change = max(change, float((np.abs(dd[iu] - dref[iu]) / dref[iu]).max()))
            step_px[ci] = max(step_px[ci], disp)
            cur = nxt
        if ok:
            cost[ci] = change + cost_look[ci]
            motion[ci] = float(np.linalg.norm(cur - pos, axis=1).mean())
    finite = np.isfinite(cost)
    if (finite & (motion >= 0.5)).any():
        cost[motion < 0.5] = np.inf
    if not np.isfinite(cost).any():
        return regions, None, {**info, "why": "no consistent cluster"}
    order = np.argsort(cost)
    best = order[0]
    info.update(best_cost=float(cost[best]), motion_px=float(step_px[best]))
    second = np.inf
    for o in order[1:]:
        if not np.isfinite(cost[o]):
            break
        if set(combos[o]) != set(combos[best]):
            second = float(cost[o])
            break
    info.update(second_cost=second)
    if np.isfinite(second) and second < 1.5 * cost[best] + 0.01:
        return regions, None, {**info, "why": "two clusters fit equally well"}
    return regions, keep[combos[best]], info


def cluster_persistence(cache: CandidateCache, frame: int, px, tolerance: float = 0.15,
                        max_shift: float = 20.0):
    """Frames ``(first, last)`` through which a cluster is followed from ``frame``.

    The cluster is followed frame by frame in both directions with
    :func:`follow_cluster` (distances of the previous frame, ``tolerance``,
    displacement at most ``max_shift``), looking only in a window around it
    (candidates as in :class:`CandidateCache`), until it is lost. The
    markers stay together for the whole pass of the horse; chance clusters
    of pseudo markers (legs, rider, glints) break up.

    Returns
    -------
    first, last : int
    complete : bool
        Both ends are explained: the sequence ends, or the cluster was last
        seen within ``max_shift`` of the image border (it left the image).
    """
    gray0 = cache.frames[frame]
    H, W = gray0.shape[:2]
    amax = max(50.0, GENERIC_MAX_AREA_FRACTION * H * W)
    pad = max_shift + np.sqrt(amax / np.pi) + 2
    out, complete = [], True
    for step in (1, -1):
        cur, k = np.asarray(px, float), frame
        while 0 <= k + step < len(cache):
            lo, hi = cur.min(axis=0) - pad, cur.max(axis=0) + pad
            box = _clip_crop((int(lo[0]), int(lo[1]), int(hi[0]) + 2, int(hi[1]) + 2), W, H)
            if hasattr(cache.frames, "crop"):
                sub = cache.frames.crop(k + step, *box)
            else:
                sub = cache.frames[k + step][box[1]:box[3], box[0]:box[2]]
            r2, k2 = _candidates_in(sub, box[:2], (W, H), cache.threshold, (GENERIC_AREA[0], amax),
                                    cache.min_circularity)
            k2 = k2[~r2.touches_border[k2]]
            nxt, _ = follow_cluster(cur, r2.centroid[k2], tolerance, max_shift)
            if nxt is None:
                break
            cur, k = nxt, k + step
        out.append(k)
        at_end = k + step < 0 or k + step >= len(cache)
        near_border = (cur.min(axis=0) < max_shift + 2).any() or (cur[:, 0].max() > W - max_shift - 3) \
            or (cur[:, 1].max() > H - max_shift - 3)
        complete &= bool(at_end or near_border)
    return out[1], out[0], complete


# --------------------------------------------------------------------------
# tracking through the sequence
# --------------------------------------------------------------------------
def _frames_array(frames):
    """``frames`` as an array, or as they are if decoded on demand (:class:`~horsemocap.sources.FrameSequence`)."""
    from ..sources import FrameSequence

    return frames if isinstance(frames, FrameSequence) else np.asarray(frames)


def _as_gray_frames(frames):
    frames = _frames_array(frames)
    if frames.ndim == 4 and frames.shape[-1] == 3:
        return None, frames
    if frames.ndim == 3:
        return frames, frames
    raise ValueError(f"detect_markers: frames must be (n, h, w, 3) RGB or (n, h, w) gray, got shape {frames.shape}")


class _GrayCache:
    """Gray frames converted on demand (eq. 4.4), crops converted alone."""

    def __init__(self, frames):
        self.frames = frames
        self.is_gray = frames.ndim == 3
        self.full = {}

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, i):
        if self.is_gray:
            return self.frames[i]
        g = self.full.get(i)
        if g is None:
            g = cv2.cvtColor(self.frames[i], cv2.COLOR_RGB2GRAY)
            if len(self.full) > 64:
                self.full.pop(next(iter(self.full)))
            self.full[i] = g
        return g

    def crop(self, i, u0, v0, u1, v1):
        """Gray of a window crop only (returns an image of the full size view-free)."""
        if u1 <= u0 or v1 <= v0:
            return np.zeros((0, 0), np.uint8)
        if self.is_gray or i in self.full:
            return self[i][v0:v1, u0:u1]
        return cv2.cvtColor(self.frames[i][v0:v1, u0:u1], cv2.COLOR_RGB2GRAY)


def _centres(gray_sub, regions, idx, method):
    if method == "binary":
        return regions.centroid[idx]
    return weighted_centroids(gray_sub, regions, idx)


def _frame_regions(gc, i, thr, area_range, min_circ, crop):
    """Candidates of frame i (full image if crop None) with the gray of that crop."""
    H, W = gc.frames.shape[1:3]
    u0, v0, u1, v1 = _clip_crop(crop, W, H)
    sub = gc.crop(i, u0, v0, u1, v1)
    regions, keep = _candidates_in(sub, (u0, v0), (W, H), thr, area_range, min_circ)
    return sub, regions, keep


def _predict(state, k):
    """Prediction of every marker at frame k.

    Markers found in the neighbouring frame with a known velocity: constant
    velocity. The others (lost, or velocity unknown): the configuration of
    the last frame where all were found, moved by the mean displacement of
    the well-predicted ones (the markers sit on one body); with none of
    those, constant velocity from their last position for up to
    ``max_gap`` frames.
    """
    last_k, last_p, vel = state["last_k"], state["last_p"], state["vel"]
    M = len(last_p)
    pred = np.full_like(last_p, np.nan)
    good = np.zeros(M, bool)
    for m in range(M):
        if last_k[m] is not None and abs(k - last_k[m]) == 1 and state["vel_known"][m]:
            pred[m] = last_p[m] + vel[m] * (k - last_k[m])
            good[m] = True
    if good.any() and not good.all() and state["config"] is not None:
        shift = (pred[good] - state["config"][good]).mean(axis=0)
        pred[~good] = state["config"][~good] + shift
    elif not good.all():
        for m in np.flatnonzero(~good):
            if last_k[m] is not None and abs(k - last_k[m]) <= state["max_gap"]:
                pred[m] = last_p[m] + vel[m] * (k - last_k[m])
    return pred


def _inside(pred, radius, size):
    """Boolean per marker: predicted wholly inside the image."""
    W, H = size
    with np.errstate(invalid="ignore"):
        return ((pred[:, 0] >= radius - 0.5) & (pred[:, 1] >= radius - 0.5)
                & (pred[:, 0] <= W - 0.5 - radius) & (pred[:, 1] <= H - 0.5 - radius))


def _missing_reason(pred_m, radius, regions, keep, size):
    W, H = size
    if not np.isfinite(pred_m).all():
        return "not_tracked"
    if (pred_m[0] < radius - 0.5 or pred_m[1] < radius - 0.5
            or pred_m[0] > W - 0.5 - radius or pred_m[1] > H - 0.5 - radius):
        return "left_image"
    return "occluded"


def _track_frame(gc, k, state, p):
    """Find the markers in frame k from the tracking state. Returns (px, area, reason)."""
    M = state["M"]
    H, W = gc.frames.shape[1:3]
    pred = _predict(state, k)
    has_pred = np.isfinite(pred).all(axis=1)
    px = np.full((M, 2), np.nan)
    ar = np.full(M, np.nan)
    reason = np.array(["not_tracked"] * M, dtype=object)
    tol = p.distance_tolerance
    dref = state["dref"]
    if has_pred.any():
        centre = pred[has_pred].mean(axis=0) if p.window_predict else window_center(state["last_p"])
        half = np.asarray(p.window, float) / 2
        pad = state["radius"] * 2 + 2
        crop = (int(np.floor(centre[0] - half[0] - pad)), int(np.floor(centre[1] - half[1] - pad)),
                int(np.ceil(centre[0] + half[0] + pad)) + 1, int(np.ceil(centre[1] + half[1] + pad)) + 1)
    else:
        centre, crop = None, None
    cache = state.get("cache")
    if crop is None and cache is not None and k in cache._cache:
        # the whole image was labelled already while choosing the markers
        sub, regions = gc[k], cache[k][0]
        keep = np.flatnonzero(filter_area(regions.area, p.area_min, p.area_max))
        if p.min_circularity is not None and len(keep):
            keep = keep[region_circularity(regions.subset(keep)) >= p.min_circularity]
    else:
        sub, regions, keep = _frame_regions(gc, k, p.threshold, (p.area_min, p.area_max), p.min_circularity,
                                            crop)
    if centre is not None and len(keep):
        keep = keep[filter_window(regions.centroid[keep], centre, p.window)]
    cent = regions.centroid[keep]
    # markers whose velocity is not known yet may have moved by a whole frame's motion
    gate_m = np.where(state["vel_known"], state["gate"], state["gate"] + 1.5 * state["motion"] + 2.0)
    gate = float(gate_m[has_pred].max()) if has_pred.any() else state["gate"]
    # 1) the thesis path: all markers, distance + cross-product filters
    choice = None
    ambiguous = False
    inside = _inside(pred, state["radius"], (W, H))
    if len(keep) >= M and not (has_pred & ~inside).any():
        ch = filter_distance(cent, dref, tol)
        ch = filter_cross_product(cent, ch, state["signs"])
        if len(ch):
            if has_pred.any():
                dev = np.linalg.norm(cent[ch][:, has_pred] - pred[has_pred][None], axis=-1)
                err = dev.max(axis=1)
                gated = (dev <= gate_m[has_pred][None]).all(axis=1)
                err = np.where(gated, err, np.inf)
                order = np.argsort(err)
                if np.isfinite(err[order[0]]):
                    if len(ch) > 1 and err[order[1]] <= 2 * err[order[0]] + 1.0:
                        ambiguous = True
                    else:
                        choice = ch[order[0]]
            elif len(ch) == 1:
                choice = ch[0]
            else:
                ambiguous = True
    if choice is not None:
        sel = keep[choice]
        found = np.ones(M, bool)
    else:
        # 2) partial: each marker near its prediction, distances kept among the found ones
        found = np.zeros(M, bool)
        sel = np.full(M, -1, dtype=np.intp)
        if has_pred.any() and len(keep):
            opts = []
            for m in range(M):
                if has_pred[m] and inside[m]:      # a marker predicted outside cannot be seen
                    d = np.linalg.norm(cent - pred[m], axis=1)
                    near = np.flatnonzero(d <= gate_m[m])
                    opts.append([(-1, 0.0)] + [(int(j), float(d[j])) for j in near[np.argsort(d[near])][:4]])
                else:
                    opts.append([(-1, 0.0)])
            best, second = None, None
            for combo in itertools.product(*opts):
                js = [c[0] for c in combo]
                got = [m for m in range(M) if js[m] >= 0]
                if len(set(js[m] for m in got)) < len(got):
                    continue
                good = True
                for a, b in itertools.combinations(got, 2):
                    dd = np.linalg.norm(cent[js[a]] - cent[js[b]])
                    if abs(dd - dref[a, b]) > tol * dref[a, b]:
                        good = False
                        break
                if not good:
                    continue
                err = max([c[1] for c in combo if c[0] >= 0], default=0.0)
                key = (-len(got), err)
                cand = (key, js)
                if best is None or key < best[0]:
                    best, second = cand, best
                elif second is None or key < second[0]:
                    second = cand
            if best is not None and -best[0][0] > 0:
                js = np.array(best[1])
                amb = np.zeros(M, bool)
                if second is not None and second[0][0] == best[0][0] and second[0][1] <= 2 * best[0][1] + 1.0:
                    amb = (np.array(second[1]) != js)
                for m in range(M):
                    if js[m] >= 0 and not amb[m]:
                        found[m] = True
                        sel[m] = keep[js[m]]
                    elif amb[m]:
                        reason[m] = "ambiguous"
    if found.any():
        idx = sel[found]
        px[found] = _centres(sub, regions, idx, p.centroid)
        ar[found] = regions.area[idx]
        reason[found] = ""
        # a region cut by the image border has a biased centre: the disc of the
        # marker's recent area, centred there, must lie inside the image
        cut = regions.touches_border[idx]
        if cut.any():
            fm0 = np.flatnonzero(found)
            ref_a = np.where(np.isfinite(state["area"][fm0]), state["area"][fm0], ar[fm0])
            r_m = np.sqrt(ref_a / np.pi) + 0.5        # + half a pixel: the pixelated rim
            c = px[fm0]
            cut &= ((c[:, 0] - r_m < -0.5) | (c[:, 1] - r_m < -0.5)
                    | (c[:, 0] + r_m > W - 0.5) | (c[:, 1] + r_m > H - 0.5))
        if cut.any():
            fm = np.flatnonzero(found)[cut]
            px[fm] = np.nan
            ar[fm] = np.nan
            reason[fm] = "left_image"
            found[fm] = False
        # a region much smaller than the marker's recent area is partly hidden
        ref_area = state["area"]
        small = found & np.isfinite(ref_area) & (ar < 0.5 * ref_area)
        if small.any():
            px[small] = np.nan
            ar[small] = np.nan
            reason[small] = "partly_occluded"
            found &= ~small
    for m in range(M):
        if not found[m] and reason[m] == "not_tracked":
            if ambiguous:
                reason[m] = "ambiguous"
            elif has_pred[m]:
                reason[m] = _missing_reason(pred[m], state["radius"], regions, keep, (W, H))
            elif state["last_k"][m] is not None:
                # lost for longer than max_gap: where would its last motion have taken it?
                far = state["last_p"][m] + state["vel"][m] * (k - state["last_k"][m])
                r = _missing_reason(far, state["radius"], regions, keep, (W, H))
                reason[m] = "left_image" if r == "left_image" else "not_tracked"
    return px, ar, reason


def _update_state(state, k, px, ar, p):
    M = state["M"]
    for m in range(M):
        if np.isfinite(px[m]).all():
            if state["last_k"][m] is not None and abs(k - state["last_k"][m]) <= state["max_gap"]:
                state["vel"][m] = (px[m] - state["last_p"][m]) / (k - state["last_k"][m])
                state["vel_known"][m] = True
            else:
                state["vel"][m] = 0.0
                state["vel_known"][m] = False
            state["last_k"][m] = k
            state["last_p"][m] = px[m]
            a0 = state["area"][m]
            state["area"][m] = ar[m] if not np.isfinite(a0) else 0.7 * a0 + 0.3 * ar[m]
    if np.isfinite(px).all():
        state["config"] = px.copy()
        if p.distance_reference == "previous":
            state["dref"] = marker_distances(px)
            s = cross_product_signs(px, 0.1)
            state["signs"] = s


def _new_state(px, area, k, M, radius, p, motion=0.0):
    dref = marker_distances(px)
    return {
        "M": M, "last_k": [k] * M, "last_p": px.copy(), "vel": np.zeros((M, 2)),
        "vel_known": np.zeros(M, bool), "motion": float(motion),
        "area": area.astype(float).copy(), "config": px.copy(), "dref": dref,
        "signs": cross_product_signs(px, 0.1), "radius": radius, "max_gap": 5,
        "gate": max(3.0, 0.5 * float(np.min(dref[np.triu_indices(M, 1)])) if M > 1 else 3.0 * radius),
    }


def detect_markers(frames, n_markers: int, params: DetectionParams | None = None) -> MarkerTrack:
    """Find and follow ``n_markers`` markers in the frames of one camera.

    The thesis chain (Appendix A step 4: threshold, labels, area, window,
    distance and cross-product filters) with every prompt automatic unless
    given in ``params``:

    1. threshold ``l`` (eq. 4.5): :func:`auto_threshold` over frames
       sampled across the motion;
    2. first frame and labels: from the middle of the sequence outward,
       the first frame where :func:`choose_markers` finds a consistent
       cluster of ``n_markers`` round regions;
    3. area range, window size and distance tolerance from the chosen
       markers (see :class:`DetectionParams`);
    4. tracking forward and backward from that frame: each frame is
       thresholded and labelled inside the window centred on the predicted
       marker centre (Figure 4.11), area-filtered, then the distance filter
       (eq. 4.6-4.11) and the cross-product filter (Figure 4.13) keep the
       choices of regions; the choice nearest the constant-velocity
       prediction is taken when it is unambiguous. When not all markers
       pass, each is looked for alone near its prediction, with the
       distances to the other found markers kept.

    Markers are numbered by ascending ``u`` in the first frame where all are
    found. A marker not found is NaN with a reason (:data:`REASONS`).

    Parameters
    ----------
    frames : ndarray (n, h, w, 3) uint8 RGB or (n, h, w) uint8 gray, or FrameSequence
        The frames, or a :class:`~horsemocap.sources.FrameSequence` that
        decodes them on demand (long sessions: only a few dozen frames in
        memory; the result is the same).
    n_markers : int, number of markers ``M``
    params : DetectionParams, optional

    Returns
    -------
    MarkerTrack
    """
    p = params or DetectionParams()
    frames = _frames_array(frames)
    _as_gray_frames(frames)
    if frames.dtype != np.uint8:
        raise ValueError(f"detect_markers: frames must be uint8, got {frames.dtype}")
    n = len(frames)
    M = int(n_markers)
    if M < 1:
        raise ValueError(f"detect_markers: n_markers must be >= 1, got {n_markers}")
    if n == 0:
        raise ValueError("detect_markers: no frames")
    gc = _GrayCache(frames)
    H, W = frames.shape[1:3]
    # 1) threshold
    if p.threshold is None:
        sample = np.unique(np.linspace(0, n - 1, min(n, 8)).round().astype(int))
        p = replace(p, threshold=auto_threshold([gc[i] for i in sample], p.threshold_method))
    # 2) first frame and labels
    cache = None
    if p.labels is not None:
        if p.first_frame is None:
            raise ValueError("DetectionParams.labels given without first_frame: labels name regions of one frame")
        if len(p.labels) != M:
            raise ValueError(f"DetectionParams.labels: expected {M} labels, got {len(p.labels)}")
        f0 = int(p.first_frame)
        if not 0 <= f0 < n:
            raise ValueError(f"DetectionParams.first_frame: {f0} outside 0..{n - 1}")
        regions = label_regions(binarize(gc[f0], p.threshold))
        missing = [lab for lab in p.labels if lab not in set(regions.ids.tolist())]
        if missing:
            raise DetectionError(f"frame {f0}: labels {missing} do not exist at threshold {p.threshold} "
                                 f"(labels 1..{len(regions)})")
        chosen = np.array([int(np.flatnonzero(regions.ids == lab)[0]) for lab in p.labels])
        motion = _measure_motion(gc, f0, regions.centroid[chosen], p.threshold)
    else:
        cache = CandidateCache(gc, p.threshold, AUTO_MIN_CIRCULARITY)
        f0, regions, chosen, motion, tried = _find_anchor(cache, M, p.first_frame)
        if chosen is None:
            raise DetectionError(f"no frame with a consistent cluster of {M} markers at threshold "
                                 f"{p.threshold} (tried frames {[t[0] for t in tried[:10]]}...; "
                                 f"e.g. {tried[0][1] if tried else ''}); give threshold/first_frame/labels")
        chosen = chosen[np.argsort(regions.centroid[chosen][:, 0])]
        p = replace(p, first_frame=int(f0), labels=tuple(int(x) for x in regions.ids[chosen]))
    gray0 = gc[f0]
    px0 = _centres(gray0, regions, chosen, p.centroid)
    area0 = regions.area[chosen].astype(float)
    radius = float(np.sqrt(area0.max() / np.pi))
    # 3) area range, window, tolerance
    if p.area_min is None:
        p = replace(p, area_min=float(max(1.0, np.floor(area0.min() / 4))))
    if p.area_max is None:
        p = replace(p, area_max=float(np.ceil(area0.max() * 4)))
    dm = marker_distances(px0)
    dmin = float(np.min(dm[np.triu_indices(M, 1)])) if M > 1 else 4 * radius
    if p.window is None:
        ext = px0.max(axis=0) - px0.min(axis=0)
        pad = 0.5 * (float(dm.max()) if M > 1 else 0.0) + 4 * radius + 4 + 2 * motion
        p = replace(p, window=(int(np.ceil(ext[0] + 2 * pad)), int(np.ceil(ext[1] + 2 * pad))))
    if p.distance_tolerance is None:
        p = replace(p, distance_tolerance=round(0.10 + 2.0 / dmin, 4))
    # 4) track both ways
    px = np.full((n, M, 2), np.nan)
    ar = np.full((n, M), np.nan)
    reason = np.full((n, M), "", dtype=object)
    px[f0], ar[f0] = px0, area0
    for direction in (1, -1):
        state = _new_state(px0, area0, f0, M, radius, p, motion)
        state["cache"] = cache if cache is not None and cache.threshold == p.threshold else None
        k = f0 + direction
        while 0 <= k < n:
            a, b, r = _track_frame(gc, k, state, p)
            px[k], ar[k], reason[k] = a, b, r
            _update_state(state, k, a, b, p)
            k += direction
    # 5) number the markers by ascending u in the first frame where all are found
    allf = (reason == "").all(axis=1)
    first = int(np.flatnonzero(allf)[0])
    perm = np.argsort(px[first, :, 0], kind="stable")
    px, ar, reason = px[:, perm], ar[:, perm], reason[:, perm]
    labels = tuple(int(x) for x in np.asarray(p.labels)[np.argsort(px0[:, 0])]) if p.labels else None
    p = replace(p, labels=labels)
    return MarkerTrack(marker_px=px, reason=reason.astype(str), params=p, area=ar)


def _find_anchor(cache: CandidateCache, M: int, first_frame=None):
    """The frame and regions where the markers are chosen automatically.

    Frames are tried from the middle of the sequence outward, every
    ``n // 30``-th frame but at least every 8th (a pass of the horse lasts a few
    dozen frames; all frames when short). In each, the best cluster
    of :func:`choose_markers` is followed both ways
    (:func:`cluster_persistence`); the cluster followed through the most
    frames is taken (the markers stay together for the whole pass; chance
    clusters of pseudo markers break up). Frames inside a followed span are
    not tried again, and the search stops at a cluster followed from where
    it entered the image (or the sequence began) to where it left.
    """
    n = len(cache)
    if first_frame is not None:
        if not 0 <= int(first_frame) < n:
            raise ValueError(f"DetectionParams.first_frame: {first_frame} outside 0..{n - 1}")
        order = [int(first_frame)]
    else:
        # every 8th frame at most: a horse crossing the view stays in it for a few dozen frames
        stride = max(1, min(n // 30, 8))
        order = [f for f in _middle_out(n) if (f - n // 2) % stride == 0]
    covered = np.zeros(n, bool)
    found, tried = [], []
    for f in order:
        if covered[f]:
            continue
        regions, chosen, info = choose_markers(cache.frames, M, cache.threshold, f, cache=cache)
        if chosen is None:
            tried.append((f, info.get("why", "")))
            continue
        px = regions.centroid[chosen]
        motion = float(info.get("motion_px", 0.0))
        dmin = float(marker_distances(px)[np.triu_indices(M, 1)].min()) if M > 1 else 10.0
        a, b, complete = cluster_persistence(cache, f, px, 0.15, 3 * motion + 0.5 * dmin + 3)
        covered[a:b + 1] = True
        tried.append((f, f"cluster followed through frames {a}..{b}"))
        found.append((b - a, float(info.get("best_cost", np.inf)), f, regions, chosen, motion))
        if complete and b - a == max(x[0] for x in found):
            break          # followed from where it entered to where it left: the whole pass
    if not found:
        return None, None, None, 0.0, tried
    # A marker hidden for a few frames (a hand, a rein) cuts the true cluster's span in two,
    # while a chance cluster that includes a pseudo marker riding with the horse (stirrup,
    # boot) may be followed longer. Among the clusters followed through at least half the
    # longest span, the one that looks most like the markers (choose_markers' cost) wins.
    longest = max(x[0] for x in found)
    best = min((x for x in found if x[0] >= 0.5 * longest), key=lambda x: (x[1], -x[0]))
    return best[2], best[3], best[4], best[5], tried


def _measure_motion(gc, f0, px, threshold):
    """Largest marker displacement from ``f0`` to its neighbour frame (0 if not found)."""
    n = len(gc)
    f1 = f0 + 1 if f0 + 1 < n else f0 - 1
    if not 0 <= f1 < n or f1 == f0:
        return 0.0
    r2, k2 = _generic_candidates(gc[f1], threshold, None)
    _, disp = follow_cluster(px, r2.centroid[k2], 0.10)
    return float(disp) if np.isfinite(disp) else 0.0


def _middle_out(n):
    mid = n // 2
    out = [mid]
    for d in range(1, n):
        for k in (mid + d, mid - d):
            if 0 <= k < n:
                out.append(k)
    return out


def filter_stages(image, params: DetectionParams, center=None, reference_px=None, first_px=None) -> dict:
    """Every intermediate result of the filter chain on one image (Figure 4.15).

    Parameters
    ----------
    image : (h, w, 3) RGB or (h, w) gray frame
    params : DetectionParams with threshold, area range, window and tolerance set
        (e.g. ``track.params``)
    center : window centre ``W_c(k)`` (e.g. the previous frame's marker
        centre); None = no window
    reference_px : (M, 2) marker centres giving ``DM_ij`` (eq. 4.6)
    first_px : (M, 2) marker centres of the first frame (cross-product signs)

    Returns
    -------
    dict with ``gray``, ``binary`` (eq. 4.5), ``regions`` (4.5.2), ``area_ok``
    (indices kept by the area filter), ``window_ok`` (indices also inside
    the window), ``choices`` (region index rows after the distance filter)
    and ``kept`` (after the cross-product filter), ``marker_px`` (centres of
    the single remaining choice, else None).
    """
    p = params
    gray = to_gray(np.asarray(image))
    binary = binarize(gray, p.threshold)
    regions = label_regions(binary)
    area_ok = np.flatnonzero(filter_area(regions.area, p.area_min, p.area_max))
    if p.min_circularity is not None and len(area_ok):
        area_ok = area_ok[region_circularity(regions.subset(area_ok)) >= p.min_circularity]
    window_ok = area_ok
    if center is not None and p.window is not None and len(area_ok):
        window_ok = area_ok[filter_window(regions.centroid[area_ok], center, p.window)]
    out = {"gray": gray, "binary": binary, "regions": regions, "area_ok": area_ok, "window_ok": window_ok,
           "choices": None, "kept": None, "marker_px": None}
    if reference_px is not None:
        ref = np.asarray(reference_px, float)
        ch = filter_distance(regions.centroid[window_ok], marker_distances(ref), p.distance_tolerance)
        signs = cross_product_signs(first_px if first_px is not None else ref, 0.1)
        kept = filter_cross_product(regions.centroid[window_ok], ch, signs)
        out["choices"], out["kept"] = window_ok[ch], window_ok[kept]
        if len(kept) >= 1:
            # the remaining choice nearest the reference centre (unique in a clean frame)
            cost = [np.linalg.norm(regions.centroid[window_ok[k]] - ref, axis=1).max() for k in kept]
            best = window_ok[kept[int(np.argmin(cost))]]
            out["marker_px"] = (regions.centroid[best] if p.centroid == "binary"
                                else weighted_centroids(gray, regions, best))
    return out


# --------------------------------------------------------------------------
# stills
# --------------------------------------------------------------------------
def detect_still(image, n_markers: int, params: DetectionParams | None = None, order: str | None = None):
    """Marker centres in one still image (Appendix A steps 7a, 8a, 12a).

    The same filters as the sequence, without the window (one image): the
    threshold (given or automatic, eq. 4.5), labelling, the area range (if
    given, else 3 px to 0.5 % of the image), the shape filter (circularity
    >= ``params.min_circularity``, default 0.5) and the border test. When
    ``params.labels`` are given they are taken as they are. Otherwise the
    ``n_markers`` regions are chosen among the candidates as the
    combination that looks most like the markers (as in
    :func:`choose_markers`: areas within 3 times, then round and white: the
    smallest mean ``1 - circularity`` plus mean ``1 - peak/255``);
    when the regions that only the next best combination uses do not score
    clearly worse (twice + 0.02) than those it replaces, the error says so.

    Order of the returned markers: ``order="v"`` (top first; used for the
    plumb: tip = the upper marker, tail = the lower) or ``order="u"`` (by
    ascending ``u``; static shot). Default: ``"v"`` for 2 markers,
    ``"u"`` otherwise.

    Returns
    -------
    ndarray (n_markers, 2) of ``(u, v)``

    Raises
    ------
    DetectionError
        When ``n_markers`` markers cannot be found.
    """
    p = params or DetectionParams()
    gray = to_gray(np.asarray(image))
    M = int(n_markers)
    order = order or ("v" if M == 2 else "u")
    if order not in ("u", "v"):
        raise ValueError(f"detect_still: order must be 'u' or 'v', got {order!r}")
    thr = p.threshold if p.threshold is not None else auto_threshold([gray], p.threshold_method)
    if p.labels is not None:
        regions = label_regions(binarize(gray, thr))
        have = set(regions.ids.tolist())
        bad = [x for x in p.labels if x not in have]
        if bad or len(p.labels) != M:
            raise DetectionError(f"still: labels {list(p.labels)} do not name {M} regions at threshold {thr}")
        idx = np.array([int(np.flatnonzero(regions.ids == x)[0]) for x in p.labels])
    else:
        H, W = gray.shape
        amin = p.area_min if p.area_min is not None else GENERIC_AREA[0]
        amax = p.area_max if p.area_max is not None else max(50.0, GENERIC_MAX_AREA_FRACTION * H * W)
        circ = p.min_circularity if p.min_circularity is not None else AUTO_MIN_CIRCULARITY
        cache = CandidateCache([gray], thr, circ)
        regions, keep, circv, peak = cache[0]
        sel = (regions.area[keep] >= amin) & (regions.area[keep] <= amax)
        keep, circv, peak = keep[sel], circv[sel], peak[sel]
        if len(keep) < M:
            raise DetectionError(f"still: {len(keep)} round regions of area {amin:g}..{amax:g} px above "
                                 f"threshold {thr}, expected {M} markers")
        if len(keep) == M:
            idx = keep
        else:
            combos = np.array(list(itertools.combinations(range(len(keep)), M)), dtype=np.intp)
            spread = _tuple_cost_static(regions.centroid[keep], regions.area[keep], combos)
            cost = (1 - circv[combos]).mean(axis=1) + (1 - peak[combos] / 255.0).mean(axis=1)
            cost[spread > np.log(3.0)] = np.inf
            o = np.argsort(cost)
            if not np.isfinite(cost[o[0]]):
                raise DetectionError(f"still: no {M} candidate regions of similar area (within 3 times)")
            # decide between the regions the two best combinations do not share
            score = (1 - circv) + (1 - peak / 255.0)
            only_best = sorted(set(combos[o[0]]) - set(combos[o[1]]))
            only_second = sorted(set(combos[o[1]]) - set(combos[o[0]]))
            if np.isfinite(cost[o[1]]) and score[only_second].sum() < 2 * score[only_best].sum() + 0.02:
                raise DetectionError(
                    f"still: {len(keep)} candidate regions at threshold {thr}; the {M} markers are "
                    f"ambiguous (costs {cost[o[0]]:.3f} vs {cost[o[1]]:.3f}); give labels or an area range")
            idx = keep[combos[o[0]]]
    c = (regions.centroid[idx] if p.centroid == "binary" else weighted_centroids(gray, regions, idx))
    key = 1 if order == "v" else 0
    return c[np.argsort(c[:, key], kind="stable")]


# --------------------------------------------------------------------------
# stills seen by several cameras
# --------------------------------------------------------------------------
#: Largest number of combinations of consistent points examined for the
#: choice of the markers (more consistent points: only the best-looking
#: ones enter the combinations, see :func:`match_still_views`).
MAX_VIEW_COMBINATIONS = 200_000


@dataclass(frozen=True)
class StillCandidates:
    """Marker-like candidate regions of one still image (same rules as :func:`detect_still`).

    Attributes
    ----------
    threshold : int
        Gray level ``l`` of eq. (4.5) used.
    centre : ndarray (K, 2)
        ``(u, v)`` centres (intensity-weighted, or binary with ``centroid="binary"``).
    area : ndarray (K,)
        Pixel count (4.5.3).
    circularity : ndarray (K,)
        ``A / (2 pi (var_u + var_v))`` (1 for a disc).
    peak : ndarray (K,)
        Brightest gray level of the region.
    score : ndarray (K,)
        Appearance cost ``(1 - circularity) + (1 - peak / 255)`` (0 = a
        round saturated disc), the cost :func:`detect_still` minimises.
    """

    threshold: int
    centre: np.ndarray
    area: np.ndarray
    circularity: np.ndarray
    peak: np.ndarray
    score: np.ndarray

    def __len__(self):
        return len(self.area)


def still_candidates(image, params: DetectionParams | None = None) -> StillCandidates:
    """Every marker-like region of a still image, with its appearance cost.

    The candidate rules of :func:`detect_still`: threshold ``params.threshold``
    (automatic: :func:`auto_threshold` of this image), labelling (4.5.2), area
    range ``params.area_min .. area_max`` (default 3 px .. 0.5 % of the
    image, 4.5.3), circularity ``>= params.min_circularity`` (default 0.5),
    not cut by the image border; at most the 24 largest regions are kept.
    """
    p = params or DetectionParams()
    gray = to_gray(np.asarray(image))
    thr = p.threshold if p.threshold is not None else auto_threshold([gray], p.threshold_method)
    H, W = gray.shape
    amin = p.area_min if p.area_min is not None else GENERIC_AREA[0]
    amax = p.area_max if p.area_max is not None else max(50.0, GENERIC_MAX_AREA_FRACTION * H * W)
    circ_min = p.min_circularity if p.min_circularity is not None else AUTO_MIN_CIRCULARITY
    regions, keep, circ, peak = CandidateCache([gray], thr, circ_min)[0]
    sel = (regions.area[keep] >= amin) & (regions.area[keep] <= amax)
    keep, circ, peak = keep[sel], circ[sel], peak[sel]
    if len(keep) == 0:
        centre = np.zeros((0, 2))
    elif p.centroid == "binary":
        centre = regions.centroid[keep].astype(float)
    else:
        centre = weighted_centroids(gray, regions, keep)
    return StillCandidates(int(thr), centre, regions.area[keep].astype(float), circ.astype(float),
                           peak.astype(float), (1 - circ) + (1 - peak / 255.0))


@dataclass(frozen=True)
class StillViews:
    """The markers of one still seen by several cameras (:func:`match_still_views`).

    Attributes
    ----------
    marker_px : dict camera -> ndarray (n_markers, 2)
        Detected ``(u, v)`` centres, same marker order in every camera
        (thesis ``PM_L``, ``PM_M``, ``PM_R`` of one image).
    points : ndarray (n_markers, 3)
        Joint triangulation of the chosen centres (world frame = reference
        camera frame, m; thesis ``CM_L``).
    residual_px : ndarray (n_markers,)
        Largest reprojection error of each chosen point over the cameras.
    score : ndarray (n_markers,)
        Appearance cost of each chosen point (mean over the cameras of
        :attr:`StillCandidates.score`).
    candidates : dict camera -> StillCandidates
    index : dict camera -> ndarray (n_markers,) of int
        Index of each chosen marker among the camera's candidates.
    consistent : ndarray (T, C) of int
        Every consistent correspondence found (candidate index per camera,
        cameras in :attr:`cameras` order).
    consistent_score : ndarray (T,)
        Their appearance costs.
    margin : float
        How clearly the choice wins: cost of the points only the second-best
        choice uses minus ``2 x`` the cost of those only the best uses minus
        0.02 (the ambiguity rule of :func:`detect_still`); ``inf`` when no
        other choice exists. A choice is accepted only when ``margin >= 0``.
    cameras : tuple of str
        Cameras, reference first (rig order).
    """

    marker_px: dict
    points: np.ndarray
    residual_px: np.ndarray
    score: np.ndarray
    candidates: dict
    index: dict
    consistent: np.ndarray
    consistent_score: np.ndarray
    margin: float
    cameras: tuple


def _consistent_points(rig, cams, cand, max_residual_px):
    """Correspondences of candidates found in ALL cameras with a small reprojection error.

    Hypotheses start as the candidates of the reference camera; each further
    camera's candidates are added to every hypothesis and the extended
    hypotheses are triangulated jointly (:func:`horsemocap.reconstruction.triangulate`,
    ``mode="joint"``, every camera kept); those whose largest reprojection
    error is below ``max_residual_px`` (the epipolar constraint for two
    cameras, the 3D consistency for more) survive.

    Returns index rows (T, C), points (T, 3) and largest residuals (T,).
    """
    from ..reconstruction import triangulate

    hyp = np.arange(len(cand[cams[0]]))[:, None]
    X, res = np.zeros((len(hyp), 3)), np.zeros(len(hyp))
    for j in range(1, len(cams)):
        nc = len(cand[cams[j]])
        new = np.column_stack([np.repeat(hyp, nc, axis=0), np.tile(np.arange(nc), len(hyp))])
        if len(new) == 0:
            return new, np.zeros((0, 3)), np.zeros(0)
        px = {cams[i]: cand[cams[i]].centre[new[:, i]][None] for i in range(j + 1)}
        tri = triangulate(rig, px, mode="joint", max_residual_px=None)
        r = np.max(np.stack([tri.residual_px[c][0] for c in cams[:j + 1]]), axis=0)
        ok = tri.valid[0] & np.isfinite(r) & (r < max_residual_px)
        hyp, X, res = new[ok], tri.points[0][ok], r[ok]
    return hyp, X, res


def _choose_points(hyp, score, area, M):
    """Best combination of M disjoint correspondences; its cost and the runner-up's.

    A combination may use each candidate of each camera once, and the areas of
    its regions lie within 3 times in every camera (markers share one size,
    as in :func:`detect_still`). Cost = sum of the appearance costs.
    """
    T = len(hyp)
    order = np.argsort(score, kind="stable")
    K = T
    while K > M and math.comb(K, M) > MAX_VIEW_COMBINATIONS:
        K -= 1
    pool = order[:K]
    combos = pool[np.array(list(itertools.combinations(range(K), M)), dtype=np.intp)]
    ok = np.ones(len(combos), bool)
    for c in range(hyp.shape[1]):
        idx = hyp[combos, c]                                    # (n, M)
        s = np.sort(idx, axis=1)
        ok &= np.all(s[:, 1:] != s[:, :-1], axis=1)             # a region serves one marker only
        la = np.log(area[c][idx])
        ok &= (la.max(axis=1) - la.min(axis=1)) <= np.log(3.0)
    combos = combos[ok]
    cost = score[combos].sum(axis=1)
    o = np.argsort(cost, kind="stable")
    return combos[o], cost[o]


def match_still_views(images: dict, rig, n_markers: int, params: DetectionParams | None = None, *,
                      max_residual_px: float = 2.0, order: str | None = None) -> StillViews:
    """The markers of a still (plumb, static shot) found consistently by every camera.

    One camera alone cannot tell a marker from a round bright pseudo marker
    (a glint, a buckle) of similar look; the other cameras can: a marker is
    a 3D point whose projections are candidate regions in ALL cameras.

    1. Candidates of each camera: :func:`still_candidates` (the rules of
       :func:`detect_still`: threshold eq. 4.5, labelling 4.5.2, area 4.5.3,
       circularity, border).
    2. Correspondences: every candidate of the reference camera (the first
       camera of ``rig`` present in ``images``) is paired with every
       candidate of the next camera, then of the next..., each extended set
       triangulated jointly (``triangulate(mode="joint")``, thesis 5.1) and
       kept when its largest reprojection error is below ``max_residual_px``
       (for two cameras this is the epipolar constraint; with three, the
       point must also project onto a candidate of the third camera).
    3. Choice: among the consistent points, the ``n_markers`` with disjoint
       regions, areas within 3 times in every camera, and the smallest sum of
       appearance costs (mean over the cameras of ``(1 - circularity) +
       (1 - peak / 255)``). As in :func:`detect_still`, when the points that
       only the second-best choice uses do not cost clearly more (twice +
       0.02) than those only the best uses, the choice is ambiguous.

    Parameters
    ----------
    images : dict camera -> (h, w, 3) RGB or (h, w) gray still
    rig : horsemocap.camera.Rig
        Calibrated cameras (world = reference camera frame).
    n_markers : int
        2 for the plumb (thesis 5.3), markers + 1 for the static shot (6.3).
    params : DetectionParams, optional
        ``threshold`` (one level for every camera; default automatic per
        image), ``area_min``/``area_max``, ``min_circularity``, ``centroid``.
        ``labels`` name regions of one image and are refused here.
    max_residual_px : float
        Largest reprojection error (pixels) of a consistent point.
    order : {"v", "u"} or None
        Marker order, decided in the reference camera: ``"v"`` top first
        (plumb: tail = upper, tip = lower), ``"u"`` ascending ``u``. Default
        ``"v"`` for 2 markers, else ``"u"`` (as :func:`detect_still`).

    Returns
    -------
    StillViews

    Raises
    ------
    DetectionError
        Naming the cameras, when fewer than ``n_markers`` consistent points
        exist or the choice is ambiguous.
    ValueError
        Bad input (unknown camera, fewer than two cameras, labels given).
    """
    p = params or DetectionParams()
    M = int(n_markers)
    if M < 1:
        raise ValueError(f"still views: n_markers must be >= 1, got {n_markers!r}")
    order = order or ("v" if M == 2 else "u")
    if order not in ("u", "v"):
        raise ValueError(f"still views: order must be 'u' or 'v', got {order!r}")
    if p.labels is not None:
        raise ValueError("still views: params.labels name the regions of one image; "
                         "use detect_still per camera to give labels")
    if not isinstance(images, dict):
        raise ValueError("still views: images must be a dict {camera name: image}")
    unknown = [c for c in images if c not in rig.names]
    if unknown:
        raise ValueError(f"still views: camera(s) {unknown} are not in the rig (it has {rig.names})")
    cams = tuple(c for c in rig.names if c in images)
    if len(cams) < 2:
        raise ValueError(f"still views: need the stills of at least two cameras, got {list(images)}")
    cand = {c: still_candidates(images[c], p) for c in cams}
    counts = ", ".join(f"{c}: {len(cand[c])} at threshold {cand[c].threshold}" for c in cams)
    short = [c for c in cams if len(cand[c]) < M]
    if short:
        raise DetectionError(f"still views: camera(s) {short} have fewer than {M} round candidate regions "
                             f"({counts})")
    hyp, X, res = _consistent_points(rig, cams, cand, max_residual_px)
    score = (np.mean([cand[c].score[hyp[:, i]] for i, c in enumerate(cams)], axis=0)
             if len(hyp) else np.zeros(0))
    n_distinct = min((len(np.unique(hyp[:, i])) for i in range(len(cams))), default=0)
    if len(hyp) < M or n_distinct < M:
        raise DetectionError(
            f"still views: only {min(len(hyp), n_distinct)} point(s) are seen consistently by all cameras "
            f"{list(cams)} (reprojection error < {max_residual_px:g} px), expected {M} markers "
            f"(candidates {counts}); check the rig or the stills")
    combos, cost = _choose_points(hyp, score, [cand[c].area for c in cams], M)
    if len(combos) == 0:
        raise DetectionError(
            f"still views: {len(hyp)} consistent points in cameras {list(cams)} but no {M} of them with "
            f"distinct regions of similar area (within 3 times) in every camera (candidates {counts})")
    margin = np.inf
    if len(combos) > 1:
        only_best = sorted(set(combos[0]) - set(combos[1]))
        only_second = sorted(set(combos[1]) - set(combos[0]))
        # detect_still's rule on the costs averaged over the cameras ...
        mean_margin = float(score[only_second].sum() - 2 * score[only_best].sum() - 0.02)
        # ... or every camera on its own prefers the choice by more than its slack
        per_cam = [cand[c].score[hyp[only_second, i]].sum() - cand[c].score[hyp[only_best, i]].sum() - 0.02
                   for i, c in enumerate(cams)]
        margin = max(mean_margin, float(min(per_cam)))
        if margin < 0:
            raise DetectionError(
                f"still views: cameras {list(cams)}: {len(hyp)} points are consistent in all cameras and the "
                f"{M} markers among them are ambiguous (costs {cost[0]:.3f} vs {cost[1]:.3f}); "
                f"give an area range or a threshold (candidates {counts})")
    best = combos[0]
    ref_px = cand[cams[0]].centre[hyp[best, 0]]
    o = best[np.argsort(ref_px[:, 1 if order == "v" else 0], kind="stable")]
    index = {c: hyp[o, i] for i, c in enumerate(cams)}
    return StillViews(
        marker_px={c: cand[c].centre[index[c]] for c in cams},
        points=X[o], residual_px=res[o], score=score[o], candidates=cand, index=index,
        consistent=hyp, consistent_score=score, margin=float(margin), cameras=cams)


def detect_still_views(images: dict, rig, n_markers: int, params: DetectionParams | None = None, *,
                       max_residual_px: float = 2.0) -> dict:
    """Marker centres of a still seen by several cameras (Appendix A steps 7a, 8a, 12a).

    The plumb (2 markers, thesis 5.3) and static-shot (markers + saddle
    marker, thesis 6.3) stills of all cameras at once: the markers are the
    ``n_markers`` 3D points whose projections are candidate regions in every
    camera with a reprojection error below ``max_residual_px``, and among
    those the ones that look most like markers. See :func:`match_still_views`
    for the method and the errors.

    Returns
    -------
    dict camera -> ndarray (n_markers, 2)
        ``(u, v)`` per camera (thesis ``PM_L``, ``PM_M``, ``PM_R`` of the
        still), the same marker order in every camera: for 2 markers top
        first by ``v`` in the reference camera, else ascending ``u`` in the
        reference camera (as :func:`detect_still`).
    """
    return match_still_views(images, rig, n_markers, params, max_residual_px=max_residual_px).marker_px


# --------------------------------------------------------------------------
# output
# --------------------------------------------------------------------------
def valid_frames(track: MarkerTrack) -> np.ndarray:
    """Frames (own numbering) where every marker was found."""
    return np.flatnonzero(track.all_found)


def usable_frames(tracks: dict, offsets: dict | None = None, reference: str | None = None) -> np.ndarray:
    """Reference-camera frames where every camera sees every marker.

    Frame ``k`` of the reference camera is frame ``k + offsets[c] -
    offsets[reference]`` of camera ``c`` (thesis eq. 3.11-3.13).

    Parameters
    ----------
    tracks : dict camera -> MarkerTrack (each in its own numbering)
    offsets : dict camera -> frame offset (default all 0)
    reference : camera name (default: the first key of ``tracks``)

    Returns
    -------
    ndarray of int, sorted
    """
    if not tracks:
        return np.zeros(0, int)
    reference = reference or next(iter(tracks))
    offsets = offsets or {c: 0 for c in tracks}
    missing = [c for c in tracks if c not in offsets]
    if missing:
        raise ValueError(f"usable_frames: no offset for camera(s) {missing}")
    ok = None
    for cam, tr in tracks.items():
        shift = int(offsets[cam]) - int(offsets[reference])
        frames_ref = np.flatnonzero(tr.all_found) - shift
        ok = set(frames_ref.tolist()) if ok is None else ok & set(frames_ref.tolist())
    return np.array(sorted(f for f in ok if f >= 0), dtype=int)


def marker_label(index: int) -> str:
    """The name of marker ``index`` (0-based) in every result file: ``marker1``, ``marker2``, ..."""
    return f"marker{int(index) + 1}"


def _px_text(value: float) -> str:
    return f"{float(value):.9g}" if np.isfinite(value) else ""


def markers_2d_rows(camera: str, track, frame_offset: int = 0) -> list[list]:
    """Rows ``[camera, frame, marker, u_px, v_px]`` of ``markers_2d.csv``.

    Parameters
    ----------
    camera : str
    track : MarkerTrack or ndarray (frames, markers, 2)
        The detections (a track's ``marker_px``), NaN where not found.
    frame_offset : int
        Index in the camera's own motion source of the track's first frame.

    Returns
    -------
    list of list
        ``frame`` = track index + ``frame_offset``, ``marker`` =
        :func:`marker_label`, ``u_px``/``v_px`` to 9 significant digits,
        ``""`` where the marker was not found.
    """
    px = np.asarray(getattr(track, "marker_px", track), float)
    return [[camera, k + int(frame_offset), marker_label(m), _px_text(px[k, m, 0]), _px_text(px[k, m, 1])]
            for k in range(px.shape[0]) for m in range(px.shape[1])]


def markers_2d_csv_text(tracks: dict, frame_offsets: dict | None = None) -> str:
    """The text of ``markers_2d.csv`` (spec ``sessions.md``: ``camera,frame,marker,u_px,v_px``).

    ``tracks`` maps camera -> :class:`MarkerTrack` or ``marker_px`` array;
    ``frame_offsets`` maps camera -> source index of its first frame (0 if absent).
    The pipeline's results and :func:`write_markers_2d_csv` both use this.
    """
    lines = ["camera,frame,marker,u_px,v_px"]
    for cam, tr in tracks.items():
        off = (frame_offsets or {}).get(cam, 0)
        lines.extend(",".join(str(x) for x in r) for r in markers_2d_rows(cam, tr, off))
    return "\n".join(lines) + "\n"


def write_markers_2d_csv(path, tracks: dict, frame_offsets: dict | None = None) -> Path:
    """Write ``markers_2d.csv`` atomically (:func:`markers_2d_csv_text`)."""
    from ..store import atomic_write_text
    return atomic_write_text(path, markers_2d_csv_text(tracks, frame_offsets))
