"""The thesis' per-camera chain: the markers of one camera through a sequence (chapter 4).

This is the thesis' own detection (``left_image_centroids_3.m``, Appendix A
step 4): each camera on its own, with the filters of chapter 4. The
pipeline's default is the multi-view identification
(:mod:`~horsemocap.detection.tracker3d`); this chain runs with
``detection_method="thesis"`` (``--preset thesis``).

:func:`detect_markers` chooses the markers automatically (whole-image
candidates of :class:`CandidateCache`, the consistent cluster of
:func:`choose_markers` found again by :func:`follow_cluster`, the anchor
frame whose cluster :func:`cluster_persistence` follows longest), then follows
them forward and backward from that frame with the chain of
:mod:`~horsemocap.detection.filters` inside a window centred on the predicted
marker centre (``_track_frame``). :func:`valid_frames` and
:func:`usable_frames` say which frames the tracks of one or several cameras
cover.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import replace

import cv2
import numpy as np

from ..sources import FrameSequence
from .base import (AUTO_MIN_CIRCULARITY, GENERIC_AREA, GENERIC_MAX_AREA_FRACTION, DetectionError, DetectionParams,
                   MarkerTrack, boxes_touch_border)
from .filters import (_candidates_in, _norm, clip_crop, cross_product_signs, filter_area, filter_cross_product,
                      filter_distance, find_candidates, marker_distances, region_circularity, weighted_centroids,
                      window_center)
from .thresholds import auto_threshold

__all__ = [
    "CandidateCache",
    "follow_cluster",
    "choose_markers",
    "cluster_persistence",
    "detect_markers",
    "valid_frames",
    "usable_frames",
]


# --------------------------------------------------------------------------
# automatic choice of the markers in one frame
# --------------------------------------------------------------------------
#: The most candidates of one frame among which the markers are chosen (the largest).
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
    holds a label image of the whole frame, so only the ``max_frames`` most
    recently used frames are kept.
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
    ch = _thesis_choices(c, marker_distances(px), tolerance, cross_product_signs(px, 0.1))
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
            box = clip_crop((int(lo[0]), int(lo[1]), int(hi[0]) + 2, int(hi[1]) + 2), W, H)
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
    u0, v0, u1, v1 = clip_crop(crop, W, H)
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
    dt = [np.nan if lk is None else float(k - lk) for lk in last_k]
    good = [lk is not None and abs(k - lk) == 1 and known for lk, known in zip(last_k, state["vel_known"].tolist())]
    ext = last_p + vel * np.array(dt)[:, None]            # constant velocity, every marker (one NumPy pass)
    if all(good):
        return ext
    good = np.array(good, bool)
    pred = np.full_like(last_p, np.nan)
    pred[good] = ext[good]
    if good.any() and state["config"] is not None:
        shift = (pred[good] - state["config"][good]).mean(axis=0)
        pred[~good] = state["config"][~good] + shift
    else:
        recent = [m for m, (g, t) in enumerate(zip(good.tolist(), dt)) if not g and abs(t) <= state["max_gap"]]
        pred[recent] = ext[recent]
    return pred


def _inside(pred, radius, size):
    """Boolean per marker: predicted wholly inside the image."""
    W, H = size
    lo, hu, hv = radius - 0.5, W - 0.5 - radius, H - 0.5 - radius       # NaN: False
    return np.array([u >= lo and v >= lo and u <= hu and v <= hv for u, v in pred.tolist()], bool)


def _choice_errors(cent: list, choices: list, pred: list, gate: list, has_pred: list) -> list:
    """Per choice of regions, the largest distance of a predicted marker from its prediction (inf when a
    marker lies beyond its ``gate``), in Python floats as ``_norm`` computes it."""
    out = []
    for row in choices:
        err, ok = 0.0, True
        for m, j in enumerate(row):
            if has_pred[m]:
                dx, dy = cent[j][0] - pred[m][0], cent[j][1] - pred[m][1]
                d = math.sqrt(dx * dx + dy * dy)
                ok = ok and d <= gate[m]
                err = d if d > err else err
        out.append(err if ok else math.inf)
    return out


def _in_window(cent: np.ndarray, centre, half) -> np.ndarray:
    """:func:`filter_window` of the centres ``cent`` about ``centre`` (half sizes ``half``), in Python floats."""
    (cu, cv), (hu, hv) = centre, half
    return np.array([abs(u - cu) <= hu and abs(v - cv) <= hv for u, v in cent.tolist()], bool)


def _thesis_choices(cent: np.ndarray, dref: np.ndarray, tol: float, signs: np.ndarray) -> np.ndarray:
    """:func:`filter_distance` then :func:`filter_cross_product` (default ``min_sine``) of the centres ``cent``.

    The ordered choices of regions are built marker by marker, a region joining a choice only when its
    distances to the regions already chosen pass eq. (4.11): the choices that survive are those the
    distance filter keeps among all permutations, in the same (lexicographic) order; each distance and
    sign is computed in Python floats by the same operations as the filters, so the numbers are the same,
    without building every permutation or NumPy's per-call cost (a tracked frame has a few candidates).
    """
    C, M = len(cent), len(dref)
    if C < M or M < 2:
        return filter_cross_product(cent, filter_distance(cent, dref, tol), signs)
    pts, ref = cent.tolist(), dref.tolist()
    dist = [[0.0] * C for _ in range(C)]
    for a in range(C):
        xa, ya = pts[a]
        for b in range(a + 1, C):
            dx, dy = xa - pts[b][0], ya - pts[b][1]
            dist[a][b] = dist[b][a] = math.sqrt(dx * dx + dy * dy)
    lim = [[tol * r for r in row] for row in ref]
    sg = signs.tolist() if M >= 3 and np.asarray(signs).any() else None
    kept = []

    def extend(chosen):
        m = len(chosen)
        if m == M:
            if sg is not None:
                s = _signs_of([pts[a] for a in chosen], 0.05).tolist()
                if not all(x == y or y == 0 or x == 0 for x, y in zip(s, sg)):
                    return
            kept.append(tuple(chosen))
            return
        checks = [(dist[c], ref[i][m], lim[i][m]) for i, c in enumerate(chosen)]
        for a in range(C):
            if a in chosen:
                continue
            for row, r, lm in checks:
                if not abs(row[a] - r) <= lm:
                    break
            else:
                chosen.append(a)
                extend(chosen)
                chosen.pop()
    extend([])
    return np.array(kept, dtype=np.intp).reshape(-1, M)


def _touches_border(bbox: np.ndarray, W: int, H: int) -> np.ndarray:
    """:attr:`Regions.touches_border` of the boxes ``bbox`` (a few rows: in Python, one array at the end)."""
    return np.array(boxes_touch_border(bbox.tolist(), W, H), bool)


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
    all_pred = bool(has_pred.all())
    px = np.full((M, 2), np.nan)
    ar = np.full(M, np.nan)
    reason = np.array(["not_tracked"] * M, dtype=object)
    tol = p.distance_tolerance
    dref = state["dref"]
    any_pred = bool(has_pred.any())
    if any_pred:
        centre = (pred if all_pred else pred[has_pred]).mean(axis=0) if p.window_predict \
            else window_center(state["last_p"])
        (cu, cv), (hu, hv) = centre.tolist(), (float(p.window[0]) / 2, float(p.window[1]) / 2)
        pad = state["radius"] * 2 + 2
        crop = (math.floor(cu - hu - pad), math.floor(cv - hv - pad),
                math.ceil(cu + hu + pad) + 1, math.ceil(cv + hv + pad) + 1)
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
        keep = keep[_in_window(regions.centroid[keep], (cu, cv), (hu, hv))]
    cent = regions.centroid[keep]
    # markers whose velocity is not known yet may have moved by a whole frame's motion
    gate_m = np.where(state["vel_known"], state["gate"], state["gate"] + 1.5 * state["motion"] + 2.0)
    # 1) the thesis path: all markers, distance + cross-product filters
    choice = None
    ambiguous = False
    inside = _inside(pred, state["radius"], (W, H))
    if len(keep) >= M and (inside | ~has_pred).all():
        ch = _thesis_choices(cent, dref, tol, state["signs"])
        if len(ch):
            if any_pred:
                err = _choice_errors(cent.tolist(), ch.tolist(), pred.tolist(), gate_m.tolist(), has_pred.tolist())
                order = sorted(range(len(err)), key=err.__getitem__)   # (a tie makes the frame ambiguous)
                if math.isfinite(err[order[0]]):
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
        if any_pred and len(keep):
            opts = []
            for m in range(M):
                if has_pred[m] and inside[m]:      # a marker predicted outside cannot be seen
                    d = _norm(cent - pred[m])
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
        cut = _touches_border(regions.bbox[idx], W, H)
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
    """Fold frame ``k``'s found markers (``px``, ``ar``; NaN = not found) into the tracking state: position,
    velocity (known when the marker was seen at most ``max_gap`` frames before), smoothed area; with every
    marker found, the configuration (and with ``distance_reference="previous"`` the distances and signs)."""
    seen = np.isfinite(px).all(axis=1)
    seen_l = seen.tolist()
    if any(seen_l):
        last_k = state["last_k"]
        dt = np.array([np.nan if lk is None else float(k - lk) for lk in last_k])
        near = np.abs(dt) <= state["max_gap"]                  # NaN (never seen): False
        vel = np.where(near[:, None], (px - state["last_p"]) / dt[:, None], 0.0)   # (NaN quietly where unused)
        a0 = state["area"]
        area = np.where(np.isfinite(a0), 0.7 * a0 + 0.3 * ar, ar)
        state["vel"][seen], state["vel_known"][seen], state["area"][seen] = vel[seen], near[seen], area[seen]
        state["last_p"][seen] = px[seen]
        state["last_k"] = [k if s else lk for s, lk in zip(seen_l, last_k)]
    if all(seen_l):
        state["config"] = px.copy()
        if p.distance_reference == "previous":
            state["dref"] = marker_distances(px)
            state["signs"] = _signs_of(px.tolist(), 0.1)


def _signs_of(pts: list, min_sine: float) -> np.ndarray:
    """:func:`~horsemocap.detection.filters.cross_product_signs` of finite centres given as a list of
    ``[u, v]``, in Python floats (the same operations, so the same numbers, without NumPy's per-call cost)."""
    out = []
    for (xa, ya), (xb, yb), (xc, yc) in zip(pts, pts[1:], pts[2:]):
        r1x, r1y, r2x, r2y = xb - xa, yb - ya, xc - xb, yc - yb
        z = r1x * r2y - r1y * r2x
        bent = abs(z) >= min_sine * (math.sqrt(r1x * r1x + r1y * r1y) * math.sqrt(r2x * r2x + r2y * r2y))
        out.append((1 if z > 0 else -1 if z < 0 else 0) if bent else 0)
    return np.array(out, dtype=int)


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
        regions = _candidates_in(gc[f0], (0, 0), (W, H), p.threshold, (0, np.inf), None)[0]   # every region
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


# --------------------------------------------------------------------------
# frames the tracks cover
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
