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

from .base import DetectionError, DetectionParams
from .filters import label_regions, weighted_centroids
from .thresholds import auto_threshold, binarize, to_gray
from .tracking import (AUTO_MIN_CIRCULARITY, GENERIC_AREA, GENERIC_MAX_AREA_FRACTION, CandidateCache,
                       _tuple_cost_static)

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
