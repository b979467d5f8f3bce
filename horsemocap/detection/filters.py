"""The filters of thesis chapter 4 (4.5.2-4.5.5), each a pure function.

- labelling and region centres (4.5.2): :func:`label_regions`;
- area filter (4.5.3): :func:`filter_area`; circularity by geometric moments
  (seed 000, Hu's first invariant): :func:`region_circularity`,
  :func:`filter_circularity`;
- the sliding window (4.5.4, Figure 4.11): :func:`window_center`,
  :func:`filter_window`;
- the distance filter, eq. (4.6)-(4.11): :func:`marker_distances`,
  :func:`filter_distance`; the cross-product filter (Figure 4.13):
  :func:`cross_product_signs`, :func:`filter_cross_product`;
- intensity-weighted centres above the local background:
  :func:`weighted_centroids`;
- candidates of one image or window crop (threshold, labels, area, shape):
  :func:`find_candidates`;
- every stage of the chain on one frame (Figure 4.15): :func:`filter_stages`.
"""
from __future__ import annotations

import itertools
from functools import lru_cache
from typing import NamedTuple

import cv2
import numpy as np

from .base import DetectionParams, Regions, boxes_touch_border
from .thresholds import binarize, connected_components, to_gray

__all__ = [
    "label_regions",
    "clip_crop",
    "region_circularity",
    "filter_area",
    "filter_circularity",
    "window_center",
    "filter_window",
    "marker_distances",
    "filter_distance",
    "cross_product_signs",
    "filter_cross_product",
    "RegionWeight",
    "region_weights",
    "weighted_centroids",
    "light_terms",
    "find_candidates",
    "filter_stages",
]


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
    return _regions_of(connected_components(b, connectivity), b.shape, origin, image_size)


def _regions_of(labelled, shape, origin, image_size) -> Regions:
    """:class:`Regions` of ``(n, labels, stats, centroids)`` (``cv2.connectedComponentsWithStats``' output)
    of an area of ``shape`` at ``origin`` in the full image."""
    n, labels, stats, cents = labelled
    u0, v0 = int(origin[0]), int(origin[1])
    size = tuple(image_size) if image_size is not None else (shape[1] + u0, shape[0] + v0)
    if u0 == 0 and v0 == 0:
        bbox, centroid = stats[1:, :4].astype(np.int64), cents[1:]
    else:
        bbox, centroid = stats[1:, :4] + np.array([u0, v0, 0, 0]), cents[1:] + np.array([u0, v0], float)
    return Regions(labels=labels, ids=np.arange(1, n), area=stats[1:, 4].astype(np.int64), bbox=bbox,
                   centroid=centroid, origin=(u0, v0), image_size=size)


def region_circularity(regions: Regions, by_moments: bool | None = None) -> np.ndarray:
    """Circularity from geometric moments (seed 000 section 5.2.1; Hu 1962).

    ``c = A / (2 pi (var_u + var_v))`` = ``1 / (2 pi phi_1)`` where
    ``phi_1 = eta_20 + eta_02`` is Hu's first moment invariant; the pixel
    variances include each pixel's own extent (1/12). ``c`` is 1 for a disc,
    ``2r / (1 + r^2)`` for an ellipse of axis ratio ``r`` and
    ``6k / (pi (1 + k^2))`` for a ``k``:1 bar.

    Up to 8 regions each region's moments are taken by ``cv2.moments`` on
    its box, more by one pass of sums over the labelled area (the two agree
    to rounding); ``by_moments`` forces one of the two (a search labelling an
    image in crops takes the path the whole image's regions would; forced
    sums are taken in full-image pixels, as for the whole image).
    """
    C = len(regions)
    if C == 0:
        return np.zeros(0)
    lab = regions.labels
    u0, v0 = regions.origin
    out = np.empty(C)
    if (C <= 8) if by_moments is None else by_moments:
        for i, (rid, bb) in enumerate(zip(regions.ids, regions.bbox)):
            x, y = bb[0] - u0, bb[1] - v0
            sub = (lab[y:y + bb[3], x:x + bb[2]] == rid).astype(np.uint8)
            m = cv2.moments(sub, binaryImage=True)
            a = m["m00"]
            var = (m["mu20"] + m["mu02"]) / a + 1.0 / 6.0
            out[i] = a / (2 * np.pi * var)
        return out
    # sums of pixel indices (integers: exact, so the same numbers however they are summed), in
    # full-image pixels when forced, else in the labelled area's
    ou, ov = (0, 0) if by_moments is False else (u0, v0)
    if C <= SUMS_BY_REGION:             # each region's box: its raw moments, shifted exactly
        a, su, sv, suu, svv = _region_sums(regions, ou, ov)
    else:                               # one pass over the labelled area
        v, u = np.nonzero(lab)
        ll = lab[v, u]
        u, v = u + (u0 - ou), v + (v0 - ov)
        n = int(lab.max()) + 1
        ids = regions.ids
        a = np.bincount(ll, minlength=n).astype(float)[ids]
        su, sv = np.bincount(ll, u, n)[ids], np.bincount(ll, v, n)[ids]
        suu, svv = np.bincount(ll, u.astype(float) ** 2, n)[ids], np.bincount(ll, v.astype(float) ** 2, n)[ids]
    with np.errstate(invalid="ignore", divide="ignore"):
        var = (suu - su ** 2 / a + svv - sv ** 2 / a) / a + 1.0 / 6.0
        return a / (2 * np.pi * var)


#: Up to this many regions :func:`region_circularity`'s sums are taken region by region (their boxes), more
#: in one pass over the labelled area.
SUMS_BY_REGION = 64


def _region_sums(regions: Regions, ou: int, ov: int):
    """Area and the sums of ``u``, ``v``, ``u^2``, ``v^2`` over each region's pixels (``u = x - ou``, ...).

    ``x, y`` full-image pixels. ``cv2.moments`` of the region's box (integer
    raw moments, exact), moved to the origin ``(ou, ov)`` in Python integers.
    """
    lab = regions.labels
    u0, v0 = regions.origin
    rows = []
    for rid, (x, y, w, h) in zip(regions.ids.tolist(), regions.bbox.tolist()):
        m = cv2.moments((lab[y - v0:y - v0 + h, x - u0:x - u0 + w] == rid).view(np.uint8), binaryImage=True)
        a, m10, m01, m20, m02 = (int(m[k]) for k in ("m00", "m10", "m01", "m20", "m02"))
        du, dv = x - ou, y - ov
        rows.append((a, m10 + du * a, m01 + dv * a, m20 + 2 * du * m10 + du * du * a, m02 + 2 * dv * m01 + dv * dv * a))
    return tuple(np.array(c, float) for c in zip(*rows))


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
    d = p[:, None, :] - p[None, :, :]
    return _norm(d)


def _norm(d: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(d, axis=-1)`` of a real array: the same numbers, without its Python overhead."""
    return np.sqrt(np.add.reduce(d * d, axis=-1))


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
    i, j = _pairs(m)
    ref = dm[i, j]
    ok = (np.abs(dc[perms[:, i], perms[:, j]] - ref) <= tolerance * ref).all(axis=1)   # every pair at once
    return perms[ok]


@lru_cache(maxsize=16)
def _pairs(m: int):
    """The pairs ``i < j`` of ``m`` markers, as two index arrays."""
    return np.triu_indices(m, 1)


def cross_product_signs(marker_px: np.ndarray, min_sine: float = 0.0) -> np.ndarray:
    """``sgn[(r_12 x r_23)_3]`` for each consecutive triple of markers (Figure 4.13).

    Returns (M-2,) values in {-1, 0, +1}; 0 where the triple is so nearly
    straight (``|sin| < min_sine``) that its sign says nothing.
    """
    return _turn_signs(np.asarray(marker_px, float), min_sine).astype(int)


def _turn_signs(p: np.ndarray, min_sine: float) -> np.ndarray:
    """Signs of ``(r_12 x r_23)_3`` along the marker axis (second to last) of ``p`` (..., M, 2):
    0 for a triple bent less than ``min_sine`` and for a NaN centre."""
    r1 = p[..., 1:-1, :] - p[..., :-2, :]
    r2 = p[..., 2:, :] - p[..., 1:-1, :]
    z = r1[..., 0] * r2[..., 1] - r1[..., 1] * r2[..., 0]
    s = np.sign(z)
    s[~(np.abs(z) >= min_sine * (_norm(r1) * _norm(r2)))] = 0
    return s


def filter_cross_product(centroid, choices, reference_signs, min_sine: float = 0.05) -> np.ndarray:
    """Cross-product filter (thesis Figure 4.13): keep the marker order.

    A choice of regions is kept when, for every consecutive triple whose
    reference sign is not 0, ``sgn[(r_12 x r_23)_3]`` equals the sign in
    the reference (first) frame. Triples bent less than ``min_sine`` in the
    candidate are not tested either (their sign is noise).
    """
    choices = np.asarray(choices, dtype=np.intp)
    ref = np.asarray(reference_signs)
    if len(choices) == 0 or choices.shape[1] < 3 or not ref.any():
        return choices
    s = _turn_signs(np.asarray(centroid, float)[choices], min_sine)     # (K, M-2)
    ok = ((s == ref) | (ref == 0) | (s == 0)).all(axis=1)
    return choices[ok]


# --------------------------------------------------------------------------
# centres
# --------------------------------------------------------------------------
_K3 = np.ones((3, 3), np.uint8)


@lru_cache(maxsize=16)
def _square(size: int) -> np.ndarray:
    """A ``size`` x ``size`` square kernel: one dilation by it = ``(size - 1) / 2`` dilations by 3 x 3."""
    return np.ones((size, size), np.uint8)


class RegionWeight(NamedTuple):
    """The weights of one region (:func:`region_weights`), in a patch around it.

    Attributes
    ----------
    i : index in their :class:`Regions` (the list of :func:`region_weights` is in the order asked for)
    weight : (p, q) float32, ``max(I - b, 0)`` on the region grown by ``margin`` (other regions left out),
        else 0 (multiples of 1/2 below 256: exact in float32)
    above : (p, q) float32, ``I - b``, the gray level above the region's background ``b``
    own : (p, q) uint8, 1 on the region's own pixels
    x0, y0 : the patch's corner in the labelled area's pixels
    cut : (left, right, top, bottom) image edges the region touches
    moments : ``cv2.moments(weight)``; its sums (weights times pixel indices) are exact:
        the weights are multiples of 1/2
    """

    i: int
    weight: np.ndarray
    above: np.ndarray
    own: np.ndarray
    x0: int
    y0: int
    cut: tuple
    moments: dict


def region_weights(gray: np.ndarray, regions: Regions, index=None, margin: int = 2) -> list:
    """The weights of :func:`weighted_centroids` (and :func:`light_terms`) of the regions ``index``.

    For each region its mask is grown by ``margin`` pixels (``near``) and by
    ``margin + 2`` (``far``: one dilation by a square each, as ``margin`` and
    ``margin + 2`` dilations by 3 x 3); the pixels of other regions, grown by
    one, are left out (looked for only when the patch holds more labelled
    pixels than the region's area); the background ``b`` is the median of
    the ring ``far \\ near`` (the region's darkest pixel - 1 when the ring is
    empty) and the weight ``max(I - b, 0)`` on ``near``. The sums of
    :func:`weighted_centroids` by ``cv2.moments`` (one call per region).

    Returns
    -------
    list of :class:`RegionWeight`
    """
    W, H = regions.image_size
    boxes = regions.bbox.tolist()
    out = []
    for i, x0, y0, own_b, near, sub8, b in _near_and_background(gray, regions, index, margin):
        above = np.subtract(sub8, b, dtype=np.float32)   # halves within +-256: exact in float32
        wgt = np.maximum(above, np.float32(0))
        wgt *= near
        bx, by, bw, bh = boxes[i]
        cut = (bx <= 0, bx + bw >= W, by <= 0, by + bh >= H)
        out.append(RegionWeight(i, wgt, above, own_b.view(np.uint8), x0, y0, cut, _image_moments(wgt)))
    return out


def _image_moments(img: np.ndarray) -> dict:
    """``cv2.moments`` of an image (weights); a float image two columns wide, which ``cv2.moments`` would
    take for a contour of points, gets a zero column (the same moments)."""
    if img.ndim == 2 and img.shape[1] == 2 and img.dtype != np.uint8:
        img = np.pad(img, ((0, 0), (0, 1)))
    return cv2.moments(img)


def _near_and_background(gray: np.ndarray, regions: Regions, index, margin: int):
    """Per region of ``index``: ``(i, x0, y0, own, near, sub8, b)``, what :func:`region_weights` describes:
    the patch's corner, the region's own pixels and its grown mask (bool) in the patch, the gray patch and
    the background ``b`` (a multiple of 1/2)."""
    idx = np.arange(len(regions)) if index is None else np.atleast_1d(np.asarray(index, dtype=np.intp))
    lab = regions.labels
    h, w = lab.shape
    u0, v0 = regions.origin
    g = 2 * margin + 2                     # the ring reaches margin + 2 px from the region, other regions + 1
    k_near, k_far = _square(2 * margin + 1), _square(2 * margin + 5)
    ids, areas = regions.ids.tolist(), regions.area.tolist()
    boxes = regions.bbox.tolist()
    for i in idx.tolist():
        bx, by, bw, bh = boxes[i]
        bx, by = bx - u0, by - v0
        x0, y0 = max(bx - g, 0), max(by - g, 0)
        x1, y1 = min(bx + bw + g, w), min(by + bh + g, h)
        sl = lab[y0:y1, x0:x1]
        own_b = sl == ids[i]
        own = own_b.view(np.uint8)
        near = cv2.dilate(own, k_near).view(bool)
        far = cv2.dilate(own, k_far).view(bool)
        sub8 = gray[y0:y1, x0:x1]
        if np.count_nonzero(sl) > areas[i]:             # other regions in the patch: left out, grown by one
            other = cv2.dilate(((sl != 0) & ~own_b).view(np.uint8), _K3).view(bool)
            ring = far & ~near & ~other
            near = near & ~(other & ~own_b)
        else:
            ring = far ^ near
        vals = sub8[ring]
        if vals.size:
            vals.sort()
            n = vals.size
            b = float(vals[n // 2]) if n % 2 else (float(vals[n // 2 - 1]) + float(vals[n // 2])) / 2
        else:
            b = float(sub8[own_b].min()) - 1
        yield i, x0, y0, own_b, near, sub8, b


def _weight_sums(gray: np.ndarray, regions: Regions, index, margin: int) -> list:
    """``(i, x0, y0, m00, m10, m01)`` of each region's weights (:func:`region_weights`), without the arrays
    :func:`light_terms` needs: a whole-level background ``b`` (most) by one saturating ``cv2.subtract`` on
    the grown mask (uint8 weights); the sums are the same integers either way."""
    out = []
    for i, x0, y0, own_b, near, sub8, b in _near_and_background(gray, regions, index, margin):
        if b == int(b) and b >= 0 and min(sub8.shape) > 4:   # (cv2 takes a tiny array for a scalar, and
            # an (n, 2) float array for points: patches are at least 13 px a side but at a crop's edge)
            wgt = cv2.subtract(sub8, int(b), mask=near.view(np.uint8))
        else:
            wgt = np.maximum(np.subtract(sub8, b, dtype=np.float32), np.float32(0))
            wgt *= near
        m = _image_moments(wgt)
        out.append((i, x0, y0, m["m00"], m["m10"], m["m01"]))
    return out


def weighted_centroids(gray: np.ndarray, regions: Regions, index=None, margin: int = 2,
                       symmetric_border: bool = False, patches: list | None = None) -> np.ndarray:
    """Intensity-weighted centres of regions, above the local background.

    For each region the mask is grown by ``margin`` pixels (to take in the
    anti-aliased rim below the threshold), pixels of other regions are
    excluded, the background ``b`` is the median of a 2-pixel ring outside
    the grown mask, and the centre is ``sum w (u, v) / sum w`` with
    ``w = max(I - b, 0)``. Unbiased for a uniform local background, and far
    more precise than the binary centre (which moves by whole pixels).
    The weights are multiples of 1/2: their sums (``cv2.moments``) are exact,
    whatever the order of summation.

    With ``symmetric_border`` (the multi-view identification's choice) a
    region touching the image border is measured from the part of it
    symmetric about its centre (:func:`_symmetric_in_image`): the profile
    cut off by the border no longer pulls the centre inwards. (Off by
    default: the per-camera chain never uses such a region, and its results
    stay as they were.)

    A marker lit unevenly pulls its weighted centre towards its bright side
    (:func:`light_terms` measures the light; the multi-view identification
    corrects it with the light pooled over the marker's track).

    Parameters
    ----------
    gray : (h, w) gray image of the labelled area (same crop as ``regions.labels``)
    regions : Regions
    index : indices into ``regions`` (default all)
    patches : list, optional
        ``region_weights(gray, regions, index, margin)``, when
        :func:`light_terms` takes them too (the weights made once).

    Returns
    -------
    (K, 2) centres ``(u, v)`` in full-image pixels.
    """
    u0, v0 = regions.origin
    wts = None                                         # the weight arrays, when the border needs them
    if patches is None and not (symmetric_border and _any_cut(regions, index)):
        rows = _weight_sums(gray, regions, index, margin)
    else:
        wts = patches if patches is not None else region_weights(gray, regions, index, margin)
        rows = [(r.i, r.x0, r.y0, r.moments["m00"], r.moments["m10"], r.moments["m01"]) for r in wts]
    out = np.empty((len(rows), 2))
    for k, (i, x0, y0, s, m10, m01) in enumerate(rows):
        if s <= 0:
            out[k] = regions.centroid[i]
            continue
        ou, ov = x0 + u0, y0 + v0                      # the sums in full-image pixels, exact
        out[k] = ((m10 + ou * s) / s, (m01 + ov * s) / s)
        if wts is not None and symmetric_border and any(wts[k].cut):
            hh, ww = wts[k].weight.shape
            out[k] = _symmetric_in_image(wts[k].weight, np.arange(ou, ou + ww), np.arange(ov, ov + hh), out[k],
                                           wts[k].cut, regions.image_size)
    return out


def _any_cut(regions: Regions, index) -> bool:
    """Whether any region of ``index`` (default all) touches the image border."""
    bbox = regions.bbox if index is None else regions.bbox[np.atleast_1d(np.asarray(index, dtype=np.intp))]
    return any(boxes_touch_border(bbox.tolist(), *regions.image_size))


def light_terms(gray: np.ndarray, regions: Regions, index=None, margin: int = 2, min_inner: int = 5,
                patches: list | None = None):
    """The light across each region and the second moments of its weights.

    A marker lit unevenly has brightness ``H (1 + s . (p - p0))`` across it
    (``s`` the relative slope, 1/px); its weighted centre
    (:func:`weighted_centroids`) then lies ``S s`` from the disc's centre,
    ``S`` the weights' second central moments (px^2): ``|s| r^2 / 4`` for a
    disc of radius ``r``, 0.1-0.15 px on 1080p markers. The pixels one
    pixel inside the thresholded region are (nearly) fully covered: the
    plane ``a + g . (p - p0)`` fitted to their heights above the background
    gives ``s = g / a``. One frame's slope is noisy (a few pixels, the
    sensor's noise); pooled over a marker's track it is precise
    (:func:`~horsemocap.detection.candidates.correct_light`).

    The moments and the plane's normal equations come from ``cv2.moments``
    (of the weights, of the interior pixels and of their heights); the plane
    is solved in the pixels' offsets from the weighted centre (a region whose
    interior pixels lie on one line, a rank-deficient fit: least squares, the
    minimum-norm solution).

    ``patches``: as for :func:`weighted_centroids`.

    Returns
    -------
    slope : (K, 2)
        ``s`` per region, NaN with fewer than ``min_inner`` interior pixels or
        for a region touching the image border (its interior is one-sided).
    moments : (K, 2, 2)
        ``S`` per region.
    """
    wts = patches if patches is not None else region_weights(gray, regions, index, margin)
    slope = np.full((len(wts), 2), np.nan)
    moments = np.full((len(wts), 2, 2), np.nan)
    for k, r in enumerate(wts):
        m = r.moments
        s = m["m00"]
        if s <= 0:
            continue
        mu20, mu11, mu02 = _central_moments(m)
        suv = mu11 / s
        moments[k] = ((mu20 / s, suv), (suv, mu02 / s))
        if any(r.cut):
            continue
        inner = cv2.erode(r.own, _K3, borderType=cv2.BORDER_CONSTANT, borderValue=0)
        mi = cv2.moments(inner, binaryImage=True)
        n = int(mi["m00"])
        if n < min_inner:
            continue
        cu, cv = m["m10"] / s, m["m01"] / s
        sol = _plane(mi, _image_moments(r.above * inner), cu, cv)
        if sol is None:                                 # interior on one line: least squares (minimum norm)
            iy, ix = np.nonzero(inner)
            A = np.column_stack([np.ones(n), ix - cu, iy - cv])
            sol = np.linalg.lstsq(A, r.above[iy, ix], rcond=None)[0]
        a, gu, gv = sol
        if a > 0:
            slope[k] = (gu / a, gv / a)
    return slope, moments


def _central_moments(m: dict):
    """``(mu20, mu11, mu02)`` from the raw moments of ``cv2.moments`` (exact sums), by ``cv::Moments``'
    formula: the same numbers whether OpenCV computed its central moments itself or by IPP (which rounds
    differently)."""
    inv = 1.0 / m["m00"]
    cx, cy = m["m10"] * inv, m["m01"] * inv
    return m["m20"] - m["m10"] * cx, m["m11"] - m["m10"] * cy, m["m02"] - m["m01"] * cy


def _plane(mi: dict, mz: dict, cu: float, cv: float):
    """``(a, gu, gv)`` of the plane ``a + gu (x - cu) + gv (y - cv)`` fitted to heights ``z`` at pixels.

    ``mi``: ``cv2.moments`` of the pixels (binary), ``mz``: of their heights.
    None when the pixels lie on one line (exact: their integer moments).
    """
    n, sx, sy = int(mi["m00"]), int(mi["m10"]), int(mi["m01"])
    sxx, sxy, syy = int(mi["m20"]), int(mi["m11"]), int(mi["m02"])
    if (n * sxx - sx * sx) * (n * syy - sy * sy) - (n * sxy - sx * sy) ** 2 == 0:   # Python ints: exact
        return None
    # the normal equations in offsets from (cu, cv)
    ex, ey = sx - n * cu, sy - n * cv
    exx = sxx - 2 * cu * sx + n * cu * cu
    eyy = syy - 2 * cv * sy + n * cv * cv
    exy = sxy - cu * sy - cv * sx + n * cu * cv
    z = mz["m00"]
    bz, bx, by = z, mz["m10"] - cu * z, mz["m01"] - cv * z
    # Cramer's rule on the symmetric 3 x 3 system (cofactors), in Python floats
    c00, c01, c02 = exx * eyy - exy * exy, ey * exy - ex * eyy, ex * exy - ey * exx
    c11, c12, c22 = n * eyy - ey * ey, ex * ey - n * exy, n * exx - ex * ex
    det = n * c00 + ex * c01 + ey * c02
    return ((c00 * bz + c01 * bx + c02 * by) / det, (c01 * bz + c11 * bx + c12 * by) / det,
            (c02 * bz + c12 * bx + c22 * by) / det)


def _symmetric_in_image(wgt, cols, rows, centre, cut, size, iterations: int = 5):
    """Centre of a region cut by the image border, from the part symmetric about it.

    The image edge (``-0.5`` or ``W - 0.5``) cuts off one side of the
    marker's profile (its blurred rim, or more), which pulls the weighted
    centre inwards. Mirrored about the centre, the edge also cuts the other
    side: the weights beyond the mirrored edge are left out, and the centre
    of what remains, a profile cut symmetrically, is the marker's own. Per
    axis, on the weights summed over the other axis (a cut along ``u`` keeps
    the ``v`` profile symmetric); a few fixed-point iterations from the
    plain weighted centre. ``cut``: (left, right, top, bottom) edges the
    region touches.
    """
    W, H = size
    cu = _symmetric_1d(wgt.sum(axis=0), cols, centre[0], cut[0], cut[1], W, iterations)
    cv = _symmetric_1d(wgt.sum(axis=1), rows, centre[1], cut[2], cut[3], H, iterations)
    return cu, cv


def _symmetric_1d(p, x, c, cut_low, cut_high, n, iterations):
    """1-D centre of profile ``p`` at pixels ``x``, cut by the image edge(s) and mirrored (see above).

    The pixel straddling the mirrored edge counts by the part of it inside,
    the profile taken linear across that pixel (its slope from its
    neighbours), so that the centre moves smoothly with the edge.
    """
    if not (cut_low or cut_high):
        return c
    p = np.asarray(p, float)
    slope = np.gradient(p) if len(p) > 1 else np.zeros_like(p)
    for _ in range(iterations):
        lo = 2 * c - (n - 0.5) if cut_high else -np.inf      # window [lo, hi]
        hi = 2 * c + 0.5 if cut_low else np.inf
        t0 = np.clip(lo - x, -0.5, 0.5)                     # the part of each pixel inside, about its centre
        t1 = np.clip(hi - x, -0.5, 0.5)
        t1 = np.maximum(t1, t0)
        mass = p * (t1 - t0) + slope * (t1 ** 2 - t0 ** 2) / 2
        moment = x * mass + p * (t1 ** 2 - t0 ** 2) / 2 + slope * (t1 ** 3 - t0 ** 3) / 3
        s = mass.sum()
        if not s > 0:
            break
        c = moment.sum() / s
    return float(c)


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
    u0, v0, u1, v1 = clip_crop(crop, W, H)
    return _candidates_in(gray[v0:v1, u0:u1], (u0, v0), (W, H), threshold, area_range,
                          min_circularity, connectivity)


def clip_crop(crop, W, H):
    """A crop rectangle clipped to a ``W`` x ``H`` image.

    Parameters
    ----------
    crop : sequence of 4 numbers or None
        ``(u0, v0, u1, v1)`` in pixels, ``u1``/``v1`` exclusive; None for the whole image.
    W, H : int
        The image's width and height.

    Returns
    -------
    tuple of int
        ``(u0, v0, u1, v1)`` inside the image; ``(0, 0, 0, 0)`` when the crop misses it.
    """
    if crop is None:
        return 0, 0, W, H
    u0, v0 = max(int(crop[0]), 0), max(int(crop[1]), 0)
    u1, v1 = min(int(crop[2]), W), min(int(crop[3]), H)
    if u1 <= u0 or v1 <= v0:
        return 0, 0, 0, 0
    return u0, v0, u1, v1


#: Up to this many labelled regions :func:`_candidates_in` filters them in Python (:func:`_kept`).
KEEP_IN_PYTHON = 48


def _kept(regions: Regions, area_range, crop, size) -> list:
    """Indices of the regions in ``area_range`` not cut by an edge of ``crop`` that is not an image edge
    (the filters of :func:`_candidates_in`, region by region in Python integers: the same test)."""
    amin, amax = area_range
    u0, v0, u1, v1 = crop
    W, H = size
    lo_u, lo_v = (u0 if u0 > 0 else -1), (v0 if v0 > 0 else -1)
    hi_u, hi_v = (u1 if u1 < W else np.inf), (v1 if v1 < H else np.inf)
    return [i for i, ((x, y, w, h), a) in enumerate(zip(regions.bbox.tolist(), regions.area.tolist()))
            if amin <= a <= amax and x > lo_u and y > lo_v and x + w < hi_u and y + h < hi_v]


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
    if len(regions) <= KEEP_IN_PYTHON:
        keep = np.array(_kept(regions, area_range, (u0, v0, u1, v1), (W, H)), np.intp)
    else:
        ok = filter_area(regions.area, area_range[0], area_range[1])
        b = regions.bbox              # regions cut by a crop edge that is not an image edge
        if u0 > 0:
            ok &= b[:, 0] > u0
        if v0 > 0:
            ok &= b[:, 1] > v0
        if u1 < W:
            ok &= b[:, 0] + b[:, 2] < u1
        if v1 < H:
            ok &= b[:, 1] + b[:, 3] < v1
        keep = np.flatnonzero(ok)
    if min_circularity is not None and len(keep):
        circ = region_circularity(regions.subset(keep))
        keep = keep[circ >= min_circularity]
    return regions, keep


# --------------------------------------------------------------------------
# Figure 4.15: every stage of the chain on one frame
# --------------------------------------------------------------------------

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
