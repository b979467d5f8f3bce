"""Markers identified by all cameras together and followed in 3D (seed 000 sec. 5).

The thesis finds the markers of each camera on its own (chapter 4, the chain
of :mod:`~horsemocap.detection.thesis_chain`). One camera alone cannot tell a
marker from a round bright pseudo marker: a shining stirrup, a buckle, a
glint, a reflector that crosses the markers. The cameras together can. A real
marker

1. is a 3D point whose projections are candidate regions in every camera that
   sees it (the epipolar constraint for two cameras, validation by a further
   camera for three: seed 000, sec. 5.2.3;
   :mod:`~horsemocap.detection.matching`);
2. belongs to a rigid set whose 3D side lengths the static shot gives to a
   millimetre, with the handedness of the static shot
   (:mod:`~horsemocap.detection.marker_model`);
3. moves smoothly: its next position is predicted with minimum acceleration
   over the last frames (seed 000 sec. 5.2.4), and it is looked for near the
   projection of that prediction in every camera, in a search radius that
   widens while it is missed (this module's tracker).

:func:`identify_markers` runs the whole chain over a synchronised session:
candidates of every camera (:mod:`~horsemocap.detection.candidates`: the
thesis' threshold eq. 4.5, labels 4.5.2 and area 4.5.3, plus circularity),
correspondences across cameras, labelling by the rigid model of the static
shot, then tracking in 3D forward and backward from the frame where the
labelling is clearest. Every rejected 2D value keeps its reason
(:data:`IDENTIFICATION_REASONS`; :func:`reason_counts` sums them up).

A marker seen by at least two cameras gets a 3D position; a marker seen by
one camera only is not used (its identity cannot be validated) and is NaN
with reason ``single_view``. Gaps of a few frames in every camera are bridged
later, in 3D (:func:`~horsemocap.detection.gaps.bridge_gaps`), and marked
``interpolated``.

Example
-------
>>> import numpy as np
>>> reason = {"left": np.array([["", "occluded"], ["", ""]]), "right": np.array([["merged", ""], ["", ""]])}
>>> reason_counts(reason)
'left: used 3 of 4, occluded 1; right: used 3 of 4, merged 1'
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..reconstruction import DEFAULT_MAX_RESIDUAL_PX, triangulate
from ..subframe import whole_frames_gained
from .base import DetectionError, DetectionParams
from .candidates import (MAX_CANDIDATES_PER_CAMERA, Candidates, ClockFollowingFrames, candidate_area_range,
                         candidate_min_circularity, correct_light, frame_candidates, source_frame,
                         whole_frame_candidates, whole_frame_count)
from .marker_model import RIGID_SLACK_M, distance_tolerance, label_frame, point_uncertainty
from .matching import candidates_at_instant, triangulate_rows
from .thresholds import auto_threshold

__all__ = ["IDENTIFICATION_REASONS", "Identification", "identify_markers", "reason_counts"]

#: Reasons of a missing or rejected 2D value (``""`` = used for the 3D point).
IDENTIFICATION_REASONS = {
    "": "found and used",
    "occluded": "not seen near its predicted position inside the image",
    "outside_image": "predicted outside the image, or its region is cut by the image border",
    "inconsistent_views": "a region lies near the prediction, but its ray disagrees with the other cameras",
    "not_rigid": "triangulates consistently but breaks the marker set's rigid shape (a stirrup, a glint)",
    "merged": "its region merged with another bright region (far larger than the marker's): centre biased",
    "partly_occluded": "its region is far smaller than the marker's recent area: centre biased",
    "partly_covered": "its region shrank and lost the marker's own shape (a leg, a rein, a hand over part of it): "
                      "centre biased",
    "single_view": "seen by one camera only: its identity cannot be validated by another camera",
    "off_track": "consistent in the cameras, but further from the predicted 3D position than a marker moves",
    "unconfirmed": "found alone (no other marker confirms its distance) on an extrapolated track or by too few cameras",
    "lost": "its own track is lost (unseen for more frames than a prediction holds); found again "
            "when the marker set is labelled anew",
    "not_tracked": "the marker set is not followed in this frame (not in view, or lost)",
    "not_read": "a frame of a camera whose clock drifts by whole frames that no reference instant compared (its "
                "clock runs fast, or the frame lies past the reference's last instant)",
}
#: A region whose area is more than this factor away from the marker's recent
#: area in that camera is a merge (or a partial occlusion): its centre is biased.
AREA_FACTOR = 1.6
#: A region is partly covered (:func:`shape_change`) when its area is below this share of the marker's
#: recent area in that camera ...
COVER_AREA = 0.85
#: ... and the marker's spread along some direction is below this share of its recent spread (variance
#: ratio): a disc covered beyond a chord keeps 0.78 of its area and 0.59 of its variance across the chord
#: at a fifth covered, 0.67 and 0.45 at a third.
COVER_SPREAD = 0.72
#: Frames looked back for the marker's recent shape in a camera (a cover may last longer than the search's
#: area memory), the used views its median is taken over, and the frames just before left out of it.
SHAPE_MEMORY = 60
SHAPE_VIEWS = 9
SHAPE_LAG = 4
#: Smallest leave-one-out residual limit (px) of a view (see ``_Tracker._limit``).
RESIDUAL_FLOOR_PX = 0.3
#: The most candidates of one camera tried for one marker (the nearest its prediction).
MAX_OPTIONS = 3
#: Frames without any marker after which the set is looked for again in whole frames.
MAX_LOST_FRAMES = 10
#: A marker neither seen lately nor carried by the others is looked for this many frames on its
#: own extrapolated track, then no more (until the set is found again).
MAX_STALE_FRAMES = 3


def shape_change(area, moments, ref_area, ref_moments) -> tuple[float, float]:
    """How a region's size and shape compare with a marker's recent ones in the same camera.

    Returns ``(area_ratio, spread_ratio)``: the region's area over the
    reference area, and the smallest eigenvalue of ``S_ref^-1/2 S S_ref^-1/2``
    (``S`` the weights' second central moments, px^2): the smallest ratio of
    the region's variance to the reference's along any direction. A marker
    partly covered by something dark shrinks (area) and loses spread across
    the covering edge; one seen whole keeps both near 1 whatever its smear
    (the reference is its own recent shape). NaN when a term is missing.

    Examples
    --------
    >>> S = np.diag([4.0, 2.0])
    >>> shape_change(60.0, S, 60.0, S)
    (1.0, 1.0)
    >>> a, s = shape_change(40.0, np.diag([1.8, 2.1]), 60.0, S)
    >>> round(a, 3), round(s, 3)
    (0.667, 0.45)
    """
    S, R = np.asarray(moments, float), np.asarray(ref_moments, float)
    if not (np.all(np.isfinite(S)) and np.all(np.isfinite(R)) and np.isfinite(area) and np.isfinite(ref_area)
            and ref_area > 0):
        return float("nan"), float("nan")
    w, V = np.linalg.eigh(R)
    if w.min() <= 0:
        return float(area / ref_area), float("nan")
    Ri = V @ np.diag(w ** -0.5) @ V.T
    return float(area / ref_area), float(np.linalg.eigvalsh(Ri @ S @ Ri).min())


def same_marker_set(before, after, max_step: float) -> bool:
    """Are the markers labelled in two neighbouring frames the same markers under the same labels?

    The set moves as a whole: at a canter it travels more than its
    smallest marker spacing in one frame, so how far the markers moved
    tells nothing about their labels. A label given to another marker
    moves that marker by a marker spacing *against the others*. Each
    marker's displacement less the set's common displacement (the
    median, robust to one wrong label) must stay within ``max_step``
    (half the smallest spacing; the set's rotation and the points' noise
    in one frame are far smaller).

    Parameters
    ----------
    before, after : (M, 3)
        The markers' positions (m) in the two frames, in label order.
    max_step : float
        Half the smallest marker spacing (m).

    Returns
    -------
    bool
        False also when a position is missing.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0.0, 0, 0], [0.2, 0, 0], [0, 0.3, 0]])
    >>> same_marker_set(X, X + [0.25, 0.0, 0.01], 0.1)   # the whole set ran 25 cm
    True
    >>> same_marker_set(X, X[[1, 0, 2]], 0.1)            # two labels swapped
    False
    """
    before, after = np.asarray(before, float), np.asarray(after, float)
    if not (np.all(np.isfinite(before)) and np.all(np.isfinite(after))):
        return False
    step = after - before
    relative = np.linalg.norm(step - np.median(step, axis=0), axis=1)
    return bool(np.all(relative < max_step))


def reason_counts(reason: dict) -> str:
    """How often each reason of :data:`IDENTIFICATION_REASONS` was given, per camera, for an error message.

    Parameters
    ----------
    reason : dict camera -> array of str
        The reasons (:attr:`Identification.reason`), frames x markers.

    Returns
    -------
    str
        Per camera the values used (``""``) of all, then every other reason
        with its count, most frequent first:
        ``"left: used 880 of 1000, not_tracked 108, occluded 12; middle: ..."``.

    Example
    -------
    >>> import numpy as np
    >>> reason_counts({"left": np.array([["", "lost"], ["occluded", "lost"]])})
    'left: used 1 of 4, lost 2, occluded 1'
    """
    parts = []
    for cam, r in reason.items():
        names, counts = np.unique(np.asarray(r, dtype=object).ravel().astype(str), return_counts=True)
        tally = {str(k): int(n) for k, n in zip(names, counts)}
        used, total = tally.pop("", 0), int(np.size(r))
        found = sorted(((n, k) for k, n in tally.items()), key=lambda t: (-t[0], t[1]))
        parts.append(f"{cam}: used {used} of {total}" + "".join(f", {k} {n}" for n, k in found))
    return "; ".join(parts)


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


def _camera_params(params, cams) -> dict:
    """Each camera's :class:`DetectionParams`: ``params`` for all, or a dict camera -> params (default ones
    for a camera not in it, and for all when None)."""
    p = params or {}
    if isinstance(p, DetectionParams):
        return {c: p for c in cams}
    return {c: p.get(c) or DetectionParams() for c in cams}


def _middle_out(n, step) -> list:
    """Frames ``0..n-1`` every ``step`` frames from the middle outward: ``n // 2``, then ``+step``, ``-step``, ..."""
    mid = n // 2
    out = [mid]
    for d in range(step, n, step):
        for k in (mid + d, mid - d):
            if 0 <= k < n:
                out.append(k)
    return out


#: Frames labelled on their own before the skin markers among the static shot's points are
#: chosen (the choice most of them agree on; see :func:`_find_anchor`).
ANCHOR_VOTES = 5


@dataclass(frozen=True)
class CameraDelay:
    """When a camera not exposing at the reference instants sees its rows, in frames after the reference instant.

    Its frame ``k``'s row 0 is seen ``start + drift x k`` frames after the
    reference instant ``k`` (its phase at frame 0 plus the start given in
    ``row_timing``; ``drift``: its rate ratio minus 1, the phase its clock
    gains per frame), row ``r`` a further ``r / height x readout`` (a
    rolling shutter). With ``gained`` (:func:`~horsemocap.subframe.whole_frames_gained`,
    a drift of a frame or more over the record) the frame compared at the reference
    instant ``k`` is its frame ``j = k - gained[k]``
    (:class:`~horsemocap.detection.candidates.ClockFollowingFrames`), seen
    ``start + drift x j - gained[k]`` frames after ``k``.

    Examples
    --------
    >>> d = CameraDelay(start=0.25, readout=0.5, height=480.0, drift=1e-4)
    >>> [round(float(v), 4) for v in d.at(np.array([[10.0, 0.0], [10.0, 240.0]]), k=1000)]
    [0.35, 0.6]
    >>> far = CameraDelay(start=0.25, readout=0.0, height=480.0, drift=1e-3, gained=np.array([0] * 500 + [1] * 500))
    >>> round(float(far.at(np.array([[10.0, 0.0]]), k=900)[0]), 4)      # its frame 899: 0.25 + 0.899 - 1
    0.149
    """
    start: float
    readout: float
    height: float
    drift: float = 0.0
    gained: np.ndarray | None = field(default=None, compare=False)

    def at(self, centre: np.ndarray, k: int = 0) -> np.ndarray:
        """Frames after the reference instant ``k`` at which regions at ``centre`` (K, 2) of the frame compared
        there were seen."""
        g = 0 if self.gained is None else int(self.gained[k])
        return self.start + self.drift * (k - g) - g + np.asarray(centre, float)[:, 1] / self.height * self.readout


def _camera_timing(cams, phase, row_timing, rig, rate_ratio=None, *, n: int) -> dict:
    """Camera -> :class:`CameraDelay` (its phase, rate ratio, the whole frames its clock gains over the ``n``
    frames when they reach one, and the start given in ``row_timing``), only for the cameras not exposing at
    the reference instants."""
    out = {}
    for c in cams:
        start, readout = (row_timing or {}).get(c, (0.0, 0.0))
        start = float((phase or {}).get(c, 0.0)) + float(start)
        rate = float((rate_ratio or {}).get(c, 1.0))
        gained = whole_frames_gained(rate, n)
        if start != 0.0 or float(readout) != 0.0 or rate != 1.0:
            out[c] = CameraDelay(start, float(readout), float(rig[c].size[1]), rate - 1.0,
                                 gained if gained.any() else None)
    return out


def _following_the_clocks(frames: dict, timing: dict) -> dict:
    """Each camera's frames, read at the reference instants (:class:`ClockFollowingFrames`) where its clock gains
    whole frames over the record."""
    return {c: (ClockFollowingFrames(seq, timing[c].gained) if c in timing and timing[c].gained is not None
                else seq) for c, seq in frames.items()}


def _in_own_frames(idn: "Identification", timing: dict) -> "Identification":
    """``idn`` identified on :func:`_following_the_clocks`' frames, with each camera's 2D values back in its own
    frames' numbering: frame ``k - gained[k]`` holds what the reference instant ``k`` compared (a frame compared
    at two instants keeps a used view; a frame compared at none is NaN, ``not_read``)."""
    px, reason, area = dict(idn.marker_px), dict(idn.reason), dict(idn.area)
    for c, d in timing.items():
        if d.gained is None or c not in px:
            continue
        n = len(d.gained)
        src = np.arange(n) - d.gained
        inside = np.broadcast_to(((src >= 0) & (src < n))[:, None], idn.reason[c].shape)
        px[c], area[c] = np.full_like(idn.marker_px[c], np.nan), np.full_like(idn.area[c], np.nan)
        reason[c] = np.full(idn.reason[c].shape, "not_read", dtype=object)      # not cut to the reasons' width
        for pick in (inside, inside & (idn.reason[c] == "")):     # every view read, then the used ones over them
            k, m = np.nonzero(pick)
            px[c][src[k], m] = idn.marker_px[c][k, m]
            reason[c][src[k], m] = idn.reason[c][k, m]
            area[c][src[k], m] = idn.area[c][k, m]
        reason[c] = reason[c].astype(object if idn.reason[c].dtype == object else str)
    return replace(idn, marker_px=px, reason=reason, area=area)


def _candidates_at_reference(frames, k, cams, thr, cparams, timing, cands=None,
                             search=None) -> tuple[dict, dict]:
    """Frame ``k``'s candidates of every camera (``cands`` when already searched), and the same moved to the
    reference instant ``k``.

    A camera whose frame ``k`` shows a region at the instant ``k + delay``
    (free running: its phase; a rolling shutter: plus its row's time;
    :func:`_camera_timing`) has its candidates moved by ``-delay`` frames
    along their image motion
    (:func:`~horsemocap.detection.matching.candidates_at_instant`, with
    frames ``k - 1`` and ``k + 1``), so the cameras are compared at one
    instant; a camera exposing at ``k`` is its own.
    """
    search = search or whole_frame_candidates
    cands = search(frames, k, cams, thr, cparams) if cands is None else cands
    moving = [c for c in cams if c in (timing or {})]
    if not moving:
        return cands, cands
    moved = dict(cands)
    for c in moving:
        before, after = _neighbours(frames[c], k, c, thr, cparams, search)
        moved[c] = candidates_at_instant(before, cands[c], after, -timing[c].at(cands[c].centre, k))
    return cands, moved


def _neighbours(seq, k: int, c: str, thr: dict, cparams: dict, search) -> tuple:
    """Camera ``c``'s candidates in the frames of its own just before and after the one frame ``k`` of ``seq``
    is (:func:`~horsemocap.detection.candidates.source_frame`), None outside its frames."""
    own, j = source_frame(seq, k)
    return tuple(search({c: own}, i, [c], thr, cparams)[c] if 0 <= i < len(own) else None for i in (j - 1, j + 1))


def _find_anchor(frames, rig, cams, thr, cparams, model, M, model_index, max_residual_px, step, timing=None,
                 search=None):
    """The first frame (middle of the record outward) labelled clearly, and the skin markers.

    The static shot holds the skin markers and the saddle marker; which of
    its points are the skin markers is decided by up to ``ANCHOR_VOTES``
    clearly labelled frames together: the subset most of them chose (ties:
    the smaller median shape error), so one frame in which a pseudo marker
    rigid with the horse completes a look-alike of another subset (the horse
    half in view, say) does not decide it. The anchor is the first of the
    frames that chose it.

    Free-running cameras (``timing``: :func:`_camera_timing`) are compared at the reference
    instants: their candidates are moved there first
    (:func:`_candidates_at_reference`), as a marker moves tens of
    millimetres in a fraction of a frame at trot and the 3D distances the
    subsets are told apart by would change with it. The returned
    candidates are the frame's own (the centres measured), indexed as the
    labelling's views.

    Returns ``((k, cands, vp, fit) or None, tried, votes)``: ``tried`` lists
    ``(frame, why)`` of the frames without a clear labelling, ``votes`` maps
    each chosen subset to its frames.
    """
    n = len(frames[cams[0]])
    tried, fits = [], []
    single = model_index is not None or len(model) == M
    for k in _middle_out(n, step):
        cands, moved = _candidates_at_reference(frames, k, cams, thr, cparams, timing, search=search)
        vp, fit, why = label_frame(rig, moved, model, M, max_residual_px, model_index)
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
                     progress=None, phase: dict | None = None, row_timing: dict | None = None,
                     rate_ratio: dict | None = None, whole_frames=None) -> Identification:
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
    phase : dict camera -> float, optional
        Free-running cameras: camera ``c``'s frame ``k`` shows the instant
        ``k + phase[c]`` (reference frames; the flash's estimate, see
        :mod:`horsemocap.subframe`). The labelling that chooses the skin
        markers, and the tracking, compare the cameras at the reference
        instants. Absent or 0: the cameras expose together.
    rate_ratio : dict camera -> float, optional
        A camera whose clock runs at another rate than the reference's:
        ``phase`` is its phase at frame 0, which then grows by
        ``rate_ratio[c] - 1`` frame per frame (:func:`~horsemocap.subframe.camera_frames`).
        Absent or 1: the phase holds over the record. Where the drift reaches whole frames, each
        reference instant compares the camera's frame that keeps its delay within half a frame of the
        phase at frame 0 (:func:`~horsemocap.subframe.whole_frames_gained`); the result is in each
        camera's own frames.
    whole_frames : callable, optional
        The whole-frame search, with :func:`~horsemocap.detection.candidates.whole_frame_candidates`' arguments
        (the default); :meth:`~horsemocap.detection.candidates.WholeFrameSearches.of_offsets` keeps the searches
        for the identifications of the same recording that follow.
    row_timing : dict camera -> (start, readout), optional
        When a camera's rows are seen, in frames: row 0 ``start`` after its
        frame's instant (a quarter of a frame for interlaced fields, whose
        blobs' centres lie half-way between the fields), row ``r`` of
        ``height`` a further ``r / height x readout`` (a rolling shutter;
        :func:`~horsemocap.subframe.observation_instants`).

    Returns
    -------
    Identification

    Raises
    ------
    DetectionError
        No frame in which the static shot's marker set is seen consistently
        (naming the cameras, the frames tried and why).
    """
    cams, static_points, n = _checked_inputs(frames, rig, static_points, int(n_markers))
    M = int(n_markers)
    progress = progress or (lambda *a: None)
    cparams = _camera_params(params, cams)
    thr = _thresholds(frames, cams, cparams, n)
    step = max(1, min(8, n // 30))
    timing = _camera_timing(cams, phase, row_timing, rig, rate_ratio, n=n)
    frames = _following_the_clocks(frames, timing)
    found, tried, votes = _find_anchor(frames, rig, cams, thr, cparams, static_points, M, None,
                                       max_residual_px, step, timing, whole_frames)
    if found is None:
        why = "; ".join(f"frame {k}: {w}" for k, w in tried[:6])
        raise DetectionError(
            f"identification: no frame in which cameras {list(cams)} see the static shot's {M} markers "
            f"consistently (thresholds {thr}; tried {len(tried)} frames, e.g. {why}); check the rig, the "
            "static stills, the threshold, or use detection_method 'thesis'")
    k0, cands0, vp0, fit0 = found
    tracker = _Tracker(frames, rig, cams, thr, cparams, static_points[fit0.model_index], M,
                       max_residual_px, slack_m, n, timing, whole_frames)
    tracker.anchor_rms = fit0.rms_m
    tracker.start(k0, cands0, vp0, fit0)
    if len(votes) > 1:
        progress("detect", "the skin markers among the static shot's points, as labelled frame by frame: "
                 + "; ".join(f"points {list(sub)} in frames {ks}" for sub, ks in votes.items())
                 + f"; taken: {[int(i) for i in fit0.model_index]}")
    progress("detect", f"markers labelled in synchronised frame {k0} (model fit {1000 * fit0.rms_m:.1f} mm rms); "
                       "following them in 3D ...")
    for direction in (1, -1):
        k1 = tracker.seed_neighbour(k0, direction)
        tracker.run(k1, direction)
    tracker.flag_covered_views()
    return _in_own_frames(tracker.result(fit0.model_index, k0, fit0.margin), timing)


def _checked_inputs(frames: dict, rig, static_points, M: int):
    """``(cameras, static points as floats, frames per camera)`` of :func:`identify_markers`' input, or a
    ValueError naming what is wrong."""
    cams = tuple(c for c in rig.names if c in frames)
    if len(cams) < 2:
        raise ValueError(f"identification: need at least two cameras, got {list(frames)}")
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
    return cams, static_points, n


def _thresholds(frames: dict, cams, cparams: dict, n: int) -> dict:
    """Each camera's threshold: its parameter's, else :func:`auto_threshold` of 8 frames spread over the record."""
    thr = {}
    for c in cams:
        if cparams[c].threshold is not None:
            thr[c] = int(cparams[c].threshold)
        else:
            sample = np.unique(np.linspace(0, n - 1, min(n, 8)).round().astype(int))
            thr[c] = auto_threshold([frames[c][i] for i in sample], cparams[c].threshold_method)
    return thr


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

    def __init__(self, frames, rig, cams, thr, cparams, model, M, max_residual_px, slack_m, n, timing=None,
                 search=None):
        self.frames, self.rig, self.cams, self.thr, self.cparams = frames, rig, cams, thr, cparams
        #: The whole-frame search (None: :func:`whole_frame_candidates`; or one that keeps its searches).
        self.search = search
        #: The cameras not exposing at the reference instants (:func:`_camera_timing`).
        self.timing = dict(timing or {})
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
        pair = self._two_own_frames(c, recent)
        if pair is not None:
            first, second, apart = pair
            motion = 0.5 * float(np.linalg.norm(self.px[c][first, m] - self.px[c][second, m])) / abs(apart)
        else:
            motion = 0.08 * max(self.size[c])
        return (2.0 * size + 2.0 + motion) * (1.0 + 0.5 * gap), ref_area

    # -- one frame ---------------------------------------------------------
    def step(self, k, direction):
        """Follow the markers into frame ``k`` (``direction`` +1 or -1); True when any marker was found."""
        pred, gaps = self._predict(k, direction)
        self._direction, self._pred = direction, pred
        predicted = np.all(np.isfinite(pred), axis=1)
        if not predicted.any():
            return False
        self._cand_index = {}
        proj, radius, ref_area, cands = self._predicted_candidates(k, direction, pred, gaps)
        for m in range(self.M):         # a marker with no prediction (or too stale a one) is not searched
            if predicted[m] and gaps[m] <= MAX_STALE_FRAMES:
                self._solve_marker(k, m, self.cams, proj, radius, ref_area, cands, pred[m])
            else:
                for c in self.cams:
                    self.reason[c][k, m] = "lost"
        self._resolve_shared(k, cands)
        self._check_rigid(k, pred)
        self._check_alone(k, gaps, pred, direction)
        self._rigid_rms(k)
        return bool(np.any(np.all(np.isfinite(self.X[k]), axis=1)))

    def _predicted_candidates(self, k, direction, pred, gaps):
        """Per camera: the projections of the predictions ``pred``, each marker's search radius and reference
        area (:meth:`_radius`), and the candidates (with their light terms) in the crop around them."""
        M = self.M
        proj, radius, ref_area, cands = {}, {}, {}, {}
        for c in self.cams:
            proj[c] = self.rig[c].project(pred)
            r = np.zeros(M)
            ra = np.zeros(M)
            for m in range(M):
                r[m], ra[m] = self._radius(k, direction, c, m, gaps[m])
            radius[c], ref_area[c] = r, ra
            fin = np.all(np.isfinite(proj[c]), axis=1)
            if not fin.any():
                cands[c] = Candidates(np.zeros((0, 2)), np.zeros(0), np.zeros(0, bool))
                continue
            lo = np.floor((proj[c][fin] - r[fin, None]).min(axis=0)) - 4
            hi = np.ceil((proj[c][fin] + r[fin, None]).max(axis=0)) + 4
            crop = (lo[0], lo[1], hi[0] + 1, hi[1] + 1)
            cp = self.cparams[c]
            cands[c] = frame_candidates(self.frames[c][k], self.thr[c], candidate_area_range(cp), None, crop=crop,
                                        centroid=cp.centroid, light=True)
        return proj, radius, ref_area, cands

    def _solve_marker(self, k, m, cams, proj, radius, ref_area, cands, pred):
        """Marker ``m`` in frame ``k``: its best consistent views near the prediction ``pred``, recorded."""
        self._shape_ref = {c: self._reference_shape(k, c, m) for c in cams}
        options, why = self._view_options(m, cams, proj, radius, ref_area, cands)
        self._k, self._m = k, m
        at_ref = self._at_reference(k, m, cands)
        used, dropped, why_all, edge = self._best_views(k, m, cams, proj, radius, at_ref, pred, options)
        self._record_views(k, m, cams, cands, options, why, used, dropped, why_all, edge)

    def _image_velocity(self, k, c, m) -> np.ndarray:
        """Marker ``m``'s image motion (px per frame, forward in time) in camera ``c`` before frame ``k``
        (tracking order), from its last two centres within three frames; zero when unknown."""
        direction = getattr(self, "_direction", 1)
        seen = [j for j in (k - direction * i for i in (1, 2, 3))
                if 0 <= j < self.n and np.all(np.isfinite(self.px[c][j, m]))]
        pair = self._two_own_frames(c, seen)
        if pair is None:
            return np.zeros(2)
        a, b, apart = pair
        return (self.px[c][a, m] - self.px[c][b, m]) / apart

    def _two_own_frames(self, c, frames) -> tuple | None:
        """``(a, b, apart)``: the first of ``frames`` and the next of them that shows another of camera ``c``'s own
        frames (a drifting clock's frame may be compared at two instants: :func:`_following_the_clocks`), and how
        many of its own frames ``b``'s is before ``a``'s; None when there is no such pair."""
        own = [source_frame(self.frames[c], j)[1] for j in frames]
        later = [i for i in range(1, len(frames)) if own[i] != own[0]]
        return None if not later else (frames[0], frames[later[0]], own[0] - own[later[0]])

    def _at_reference(self, k, m, cands) -> dict:
        """The candidates of a free-running camera moved to the reference instant ``k`` for marker ``m``.

        Camera ``c``'s frame ``k`` shows a region at the instant ``k +
        delay`` (:meth:`CameraDelay.at`); near marker ``m`` its regions are moved by
        ``-delay`` frames of the marker's own image motion
        (:meth:`_image_velocity`), so its views are triangulated and checked
        against the other cameras' at one instant. The recorded centres stay
        the measured ones. Cameras exposing at ``k``: the candidates themselves.
        """
        out = dict(cands)
        for c, timing in self.timing.items():
            if len(cands[c]) == 0:
                continue
            v = self._image_velocity(k, c, m)
            if not np.any(v):
                continue
            cc = cands[c]
            out[c] = Candidates(cc.centre - timing.at(cc.centre, k)[:, None] * v, cc.area, cc.cut, cc.slope,
                                cc.moments)
        return out

    def _reference_shape(self, k, c, m):
        """Marker ``m``'s recent area and second moments in camera ``c``, or NaNs.

        Medians of its last :data:`SHAPE_VIEWS` used views within
        :data:`SHAPE_MEMORY` frames before ``k`` in tracking order, leaving
        out the :data:`SHAPE_LAG` frames just before ``k``: a cover sliding
        in a little each frame would otherwise carry the reference with it.
        """
        direction = getattr(self, "_direction", 1)
        j, recent = k - direction * (1 + SHAPE_LAG), []
        while 0 <= j < self.n and len(recent) < SHAPE_VIEWS and abs(k - j) <= SHAPE_MEMORY:
            if self.reason[c][j, m] == "" and np.isfinite(self.area[c][j, m]) \
                    and np.all(np.isfinite(self.moments[c][j, m])):
                recent.append(j)
            j -= direction
        if len(recent) < 3:
            return np.nan, np.full((2, 2), np.nan)
        return float(np.median(self.area[c][recent, m])), np.median(self.moments[c][recent, m], axis=0)

    def _covered(self, c, cc, j) -> bool:
        """Is candidate ``j`` of camera ``c`` the current marker partly covered (:func:`shape_change`)?"""
        if cc.moments is None:
            return False
        ra, rs = self._shape_ref.get(c, (np.nan, None))
        if rs is None:
            return False
        a, s = shape_change(cc.area[j], cc.moments[j], ra, rs)
        return bool(a < COVER_AREA and s < COVER_SPREAD)

    def _view_options(self, m, cams, proj, radius, ref_area, cands):
        """Per camera, the candidates near marker ``m``'s projection that may stand for it.

        Returns ``(options, why)``: per camera the list of candidate indices
        (nearest first, at most ``MAX_OPTIONS``) followed by ``-1`` (unseen),
        or ``[-1]`` alone; and per camera the reason to give when none is
        used (that of the nearest region rejected here, else ``occluded`` or
        ``outside_image``).
        """
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
                elif self._covered(c, cc, j):
                    rejected.append("partly_covered")
                else:
                    good.append(int(j))
            why[c] = rejected[0] if rejected else "occluded"
            options.append(good + [-1] if good else [-1])
        return options, why

    def _best_views(self, k, m, cams, proj, radius, cands, pred, options):
        """The cheapest consistent combination of the ``options`` (two views or more) for marker ``m``.

        Cost: more views first, then the normalised distances to the
        projections, the residual and the 3D step from ``pred``; a point
        further from ``pred`` than ``max_step`` is not taken. Sets the
        marker's 3D position when a combination is taken. Returns ``(used,
        dropped, why_all, edge)``: the candidate per camera (``-1`` unseen;
        None: nothing taken), the views left out as inconsistent, the reason
        for all cameras (``"off_track"`` or None) and the edge views left out.
        """
        combos = np.array(list(itertools.product(*options)), dtype=int)
        nviews = (combos >= 0).sum(axis=1)
        combos = combos[nviews >= 2]
        used, dropped, why_all, edge = None, set(), None, set()
        if not len(combos):
            return used, dropped, why_all, edge
        X, worst, ok = triangulate_rows(self.rig, cams, cands, combos, self.tol)
        if not ok.any():
            return used, dropped, why_all, edge
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
        return used, dropped, why_all, edge

    def _record_views(self, k, m, cams, cands, options, why, used, dropped, why_all, edge):
        """Write marker ``m``'s views of frame ``k`` (centre, area, light, reason) from :meth:`_best_views`."""
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
        Xa, _, oka = triangulate_rows(self.rig, cams, cands, alt[None], self.tol)
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
                Xr, _, okr = triangulate_rows(self.rig, cams, cands, rest[None], self.tol)
                if okr[0]:
                    c = cams[ci]
                    r = float(np.linalg.norm(self.rig[c].project(Xr[0]) - cands[c].centre[used[ci]]))
                    loo[int(ci)] = (r, r / self._limit(c), Xr[0])
            if not loo:
                break
            ci, (r, ratio, Xr) = max(loo.items(), key=lambda kv: kv[1][1])
            if ratio > 1.0 and len(loo) == 3:       # two views agree, one does not: the rigid set decides
                ci, (r, _, Xr) = self._rigid_choice(loo, ci)
            if ratio <= 1.0:
                for cj, (rj, _, _) in loo.items():
                    self._loo.setdefault(cams[cj], []).append(rj)
                break
            used = used.copy()
            used[ci] = -1
            X = Xr
            dropped.add(ci)
        return used, X, dropped

    def _rigid_error(self, X) -> float:
        """RMS error (m) of the current marker at ``X`` against the static shot's distances to the others
        (their positions in this frame where found, else their predictions from the neighbouring frames)."""
        k, m = self._k, self._m
        errs = []
        for o in range(self.M):
            if o == m:
                continue
            P = self.X[k, o] if np.all(np.isfinite(self.X[k, o])) else self._pred[o]
            if np.all(np.isfinite(P)):
                errs.append(np.linalg.norm(X - P) - self.model_d[m, o])
        return math.sqrt(np.mean(np.square(errs))) if errs else float("nan")

    def _rigid_choice(self, loo, ci):
        """The view to leave out of three when one disagrees: not by a vote of two.

        Two views of a marker partly covered the same way in two cameras
        agree with each other (their centres are biased alike) and outvote
        the third, correct one. Each pair's point is compared with the rigid
        set (:meth:`_rigid_error`); the pair that keeps it rigid wins when
        its error is less than half that of the pair the residuals chose.
        Returns the item of ``loo`` to leave out.
        """
        err = {cj: self._rigid_error(v[2]) for cj, v in loo.items()}
        best = min(err, key=lambda cj: err[cj] if np.isfinite(err[cj]) else np.inf)
        if best != ci and np.isfinite(err[best]) and np.isfinite(err[ci]) and err[best] < 0.5 * err[ci]:
            return best, loo[best]
        return ci, loo[ci]

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
        was labelled as the same markers as frame ``k``, else ``k``; see
        :func:`same_marker_set`).
        """
        j = k + direction
        if not 0 <= j < self.n:
            return k
        cands, vp, fit = self._label_whole_frame(j)
        if fit is None:
            return k
        if not same_marker_set(self.X[k], vp.points[fit.assignment], self.max_step):
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
        """Candidates (searched without a prediction unless given), 3D points and model labelling of frame ``k``
        (free-running cameras' candidates moved to the reference instant: :func:`_candidates_at_reference`)."""
        cands, moved = _candidates_at_reference(self.frames, k, self.cams, self.thr, self.cparams, self.timing, cands,
                                                self.search)
        vp, fit, _ = label_frame(self.rig, moved, self.model, self.M, self.tol, np.arange(self.M), self.slack)
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
        it. Exact: a frame rejected here fails the full test too.
        """
        need = self.M * min(3, self.C)
        gray = {c: self.frames[c][k] for c in self.cams}    # every camera read in turn (its reading ahead goes on)
        have, cands = 0, {}
        for i, c in enumerate(self.cams):
            left = self.M * (self.C - 1 - i)                # the most the cameras after this one can add
            cp = self.cparams[c]
            whole, search = whole_frame_count(gray[c], self.thr[c], candidate_area_range(cp))  # before the shape rule
            if have + min(whole, self.M) + left < need:
                return None
            have += min(search.whole_count(candidate_min_circularity(cp), MAX_CANDIDATES_PER_CAMERA), self.M)
            if have + left < need:
                return None
            cands[c] = search
        # the centres only for a frame that can succeed
        return {c: search(candidate_min_circularity(self.cparams[c]), self.cparams[c].centroid,
                          MAX_CANDIDATES_PER_CAMERA) for c, search in cands.items()}

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

    def flag_covered_views(self):
        """Leave out every used view whose region lost the marker's shape against its own track around it.

        The tracker compares a region with the marker's shape in the frames
        before it in tracking order; a track that starts inside a cover (its
        anchor frame covered) takes the covered shape for the marker's. Here
        each used view is compared (:func:`shape_change`) with the medians of
        the marker's used views in that camera within ``SHAPE_MEMORY / 2``
        frames on both sides (at least ``SHAPE_VIEWS`` of them), and left out
        as ``partly_covered`` when it fails; the marker is triangulated again
        from its other views (or has no position).
        """
        half = SHAPE_MEMORY // 2
        for c in self.cams:
            for m in range(self.M):
                used = np.flatnonzero((self.reason[c][:, m] == "") & np.isfinite(self.area[c][:, m])
                                      & np.all(np.isfinite(self.moments[c][:, m]), axis=(1, 2)))
                flagged = []
                for k in used:
                    near = used[np.abs(used - k) <= half]
                    if len(near) < SHAPE_VIEWS:
                        continue
                    a, sp = shape_change(self.area[c][k, m], self.moments[c][k, m],
                                         float(np.median(self.area[c][near, m])),
                                         np.median(self.moments[c][near, m], axis=0))
                    if a < COVER_AREA and sp < COVER_SPREAD:
                        flagged.append(k)
                for k in flagged:
                    self._drop_view(k, m, c, "partly_covered")
                    self._rigid_rms(k)

    def result(self, model_index, k0, margin):
        px = {c: correct_light(self.px[c], self.slope[c], self.moments[c]) for c in self.cams}
        return Identification(
            marker_px=px, reason={c: r.astype(str) for c, r in self.reason.items()}, area=self.area,
            points=self.X, model_index=np.asarray(model_index, int), rigid_rms_m=self.rigid,
            thresholds=dict(self.thr), anchor_frame=int(k0), anchor_margin=float(margin), cameras=self.cams)

