"""Step ``triangulate``: 3D marker positions in the reference camera's frame (thesis section 5.1)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Rig
from ..detection import bridge_gaps
from ..params import TriangulateParams
from ..reconstruction import nearest_covariance, triangulate
from ..subframe import OUTSIDE_TRACK, drift_text, others_residual, tracks_at_reference_instants
from .base import AnalysisError, StepResult, longest_run
from .detect import MIN_SEGMENT_FRAMES, DetectResult


@dataclass(frozen=True)
class TriangulateResult(StepResult):
    """The markers' 3D positions, every synchronised frame.

    Attributes
    ----------
    points : (n, m, 3) array
        Positions in the reference camera's frame (thesis ``CM_L``), NaN where
        fewer than two cameras agree; short gaps bridged.
    residual_px : dict
        Camera -> (n, m) reprojection residual (px).
    reason : (n, m) str array
        "" where measured, ``interpolated`` in a bridged gap, else why there is no position.
    n_views : (n, m) int array
        Cameras used per point.
    segment : (int, int)
        The analysed frames: the longest run inside the detection's in which every marker has a position.
    covariance : (n, m, 3, 3) array or None
        Each point's covariance for the detection noise (world frame).
    noise_px : float or None
        The detection noise estimated from the residuals.
    sync_residual_px : dict or None
        Free-running cameras: camera -> (n, m) distance (px) of its positions at the reference instants from
        the other cameras' markers projected into it (:func:`horsemocap.subframe.others_residual`), the
        residual of the sub-frame synchronisation; None for genlocked cameras.
    """

    points: np.ndarray
    residual_px: dict
    reason: np.ndarray
    n_views: np.ndarray
    segment: tuple
    covariance: np.ndarray | None
    noise_px: float | None
    sync_residual_px: dict | None = None


def step_triangulate(section: TriangulateParams, rig: Rig, detect: DetectResult, progress) -> TriangulateResult:
    """3D marker positions in the reference camera frame (section 5.1).

    The analysed segment is the longest run, inside the detection's, in
    which every marker was triangulated (a point whose views disagree beyond
    the residual limit is NaN with reason ``inconsistent_views``). Each
    point's covariance for the detection noise estimated from the residuals
    (``covariance``, world frame; an interpolated point takes its nearest
    measured frame's) weights the markers in the rigid-body step's pose
    registration.
    """
    marker_px, outside = common_instants(detect, progress)
    tri = triangulate(rig, marker_px, mode=section.mode, covariance=True)
    points, bridged = bridge_gaps(tri.points, detect.max_gap_frames)
    cov = None if tri.covariance is None else nearest_covariance(tri.covariance, bridged)
    reason = np.where(bridged, "interpolated", tri.reason)
    if outside is not None:
        reason = np.where(outside & ~np.isfinite(points[..., 0]), OUTSIDE_TRACK, reason)
    if bridged.any():
        progress("triangulate", f"{int(bridged.sum())} marker position(s) in gaps of at most "
                                f"{detect.max_gap_frames} frames interpolated")
    med = {c: float(np.nanmedian(r)) if np.isfinite(r).any() else float("nan") for c, r in tri.residual_px.items()}
    progress("triangulate", f"{section.mode} mode; median reprojection residual (px) "
                            + ", ".join(f"{c} {v:.3f}" for c, v in med.items()))
    a, b = detect.segment
    ok = np.zeros(len(tri.points), bool)
    # every marker of three; any three or more of four or more (the others define the pose meanwhile)
    ok[a:b] = np.all(np.isfinite(points[a:b]), axis=2).sum(axis=1) >= min(3, points.shape[1])
    segment = _whole_at_ends(longest_run(ok), points)
    if segment is None or segment[1] - segment[0] < MIN_SEGMENT_FRAMES:
        why = sorted({str(r) for r in reason[a:b].ravel() if r})
        raise AnalysisError("triangulate", f"fewer than 8 consecutive frames with every marker (three of four or "
                            f"more) triangulated "
                            f"(reasons: {', '.join(why) or 'none'}); check the rig (calibration) and the "
                            "detections in markers_2d.csv")
    if segment != (a, b):
        progress("triangulate", f"analysing frames {segment[0]}..{segment[1] - 1}: some markers of frames "
                                f"{a}..{b - 1} could not be triangulated ("
                                + ", ".join(sorted({str(r) for r in reason[a:b].ravel() if r and r != "interpolated"}))
                                + ")")
    sync_residual = None if outside is None or len(marker_px) < 3 else others_residual(rig, marker_px)
    return TriangulateResult(points=points, residual_px=tri.residual_px, reason=reason, n_views=tri.n_views,
                             segment=segment, covariance=cov, noise_px=tri.noise_px, sync_residual_px=sync_residual)


def _whole_at_ends(segment, points):
    """The segment shortened until its first and last frames hold every marker (the motion frame's net
    displacement is measured between them); a marker may still be missing inside. None stays None.

    Examples
    --------
    >>> pts = np.zeros((6, 4, 3)); pts[0, 1] = np.nan; pts[3, 2] = np.nan
    >>> _whole_at_ends((0, 6), pts)
    (1, 6)
    """
    if segment is None:
        return None
    whole = np.all(np.isfinite(points), axis=(1, 2))
    a, b = segment
    while a < b and not whole[a]:
        a += 1
    while b > a and not whole[b - 1]:
        b -= 1
    return (int(a), int(b)) if b > a else None


def drift_words(sync) -> str:
    """The drifting cameras of ``sync`` in words ("" when every phase holds over the record).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> print(drift_words(SimpleNamespace(rate_ratio={"left": 1.0, "right": 1 / 1.000132}, n_frames=2800)))
     at the first frame; right (its frames 132 ppm shorter than the reference's: -0.369 frame of phase over the record)
    """
    drifting = {c: r for c, r in sync.rate_ratio.items() if r != 1.0}
    return (" at the first frame" + "".join(f"; {c}{drift_text(r, sync.n_frames)}" for c, r in drifting.items())
            if drifting else "")


def common_instants(detect: DetectResult, progress) -> tuple[dict, np.ndarray | None]:
    """The cameras' centroids at the reference camera's instants, and where a camera's could not be interpolated.

    Genlocked cameras (no phase, no rate, no row times): the detections as they are and None. Free-running
    cameras: each camera's tracks interpolated (cubic, on the frames where the marker is seen, spanning gaps of
    up to the step's bridged gap ``detect.max_gap_frames``, read within a frame of an observation) to the reference
    instants (:func:`horsemocap.subframe.tracks_at_reference_instants`); the returned (n, m) mask marks the
    marker-frames that some camera saw but could not interpolate (reason ``outside_track``).
    """
    sync = detect.sync
    if not sync.free_running and not detect.observation_frames:
        return detect.marker_px, None
    moved, outside = tracks_at_reference_instants(detect.marker_px, sync.phase_frames, sync.rate_ratio,
                                                  detect.observation_frames, max_gap=detect.max_gap_frames)
    lost = np.any(np.stack(list(outside.values())), axis=0)
    progress("triangulate", "the cameras' tracks interpolated to the reference camera's instants (phases "
                            + ", ".join(f"{c} {v:+.3f}" for c, v in sync.phase_frames.items())
                            + " frame" + drift_words(sync)
                            + f"); {int(lost.sum())} marker-frame(s) outside a camera's track")
    return moved, lost
