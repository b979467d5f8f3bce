"""The result files of ``horsemocap analyze`` (spec ``sessions.md``).

:func:`write_available` writes every file whose steps have run, each one
atomically, so a failed step leaves the files of the steps before it whole.
"""
from __future__ import annotations

import csv
import io
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

import platform

import cv2
import scipy

from . import __version__
from .camera import rig_to_toml
from .detection import ACTIVE_PATH
from .detection.markers2d import marker_label, markers_2d_csv_text
from .passes import passes_rows
from .store import atomic_write_json, atomic_write_text
from .vibration import write_comfort_csv, write_comfort_spreadsheet

FORMAT = "horsemocap-results/1"


def _csv_text(header, rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def _num(v, digits=9) -> str:
    return "" if v is None or not np.isfinite(v) else f"{float(v):.{digits}g}"


def frame_numbers(analysis) -> tuple[np.ndarray, np.ndarray]:
    """``(frame, time_s)`` of the analysed samples.

    ``frame`` is the index in the reference camera's own motion source;
    ``time_s`` counts from the first analysed frame (thesis eq. 5.13).
    """
    s = analysis.session
    a, b = analysis.triangulate.segment
    frame = analysis.synchronisation.offsets[s.reference_camera] + np.arange(a, b)
    return frame, np.arange(b - a) / s.fps


def markers_2d_text(analysis) -> str:
    """``camera,frame,marker,u_px,v_px,reason,residual_px`` in each camera's own numbering."""
    tri = analysis.triangulate
    return markers_2d_csv_text(analysis.detect.marker_px, analysis.synchronisation.offsets, analysis.detect.reason,
                               tri.residual_px if tri else None)


def markers_3d_text(analysis) -> str:
    """``frame,marker,x_m,y_m,z_m,n_views,residual_px,reason``: every synchronised frame, world frame.

    Positions in the reference camera's frame (thesis ``CM_L``) before
    smoothing; ``n_views`` cameras used; ``residual_px`` the largest
    reprojection residual over them; ``reason`` empty when measured,
    ``interpolated`` in a bridged gap, else why there is no position.
    """
    s, tri = analysis.session, analysis.triangulate
    pts, reason = tri.points, tri.reason
    worst = np.fmax.reduce(np.stack(list(tri.residual_px.values())), axis=0)   # NaN-ignoring maximum
    views = tri.n_views
    off = analysis.synchronisation.offsets[s.reference_camera]
    rows = [[k + off, marker_label(m), *(_num(v) for v in pts[k, m]), int(views[k, m]),
             _num(worst[k, m], 4) if reason[k, m] != "interpolated" else "", str(reason[k, m])]
            for k in range(pts.shape[0]) for m in range(pts.shape[1])]
    return _csv_text(["frame", "marker", "x_m", "y_m", "z_m", "n_views", "residual_px", "reason"], rows)


def _points(analysis, key):
    """Marker and saddle arrays ``(n, m+1, 3)`` for ``position``/``velocity``/``acceleration``.

    Marker positions are the registered ones (section 5.5.2 keeps them);
    velocities and accelerations come from the fits.
    """
    rb = analysis.rigid_body
    markers = rb.registered if key == "position" else getattr(rb, key)
    return np.concatenate([markers, getattr(rb, f"saddle_{key}")[:, None, :]], axis=1)


def _point_names(n_markers):
    return [marker_label(i) for i in range(n_markers)] + ["saddle"]


def trajectories_text(analysis) -> str:
    frame, t = frame_numbers(analysis)
    pos = _points(analysis, "position")
    names = _point_names(pos.shape[1] - 1)
    rows = [[int(frame[k]), _num(t[k]), names[j], *(_num(v) for v in pos[k, j])]
            for k in range(len(frame)) for j in range(pos.shape[1])]
    return _csv_text(["frame", "time_s", "point", "x_m", "y_m", "z_m"], rows)


def kinematics_text(analysis) -> str:
    frame, t = frame_numbers(analysis)
    vel, acc = _points(analysis, "velocity"), _points(analysis, "acceleration")
    names = _point_names(vel.shape[1] - 1)
    rows = [[int(frame[k]), _num(t[k]), names[j], *(_num(v) for v in vel[k, j]), *(_num(v) for v in acc[k, j])]
            for k in range(len(frame)) for j in range(vel.shape[1])]
    return _csv_text(["frame", "time_s", "point", "vx_mps", "vy_mps", "vz_mps",
                      "ax_mps2", "ay_mps2", "az_mps2"], rows)


ANGULAR_OPTIONAL = ("roll_deg", "pitch_deg", "yaw_deg", "singularity_deg", "triangle_height_m",
                    "registration_rms_m")
"""Optional columns of angular.csv (docs/sessions.md): the saddle's orientation and the
per-frame conditioning of the rigid-body step."""


def angular_text(analysis) -> str:
    frame, t = frame_numbers(analysis)
    rb = analysis.rigid_body
    w, a, c = rb.omega, rb.alpha, rb.conditioning
    header = ["frame", "time_s", "wx_radps", "wy_radps", "wz_radps",
              "alphax_radps2", "alphay_radps2", "alphaz_radps2", *ANGULAR_OPTIONAL]
    extra = np.column_stack([rb.saddle_angles_deg, c.singularity_deg, c.triangle_height_m, c.registration_rms_m])
    rows = [[int(frame[k]), _num(t[k]), *(_num(v) for v in w[k]), *(_num(v) for v in a[k]),
             *(_num(v) for v in extra[k])] for k in range(len(frame))]
    return _csv_text(header, rows)


def passes_text(analysis) -> str:
    """``passes.csv``: every pass of the horse through the views, its verdict and comfort indicators, and
    the row ``all``: the comfort over every pass, weighted by their durations (:mod:`horsemocap.passes`)."""
    offset = analysis.synchronisation.offsets[analysis.session.reference_camera]
    header, rows = passes_rows(analysis.passes, offset, analysis.session.fps)
    return _csv_text(header, rows)


def software_record() -> dict:
    """What computed the results: the versions of horsemocap, Python, NumPy, SciPy and OpenCV, and the
    detection path (``"python"``: the only one since the optional compiled core was removed; earlier
    results may say ``"compiled"``, which gave the same numbers)."""
    return {"horsemocap": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "opencv": cv2.__version__, "detection_core": ACTIVE_PATH}


def analysis_record(analysis) -> dict:
    """Everything needed to repeat the run: parameters given and chosen."""
    record = {
        "format": FORMAT,
        "session": str(analysis.session.root),
        "session_name": analysis.session.name,
        "written": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "steps_done": list(analysis.steps_done),
        "parameters": analysis.params.to_dict(),
        "chosen": {},
        "timings_s": {k: round(v, 3) for k, v in analysis.timings.items()},
        "software": software_record(),
    }
    p, chosen = record["parameters"], record["chosen"]
    if analysis.sync is not None:
        _record_sync(analysis, p, chosen)
    if analysis.rig is not None:
        chosen["rig"] = analysis.rig.rig_from
    for kind in ("plumb", "static"):
        clip = _clip_record(getattr(analysis, kind, None))
        if clip:
            chosen[f"{kind}_clip"] = clip
    if analysis.detect is not None:
        _record_detect(analysis.detect, p, chosen)
    if analysis.triangulate is not None:
        chosen["analysed_frames"] = list(analysis.triangulate.segment)
    if analysis.motion_frame is not None:
        _set(p, "motion_frame.period_frames", analysis.motion_frame.period_frames)
        if analysis.motion_frame.frame.n_periods > 0:
            _set(p, "motion_frame.n_periods", int(analysis.motion_frame.frame.n_periods))
    if analysis.rigid_body is not None:
        _record_rigid_body(analysis.rigid_body, p, chosen)
    if analysis.comfort is not None and analysis.comfort.indicators is None:
        chosen["comfort_not_computed"] = analysis.comfort.reason
    if getattr(analysis, "passes", None) is not None:
        chosen["passes"] = [{"pass": p.index, "frames": list(p.run), "analysed_frames":
                             list(p.segment) if p.segment is not None else None, "verdict": p.verdict,
                             **({"error": p.error} if p.error else {})} for p in analysis.passes.passes]
    return record


def _set(parameters: dict, path: str, value) -> None:
    """Record a chosen value in the parameters object (``path``: a dotted field, as
    :meth:`~horsemocap.params.AnalysisParams.to_dict` nests it)."""
    *sections, name = path.split(".")
    node = parameters
    for key in sections:
        node = node.setdefault(key, {})
    node[name] = value


def _record_sync(analysis, p: dict, chosen: dict) -> None:
    sync = analysis.synchronisation
    _set(p, "sync.offsets", dict(sync.offsets))
    chosen["sync"] = {"offsets_from": sync.offsets_from, "n_frames": sync.n_frames}
    if sync.flash_offsets is not None:
        chosen["sync"]["flash_offsets"] = dict(sync.flash_offsets)
    if sync.flash_ambiguous:        # camera -> the frame of a second candidate nearly as likely
        chosen["sync"]["flash_ambiguous"] = {c: int(f) for c, f in sync.flash_ambiguous.items()}
    if sync.subframe_method:        # free-running cameras: the offsets to a fraction of a frame
        ref = analysis.session.reference_camera
        chosen["sync"]["subframe"] = {
            "method": sync.subframe_method,
            "offsets_frames": {c: round(v, 4) for c, v in sync.offsets_with_fraction(ref).items()},
            "phase_frames": {c: round(float(v), 4) for c, v in sync.phase_frames.items()},
            "uncertainty_frames": {c: round(float(v), 4) for c, v in sync.offset_uncertainty_frames.items()},
            "rate_ratio": {c: round(float(v), 7) for c, v in sync.rate_ratio.items()}}
    if sync.genlocked_check:        # a fully lit flash in every camera; the markers measured the phases
        chosen["sync"]["genlocked_by_markers"] = {
            "phase_frames": {c: round(p, 4) for c, (p, _) in sync.genlocked_check.items()},
            "uncertainty_frames": {c: round(u, 4) for c, (_, u) in sync.genlocked_check.items()}}
        if sync.genlocked_check_method:     # "linearised" (the search not needed) or "search"
            chosen["sync"]["genlocked_by_markers"]["method"] = sync.genlocked_check_method
    check = analysis.detect.sync_check if analysis.detect is not None else None
    if check:
        chosen["sync"]["checked_by_markers"] = {
            c: {"shift_frames": int(v.shift), "residual_px": _rounded(v.current_px),
                "residual_after_px": _rounded(v.best_px), "marker_frames": int(v.n_points),
                "decided": bool(v.decided), "rounds": int(v.rounds)}
            for c, v in check.items()}


def _clip_record(still) -> dict:
    """A plumb line's or static shot's clip as analysis.json records it: the frames averaged, every frame left
    out with its reason and, for the static shot, each point's scatter (mm), its lag-1 correlation and the
    independent frames the average is worth; empty for one still per camera (or no such step)."""
    used = getattr(still, "frames_used", None)
    if used is None:
        return {}
    record = {"frames_used": int(used),
              "frames_left_out": [{"frame": int(f), "reason": str(r)} for f, r in still.frames_left_out]}
    if getattr(still, "scatter_m", None) is not None:
        record.update(scatter_mm=[round(1000.0 * float(v), 3) for v in still.scatter_m],
                      scatter_lag1=_rounded(still.scatter_lag1),
                      effective_frames=round(float(still.effective_frames), 2))
    return record


def _record_detect(detect, p: dict, chosen: dict) -> None:
    _set(p, "detect.cameras", detect.detection)
    chosen["detection_method"] = detect.method
    if detect.method_note:
        chosen["detection_method_note"] = detect.method_note
    if detect.identification is not None:
        chosen["identification"] = {"anchor_frame": detect.identification.anchor_frame,
                                    "model_index_in_static": detect.identification.model_index}
    chosen["analysed_frames"] = list(detect.segment)
    if detect.fields:               # interlaced cameras: measured field by field
        chosen["interlaced_fields"] = {c: _fields_record(f) for c, f in detect.fields.items()}


def _fields_record(measured) -> dict:
    """An interlaced camera's :class:`~horsemocap.steps.detect.FieldsMeasured` as analysis.json records it."""
    reasons, counts = np.unique(measured.reason[measured.reason != ""], return_counts=True)
    return {"aliasing_px": [round(float(v), 4) for v in measured.aliasing_px],
            "aliasing_removed": not measured.aliasing_note, **({"aliasing_note": measured.aliasing_note}
                                                               if measured.aliasing_note else {}),
            "kept_blended": {str(r): int(n) for r, n in zip(reasons, counts)}}


def _record_rigid_body(rb, p: dict, chosen: dict) -> None:
    chosen["static_order"] = rb.static_order
    chosen["saddle_index_in_static"] = rb.saddle_index
    if getattr(rb.body, "model_choice", None) is not None:     # the static shot's shape or the moving frames'
        chosen["marker_model"] = rb.body.model_choice.to_dict()
    if rb.orders is not None:
        _set(p, "rigid_body.fits.fourier_orders", np.asarray(rb.orders).astype(int).tolist())
    if rb.warnings:
        chosen["rigid_body_warnings"] = list(rb.warnings)
    pose = rb.body.pose
    if pose is not None and pose.smoothing_choice:
        chosen["pose_smoothing"] = pose.smoothing_choice
    if pose is not None and pose.windows is not None:     # a long pass smoothed in windows
        chosen["pose_windows"] = pose.windows.to_dict()


def write_available(out_dir: Path, analysis) -> list[Path]:
    """Write every result file whose steps are done; returns the paths written."""
    out, written = Path(out_dir), []
    if analysis.rig is not None:
        written.append(atomic_write_text(out / "rig.toml", rig_to_toml(analysis.rig.rig)))
    if analysis.detect is not None:
        written.append(atomic_write_text(out / "markers_2d.csv", markers_2d_text(analysis)))
    if analysis.triangulate is not None:
        written.append(atomic_write_text(out / "markers_3d.csv", markers_3d_text(analysis)))
    if analysis.rigid_body is not None:
        written.append(atomic_write_text(out / "trajectories.csv", trajectories_text(analysis)))
        written.append(atomic_write_text(out / "kinematics.csv", kinematics_text(analysis)))
        written.append(atomic_write_text(out / "angular.csv", angular_text(analysis)))
    if analysis.comfort is not None and analysis.comfort.indicators is not None:
        written.append(write_comfort_csv(out / "comfort.csv", analysis.comfort.indicators))
        written.append(write_comfort_spreadsheet(out / "comfort.xlsx", analysis.comfort.indicators))
    if getattr(analysis, "passes", None) is not None:
        written.append(atomic_write_text(out / "passes.csv", passes_text(analysis)))
    written.append(atomic_write_json(out / "analysis.json", analysis_record(analysis)))
    return written


def _rounded(x, digits: int = 3):
    """A float for JSON: rounded, ``None`` for NaN."""
    x = float(x)
    return round(x, digits) if np.isfinite(x) else None
