"""Markers of an interlaced camera measured in each field.

An interlaced frame (PAL DV: 720 x 576, 25 frames of two fields) holds two
pictures: the rows of one parity exposed half a frame after the others. A
marker moving between the fields is a combed blob, its rows alternately at
two positions. The multi-view identification follows the markers in frames
whose fields are blended (:func:`horsemocap.sources.fields_blended`: one
blob again); here each identified marker is then measured in each field on
its own (:func:`marker_in_fields`): around the marker, each field's rows
filled in (:func:`field_window`) and thresholded, and of the blobs found the
pair (one per field) that straddles the marker's blended centre is kept,
each blob's intensity-weighted centre above the local background
(:func:`~horsemocap.detection.weighted_centroids`). A field's blob is one
disc smeared over that field's exposure, not the streak of two overlapping
discs the blended frame shows. A marker the two fields do not show as such
a pair keeps its blended centre, with the reason recorded
(:data:`FIELD_NOT_FOUND`, :data:`FIELDS_DISAGREE`).

A field holds every other row, so a marker's vertical centre in one field
errs periodically with its row (a period of two rows), with opposite signs
in the two fields; the errors cancel in the fields' mean only when the
marker has not moved vertically between them. :func:`row_aliasing` fits
that error over a camera's whole record from the two fields' differences,
:func:`corrected_mean` removes it and averages the fields
(:func:`remeasure_by_fields` does all three). The mean is the marker
half-way between the two fields' instants, the instant
:func:`horsemocap.subframe.observation_instants` gives a centroid of an
interlaced camera, so the times stay as they are.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..sources import field_image
from .filters import find_candidates, weighted_centroids

#: Reason of a centroid kept from the blended frame: a field shows no blob near it (or it lies outside the frame).
FIELD_NOT_FOUND = "field_not_found"
#: Reason of a centroid kept from the blended frame: the two fields' blobs do not straddle the blended centre
#: (e.g. the marker is missing from one field and another light is near it there).
FIELDS_DISAGREE = "fields_disagree"

#: Half-width (px) of the first window searched around a marker; it grows until it holds the marker's two
#: field blobs whole, so it only needs to be small.
FIRST_HALF_WINDOW = 8
#: Pixels a blob's weighted centre uses around its region (:func:`weighted_centroids`: a 2-pixel rim and a
#: 2-pixel background ring).
CENTROID_RIM = 4
#: The fields' mean may lie this share of the field blobs' equivalent radius (or one pixel, if more) from the
#: blended centre: the two measure the same light and differ by the threshold's cut of the blended streak; a
#: wrong pair (another light in one field) is off by half the distance between two separate blobs, at least
#: half a radius.
CONSISTENCY_OF_RADIUS = 0.25
#: A fit of the vertical sampling error needs this many marker-frames: its coefficients' standard error is
#: about the fields' vertical scatter times sqrt(2 / n), a third of that scatter at 20.
ROW_ALIASING_MIN_SAMPLES = 20
#: Samples further than this many robust standard deviations (1.4826 MAD) from the fit's median residual are
#: not fitted (a normal sample has 1 in 2000 beyond it): a marker mismeasured in one field does not bend the fit.
ROW_ALIASING_OUTLIER_SDS = 3.5
#: Refits (each with the motion regressor taken from the previous fit's corrected mean) until the coefficients
#: move less than :data:`ROW_ALIASING_TOLERANCE_PX`, at most this many.
ROW_ALIASING_MAX_FITS = 20
ROW_ALIASING_TOLERANCE_PX = 1e-6


def field_window(frame: np.ndarray, parity: int, rows=None, cols=None) -> np.ndarray:
    """One field of an interlaced gray frame, in a window, as uint8: :func:`horsemocap.sources.field_image`
    rounded, computed from the window's rows and one row either side only.

    Parameters
    ----------
    frame : (h, w) uint8
        The interlaced frame as recorded.
    parity : {0, 1}
        The field: rows ``r % 2 == parity`` stay, the others are interpolated.
    rows, cols : (start, stop), optional
        The window (frame pixels, stop exclusive); default the whole frame.

    Returns
    -------
    (stop - start rows, stop - start cols) uint8
        Exactly ``field_image(frame, parity)[rows, cols]``, rounded.

    Examples
    --------
    >>> f = np.array([[0], [10], [200], [30], [0]], np.uint8)
    >>> field_window(f, 0)[:, 0].tolist()
    [0, 100, 200, 100, 0]
    >>> field_window(f, 0, rows=(1, 2))[:, 0].tolist()
    [100]
    """
    frame = np.asarray(frame)
    if frame.ndim != 2:
        raise ValueError(f"field_window: expected a gray frame (h, w), got shape {frame.shape}")
    if parity not in (0, 1):
        raise ValueError(f"field_window: parity must be 0 or 1, got {parity!r}")
    height, width = frame.shape
    if height < 2:
        raise ValueError(f"field_window: a frame of {height} row(s) has no two fields")
    r0, r1 = (0, height) if rows is None else (max(0, int(rows[0])), min(height, int(rows[1])))
    c0, c1 = (0, width) if cols is None else (max(0, int(cols[0])), min(width, int(cols[1])))
    if r1 <= r0 or c1 <= c0:
        raise ValueError(f"field_window: the window rows {rows}, columns {cols} misses the {width}x{height} frame")
    s0, s1 = max(0, r0 - 1), min(height, r1 + 1)          # the interpolated rows' neighbours (2 rows or more)
    slab = field_image(frame[s0:s1, c0:c1], (parity - s0) % 2)
    return np.clip(np.rint(slab[r0 - s0:r1 - s0]), 0, 255).astype(np.uint8)


def _window(centre, half: int, shape) -> tuple:
    """Rows and columns ``centre +- half`` clipped to a frame of ``shape``."""
    u, v = centre
    return ((max(0, v - half), min(shape[0], v + half + 1)), (max(0, u - half), min(shape[1], u + half + 1)))


def _touches_cut(bbox, rows, cols, shape) -> bool:
    """Does a region's ``(u0, v0, width, height)`` (window pixels) touch a window edge that is not a frame edge?"""
    u0, v0, w, h = (int(x) for x in bbox)
    return ((u0 == 0 and cols[0] > 0) or (v0 == 0 and rows[0] > 0)
            or (u0 + w == cols[1] - cols[0] and cols[1] < shape[1])
            or (v0 + h == rows[1] - rows[0] and rows[1] < shape[0]))


def _field_blobs(field, threshold, rows, cols, shape):
    """One field window's blobs: weighted centres (frame px), areas, bounding boxes ``(u0, v0, w, h)`` (frame
    px) and whether a window edge that is not a frame edge cuts them."""
    regions, _ = find_candidates(field, int(threshold))
    index = np.arange(len(regions))
    centres = weighted_centroids(field, regions, index) + (cols[0], rows[0]) if len(index) else np.empty((0, 2))
    cut = np.array([_touches_cut(b, rows, cols, shape) for b in regions.bbox], bool)
    boxes = np.asarray(regions.bbox, int).reshape(-1, 4) + (cols[0], rows[0], 0, 0)
    return centres, np.asarray(regions.area, float), boxes, cut


def _held(boxes, shape) -> tuple:
    """The rows and columns a window needs to hold ``boxes`` with the rim their centres use (clipped)."""
    u0, v0 = boxes[:, 0].min() - CENTROID_RIM, boxes[:, 1].min() - CENTROID_RIM
    u1 = (boxes[:, 0] + boxes[:, 2]).max() + CENTROID_RIM
    v1 = (boxes[:, 1] + boxes[:, 3]).max() + CENTROID_RIM
    return (max(0, int(v0)), min(shape[0], int(v1))), (max(0, int(u0)), min(shape[1], int(u1)))


def _pair_in_window(frame, position, centre, threshold):
    """The pair of field blobs (one per field) whose mean is nearest ``position``, measured in a window grown
    until neither blob is cut and both, with their centres' rim, lie inside it. Returns ``(centres (2, 2),
    areas (2,))`` or None when a field shows no blob near the marker."""
    half = FIRST_HALF_WINDOW
    while True:
        rows, cols = _window(centre, half, frame.shape)
        blobs = [_field_blobs(field_window(frame, p, rows, cols), threshold, rows, cols, frame.shape)
                 for p in (0, 1)]
        if not len(blobs[0][0]) or not len(blobs[1][0]):
            return None
        means = 0.5 * (blobs[0][0][:, None, :] + blobs[1][0][None, :, :])
        i, j = np.unravel_index(int(np.argmin(np.linalg.norm(means - position, axis=2))), means.shape[:2])
        if blobs[0][3][i] or blobs[1][3][j]:
            half *= 2
            continue
        need_rows, need_cols = _held(np.stack([blobs[0][2][i], blobs[1][2][j]]), frame.shape)
        if need_rows[0] < rows[0] or need_rows[1] > rows[1] or need_cols[0] < cols[0] or need_cols[1] > cols[1]:
            half = max(half, centre[0] - need_cols[0], need_cols[1] - 1 - centre[0], centre[1] - need_rows[0],
                       need_rows[1] - 1 - centre[1])
            continue
        return np.stack([blobs[0][0][i], blobs[1][0][j]]), np.array([blobs[0][1][i], blobs[1][1][j]])


def marker_in_fields(frame: np.ndarray, position, threshold: int):
    """One marker of an interlaced gray frame measured in each of its two fields.

    Around ``position`` (the marker's centre in the blended frame) each
    field's rows are filled in (:func:`field_window`) and thresholded; of
    every pair of blobs, one per field, the one whose mean is nearest
    ``position`` is taken, in a window grown until it holds both blobs
    whole (it follows the blob's size and its smear). The pair is kept when
    the two straddle ``position`` as one marker's two fields do: their mean
    within :data:`CONSISTENCY_OF_RADIUS` of the blobs' equivalent radius (at
    least 1 px) of ``position``, and the two no further apart than their
    equivalent radii plus 2 px (further, the blobs do not touch: the blended
    frame shows two, and its centre is not their mean).

    Parameters
    ----------
    frame : (h, w) uint8
        The interlaced frame as recorded (its fields not blended).
    position : (2,)
        ``(u, v)``: the marker's centre in the blended frame (px).
    threshold : int
        Gray level of the marker regions (the identification's).

    Returns
    -------
    per_field : (2, 2) ndarray
        ``(u, v)`` of the marker in the field of parity 0, then 1 (frame px);
        NaN when not measured.
    reason : str
        ``""``, :data:`FIELD_NOT_FOUND` or :data:`FIELDS_DISAGREE`.

    Examples
    --------
    A marker 4 px further right in the top field (parity 0) than in the
    bottom one:

    >>> yy, xx = np.mgrid[0:40, 0:60]
    >>> disc = lambda u, v: 200.0 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 2.0 ** 2))
    >>> frame = np.where(yy % 2 == 1, disc(28.0, 20.0), disc(32.0, 20.0)).round().astype(np.uint8)
    >>> per_field, reason = marker_in_fields(frame, (30, 20), 60)
    >>> np.round(per_field, 1).tolist(), reason
    ([[32.0, 20.0], [28.0, 20.0]], '')
    >>> marker_in_fields(frame, (5, 35), 60)[1]
    'field_not_found'
    """
    frame = np.asarray(frame)
    nowhere = np.full((2, 2), np.nan)
    position = np.asarray(position, float)
    centre = tuple(int(round(float(c))) for c in position)
    if not (0 <= centre[0] < frame.shape[1] and 0 <= centre[1] < frame.shape[0]):
        return nowhere, FIELD_NOT_FOUND
    pair = _pair_in_window(frame, position, centre, threshold)
    if pair is None:
        return nowhere, FIELD_NOT_FOUND
    centres, areas = pair
    radii = np.sqrt(areas / np.pi)
    tolerance = max(1.0, CONSISTENCY_OF_RADIUS * radii.mean())
    if (np.linalg.norm(centres.mean(axis=0) - position) > tolerance
            or np.linalg.norm(centres[0] - centres[1]) > radii.sum() + 2.0):
        return nowhere, FIELDS_DISAGREE
    return centres, ""


def field_centroids(frame: np.ndarray, positions, threshold: int):
    """Markers of one interlaced frame measured in each field (:func:`marker_in_fields`); their mean.

    Parameters
    ----------
    frame : (h, w) uint8
        The frame as recorded.
    positions : (m, 2)
        The markers' centres in the blended frame (NaN: not seen; stays NaN).
    threshold : int

    Returns
    -------
    centres : (m, 2)
        The mean of the two fields' centres; where they were not measured,
        the given position.
    per_field : (2, m, 2)
        Each field's centre (parity 0, then 1), NaN where not measured.
    reason : (m,) str
        Why a seen marker was not measured (``""`` where it was, or not seen).

    Examples
    --------
    >>> yy, xx = np.mgrid[0:40, 0:60]
    >>> disc = lambda u, v: 200.0 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 2.0 ** 2))
    >>> frame = np.where(yy % 2 == 1, disc(28.0, 20.0), disc(32.0, 20.0)).round().astype(np.uint8)
    >>> centres, per_field, reason = field_centroids(frame, [[30.0, 20.0], [np.nan, np.nan]], 60)
    >>> np.round(centres[0], 1).tolist(), reason.tolist()
    ([30.0, 20.0], ['', ''])
    """
    positions = np.asarray(positions, float).reshape(-1, 2)
    per_field = np.full((2,) + positions.shape, np.nan)
    reason = np.full(len(positions), "", dtype=object)
    for m in np.flatnonzero(np.all(np.isfinite(positions), axis=1)):
        measured, reason[m] = marker_in_fields(frame, positions[m], threshold)
        per_field[:, m] = measured
    found = np.all(np.isfinite(per_field), axis=(0, 2))
    centres = positions.copy()
    centres[found] = per_field[:, found].mean(axis=0)
    return centres, per_field, reason.astype(str)


def row_aliasing(per_field: np.ndarray, min_samples: int = ROW_ALIASING_MIN_SAMPLES) -> np.ndarray:
    """The vertical sampling error of one interlaced camera's field centres: ``(a, b)`` px.

    A field holds every other row, so a marker's vertical centre in one field
    is sampled at a pitch of two rows; the weighted centre then errs
    periodically with the marker's row, ``E(v) = a cos(pi v) + b sin(pi v)``
    in the field of parity 0 and ``-E(v)`` in that of parity 1 (its rows one
    row further). The two fields' errors cancel in their mean only when
    the marker has not moved vertically between them. The difference of
    the two fields' centres of one frame is the marker's vertical motion
    over half a frame (proportional to its velocity, ``m(k+1) - m(k-1)`` of
    the fields' mean ``m``) plus ``-E(v1) - E(v0)``; a least-squares fit of
    that over every marker and frame of the camera gives ``a`` and ``b``
    (and the motion's factor, so either field order fits). Samples far from
    the fit (:data:`ROW_ALIASING_OUTLIER_SDS`) are left out, and the fit is
    repeated with the motion taken from the corrected mean until it settles
    (:data:`ROW_ALIASING_TOLERANCE_PX`).

    Parameters
    ----------
    per_field : (n, 2, m, 2)
        Each frame's field centres (parity 0, then 1), NaN where not measured.
    min_samples : int
        Fewer marker-frames with both fields and both neighbouring frames: ``(0, 0)``
        (:data:`ROW_ALIASING_MIN_SAMPLES`).

    Returns
    -------
    (2,) ndarray
        ``(a, b)`` px (as fitted: :func:`corrected_mean` refuses an error
        whose removal is ambiguous, ``pi hypot(a, b) >= 1``).

    Examples
    --------
    A marker moving up and down by 3 px over 20 frames, its fields a quarter
    of a frame before and after each frame's middle (parity 1 first),
    sampled with ``a = 0.05``, ``b = -0.12``:

    >>> y = lambda t: 100.0 + 3.0 * np.sin(2 * np.pi * t / 20.0)
    >>> E = lambda v: 0.05 * np.cos(np.pi * v) - 0.12 * np.sin(np.pi * v)
    >>> k = np.arange(200.0)
    >>> per_field = np.zeros((200, 2, 1, 2))
    >>> per_field[:, 0, 0, 1] = y(k + 0.25) + E(y(k + 0.25))
    >>> per_field[:, 1, 0, 1] = y(k - 0.25) - E(y(k - 0.25))
    >>> np.round(row_aliasing(per_field), 2).tolist()
    [0.05, -0.12]
    """
    per_field = np.asarray(per_field, float)
    if per_field.ndim != 4 or per_field.shape[1:2] != (2,) or per_field.shape[3] != 2:
        raise ValueError(f"row_aliasing: per_field must be (frames, 2 fields, markers, 2), got {per_field.shape}")
    v0, v1 = per_field[:, 0, :, 1], per_field[:, 1, :, 1]
    aliasing, used = np.zeros(2), None
    for _ in range(ROW_ALIASING_MAX_FITS):      # the fields' mean, whose motion is a regressor, freed of the error
        mean = corrected_mean(per_field, aliasing)[..., 1]
        motion = np.full_like(mean, np.nan)
        motion[1:-1] = mean[2:] - mean[:-2]
        ok = np.isfinite(v0) & np.isfinite(v1) & np.isfinite(motion)
        if ok.sum() < min_samples:
            return np.zeros(2)
        design = np.column_stack([-(np.cos(np.pi * v0[ok]) + np.cos(np.pi * v1[ok])),
                                  -(np.sin(np.pi * v0[ok]) + np.sin(np.pi * v1[ok])), motion[ok]])
        target = (v1 - v0)[ok]
        used = np.ones(len(target), bool) if used is None or len(used) != len(target) else used
        if used.sum() < min_samples:
            return np.zeros(2)
        fitted = np.linalg.lstsq(design[used], target[used], rcond=None)[0]
        residual = target - design @ fitted
        centre = np.median(residual[used])
        spread = 1.4826 * np.median(np.abs(residual[used] - centre))
        inliers = np.abs(residual - centre) <= max(ROW_ALIASING_OUTLIER_SDS * spread, ROW_ALIASING_TOLERANCE_PX)
        settled = np.abs(fitted[:2] - aliasing).max() < ROW_ALIASING_TOLERANCE_PX and np.array_equal(inliers, used)
        aliasing, used = fitted[:2], inliers
        if settled or not aliasing_removable(aliasing):
            break
    return aliasing


def aliasing_removable(aliasing) -> bool:
    """Is ``v = row + E(row)`` (and ``- E``) one-to-one, so the error ``aliasing = (a, b)`` can be removed?
    True when ``pi hypot(a, b) < 1`` (``E``'s slope, at most ``pi hypot(a, b)``, never cancels the row's).

    Examples
    --------
    >>> aliasing_removable((0.0, -0.13)), aliasing_removable((0.3, 0.2))
    (True, False)
    """
    return bool(np.pi * np.hypot(*(float(c) for c in aliasing)) < 1.0)


def corrected_mean(per_field: np.ndarray, aliasing) -> np.ndarray:
    """The two fields' centres freed of the vertical sampling error ``aliasing = (a, b)``
    (:func:`row_aliasing`) and averaged: (n, m, 2), NaN where a field is NaN.

    Each field's measured row is ``v = row + s E(row)`` (``s`` = +1 for
    parity 0, -1 for parity 1); ``row`` lies within ``hypot(a, b)`` of ``v``
    and the map is increasing (:func:`aliasing_removable`), so bisection of
    that interval finds it to float precision. An error whose removal is
    ambiguous is refused (ValueError).

    Examples
    --------
    >>> per_field = np.array([[[[10.0, 20.0 + 0.1]], [[12.0, 20.0 - 0.1]]]])     # E(20) = a = 0.1
    >>> corrected_mean(per_field, (0.1, 0.0)).tolist()
    [[[11.0, 20.0]]]
    """
    per_field = np.asarray(per_field, float)
    a, b = (float(c) for c in aliasing)
    if not aliasing_removable((a, b)):
        raise ValueError(f"corrected_mean: a vertical sampling error of amplitude {np.hypot(a, b):.3f} px "
                         f"(a {a:+.3f}, b {b:+.3f}) is not a function of the row (needs pi * amplitude < 1)")
    amplitude = np.hypot(a, b)
    rows = per_field.copy()
    for parity, sign in ((0, 1.0), (1, -1.0)):
        v = per_field[:, parity, :, 1]
        low, high = v - amplitude, v + amplitude
        for _ in range(60):             # halves the interval to below float spacing: 2 * amplitude / 2**60
            row = 0.5 * (low + high)
            above = row + sign * (a * np.cos(np.pi * row) + b * np.sin(np.pi * row)) > v
            high, low = np.where(above, row, high), np.where(above, low, row)
        rows[:, parity, :, 1] = 0.5 * (low + high)
    return rows.mean(axis=1)


class FieldMeasurement(NamedTuple):
    """An interlaced camera's markers measured field by field (:func:`remeasure_by_fields`).

    Attributes
    ----------
    marker_px : (n, m, 2)
        The fields' centres freed of the vertical sampling error and
        averaged; where the fields do not show the marker, the given centre.
    reason : (n, m) str
        Why the given centre was kept (:data:`FIELD_NOT_FOUND`,
        :data:`FIELDS_DISAGREE`), else ``""``.
    per_field : (n, 2, m, 2)
        Each field's centre as measured (parity 0, then 1), NaN where not measured.
    aliasing : (2,)
        ``(a, b)`` of :func:`row_aliasing` (px).
    aliasing_note : str
        ``""``, or why the fitted error was not removed (the fields' plain
        mean is used then).
    """

    marker_px: np.ndarray
    reason: np.ndarray
    per_field: np.ndarray
    aliasing: np.ndarray
    aliasing_note: str = ""


def remeasure_by_fields(frames, marker_px: np.ndarray, threshold: int) -> FieldMeasurement:
    """An interlaced camera's identified markers measured again in each field.

    Each marker of each frame is measured in both fields
    (:func:`field_centroids`); the camera's vertical sampling error is fitted
    over the whole record (:func:`row_aliasing`) and removed, and the two
    fields' centres are averaged (:func:`corrected_mean`): the marker half-way
    between the fields' instants.

    Parameters
    ----------
    frames : sequence of (h, w) uint8
        The camera's frames as recorded (not blended), ``frames[k]`` the
        frame of ``marker_px[k]``.
    marker_px : (n, m, 2)
        The identification's centres (NaN where not seen: stays NaN).
    threshold : int
        Gray level of the marker regions.

    Returns
    -------
    FieldMeasurement

    Examples
    --------
    >>> yy, xx = np.mgrid[0:40, 0:60]
    >>> disc = lambda u, v: 200.0 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 2.0 ** 2))
    >>> frame = np.where(yy % 2 == 1, disc(28.0, 20.0), disc(32.0, 20.0)).round().astype(np.uint8)
    >>> got = remeasure_by_fields([frame], np.array([[[30.4, 20.2], [5.0, 35.0]]]), 60)
    >>> np.round(got.marker_px[0], 1).tolist(), got.reason.tolist()
    ([[30.0, 20.0], [5.0, 35.0]], [['', 'field_not_found']])
    """
    marker_px = np.asarray(marker_px, float)
    if marker_px.ndim != 3 or marker_px.shape[2] != 2:
        raise ValueError(f"remeasure_by_fields: marker_px must be (frames, markers, 2), got {marker_px.shape}")
    if len(frames) < len(marker_px):
        raise ValueError(f"remeasure_by_fields: {len(marker_px)} frames of centres but {len(frames)} frames")
    n, m = marker_px.shape[:2]
    per_field = np.full((n, 2, m, 2), np.nan)
    reason = np.full((n, m), "", dtype=object)
    for k in range(n):
        if np.all(np.isfinite(marker_px[k]), axis=1).any():
            _, per_field[k], reason[k] = field_centroids(frames[k], marker_px[k], threshold)
    aliasing, note = row_aliasing(per_field), ""
    if not aliasing_removable(aliasing):
        note = (f"the fitted vertical sampling error (a {aliasing[0]:+.3f}, b {aliasing[1]:+.3f} px) is too "
                "large to be one: the fields' plain mean is used")
    found = np.all(np.isfinite(per_field), axis=(1, 3))
    measured = marker_px.copy()
    measured[found] = corrected_mean(per_field, (0.0, 0.0) if note else aliasing)[found]
    return FieldMeasurement(measured, reason.astype(str), per_field, aliasing, note)
