"""The rigid marker model of the static shot, and the markers of one frame labelled by it.

The static shot gives the skin markers' (and the saddle marker's) 3D
positions to a millimetre. The markers ride a rigid set: in every frame their
3D distances equal the static shot's within the measured uncertainty of a
triangulated point (:func:`point_uncertainty`, :func:`distance_tolerance`)
plus a skin slack, and their triangle faces the reference camera as in the
static shot (the thesis' cross-product rule of Figure 4.13, taken to 3D).
:func:`fit_marker_model` labels a frame's 3D points with the model;
:func:`label_frame` does the whole frame: correspondences
(:func:`~horsemocap.detection.matching.match_views`), the working volume
(:func:`in_working_volume`), then the labelling, which must be clear
(``MIN_MARGIN``).

Example
-------
>>> import numpy as np
>>> model = np.array([[0.0, 0.0, 5.0], [0.3, 0.0, 5.0], [0.1, 0.2, 5.0]])
>>> frame = np.vstack([model[[2, 0, 1]] + [0.5, 0.1, 0.0], [[1.0, 1.0, 5.0]]])   # shuffled, moved, one more
>>> cov = np.tile(np.eye(3) * 1e-6, (4, 1, 1))
>>> fit = fit_marker_model(frame, cov, model, 3, np.zeros(3))
>>> fit.assignment.tolist(), fit.model_index.tolist()
([1, 2, 0], [0, 1, 2])
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .base import DetectionError
from .matching import ViewPoints, match_views

__all__ = [
    "RIGID_SLACK_M", "ModelFit", "point_uncertainty", "distance_tolerance", "fit_marker_model",
    "in_working_volume", "label_frame",
]

#: Static-shot and skin-marker tolerance added to the measured uncertainty of a
#: 3D distance (m): markers on skin move by millimetres against each other.
RIGID_SLACK_M = 0.010
#: Detection noise (px, one sigma) assumed when converting the rig's geometry
#: into the 3D uncertainty of a point (a generous value).
PIXEL_SIGMA = 0.2
#: The markers of one frame have areas within this factor in every camera (as
#: for the stills, :func:`~horsemocap.detection.match_still_views`).
SIZE_SPREAD = 3.0
#: Cost of one camera that should see a labelled point and does not (a
#: normalised distance error of 1 costs 1).
MISSING_VIEW_COST = 0.5
#: The markers are looked for between these fractions and multiples of the
#: static shot's distance from the reference camera.
DEPTH_RANGE = (0.5, 2.0)
#: Smallest normalised cost difference between the best labelling and the runner-up.
MIN_MARGIN = 1.0


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

    Every ordered choice of ``n_markers`` distinct frame points
    (:func:`_rigid_assignments`: only those whose distances agree) is compared
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
    points = np.asarray(points, float)
    subsets = [np.asarray(model_index, int)] if model_index is not None else \
        [np.asarray(s, int) for s in itertools.combinations(range(len(model)), M)]
    pairs = list(itertools.combinations(range(M), 2))
    d_pts, tol_pts = _pair_distances(points, cov, slack_m)
    best = []
    for sub in subsets:
        ms = model[sub]
        model_d = np.array([[np.linalg.norm(ms[i] - ms[j]) for j in range(M)] for i in range(M)])
        perms = _rigid_assignments(d_pts, tol_pts, model_d)
        if not len(perms):
            continue
        ok = _region_rules(perms, areas, views)
        pts = points[perms]                                           # (K, M, 3)
        extra = (np.asarray(missing, float)[perms].sum(axis=1) * MISSING_VIEW_COST if missing is not None
                 else np.zeros(len(perms)))
        err = np.zeros(len(perms))
        for i, j in pairs:
            d = np.linalg.norm(pts[:, i] - pts[:, j], axis=-1)
            D = np.linalg.norm(ms[i] - ms[j])
            tol = distance_tolerance(cov[perms[:, i]], cov[perms[:, j]], pts[:, i], pts[:, j], slack_m)
            err += (np.abs(d - D) / tol) ** 2
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



#: Most assignments of a frame's points to the markers that agree with every model distance (beyond: a
#: cluttered frame, refused with a message).
MAX_ASSIGNMENTS = 200000


def _pair_distances(points, cov, slack_m):
    """Distances ``(P, P)`` between the frame's points and their tolerances (:func:`distance_tolerance`)."""
    a, b = np.triu_indices(len(points), 1)
    d = np.zeros((len(points), len(points)))
    tol = np.zeros((len(points), len(points)))          # (0 on the diagonal: a point serves one marker)
    d[a, b] = d[b, a] = np.linalg.norm(points[a] - points[b], axis=-1)
    tol[a, b] = tol[b, a] = distance_tolerance(cov[a], cov[b], points[a], points[b], slack_m)
    return d, tol


def _rigid_assignments(d_pts, tol_pts, model_d) -> np.ndarray:
    """Every ordered choice of ``M`` distinct points whose pairwise distances all agree with the model's.

    Built marker by marker: a point joins an assignment only when its
    distance to each point already chosen is within tolerance of the
    model's (``|d - D| / tol <= 1``), so the choices that break a distance
    are never listed (the search stays small with four or more markers in a
    cluttered frame). Lexicographic order, as :func:`itertools.permutations`.

    Examples
    --------
    >>> pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0], [5, 5, 5]])
    >>> d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    >>> tol = np.full(d.shape, 0.01)
    >>> _rigid_assignments(d, tol, d[:3, :3]).tolist()
    [[0, 1, 2]]
    """
    P, M = len(d_pts), len(model_d)
    prefix = np.arange(P)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        for level in range(1, M):
            fits = np.ones((len(prefix), P), bool)
            for i in range(level):
                fits &= np.abs(d_pts[prefix[:, i]] - model_d[i, level]) / tol_pts[prefix[:, i]] <= 1.0
            rows, cols = np.nonzero(fits)
            if len(rows) > MAX_ASSIGNMENTS:
                raise DetectionError(f"identification: {P} consistent 3D points in one frame are too many to "
                                     "label; give a higher threshold or a smaller area range")
            prefix = np.column_stack([prefix[rows], cols])
            if not len(prefix):
                break
    return prefix.astype(np.intp).reshape(-1, M)


def _region_rules(perms, areas, views) -> np.ndarray:
    """Assignments that give no region of a camera to two markers and whose markers' areas are alike."""
    size_ok = np.ones(len(perms), bool)
    if views is not None:                      # a region of one camera serves one marker only
        idx = np.asarray(views, int)[perms]                          # (K, M, C)
        srt = np.sort(idx, axis=1)
        size_ok &= ~np.any((srt[:, 1:] == srt[:, :-1]) & (srt[:, 1:] >= 0), axis=(1, 2))
    if areas is not None:
        la = np.log(np.asarray(areas, float))[perms]               # (K, M, C), NaN where unseen
        spread = np.fmax.reduce(la, axis=1) - np.fmin.reduce(la, axis=1)
        size_ok &= np.all(~(spread > math.log(SIZE_SPREAD)), axis=1)   # (and kept the shared-region rule)
    return size_ok


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
                model_index=None, slack_m: float = RIGID_SLACK_M) -> tuple[ViewPoints, ModelFit | None, str]:
    """Correspondences (:func:`~horsemocap.detection.matching.match_views`) and labels (:func:`fit_marker_model`)
    of one frame.

    The points in the working volume (:func:`in_working_volume`) are
    labelled with their uncertainty (:func:`point_uncertainty`), their
    missing views, their region areas and regions; a labelling whose margin
    over the runner-up is below ``MIN_MARGIN`` is ambiguous and not taken.

    Parameters
    ----------
    rig : horsemocap.camera.Rig
    cands : dict camera -> :class:`~horsemocap.detection.candidates.Candidates`
    model : (S, 3) static-shot points
    n_markers : int
    max_residual_px : float
    model_index : (M,) int, optional: the skin markers among the static points
    slack_m : float

    Returns
    -------
    (ViewPoints, ModelFit or None, why)
        ``why`` says what failed (``""`` when labelled).
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

