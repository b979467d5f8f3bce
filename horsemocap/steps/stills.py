"""Steps ``plumb`` and ``static``: the markers of one still per camera (thesis sections 5.3 and 6.3).

The static shot may also be a short clip of the horse standing (a video or a
folder of frames per camera): each frame's markers are found as a still's,
aligned rigidly onto a reference frame's and averaged (:func:`average_static_clip`),
as the "static trial" of optical motion-capture systems is.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..camera import Rig
from ..detection import DetectionParams, MarkerCountError, detect_still, detect_still_views
from ..frames import gravity_from_plumb
from ..params import StillsParams
from ..reconstruction import triangulate
from ..registration import rotation_from_cross_covariance
from ..session import Session
from ..sources import is_still_image, read_image, SourceError, still_frames
from .base import AnalysisError, StepResult

#: A clip frame whose markers' shape is further from the clip's mean shape than this many robust standard
#: deviations of the frames' distances (1.4826 median absolute deviations) is left out as not rigid.
OUTLIER_Z = 5.0


@dataclass(frozen=True)
class PlumbResult(StepResult):
    """Gravity from the plumb line's two markers (section 5.3).

    Attributes
    ----------
    plumb_points : (2, 3) array
        The two markers (world frame), the upper one first.
    plumb_px : dict
        Camera -> (2, 2) their centroids (px).
    gravity : (3,) array
        Unit vector of gravity (downward) in the world frame.
    frames_used : int or None
        A clip of the plumb line: the frames averaged (None: one still per camera).
    frames_left_out : tuple
        A clip: ``(frame, reason)`` of every frame not averaged.
    """

    plumb_points: np.ndarray
    plumb_px: dict
    gravity: np.ndarray
    frames_used: int | None = None
    frames_left_out: tuple = ()


@dataclass(frozen=True)
class StaticResult(StepResult):
    """The static shot: the horse standing, every marker and the saddle marker visible (section 6.3).

    Attributes
    ----------
    static_points : (m + 1, 3) array or None
        The markers and the saddle marker (world frame), ascending image u in
        the reference camera; None when the session has no static shot.
    static_px : dict or None
        Camera -> their centroids (px); of a clip, each point's mean over the frames averaged.
    missing : str
        Why there is no static shot ("" when there is one).
    frames_used : int or None
        A clip: the frames averaged (None: one still per camera).
    frames_left_out : tuple
        A clip: ``(frame, reason)`` of every frame not averaged (no markers found, a marker seen by fewer
        than two cameras, points not matching the reference frame's, a shape far from the others').
    scatter_m : (m + 1,) array or None
        A clip: each point's rms distance (m) over the averaged frames from its mean, after the rigid
        alignment (the detection noise and any non-rigid wobble; the horse's sway is aligned away).
    scatter_lag1 : float or None
        A clip: the lag-1 autocorrelation of that scatter from frame to frame (NaN when not measurable).
    effective_frames : float or None
        A clip: how many independent frames the average is worth (:func:`effective_frame_count`): the
        variance of the average's part that changes from frame to frame is the scatter's divided by it.
        An error that stays the same in every frame (a marker's centroid seen off its centre by a camera)
        is not averaged away.
    """

    static_points: np.ndarray | None
    static_px: dict | None
    missing: str = ""
    frames_used: int | None = None
    frames_left_out: tuple = ()
    scatter_m: np.ndarray | None = None
    scatter_lag1: float | None = None
    effective_frames: float | None = None


@dataclass(frozen=True)
class ClipAverage:
    """A static clip's points averaged over its frames (:func:`average_static_clip`).

    Attributes
    ----------
    points : (k, 3) array
        The mean shape, placed at the frames' mean pose.
    order : (F, k) int array
        Frame f's point ``order[f, j]`` is point j (-1 in frames left out).
    used : (F,) bool array
        The frames averaged.
    left_out : tuple
        ``(frame, reason)`` of the frames not averaged.
    scatter_m : (k,) array
        Each point's rms distance from its mean over the averaged frames, after alignment (m).
    lag1 : float
        The scatter's lag-1 autocorrelation over consecutive averaged frames (NaN: not measurable).
    effective_frames : float
        :func:`effective_frame_count` of the averaged frames and ``lag1``.
    """

    points: np.ndarray
    order: np.ndarray
    used: np.ndarray
    left_out: tuple
    scatter_m: np.ndarray
    lag1: float
    effective_frames: float


def align_onto(points, reference) -> np.ndarray:
    """``points`` (k, 3) moved rigidly onto ``reference`` (k, 3), the same point order: least squares
    (Horn's closed form, :func:`horsemocap.registration.rotation_from_cross_covariance`).

    Examples
    --------
    >>> ref = np.array([[0.0, 0, 0], [0.4, 0, 0], [0.1, 0.2, 0], [0.2, 0.1, 0.3]])
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> bool(np.allclose(align_onto(ref @ turn.T + [1.0, 2, 3], ref), ref))
    True
    """
    p = np.asarray(points, float)
    x = np.asarray(reference, float)
    pc, xc = p - p.mean(0), x - x.mean(0)
    R = rotation_from_cross_covariance((pc.T @ xc)[None]).as_matrix()[0]   # x - mu_x = R (p - mu_p)
    return pc @ R.T + x.mean(0)


def match_onto(points, reference) -> tuple[np.ndarray, np.ndarray]:
    """Which of ``points`` (k, 3) is which of ``reference``'s (k, 3), the two sets a little apart (a horse
    standing, swaying): ``(order, aligned)``, ``points[order]`` aligned onto ``reference`` (:func:`align_onto`).

    The points are paired by least total distance, first with the centroids together, then again after
    the rigid alignment (a sway's rotation may swap two close points' nearest neighbours).

    Examples
    --------
    >>> ref = np.array([[0.0, 0, 0], [0.4, 0, 0], [0.1, 0.2, 0], [0.2, 0.1, 0.3]])
    >>> order, aligned = match_onto(ref[[2, 0, 3, 1]] + 0.01, ref)
    >>> order.tolist(), bool(np.allclose(aligned, ref))
    ([1, 3, 0, 2], True)
    """
    p = np.asarray(points, float)
    x = np.asarray(reference, float)
    moved = p - p.mean(0) + x.mean(0)           # in the order of ``points``
    order, aligned = None, None
    for _ in range(3):
        rows, cols = linear_sum_assignment(np.linalg.norm(moved[:, None] - x[None], axis=-1))
        new = np.empty(len(x), int)
        new[cols] = rows
        if order is not None and np.array_equal(new, order):
            break
        order = new
        aligned = align_onto(p[order], x)
        moved = np.empty_like(p)
        moved[order] = aligned
    return order, aligned


def effective_frame_count(frames: int, lag1: float) -> float:
    """The number of independent frames the mean of ``frames`` frames is worth, their errors an AR(1)
    sequence of lag-1 autocorrelation ``lag1``: ``frames / (1 + 2 sum_k (1 - k / frames) lag1^k)``, the
    variance of the mean being the frames' divided by it. A negative or unknown (NaN) ``lag1`` counts every
    frame; the count is at least 1.

    Examples
    --------
    >>> effective_frame_count(60, 0.0), round(effective_frame_count(60, 0.8), 2)
    (60.0, 7.2)
    >>> effective_frame_count(1, 0.9)
    1.0
    """
    n = int(frames)
    if n <= 1 or not np.isfinite(lag1) or lag1 <= 0:
        return float(max(n, 1))
    k = np.arange(1, n)
    return float(max(1.0, n / (1.0 + 2.0 * np.sum((1.0 - k / n) * float(lag1) ** k))))


def _scatter_lag1(residuals, frame_index) -> float:
    """Pooled lag-1 autocorrelation of residuals (F, k, 3) over pairs of consecutive frames (``frame_index``)."""
    pairs = np.flatnonzero(np.diff(frame_index) == 1)
    if not len(pairs):
        return float("nan")
    a, b = residuals[pairs], residuals[pairs + 1]
    power = 0.5 * float(np.sum(a * a) + np.sum(b * b))
    return float(np.sum(a * b)) / power if power > 0 else 1.0     # frames alike: together worth one frame


def _typical_frame(points, complete) -> int:
    """The complete frame (``points`` (F, k, 3), ``complete`` (F,) bool) whose shape is nearest the frames'
    median shape: its sorted distances between points (which do not depend on the points' order) nearest,
    in the largest difference, to their median over the complete frames; a frame with a glint taken for a
    marker is then never the reference the others are matched to."""
    frames = np.flatnonzero(complete)
    k = points.shape[1]
    if k < 2 or frames.size < 3:
        return int(frames[0])
    upper = np.triu_indices(k, 1)
    p = points[frames]
    shapes = np.sort(np.linalg.norm(p[:, :, None] - p[:, None], axis=-1)[:, upper[0], upper[1]], axis=1)
    return int(frames[np.argmin(np.abs(shapes - np.median(shapes, axis=0)).max(axis=1))])


def _not_rigid(rms, candidates, outlier_z: float) -> np.ndarray:
    """Frames among ``candidates`` whose ``rms`` is more than ``outlier_z`` robust standard deviations
    above the candidates' median (with five frames or more)."""
    if candidates.sum() < 5:
        return np.zeros_like(candidates)
    med = np.median(rms[candidates])
    # at least a micrometre: frames that repeat one another (no spread) are not told apart by rounding
    spread = max(1.4826 * float(np.median(np.abs(rms[candidates] - med))), 1e-6)
    return candidates & (rms > med + outlier_z * spread + 1e-9)


def average_static_clip(frames, *, outlier_z: float = OUTLIER_Z) -> ClipAverage:
    """The points of a static clip averaged over its frames: each frame aligned rigidly onto the mean shape.

    The reference is the complete frame whose shape is nearest the clip's
    median shape (a frame with a glint taken for a marker never is): every
    frame's points are paired with its points (:func:`match_onto`) and aligned
    onto them rigidly, so a horse swaying a little changes nothing; the mean
    shape is then refined (each frame aligned onto the mean of the aligned
    frames, generalised Procrustes, a few rounds). A frame with a non-finite
    point, or whose points stay further from the reference's than half the
    smallest distance between two of them, or whose shape is more than
    ``outlier_z`` robust standard deviations further from the mean shape than
    the median frame (a glint taken for a marker), is left out with its
    reason. The mean shape is placed at the frames' mean pose (aligned onto
    the per-point mean of the unaligned frames).

    Parameters
    ----------
    frames : (F, k, 3) array
        Each frame's points (world frame), NaN where a frame has none.
    outlier_z : float
        The robust distance beyond which a frame's shape is not rigid with the others'.

    Returns
    -------
    ClipAverage

    Raises
    ------
    ValueError
        When no frame has every point finite.

    Examples
    --------
    Three points swaying: each frame the shape turned a little about z and moved, plus an independent
    0.1 mm of noise; the average is the shape to a small fraction of that:

    >>> rng = np.random.default_rng(1)
    >>> shape = np.array([[0.0, 0, 3], [0.4, 0, 3], [0.1, 0.2, 3]])
    >>> def turned(a):
    ...     c, s = np.cos(a), np.sin(a)
    ...     return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    >>> clip = np.stack([shape @ turned(0.01 * np.sin(f)).T + [0.002 * f, 0, 0] for f in range(40)])
    >>> clip = clip + 1e-4 * rng.standard_normal(clip.shape)
    >>> clip[7] = np.nan                                      # a frame without markers
    >>> avg = average_static_clip(clip)
    >>> int(avg.used.sum()), avg.left_out
    (39, ((7, 'a point is not finite'),))
    >>> d = lambda p: np.linalg.norm(p[:, None] - p[None], axis=-1)
    >>> bool(np.abs(d(avg.points) - d(shape)).max() < 5e-5)
    True
    """
    pts = np.asarray(frames, float)
    if pts.ndim != 3 or pts.shape[-1] != 3:
        raise ValueError(f"frames: expected (F, k, 3) points, got shape {pts.shape}")
    count, k = pts.shape[:2]
    finite = np.isfinite(pts).all(axis=(1, 2))
    if not finite.any():
        raise ValueError(f"frames: none of the {count} frames has every one of its {k} points")
    reasons = {int(f): "a point is not finite" for f in np.flatnonzero(~finite)}
    first = _typical_frame(pts, finite)
    reference = pts[first]
    gaps = np.linalg.norm(reference[:, None] - reference[None], axis=-1)[np.triu_indices(k, 1)]
    half_gap = 0.5 * float(gaps.min()) if len(gaps) else np.inf
    order = np.full((count, k), -1)
    aligned = np.full_like(pts, np.nan)
    for f in np.flatnonzero(finite):
        order[f], aligned[f] = match_onto(pts[f], reference)
        far = float(np.linalg.norm(aligned[f] - reference, axis=-1).max())
        if far > half_gap:
            reasons[int(f)] = (f"its points do not match the reference frame's (frame {first}): "
                               f"a point {1000 * far:.1f} mm from its match, more than half the smallest "
                               f"distance between two points ({1000 * half_gap:.1f} mm)")
    used = finite & ~np.isin(np.arange(count), list(reasons))
    mean = aligned[used].mean(0)
    for _ in range(4):
        for f in np.flatnonzero(used):
            aligned[f] = align_onto(pts[f][order[f]], mean)
        mean = aligned[used].mean(0)
        rms = np.sqrt(np.mean(np.sum((aligned - mean) ** 2, -1), -1))
        outliers = _not_rigid(rms, used, outlier_z)
        if not outliers.any():
            break
        for f in np.flatnonzero(outliers):
            reasons[int(f)] = (f"not rigid with the other frames: its points {1000 * rms[f]:.2f} mm rms from the "
                               f"clip's mean shape, more than {outlier_z:g} robust standard deviations above "
                               f"the frames' median ({1000 * np.median(rms[used]):.2f} mm)")
        used = used & ~outliers
        mean = aligned[used].mean(0)
    unaligned = np.stack([pts[f][order[f]] for f in np.flatnonzero(used)])
    placed = align_onto(mean, unaligned.mean(0))
    residuals = aligned[used] - mean
    lag1 = _scatter_lag1(residuals, np.flatnonzero(used))
    order[~used] = -1
    return ClipAverage(points=placed, order=order, used=used,
                       left_out=tuple(sorted(reasons.items())),
                       scatter_m=np.sqrt(np.mean(np.sum(residuals ** 2, -1), 0)), lag1=lag1,
                       effective_frames=effective_frame_count(int(used.sum()), lag1))


def still_params(section: StillsParams, kind: str, cameras) -> dict:
    """The detector parameters of one still per camera (``section.plumb`` or ``.static``: "all" then the camera).

    Returns ``{camera: DetectionParams}`` (empty when every choice is automatic).

    Examples
    --------
    >>> p = still_params(StillsParams(static={"all": {"threshold": 150}}), "static", ["left"])
    >>> p["left"].threshold
    150
    """
    given = getattr(section, kind)
    if not given:
        return {}
    out = {}
    for c in cameras:
        d = {**given.get("all", {}), **given.get(c, {})}
        if "labels" in d:
            d["labels"] = tuple(d["labels"])
        out[c] = DetectionParams(**d)
    return out


def still_points(session: Session, rig: Rig, images: dict, count: int, step: str, mode: str,
                 given: dict | None = None):
    """Markers of one still per camera, matched across the cameras and triangulated.

    :func:`horsemocap.detection.detect_still_views` keeps only candidates that
    triangulate consistently in every camera (a glint or a buckle seen by one
    camera is not a marker), then picks the most marker-like ones. ``given``
    (:func:`still_params`): per-camera thresholds for that matching, or, with
    labels for every camera, the thesis' way (Appendix A 7a, 8a, 12a): the
    labelled regions of each camera taken as they are
    (:func:`horsemocap.detection.detect_still`). Returns ``(points, px)``.
    """
    try:
        px = _still_px({c: read_image(images[c]) for c in session.cameras}, rig, count, given)
    except ValueError as exc:
        files = ", ".join(str(images[c]) for c in session.cameras)
        raise AnalysisError(step, f"{files}: {exc}{_count_said(exc, step)}") from None
    return triangulate(rig, {c: p[None] for c, p in px.items()}, mode=mode).points[0], px


def _count_said(exc: Exception, step: str) -> str:
    """For the static shot, the ``markers.count`` its marker-like points give (the markers and the saddle
    marker), when the detection found another number of them (:class:`MarkerCountError`); else nothing.

    Examples
    --------
    >>> _count_said(MarkerCountError("...", 4), "static"), _count_said(MarkerCountError("...", 4), "plumb")
    ("; the static shot's 4 marker-like points say 'markers.count': 3", '')
    """
    if step != "static" or not isinstance(exc, MarkerCountError) or exc.marker_like < 2:
        return ""
    return f"; the static shot's {exc.marker_like} marker-like points say 'markers.count': {exc.marker_like - 1}"


def _still_px(images: dict, rig: Rig, count: int, given: dict | None) -> dict:
    """Camera -> (count, 2) marker centres of one still per camera (``images``: camera -> RGB image), as
    :func:`still_points` finds them; ValueError when they cannot be found."""
    given = given or {}
    if given and all(given[c].labels is not None for c in images):
        return {c: detect_still(images[c], count, given[c]) for c in images}
    return detect_still_views(images, rig, count, given or None)


def clip_points(session: Session, rig: Rig, clips: dict, count: int, step: str, mode: str,
                given: dict | None = None):
    """Each frame's markers of a clip per camera (a video or a folder of frames), found as a still's.

    Returns ``(points, px, reasons)``: points (F, count, 3) triangulated, px camera -> (F, count, 2), NaN in a
    frame whose markers were not found, and ``{frame: reason}`` for those frames. The cameras' frames are
    read in step; a camera whose clip ends before the others', a frame that cannot be read, or a clip none of
    whose frames gives every marker is an :class:`AnalysisError` naming the files.
    """
    cams = session.cameras
    files = ", ".join(str(clips[c]) for c in cams)
    readers = {c: still_frames(clips[c]) for c in cams}
    points, px, reasons = [], {c: [] for c in cams}, {}
    for f in itertools.count():
        try:
            got = {c: next(readers[c], None) for c in cams}
        except SourceError as exc:
            raise AnalysisError(step, f"frame {f} of the clip: {exc}") from None
        ended = [c for c in cams if got[c] is None]
        if len(ended) == len(cams):
            break
        if ended:
            raise AnalysisError(step, f"the clip of camera '{ended[0]}' ({clips[ended[0]]}) ends after {f} "
                                      f"frames, those of the others do not (expected one frame count in "
                                      f"every camera: {files})")
        try:
            found = _still_px({c: got[c][1] for c in cams}, rig, count, given)
        except ValueError as exc:
            reasons[f] = f"markers not found: {exc}"
        else:
            pts = triangulate(rig, {c: q[None] for c, q in found.items()}, mode=mode).points[0]
            if not np.isfinite(pts).all():
                reasons[f] = "a marker was not triangulated (seen by fewer than two cameras)"
        if f in reasons:
            found, pts = {c: np.full((count, 2), np.nan) for c in cams}, np.full((count, 3), np.nan)
        points.append(pts)
        for c in cams:
            px[c].append(np.asarray(found[c], float))
    if not points:
        raise AnalysisError(step, f"the clip has no frame: {files}")
    if len(reasons) == len(points):         # every frame has a reason: none gave every marker
        markers = "both markers" if count == 2 else "every marker"
        raise AnalysisError(step, f"{files}: no frame of the {len(points)}-frame {step} clip gave {markers}: "
                                  + "; ".join(f"frame {k}: {r}" for k, r in sorted(reasons.items())[:3]))
    return np.stack(points), {c: np.stack(v) for c, v in px.items()}, reasons


def step_plumb(session: Session, section: StillsParams, rig: Rig, triangulation: str, progress) -> PlumbResult:
    """Gravity from the plumb line's two markers (section 5.3), triangulated as ``triangulation`` says: of one
    still per camera, or their mean over a clip's frames (:func:`clip_points`)."""
    if session.plumb is None:
        raise AnalysisError("plumb", f"{session.json_path}: no 'plumb' stills; gravity cannot be found")
    given = still_params(section, "plumb", session.cameras)
    used, left_out = None, ()
    if all(is_still_image(p) for p in session.plumb.values()):
        pts, px = still_points(session, rig, session.plumb, 2, "plumb", triangulation, given)
    else:       # a clip: the line hangs still, each marker's mean over the frames where both were found
        points, px_all, reasons = clip_points(session, rig, session.plumb, 2, "plumb", triangulation, given)
        ok = np.isfinite(points).all(axis=(1, 2))
        pts, px = points[ok].mean(0), {c: v[ok].mean(0) for c, v in px_all.items()}
        used, left_out = int(ok.sum()), tuple(sorted(reasons.items()))
        progress("plumb", f"clip of {len(points)} frames: {used} averaged, {len(left_out)} left out")
    # the still's two markers come top first (image v): the upper one is the tail, the lower one
    # the tip, and gravity points from tail to tip (down)
    gravity = gravity_from_plumb(tip_world=pts[1], tail_world=pts[0])
    progress("plumb", f"gravity {np.round(gravity, 4).tolist()}")
    return PlumbResult(plumb_points=pts, plumb_px=px, gravity=gravity, frames_used=used, frames_left_out=left_out)


def step_static(session: Session, section: StillsParams, rig: Rig, triangulation: str, progress) -> StaticResult:
    """The static shot's markers and saddle marker, all visible (section 6.3): one still per camera, or a
    clip of the horse standing, averaged (:func:`average_static_clip`)."""
    if session.static is None:
        return StaticResult(static_points=None, static_px=None,
                            missing=f"{session.json_path}: no 'static' stills; the saddle marker cannot be placed")
    given = still_params(section, "static", session.cameras)
    if all(is_still_image(p) for p in session.static.values()):
        pts, px = still_points(session, rig, session.static, session.marker_count + 1, "static", triangulation, given)
        return StaticResult(static_points=pts, static_px=px)
    return _static_clip(session, rig, triangulation, given, progress)


def _static_clip(session: Session, rig: Rig, triangulation: str, given: dict, progress) -> StaticResult:
    """The static shot of a clip per camera: each frame's markers (:func:`clip_points`) averaged
    (:func:`average_static_clip`); the frames left out counted with their reasons."""
    points, px, reasons = clip_points(session, rig, session.static, session.marker_count + 1, "static",
                                      triangulation, given)
    avg = average_static_clip(points)
    left_out = tuple(sorted({**{f: r for f, r in avg.left_out}, **reasons}.items()))
    used = np.flatnonzero(avg.used)
    mean_px = {c: np.mean([v[f][avg.order[f]] for f in used], axis=0) for c, v in px.items()}
    progress("static", f"clip of {len(points)} frames: {len(used)} averaged ({avg.effective_frames:.1f} "
                       f"independent), {len(left_out)} left out" +
             "".join(f"; frame {f}: {r}" for f, r in left_out[:3]))
    return StaticResult(static_points=avg.points, static_px=mean_px, frames_used=int(len(used)),
                        frames_left_out=left_out, scatter_m=avg.scatter_m, scatter_lag1=avg.lag1,
                        effective_frames=avg.effective_frames)
