"""3D marker trajectories in and out: our trajectories.csv, C3D (ezc3d) and TRC.

For users who already have 3D markers from another system (Vicon, Qualisys,
OptiTrack, ...): :func:`read_trajectories` reads a CSV in the layout of
``trajectories.csv`` (``frame,time_s,point,x_m,y_m,z_m``, docs/sessions.md)
or a C3D file (through ezc3d, units from ``POINT:UNITS``, rate from
``POINT:RATE``); :func:`kinematics_from_trajectories` runs the pose-trajectory
estimator (:mod:`horsemocap.pose`) with a static shot; :func:`write_trc` and
:func:`write_c3d` export trajectories for OpenSim, Mokka and Visual3D.
Every bad file ends with a :class:`TrajectoryFileError` naming the file and
the field.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["TrajectoryFileError", "Trajectories", "read_trajectories", "read_trajectories_csv", "read_c3d",
           "write_trc", "write_c3d", "frame_rate", "kinematics_from_trajectories"]

_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "dm": 0.1}


class TrajectoryFileError(ValueError):
    """A trajectory file that cannot be read; the message names the file and field."""


@dataclass(frozen=True)
class Trajectories:
    """Named 3D points over time.

    Attributes
    ----------
    time_s : (n,)
    frame : (n,) int
    names : tuple of str
    points : (n, k, 3) metres, NaN where a point is missing.
    source : str
    """

    time_s: np.ndarray
    frame: np.ndarray
    names: tuple
    points: np.ndarray
    source: str

    def subset(self, names) -> np.ndarray:
        """Points (n, len(names), 3) in the given order."""
        idx = [self.names.index(nm) for nm in names]
        return self.points[:, idx]


def read_trajectories_csv(path) -> Trajectories:
    """Read a CSV in the trajectories.csv layout (``frame,time_s,point,x_m,y_m,z_m``)."""
    path = Path(path)
    if not path.is_file():
        raise TrajectoryFileError(f"{path}: file not found")
    want = ["frame", "time_s", "point", "x_m", "y_m", "z_m"]
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            raise TrajectoryFileError(f"{path}: empty file (expected the header {','.join(want)})")
        header = [h.strip() for h in header]
        missing = [c for c in want if c not in header]
        if missing:
            raise TrajectoryFileError(f"{path}: header lacks the column(s) {missing} (expected {','.join(want)}, "
                                      f"got {','.join(header)})")
        col = {c: header.index(c) for c in want}
        rows = {}
        names = []
        times = {}
        for ln, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            try:
                fr = int(row[col["frame"]])
            except (ValueError, IndexError):
                raise TrajectoryFileError(f"{path}: line {ln}: field 'frame': expected an integer, got "
                                          f"{row[col['frame']] if len(row) > col['frame'] else ''!r}") from None
            try:
                tm = float(row[col["time_s"]])
            except (ValueError, IndexError):
                raise TrajectoryFileError(f"{path}: line {ln}: field 'time_s': expected a number") from None
            name = row[col["point"]].strip() if len(row) > col["point"] else ""
            if not name:
                raise TrajectoryFileError(f"{path}: line {ln}: field 'point': empty point name")
            xyz = []
            for c in ("x_m", "y_m", "z_m"):
                v = row[col[c]].strip() if len(row) > col[c] else ""
                try:
                    xyz.append(float(v) if v else np.nan)
                except ValueError:
                    raise TrajectoryFileError(f"{path}: line {ln}: field '{c}': expected a number or empty, "
                                              f"got {v!r}") from None
            if name not in names:
                names.append(name)
            if fr in times and abs(times[fr] - tm) > 1e-9:
                raise TrajectoryFileError(f"{path}: line {ln}: frame {fr} has two times ({times[fr]} and {tm})")
            times[fr] = tm
            rows[(fr, name)] = xyz
    if not times:
        raise TrajectoryFileError(f"{path}: no data rows")
    frames = np.array(sorted(times))
    pts = np.full((frames.size, len(names), 3), np.nan)
    fi = {f: i for i, f in enumerate(frames)}
    for (fr, name), xyz in rows.items():
        pts[fi[fr], names.index(name)] = xyz
    t = np.array([times[f] for f in frames])
    if frames.size > 1 and np.any(np.diff(t) <= 0):
        raise TrajectoryFileError(f"{path}: field 'time_s' must increase with 'frame'")
    return Trajectories(t, frames, tuple(names), pts, str(path))


def read_c3d(path) -> Trajectories:
    """Read the 3D points of a C3D file with ezc3d (units from ``POINT:UNITS``, rate ``POINT:RATE``)."""
    path = Path(path)
    if not path.is_file():
        raise TrajectoryFileError(f"{path}: file not found")
    try:
        import ezc3d
    except ImportError:  # pragma: no cover - ezc3d is a dependency
        raise TrajectoryFileError(f"{path}: reading C3D needs the ezc3d package (pip install ezc3d)") from None
    try:
        c = ezc3d.c3d(str(path))
    except Exception as exc:
        raise TrajectoryFileError(f"{path}: not a readable C3D file ({exc})") from None
    par = c["parameters"]["POINT"]
    try:
        units = str(par["UNITS"]["value"][0]).strip().lower()
    except (KeyError, IndexError):
        raise TrajectoryFileError(f"{path}: parameter POINT:UNITS is missing (expected mm or m)") from None
    if units not in _UNITS:
        raise TrajectoryFileError(f"{path}: parameter POINT:UNITS is {units!r} (expected one of {sorted(_UNITS)})")
    try:
        rate = float(np.ravel(par["RATE"]["value"])[0])
    except (KeyError, IndexError):
        raise TrajectoryFileError(f"{path}: parameter POINT:RATE is missing") from None
    if not (rate > 0):
        raise TrajectoryFileError(f"{path}: parameter POINT:RATE is {rate} (expected a positive rate in Hz)")
    names = tuple(str(s).strip() for s in par["LABELS"]["value"])
    data = np.asarray(c["data"]["points"], float)[:3]            # (3, k, n)
    if data.shape[1] != len(names):
        raise TrajectoryFileError(f"{path}: POINT:LABELS names {len(names)} points, the data hold {data.shape[1]}")
    pts = np.moveaxis(data, [0, 1, 2], [2, 1, 0]) * _UNITS[units]
    try:
        resid = np.asarray(c["data"]["meta_points"]["residuals"], float)[0].T
        pts[resid < 0] = np.nan                                     # C3D: a negative residual marks a gap
    except (KeyError, IndexError, ValueError):
        pass
    first = int(c["header"]["points"]["first_frame"])
    n = pts.shape[0]
    return Trajectories(np.arange(n) / rate, first + np.arange(n), names, pts, str(path))


def read_trajectories(path) -> Trajectories:
    """:func:`read_c3d` for ``.c3d`` files, :func:`read_trajectories_csv` otherwise."""
    return read_c3d(path) if str(path).lower().endswith(".c3d") else read_trajectories_csv(path)


def frame_rate(traj: Trajectories, rate: float | None = None) -> float:
    """The frame rate (Hz) of ``traj``: ``rate`` if given, else from its times and frame numbers.

    Raises :class:`TrajectoryFileError` naming the file when ``rate`` is not a
    positive number, or when it is not given and the file has one frame (its
    rate is unknown).
    """
    if rate is not None:
        if not (np.isfinite(rate) and rate > 0):
            raise TrajectoryFileError(f"{traj.source}: frame rate {rate}: expected a positive number of Hz")
        return float(rate)
    if traj.frame.size < 2:
        raise TrajectoryFileError(f"{traj.source}: a single frame: its frame rate is unknown; give it "
                                  "(horsemocap export --rate HZ)")
    return float(1.0 / np.median(np.diff(traj.time_s) / np.diff(traj.frame)))


def write_trc(path, traj: Trajectories, rate: float | None = None) -> Path:
    """Write an OpenSim TRC file (``PathFileType 4``, millimetres).

    ``rate``: the frame rate (Hz); default from the times (:func:`frame_rate`).
    ``OrigDataStartFrame`` is the first frame number of ``traj``.
    """
    from .store import atomic_write_text

    path = Path(path)
    n, k, _ = traj.points.shape
    rate = frame_rate(traj, rate)
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             f"{rate:.6g}\t{rate:.6g}\t{n}\t{k}\tmm\t{rate:.6g}\t{int(traj.frame[0]) if n else 1}\t{n}",
             "Frame#\tTime\t" + "\t\t\t".join(traj.names) + "\t\t",
             "\t\t" + "\t".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}" for i in range(k)), ""]
    for i in range(n):
        vals = ["" if not np.isfinite(v) else f"{1000 * v:.6f}" for v in traj.points[i].ravel()]
        lines.append(f"{i + 1}\t{traj.time_s[i]:.6f}\t" + "\t".join(vals))
    atomic_write_text(path, "\n".join(lines) + "\n")
    return path


def _every_frame(traj: Trajectories) -> np.ndarray:
    """Points (n, k, 3) on every frame number from the first to the last (NaN in a frame the file lacks)."""
    full = np.full((int(traj.frame[-1] - traj.frame[0]) + 1, len(traj.names), 3), np.nan)
    full[traj.frame - traj.frame[0]] = traj.points
    return full


def write_c3d(path, traj: Trajectories, rate: float | None = None) -> Path:
    """Write a C3D file with ezc3d (``POINT:UNITS`` mm, gaps as residual -1).

    The header's first frame is the first frame number of ``traj`` (read back
    by :func:`read_c3d`); frame numbers the file lacks between the first and
    the last are gaps of every point. ``rate``: the frame rate (Hz); default
    from the times (:func:`frame_rate`). Written whole (a temporary file
    beside ``path``, renamed).
    """
    import ezc3d

    path = Path(path)
    rate = frame_rate(traj, rate)
    if traj.frame.size and traj.frame[0] < 0:
        raise TrajectoryFileError(f"{traj.source}: field 'frame': the first frame is {traj.frame[0]}; a C3D file's "
                                  "frame numbers start at 0 or later")
    points = _every_frame(traj) if traj.frame.size else traj.points
    n, k, _ = points.shape
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(traj.names)
    c.add_parameter("POINT", "UNITS", ["mm"])
    c["header"]["points"]["first_frame"] = int(traj.frame[0]) if traj.frame.size else 0
    data = np.ones((4, k, n))
    p = np.moveaxis(points, [0, 1, 2], [2, 1, 0]) * 1000.0
    gap = ~np.isfinite(p).all(axis=0)
    data[:3] = np.where(np.isfinite(p), p, 0.0)
    c["data"]["points"] = data
    resid = np.where(gap, -1.0, 0.0)[None]
    c["data"]["meta_points"] = {"residuals": resid, "camera_masks": np.zeros((7, k, n), bool)}
    from .store import atomic_write_by_name

    atomic_write_by_name(path, lambda tmp: c.write(str(tmp)), suffix=".c3d")   # ezc3d appends ".c3d" to any other
    return path


def kinematics_from_trajectories(traj: Trajectories, static: Trajectories, *, smoothing: str = "auto",
                                 events=None):
    """Pose-trajectory kinematics of a rigid body from 3D markers and a static shot.

    The markers are the points present in both files; the hidden points are
    those of the static shot absent from the trajectories (e.g. the saddle).
    The static shot's first frame with every point finite is the model.
    ``events``: known times (s, the file's time axis) where the acceleration
    may jump, e.g. an impact's onset from a force plate
    (:func:`horsemocap.pose.fit_pose_trajectory`, ``events``; smoothing
    "auto" (default: gcv with harmonics on a periodic record, adaptive otherwise), "gcv" or "adaptive"). With events the record is smoothed without stride
    harmonics (the change points are for a non-periodic record; the two are
    not fitted together).

    Returns
    -------
    dict with ``trajectory`` (:class:`horsemocap.pose.PoseTrajectory`),
    ``markers`` and ``hidden`` (names), ``marker_kinematics`` and
    ``hidden_kinematics`` (:class:`horsemocap.pose.PointKinematics`, (n, k, 3)),
    ``registration``.
    """
    from . import pose

    markers = [nm for nm in traj.names if nm in static.names]
    hidden = [nm for nm in static.names if nm not in traj.names]
    if len(markers) < 3:
        raise TrajectoryFileError(f"{traj.source}: only {len(markers)} point name(s) {markers} also in the static "
                                  f"shot {static.source}; a rigid body needs 3 non-collinear markers")
    sp = static.subset(markers + hidden)
    ok = np.flatnonzero(np.all(np.isfinite(sp), axis=(1, 2)))
    if ok.size == 0:
        raise TrajectoryFileError(f"{static.source}: no frame has every point {markers + hidden} finite")
    model_all = sp[ok[0]]
    model = model_all[: len(markers)]
    pose.check_model_conditioning(model, name=f"static shot {static.source}")
    reg = pose.register_pose(traj.subset(markers), model)
    harmonics = "none" if events is not None and len(events) else "auto"
    tr = pose.fit_pose_trajectory(traj.time_s, reg, model, smoothing=smoothing, events=events, harmonics=harmonics)
    mk = tr.points(traj.time_s, model)
    hk = tr.points(traj.time_s, model_all[len(markers):]) if hidden else None
    return {"trajectory": tr, "markers": markers, "hidden": hidden, "marker_kinematics": mk,
            "hidden_kinematics": hk, "registration": reg}
