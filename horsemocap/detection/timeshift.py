"""The synchronisation checked by the markers: is every camera on the others' instant?

The thesis synchronises the cameras by the frame in which a flashlight comes
on (eq. 3.11-3.14). A flash found one or two frames early (a bright object
entering the view first) or not at all (another light taken for it) puts a
camera's frames at other instants than the others': its views no longer
triangulate with theirs, and the multi-view identification quietly drops
them. The markers tell the truth: the positions the other cameras measure,
projected into this camera, land on its marker regions only in the frames of
the same instant. :func:`frame_shift_residuals` measures, for every shift of
the camera's frames within a range, how far the projections fall from the
nearest candidate region; :func:`best_frame_shift` decides.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .candidates import frame_candidates

__all__ = ["FrameShift", "frame_shift_residuals", "best_frame_shift"]

#: Distance (px) at which a projection counts as not landing on any region.
MISS_PX = 10.0
#: A shift is taken only when its median residual is below this share of the current one ...
SHIFT_RATIO = 0.5
#: ... and the current one is at least this (px): sub-frame timing leaves residuals of
#: half a frame's image motion, which no whole-frame shift can remove.
MIN_CURRENT_PX = 1.0


@dataclass(frozen=True)
class FrameShift:
    """The residuals of one camera's frames shifted against the others' instants.

    Attributes
    ----------
    shifts : ndarray (S,) int
        Frames added to the camera's synchronised frame index.
    median_px : ndarray (S,)
        Median over the sampled marker-frames of the distance from the
        projection of the others' 3D marker to the nearest candidate region
        of this camera (capped at ``MISS_PX``); NaN where no frame could be read.
    n_points : int
        Marker-frames compared.
    best : int
        The shift to apply (0 = keep the flash's offset).
    decided : bool
        Enough marker-frames were compared to test the shifts (``best`` 0 then
        confirms the offset; without, it says nothing).
    """

    shifts: np.ndarray
    median_px: np.ndarray
    n_points: int
    best: int
    decided: bool = True

    @property
    def current_px(self) -> float:
        return float(self.median_px[int(np.flatnonzero(self.shifts == 0)[0])])

    @property
    def best_px(self) -> float:
        return float(self.median_px[int(np.flatnonzero(self.shifts == self.best)[0])])


def frame_shift_residuals(camera, points: np.ndarray, frames, first: int, shifts, threshold: int,
                          area_range, min_circularity, centroid: str = "weighted", n_sample: int = 40,
                          miss_px: float = MISS_PX):
    """Median distance of the others' markers' projections to this camera's regions, per frame shift.

    Parameters
    ----------
    camera : Camera
        The camera checked (world = reference camera frame).
    points : (n, M, 3)
        Marker positions at the synchronised frames ``0..n-1`` measured
        WITHOUT this camera (NaN where unknown).
    frames : sequence of (h, w) uint8 gray frames
        ``frames[i]`` is this camera's frame at synchronised index ``first + i``
        (``first`` may be negative: frames before the flash).
    first : int
    shifts : iterable of int
    threshold, area_range, min_circularity, centroid
        Candidate rules (:func:`~horsemocap.detection.candidates.frame_candidates`).
    n_sample : int
        Frames sampled, evenly over those with at least two known markers.
    miss_px : float

    Returns
    -------
    (shifts (S,), median_px (S,), n_points)
    """
    shifts = np.asarray(list(shifts), int)
    points = np.asarray(points, float)
    known = np.all(np.isfinite(points), axis=-1)
    usable = np.flatnonzero(known.sum(axis=1) >= 2)
    if len(usable) == 0:
        return shifts, np.full(len(shifts), np.nan), 0
    sample = usable[np.unique(np.linspace(0, len(usable) - 1, min(n_sample, len(usable))).round().astype(int))]
    proj = np.full(points[sample].shape[:2] + (2,), np.nan)
    proj[known[sample]] = camera.project(points[sample][known[sample]])
    W, H = camera.size
    inside = np.all(np.isfinite(proj), axis=-1) & (proj[..., 0] >= 0) & (proj[..., 0] <= W - 1) \
        & (proj[..., 1] >= 0) & (proj[..., 1] <= H - 1)
    dist = np.full((len(shifts), len(sample), points.shape[1]), np.nan)
    # the frames each (shift, sampled frame) reads: every pair reading frame j is measured in one pass
    read = sample[None, :] + shifts[:, None]
    wanted = (read >= first) & (read < first + len(frames)) & inside.any(axis=1)[None, :]
    pair_shift, pair_sample = np.nonzero(wanted)
    pair_frame = read[pair_shift, pair_sample]
    seen_uv = [proj[i][inside[i]] for i in range(len(sample))]
    seen_marker = [np.flatnonzero(inside[i]) for i in range(len(sample))]
    counts = inside.sum(axis=1)
    margin = 2.0 * miss_px
    for j in np.unique(pair_frame):
        at_j = pair_frame == j
        rows_shift, rows_sample = pair_shift[at_j], pair_sample[at_j]
        uv = np.concatenate([seen_uv[i] for i in rows_sample])
        lo, hi = np.floor(uv.min(axis=0) - margin), np.ceil(uv.max(axis=0) + margin)
        crop = (max(0, lo[0]), max(0, lo[1]), min(W, hi[0] + 1), min(H, hi[1] + 1))
        cands = frame_candidates(frames[int(j) - first], threshold, area_range, min_circularity, crop=crop,
                                 centroid=centroid)
        if len(cands):
            dd = np.min(np.linalg.norm(uv[:, None] - cands.centre[None], axis=-1), axis=1)
        else:
            dd = np.full(len(uv), miss_px)
        dist[np.repeat(rows_shift, counts[rows_sample]), np.repeat(rows_sample, counts[rows_sample]),
             np.concatenate([seen_marker[i] for i in rows_sample])] = np.minimum(dd, miss_px)
    n_points = int(inside.sum())
    with np.errstate(all="ignore"):
        med = np.array([np.nanmedian(dist[si]) if np.isfinite(dist[si]).any() else np.nan
                        for si in range(len(shifts))])
    return shifts, med, n_points


def best_frame_shift(shifts, median_px, n_points: int, min_points: int = 20) -> FrameShift:
    """The shift that puts the camera on the others' instants, or 0 when none clearly does.

    A shift is taken when its median residual is the smallest, below
    ``SHIFT_RATIO`` times the current one (shift 0), and the current one is
    at least ``MIN_CURRENT_PX``; with fewer than ``min_points`` marker-frames
    nothing is decided.
    """
    shifts, med = np.asarray(shifts, int), np.asarray(median_px, float)
    best = 0
    decided = bool(n_points >= min_points and np.isfinite(med).any() and 0 in shifts)
    if decided:
        cur = med[int(np.flatnonzero(shifts == 0)[0])]
        i = int(np.nanargmin(med))
        if shifts[i] != 0 and (not np.isfinite(cur) or (cur >= MIN_CURRENT_PX and med[i] < SHIFT_RATIO * cur)):
            best = int(shifts[i])
    return FrameShift(shifts, med, int(n_points), best, decided)
