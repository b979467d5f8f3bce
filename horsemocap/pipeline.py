"""The whole analysis of a riding session, one step after another.

Every arrow of DESIGN.md is a step here: each takes the session, the
parameters and the results of the steps before it, calls the package
function of its module, and returns a small dict of arrays and chosen values.
:func:`analyze` runs the steps in order, saves each one whole in the results
store (so the steps before a failure stay written) and writes the files of
``docs/sessions.md``. Notebooks call :func:`results_for` to load what
earlier steps computed (computing it with the defaults when absent).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .camera import Rig, read_rig
from .params import AnalysisParams
from .session import Session, SessionError, check_frame_counts, load_session
from .sources import FrameSource, read_image
from .store import ResultsStore, check_outside
from .threads import blas_single_threaded

STEPS = ("sync", "rig", "plumb", "static", "detect", "triangulate", "smooth",
         "motion_frame", "rigid_body", "comfort")


class AnalysisError(RuntimeError):
    """A step that cannot go on; the message names the input to look at."""

    def __init__(self, step: str, message: str):
        super().__init__(f"step '{step}': {message}")
        self.step = step


@dataclass
class Analysis:
    """Results of the steps run so far.

    Attributes
    ----------
    session : Session
    params : AnalysisParams
        The parameters given (``None`` fields are filled in ``chosen``).
    results : dict
        Step name -> dict of arrays and values.
    chosen : dict
        Every automatic choice made, by step (written to ``analysis.json``).
    timings : dict
        Seconds spent per step.
    """

    session: Session
    params: AnalysisParams
    results: dict = field(default_factory=dict)
    chosen: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    def __getitem__(self, step: str) -> dict:
        return self.results[step]


def _progress_printer(stream=None):
    """``[horsemocap] step: message`` lines; counts inside long steps as a bar on a terminal
    (:class:`horsemocap.progress.ProgressPrinter`)."""
    from .progress import ProgressPrinter

    return ProgressPrinter(stream)


# ---------------------------------------------------------------------------
# the steps
# ---------------------------------------------------------------------------

def step_sync(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Frame offsets (eq. 3.11-3.14) and the synchronised frame count."""
    from . import sync

    sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
    ambiguous = {}
    if params.sync_offsets:
        offsets, how = dict(params.sync_offsets), "given in parameters"
    elif session.sync_offsets:
        offsets, how = dict(session.sync_offsets), "given in session.json"
    else:
        found, how = sync.flash_detections(sources), "flashlight"
        offsets = {c: int(d.frame) for c, d in found.items()}
        ambiguous = {c: int(d.runner_up["on_frame"]) for c, d in found.items() if d.ambiguous and d.runner_up}
    counts = {c: len(s) for c, s in sources.items()}
    n = check_frame_counts(session, counts, offsets, offsets_from=how)
    progress("sync", f"offsets {offsets} ({how}); {n} synchronised frames")
    out = {"offsets": offsets, "frame_counts": counts, "n_frames": n, "offsets_from": how}
    if ambiguous:
        progress("sync", "two flash candidates of similar score in " + ", ".join(
            f"camera '{c}' (frame {offsets[c]} taken, frame {f} nearly as likely)" for c, f in ambiguous.items())
            + "; the markers will check it")
        out["flash_ambiguous"] = ambiguous
    return out


def step_rig(session: Session, params: AnalysisParams, res: dict, progress, cache_dirs=(), board_views=None) -> dict:
    """The calibrated rig: the session's ``rig.toml`` or a calibration of its views.

    ``cache_dirs``: results folders (the run's own first) where a calibration
    of the same views, board, cameras and code is reused from
    ``calibration.json`` and the new one is kept
    (:func:`horsemocap.calibration.cache.cached_calibration`; ``recalibrate``
    ignores it). ``board_views``: a
    :class:`~horsemocap.calibration.cache.BoardDetectionJob` already
    detecting the views.
    """
    if session.rig_path is not None and not params.recalibrate:
        rig, how = read_rig(session.rig_path), f"read {session.rig_path.name}"
    elif session.calibration_images is not None:
        from .calibration.cache import cached_calibration

        cache_dirs = [d for d in cache_dirs if d is not None]
        exclude = {c: list(v) for c, v in params.calibration_exclude.items()} or None
        if exclude:
            progress("rig", "views left out: " + "; ".join(f"{c} {', '.join(v)}" for c, v in exclude.items()))
        rig, how = cached_calibration(session.calibration_images, session.board.inner_corners,
                                      session.board.square_size_m, session.reference_camera,
                                      write_to=cache_dirs[0] if cache_dirs else None, read_from=cache_dirs[1:],
                                      recalibrate=params.recalibrate, progress=progress,
                                      exclude=exclude, mode=params.calibration_mode, detected=board_views)
    else:
        raise AnalysisError("rig", f"{session.json_path}: 'calibration' gives neither a rig nor views")
    missing = [c for c in session.cameras if c not in rig.names]
    if missing:
        raise AnalysisError("rig", f"the rig has no camera {missing[0]!r} (it has {rig.names}); "
                                   f"check 'calibration' in {session.json_path}")
    rig = rig.subset(session.cameras)
    progress("rig", how)
    return {"rig": rig, "rig_from": how}


def _detection_params(params: AnalysisParams, camera: str):
    from .detection import DetectionParams

    given = dict(params.detection.get("all", {}))
    given.update(params.detection.get(camera, {}))
    return DetectionParams.from_dict(given) if given else None


def step_detect(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Marker centroids per camera in the synchronised numbering (chapter 4; issue 17).

    ``detection_method="multiview"`` (default): the markers are identified by
    all cameras together and followed in 3D
    (:func:`horsemocap.detection.identify_markers`, which needs the static
    shot's markers as its rigid model); ``"thesis"``: each camera alone with
    the filters of chapter 4 (:func:`horsemocap.detection.detect_markers`),
    and the analysed segment is the longest run in which every camera sees
    every marker.
    """
    method, why = params.detection_method, ""
    if method == "multiview":
        if res["static"]["static_points"] is None:
            method, why = "thesis", "no static shot to take the markers' rigid shape from"
        elif session.marker_count < 3:
            method, why = "thesis", f"{session.marker_count} marker(s): a rigid shape needs 3"
        if why:
            progress("detect", f"multi-view identification not possible ({why}); the thesis' per-camera chain")
    out = _detect_multiview(session, params, res, progress) if method == "multiview" \
        else _detect_per_camera(session, params, res, progress)
    out["method"] = method
    out["method_note"] = why
    return out


def _frames_of(session: Session, res: dict, cam: str, progress=None, message: str = ""):
    """The synchronised gray frames of ``cam``; with ``progress``, each first read of a frame is counted."""
    from .progress import CountingFrames, counter

    offsets, n = res["sync"]["offsets"], res["sync"]["n_frames"]
    seq = FrameSource(session.motion[cam]).sequence(offsets[cam], offsets[cam] + n, color=False)
    if progress is None or not getattr(progress, "counts", False):
        return seq
    return CountingFrames(seq, counter(progress, "detect", message or f"camera '{cam}' frames", n))


def _max_gap(session: Session, params: AnalysisParams) -> int:
    from .detection import default_max_gap

    return default_max_gap(session.fps) if params.max_gap_frames is None else int(params.max_gap_frames)


def _detect_multiview(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    from .detection import DetectionParams, bridge_gaps

    rig = res["rig"]["rig"]
    first = session.cameras[0]
    frames = {c: _frames_of(session, res, c, progress if c == first else None, "frames identified")
              for c in session.cameras}
    given = {c: _detection_params(params, c) or DetectionParams() for c in session.cameras}
    progress("detect", f"{res['sync']['n_frames']} frames of cameras {', '.join(session.cameras)}: "
                       "markers identified by all cameras together ...")
    idn = _identify(session, rig, res, given, progress, frames)
    sync_check = {}
    if res["sync"].get("offsets_from") == "flashlight" and len(session.cameras) >= 3:
        rounds = []
        for _ in range(SYNC_CHECK_ROUNDS):      # again after a correction: the others' markers have moved too
            rounds.append(_check_sync_by_markers(session, params, res, idn, progress))
            if not any(v["shift"] for v in rounds[-1].values()):
                break
            idn = _identify(session, rig, res, given, progress)
        sync_check = _sync_check_summary(rounds, res["sync"])
    have, _ = bridge_gaps(idn.points, _max_gap(session, params))
    tracked = np.all(np.isfinite(have), axis=(1, 2))
    segment = _longest_run(tracked)
    if segment is None or segment[1] - segment[0] < 8:
        from .detection.identification import reason_counts

        moved = [c for c, v in sync_check.items() if v["moved"] or not v["decided"]]
        hint = (f"; the markers moved or could not check the flash offsets of {', '.join(moved)} (offsets now "
                f"{res['sync']['offsets']}, the flash's {res['sync'].get('flash_offsets', res['sync']['offsets'])}): "
                "if the flash was found in the wrong frame in two cameras, give the offsets (--offsets)"
                if moved else "")
        raise AnalysisError("detect", "fewer than 8 consecutive frames in which every marker is seen by two or "
                            f"more cameras (marker-frames per camera: {reason_counts(idn.reason)}); check the "
                            "motion videos, the threshold, the rig and 'markers.count' in session.json" + hint)
    progress("detect", f"{_frames_text(session, res, segment[0], segment[1] - 1)}: every marker seen by two or more "
                       f"cameras (or bridged); labelled in synchronised frame {idn.anchor_frame}")
    chosen = {c: {**given[c].to_dict(), "threshold": int(idn.thresholds[c])} for c in session.cameras}
    return {"marker_px": idn.marker_px, "reason": idn.reason, "segment": segment, "detection": chosen,
            "all_seen": tracked, "sync_check": sync_check,
            **({"sync_corrected": res["sync"]} if any(v["shift"] for v in sync_check.values()) else {}),
            "identification": {
                "anchor_frame": idn.anchor_frame, "anchor_margin": idn.anchor_margin,
                "model_index": [int(i) for i in idn.model_index], "rigid_rms_m": idn.rigid_rms_m}}


def _identify(session: Session, rig, res: dict, given: dict, progress, frames=None):
    from .detection import DetectionError, identify_markers

    frames = frames or {c: _frames_of(session, res, c) for c in session.cameras}
    try:
        return identify_markers(frames, rig, res["static"]["static_points"], session.marker_count,
                                params=given, progress=progress)
    except DetectionError as exc:
        raise AnalysisError("detect", f"{exc}") from None
    finally:
        for f in frames.values():
            f.close()


#: Rounds of the markers' check of the flash offsets: a camera corrected in one round moves the markers the
#: next round projects into the others (two cameras' flashes found in wrong frames need two rounds).
SYNC_CHECK_ROUNDS = 3


def _sync_check_summary(rounds: list, sync: dict) -> dict:
    """Per camera over the rounds of :func:`_check_sync_by_markers`: the total ``shift`` from the flash's
    offset, ``moved`` (a round moved the camera, even if the moves cancel), the first round's
    ``current_px``, the last round's ``best_px``, ``n_points`` and ``decided``, ``rounds`` and ``settled``
    (the last round moved no camera: the offsets the results use were checked; False when the rounds ran
    out with a correction still to check)."""
    flash = sync.get("flash_offsets", sync["offsets"])
    settled = not any(v["shift"] for v in rounds[-1].values())
    out = {}
    for c, last in rounds[-1].items():
        out[c] = {"shift": int(sync["offsets"][c] - flash[c]), "moved": any(r[c]["shift"] for r in rounds),
                  "current_px": rounds[0][c]["current_px"], "best_px": last["best_px"],
                  "n_points": last["n_points"], "decided": last["decided"], "rounds": len(rounds),
                  "settled": settled}
    return out


def _check_sync_by_markers(session: Session, params: AnalysisParams, res: dict, idn, progress) -> dict:
    """Each camera's flash offset checked against the instants of the others' markers.

    For every camera, the markers triangulated from the OTHER cameras are
    projected into its frames shifted by up to one second
    (:func:`horsemocap.detection.timeshift.frame_shift_residuals`); when a
    shift clearly puts them on its marker regions
    (:func:`~horsemocap.detection.timeshift.best_frame_shift`), the camera's
    offset is corrected and ``res["sync"]`` says so (``offsets_from``,
    ``flash_offsets``). Returns per camera the shift and the residuals.
    """
    from .detection import DetectionParams
    from .detection.identification import _area_range, _min_circ
    from .detection.timeshift import best_frame_shift, frame_shift_residuals
    from .reconstruction import triangulate

    rig, sync = res["rig"]["rig"], res["sync"]
    offsets, n = sync["offsets"], sync["n_frames"]
    reach = max(5, int(round(session.fps)))
    out = {}
    for c in session.cameras:
        others = {o: idn.marker_px[o] for o in session.cameras if o != c}
        points = triangulate(rig, others, mode="joint").points
        first = max(-reach, -offsets[c])
        stop = min(sync["frame_counts"][c], offsets[c] + n + reach)
        seq = FrameSource(session.motion[c]).sequence(offsets[c] + first, stop, color=False)
        p = _detection_params(params, c) or DetectionParams()
        try:
            shifts, med, npts = frame_shift_residuals(rig[c], points, seq, first, range(-reach, reach + 1),
                                                      idn.thresholds[c], _area_range(p), _min_circ(p),
                                                      centroid=p.centroid)
        finally:
            seq.close()
        fs = best_frame_shift(shifts, med, npts)
        out[c] = {"shift": fs.best, "current_px": fs.current_px, "best_px": fs.best_px, "n_points": fs.n_points,
                  "decided": fs.decided}
    moved = {c: v["shift"] for c, v in out.items() if v["shift"]}
    if moved:
        new = {c: int(offsets[c] + moved.get(c, 0)) for c in session.cameras}
        what = ", ".join(f"{c} {d:+d} frame(s) (residual {out[c]['current_px']:.1f} -> {out[c]['best_px']:.2f} px)"
                         for c, d in moved.items())
        again = "flash_offsets" in sync                    # a round after a correction
        progress("detect", f"the {'corrected offsets still disagree' if again else 'flash offsets disagree'} with "
                           f"the markers: {what}; offsets {new}, identifying again")
        flash = sync.get("flash_offsets", offsets)          # the flash's own, kept over the rounds
        how = f"{sync['offsets_from']}{'; then' if again else ','} corrected by the markers ({what})"
        res["sync"] = {**sync, "offsets": new, "offsets_from": how,
                       "n_frames": check_frame_counts(session, sync["frame_counts"], new, offsets_from=how),
                       "flash_offsets": dict(flash)}
    return out


def _detect_per_camera(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """The thesis' chain: every camera on its own (chapter 4)."""
    from .detection import detect_markers

    n = res["sync"]["n_frames"]
    marker_px, reasons, chosen = {}, {}, {}
    for cam in session.cameras:
        progress("detect", f"camera '{cam}': {n} frames ...")
        frames = _frames_of(session, res, cam, progress, f"camera '{cam}' frames")
        track = detect_markers(frames, session.marker_count, params=_detection_params(params, cam))
        marker_px[cam], reasons[cam] = track.marker_px, track.reason
        chosen[cam] = track.params.to_dict()
        frames.close()
    seen = np.all([np.all(np.isfinite(marker_px[c][..., 0]), axis=1) for c in session.cameras], axis=0)
    segment = _longest_run(seen)
    if segment is None or segment[1] - segment[0] < 8:
        counts = {c: int(np.all(np.isfinite(marker_px[c][..., 0]), axis=1).sum()) for c in session.cameras}
        raise AnalysisError("detect", "fewer than 8 consecutive frames in which every camera sees every "
                            f"marker (frames with all markers, per camera: {counts}); check the motion "
                            "videos, the threshold and the marker count in session.json")
    progress("detect", f"frames {segment[0]}..{segment[1] - 1} seen by every camera")
    gaps = _gaps_inside(seen, reasons)
    if gaps:
        progress("detect", "not every marker seen in frames " + "; ".join(gaps)
                 + f"; analysing the longest run {segment[0]}..{segment[1] - 1}")
    return {"marker_px": marker_px, "reason": reasons, "all_seen": seen,
            "segment": segment, "detection": chosen}


def _gaps_inside(seen: np.ndarray, reasons: dict) -> list[str]:
    """Frames between the first and last all-seen frame where a marker is missing, and why."""
    idx = np.flatnonzero(seen)
    if idx.size == 0:
        return []
    out = []
    for k in range(idx[0], idx[-1] + 1):
        if seen[k]:
            continue
        why = sorted({f"{cam} marker{m + 1} {r[k, m]}" for cam, r in reasons.items()
                      for m in range(r.shape[1]) if r[k, m]})
        out.append(f"{k} ({', '.join(why)})")
    return out


def _longest_run(mask: np.ndarray):
    best, start = None, None
    for i, v in enumerate(list(mask) + [False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if best is None or i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return best


def step_triangulate(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """3D marker positions in the reference camera frame (section 5.1).

    The analysed segment is the longest run, inside the detection's, in
    which every marker was triangulated (a point whose views disagree beyond
    the residual limit is NaN with reason ``inconsistent_views``). Each
    point's covariance for the detection noise estimated from the residuals
    (``covariance``, world frame; an interpolated point takes its nearest
    measured frame's) weights the markers in the rigid-body step's pose
    registration.
    """
    from .reconstruction import nearest_covariance, triangulate

    from .detection import bridge_gaps

    tri = triangulate(res["rig"]["rig"], res["detect"]["marker_px"], mode=params.triangulation, covariance=True)
    points, bridged = bridge_gaps(tri.points, _max_gap(session, params))
    cov = None if tri.covariance is None else nearest_covariance(tri.covariance, bridged)
    reason = np.where(bridged, "interpolated", tri.reason)
    if bridged.any():
        progress("triangulate", f"{int(bridged.sum())} marker position(s) in gaps of at most "
                                f"{_max_gap(session, params)} frames interpolated")
    med = {c: float(np.nanmedian(r)) if np.isfinite(r).any() else float("nan") for c, r in tri.residual_px.items()}
    progress("triangulate", f"{params.triangulation} mode; median reprojection residual (px) "
                            + ", ".join(f"{c} {v:.3f}" for c, v in med.items()))
    a, b = res["detect"]["segment"]
    ok = np.zeros(len(tri.points), bool)
    ok[a:b] = np.all(np.isfinite(points[a:b]), axis=(1, 2))
    segment = _longest_run(ok)
    if segment is None or segment[1] - segment[0] < 8:
        why = sorted({str(r) for r in reason[a:b].ravel() if r})
        raise AnalysisError("triangulate", f"fewer than 8 consecutive frames with every marker triangulated "
                            f"(reasons: {', '.join(why) or 'none'}); check the rig (calibration) and the "
                            "detections in markers_2d.csv")
    if segment != (a, b):
        progress("triangulate", f"analysing frames {segment[0]}..{segment[1] - 1}: some markers of frames "
                                f"{a}..{b - 1} could not be triangulated ("
                                + ", ".join(sorted({str(r) for r in reason[a:b].ravel() if r and r != "interpolated"}))
                                + ")")
    return {"points": points, "residual_px": tri.residual_px, "reason": reason, "n_views": tri.n_views,
            "segment": segment, "covariance": cov, "noise_px": tri.noise_px}


def still_params(params: AnalysisParams, kind: str, cameras) -> dict:
    """The detector parameters of one still per camera (``params.stills[kind]``, "all" then the camera).

    Returns ``{camera: DetectionParams}`` (empty when every choice is automatic).
    """
    from .detection import DetectionParams

    given = params.stills.get(kind, {})
    if not given:
        return {}
    out = {}
    for c in cameras:
        d = {**given.get("all", {}), **given.get(c, {})}
        if "labels" in d:
            d["labels"] = tuple(d["labels"])
        out[c] = DetectionParams(**d)
    return out


def _still_points(session: Session, rig: Rig, images: dict, count: int, step: str, mode: str,
                  given: dict | None = None):
    """Markers of one still per camera, matched across the cameras and triangulated.

    :func:`horsemocap.detection.detect_still_views` keeps only candidates that
    triangulate consistently in every camera (a glint or a buckle seen by one
    camera is not a marker), then picks the most marker-like ones. ``given``
    (:func:`still_params`): per-camera thresholds for that matching, or, with
    labels for every camera, the thesis' way (Appendix A 7a, 8a, 12a): the
    labelled regions of each camera taken as they are
    (:func:`horsemocap.detection.detect_still`).
    """
    from .detection import detect_still, detect_still_views
    from .reconstruction import triangulate

    given = given or {}
    try:
        imgs = {c: read_image(images[c]) for c in session.cameras}
        if given and all(given[c].labels is not None for c in session.cameras):
            px = {c: detect_still(imgs[c], count, given[c]) for c in session.cameras}
        else:
            px = detect_still_views(imgs, rig, count, given or None)
    except ValueError as exc:
        files = ", ".join(str(images[c]) for c in session.cameras)
        raise AnalysisError(step, f"{files}: {exc}") from None
    return triangulate(rig, {c: p[None] for c, p in px.items()}, mode=mode).points[0], px


def step_plumb(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Gravity from the plumb line's two markers (section 5.3)."""
    from .frames import gravity_from_plumb

    if session.plumb is None:
        raise AnalysisError("plumb", f"{session.json_path}: no 'plumb' stills; gravity cannot be found")
    pts, px = _still_points(session, res["rig"]["rig"], session.plumb, 2, "plumb", params.triangulation,
                            still_params(params, "plumb", session.cameras))
    # detect_still orders the two plumb markers top first (image v): the upper one is
    # the tail, the lower one the tip, and gravity points from tail to tip (down).
    gravity = gravity_from_plumb(tip_world=pts[1], tail_world=pts[0])
    progress("plumb", f"gravity {np.round(gravity, 4).tolist()}")
    return {"plumb_points": pts, "plumb_px": px, "gravity": gravity}


def step_static(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Static shot: the markers and the saddle marker, all visible (section 6.3)."""
    if session.static is None:
        return {"static_points": None, "static_px": None,
                "missing": f"{session.json_path}: no 'static' stills; the saddle marker cannot be placed"}
    pts, px = _still_points(session, res["rig"]["rig"], session.static, session.marker_count + 1,
                            "static", params.triangulation, still_params(params, "static", session.cameras))
    return {"static_points": pts, "static_px": px}


def step_smooth(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Smoothing of every coordinate (section 5.2), or none.

    The thesis smooths with ``smooth(y, 0.1, 'rloess')``; ``"none"`` keeps
    the triangulated positions (the Fourier fits of section 5.5 filter them).
    """
    from .smoothing import smooth_positions

    a, b = res["triangulate"]["segment"]
    raw = res["triangulate"]["points"][a:b]
    if params.smoothing_method == "none":
        return {"raw": raw, "smoothed": raw.copy()}
    smoothed = smooth_positions(raw, span=params.smoothing_span, method=params.smoothing_method)
    return {"raw": raw, "smoothed": smoothed}


def step_motion_frame(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Motion reference frame: x along net displacement, y along gravity (5.3).

    ``params.motion_frame = "period"``: the thesis' eq. 5.6/5.7 over one or
    two periods; ``"record"``: x from the net displacement over the whole
    record (:func:`horsemocap.frames.motion_frame_from_record`), the period
    then only estimated for the comfort step and possibly absent; ``"auto"``
    (default): ``"period"`` when a period is given or found, else ``"record"``.
    """
    from .frames import motion_frame, motion_frame_from_record, stride_period, to_motion_frame

    smoothed = res["smooth"]["smoothed"]
    if res["static"]["static_points"] is None:
        raise AnalysisError("motion_frame", res["static"]["missing"])
    a, b = res["triangulate"]["segment"]
    period, faster, not_found = params.period_frames, None, None
    if period is None:       # estimated once, a horse's stride the bound (frames.HORSE_STRIDE_HZ)
        try:
            period, faster = stride_period(smoothed, session.fps, gravity=res["plumb"]["gravity"])
        except ValueError as exc:
            not_found = exc
    mode = params.motion_frame
    if mode == "auto":
        try:
            motion_frame(smoothed, res["plumb"]["gravity"], marker=params.x_marker,
                         period=period, n_periods=params.n_periods)
            mode = "period"
        except ValueError as exc:
            progress("motion_frame", f"the thesis' motion frame needs a period: {exc}; using the net "
                                     "displacement over the whole record instead")
            mode = "record"
    if mode == "record":
        why = "given" if params.period_frames is not None else \
            "estimated" if not_found is None else f"not found ({not_found})"
        try:
            mf = motion_frame_from_record(smoothed, res["plumb"]["gravity"], period)
        except ValueError as exc:
            raise AnalysisError("motion_frame", f"{exc} (frames {a}..{b - 1}; see trajectories in markers_2d.csv)") from None
        progress("motion_frame", "x-motion from the net displacement over the whole record; "
                 + (f"period {period:.2f} frames ({why})" if period is not None else
                    f"period {why}: only the comfort step needs it"))
        return {"frame": mf, "axes": mf.axes, "period_frames": None if period is None else float(period),
                "positions": to_motion_frame(smoothed, mf),
                "static": to_motion_frame(res["static"]["static_points"], mf),
                **_faster_period(session.fps, period, faster, progress)}
    try:
        mf = motion_frame(smoothed, res["plumb"]["gravity"], marker=params.x_marker,
                          period=period, n_periods=params.n_periods)
    except ValueError as exc:
        raise AnalysisError("motion_frame", f"{exc}. The analysed frames {a}..{b - 1} ({b - a} frames, the "
                            "longest run in which every camera sees every marker; see markers_2d.csv) "
                            "may hold less than the two periods the thesis uses: give the period in frames "
                            "with --period (analysis 'period_frames'), check the motion videos, or use "
                            "motion_frame 'record' (no period needed)") from None
    progress("motion_frame", f"period {mf.period_frames:.2f} frames")
    return {"frame": mf, "axes": mf.axes, "period_frames": float(mf.period_frames),
            "positions": to_motion_frame(smoothed, mf),
            "static": to_motion_frame(res["static"]["static_points"], mf),
            **_faster_period(session.fps, mf.period_frames, faster, progress)}


def _faster_period(fps, period, faster, progress) -> dict:
    """``{"faster_period_frames": faster}`` when the record also repeats faster than a horse strides
    (:func:`horsemocap.frames.stride_period`), so the period taken was searched again among longer lags
    (said, and judged by :func:`horsemocap.quality.check_stride_frequency`); else {}."""
    if faster is None:
        return {}
    progress("motion_frame", f"the record also repeats every {faster:.2f} frames ({fps / faster:.3g} Hz), faster than "
                             f"a horse strides: the period was searched among longer lags and taken as {float(period):.2f}")
    return {"faster_period_frames": float(faster)}


def _fourier_orders(given, n_markers):
    """``{"y": N, "z": N}`` or per-marker ``[[Ny, Nz], ...]`` -> array (m, 2) or None."""
    if given is None:
        return None
    if isinstance(given, dict):
        if "y" not in given or "z" not in given:
            return None
        return np.tile([int(given["y"]), int(given["z"])], (n_markers, 1))
    arr = np.asarray(given, int)
    if arr.shape != (n_markers, 2):
        raise AnalysisError("rigid_body", f"parameter 'fourier_orders': expected {{'y': N, 'z': N}} or "
                                          f"{n_markers} pairs [Ny, Nz], got {given!r}")
    return arr


def _extra_orders(given, key, k):
    """``fourier_orders[key]`` ("rotation": 3 ints or one, "saddle": [Ny, Nz] or one) or None."""
    if not isinstance(given, dict) or given.get(key) is None:
        return None
    o = np.broadcast_to(np.asarray(given[key], int), (k,))
    return o.copy()


def step_rigid_body(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Registration, pose trajectory, fits, omega/alpha and the hidden saddle marker (5.4-5.5, 6).

    One call of :func:`horsemocap.rigid.analyse_rigid_body`. With
    ``kinematics="pose_spline"`` the markers' poses are registered
    frame by frame to the static shot and smoothed (:mod:`horsemocap.pose`),
    and omega, alpha, the markers' and the saddle's kinematics come from that
    pose trajectory; the thesis' chain (poly x, Fourier y/z with the order
    rule of 5.5.2.2, the six versions, eq. 6.48-6.55) is computed too and is
    what ``kinematics="fits"`` (default) passes on. Per-frame conditioning (the eq. 6.35
    angle, the marker triangle's smallest height, the registration residual)
    is kept, and a warning is printed when it makes the result unreliable.
    """
    from .frames import time_axis, to_motion_frame
    from .pose import CollinearMarkersError
    from .params import FitsParams, PoseParams, RigidBodyParams
    from .rigid import FourierOrders, PoseInput, analyse_rigid_body
    from .splines import ChangePointError

    positions, static = res["motion_frame"]["positions"], res["motion_frame"]["static"]
    # the pose trajectory is smoothed from the unsmoothed positions (its own smoothing is chosen
    # from their noise); the thesis chain keeps the smoothing step's positions (5.2)
    raw = to_motion_frame(res["smooth"]["raw"], res["motion_frame"]["frame"])
    t = time_axis(len(positions), session.fps)
    pose_t, pose_points = None, raw
    lo, hi = a, b = res["triangulate"]["segment"]
    if params.kinematics == "pose_spline" and params.pose_partial_frames:
        lo, hi = pose_margin(res["triangulate"]["points"], res["triangulate"]["segment"])
        if (lo, hi) != (a, b):
            pose_points = to_motion_frame(res["triangulate"]["points"][lo:hi], res["motion_frame"]["frame"])
            pose_t = np.arange(lo - a, hi - a) / float(session.fps)
            progress("rigid_body", f"pose trajectory smoothed over {_frames_text(session, res, lo, hi - 1)}: {a - lo} "
                                   f"before and {hi - b} after the analysed frames have two markers (reported: "
                                   f"{_frames_text(session, res, a, b - 1)})")
    cov = res["triangulate"].get("covariance") if params.pose_weights == "covariance" else None
    if cov is not None:   # the markers' covariances in the motion frame (x_M = A (x - o): A C A^T)
        axes = res["motion_frame"]["frame"].axes
        cov = axes @ cov[lo:hi] @ axes.T
    period = res["motion_frame"]["period_frames"]
    fo = params.fourier_orders
    _check_pose_events(params.pose_events, t if pose_t is None else pose_t)
    try:
        rb = analyse_rigid_body(
            t, positions, static,
            RigidBodyParams(kinematics=params.kinematics, saddle_marker=params.saddle_marker,
                            fits=FitsParams(x_degree=params.x_degree, fourier_orders=fo, order_rule=params.order_rule,
                                            trend=params.fourier_trend, angular_method=params.angular_method,
                                            omega_versions=params.omega_versions,
                                            alpha_versions=params.alpha_versions,
                                            saddle_method=params.saddle_method),
                            pose=PoseParams(smoothing=params.pose_smoothing, partial_frames=params.pose_partial_frames,
                                            harmonics=params.pose_harmonics, weights=params.pose_weights,
                                            rotation_weights=params.pose_rotation_weights,
                                            events=params.pose_events)),
            period_s=None if period is None else period / session.fps,
            fourier_orders=FourierOrders(_fourier_orders(fo, positions.shape[1]), _extra_orders(fo, "rotation", 3),
                                         _extra_orders(fo, "saddle", 2)),
            pose_input=PoseInput(points=pose_points, t=pose_t, covariance=cov))
    except CollinearMarkersError as exc:
        raise AnalysisError("rigid_body", f"{exc} (static shot of {session.json_path})") from None
    except ChangePointError as exc:
        raise AnalysisError("rigid_body", f"parameter 'pose_events': {exc}") from None
    orders = np.asarray(rb.motion_fit.orders)[:, 1:] if rb.motion_fit is not None else None
    pos, vel, acc = rb.marker_kinematics
    cond = conditioning(rb)
    sing = float(np.nanmin(np.abs(90 - cond["singularity_deg"])))
    if params.kinematics == "pose_spline":
        sm = rb.pose.smoothing
        ran = rb.pose.smoothing_choice
        how = (f"{ran['method']} smoothing ({params.pose_smoothing}: {ran['reason']})" if ran
               else f"{params.pose_smoothing} smoothing")
        progress("rigid_body", f"pose trajectory ({how}, effective degrees of "
                 f"freedom per component " + ", ".join(f"{k} {v['edf']:.1f}" for k, v in sm.items())
                 + f"); registration residual median {1000 * np.nanmedian(cond['registration_rms_m']):.2f} mm")
        weighted = [k for k, v in sm.items() if v.get("weights", "equal") != "equal"]
        if weighted:
            progress("rigid_body", "rotation smoothed with each frame weighted by its predicted variance (its noise "
                                   f"model explains the residuals better) in {', '.join(weighted)}")
        f0 = [v["fundamental_hz"] for v in sm.values() if v.get("fundamental_hz")]
        if f0:
            progress("rigid_body", f"stride harmonics of {f0[0]:.3f} Hz kept unpenalised, per component "
                     + ", ".join(f"{k} {_harmonics_text(v)}" for k, v in sm.items()))
        if params.pose_events:
            progress("rigid_body", "acceleration free to jump at the known change points (pose_events) "
                     + ", ".join(f"{e:g}" for e in sorted(params.pose_events)) + " s")
        if rb.chain_error:
            progress("rigid_body", f"the thesis' chain of fits was not computed: {rb.chain_error}")
    else:
        progress("rigid_body", f"Fourier orders (y, z) per marker {orders.tolist()}; omega by {params.angular_method}, "
                               f"saddle by {params.saddle_method}")
    progress("rigid_body", f"closest approach to the eq. 6.35 singularity {sing:.1f} deg; smallest marker "
                           f"triangle height {1000 * np.nanmin(cond['triangle_height_m']):.1f} mm")
    warn = list(cond["warnings"])
    for w in warn:
        progress("rigid_body", "WARNING: " + w)
    return {"analysis": rb, "t": t, "registered": pos, "model": rb.model, "saddle_static": rb.static_saddle,
            "static_order": [int(i) for i in rb.static_index], "saddle_index": int(rb.saddle_index),
            "velocity": vel, "acceleration": acc, "orders": orders,
            "omega": rb.omega, "alpha": rb.alpha, "singularity_deg": cond["singularity_deg"],
            "saddle_position": rb.saddle_position, "saddle_velocity": rb.saddle_velocity,
            "saddle_acceleration": rb.saddle_acceleration, "conditioning": cond, "warnings": warn,
            "saddle_angles_deg": saddle_angles(rb)}


def _check_pose_events(events, times) -> None:
    """Refuse ``pose_events`` outside the smoothed record (:class:`AnalysisError` naming the parameter)."""
    if not events:
        return
    lo, hi = float(times[0]), float(times[-1])
    outside = [e for e in events if not lo < e < hi]
    if outside:
        raise AnalysisError("rigid_body", f"parameter 'pose_events': {outside} s outside the smoothed record: expected "
                                          f"times strictly inside ({lo:.6g}, {hi:.6g}) s, the time_s axis of "
                                          "trajectories.csv (0 = the first analysed frame)")


def pose_margin(points: np.ndarray, segment, min_markers: int = 2) -> tuple[int, int]:
    """Frames next to the analysed segment in which at least ``min_markers`` markers have a 3D position.

    The analysed segment ends where a marker is lost; the frames just beyond
    it in which two markers are still triangulated carry five of the pose's
    six degrees of freedom (:func:`horsemocap.pose.partial_pose`). Returns
    ``(lo, hi)``: the segment ``(a, b)`` widened over the contiguous runs of
    such frames on both sides.
    """
    count = np.all(np.isfinite(np.asarray(points, float)), axis=2).sum(1)
    lo, hi = segment
    while lo > 0 and count[lo - 1] >= min_markers:
        lo -= 1
    while hi < count.size and count[hi] >= min_markers:
        hi += 1
    return int(lo), int(hi)


def conditioning(rb) -> dict:
    """Per-frame conditioning of a :class:`~horsemocap.rigid.RigidBodyAnalysis`, as a dict
    (:func:`horsemocap.rigid.conditioning`: ``singularity_deg``, ``triangle_height_m``,
    ``registration_rms_m``, ``registration_n_markers``, ``noise_m``, ``warnings``)."""
    from .rigid import conditioning as rigid_conditioning

    return dict(vars(rigid_conditioning(rb)))


def saddle_angles(rb) -> np.ndarray:
    """Roll, pitch, yaw (deg) of the saddle per frame (n, 3): :func:`horsemocap.rigid.saddle_angles`."""
    from .rigid import saddle_angles as rigid_saddle_angles

    return rigid_saddle_angles(rb)


def _frames_text(session: Session, res: dict, first: int, last: int) -> str:
    """Synchronised frames ``first..last`` as the results files number them: the reference camera's own
    frames (``frame`` of trajectories.csv), with the synchronised index beside them."""
    off = int(res["sync"]["offsets"][session.reference_camera])
    return (f"{session.reference_camera} camera's frames {first + off}..{last + off} "
            f"(synchronised frames {first}..{last})")


def step_comfort(session: Session, params: AnalysisParams, res: dict, progress) -> dict:
    """Whole-body vibration indicators of the saddle's vertical motion (chapter 7).

    The indicators are harmonic series of the stride frequency: the one the
    motion-frame step estimated (5.3), or, if it found none, one estimated
    from the saddle's vertical position; if neither exists the indicators are
    not computed (``indicators`` None, ``reason`` says why) and the earlier
    results stand.
    """
    from .vibration import saddle_comfort

    rb = res["rigid_body"]
    period = res["motion_frame"]["period_frames"]
    f0_hz = None if period is None else session.fps / period
    pos, acc, vel = rb["saddle_position"], rb["saddle_acceleration"], rb["saddle_velocity"]
    ok = np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(vel), axis=1)
    try:
        ind = saddle_comfort(rb["t"][ok], pos[ok], acc[ok], vel[ok], mode=params.weighting_mode, f0_hz=f0_hz)
    except ValueError as exc:
        why = f"no stride frequency could be estimated ({exc})" if f0_hz is None else str(exc)
        progress("comfort", f"comfort indicators not computed: {why}")
        return {"indicators": None, "reason": why}
    # no figure here: the command prints the comfort figures only beside the quality verdict (horsemocap.run)
    progress("comfort", "indicators of chapter 7 computed")
    return {"indicators": ind}


STEP_FUNCTIONS = {name: globals()[f"step_{name}"] for name in STEPS}


# ---------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------

def analyze(session_dir, out_dir=None, params: AnalysisParams | dict | None = None, *,
            until: str | None = None, progress=None, write_outputs: bool = True,
            reuse: bool = False, previous_results=None, board_views=None) -> Analysis:
    """Run the analysis of a session, step by step.

    Parameters
    ----------
    session_dir : path
        The session folder (``session.json`` inside).
    out_dir : path, optional
        Results folder (outside the session). None: nothing is written.
    params : AnalysisParams or dict, optional
        Overrides; the session's own ``analysis`` object is applied first.
    until : str, optional
        Stop after this step (one of :data:`STEPS`).
    progress : callable(step, message), optional
        Progress reports; default prints to stderr.
    write_outputs : bool
        Write the spec's result files into ``out_dir`` as steps finish.
    reuse : bool
        Keep each step's result in ``out_dir``'s results store and reuse the
        stored ones computed for the same session, parameters and code.
    previous_results : path, optional
        An earlier run's results folder (``horsemocap analyze`` writes into a
        new folder that replaces it): its cached calibration
        (``calibration.json``) is reused when the views, board, cameras and
        code are the same, as one in ``out_dir`` is.
    board_views : horsemocap.calibration.cache.BoardDetectionJob, optional
        The board detection of the session's views, started earlier by the
        caller (``horsemocap analyze`` starts it as soon as the session is
        read); its views are used when they are those of the session.

    Returns
    -------
    Analysis

    Raises
    ------
    SessionError, AnalysisError
        Naming the input to look at; the steps before stay written.

    Notes
    -----
    When the rig is calibrated from checkerboard views, the rig step starts
    in a thread at once and runs while the sync step reads the videos (it
    needs nothing of it); its progress lines may come before the sync's.
    ``timings["rig"]`` is the step's own duration. The whole run then has
    one BLAS thread (:data:`horsemocap.threads.blas_single_threaded`).
    """
    session = load_session(session_dir)
    params = resolve_params(session, params)
    params.check_session(session)
    progress = progress or _progress_printer()
    if until is not None and until not in STEPS:
        raise ValueError(f"until must be one of {STEPS}, got {until!r}")
    analysis = Analysis(session, params)
    if out_dir is not None:
        check_outside(out_dir, session.root)
        Path(out_dir).mkdir(parents=True, exist_ok=True)
    store = ResultsStore(out_dir) if (reuse and out_dir is not None) else None
    keys = step_keys(session, params) if store else {}
    early = store is None and session.calibrates_from_views(params.recalibrate) and until != "sync"
    # the calibration's one BLAS thread (horsemocap.threads) set here, in the main thread, before
    # the rig's thread starts: its own blocks inside then leave the setting alone
    with blas_single_threaded() if early else contextlib.nullcontext():
        early_rig = None
        if early:
            progress = _serialised(progress)
            early_rig = _BackgroundStep(step_rig, session, params, {}, progress,
                                        cache_dirs=(out_dir, previous_results), board_views=board_views)
        try:
            _run_steps(analysis, store, keys, until, out_dir, write_outputs, progress, previous_results, early_rig,
                       board_views)
        except BaseException:
            if board_views is not None:
                board_views.stop()  # an error or Ctrl-C: the rig step waiting for the views ends at once
            raise
        finally:
            if early_rig is not None:
                early_rig.wait()    # never left running: it writes calibration.json into out_dir
    return analysis


def _harmonics_text(info: dict) -> str:
    """How many stride harmonics a pose component kept, with their orders when they are not 1..K."""
    n = int(info.get("harmonics", 0))
    orders = [int(k) for k in info.get("harmonic_indices", range(1, n + 1))]
    return str(n) if orders == list(range(1, n + 1)) else f"{n} (order {', '.join(map(str, orders))})"


class _BackgroundStep:
    """One step run in a thread: the rig's calibration while the sync step reads the videos (issue 16).

    The rig step needs nothing of the sync step's result; the board
    detection's threads and the bundle adjustment then share the processors
    with the flash search. :meth:`result` gives the step's result or raises
    its error; ``seconds`` is the step's own duration.
    """

    def __init__(self, function, *args, **kwargs):
        import threading

        self.seconds = 0.0
        self._value, self._error = None, None
        self._thread = threading.Thread(target=self._run, args=(function, args, kwargs),
                                        name="horsemocap-rig", daemon=True)
        self._thread.start()

    def _run(self, function, args, kwargs):
        t0 = time.perf_counter()
        try:
            self._value = function(*args, **kwargs)
        except BaseException as exc:  # given to the caller by result()
            self._error = exc
        finally:
            self.seconds = time.perf_counter() - t0

    def wait(self) -> None:
        self._thread.join()

    def result(self):
        self.wait()
        if self._error is not None:
            raise self._error
        return self._value


def _serialised(progress):
    """``progress`` called by one thread at a time (the rig step reports from its own thread)."""
    import threading

    lock = threading.Lock()

    def report(*args):
        with lock:
            progress(*args)
    report.counts = getattr(progress, "counts", False)
    return report


def _run_steps(analysis: Analysis, store, keys: dict, until, out_dir, write_outputs: bool, progress,
               previous_results, early_rig, board_views) -> None:
    """:func:`analyze`'s loop over the steps (``early_rig``: the rig step already running)."""
    from . import results as result_files

    session, params = analysis.session, analysis.params
    for name in STEPS:
        t0 = time.perf_counter()
        key = keys.get(name, "")
        try:
            stored = store.load(name, key) if store else None
            if stored is not None:
                analysis.results[name] = stored
            elif name == "rig" and early_rig is not None:
                analysis.results[name] = early_rig.result()
                t0 = time.perf_counter() - early_rig.seconds      # the step's own time, not the wait
            else:
                if name == "rig":
                    analysis.results[name] = step_rig(session, params, analysis.results, progress,
                                                      cache_dirs=(out_dir, previous_results), board_views=board_views)
                else:
                    analysis.results[name] = STEP_FUNCTIONS[name](session, params, analysis.results, progress)
                if store:
                    store.save(name, analysis.results[name], key)
            _carry_corrections(analysis.results, name)
        except (AnalysisError, SessionError) as exc:
            exc.partial = analysis  # the steps that finished (horsemocap.run marks them partial)
            raise
        except Exception as exc:  # a step's own error: say which step and input
            err = AnalysisError(name, f"{type(exc).__name__}: {exc}")
            err.partial = analysis
            raise err from exc
        finally:
            analysis.timings[name] = time.perf_counter() - t0
            if out_dir is not None and write_outputs:
                result_files.write_available(Path(out_dir), analysis)
        if name == until:
            break


def run_steps(session: Session, params: AnalysisParams, results: dict, steps, progress=None) -> Analysis:
    """Run ``steps`` (names, in pipeline order) on top of given ``results``.

    For studies that replace one step's output (e.g. noisy detections) and
    follow the change through the later steps. Nothing is written.
    """
    progress = progress or (lambda *a: None)
    analysis = Analysis(session, params, dict(results))
    for name in steps:
        t0 = time.perf_counter()
        analysis.results[name] = STEP_FUNCTIONS[name](session, params, analysis.results, progress)
        _carry_corrections(analysis.results, name)
        analysis.timings[name] = time.perf_counter() - t0
    return analysis


def _carry_corrections(results: dict, name: str) -> None:
    """A step that corrects an earlier one's result says so in its own (also when loaded from the store).

    The detect step's check of the flash offsets by the markers
    (``sync_corrected``) replaces the sync step's offsets for every later step.
    """
    if name == "detect" and results[name].get("sync_corrected"):
        results["sync"] = results[name]["sync_corrected"]


def resolve_params(session: Session, params=None) -> AnalysisParams:
    """Defaults, then the session's ``analysis`` object, then ``params``."""
    base = AnalysisParams.from_dict(session.analysis, f"{session.json_path}: 'analysis'")
    if params is None:
        return base
    if isinstance(params, AnalysisParams):
        return params
    # the given values only (not the defaults filled in), so a preset named in either is not undone
    return AnalysisParams.from_dict({**session.analysis, **params})


def session_files(session: Session) -> list[Path]:
    """Every input file of a session: session.json, motion sources, calibration, stills.

    Folders (image sequences, calibration views) give their image files.
    """
    from .sources import list_images

    paths = [session.json_path]
    groups = [session.motion, session.calibration_images or {}, session.plumb or {}, session.static or {}]
    for group in groups:
        for cam in sorted(group):
            p = Path(group[cam])
            paths.extend(list_images(p) if p.is_dir() else [p])
    if session.rig_path is not None:
        paths.append(session.rig_path)
    return paths


FINGERPRINT_EDGE_BYTES = 1 << 20


def file_fingerprint(path: Path, edge: int = FINGERPRINT_EDGE_BYTES) -> str:
    """``path``, size, mtime (ns) and the SHA-256 of its first and last ``edge`` bytes.

    Any change of length, modification time or the bytes at either end
    (a replaced video, re-encoded images, a truncated file) changes it.
    Files up to ``2 * edge`` bytes are hashed whole. Measured on the 2-core
    test machine: a 1 GB file takes 3.2 ms this way and 0.99 s hashed whole
    (from the page cache; longer from disk), and every notebook computes the
    key, so a session of multi-GB videos would cost seconds per notebook;
    the bundled session's 145 files (10.3 MB) take 49 ms either way.
    """
    st = path.stat()
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        if st.st_size <= 2 * edge:
            h.update(fh.read())
        else:
            h.update(fh.read(edge))
            fh.seek(-edge, os.SEEK_END)
            h.update(fh.read(edge))
    return f"{path}|{st.st_size}|{st.st_mtime_ns}|{h.hexdigest()}"


def run_key(session: Session, params: AnalysisParams | None) -> str:
    """Fingerprint of a run: every input file of the session, the parameters and the package's code.

    ``params=None``: the files and the code only (:func:`step_keys` adds each step's parameters).

    Each file of :func:`session_files` enters by :func:`file_fingerprint`
    (replacing a video or a still recomputes the steps; so does touching it).
    """
    h = hashlib.sha256()
    for path in session_files(session):
        h.update(file_fingerprint(path).encode("utf-8", "surrogateescape"))
    if params is not None:
        h.update(json.dumps(params.to_dict(), sort_keys=True, default=str).encode())
    for src in sorted(Path(__file__).parent.rglob("*.py")):
        h.update(src.read_bytes())
    return h.hexdigest()


# The parameters each step reads; a step's stored result depends on its own and every earlier step's.
# Parameters no step before the rigid-body step names are the rigid-body step's (and so the comfort
# step's), so a parameter added later is never left out of a key.
STEP_PARAMS = {
    "sync": ("sync_offsets",),
    "rig": ("recalibrate", "calibration_exclude"),
    "plumb": ("stills", "triangulation"),
    "static": ("stills", "triangulation"),
    "detect": ("detection_method", "detection", "max_gap_frames"),
    "triangulate": ("triangulation", "max_gap_frames"),
    "smooth": ("smoothing_method", "smoothing_span"),
    "motion_frame": ("motion_frame", "x_marker", "period_frames", "n_periods"),
}


def step_keys(session: Session, params: AnalysisParams) -> dict:
    """The results-store key of every step: :func:`run_key` restricted to what the step depends on.

    A step's key covers the session's files, the package's code and the
    parameters of :data:`STEP_PARAMS` of this and every earlier step; from
    the rigid-body step on, every parameter. So a threshold chosen in
    notebook 04 recomputes the steps from detection on and keeps the
    calibration, the plumb and the static shot.
    """
    base = run_key(session, None)
    values = params.to_dict()
    keys, used = {}, set()
    for name in STEPS:
        if name in STEP_PARAMS:
            used |= set(STEP_PARAMS[name])
            part = {k: values[k] for k in sorted(used)}
        else:
            part = values
        h = hashlib.sha256(base.encode())
        h.update(json.dumps(part, sort_keys=True, default=str).encode())
        keys[name] = h.hexdigest()
    return keys


def safe_store_name(name: str) -> str:
    """A session name as one folder name that stays inside the store.

    Letters, digits, ``.``, ``-`` and ``_`` are kept, anything else (``/``,
    ``..``, NUL, spaces) becomes ``_``; leading dots are dropped. A changed
    name gets 8 hex digits of its SHA-256, so two names never share a folder.
    """
    import re

    safe = re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".")[:80] or "session"
    if safe != name:
        safe += "-" + hashlib.sha256(name.encode("utf-8", "surrogateescape")).hexdigest()[:8]
    return safe


def notebook_results_dir(session: Session | Path) -> Path:
    """Where notebooks keep a session's results (``$HORSEMOCAP_RESULTS``).

    ``<root>/<name>-<folder>`` with the session's name made safe by
    :func:`safe_store_name` (a name like ``../../x`` stays inside the root)
    and 8 hex digits of the SHA-256 of the session folder's resolved path:
    two sessions with one name (the bundled Horse 2 canter and the herd's
    render of it) never share their results or the choices made for them.
    """
    from .data import cache_dir

    if not isinstance(session, Session):
        session = load_session(session, open_sources=False)
    folder = str(Path(session.root).resolve())
    digest = hashlib.sha256(folder.encode("utf-8", "surrogateescape")).hexdigest()[:8]
    root = Path(os.environ.get("HORSEMOCAP_RESULTS") or (cache_dir() / "results")).resolve()
    path = root / f"{safe_store_name(session.name)}-{digest}"
    if path.parent != root:  # cannot happen with a safe name; never write outside the store
        raise ValueError(f"session name {session.name!r} leaves the results store {root}")
    return path


def results_for(session_dir=None, until: str = "comfort", params=None) -> Analysis:
    """The analysis of a session up to a step, for notebooks.

    Runs the steps quietly and writes the spec's files to
    :func:`notebook_results_dir` (a clean folder per test run under nbval).
    Steps an earlier notebook computed for the same session, parameters and
    code are loaded from the results store, so each notebook runs alone and
    none repeats another's work.

    Parameters
    ----------
    session_dir : path, optional
        Default: the session of the workspace (:mod:`horsemocap.workspace`:
        the one chosen in a notebook's first cell, else the bundled session).
    until : str
        The last step to run.
    params : dict or AnalysisParams, optional
        The choices made with the notebooks' widgets (the session's
        ``choices.json``) are applied first, then a dict's overrides; an
        :class:`AnalysisParams` is used as it is. With no choices made, every
        choice is the automatic one.
    """
    from .workspace import current_session, read_choices

    session_dir = Path(session_dir or current_session()).resolve()
    if not isinstance(params, AnalysisParams):
        chosen = read_choices(session_dir)
        if chosen or params:
            params = {**chosen, **(params or {})}
    return analyze(session_dir, notebook_results_dir(session_dir), params, until=until,
                   progress=lambda *a: None, reuse=True)
