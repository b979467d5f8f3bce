"""Candidates of several cameras matched into 3D points (seed 000 sec. 5.2.3).

One camera cannot tell a marker from a round bright pseudo marker; the
cameras together can: a real marker is a 3D point whose projections are
candidate regions (:mod:`~horsemocap.detection.candidates`) in every camera
that sees it. :func:`match_views` pairs the candidates of every two cameras
by triangulation (the epipolar constraint: both reprojection errors small),
then validates each point by the further cameras (the nearest candidate near
its projection joins it when the point stays consistent). The result,
:class:`ViewPoints`, holds each point with its candidate in every camera.
:func:`triangulate_rows` is the fast linear triangulation both use.
:func:`candidates_at_instant` moves a free-running camera's candidates to the
instant the other cameras' frames show, before they are matched.

Example
-------
>>> import numpy as np
>>> from horsemocap.virtuallab.rig import thesis_rig
>>> rig = thesis_rig()
>>> X = np.array([[0.0, 0.0, 7.5], [0.3, -0.1, 7.6]])
>>> cands = {c: Candidates(rig[c].project(X), np.full(2, 20.0), np.zeros(2, bool)) for c in rig.names}
>>> vp = match_views(rig, cands)
>>> len(vp), bool(np.allclose(np.sort(vp.points[:, 0]), X[:, 0]))
(2, True)
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..reconstruction import DEFAULT_MAX_RESIDUAL_PX, _dlt, _undistort
from .candidates import Candidates

__all__ = ["ViewPoints", "match_views", "triangulate_rows", "candidates_at_instant"]


@dataclass(frozen=True)
class ViewPoints:
    """3D points made of candidates of several cameras (:func:`match_views`).

    Attributes
    ----------
    points : ndarray (P, 3)
        Joint triangulation (world frame, m).
    index : ndarray (P, C) int
        Candidate index per camera (``-1``: that camera does not see it).
    residual_px : ndarray (P,)
        Largest reprojection error over the cameras used.
    cameras : tuple of str
    missing : ndarray (P,) int
        Cameras in whose image the point projects (inside, away from the
        border) without a candidate there: evidence against a real marker
        (a chance match along an epipolar line), though a marker hidden in
        one camera has one too.
    """

    points: np.ndarray
    index: np.ndarray
    residual_px: np.ndarray
    cameras: tuple
    missing: np.ndarray = None

    def subset(self, keep) -> "ViewPoints":
        return ViewPoints(self.points[keep], self.index[keep], self.residual_px[keep], self.cameras,
                          self.missing[keep])

    def __len__(self):
        return len(self.points)


def _normalized(cam, cand: Candidates) -> np.ndarray:
    """Undistorted normalised coordinates of a camera's candidates (computed once per image)."""
    xn = cand.__dict__.get("_normalized")
    if xn is None:
        xn = _undistort(cam, np.asarray(cand.centre, float)) if len(cand) else np.zeros((0, 2))
        object.__setattr__(cand, "_normalized", xn)
    return xn


def _extrinsics(rig, cams) -> np.ndarray:
    """The cameras' ``[R | t]`` stacked (C, 3, 4), kept on the rig per tuple of cameras (the rig is frozen)."""
    kept = rig.__dict__.get("_extrinsics")
    if kept is None:
        kept = {}
        object.__setattr__(rig, "_extrinsics", kept)
    cams = tuple(cams)
    Ps = kept.get(cams)
    if Ps is None:
        Ps = kept[cams] = np.stack([np.hstack([rig[c].rotation_matrix, rig[c].translation[:, None]])
                                    for c in cams])
    return Ps


def triangulate_rows(rig, cams, cands, rows, max_residual_px):
    """Linear triangulation of rows of candidates, one candidate (or none) per camera.

    The DLT of :mod:`horsemocap.reconstruction` on undistorted normalised
    coordinates, without its nonlinear refinement: identification only needs
    to tell consistent views from inconsistent ones (residuals of a pixel
    against a limit of 2 px), which the linear solution does to a fraction of
    the noise, at a fraction of the cost. The positions the analysis uses are
    triangulated again, refined, by the triangulation step.

    Parameters
    ----------
    rig : horsemocap.camera.Rig
    cams : tuple of str
        The cameras of the columns of ``rows``.
    cands : dict camera -> Candidates
    rows : ndarray (R, C) int
        Candidate index per camera, ``-1`` where the camera is not used.
    max_residual_px : float

    Returns
    -------
    points : ndarray (R, 3)
    worst : ndarray (R,)
        Largest reprojection error (px) over the cameras used (inf for a
        point behind a camera).
    ok : ndarray (R,) bool
        Finite, seen by two cameras or more, ``worst <= max_residual_px``.
    """
    R, C = len(rows), len(cams)
    seen = rows.T >= 0                                            # (C, R)
    xn = np.zeros((C, R, 2))
    px = np.full((C, R, 2), np.nan)
    for i, c in enumerate(cams):
        sel = seen[i]
        if sel.any():
            xn[i, sel] = _normalized(rig[c], cands[c])[rows[sel, i]]
            px[i, sel] = cands[c].centre[rows[sel, i]]
    X = _dlt(xn, seen, _extrinsics(rig, cams)) if R else np.zeros((0, 3))
    res = np.zeros((C, R))
    for i, c in enumerate(cams):
        if seen[i].any():
            cam = rig[c]
            in_camera = cam.world_to_camera(X[seen[i]])
            r = np.linalg.norm(cam.camera_to_pixels(in_camera) - px[i, seen[i]], axis=1)
            res[i, seen[i]] = np.where(in_camera[:, 2] > 0, r, np.inf)
    worst = np.max(np.where(np.isfinite(res), res, np.inf), axis=0) if R else np.zeros(0)
    ok = np.all(np.isfinite(X), axis=1) & (seen.sum(axis=0) >= 2) & (worst <= max_residual_px)
    return X, worst, ok


def match_views(rig, cands: dict, max_residual_px: float = DEFAULT_MAX_RESIDUAL_PX) -> ViewPoints:
    """Every 3D point whose projections are candidates of two or more cameras.

    1. Every pair of cameras: every candidate of one with every candidate of
       the other, triangulated; kept when both reprojection errors are below
       ``max_residual_px`` (the epipolar constraint).
    2. Validation by the further cameras (seed 000 sec. 5.2.3): the point is
       projected into each other camera; the nearest candidate within
       ``max_residual_px`` joins it when the point triangulated from all its
       views stays consistent.
    3. The same set of views found from different pairs is kept once; a
       2-view point whose views are part of a 3-view point is dropped.

    Regions cut by the image border never take part.

    Parameters
    ----------
    rig : horsemocap.camera.Rig
    cands : dict camera -> Candidates
    max_residual_px : float

    Returns
    -------
    ViewPoints
    """
    cams = tuple(c for c in rig.names if c in cands)
    C = len(cams)
    rows = []
    for a, b in itertools.combinations(range(C), 2):
        ia = np.flatnonzero(~cands[cams[a]].cut)
        ib = np.flatnonzero(~cands[cams[b]].cut)
        if len(ia) == 0 or len(ib) == 0:
            continue
        r = np.full((len(ia) * len(ib), C), -1, int)
        r[:, a] = np.repeat(ia, len(ib))
        r[:, b] = np.tile(ib, len(ia))
        rows.append(r)
    if not rows:
        return ViewPoints(np.zeros((0, 3)), np.zeros((0, C), int), np.zeros(0), cams, np.zeros(0, int))
    rows = np.vstack(rows)
    X, worst, ok = triangulate_rows(rig, cams, cands, rows, max_residual_px)
    rows, X, worst = rows[ok], X[ok], worst[ok]
    # validation by the other cameras
    for c in range(C):
        free = rows[:, c] < 0
        if not free.any() or len(cands[cams[c]]) == 0:
            continue
        proj = rig[cams[c]].project(X[free])
        d = np.linalg.norm(proj[:, None, :] - cands[cams[c]].centre[None], axis=-1)
        d[:, cands[cams[c]].cut] = np.inf
        j = np.argmin(d, axis=1)
        near = d[np.arange(len(j)), j] <= max_residual_px
        if not near.any():
            continue
        ext = rows[free][near].copy()
        ext[:, c] = j[near]
        Xe, we, oke = triangulate_rows(rig, cams, cands, ext, max_residual_px)
        rows = np.vstack([rows, ext[oke]])
        X = np.vstack([X, Xe[oke]])
        worst = np.concatenate([worst, we[oke]])
    # unique view sets; drop subsets of larger ones
    order = np.lexsort((worst, -(rows >= 0).sum(axis=1)))
    keep, seen_sets = [], []
    for i in order:
        s = {(c, int(rows[i, c])) for c in range(C) if rows[i, c] >= 0}
        if any(s <= t for t in seen_sets):
            continue
        seen_sets.append(s)
        keep.append(i)
    keep = np.asarray(keep, int)
    X, rows = X[keep], rows[keep]
    missing = np.zeros(len(X), int)
    for c in range(C):
        free = rows[:, c] < 0
        if free.any():
            inside = rig[cams[c]].in_image(rig[cams[c]].project(X[free]), margin=4 * max_residual_px)
            missing[np.flatnonzero(free)[inside]] += 1
    return ViewPoints(X, rows, worst[keep], cams, missing)



def _followed(centre: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Index in ``other`` of each of ``centre``'s regions in one neighbouring frame, ``-1`` when unclear.

    A pair is taken when each is the other's nearest region and the
    nearest is at most half as far as the runner-up in both frames (so two
    regions passing near each other are not swapped).
    """
    out = np.full(len(centre), -1, int)
    if len(centre) == 0 or len(other) == 0:
        return out
    d = np.linalg.norm(centre[:, None] - other[None], axis=-1)
    fwd, back = np.argmin(d, axis=1), np.argmin(d, axis=0)
    for i, j in enumerate(fwd):
        if back[j] != i:
            continue
        near = d[i, j]
        row = np.delete(d[i], j)
        col = np.delete(d[:, j], i)
        if (row.size and near > 0.5 * row.min()) or (col.size and near > 0.5 * col.min()):
            continue
        out[i] = j
    return out


def _followed_both(previous: np.ndarray, centre: np.ndarray, following: np.ndarray) -> np.ndarray:
    """Per region of ``centre``, its image motion per frame from the previous and following frames, NaN when
    unclear.

    The pair of regions (one in each neighbouring frame) that makes its
    path straightest (the smallest second difference ``|x(k+1) - 2 x(k) +
    x(k-1)|``: a marker's acceleration over two frames is a fraction of a
    pixel, while a neighbouring marker's region, a marker spacing away,
    bends the path by that spacing) is taken when its bend is at most half
    that of the runner-up pair; markers moving further in a frame than
    half their spacing are followed too, unlike by nearness alone.
    """
    out = np.full(centre.shape, np.nan)
    if len(previous) == 0 or len(following) == 0:
        return out
    bend = np.linalg.norm(following[None, None, :] + previous[None, :, None] - 2.0 * centre[:, None, None],
                          axis=-1)                                        # (K, P, F)
    flat = bend.reshape(len(centre), -1)
    order = np.argsort(flat, axis=1)
    for i in range(len(centre)):
        best = flat[i, order[i, 0]]
        if flat.shape[1] > 1 and best > 0.5 * flat[i, order[i, 1]]:
            continue
        p, f = np.unravel_index(order[i, 0], bend.shape[1:])
        out[i] = 0.5 * (following[f] - previous[p])
    return out


def candidates_at_instant(previous: Candidates | None, current: Candidates, following: Candidates | None,
                          shift) -> Candidates:
    """A frame's candidates moved along their image motion by ``shift`` frames.

    A free-running camera's frame ``k`` shows the instant ``k + phase``
    (reference frames); its regions at the reference instant ``k`` are
    where they were ``shift = -phase`` frames later. Each region is
    followed into the previous and the following frame
    (:func:`_followed`: mutual nearest regions, clearly nearest); its
    motion per frame is the central difference of the two (one side when
    the other is not followed), and its centre moves by ``shift`` times
    that motion. A region followed into neither frame stays where it is.
    Areas, cut flags and order are kept, so an index into the result is
    an index into ``current``.

    Parameters
    ----------
    previous, current, following : Candidates
        Frames ``k - 1``, ``k`` and ``k + 1`` of one camera (``None`` at the
        record's ends).
    shift : float or ndarray (K,)
        Frames to move, for all regions or each (a rolling shutter's rows
        are exposed one after another); ``0``: ``current`` itself.

    Returns
    -------
    Candidates

    Example
    -------
    >>> import numpy as np
    >>> box = lambda x: Candidates(np.array([[x, 10.0], [x + 40.0, 60.0]]), np.full(2, 20.0), np.zeros(2, bool))
    >>> moved = candidates_at_instant(box(100.0), box(104.0), box(108.0), -0.25)
    >>> moved.centre.tolist()
    [[103.0, 10.0], [143.0, 60.0]]
    """
    shift = np.asarray(shift, float)
    if len(current) == 0 or not np.any(shift):
        return current
    centre = np.asarray(current.centre, float)
    have = [c is not None and len(c) > 0 for c in (previous, following)]
    if all(have):
        velocity = _followed_both(np.asarray(previous.centre, float), centre, np.asarray(following.centre, float))
    elif any(have):
        other, sign = (previous, -1.0) if have[0] else (following, 1.0)
        j = _followed(centre, np.asarray(other.centre, float))
        velocity = np.full(centre.shape, np.nan)
        velocity[j >= 0] = sign * (np.asarray(other.centre, float)[j[j >= 0]] - centre[j >= 0])
    else:
        velocity = np.full(centre.shape, np.nan)
    moved = centre + shift.reshape(-1, 1) * np.where(np.isfinite(velocity), velocity, 0.0)
    return Candidates(moved, current.area, current.cut, current.slope, current.moments)
