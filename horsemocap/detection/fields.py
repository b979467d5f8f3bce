"""Markers of an interlaced camera measured in each field.

An interlaced frame (PAL DV: 720 x 576, 25 frames of two fields) holds two
pictures: the rows of one parity exposed half a frame after the others. A
marker moving between the fields is a combed blob, its rows alternately at
two positions. The multi-view identification follows the markers in frames
whose fields are blended (:func:`horsemocap.sources.fields_blended`: one
blob again); here each identified marker is then measured in each field on
its own (:func:`field_centroid`): the field's rows thresholded, the blob
nearest the marker's position kept, its intensity-weighted centre above the
local background (:func:`~horsemocap.detection.weighted_centroids`). A
field's blob is one disc smeared over that field's exposure, not the streak
of two overlapping discs the blended frame shows.

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

from .filters import find_candidates, weighted_centroids

#: Reason of a centroid kept from the blended frame because a field's blob was not found near it.
FIELD_NOT_FOUND = "field_not_found"


def field_image(frame: np.ndarray, parity: int) -> np.ndarray:
    """One field of an interlaced gray frame at the frame's size, as uint8 (other rows interpolated).

    The rows ``r % 2 == parity`` stay where they are (pixel ``(u, v)`` is
    still the camera model's pixel); each row of the other field becomes the
    mean of the field's rows above and below it (at the top or bottom edge,
    the one next to it), rounded. A symmetric interpolation: a blob's
    weighted centre is that of the field's own rows.

    Examples
    --------
    >>> f = np.array([[0], [10], [200], [30], [0]], np.uint8)
    >>> field_image(f, 1)[:, 0].tolist()
    [10, 10, 20, 30, 30]
    >>> field_image(f, 0)[:, 0].tolist()
    [0, 100, 200, 100, 0]
    """
    frame = np.asarray(frame)
    if frame.ndim != 2:
        raise ValueError(f"field_image: expected a gray frame (h, w), got shape {frame.shape}")
    if parity not in (0, 1):
        raise ValueError(f"field_image: parity must be 0 or 1, got {parity!r}")
    height = frame.shape[0]
    if height < 2:
        raise ValueError(f"field_image: a frame of {height} row(s) has no two fields")
    out = frame.astype(np.float32)
    other = np.arange(1 - parity, height, 2)
    above = np.where(other - 1 >= 0, other - 1, other + 1)
    below = np.where(other + 1 < height, other + 1, other - 1)
    out[other] = 0.5 * (out[above] + out[below])
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def field_centroid(frame: np.ndarray, parity: int, position, threshold: int, half_window: int = 12,
                   area_range=(3, np.inf)) -> np.ndarray:
    """Weighted centre of the blob nearest ``position`` in one field of an interlaced gray frame.

    Parameters
    ----------
    frame : (h, w) uint8
        The interlaced frame as recorded (its fields not blended).
    parity : {0, 1}
        The field: rows ``r % 2 == parity`` (1: the bottom field, rows 1, 3, ...).
    position : (2,)
        ``(u, v)`` near the marker (px), e.g. its centre in the blended frame.
    threshold : int
        Gray level of the marker regions (the identification's).
    half_window : int
        The blob is searched in the square ``position +- half_window`` px.
    area_range : (min, max)
        Region areas (px, in the field's interpolated image) kept.

    Returns
    -------
    (2,) ndarray
        ``(u, v)`` in the frame's pixels; NaN when no region of the field
        lies in the window.

    Examples
    --------
    A marker 4 px further right in the second (top) field than in the
    first (bottom) one:

    >>> yy, xx = np.mgrid[0:40, 0:60]
    >>> disc = lambda u, v: 200.0 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 2.0 ** 2))
    >>> frame = np.where(yy % 2 == 1, disc(28.0, 20.0), disc(32.0, 20.0)).round().astype(np.uint8)
    >>> np.round(field_centroid(frame, 1, (30, 20), 60), 1).tolist()
    [28.0, 20.0]
    >>> np.round(field_centroid(frame, 0, (30, 20), 60), 1).tolist()
    [32.0, 20.0]
    """
    gray = field_image(frame, parity)
    u, v = (int(round(float(c))) for c in position)
    crop = (u - half_window, v - half_window, u + half_window + 1, v + half_window + 1)
    regions, keep = find_candidates(gray, int(threshold), area_range, None, crop=crop)
    if len(keep) == 0:
        return np.full(2, np.nan)
    u0, v0 = regions.origin
    sub = gray[v0:v0 + regions.labels.shape[0], u0:u0 + regions.labels.shape[1]]
    centres = weighted_centroids(sub, regions, keep)
    return centres[int(np.argmin(np.linalg.norm(centres - np.asarray(position, float), axis=1)))]


def field_centroids(frame: np.ndarray, positions, threshold: int, half_window: int = 12):
    """Markers of one interlaced frame measured in each field; their mean, half-way between the fields.

    Parameters
    ----------
    frame : (h, w) uint8
        The frame as recorded.
    positions : (m, 2)
        The markers' centres in the blended frame (NaN: not seen; stays NaN).
    threshold : int
    half_window : int
        As :func:`field_centroid`.

    Returns
    -------
    centres : (m, 2)
        The mean of the two fields' centres; where a field's blob is not
        found, the given position (and ``found`` False).
    per_field : (2, m, 2)
        Each field's centre (parity 0, then 1), NaN where not found.
    found : (m,) bool
        Both fields measured (False also where ``positions`` is NaN).

    Examples
    --------
    >>> yy, xx = np.mgrid[0:40, 0:60]
    >>> disc = lambda u, v: 200.0 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 2.0 ** 2))
    >>> frame = np.where(yy % 2 == 1, disc(28.0, 20.0), disc(32.0, 20.0)).round().astype(np.uint8)
    >>> centres, per_field, found = field_centroids(frame, [[30.0, 20.0], [np.nan, np.nan]], 60)
    >>> np.round(centres[0], 1).tolist(), found.tolist()
    ([30.0, 20.0], [True, False])
    """
    positions = np.asarray(positions, float).reshape(-1, 2)
    per_field = np.full((2,) + positions.shape, np.nan)
    seen = np.all(np.isfinite(positions), axis=1)
    for parity in (0, 1):
        for m in np.flatnonzero(seen):
            per_field[parity, m] = field_centroid(frame, parity, positions[m], threshold, half_window)
    found = seen & np.all(np.isfinite(per_field), axis=(0, 2))
    centres = positions.copy()
    centres[found] = per_field[:, found].mean(axis=0)
    return centres, per_field, found


def row_aliasing(per_field: np.ndarray, min_samples: int = 20, iterations: int = 3) -> np.ndarray:
    """The vertical sampling error of one interlaced camera's field centres: ``(a, b)`` px.

    A field holds every other row, so a marker's vertical centre in one
    field is sampled at a pitch of two rows; the weighted centre then errs
    periodically with the marker's row, ``E(v) = a cos(pi v) + b sin(pi v)``
    in the field of parity 0 and ``-E(v)`` in that of parity 1 (its rows one
    row further). The two fields' errors cancel in their mean only when
    the marker has not moved vertically between them. The difference of
    the two fields' centres of one frame is the marker's vertical motion
    over half a frame (proportional to its velocity, ``m(k+1) - m(k-1)`` of
    the fields' mean ``m``) plus ``-E(v1) - E(v0)``; a least-squares fit of
    that over every marker and frame of the camera gives ``a`` and ``b``
    (and the motion's factor, so either field order fits).

    Parameters
    ----------
    per_field : (n, 2, m, 2)
        Each frame's field centres (parity 0, then 1), NaN where not measured.
    min_samples : int
        Fewer marker-frames with both fields and both neighbouring frames: ``(0, 0)``.
    iterations : int
        Fits, each with the motion of the fields' mean corrected by the previous fit.

    Returns
    -------
    (2,) ndarray
        ``(a, b)`` px.

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
    aliasing = np.zeros(2)
    for _ in range(iterations):             # the fields' mean, whose motion is a regressor, freed of the error
        mean = corrected_mean(per_field, aliasing)[..., 1]
        motion = np.full_like(mean, np.nan)
        motion[1:-1] = mean[2:] - mean[:-2]
        ok = np.isfinite(v0) & np.isfinite(v1) & np.isfinite(motion)
        if ok.sum() < min_samples:
            return np.zeros(2)
        design = np.column_stack([-(np.cos(np.pi * v0[ok]) + np.cos(np.pi * v1[ok])),
                                  -(np.sin(np.pi * v0[ok]) + np.sin(np.pi * v1[ok])), motion[ok]])
        aliasing = np.linalg.lstsq(design, (v1 - v0)[ok], rcond=None)[0][:2]
    return aliasing


def corrected_mean(per_field: np.ndarray, aliasing) -> np.ndarray:
    """The two fields' centres freed of the vertical sampling error ``aliasing = (a, b)``
    (:func:`row_aliasing`) and averaged: (n, m, 2), NaN where a field is NaN.

    Examples
    --------
    >>> per_field = np.array([[[[10.0, 20.0 + 0.1]], [[12.0, 20.0 - 0.1]]]])     # E(20) = a = 0.1
    >>> corrected_mean(per_field, (0.1, 0.0)).tolist()
    [[[11.0, 20.0]]]
    """
    per_field = np.asarray(per_field, float)
    a, b = (float(c) for c in aliasing)
    out = per_field.copy()
    for parity, sign in ((0, 1.0), (1, -1.0)):
        v = per_field[:, parity, :, 1]
        row = v
        for _ in range(12):                 # the error is a function of the true row: v = row + sign E(row)
            row = v - sign * (a * np.cos(np.pi * row) + b * np.sin(np.pi * row))
        out[:, parity, :, 1] = row
    return out.mean(axis=1)


class FieldMeasurement(NamedTuple):
    """An interlaced camera's markers measured field by field (:func:`remeasure_by_fields`).

    Attributes
    ----------
    marker_px : (n, m, 2)
        The fields' centres freed of the vertical sampling error and
        averaged; where a field does not show the marker, the given centre.
    reason : (n, m) str
        :data:`FIELD_NOT_FOUND` where the given centre was kept, else ``""``.
    per_field : (n, 2, m, 2)
        Each field's centre as measured (parity 0, then 1), NaN where not found.
    aliasing : (2,)
        ``(a, b)`` of :func:`row_aliasing` (px).
    """

    marker_px: np.ndarray
    reason: np.ndarray
    per_field: np.ndarray
    aliasing: np.ndarray


def remeasure_by_fields(frames, marker_px: np.ndarray, threshold: int, half_window: int = 12) -> FieldMeasurement:
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
    half_window : int
        As :func:`field_centroid`.

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
    for k in range(n):
        if np.all(np.isfinite(marker_px[k]), axis=1).any():
            per_field[k] = field_centroids(frames[k], marker_px[k], threshold, half_window)[1]
    aliasing = row_aliasing(per_field)
    seen = np.all(np.isfinite(marker_px), axis=2)
    found = seen & np.all(np.isfinite(per_field), axis=(1, 3))
    out = marker_px.copy()
    out[found] = corrected_mean(per_field, aliasing)[found]
    reason = np.where(seen & ~found, FIELD_NOT_FOUND, "")
    return FieldMeasurement(out, reason, per_field, aliasing)
