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

from .camera import rig_to_toml
from .store import atomic_write_json, atomic_write_text

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
    a, b = analysis.results["triangulate"]["segment"]
    frame = analysis.results["sync"]["offsets"][s.reference_camera] + np.arange(a, b)
    return frame, np.arange(b - a) / s.fps


def markers_2d_text(analysis) -> str:
    """``camera,frame,marker,u_px,v_px,reason,residual_px`` in each camera's own numbering."""
    from .detection.markers2d import markers_2d_csv_text

    res = analysis.results
    tri = res.get("triangulate")
    return markers_2d_csv_text(res["detect"]["marker_px"], res["sync"]["offsets"], res["detect"]["reason"],
                               tri["residual_px"] if tri else None)


def markers_3d_text(analysis) -> str:
    """``frame,marker,x_m,y_m,z_m,n_views,residual_px,reason``: every synchronised frame, world frame.

    Positions in the reference camera's frame (thesis ``CM_L``) before
    smoothing; ``n_views`` cameras used; ``residual_px`` the largest
    reprojection residual over them; ``reason`` empty when measured,
    ``interpolated`` in a bridged gap, else why there is no position.
    """
    from .detection.markers2d import marker_label

    res, s = analysis.results, analysis.session
    tri = res["triangulate"]
    pts, reason = tri["points"], tri["reason"]
    worst = np.fmax.reduce(np.stack(list(tri["residual_px"].values())), axis=0)   # NaN-ignoring maximum
    views = tri.get("n_views", np.zeros(pts.shape[:2], int))
    off = res["sync"]["offsets"][s.reference_camera]
    rows = [[k + off, marker_label(m), *(_num(v) for v in pts[k, m]), int(views[k, m]),
             _num(worst[k, m], 4) if reason[k, m] != "interpolated" else "", str(reason[k, m])]
            for k in range(pts.shape[0]) for m in range(pts.shape[1])]
    return _csv_text(["frame", "marker", "x_m", "y_m", "z_m", "n_views", "residual_px", "reason"], rows)


def _points(analysis, key):
    """Marker and saddle arrays ``(n, m+1, 3)`` for ``position``/``velocity``/``acceleration``.

    Marker positions are the registered ones (section 5.5.2 keeps them);
    velocities and accelerations come from the fits.
    """
    rb = analysis.results["rigid_body"]
    markers = rb["registered"] if key == "position" else rb[key]
    return np.concatenate([markers, rb[f"saddle_{key}"][:, None, :]], axis=1)


def _point_names(n_markers):
    from .detection.markers2d import marker_label

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
    rb = analysis.results["rigid_body"]
    w, a = rb["omega"], rb["alpha"]
    extra = np.full((len(frame), 0), np.nan)
    header = ["frame", "time_s", "wx_radps", "wy_radps", "wz_radps",
              "alphax_radps2", "alphay_radps2", "alphaz_radps2"]
    if "conditioning" in rb:
        c = rb["conditioning"]
        extra = np.column_stack([rb["saddle_angles_deg"], c["singularity_deg"], c["triangle_height_m"],
                                 c["registration_rms_m"]])
        header += list(ANGULAR_OPTIONAL)
    rows = [[int(frame[k]), _num(t[k]), *(_num(v) for v in w[k]), *(_num(v) for v in a[k]),
             *(_num(v) for v in extra[k])] for k in range(len(frame))]
    return _csv_text(header, rows)


def software_record() -> dict:
    """What computed the results: the versions of horsemocap, Python, NumPy, SciPy and OpenCV, and the
    detection path (``"compiled"``: the optional compiled core, ``"python"``: the pure-Python path;
    the two give the same results, ``tests/test_regions_core.py``)."""
    import platform

    import cv2
    import scipy

    from . import __version__
    from .detection import ACTIVE_PATH

    return {"horsemocap": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "opencv": cv2.__version__, "detection_core": ACTIVE_PATH}


def analysis_record(analysis) -> dict:
    """Everything needed to repeat the run: parameters given and chosen."""
    res = analysis.results
    record = {
        "format": FORMAT,
        "session": str(analysis.session.root),
        "session_name": analysis.session.name,
        "written": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "steps_done": list(res),
        "parameters": analysis.params.to_dict(),
        "chosen": {},
        "timings_s": {k: round(v, 3) for k, v in analysis.timings.items()},
        "software": software_record(),
    }
    p, chosen = record["parameters"], record["chosen"]
    if "sync" in res:
        p["sync"]["offsets"] = dict(res["sync"]["offsets"])
        chosen["sync"] = {"offsets_from": res["sync"]["offsets_from"], "n_frames": res["sync"]["n_frames"]}
        if "flash_offsets" in res["sync"]:
            chosen["sync"]["flash_offsets"] = dict(res["sync"]["flash_offsets"])
        if res["sync"].get("flash_ambiguous"):        # camera -> the frame of a second candidate nearly as likely
            chosen["sync"]["flash_ambiguous"] = {c: int(f) for c, f in res["sync"]["flash_ambiguous"].items()}
        check = res.get("detect", {}).get("sync_check")
        if check:
            chosen["sync"]["checked_by_markers"] = {
                c: {"shift_frames": int(v["shift"]), "residual_px": _rounded(v["current_px"]),
                    "residual_after_px": _rounded(v["best_px"]), "marker_frames": int(v["n_points"]),
                    "decided": bool(v.get("decided", True)), "rounds": int(v.get("rounds", 1))}
                for c, v in check.items()}
    if "rig" in res:
        chosen["rig"] = res["rig"]["rig_from"]
    if "detect" in res:
        p["detect"]["cameras"] = res["detect"]["detection"]
        chosen["detection_method"] = res["detect"].get("method", p["detect"]["method"])
        if res["detect"].get("method_note"):
            chosen["detection_method_note"] = res["detect"]["method_note"]
        if "identification" in res["detect"]:
            ident = res["detect"]["identification"]
            chosen["identification"] = {"anchor_frame": ident["anchor_frame"],
                                        "model_index_in_static": ident["model_index"]}
        chosen["analysed_frames"] = list(res["detect"]["segment"])
    if "triangulate" in res:
        chosen["analysed_frames"] = list(res["triangulate"]["segment"])
    if "motion_frame" in res:
        p["motion_frame"]["period_frames"] = res["motion_frame"]["period_frames"]
        if res["motion_frame"]["frame"].n_periods > 0:
            p["motion_frame"]["n_periods"] = int(res["motion_frame"]["frame"].n_periods)
    if "rigid_body" in res:
        chosen["static_order"] = res["rigid_body"]["static_order"]
        chosen["saddle_index_in_static"] = res["rigid_body"]["saddle_index"]
        if res["rigid_body"]["orders"] is not None:
            p["rigid_body"]["fits"]["fourier_orders"] = np.asarray(res["rigid_body"]["orders"]).astype(int).tolist()
        if res["rigid_body"].get("warnings"):
            chosen["rigid_body_warnings"] = list(res["rigid_body"]["warnings"])
        pose = getattr(res["rigid_body"].get("analysis"), "pose", None)
        if pose is not None and pose.smoothing_choice:
            chosen["pose_smoothing"] = pose.smoothing_choice
    if "comfort" in res and res["comfort"].get("indicators") is None:
        chosen["comfort_not_computed"] = res["comfort"].get("reason", "")
    return record


def write_available(out_dir: Path, analysis) -> list[Path]:
    """Write every result file whose steps are done; returns the paths written."""
    from .vibration import write_comfort_csv, write_comfort_spreadsheet

    res, out, written = analysis.results, Path(out_dir), []
    if "rig" in res:
        written.append(atomic_write_text(out / "rig.toml", rig_to_toml(res["rig"]["rig"])))
    if "detect" in res:
        written.append(atomic_write_text(out / "markers_2d.csv", markers_2d_text(analysis)))
    if "triangulate" in res:
        written.append(atomic_write_text(out / "markers_3d.csv", markers_3d_text(analysis)))
    if "rigid_body" in res:
        written.append(atomic_write_text(out / "trajectories.csv", trajectories_text(analysis)))
        written.append(atomic_write_text(out / "kinematics.csv", kinematics_text(analysis)))
        written.append(atomic_write_text(out / "angular.csv", angular_text(analysis)))
    if "comfort" in res and res["comfort"].get("indicators") is not None:
        written.append(write_comfort_csv(out / "comfort.csv", res["comfort"]["indicators"]))
        written.append(write_comfort_spreadsheet(out / "comfort.xlsx", res["comfort"]["indicators"]))
    written.append(atomic_write_json(out / "analysis.json", analysis_record(analysis)))
    return written


def _rounded(x, digits: int = 3):
    """A float for JSON: rounded, ``None`` for NaN."""
    x = float(x)
    return round(x, digits) if np.isfinite(x) else None
