"""Markers in still images (Appendix A steps 7a, 8a, 12a): the plumb and the static shot.

:func:`detect_still` finds them in one camera's still with the filters of
the sequence but no window; :func:`still_candidates`,
:func:`match_still_views` and :func:`detect_still_views` find them in all
cameras at once, keeping only the candidates that are projections of one 3D
point in every camera (thesis 5.1) and choosing among those the ones that
look most like markers.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..reconstruction import triangulate
from .base import AUTO_MIN_CIRCULARITY, GENERIC_AREA, GENERIC_MAX_AREA_FRACTION, DetectionError, DetectionParams
from .filters import label_regions, weighted_centroids
from .thesis_chain import CandidateCache, _tuple_cost_static
from .thresholds import auto_threshold, binarize, to_gray

__all__ = [
    "detect_still",
    "StillCandidates",
    "still_candidates",
    "StillViews",
    "match_still_views",
    "detect_still_views",
]


# --------------------------------------------------------------------------
# stills
# --------------------------------------------------------------------------

def _clearly(cost):
    """A cost "clearly more" than ``cost`` starts here (twice it plus 0.02): the margin by which the
    still matching tells a marker from a point left out."""
    return 2 * cost + 0.02


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
            if np.isfinite(cost[o[1]]) and score[only_second].sum() < _clearly(score[only_best].sum()):
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


def _consistent_points(rig, cams, cand, max_residual_px, sizes=None):
    """Correspondences of candidates found in every camera that can see them.

    Hypotheses start as the candidates of the reference camera; each further
    camera's candidates are added to every hypothesis and the extended
    hypotheses are triangulated jointly (:func:`horsemocap.reconstruction.triangulate`,
    ``mode="joint"``, every camera kept); those whose largest reprojection
    error is below ``max_residual_px`` (the epipolar constraint for two
    cameras, the 3D consistency for more) survive.

    With three or more cameras, a point seen by only some of them (at least
    two) is kept too when it projects outside the image of every camera that
    misses it (``sizes``: camera -> ``(width, height)``; a marker at the edge
    of a view, e.g. the saddle marker above the top of one camera's image,
    :func:`_outside_view`). A point inside a camera's image must be one of
    that camera's candidates: a buckle or a glint seen by two cameras only is
    not a marker.

    Returns index rows (T, C) (``-1``: the camera does not see the point),
    points (T, 3) and largest residuals (T,).
    """
    hyp, X, res = _matched_in(rig, cams, cand, max_residual_px)
    if sizes is None or len(cams) < 3:
        return hyp, X, res
    rows, pts, resid = [hyp], [X], [res]
    for r in range(2, len(cams)):
        for seen in itertools.combinations(range(len(cams)), r):
            sub = tuple(cams[i] for i in seen)
            h, x, e = _matched_in(rig, sub, cand, max_residual_px)
            if not len(h):
                continue
            radius = _region_radius(cand, sub, h)
            ok = _near_depth(rig[cams[0]], x, X)
            for j, c in enumerate(cams):
                if j not in seen:
                    ok &= _outside_view(rig[c], x, sizes[c], radius)
            full = np.full((int(ok.sum()), len(cams)), -1, dtype=np.intp)
            full[:, list(seen)] = h[ok]
            rows.append(full), pts.append(x[ok]), resid.append(e[ok])
    return np.concatenate(rows), np.concatenate(pts), np.concatenate(resid)


def _matched_in(rig, cams, cand, max_residual_px):
    """Correspondences seen by ALL of ``cams`` (see :func:`_consistent_points`)."""
    hyp = np.arange(len(cand[cams[0]]))[:, None]
    X, res = np.zeros((len(hyp), 3)), np.zeros(len(hyp))
    for j in range(1, len(cams)):
        nc = len(cand[cams[j]])
        new = np.column_stack([np.repeat(hyp, nc, axis=0), np.tile(np.arange(nc), len(hyp))])
        if len(new) == 0:       # a camera without candidates: no correspondence, one column per camera
            return np.zeros((0, len(cams)), np.intp), np.zeros((0, 3)), np.zeros(0)
        px = {cams[i]: cand[cams[i]].centre[new[:, i]][None] for i in range(j + 1)}
        tri = triangulate(rig, px, mode="joint", max_residual_px=None)
        r = np.max(np.stack([tri.residual_px[c][0] for c in cams[:j + 1]]), axis=0)
        ok = tri.valid[0] & np.isfinite(r) & (r < max_residual_px)
        hyp, X, res = new[ok], tri.points[0][ok], r[ok]
    return hyp, X, res


def _near_depth(reference, points, seen_by_all, depth_range=(0.5, 2.0)):
    """Points at ``depth_range`` times the distance of the points every camera sees (all, if none)."""
    if not len(seen_by_all):
        return np.ones(len(points), bool)
    ref = float(np.median(np.linalg.norm(np.asarray(seen_by_all) - reference.center, axis=1)))
    d = np.linalg.norm(np.asarray(points) - reference.center, axis=1)
    return (d >= depth_range[0] * ref) & (d <= depth_range[1] * ref)


def _region_radius(cand, cams, hyp):
    """Largest region radius (px, from the area) of each correspondence over its cameras."""
    areas = np.stack([cand[c].area[hyp[:, i]] for i, c in enumerate(cams)], axis=1)
    return np.sqrt(areas.max(axis=1) / np.pi)


def _outside_view(camera, points, size, radius_px, reach: float = 0.25):
    """Points just outside the image, or so near its edge that the region is cut.

    A region touching the border is never a candidate (its centre is
    biased), so a marker within its own radius (plus 2 px) of the edge is
    not seen either. "Just outside": in front of the camera and within
    ``reach`` times the image size beyond the edge, where a marker of a
    scene that the other cameras see whole can be; a chance pairing of two
    other cameras' pseudo markers triangulates anywhere.
    """
    uv = camera.project(np.asarray(points, float))
    w, h = size
    m = np.asarray(radius_px, float) + 2.0
    inside = (uv[:, 0] >= m) & (uv[:, 0] <= w - 1 - m) & (uv[:, 1] >= m) & (uv[:, 1] <= h - 1 - m)
    near = (uv[:, 0] >= -reach * w) & (uv[:, 0] <= (1 + reach) * w) & \
        (uv[:, 1] >= -reach * h) & (uv[:, 1] <= (1 + reach) * h)
    in_front = camera.world_to_camera(np.asarray(points, float))[:, 2] > 0
    return ~inside & near & in_front


def _camera_scores(cand, cams, hyp):
    """Appearance cost of each correspondence per camera (NaN where the camera does not see it)."""
    out = np.full(hyp.shape, np.nan)
    for i, c in enumerate(cams):
        seen = hyp[:, i] >= 0
        out[seen, i] = cand[c].score[hyp[seen, i]]
    return out


def _choose_points(hyp, score, area, M):
    """Best combination of M disjoint correspondences; its cost and the runner-up's.

    A combination may use each candidate of each camera once, and the areas of
    its regions lie within 3 times in every camera (markers share one size,
    as in :func:`detect_still`; a camera that does not see a point, ``-1``, is
    left out). Cost = sum of the appearance costs.
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
        idx = hyp[combos, c]                                    # (n, M); -1: not seen
        s = np.sort(idx, axis=1)
        ok &= np.all((s[:, 1:] != s[:, :-1]) | (s[:, 1:] < 0), axis=1)   # a region serves one marker only
        la = np.where(idx >= 0, np.log(area[c][np.maximum(idx, 0)]), np.nan)
        spread = np.fmax.reduce(la, axis=1) - np.fmin.reduce(la, axis=1)
        ok &= ~(spread > np.log(3.0))
    combos = combos[ok]
    cost = score[combos].sum(axis=1)
    o = np.argsort(cost, kind="stable")
    return combos[o], cost[o]


_COUNT_HINT = ("is the number of markers right? (session field 'markers.count': the static shot holds "
               "markers.count + 1 points with the saddle marker, the plumb 2)")


def _ordinal(k: int) -> str:
    """``1st``, ``2nd``, ``3rd``, ``4th``, ... ``11th``, ``21st``."""
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


class MarkerCountError(DetectionError):
    """A still whose marker-like points are not as many as asked for: most likely a wrong ``markers.count``.

    ``marker_like``: how many of the points consistent in every camera look like markers (the static step
    turns it into the count to give: the markers and the saddle marker).

    Examples
    --------
    >>> err = MarkerCountError("still views: 5 points expected, but only 4 ...", 4)
    >>> isinstance(err, DetectionError), err.marker_like
    (True, 4)
    """

    def __init__(self, message: str, marker_like: int):
        super().__init__(message)
        self.marker_like = int(marker_like)


def _check_count(score, best, M, cams) -> None:
    """Refuse a choice of ``M`` points of which one is a pseudo marker by its look (a wrong marker count).

    The worst chosen point is taken for a pseudo marker when it costs
    clearly more than the other chosen ones (more than twice their median
    + 0.02, :func:`detect_still`'s "clearly") while a point left out costs
    not clearly more than it (less than twice + 0.02): it looks like the
    pseudo markers, not like the markers. A marker merely seen worse than
    the others, with no look-alike left out, passes. Measured on the
    virtual laboratory's 24 sessions and the bundled one (static shots,
    markers + saddle; plumbs): chosen markers cost 0.006-0.070, pseudo
    points 0.144 and more; none is refused with the right count, and every
    static shot is refused with one marker too many.
    """
    if M < 2 or len(score) <= M:
        return
    chosen = np.sort(score[best])
    rest = np.sort(np.delete(score, best))
    worst, typical = chosen[-1], float(np.median(chosen[:-1]))
    if worst > _clearly(typical) and rest[0] < _clearly(worst):
        alike = np.sort(score[score <= _clearly(typical)])
        raise MarkerCountError(
            f"still views: cameras {list(cams)}: {M} points expected, but only {alike.size} of the {len(score)} "
            f"consistent points look like markers (costs {', '.join(f'{v:.3f}' for v in alike)}); the "
            f"{_ordinal(M)} best costs {worst:.3f}, like the points left out ({rest[0]:.3f}...): {_COUNT_HINT}",
            alike.size)


def match_still_views(images: dict, rig, n_markers: int, params: DetectionParams | None = None, *,
                      max_residual_px: float = 2.0, order: str | None = None) -> StillViews:
    """The markers of a still (plumb, static shot) found consistently by every camera.

    One camera alone cannot tell a marker from a round bright pseudo marker
    (a glint, a buckle) of similar look; the other cameras can: a marker is
    a 3D point whose projections are candidate regions in every camera whose
    image it falls in (all cameras, or at least two when it projects outside
    the others' images: a saddle marker above the top edge of one view).

    1. Candidates of each camera: :func:`still_candidates` (the rules of
       :func:`detect_still`: threshold eq. 4.5, labelling 4.5.2, area 4.5.3,
       circularity, border).
    2. Correspondences: every candidate of the reference camera (the first
       camera of ``rig`` present in ``images``) is paired with every
       candidate of the next camera, then of the next..., each extended set
       triangulated jointly (``triangulate(mode="joint")``, thesis 5.1) and
       kept when its largest reprojection error is below ``max_residual_px``
       (for two cameras this is the epipolar constraint; with three, the
       point must also project onto a candidate of the third camera). A
       point that only some cameras (two or more) see is kept when it falls
       outside the image of each of the others (:func:`_consistent_points`).
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
    params : DetectionParams or dict camera -> DetectionParams, optional
        ``threshold`` (one level for every camera, or one per camera;
        default automatic per image), ``area_min``/``area_max``, ``min_circularity``, ``centroid``.
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
    per_cam = params if isinstance(params, dict) else {}
    p = DetectionParams() if isinstance(params, dict) else (params or DetectionParams())
    M = int(n_markers)
    if M < 1:
        raise ValueError(f"still views: n_markers must be >= 1, got {n_markers!r}")
    order = order or ("v" if M == 2 else "u")
    if order not in ("u", "v"):
        raise ValueError(f"still views: order must be 'u' or 'v', got {order!r}")
    if p.labels is not None or any(q.labels is not None for q in per_cam.values()):
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
    cand = {c: still_candidates(images[c], per_cam.get(c, p)) for c in cams}
    counts = ", ".join(f"{c}: {len(cand[c])} at threshold {cand[c].threshold}" for c in cams)
    short = [c for c in cams if len(cand[c]) < M]
    if len(cams) - len(short) < 2:
        raise DetectionError(f"still views: camera(s) {short} have fewer than {M} round candidate regions "
                             f"({counts})")
    sizes = {c: np.asarray(images[c]).shape[1::-1] for c in cams}
    hyp, X, res = _consistent_points(rig, cams, cand, max_residual_px, sizes)
    cam_score = _camera_scores(cand, cams, hyp)
    score = np.nanmean(cam_score, axis=1) if len(hyp) else np.zeros(0)
    n_distinct = min((len(np.unique(hyp[hyp[:, i] >= 0, i])) + int(np.sum(hyp[:, i] < 0))
                      for i in range(len(cams))), default=0)
    if len(hyp) < M or n_distinct < M:
        raise DetectionError(
            f"still views: only {min(len(hyp), n_distinct)} point(s) are seen consistently by every camera "
            f"of {list(cams)} whose image they fall in (reprojection error < {max_residual_px:g} px), "
            f"expected {M} markers (candidates {counts}); check the rig or the stills")
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
        per_cam = [np.nansum(cam_score[only_second, i]) - np.nansum(cam_score[only_best, i]) - 0.02
                   for i in range(len(cams))]
        margin = max(mean_margin, float(min(per_cam)))
        if margin < 0:
            alike = int(np.sum(score <= _clearly(np.median(score[combos[0]]))))   # as the markers chosen
            hint = (f"; {alike} of the {len(hyp)} consistent points look like markers (costs "
                    f"{', '.join(f'{v:.3f}' for v in np.sort(score)[:alike])}), not {M}: {_COUNT_HINT}"
                    ) if alike != M else ""
            message = (f"still views: cameras {list(cams)}: {len(hyp)} points are consistent in all cameras and the "
                       f"{M} markers among them are ambiguous (costs {cost[0]:.3f} vs {cost[1]:.3f}); "
                       f"give an area range or a threshold (candidates {counts}){hint}")
            raise MarkerCountError(message, alike) if alike != M else DetectionError(message)
    best = combos[0]
    _check_count(score, best, M, cams)
    ref_px = rig[cams[0]].project(X[best])           # a point the reference camera misses is ordered too
    o = best[np.argsort(ref_px[:, 1 if order == "v" else 0], kind="stable")]
    index = {c: hyp[o, i] for i, c in enumerate(cams)}
    return StillViews(
        marker_px={c: np.where(index[c][:, None] >= 0, cand[c].centre[np.maximum(index[c], 0)], np.nan)
                   for c in cams},
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
