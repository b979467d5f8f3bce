"""Markers identified by all cameras together and followed in 3D (issue 17; seed 000 sec. 5).

The thesis finds the markers of each camera on its own (chapter 4: threshold,
labels, area, sliding window, distance and cross-product filters). One camera
alone cannot tell a marker from a round bright pseudo marker: a shining
stirrup, a buckle, a glint, a reflector that crosses the markers. The cameras
together can. A real marker

1. is a 3D point whose projections are candidate regions in every camera that
   sees it (the epipolar constraint for two cameras, validation by a further
   camera for three: seed 000, sec. 5.2.3);
2. belongs to a rigid set whose 3D side lengths the static shot gives to a
   millimetre, with the handedness of the static shot (the thesis'
   cross-product rule of Figure 4.13, taken to 3D: the triangle's normal
   faces the cameras as it does in the static shot);
3. moves smoothly: its next position is predicted with minimum acceleration
   over the last frames (seed 000 sec. 5.2.4), and it is looked for near the
   projection of that prediction in every camera, in a search radius that
   widens while it is missed.

:func:`identify_markers` runs the whole chain over a synchronised session:
candidates of every camera (:func:`frame_candidates`: the thesis' threshold
eq. 4.5, labels 4.5.2 and area 4.5.3, plus circularity), correspondences
across cameras (:func:`match_views`), labelling by the rigid model of the
static shot (:func:`fit_marker_model`), then tracking in 3D forward and
backward from the frame where the labelling is clearest. Every rejected 2D
value keeps its reason (:data:`REASONS`).

A marker seen by at least two cameras gets a 3D position; a marker seen by
one camera only is not used (its identity cannot be validated) and is NaN
with reason ``single_view``. Gaps of a few frames in every camera are bridged
later, in 3D (:func:`bridge_gaps`), and marked ``interpolated``.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from ..reconstruction import DEFAULT_MAX_RESIDUAL_PX, triangulate
from . import regions_core
from .base import DetectionError, DetectionParams, Regions
from .filters import clip_crop, find_candidates, light_terms, region_circularity, region_weights, weighted_centroids
from .thresholds import auto_threshold, bright_crops, connected_components, region_order_key
from .tracking import AUTO_MIN_CIRCULARITY, GENERIC_AREA, GENERIC_MAX_AREA_FRACTION

__all__ = [
    "IDENTIFICATION_REASONS", "Candidates", "ViewPoints", "ModelFit", "Identification",
    "frame_candidates", "match_views", "in_working_volume", "label_frame", "point_uncertainty", "distance_tolerance", "fit_marker_model",
    "identify_markers", "bridge_gaps", "default_max_gap", "reason_counts",
]

#: Reasons of a missing or rejected 2D value (``""`` = used for the 3D point).
IDENTIFICATION_REASONS = {
    "": "found and used",
    "occluded": "not seen near its predicted position inside the image",
    "outside_image": "predicted outside the image, or its region is cut by the image border",
    "inconsistent_views": "a region lies near the prediction, but its ray disagrees with the other cameras",
    "not_rigid": "triangulates consistently but breaks the marker set's rigid shape (a stirrup, a glint)",
    "merged": "its region merged with another bright region (far larger than the marker's): centre biased",
    "partly_occluded": "its region is far smaller than the marker's recent area: centre biased",
    "single_view": "seen by one camera only: its identity cannot be validated by another camera",
    "off_track": "consistent in the cameras, but further from the predicted 3D position than a marker moves",
    "unconfirmed": "found alone (no other marker confirms its distance) on an extrapolated track or by too few cameras",
    "lost": "its own track is lost (unseen for more frames than a prediction holds); found again "
            "when the marker set is labelled anew",
    "not_tracked": "the marker set is not followed in this frame (not in view, or lost)",
}
REASONS = IDENTIFICATION_REASONS


def reason_counts(reason: dict) -> str:
    """How often each reason of :data:`IDENTIFICATION_REASONS` was given, per camera, for an error message.

    ``reason``: camera -> array of reasons (:attr:`Identification.reason`);
    counted over frames x markers, used values (``""``) left out, most
    frequent first: ``"left: not_tracked 120, occluded 12; middle: ..."``.
    """
    parts = []
    for cam, r in reason.items():
        names, counts = np.unique(np.asarray(r, dtype=object).ravel().astype(str), return_counts=True)
        tally = {str(k): int(n) for k, n in zip(names, counts)}
        used, total = tally.pop("", 0), int(np.size(r))
        found = sorted(((n, k) for k, n in tally.items()), key=lambda t: (-t[0], t[1]))
        parts.append(f"{cam}: used {used} of {total}" + "".join(f", {k} {n}" for n, k in found))
    return "; ".join(parts)

#: Static-shot and skin-marker tolerance added to the measured uncertainty of a
#: 3D distance (m): markers on skin move by millimetres against each other.
RIGID_SLACK_M = 0.010
#: Detection noise (px, one sigma) assumed when converting the rig's geometry
#: into the 3D uncertainty of a point (a generous value: good detections are 0.05-0.1 px).
PIXEL_SIGMA = 0.2
#: A region whose area is more than this factor away from the marker's recent
#: area in that camera is a merge (or a partial occlusion): its centre is biased.
AREA_FACTOR = 1.6
#: The markers of one frame have areas within this factor in every camera (as
#: for the stills, :func:`~horsemocap.detection.match_still_views`).
SIZE_SPREAD = 3.0
#: Smallest leave-one-out residual limit (px) of a view (see ``_Tracker._limit``).
RESIDUAL_FLOOR_PX = 0.3
MAX_CANDIDATES_PER_CAMERA = 24
MAX_OPTIONS = 3
#: Frames without any marker after which the set is looked for again in whole frames.
MAX_LOST_FRAMES = 10
#: A marker neither seen lately nor carried by the others is looked for this many frames on its
#: own extrapolated track, then no more (until the set is found again).
MAX_STALE_FRAMES = 3
#: Frames on either side whose light slopes are pooled (:func:`correct_light`).
LIGHT_WINDOW = 100
#: Cost of one camera that should see a labelled point and does not (a
#: normalised distance error of 1 costs 1).
MISSING_VIEW_COST = 0.5
#: The markers are looked for between these fractions and multiples of the
#: static shot's distance from the reference camera.
DEPTH_RANGE = (0.5, 2.0)
#: Smallest normalised cost difference between the best labelling and the runner-up.
MIN_MARGIN = 1.0


# --------------------------------------------------------------------------
# candidates of one image
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Candidates:
    """Marker-like regions of one image (thesis 4.5.2-4.5.3 and circularity).

    Attributes
    ----------
    centre : ndarray (K, 2)
        ``(u, v)`` intensity-weighted (or binary) centres, full-image pixels.
    area : ndarray (K,)
        Pixel count.
    cut : ndarray (K,) bool
        Region touching the image border (its centre from the part symmetric
        about it; used only as described in :func:`_whole_inside`).
    slope, moments : ndarray (K, 2) and (K, 2, 2), optional
        The light across the region and its weights' second moments
        (:func:`~horsemocap.detection.filters.light_terms`), when asked for.
    """

    centre: np.ndarray
    area: np.ndarray
    cut: np.ndarray
    slope: np.ndarray | None = None
    moments: np.ndarray | None = None

    def __len__(self):
        return len(self.area)


def frame_candidates(gray: np.ndarray, threshold: int, area_range=(GENERIC_AREA[0], None),
                     min_circularity: float | None = AUTO_MIN_CIRCULARITY, crop=None,
                     centroid: str = "weighted", max_count: int = MAX_CANDIDATES_PER_CAMERA,
                     light: bool = False) -> Candidates:
    """Candidate marker regions of one gray image, or of a crop of it.

    Threshold ``l`` (eq. 4.5), 8-connected labels (4.5.2), area range (4.5.3),
    circularity ``>= min_circularity`` (seed 000), at most ``max_count`` of the
    largest. Regions cut by the image border are kept with ``cut=True`` (the
    tracker needs to know a marker is there but unusable); regions cut by
    the crop edge are dropped (:func:`~horsemocap.detection.find_candidates`).

    Parameters
    ----------
    gray : (h, w) uint8 full image
    threshold : int
    area_range : (min, max) pixels; ``max=None``: 0.5 % of the image
    min_circularity : float or None
    crop : (u0, v0, u1, v1) or None
    centroid : {"weighted", "binary"}

    Returns
    -------
    Candidates

    Notes
    -----
    Run by the compiled core when it is active
    (:mod:`~horsemocap.detection.regions_core`), else by
    :func:`_frame_candidates_python` (the reference; the same result).
    """
    amax = _max_area(area_range, gray)
    if regions_core.CORE is not None and isinstance(gray, np.ndarray) and gray.ndim == 2:
        H, W = gray.shape
        out = regions_core.core_candidates(gray, threshold, [clip_crop(crop, W, H)], (area_range[0], amax),
                                           min_circularity, False, max_count, centroid, light)
        if out is not None:
            return Candidates(*out)
    return _frame_candidates_python(gray, threshold, area_range, min_circularity, crop, centroid, max_count, light)


def _frame_candidates_python(gray: np.ndarray, threshold: int, area_range=(GENERIC_AREA[0], None),
                             min_circularity: float | None = AUTO_MIN_CIRCULARITY, crop=None,
                             centroid: str = "weighted", max_count: int = MAX_CANDIDATES_PER_CAMERA,
                             light: bool = False) -> Candidates:
    """:func:`frame_candidates` in Python and OpenCV (the reference of the compiled core)."""
    regions, keep = find_candidates(gray, threshold, (area_range[0], _max_area(area_range, gray)), None, crop=crop)
    return _candidates_of(gray, regions, keep, min_circularity, centroid, max_count, light)


def _max_area(area_range, gray) -> float:
    """The area range's upper end; None: 0.5 % of the image (at least 50 pixels)."""
    H, W = gray.shape[:2]
    return area_range[1] if area_range[1] is not None else max(50.0, GENERIC_MAX_AREA_FRACTION * H * W)


def _candidates_of(gray, regions, keep, min_circularity, centroid: str, max_count: int, light: bool) -> Candidates:
    """The labelled regions ``keep`` (area already filtered) of ``gray`` as :class:`Candidates`:
    circularity, at most ``max_count`` of the largest, their centres (and light, when asked)."""
    if len(keep) and min_circularity is not None:
        circ = region_circularity(regions.subset(keep))
        keep = keep[circ >= min_circularity]
    if len(keep) > max_count:
        keep = keep[np.argsort(-regions.area[keep], kind="stable")[:max_count]]
    if len(keep) == 0:
        return Candidates(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
    slope = moments = None
    if centroid == "binary":
        centre = regions.centroid[keep].astype(float)
    else:
        u0, v0 = regions.origin
        sub = gray[v0:v0 + regions.labels.shape[0], u0:u0 + regions.labels.shape[1]]
        patches = region_weights(sub, regions, keep, 2) if light else None   # made once for both
        centre = weighted_centroids(sub, regions, keep, symmetric_border=True, patches=patches)
        if light:
            slope, moments = light_terms(sub, regions, keep, patches=patches)
    return Candidates(centre, regions.area[keep].astype(float), regions.touches_border[keep].copy(), slope, moments)


# --------------------------------------------------------------------------
# correspondences across cameras
# --------------------------------------------------------------------------
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
        from ..reconstruction import _undistort

        xn = _undistort(cam, np.asarray(cand.centre, float)) if len(cand) else np.zeros((0, 2))
        object.__setattr__(cand, "_normalized", xn)
    return xn


def _triangulate_rows(rig, cams, cands, rows, max_residual_px):
    """Linear triangulation of candidate rows (R, C) (-1 = unseen); points, largest residuals, ok mask.

    The DLT of :mod:`horsemocap.reconstruction` on undistorted normalised
    coordinates, without its nonlinear refinement: identification only needs
    to tell consistent views from inconsistent ones (residuals of a pixel
    against a limit of 2 px), which the linear solution does to a fraction of
    the noise, at a fraction of the cost. The positions the analysis uses are
    triangulated again, refined, by the triangulation step.
    """
    from ..reconstruction import _dlt

    R, C = len(rows), len(cams)
    seen = rows.T >= 0                                            # (C, R)
    xn = np.zeros((C, R, 2))
    px = np.full((C, R, 2), np.nan)
    for i, c in enumerate(cams):
        sel = seen[i]
        if sel.any():
            xn[i, sel] = _normalized(rig[c], cands[c])[rows[sel, i]]
            px[i, sel] = cands[c].centre[rows[sel, i]]
    Ps = np.stack([np.hstack([rig[c].rotation_matrix, rig[c].translation[:, None]]) for c in cams])
    X = _dlt(xn, seen, Ps) if R else np.zeros((0, 3))
    res = np.zeros((C, R))
    for i, c in enumerate(cams):
        if seen[i].any():
            cam = rig[c]
            ahead = cam.world_to_camera(X[seen[i]])[:, 2] > 0
            r = np.linalg.norm(cam.project(X[seen[i]]) - px[i, seen[i]], axis=1)
            res[i, seen[i]] = np.where(ahead, r, np.inf)
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
    X, worst, ok = _triangulate_rows(rig, cams, cands, rows, max_residual_px)
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
        Xe, we, oke = _triangulate_rows(rig, cams, cands, ext, max_residual_px)
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


# --------------------------------------------------------------------------
# the rigid marker model
# --------------------------------------------------------------------------
def point_uncertainty(rig, points: np.ndarray, seen: np.ndarray, pixel_sigma: float = PIXEL_SIGMA,
                      cameras=None) -> np.ndarray:
    """3D covariance of triangulated points from the rig's geometry.

    ``Cov = sigma^2 (J^T J)^-1`` with ``J`` the derivative of the pixel
    projections in the cameras that see the point (first-order error
    propagation of ``pixel_sigma`` of detection noise). A narrow baseline
    gives a long ellipsoid along the depth.

    Parameters
    ----------
    rig : Rig
    points : (N, 3)
    seen : (N, C) bool, cameras in ``cameras`` (default rig order)
    pixel_sigma : float

    Returns
    -------
    ndarray (N, 3, 3) (inf on the diagonal where fewer than two cameras see the point)
    """
    cams = list(cameras or rig.names)
    X = np.asarray(points, float)
    N = len(X)
    JtJ = np.zeros((N, 3, 3))
    h = 1e-5
    for i, c in enumerate(cams):
        J = np.empty((N, 2, 3))
        for k in range(3):
            d = np.zeros(3)
            d[k] = h
            J[:, :, k] = (rig[c].project(X + d) - rig[c].project(X - d)) / (2 * h)
        J = np.where(np.isfinite(J), J, 0.0) * seen[:, i, None, None]
        JtJ += np.einsum("nik,nil->nkl", J, J)
    cov = np.full((N, 3, 3), 0.0)
    ok = (np.asarray(seen).sum(axis=1) >= 2) & (np.abs(np.linalg.det(JtJ)) > 0)
    cov[ok] = pixel_sigma ** 2 * np.linalg.inv(JtJ[ok])
    cov[~ok] = np.diag([np.inf] * 3)
    return cov


def distance_tolerance(cov_a, cov_b, pa, pb, slack_m: float = RIGID_SLACK_M, k: float = 4.0):
    """Largest credible error of the distance between two triangulated points.

    ``k`` standard deviations of ``|pa - pb|`` along the line joining them
    (from the two covariances) plus ``slack_m`` (skin markers and the static
    shot's own error).
    """
    u = np.asarray(pb, float) - np.asarray(pa, float)
    n = np.linalg.norm(u, axis=-1, keepdims=True)
    u = u / np.where(n > 0, n, 1.0)
    var = np.einsum("...i,...ij,...j->...", u, np.asarray(cov_a) + np.asarray(cov_b), u)
    return k * np.sqrt(np.maximum(var, 0.0)) + slack_m


@dataclass(frozen=True)
class ModelFit:
    """The markers of one frame labelled by the rigid model (:func:`fit_marker_model`).

    Attributes
    ----------
    assignment : ndarray (M,) int
        Index of the frame point given to each model marker (the model's
        order), ``-1`` where none.
    model_index : ndarray (M,) int
        The static-shot points that are the skin markers.
    rms_m : float
        RMS of the distance errors of the assignment (m).
    margin : float
        Runner-up's normalised cost minus the best's (``inf``: no runner-up).
    n_fits : int
        Number of assignments within tolerance.
    """

    assignment: np.ndarray
    model_index: np.ndarray
    rms_m: float
    margin: float
    n_fits: int


#: A triangle seen this nearly edge-on (|cos| of the angle between its normal and the
#: line of sight) has no reliable handedness: its sign is not used.
EDGE_ON_COS = 0.05


def _facing(points3, camera_centre):
    """Sign of the triangle's normal ``(p1 - p0) x (p2 - p0)`` seen from the camera.

    ``0`` when the triangle is seen nearly edge-on (``EDGE_ON_COS``) or is
    degenerate: then a few millimetres of noise flip the sign.
    """
    n = np.cross(points3[..., 1, :] - points3[..., 0, :], points3[..., 2, :] - points3[..., 0, :])
    sight = camera_centre - points3.mean(axis=-2)
    dot = np.einsum("...i,...i->...", n, sight)
    norm = np.linalg.norm(n, axis=-1) * np.linalg.norm(sight, axis=-1)
    cos = np.divide(dot, norm, out=np.zeros_like(dot), where=norm > 0)
    return np.where(np.abs(cos) < EDGE_ON_COS, 0.0, np.sign(cos))


def fit_marker_model(points: np.ndarray, cov: np.ndarray, model: np.ndarray, n_markers: int,
                     camera_centre: np.ndarray, model_index=None, slack_m: float = RIGID_SLACK_M,
                     missing=None, areas=None, views=None) -> ModelFit | None:
    """Label the frame's 3D points with the rigid marker model of the static shot.

    Every ordered choice of ``n_markers`` distinct frame points is compared
    with every choice of ``n_markers`` model points (the static shot holds the
    skin markers and the saddle marker; which of them are the skin markers is
    decided by the fit unless ``model_index`` is given): all pairwise 3D
    distances must agree within :func:`distance_tolerance`, and the first three
    markers' triangle must face the reference camera as it does in the static
    shot (handedness: the thesis' cross-product rule in 3D, which tells a
    triangle from its mirror image when two sides are equal; not used for a
    triangle seen nearly edge-on, :data:`EDGE_ON_COS`). The cost of an
    assignment is the mean squared normalised distance error, plus the
    squared RMS distance error in units of ``slack_m`` (the shape error
    itself: the normalised one forgives errors along the poorly observed
    depth), plus ``MISSING_VIEW_COST`` per camera that should see one of its
    points and does not (``missing``); the cheapest wins and ``margin`` says
    by how much.

    Parameters
    ----------
    points : (P, 3) frame points
    cov : (P, 3, 3) their covariances (:func:`point_uncertainty`)
    model : (S, 3) static-shot points, S >= n_markers
    n_markers : int, M >= 3
    camera_centre : (3,) the reference camera's centre (world)
    model_index : (M,) int, optional: the skin markers among the static points
    slack_m : float
    missing : (P,) int, optional: :attr:`ViewPoints.missing`
    areas : (P, C) float, optional
        Region area of each point in each camera (NaN: unseen). The markers
        share one size: in every camera the areas of an assignment lie within
        ``SIZE_SPREAD`` of each other (a hoof, a white boot or a lamp does not
        pass for a marker).
    views : (P, C) int, optional
        :attr:`ViewPoints.index`: the candidate region of each point in each
        camera (``-1``: unseen). Two markers never share a region: an
        assignment that would is not considered.

    Returns
    -------
    ModelFit or None (no assignment within tolerance)
    """
    P, M = len(points), int(n_markers)
    if P < M or M < 3:
        return None
    model = np.asarray(model, float)
    subsets = [np.asarray(model_index, int)] if model_index is not None else \
        [np.asarray(s, int) for s in itertools.combinations(range(len(model)), M)]
    if math.perm(P, M) > 200000:
        raise DetectionError(f"identification: {P} consistent 3D points in one frame are too many to label; "
                             "give a higher threshold or a smaller area range")
    perms = np.array(list(itertools.permutations(range(P), M)), dtype=np.intp)
    pairs = list(itertools.combinations(range(M), 2))
    pts = points[perms]                                           # (K, M, 3)
    extra = (np.asarray(missing, float)[perms].sum(axis=1) * MISSING_VIEW_COST if missing is not None
             else np.zeros(len(perms)))
    size_ok = np.ones(len(perms), bool)
    if views is not None:                      # a region of one camera serves one marker only
        idx = np.asarray(views, int)[perms]                          # (K, M, C)
        srt = np.sort(idx, axis=1)
        size_ok &= ~np.any((srt[:, 1:] == srt[:, :-1]) & (srt[:, 1:] >= 0), axis=(1, 2))
    if areas is not None:
        la = np.log(np.asarray(areas, float))[perms]               # (K, M, C), NaN where unseen
        spread = np.fmax.reduce(la, axis=1) - np.fmin.reduce(la, axis=1)
        size_ok &= np.all(~(spread > math.log(SIZE_SPREAD)), axis=1)   # (and kept the shared-region rule)
    best = []
    for sub in subsets:
        ms = model[sub]
        err = np.zeros(len(perms))
        ok = size_ok.copy()
        for i, j in pairs:
            d = np.linalg.norm(pts[:, i] - pts[:, j], axis=-1)
            D = np.linalg.norm(ms[i] - ms[j])
            tol = distance_tolerance(cov[perms[:, i]], cov[perms[:, j]], pts[:, i], pts[:, j], slack_m)
            e = np.abs(d - D) / tol
            ok &= e <= 1.0
            err += e ** 2
            if not ok.any():
                break
        if not ok.any():
            continue
        face_model = _facing(ms[None, :3], camera_centre)[0]
        if face_model != 0:
            face = _facing(pts[:, :3], camera_centre)
            ok &= (face == face_model) | (face == 0)
        for k in np.flatnonzero(ok):
            rms = math.sqrt(np.mean([(np.linalg.norm(pts[k, i] - pts[k, j]) - np.linalg.norm(ms[i] - ms[j])) ** 2
                                     for i, j in pairs]))
            best.append((float(err[k] / len(pairs) + extra[k] + (rms / slack_m) ** 2), perms[k], sub, rms))
    if not best:
        return None
    best.sort(key=lambda b: b[0])
    margin = best[1][0] - best[0][0] if len(best) > 1 else math.inf
    return ModelFit(np.asarray(best[0][1], int), np.asarray(best[0][2], int), float(best[0][3]),
                    float(margin), len(best))


# --------------------------------------------------------------------------
# the whole session
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Identification:
    """Markers identified by all cameras and followed in 3D (:func:`identify_markers`).

    Attributes
    ----------
    marker_px : dict camera -> ndarray (n, M, 2)
        The 2D centres used for each marker (thesis ``PM_L``, ``PM_M``,
        ``PM_R``), NaN where not used; markers in the static model's order.
    reason : dict camera -> ndarray (n, M) str
        ``""`` used, else a key of :data:`IDENTIFICATION_REASONS`.
    area : dict camera -> ndarray (n, M)
        Region areas (px) of the used centres.
    points : ndarray (n, M, 3)
        3D positions from the used views (world frame), NaN where fewer than
        two cameras gave a validated view.
    model_index : ndarray (M,)
        The static-shot points that are the skin markers (the rest: the saddle marker).
    rigid_rms_m : ndarray (n,)
        RMS error of the frame's marker distances against the static shot.
    thresholds : dict camera -> int
    anchor_frame : int
        The first frame (middle of the record outward) labelled clearly with
        the chosen skin markers (:func:`_find_anchor`); tracking starts there.
    anchor_margin : float
    """

    marker_px: dict
    reason: dict
    area: dict
    points: np.ndarray
    model_index: np.ndarray
    rigid_rms_m: np.ndarray
    thresholds: dict
    anchor_frame: int
    anchor_margin: float
    cameras: tuple = field(default=())


def _camera_params(params, cams):
    p = params or {}
    if isinstance(p, DetectionParams):
        return {c: p for c in cams}
    return {c: p.get(c) or DetectionParams() for c in cams}


def _area_range(p: DetectionParams):
    return (p.area_min if p.area_min is not None else GENERIC_AREA[0], p.area_max)


def _min_circ(p: DetectionParams):
    return p.min_circularity if p.min_circularity is not None else AUTO_MIN_CIRCULARITY


def _middle_out(n, step):
    mid = n // 2
    out = [mid]
    for d in range(step, n, step):
        for k in (mid + d, mid - d):
            if 0 <= k < n:
                out.append(k)
    return out


def in_working_volume(rig, points: np.ndarray, static_points: np.ndarray, depth_range=DEPTH_RANGE) -> np.ndarray:
    """Points whose distance from the reference camera lies within ``depth_range`` times the static shot's.

    Chance matches along the nearly horizontal epipolar lines of a narrow
    rig triangulate far in front of or behind the horse; the markers ride
    at about the distance of the static shot (the same arena and rig).
    """
    c0 = rig[rig.names[0]].center
    ref = float(np.median(np.linalg.norm(np.asarray(static_points) - c0, axis=1)))
    d = np.linalg.norm(np.asarray(points) - c0, axis=1)
    return (d >= depth_range[0] * ref) & (d <= depth_range[1] * ref)


def label_frame(rig, cands: dict, model: np.ndarray, n_markers: int, max_residual_px: float,
                model_index=None, slack_m: float = RIGID_SLACK_M):
    """Correspondences (:func:`match_views`) and labels (:func:`fit_marker_model`) of one frame.

    Returns ``(ViewPoints, ModelFit or None, why)``; ``why`` says what failed.
    """
    cams = tuple(c for c in rig.names if c in cands)
    vp = match_views(rig, cands, max_residual_px)
    if len(vp):
        vp = vp.subset(in_working_volume(rig, vp.points, model))
    if len(vp) < n_markers:
        return vp, None, f"{len(vp)} consistent 3D points"
    cov = point_uncertainty(rig, vp.points, vp.index >= 0, cameras=cams)
    areas = np.full(vp.index.shape, np.nan)
    for i, c in enumerate(cams):
        seen = vp.index[:, i] >= 0
        areas[seen, i] = cands[c].area[vp.index[seen, i]]
    try:
        fit = fit_marker_model(vp.points, cov, model, n_markers, rig[cams[0]].center, model_index, slack_m,
                               missing=vp.missing, areas=areas, views=vp.index)
    except DetectionError as exc:            # a cluttered frame cannot be labelled; others may be
        return vp, None, str(exc)
    if fit is None:
        return vp, None, f"{len(vp)} consistent 3D points, none {n_markers} in the static shot's shape"
    if fit.margin < MIN_MARGIN:
        return vp, None, f"ambiguous labelling of {len(vp)} consistent 3D points (margin {fit.margin:.2f})"
    return vp, fit, ""


def _whole_frame_candidates(frames, k, cams, thr, cparams) -> dict:
    """Candidates of frame ``k`` of every camera, searched in the whole image (no prediction)."""
    return {c: _whole_frame_search(frames[c][k], thr[c], _area_range(cparams[c]), _min_circ(cparams[c]),
                                   centroid=cparams[c].centroid) for c in cams}


def _whole_frame_search(gray: np.ndarray, threshold: int, area_range, min_circularity, centroid: str = "weighted",
                        max_count: int = MAX_CANDIDATES_PER_CAMERA) -> Candidates:
    """:func:`frame_candidates` of a whole image, labelled in crops around its bright pixels.

    The same candidates (same regions, same order, same centres), without a
    label image of the whole frame: each crop of
    :func:`~horsemocap.detection.thresholds.bright_crops` (padded groups of
    bright 8 x 8 blocks; in a frame without the horse, most of a long
    session, only glints, lamps and rails are bright) is labelled alone
    (:func:`_bright_regions`); its regions in the area range get their
    circularity (by the method the whole image's would:
    :func:`~horsemocap.detection.filters.region_circularity`) and their
    centres from the crop (a weighted centre looks at most 7 px beyond its
    region, a crop holds 10); the candidates of all crops are put in the
    order OpenCV's labelling of the whole image gives them
    (:func:`~horsemocap.detection.thresholds.region_order_key`) before the
    ``max_count`` largest are kept (:func:`_crop_candidates`). Issue 16:
    labelling crops instead of the whole image, then no whole-frame label
    image.
    """
    boxes = regions_core.core_bright_boxes(gray, threshold)
    return _core_whole_search(gray, threshold, boxes, area_range, min_circularity, centroid, max_count)


def _core_whole_search(gray, threshold: int, boxes, area_range, min_circularity, centroid: str,
                       max_count: int) -> Candidates:
    """:func:`_whole_frame_search` in the crops ``boxes`` (the core's ``bright_boxes``) by the compiled core,
    or by :func:`_whole_frame_search_python` where the core is not active or does not take the input."""
    if boxes is not None:
        out = regions_core.core_candidates(gray, threshold, boxes, (area_range[0], _max_area(area_range, gray)),
                                           min_circularity, True, max_count, centroid, False)
        if out is not None:
            return Candidates(*out[:3])
    return _whole_frame_search_python(gray, threshold, area_range, min_circularity, centroid, max_count)


def _whole_frame_search_python(gray: np.ndarray, threshold: int, area_range, min_circularity,
                               centroid: str = "weighted", max_count: int = MAX_CANDIDATES_PER_CAMERA) -> Candidates:
    """:func:`_whole_frame_search` in Python and OpenCV (the reference of the compiled core)."""
    crops = _bright_regions(gray, threshold, area_range)
    return _crop_candidates(gray, crops, min_circularity, centroid, max_count)


def _whole_count(gray: np.ndarray, threshold: int, area_range):
    """The number of regions in the area range not touching the image border (the shape rule not applied),
    and ``search(min_circularity, centroid, max_count)``: :func:`_whole_frame_search`'s candidates of the
    same regions (the labels made once on the Python path; by the compiled core when active)."""
    boxes = regions_core.core_bright_boxes(gray, threshold)
    if boxes is not None:
        out = regions_core.core_candidates(gray, threshold, boxes, (area_range[0], _max_area(area_range, gray)),
                                           None, True, 2 ** 31 - 1, "binary", False)
        if out is not None:
            def search(min_circularity, centroid, max_count):
                return _core_whole_search(gray, threshold, boxes, area_range, min_circularity, centroid, max_count)
            return int(np.count_nonzero(~out[2])), search
    regions = _bright_regions(gray, threshold, area_range)

    def search_python(min_circularity, centroid, max_count):
        return _crop_candidates(gray, regions, min_circularity, centroid, max_count)
    return sum(int(np.count_nonzero(~r.touches_border)) for r in regions), search_python


def _bright_regions(gray: np.ndarray, threshold: int, area_range) -> list:
    """The regions in the area range of each crop around the bright pixels (:class:`Regions` per crop)."""
    H, W = gray.shape[:2]
    amin, amax = area_range[0], _max_area(area_range, gray)
    binary, boxes = bright_crops(gray, threshold)
    crops = []
    for u0, v0, u1, v1 in boxes:
        n, lab, st, ce = connected_components(binary[v0:v1, u0:u1])
        area = st[1:, 4].astype(np.int64)
        keep = np.flatnonzero((area >= amin) & (area <= amax))
        if len(keep) == 0:
            continue
        bbox = st[1:, :4].astype(np.int64) + np.array([u0, v0, 0, 0])
        # OpenCV's centre is (sum of coordinates) / area: the sums are integers, recovered exactly
        cents = (np.rint(ce[1:] * area[:, None]) + np.array([u0, v0]) * area[:, None]) / area[:, None]
        crops.append(Regions(labels=lab, ids=np.arange(1, n), area=area, bbox=bbox, centroid=cents,
                             origin=(u0, v0), image_size=(W, H)).subset(keep))
    return crops


def _crop_candidates(gray: np.ndarray, crops: list, min_circularity, centroid: str, max_count: int) -> Candidates:
    """:class:`Candidates` of the regions of :func:`_bright_regions`, in the whole image's labelling order."""
    W = gray.shape[1]
    if min_circularity is not None and crops:
        by_moments = sum(len(r) for r in crops) <= 8
        crops = [r.subset(region_circularity(r, by_moments) >= min_circularity) for r in crops]
    crops = [r for r in crops if len(r)]
    if not crops:
        return Candidates(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
    crop_of = np.concatenate([np.full(len(r), ci) for ci, r in enumerate(crops)])
    in_crop = np.concatenate([np.arange(len(r)) for r in crops])
    key = np.array([region_order_key(r.labels, rid, y, x, w, r.origin, W) for r in crops
                    for rid, (x, y, w, _) in zip(r.ids.tolist(), r.bbox.tolist())])
    order = np.argsort(key, kind="stable")
    if len(order) > max_count:
        areas = np.concatenate([r.area for r in crops])
        order = order[np.argsort(-areas[order], kind="stable")[:max_count]]
    centre = np.empty((len(order), 2))
    area = np.empty(len(order))
    cut = np.empty(len(order), bool)
    for ci, r in enumerate(crops):
        at = np.flatnonzero(crop_of[order] == ci)
        if len(at) == 0:
            continue
        idx = in_crop[order[at]]
        if centroid == "binary":
            centre[at] = r.centroid[idx]
        else:
            (u0, v0), (h, w) = r.origin, r.labels.shape
            centre[at] = weighted_centroids(gray[v0:v0 + h, u0:u0 + w], r, idx, symmetric_border=True)
        area[at] = r.area[idx]
        cut[at] = r.touches_border[idx]
    return Candidates(centre, area, cut)


#: Frames labelled on their own before the skin markers among the static shot's points are
#: chosen (the choice most of them agree on; see :func:`_find_anchor`).
ANCHOR_VOTES = 5


def _find_anchor(frames, rig, cams, thr, cparams, model, M, model_index, max_residual_px, step):
    """The first frame (middle of the record outward) labelled clearly, and the skin markers.

    The static shot holds the skin markers and the saddle marker; which of
    its points are the skin markers is decided by up to ``ANCHOR_VOTES``
    clearly labelled frames together: the subset most of them chose (ties:
    the smaller median shape error), so one frame in which a pseudo marker
    rigid with the horse completes a look-alike of another subset (the horse
    half in view, say) does not decide it. The anchor is the first of the
    frames that chose it.

    Returns ``((k, cands, vp, fit) or None, tried, votes)``: ``tried`` lists
    ``(frame, why)`` of the frames without a clear labelling, ``votes`` maps
    each chosen subset to its frames.
    """
    n = len(frames[cams[0]])
    tried, fits = [], []
    single = model_index is not None or len(model) == M
    for k in _middle_out(n, step):
        cands = _whole_frame_candidates(frames, k, cams, thr, cparams)
        vp, fit, why = label_frame(rig, cands, model, M, max_residual_px, model_index)
        if fit is None:
            tried.append((k, why))
            continue
        fits.append((k, cands, vp, fit))
        if single or len(fits) >= ANCHOR_VOTES:
            break
    votes = {}
    for f in fits:
        votes.setdefault(tuple(int(i) for i in f[3].model_index), []).append(f)
    if not votes:
        return None, tried, {}
    chosen = min(votes, key=lambda sub: (-len(votes[sub]), float(np.median([f[3].rms_m for f in votes[sub]]))))
    return votes[chosen][0], tried, {sub: [f[0] for f in fs] for sub, fs in votes.items()}


def identify_markers(frames: dict, rig, static_points: np.ndarray, n_markers: int, params=None, *,
                     max_residual_px: float = DEFAULT_MAX_RESIDUAL_PX, slack_m: float = RIGID_SLACK_M,
                     progress=None) -> Identification:
    """Find, label and follow the markers with all cameras together.

    Parameters
    ----------
    frames : dict camera -> sequence of (h, w) uint8 gray frames
        Synchronised (same length, frame ``k`` = the same instant), e.g.
        :class:`~horsemocap.sources.FrameSequence` with ``color=False``.
    rig : Rig
        Calibrated cameras (world = reference camera frame).
    static_points : (S, 3)
        Static-shot markers (the skin markers and the saddle marker,
        triangulated; thesis 6.3), the rigid model.
    n_markers : int
        Skin markers ``M >= 3``.
    params : DetectionParams or dict camera -> DetectionParams, optional
        ``threshold`` (automatic: :func:`~horsemocap.detection.auto_threshold`
        of 8 frames spread over the record), ``threshold_method``,
        ``area_min``/``area_max``, ``min_circularity``, ``centroid``. The
        thesis-only prompts (labels, first frame, window, distance tolerance)
        are not used.
    max_residual_px : float
        Largest reprojection error of a consistent point (as
        :func:`~horsemocap.reconstruction.triangulate`).
    slack_m : float
        Tolerance added to the measured uncertainty of a 3D distance.

    Returns
    -------
    Identification

    Raises
    ------
    DetectionError
        No frame in which the static shot's marker set is seen consistently
        (naming the cameras, the frames tried and why).
    """
    cams = tuple(c for c in rig.names if c in frames)
    if len(cams) < 2:
        raise ValueError(f"identification: need at least two cameras, got {list(frames)}")
    M = int(n_markers)
    if M < 3:
        raise ValueError(f"identification: the rigid model needs at least 3 markers, got {M}")
    static_points = np.asarray(static_points, float)
    if static_points.ndim != 2 or static_points.shape[1] != 3 or len(static_points) < M \
            or not np.all(np.isfinite(static_points)):
        raise ValueError(f"identification: static_points must be ({M} or more, 3) finite, got shape "
                         f"{static_points.shape}")
    n = len(frames[cams[0]])
    if any(len(frames[c]) != n for c in cams):
        raise ValueError("identification: the cameras' frame sequences differ in length "
                         f"({ {c: len(frames[c]) for c in cams} }); synchronise first")
    progress = progress or (lambda *a: None)
    cparams = _camera_params(params, cams)
    thr = {}
    for c in cams:
        if cparams[c].threshold is not None:
            thr[c] = int(cparams[c].threshold)
        else:
            sample = np.unique(np.linspace(0, n - 1, min(n, 8)).round().astype(int))
            thr[c] = auto_threshold([frames[c][i] for i in sample], cparams[c].threshold_method)
    step = max(1, min(8, n // 30))
    found, tried, votes = _find_anchor(frames, rig, cams, thr, cparams, static_points, M, None,
                                       max_residual_px, step)
    if found is None:
        why = "; ".join(f"frame {k}: {w}" for k, w in tried[:6])
        raise DetectionError(
            f"identification: no frame in which cameras {list(cams)} see the static shot's {M} markers "
            f"consistently (thresholds {thr}; tried {len(tried)} frames, e.g. {why}); check the rig, the "
            "static stills, the threshold, or use detection_method 'thesis'")
    k0, cands0, vp0, fit0 = found
    tracker = _Tracker(frames, rig, cams, thr, cparams, static_points[fit0.model_index], M,
                       max_residual_px, slack_m, n)
    tracker.anchor_rms = fit0.rms_m
    tracker.start(k0, cands0, vp0, fit0)
    if len(votes) > 1:
        progress("detect", "the skin markers among the static shot's points, as labelled frame by frame: "
                 + "; ".join(f"points {list(sub)} in frames {ks}" for sub, ks in votes.items())
                 + f"; taken: {list(fit0.model_index)}")
    progress("detect", f"markers labelled in synchronised frame {k0} (model fit {1000 * fit0.rms_m:.1f} mm rms); "
                       "following them in 3D ...")
    for direction in (1, -1):
        k1 = tracker.seed_neighbour(k0, direction)
        tracker.run(k1, direction)
    return tracker.result(fit0.model_index, k0, fit0.margin)


def _whole_inside(centre, ref_area: float, size) -> bool:
    """May a region touching the image border stand for its marker?

    Its centre is measured from the part of the marker symmetric about it
    (:func:`~horsemocap.detection.filters.weighted_centroids`: unbiased
    while a little of the marker is cut off). The disc of the marker's
    recent area (radius ``sqrt(area / pi)``, centred on the region's
    centre) may reach at most half a pixel beyond the image edge (``-0.5``
    or ``W - 0.5``): the thresholded disc is wider than the marker by the
    blurred rim above the threshold (~0.5 px at a threshold a quarter of the
    marker's height up), so the marker itself is then whole in the image.
    Such a view is used only to make up a second view
    (:meth:`_Tracker._without_edge_views`). Unknown area (no recent view in
    this camera): no.
    """
    if not np.isfinite(ref_area):
        return False
    r = math.sqrt(ref_area / math.pi) - 0.5
    u, v = centre
    W, H = size
    return bool(u - r >= -0.5 and v - r >= -0.5 and u + r <= W - 0.5 and v + r <= H - 0.5)


def _in_image(camera, point) -> bool:
    """Does the 3D ``point`` project inside the camera's image (and lie in front of it)?"""
    if camera.world_to_camera(np.asarray(point, float)[None])[0, 2] <= 0:
        return False
    u, v = camera.project(np.asarray(point, float)[None])[0]
    w, h = camera.size
    return bool(0 <= u <= w - 1 and 0 <= v <= h - 1)


class _Tracker:
    """3D tracking with minimum-acceleration prediction (seed 000 sec. 5.2.4)."""

    def __init__(self, frames, rig, cams, thr, cparams, model, M, max_residual_px, slack_m, n):
        self.frames, self.rig, self.cams, self.thr, self.cparams = frames, rig, cams, thr, cparams
        self.model, self.M, self.tol, self.slack, self.n = model, M, max_residual_px, slack_m, n
        C = len(cams)
        self.px = {c: np.full((n, M, 2), np.nan) for c in cams}
        self.area = {c: np.full((n, M), np.nan) for c in cams}
        self.slope = {c: np.full((n, M, 2), np.nan) for c in cams}
        self.moments = {c: np.full((n, M, 2, 2), np.nan) for c in cams}
        self.reason = {c: np.full((n, M), "not_tracked", dtype=object) for c in cams}
        self.X = np.full((n, M, 3), np.nan)
        self.rigid = np.full(n, np.nan)
        self.model_d = np.linalg.norm(model[:, None] - model[None], axis=-1)
        #: Largest distance (m) of a marker from its predicted position: half the smallest marker spacing.
        self.max_step = 0.5 * float(np.min(self.model_d[np.triu_indices(M, 1)]))
        self.size = {c: rig[c].size for c in cams}
        self.C = C
        self._loo = {}
        self.anchor_rms = 0.0

    # -- bookkeeping -------------------------------------------------------
    def start(self, k, cands, vp, fit):
        for m in range(self.M):
            i = fit.assignment[m]
            for ci, c in enumerate(self.cams):
                j = vp.index[i, ci]
                if j >= 0:
                    self.px[c][k, m] = cands[c].centre[j]
                    self.area[c][k, m] = cands[c].area[j]
                    self.reason[c][k, m] = ""
                else:
                    self.reason[c][k, m] = "occluded" if _in_image(self.rig[c], vp.points[i]) else "outside_image"
            self.X[k, m] = vp.points[i]
        self._rigid_rms(k)

    def _rigid_rms(self, k):
        X = self.X[k]
        ok = np.all(np.isfinite(X), axis=1)
        e = [np.linalg.norm(X[i] - X[j]) - self.model_d[i, j]
             for i, j in itertools.combinations(range(self.M), 2) if ok[i] and ok[j]]
        self.rigid[k] = math.sqrt(np.mean(np.square(e))) if e else np.nan

    def _history(self, k, direction, m):
        """Last up to 3 positions of marker m before frame k (tracking order), as (frames back, X), and the gap."""
        pts, gap = [], 0
        j = k - direction
        while 0 <= j < self.n and len(pts) < 3 and abs(k - j) <= 12:
            if np.all(np.isfinite(self.X[j, m])):
                pts.append((abs(k - j), self.X[j, m]))
            elif not pts:
                gap += 1
            j -= direction
        return pts, gap

    def _predict(self, k, direction):
        """Minimum-acceleration prediction of every marker for frame ``k``.

        A marker seen in the previous frame moves on with its last velocity
        (constant velocity: the smallest acceleration, seed 000 sec. 5.2.4),
        or stays put while its velocity is unknown. A marker missed lately
        moves with the others: its last position plus their mean
        displacement since then (the set is rigid), or with its own last
        velocity when no other marker helps.

        Returns the predictions (M, 3) and, per marker, the number of frames
        its prediction is stale (0 when its own track or the others carry
        it): the search widens only for those.
        """
        pred = np.full((self.M, 3), np.nan)
        gaps = np.zeros(self.M, int)
        last = {}
        for m in range(self.M):
            hist, gaps[m] = self._history(k, direction, m)
            if not hist:
                continue
            last[m] = k - direction * hist[0][0]
            if len(hist) >= 2:
                (d1, x1), (d2, x2) = hist[0], hist[1]
                pred[m] = x1 + (x1 - x2) / (d2 - d1) * d1
            else:
                pred[m] = hist[0][1]
        fresh = [m for m in range(self.M) if gaps[m] == 0 and m in last and np.all(np.isfinite(pred[m]))]
        stale = np.array([not (gaps[m] == 0 and m in last) for m in range(self.M)])
        for m in range(self.M):
            if gaps[m] == 0 and m in last:
                continue
            j = last.get(m)
            if j is None:                         # never seen near here: where the others say
                j = self._last_frame_with_all(k, direction)
                if j is None:
                    continue
            helpers = [o for o in fresh if np.all(np.isfinite(self.X[j, o]))]
            if helpers:
                pred[m] = self.X[j, m] + np.mean([pred[o] - self.X[j, o] for o in helpers], axis=0)
                stale[m] = False                  # the others carry it: as good as its own track
        return pred, np.where(stale, gaps, 0)

    def _last_frame_with_all(self, k, direction):
        j = k - direction
        while 0 <= j < self.n:
            if np.all(np.isfinite(self.X[j])):
                return j
            j -= direction
        return None

    def _radius(self, k, direction, c, m, gap):
        """Search radius (px) and reference area of marker m in camera c.

        Twice the marker's image radius plus 2 px, plus half its image motion
        per frame (the error of a constant-velocity prediction is far
        smaller than the motion itself); while its motion is unknown (the
        first frame after the anchor) 8 % of the image size; times
        ``1 + gap / 2`` for a marker whose prediction is ``gap`` frames stale
        (a widening search).
        """
        a = self.area[c][:, m]
        j, recent = k - direction, []
        while 0 <= j < self.n and len(recent) < 5 and abs(k - j) <= 15:
            if np.isfinite(a[j]):
                recent.append(j)
            j -= direction
        ref_area = float(np.median(a[recent])) if recent else np.nan
        size = math.sqrt(ref_area / math.pi) if recent else 4.0
        if len(recent) >= 2:
            p0, p1 = self.px[c][recent[0], m], self.px[c][recent[1], m]
            motion = 0.5 * float(np.linalg.norm(p0 - p1)) / abs(recent[0] - recent[1])
        else:
            motion = 0.08 * max(self.size[c])
        return (2.0 * size + 2.0 + motion) * (1.0 + 0.5 * gap), ref_area

    # -- one frame ---------------------------------------------------------
    def step(self, k, direction):
        pred, gaps = self._predict(k, direction)
        predicted = np.all(np.isfinite(pred), axis=1)
        if not predicted.any():
            return False
        cams, M = self.cams, self.M
        self._cand_index = {}
        proj, radius, ref_area, cands = {}, {}, {}, {}
        for c in cams:
            proj[c] = self.rig[c].project(pred)
            r = np.zeros(M)
            ra = np.zeros(M)
            for m in range(M):
                r[m], ra[m] = self._radius(k, direction, c, m, gaps[m])
            radius[c], ref_area[c] = r, ra
            W, H = self.size[c]
            fin = np.all(np.isfinite(proj[c]), axis=1)
            if not fin.any():
                cands[c] = Candidates(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
                continue
            lo = np.floor((proj[c][fin] - r[fin, None]).min(axis=0)) - 4
            hi = np.ceil((proj[c][fin] + r[fin, None]).max(axis=0)) + 4
            crop = (lo[0], lo[1], hi[0] + 1, hi[1] + 1)
            cp = self.cparams[c]
            cands[c] = frame_candidates(self.frames[c][k], self.thr[c], _area_range(cp), None, crop=crop,
                                        centroid=cp.centroid, light=True)
        # options per marker and camera
        for m in range(M):              # a marker with no prediction (or too stale a one) is not searched
            if predicted[m] and gaps[m] <= MAX_STALE_FRAMES:
                self._solve_marker(k, m, cams, proj, radius, ref_area, cands, pred[m], gaps[m])
            else:
                for c in cams:
                    self.reason[c][k, m] = "lost"
        self._resolve_shared(k, cands)
        self._check_rigid(k, pred)
        self._check_alone(k, gaps, pred, direction)
        self._rigid_rms(k)
        return bool(np.any(np.all(np.isfinite(self.X[k]), axis=1)))

    def _solve_marker(self, k, m, cams, proj, radius, ref_area, cands, pred, gap):
        options, why = [], {}
        for c in cams:
            W, H = self.size[c]
            p = proj[c][m]
            if not np.all(np.isfinite(p)) or p[0] < -radius[c][m] or p[1] < -radius[c][m] \
                    or p[0] > W - 1 + radius[c][m] or p[1] > H - 1 + radius[c][m]:
                options.append([-1])
                why[c] = "outside_image"
                continue
            cc = cands[c]
            d = np.linalg.norm(cc.centre - p, axis=1) if len(cc) else np.zeros(0)
            near = np.flatnonzero(d <= radius[c][m])
            near = near[np.argsort(d[near])][:MAX_OPTIONS]
            if len(near) == 0:
                options.append([-1])
                inside = 0 <= p[0] <= W - 1 and 0 <= p[1] <= H - 1
                why[c] = "occluded" if inside else "outside_image"
                continue
            good, rejected = [], []           # (the reason of the nearest rejected region is kept)
            ra = ref_area[c][m]
            for j in near:
                if cc.cut[j] and not _whole_inside(cc.centre[j], ra, (W, H)):
                    rejected.append("outside_image")
                elif np.isfinite(ra) and cc.area[j] > ra * AREA_FACTOR:
                    rejected.append("merged")
                elif np.isfinite(ra) and cc.area[j] < ra / AREA_FACTOR:
                    rejected.append("partly_occluded")
                else:
                    good.append(int(j))
            why[c] = rejected[0] if rejected else "occluded"
            options.append(good + [-1] if good else [-1])
        combos = np.array(list(itertools.product(*options)), dtype=int)
        nviews = (combos >= 0).sum(axis=1)
        combos = combos[nviews >= 2]
        used, dropped, why_all, edge = None, set(), None, set()
        if len(combos):
            X, worst, ok = _triangulate_rows(self.rig, cams, cands, combos, self.tol)
            if ok.any():
                dist = np.zeros(len(combos))
                for ci, c in enumerate(cams):
                    sel = combos[:, ci] >= 0
                    if sel.any():
                        dist[sel] += np.linalg.norm(cands[c].centre[combos[sel, ci]] - proj[c][m], axis=1) \
                            / radius[c][m]
                nv = (combos >= 0).sum(axis=1)
                cost = -100.0 * nv + dist + worst / self.tol
                cost[~ok] = np.inf
                # a marker cannot leave its predicted 3D position by half the marker spacing, and
                # between equally many views the point nearer the prediction in 3D wins (a wrong
                # view on the epipolar line moves the point along the other camera's ray)
                step = np.linalg.norm(X - pred, axis=1)
                cost = cost + 2.0 * step / self.max_step
                off = ok & ~(step <= self.max_step)
                cost[off] = np.inf
                if off.any() and not np.isfinite(cost).any():
                    why_all = "off_track"
                b = int(np.argmin(cost))
                if np.isfinite(cost[b]):          # else no combination is consistent and on track: none used
                    best, Xb, edge = self._without_edge_views(cams, cands, combos[b], X[b])
                    used, self.X[k, m], dropped = self._consistent_views(cams, cands, best, Xb)
        else:
            dropped = set()
        n_good = sum(1 for o in options if len(o) > 1)
        for ci, c in enumerate(cams):
            if used is not None and used[ci] < 0 and ci in edge and ci not in dropped:
                self._cand_index[(c, m)] = -1
                self.reason[c][k, m] = "outside_image"
                continue
            if used is not None and used[ci] >= 0:
                j = int(used[ci])
                self.px[c][k, m] = cands[c].centre[j]
                self.area[c][k, m] = cands[c].area[j]
                if cands[c].slope is not None:
                    self.slope[c][k, m] = cands[c].slope[j]
                    self.moments[c][k, m] = cands[c].moments[j]
                self.reason[c][k, m] = ""
                self._cand_index[(c, m)] = j
                continue
            self._cand_index[(c, m)] = -1
            if why_all and len(options[ci]) > 1:
                r = why_all
            elif ci in dropped or len(options[ci]) > 1:   # a good region was near, but not consistent with the others
                r = "single_view" if (used is None and n_good == 1) else "inconsistent_views"
            else:
                r = why.get(c, "occluded")
            self.reason[c][k, m] = r

    def _without_edge_views(self, cams, cands, combo, X):
        """Leave out the views whose region touches the image edge when two whole views remain.

        Such a region (:func:`_whole_inside`) only makes up a second view of
        a marker entering or leaving an image: its centre, from the part of
        the marker symmetric about it, is less precise than a whole one's,
        and it must not outvote a whole view in the consistency check.
        Returns the combination, its point and the views left out.
        """
        edge = [ci for ci in range(len(cams)) if combo[ci] >= 0 and cands[cams[ci]].cut[combo[ci]]]
        if not edge or (combo >= 0).sum() - len(edge) < 2:
            return combo, X, set()
        alt = combo.copy()
        alt[edge] = -1
        Xa, _, oka = _triangulate_rows(self.rig, cams, cands, alt[None], self.tol)
        if not oka[0]:
            return combo, X, set()
        return alt, Xa[0], set(edge)

    def _limit(self, c):
        """Largest leave-one-out residual (px) of a view of camera ``c``: six times its recent median.

        The residual of a view against the point triangulated from the other
        views; a centre biased by a region merged with a glint, or partly
        hidden, stands out from the camera's usual residuals (a fixed limit
        would be either blind to sub-pixel noise or to pixel biases).
        At least ``RESIDUAL_FLOOR_PX``, at most ``max_residual_px``.
        """
        hist = self._loo.get(c, [])
        if len(hist) < 5:
            return self.tol
        return float(min(self.tol, max(RESIDUAL_FLOOR_PX, 6.0 * np.median(hist[-60:]))))

    def _consistent_views(self, cams, cands, used, X):
        """Leave out, one at a time, the view whose leave-one-out residual breaks :meth:`_limit`."""
        dropped = set()
        while (used >= 0).sum() >= 3:
            loo = {}
            for ci in np.flatnonzero(used >= 0):
                rest = used.copy()
                rest[ci] = -1
                Xr, _, okr = _triangulate_rows(self.rig, cams, cands, rest[None], self.tol)
                if okr[0]:
                    c = cams[ci]
                    r = float(np.linalg.norm(self.rig[c].project(Xr[0]) - cands[c].centre[used[ci]]))
                    loo[int(ci)] = (r, r / self._limit(c), Xr[0])
            if not loo:
                break
            ci, (r, ratio, Xr) = max(loo.items(), key=lambda kv: kv[1][1])
            if ratio <= 1.0:
                for cj, (rj, _, _) in loo.items():
                    self._loo.setdefault(cams[cj], []).append(rj)
                break
            used = used.copy()
            used[ci] = -1
            X = Xr
            dropped.add(ci)
        return used, X, dropped

    def _drop_view(self, k, m, c, why):
        self.px[c][k, m] = np.nan
        self.area[c][k, m] = np.nan
        self.reason[c][k, m] = why
        self._cand_index[(c, m)] = -1
        self._retriangulate(k, m)

    def _retriangulate(self, k, m):
        seen = [c for c in self.cams if self.reason[c][k, m] == ""]
        if len(seen) < 2:
            self._reject(k, m, "single_view")
            return
        tri = triangulate(self.rig, {c: self.px[c][k:k + 1, m:m + 1] for c in seen}, mode="joint",
                          max_residual_px=self.tol)
        self.X[k, m] = tri.points[0, 0]
        if not np.all(np.isfinite(tri.points[0, 0])):
            self._reject(k, m, "inconsistent_views")

    def _resolve_shared(self, k, cands):
        """A region serves one marker only: two markers on one region are a merge in that camera."""
        for c in self.cams:
            owners = {}
            for m in range(self.M):
                j = self._cand_index.get((c, m), -1)
                if j >= 0:
                    owners.setdefault(j, []).append(m)
            for j, ms in owners.items():
                if len(ms) > 1:
                    for m in ms:
                        self._drop_view(k, m, c, "merged")

    def _check_alone(self, k, gaps, pred, direction):
        """A marker found alone is confirmed by no other marker's distance.

        It is used when every camera that can validate it does (at least
        three views with three or more cameras), or, seen by two, when its
        own track saw it in each of the two frames before and it lies within
        a quarter of the marker spacing of its constant-velocity prediction,
        in 3D or, in each of its two views, in that camera's image
        (:meth:`_on_image_tracks`; a marker entering or leaving the third
        camera's view while the others are out of sight). A 2-view point on a stale or borrowed track may be
        a chance match along an epipolar line, off in depth.
        """
        have = np.flatnonzero(np.all(np.isfinite(self.X[k]), axis=1))
        if len(have) != 1:
            return
        m = have[0]
        views = sum(self.reason[c][k, m] == "" for c in self.cams)
        if gaps[m] > 0:
            self._reject(k, m, "unconfirmed")
            return
        if views >= min(3, self.C):
            return
        hist, gap = self._history(k, direction, m)
        own = gap == 0 and len(hist) >= 2 and hist[0][0] == 1 and hist[1][0] == 2
        if not own:
            self._reject(k, m, "unconfirmed")
        elif not (np.linalg.norm(self.X[k, m] - pred[m]) <= 0.5 * self.max_step
                  or self._on_image_tracks(k, m, direction)):
            self._reject(k, m, "unconfirmed")

    def _on_image_tracks(self, k, m, direction) -> bool:
        """Does every view of marker ``m`` in frame ``k`` continue that camera's own image track?

        The depth of a point seen by two cameras only, near the edge of an
        image, carries the calibration's error there (several cm: its
        constant-velocity prediction in 3D misses by more than the quarter
        marker spacing allowed), while each camera's own centres move on
        smoothly. Each view must lie within the same quarter spacing, seen
        at the point's depth, of the constant-velocity prediction of the
        centres this camera gave the marker in the two frames before.
        """
        X = self.X[k, m]
        for c in self.cams:
            if self.reason[c][k, m] != "":
                continue
            j1, j2 = k - direction, k - 2 * direction
            if not (0 <= j2 < self.n and 0 <= j1 < self.n):
                return False
            p1, p2 = self.px[c][j1, m], self.px[c][j2, m]
            if not (np.all(np.isfinite(p1)) and np.all(np.isfinite(p2))):
                return False
            cam = self.rig[c]
            depth = float(cam.world_to_camera(X[None])[0, 2])
            if not depth > 0:
                return False
            gate = float(np.mean(cam.focal)) * 0.5 * self.max_step / depth
            if np.linalg.norm(self.px[c][k, m] - (2 * p1 - p2)) > gate:
                return False
        return True

    def _reject(self, k, m, why):
        """Marker ``m`` gets no position in frame ``k``: its used views are dropped with ``why``."""
        for c in self.cams:
            if self.reason[c][k, m] == "":
                self.px[c][k, m] = np.nan
                self.area[c][k, m] = np.nan
                self.reason[c][k, m] = why
        self.X[k, m] = np.nan

    def _check_rigid(self, k, pred):
        """Markers whose 3D distances to the others break the static shot's shape are rejected."""
        for _ in range(self.M):
            X = self.X[k]
            ok = np.flatnonzero(np.all(np.isfinite(X), axis=1))
            if len(ok) < 2:
                return
            seen = np.stack([[self.reason[c][k, m] == "" for c in self.cams] for m in ok])
            cov = point_uncertainty(self.rig, X[ok], seen, cameras=self.cams)
            bad = np.zeros(len(ok))
            for a, b in itertools.combinations(range(len(ok)), 2):
                d = np.linalg.norm(X[ok[a]] - X[ok[b]])
                tol = distance_tolerance(cov[a], cov[b], X[ok[a]], X[ok[b]], self.slack)
                if abs(d - self.model_d[ok[a], ok[b]]) > tol:
                    bad[a] += 1
                    bad[b] += 1
            if not bad.any():
                return
            # the marker in most violations goes; between equals nothing tells which is wrong: all go
            for worst in ok[bad == bad.max()]:
                self._reject(k, worst, "not_rigid")

    def seed_neighbour(self, k, direction):
        """Label frame ``k + direction`` on its own too, so that tracking starts with a velocity.

        Returns the frame tracking goes on from (``k + direction`` when it
        was labelled near the markers of frame ``k``, else ``k``).
        """
        j = k + direction
        if not 0 <= j < self.n:
            return k
        cands, vp, fit = self._label_whole_frame(j)
        if fit is None:
            return k
        step = np.linalg.norm(vp.points[fit.assignment] - self.X[k], axis=1)
        if not np.all(step < 2 * self.max_step):   # further than a marker spacing in one frame: not the same set
            return k
        self.start(j, cands, vp, fit)
        return j

    def run(self, k0, direction):
        """Follow the markers from frame ``k0`` to one end of the record.

        After ``MAX_LOST_FRAMES`` frames without any marker, or with a marker
        whose own track is lost, the set is looked for again in whole frames
        (as for the anchor), every frame, until it is found whole.
        """
        k, lost, partly = k0 + direction, 0, 0
        while 0 <= k < self.n:
            if (lost > MAX_LOST_FRAMES or partly > MAX_LOST_FRAMES) and self._reacquire(k):
                lost = partly = 0
                k = self.seed_neighbour(k, direction) + direction
                continue
            if lost <= MAX_LOST_FRAMES:       # (a marker lost alone: the others are followed meanwhile)
                found = self.step(k, direction)
                lost = 0 if found else lost + 1
                partly = partly + 1 if found and self._any_lost(k) else 0
            k += direction

    def _any_lost(self, k):
        return any(self.reason[c][k, m] == "lost" for c in self.cams for m in range(self.M))

    def _label_whole_frame(self, k, cands=None):
        """Candidates (searched without a prediction unless given), 3D points and model labelling of frame ``k``."""
        if cands is None:
            cands = _whole_frame_candidates(self.frames, k, self.cams, self.thr, self.cparams)
        vp, fit, _ = label_frame(self.rig, cands, self.model, self.M, self.tol, np.arange(self.M), self.slack)
        return cands, vp, fit

    def _reacquire_candidates(self, k):
        """Candidates of frame ``k`` for :meth:`_reacquire`, or None where it cannot succeed.

        Reacquiring needs every marker seen by ``min(3, C)`` cameras, and two
        markers never share a region (:func:`fit_marker_model`); regions cut
        by the border never take part (:func:`match_views`). So the cameras'
        counts of whole candidates, at most ``M`` each, must add up to
        ``M * min(3, C)``. The cameras are searched in turn, and the search
        stops when the cameras left cannot make up the count: in an empty
        arena (most of a long session) one camera's search usually settles
        it (issue 16). Exact: a frame rejected here fails the full test too.
        """
        need = self.M * min(3, self.C)
        gray = {c: self.frames[c][k] for c in self.cams}    # every camera read in turn (its reading ahead goes on)
        have, cands = 0, {}
        for i, c in enumerate(self.cams):
            left = self.M * (self.C - 1 - i)                # the most the cameras after this one can add
            whole, search = _whole_count(gray[c], self.thr[c], _area_range(self.cparams[c]))  # before the shape rule
            if have + min(whole, self.M) + left < need:
                return None
            cands[c] = search(_min_circ(self.cparams[c]), self.cparams[c].centroid, MAX_CANDIDATES_PER_CAMERA)
            have += min(int(np.count_nonzero(~cands[c].cut)), self.M)
            if have + left < need:
                return None
        return cands

    def _reacquire(self, k):
        cands = self._reacquire_candidates(k)
        if cands is None:
            return False
        cands, vp, fit = self._label_whole_frame(k, cands)
        if fit is None:
            return False
        # stricter than the anchor search (which picks the clearest of many frames): every marker
        # seen by every camera that should see it, and the shape as good as the anchor's
        views = (vp.index[fit.assignment] >= 0).sum(axis=1)
        if np.any(vp.missing[fit.assignment] > 0) or np.any(views < min(3, self.C)) \
                or fit.rms_m > 3 * self.anchor_rms + 0.003:
            return False
        self.start(k, cands, vp, fit)
        return True

    def result(self, model_index, k0, margin):
        px = {c: correct_light(self.px[c], self.slope[c], self.moments[c]) for c in self.cams}
        return Identification(
            marker_px=px, reason={c: r.astype(str) for c, r in self.reason.items()}, area=self.area,
            points=self.X, model_index=np.asarray(model_index, int), rigid_rms_m=self.rigid,
            thresholds=dict(self.thr), anchor_frame=int(k0), anchor_margin=float(margin), cameras=self.cams)


# --------------------------------------------------------------------------
# uneven light
# --------------------------------------------------------------------------
def correct_light(marker_px: np.ndarray, slope: np.ndarray, moments: np.ndarray, window: int = LIGHT_WINDOW,
                  min_count: int = 5) -> np.ndarray:
    """Centres of one camera freed of the pull of uneven light, pooled over each marker's track.

    A marker lit unevenly (brightness ``1 + s . (p - p0)`` across it) has its
    weighted centre ``S s`` from its disc's centre (``S`` the weights' second
    moments; :func:`~horsemocap.detection.filters.light_terms`): up to
    0.15 px on 1080p markers, the same in every frame of the marker's track
    while the lamps and the tape do not change. One frame's slope is too
    noisy to correct that frame alone (it would add more noise to the
    centres, and to the accelerations, than the bias it removes); the median
    slope of the marker's frames within ``window`` frames (at least
    ``min_count`` of them, else the nearest ``min_count``) is precise. The
    moments are pooled alike (their median over the same frames): the
    correction is the marker's steady offset, which hardly changes from
    frame to frame, so that it adds no motion of its own. (With each frame's
    own moments the offset follows the streak's length through the stride,
    and the slope, taken from a streak's interior, is not exact for a streak
    longer than the marker: the bundled session's chain of fits, whose
    motion is exactly a Fourier series, lost 2.6 -> 5.9 % of saddle
    acceleration.) Fewer than ``min_count`` slopes in the record: unchanged.

    Parameters
    ----------
    marker_px : (n, M, 2)
    slope : (n, M, 2)
        Per frame and marker (NaN: not measured).
    moments : (n, M, 2, 2)

    Returns
    -------
    (n, M, 2) corrected centres (NaN where ``marker_px`` is NaN).
    """
    out = np.array(marker_px, float, copy=True)
    for m in range(out.shape[1]):
        have = np.flatnonzero(np.all(np.isfinite(slope[:, m]), axis=1))
        if len(have) < min_count:
            continue
        with_s = np.flatnonzero(np.all(np.isfinite(moments[:, m]), axis=(1, 2)))
        if len(with_s) == 0:
            continue
        for k in np.flatnonzero(np.all(np.isfinite(out[:, m]), axis=1)):
            near = have[np.abs(have - k) <= window]
            if len(near) < min_count:
                near = have[np.argsort(np.abs(have - k), kind="stable")[:min_count]]
            near_s = with_s[np.abs(with_s - k) <= window]
            if len(near_s) == 0:
                near_s = with_s[np.argsort(np.abs(with_s - k), kind="stable")[:min_count]]
            S = np.median(moments[near_s, m], axis=0)
            out[k, m] = out[k, m] - S @ np.median(slope[near, m], axis=0)
    return out


# --------------------------------------------------------------------------
# gaps in 3D
# --------------------------------------------------------------------------
def default_max_gap(fps: float) -> int:
    """Longest gap bridged by interpolation: 0.1 s of frames, at least 2 (a few frames)."""
    return max(2, int(round(0.1 * float(fps))))


def bridge_gaps(points: np.ndarray, max_gap: int, context: int = 4):
    """Fill short runs of missing 3D positions by cubic interpolation.

    A run of at most ``max_gap`` NaN frames of one marker, with at least two
    measured frames on each side, is filled by a cubic spline through up to
    ``context`` measured frames on each side, within ``2 * context`` frames of
    the gap; longer runs and the record's ends stay NaN.

    Parameters
    ----------
    points : (n, M, 3)
    max_gap : int
    context : int

    Returns
    -------
    filled : (n, M, 3)
    interpolated : (n, M) bool
    """
    from scipy.interpolate import CubicSpline

    out = np.array(points, float, copy=True)
    n, M = out.shape[:2]
    interp = np.zeros((n, M), bool)
    for m in range(M):
        ok = np.all(np.isfinite(out[:, m]), axis=1)
        k = 0
        while k < n:
            if ok[k]:
                k += 1
                continue
            a = k
            while k < n and not ok[k]:
                k += 1
            b = k                                           # missing a..b-1
            if b - a > max_gap:
                continue
            left = np.flatnonzero(ok[:a])[-context:]
            right = np.flatnonzero(ok[b:])[:context] + b
            left = left[left >= a - 2 * context]              # anchors near the gap only (not across
            right = right[right < b + 2 * context]            # another gap, far from this one)
            if len(left) < 2 or len(right) < 2:
                continue
            t = np.concatenate([left, right])
            cs = CubicSpline(t, out[t, m], axis=0)
            out[a:b, m] = cs(np.arange(a, b))
            interp[a:b, m] = True
    return out, interp
