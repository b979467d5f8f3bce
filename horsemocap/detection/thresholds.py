"""Gray and binary images (thesis 4.3): eq. (4.4), eq. (4.5) and automatic levels.

:func:`to_gray` (eq. 4.4), :func:`binarize` (the global threshold ``l``,
eq. 4.5), Otsu's threshold (:func:`otsu_threshold`), the three-class Otsu of
seed 000 section 5.2.1 (:func:`otsu3_thresholds`) and :func:`auto_threshold`
over frames sampled across the motion (Appendix A step 4.a.i).
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = [
    "GRAY_WEIGHTS",
    "to_gray",
    "binarize",
    "otsu_threshold",
    "otsu3_thresholds",
    "auto_threshold",
    "label_bright",
    "connected_components",
    "bright_crops",
]


#: Gray weights of eq. (4.4) (MATLAB ``rgb2gray``).
GRAY_WEIGHTS = (0.2989, 0.5870, 0.1140)


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
    ``l1 < I <= l2``, ``I > l2`` by exhaustive search over every pair
    ``l1 < l2`` at once (the first best ``l1``, then its first best ``l2``,
    on ties). The bright class ``I > l2`` holds the markers.

    Examples
    --------
    Three separated grey levels, 1000 pixels each: the levels fall in the middle of the two gaps.

    >>> import numpy as np
    >>> hist = np.zeros(256)
    >>> hist[[20, 120, 240]] = 1000
    >>> otsu3_thresholds(hist)
    (69, 179)
    """
    a = np.asarray(gray_or_hist)
    hist = a.astype(float) if (a.ndim == 1 and a.size == 256) else _histogram([a])
    p = hist / hist.sum()
    k = np.arange(256)
    P = np.concatenate([[0.0], np.cumsum(p)])          # P[i] = sum p[:i]
    S = np.concatenate([[0.0], np.cumsum(p * k)])
    # class sums for [a, b) : P[b]-P[a]; rows l1 = 0..253, columns l2 = 1..254
    t1 = np.arange(0, 254)
    t2 = np.arange(1, 255)
    w0, s0 = P[t1 + 1], S[t1 + 1]
    w1, s1 = P[t2 + 1][None, :] - w0[:, None], S[t2 + 1][None, :] - s0[:, None]
    w2, s2 = 1.0 - P[t2 + 1], S[-1] - S[t2 + 1]
    dark = [s0[i] ** 2 / w0[i] if w0[i] > 0 else 0.0 for i in range(t1.size)]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(w1 > 0, s1 ** 2 / w1, 0) + np.where(w2 > 0, s2 ** 2 / w2, 0)[None, :]
    v = v + np.array(dark)[:, None]
    v[t2[None, :] <= t1[:, None]] = -np.inf           # l2 > l1 only
    columns = np.argmax(v, axis=1)
    best, arg = -1.0, (0, 1)
    for row, col in enumerate(columns.tolist()):
        if v[row, col] > best:
            best, arg = float(v[row, col]), (row, int(t2[col]))
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
# labelling a sparse bright image in crops (the whole-frame search)
# --------------------------------------------------------------------------
def connected_components(binary: np.ndarray, connectivity: int = 8):
    """``cv2.connectedComponentsWithStats`` (int32 labels) of ``binary``: ``(n, labels, stats, centroids)``.

    8-connected regions are labelled by Grana's block-based algorithm
    (``cv2.CCL_BBDT``), which scans the image by 2 x 2 blocks as OpenCV's
    default does and gives the same labels, stats and centres
    (``tests/test_speed.py``), but in OpenCV 5.0 the default call with int32
    labels takes a slower path. 4-connected regions: OpenCV's default.
    """
    if connectivity == 8:
        return cv2.connectedComponentsWithStatsWithAlgorithm(binary, 8, cv2.CV_32S, cv2.CCL_BBDT)
    return cv2.connectedComponentsWithStats(binary, connectivity=connectivity, ltype=cv2.CV_32S)


#: Block size (px) of the decimated image in which :func:`label_bright` looks for bright pixels.
BRIGHT_BLOCK = 8
#: Pixels labelled around each group of bright blocks: more than a weighted centre looks
#: beyond its region (6 px, plus 1 for the other regions' dilation).
BRIGHT_PAD = 10
#: Above this fraction of the image in crops, the whole image is labelled at once.
BRIGHT_MAX_FRACTION = 0.5


def _bright_boxes(binary: np.ndarray, block: int, pad: int) -> list:
    """Disjoint crops ``(u0, v0, u1, v1)`` that hold every white region of ``binary`` whole, with ``pad`` around."""
    H, W = binary.shape
    Hb, Wb = -(-H // block), -(-W // block)
    b = binary if (Hb * block, Wb * block) == (H, W) else \
        cv2.copyMakeBorder(binary, 0, Hb * block - H, 0, Wb * block - W, cv2.BORDER_CONSTANT, value=0)
    if block == 8:      # the 8 bytes of a block's row as one 64-bit word: nonzero in any of the block's 8 rows
        small = np.ascontiguousarray(b).view(np.uint64).reshape(Hb, 8, Wb).max(axis=1) != 0
    else:
        small = cv2.resize(b, (Wb, Hb), interpolation=cv2.INTER_AREA) > 0   # a block's mean: > 0 iff a white pixel
    n, _, st, _ = connected_components(small.view(np.uint8))
    boxes = [[max(x * block - pad, 0), max(y * block - pad, 0), min((x + w) * block + pad, W),
              min((y + h) * block + pad, H)] for x, y, w, h in st[1:, :4].tolist()]
    merged = True
    while merged and len(boxes) > 1:                  # overlapping crops become one
        merged = False
        out = []
        for bx in boxes:
            for o in out:
                if bx[0] < o[2] and o[0] < bx[2] and bx[1] < o[3] and o[1] < bx[3]:
                    o[0], o[1], o[2], o[3] = min(o[0], bx[0]), min(o[1], bx[1]), max(o[2], bx[2]), max(o[3], bx[3])
                    merged = True
                    break
            else:
                out.append(bx)
        boxes = out
    return boxes


def bright_crops(gray: np.ndarray, threshold: int, block: int = BRIGHT_BLOCK, pad: int = BRIGHT_PAD):
    """``gray > threshold`` (0/255) and the disjoint crops ``[u0, v0, u1, v1]`` that hold its white regions whole.

    The crops of :func:`label_bright` (``pad`` pixels around each group of
    ``block`` x ``block`` blocks holding a white pixel, overlapping crops
    merged); a single crop of the whole image when they would cover more than
    :data:`BRIGHT_MAX_FRACTION` of it; none for an image without white pixels.
    """
    binary = cv2.threshold(gray, int(threshold), 255, cv2.THRESH_BINARY)[1]
    H, W = binary.shape
    boxes = _bright_boxes(binary, block, pad)
    if sum((b[2] - b[0]) * (b[3] - b[1]) for b in boxes) > BRIGHT_MAX_FRACTION * H * W:
        boxes = [[0, 0, W, H]]
    return binary, boxes


def region_order_key(labels: np.ndarray, label: int, top: int, left: int, width: int, origin, image_width: int) -> int:
    """Rank of a region in OpenCV's labelling of the whole image (smaller: labelled first).

    OpenCV scans the image by 2 x 2 blocks; a region's number follows the
    first block it reaches: its first pair of rows (from its top row), then
    its first pair of columns within that pair of rows. ``labels`` is the
    labelling of a crop at ``origin`` (full-image pixels) holding the region
    ``label`` whole; ``top``, ``left``, ``width``: its box in full-image pixels.
    """
    u0, v0 = origin
    r0 = max((top // 2) * 2 - v0, 0)
    x = left - u0
    first = int(np.argmax((labels[r0:r0 + 2, x:x + width] == label).any(axis=0)))   # the region is there
    return (top // 2) * (image_width + 2) + (first + left) // 2


def label_bright(gray: np.ndarray, threshold: int, block: int = BRIGHT_BLOCK, pad: int = BRIGHT_PAD):
    """``cv2.connectedComponentsWithStats`` (8-connected, int32 labels) of ``gray > threshold``, in crops.

    The same ``(n, labels, stats, centroids)`` for the whole image, found by
    labelling only crops around the bright pixels: the thresholded image
    reduced by ``block`` marks the blocks holding a bright pixel; each group of
    such blocks (8-connected, so a region never spans two groups), grown by
    ``pad`` pixels (crops that overlap merged), is labelled alone, and the
    labels are renumbered in the order OpenCV's labelling of the whole image
    gives them (its 2 x 2-block scan: by the first pixel pair of rows, then
    pixel pair of columns, that a region reaches). An image of sparse bright
    spots (an empty arena: glints, a lamp) costs a fraction of labelling it
    whole; when the crops would cover more than :data:`BRIGHT_MAX_FRACTION`
    of the image, the whole image is labelled at once. Row 0 (the
    background) has OpenCV's area and box, and no centre (NaN).
    """
    binary, boxes = bright_crops(gray, threshold, block, pad)
    H, W = binary.shape
    if len(boxes) == 1 and boxes[0] == [0, 0, W, H]:
        return connected_components(binary)
    labels = np.zeros((H, W), np.int32)
    parts, keys = [], []
    for u0, v0, u1, v1 in boxes:
        n, lab, st, ce = connected_components(binary[v0:v1, u0:u1])
        if n <= 1:
            continue
        st = st[1:].astype(np.int64)
        area = st[:, 4]
        # OpenCV's centre is (sum of coordinates) / area; the sums are integers, recovered exactly
        sums = np.rint(ce[1:] * area[:, None]) + np.array([u0, v0]) * area[:, None]
        # labelling order of the whole image: the first pair of rows a region reaches (from its top
        # row), then the first pair of columns it reaches within that pair of rows
        key = np.array([region_order_key(lab, i + 1, int(st[i, 1]) + v0, int(st[i, 0]) + u0, int(st[i, 2]),
                                         (u0, v0), W) for i in range(n - 1)], np.int64)
        st[:, 0] += u0
        st[:, 1] += v0
        parts.append((u0, v0, u1, v1, lab, st, sums, n))
        keys.append(key)
    if not parts:
        stats = np.array([[0, 0, W, H, H * W]], np.int32)
        return 1, labels, stats, np.array([[(W - 1) / 2.0, (H - 1) / 2.0]])
    key = np.concatenate(keys)
    new = np.empty(len(key), np.int32)
    new[np.argsort(key, kind="stable")] = np.arange(1, len(key) + 1, dtype=np.int32)
    stats = np.empty((len(key) + 1, 5), np.int64)
    cents = np.empty((len(key) + 1, 2))
    at = 0
    for u0, v0, u1, v1, lab, st, sums, n in parts:
        ids = new[at:at + n - 1]
        if n == 2:
            np.multiply(lab, ids[0], out=labels[v0:v1, u0:u1])   # the crops are disjoint: no mask needed
        else:
            labels[v0:v1, u0:u1] = np.concatenate([[0], ids]).astype(np.int32)[lab]
        stats[ids] = st
        cents[ids] = sums / st[:, 4:5]
        at += n - 1
    stats[0] = (0, 0, W, H, H * W - int(stats[1:, 4].sum()))
    cents[0] = np.nan                                   # the background's centre is never used
    return len(key) + 1, labels, stats.astype(np.int32), cents
