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
import math
import os
import struct
import tempfile
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .store import ScratchWriteError, release_pages

__all__ = ["TrajectoryFileError", "Trajectories", "read_trajectories", "read_trajectories_csv", "read_c3d",
           "c3d_header", "write_trc", "write_c3d", "frame_rate", "match_point_names", "kinematics_from_trajectories",
           "FIRST_TIME_PARAMETER", "RATE_PARAMETER", "check_trajectory_input", "check_stated_rate",
           "kinematics_checks", "kinematics_checks_of_percentiles", "kinematics_verdict", "RunningPercentile",
           "kinematics_block_text", "csv_field",
           "read_trajectories_csv_to_disk", "read_trajectories_to_disk"]

_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "dm": 0.1}
_UNITS_TEXT = ", ".join(_UNITS)
FIRST_TIME_PARAMETER = ("HORSEMOCAP", "FIRST_TIME")
"""C3D parameter (group, name) holding the exact time (s) of the first frame, as text (a C3D real is 4 bytes)."""
RATE_PARAMETER = ("HORSEMOCAP", "RATE")
"""C3D parameter (group, name) holding the exact frame rate (Hz) as text; used when POINT:RATE is its 4-byte copy."""
MAX_COORDINATE_M = 1e6
"""A coordinate beyond this (metres) is no position of a body (an overflow, a sentinel value): refused on reading."""
MARKER_SPACING_M = (0.005, 5.0)
"""The median distance between the points of the static shot (m) of markers on a body; outside: wrong units."""
FRAME_RATE_HZ = (5.0, 50000.0)
"""Frame rates (Hz) of a motion capture; a rate from the times outside says the time column is not in seconds."""
SPEED_LIMIT_MPS = 30.0
"""The 99th percentile of a point's speed (m/s) above which it is no body's motion (a galloping horse: about 20)."""
ACCELERATION_LIMIT_MPS2 = 1000.0
"""The 99th percentile of a point's acceleration (m/s²) above which it is no body's motion (about 100 g)."""


class TrajectoryFileError(ValueError):
    r"""A trajectory file that cannot be read; the message names the file and field.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "bad.csv"
    >>> _ = path.write_text("frame,time,point\n")
    >>> try:
    ...     read_trajectories_csv(path)
    ... except TrajectoryFileError as error:
    ...     print(str(error).split(": ", 1)[1])
    header lacks the column(s) ['time_s', 'x_m', 'y_m', 'z_m'] (expected frame,time_s,point,x_m,y_m,z_m, got frame,time,point)
    """


@dataclass(frozen=True)
class Trajectories:
    r"""Named 3D points over time.

    Attributes
    ----------
    time_s : (n,)
    frame : (n,) int
    names : tuple of str
    points : (n, k, 3) metres, NaN where a point is missing.
    source : str
    info : dict
        How the file was read: ``format`` ("csv" or "c3d"), ``units`` and
        ``scale_to_m`` (the file's length unit), ``rate_hz`` (the C3D's
        ``POINT:RATE``; None for a CSV) and ``time_origin`` (where ``time_s``
        comes from).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> walk.names, walk.frame.tolist(), walk.points.shape
    (('marker1', 'marker2'), [0, 1], (2, 2, 3))
    >>> walk.subset(["marker2"])[:, 0]
    array([[0.3, 1. , 4. ],
           [nan, nan, nan]])
    """

    time_s: np.ndarray
    frame: np.ndarray
    names: tuple
    points: np.ndarray
    source: str
    info: dict = field(default_factory=dict)

    def subset(self, names) -> np.ndarray:
        """Points (n, len(names), 3) in the given order (a view of ``points``, not a copy, when the
        names follow one another in the file's order)."""
        idx = [self.names.index(nm) for nm in names]
        if idx and idx == list(range(idx[0], idx[0] + len(idx))):
            return self.points[:, idx[0]:idx[0] + len(idx)]
        return self.points[:, idx]


def read_trajectories_csv(path) -> Trajectories:
    r"""Read a CSV in the trajectories.csv layout (``frame,time_s,point,x_m,y_m,z_m``).

    An empty coordinate (or ``nan``) is a missing point. Refused with a
    :class:`TrajectoryFileError` naming the file and line: a row with more
    fields than the header (an unquoted comma in a name), a non-finite
    ``time_s``, an infinite coordinate, two rows of one (frame, point) with
    different values, two times of one frame, times that do not increase
    with the frame number. Of several faults the one on the earliest line is
    named.

    The rows are read into flat typed columns (44 bytes a row) and placed
    with NumPy; the checks across rows run on those columns, and the line
    numbers an error names are found by reading the file once more.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> walk.time_s.tolist(), walk.info["units"]
    ([0.0, 0.01], 'm')
    """
    path = Path(path)
    if not path.is_file():
        raise TrajectoryFileError(f"{path}: file not found")
    want = ",".join(TRAJECTORY_COLUMNS)
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            raise TrajectoryFileError(f"{path}: empty file (expected the header {want})")
        header, col, missing = _header_columns(header)
        if missing:
            raise TrajectoryFileError(f"{path}: header lacks the column(s) {missing} (expected {want}, "
                                      f"got {','.join(header)})")
        rows = _read_rows(path, reader, col, len(header))
    if not rows.frame.size:
        raise TrajectoryFileError(f"{path}: no data rows")
    frames, first_row, inverse = _refuse_conflicts(path, rows)
    pts = np.full((frames.size, len(rows.names), 3), np.nan)
    pts[inverse, rows.point] = rows.xyz
    t = rows.time[first_row]
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        i0, i1 = int(back[0]), int(back[0]) + 1
        f0, f1 = int(frames[i0]), int(frames[i1])
        line = _row_lines(path, [first_row[i0], first_row[i1]])
        raise TrajectoryFileError(f"{path}: field 'time_s' must increase with 'frame': frame {f1} (line "
                                  f"{line[first_row[i1]]}) has time {t[i1]}, not after frame {f0}'s {t[i0]} "
                                  f"(line {line[first_row[i0]]})")
    return Trajectories(t, frames, tuple(rows.names), pts, str(path), _csv_info())


TRAJECTORY_COLUMNS = ("frame", "time_s", "point", "x_m", "y_m", "z_m")
"""The columns of a trajectories CSV (in any order, others ignored)."""


def _csv_info() -> dict:
    """The ``info`` of a trajectories CSV (its own dict: a caller may add to it)."""
    return {"format": "csv", "units": "m", "scale_to_m": 1.0, "rate_hz": None,
            "time_origin": "the file's time_s column"}


def _header_columns(header) -> tuple:
    """``(header stripped, {column: index}, [missing columns])`` of a trajectories CSV's header row."""
    header = [h.strip() for h in header]
    missing = [c for c in TRAJECTORY_COLUMNS if c not in header]
    return header, {c: header.index(c) for c in TRAJECTORY_COLUMNS if c not in missing}, missing


def _usual_row(row, cf, ct, cp, cx, cy, cz, n_fields):
    """``(frame, time, point, x, y, z)`` of a common row (every field present and plain, coordinates
    finite and within :data:`MAX_COORDINATE_M`), read directly; None for anything else, which
    :func:`_csv_row` reads or names."""
    try:
        fr, tm, name = int(row[cf]), float(row[ct]), row[cp].strip()
        x, y, z = float(row[cx]), float(row[cy]), float(row[cz])
    except (ValueError, IndexError):
        return None
    if (len(row) == n_fields and math.isfinite(tm) and name != "" and abs(x) <= MAX_COORDINATE_M
            and abs(y) <= MAX_COORDINATE_M and abs(z) <= MAX_COORDINATE_M):
        return fr, tm, name, x, y, z
    return None


@dataclass(frozen=True)
class _Rows:
    """A trajectories CSV's data rows as columns: ``frame`` (r,) int64, ``time`` (r,), ``point`` (r,)
    index into ``names``, ``xyz`` (r, 3)."""

    frame: np.ndarray
    time: np.ndarray
    point: np.ndarray
    xyz: np.ndarray
    names: list


def _read_rows(path, reader, col, n_fields) -> _Rows:
    """The data rows of ``reader`` in flat typed columns; a bad row ends with the file, line and field
    (or with an earlier line's conflict, :func:`_refuse_conflicts`, when there is one)."""
    frame, time, point, xyz = array("q"), array("d"), array("i"), array("d")
    names, index = [], {}
    cf, ct, cp, cx, cy, cz = (col[c] for c in TRAJECTORY_COLUMNS)

    def columns():
        return _Rows(np.frombuffer(frame, np.int64), np.frombuffer(time, float), np.frombuffer(point, np.int32),
                     np.frombuffer(xyz, float).reshape(-1, 3), names)

    for ln, row in enumerate(reader, start=2):
        if not row or all(not c.strip() for c in row):
            continue
        usual = _usual_row(row, cf, ct, cp, cx, cy, cz, n_fields)   # anything unusual: _csv_row's message
        if usual is not None:
            fr, tm, name, x, y, z = usual
        else:
            try:
                fr, tm, name, (x, y, z) = _csv_row(path, ln, row, col, n_fields)
            except TrajectoryFileError:
                if frame:
                    _refuse_conflicts(path, columns())          # a fault on an earlier line is named first
                raise
        j = index.get(name)
        if j is None:
            j = index[name] = len(names)
            names.append(name)
        frame.append(fr)
        time.append(tm)
        point.append(j)
        xyz.extend((x, y, z))
    return columns()


def _refuse_conflicts(path, rows: _Rows):
    """Refuse two times of one frame and two values of one (frame, point), naming the earliest line.

    Returns the sorted distinct frames, the row of each frame's first appearance and each row's
    frame index."""
    frames, inverse = np.unique(rows.frame, return_inverse=True)
    inverse = inverse.reshape(-1)
    first_row = _first_rows(inverse, frames.size)
    bad_time = np.flatnonzero(np.abs(rows.time - rows.time[first_row][inverse]) > 1e-9)
    key = inverse.astype(np.int64) * max(len(rows.names), 1) + rows.point
    keys, key_inverse = np.unique(key, return_inverse=True)
    first_of_key = _first_rows(key_inverse.reshape(-1), keys.size)[key_inverse.reshape(-1)]
    a, b = rows.xyz, rows.xyz[first_of_key]
    bad_value = np.flatnonzero(~np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1))
    r_time = int(bad_time[0]) if bad_time.size else None
    r_value = int(bad_value[0]) if bad_value.size else None
    if r_time is not None and (r_value is None or r_time <= r_value):
        f, first = int(rows.frame[r_time]), int(first_row[inverse[r_time]])
        line = _row_lines(path, [r_time, first])
        raise TrajectoryFileError(f"{path}: line {line[r_time]}: frame {f} has two times ({rows.time[first]} on "
                                  f"line {line[first]} and {rows.time[r_time]})")
    if r_value is not None:
        first = int(first_of_key[r_value])
        line = _row_lines(path, [r_value, first])
        raise TrajectoryFileError(f"{path}: lines {line[first]} and {line[r_value]}: point "
                                  f"{rows.names[rows.point[r_value]]!r} of frame {int(rows.frame[r_value])} twice "
                                  f"with different values ({_xyz_text(rows.xyz[first])} and "
                                  f"{_xyz_text(rows.xyz[r_value])})")
    return frames, first_row, inverse


def _first_rows(group, n_groups: int) -> np.ndarray:
    """The first row (index into ``group``) of each of ``n_groups`` groups numbered 0 .. n_groups - 1."""
    first = np.full(n_groups, group.size, np.int64)
    np.minimum.at(first, group, np.arange(group.size))
    return first


def _row_lines(path, rows) -> dict:
    """The file's line number of each data row (0-based, blank rows not counted) in ``rows``."""
    wanted, found = {int(r) for r in rows}, {}
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        next(reader, None)
        k = 0
        for ln, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if k in wanted:
                found[k] = ln
                if len(found) == len(wanted):
                    break
            k += 1
    return found


def _xyz_text(xyz) -> str:
    return "(" + ", ".join("" if not np.isfinite(v) else repr(float(v)) for v in xyz) + ")"


def _csv_row(path, ln, row, col, n_fields):
    """(frame, time, point, [x, y, z]) of one data row; a bad field ends with the file, line and field."""
    if len(row) > n_fields and any(field.strip() for field in row[n_fields:]):    # a trailing comma is no field
        raise TrajectoryFileError(f"{path}: line {ln}: {len(row)} fields, the header has {n_fields} (a point "
                                  "name with a comma must be quoted, as the csv module writes it)")

    def field_text(name):
        return row[col[name]].strip() if len(row) > col[name] else ""

    try:
        fr = int(field_text("frame"))
    except ValueError:
        raise TrajectoryFileError(f"{path}: line {ln}: field 'frame': expected an integer, got "
                                  f"{field_text('frame')!r}") from None
    try:
        tm = float(field_text("time_s"))
    except ValueError:
        tm = math.nan
    if not math.isfinite(tm):
        raise TrajectoryFileError(f"{path}: line {ln}: field 'time_s': expected a finite number, got "
                                  f"{field_text('time_s')!r}")
    name = field_text("point")
    if not name:
        raise TrajectoryFileError(f"{path}: line {ln}: field 'point': empty point name")
    xyz = []
    for c in ("x_m", "y_m", "z_m"):
        v = field_text(c)
        try:
            num = float(v) if v else math.nan
        except ValueError:
            num = math.inf
        if math.isinf(num):
            raise TrajectoryFileError(f"{path}: line {ln}: field '{c}': expected a number or empty, got {v!r}")
        if abs(num) > MAX_COORDINATE_M:
            raise TrajectoryFileError(f"{path}: line {ln}: field '{c}' of point {name!r}, frame {fr}: {v} is beyond "
                                      f"any position of a body (|{c}| <= {MAX_COORDINATE_M:g} m)")
        xyz.append(num)
    return fr, tm, name, tuple(xyz)


def c3d_header(path) -> dict:
    r"""The raw header words of a C3D file that say which frames it holds.

    Returns ``{"first_frame": int, "last_frame": int, "frame_rate": float or
    None, "processor": str}``: words 4 and 5 (bytes 6-9: the first and last
    frame, 1-based, unsigned 16-bit) and words 11-12 (bytes 20-23: the
    points' rate, a 4-byte real; None for a DEC file, whose reals this does
    not decode), in the byte order of the processor type named in the
    parameter section's header (84 Intel, 85 DEC: little-endian; 86 MIPS:
    big-endian). Raises :class:`TrajectoryFileError` naming the file when
    the header is too short or not a C3D header.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> c3d_header(write_c3d(folder / "walk.c3d", walk))       # frame 0 is the C3D's 1-based frame 1
    {'first_frame': 1, 'last_frame': 2, 'frame_rate': 100.0, 'processor': 'intel'}
    """
    path = Path(path)
    with open(path, "rb") as fh:
        head = fh.read(512)
        if len(head) < 512 or head[1] != 0x50 or head[0] < 2:
            raise TrajectoryFileError(f"{path}: not a C3D file (its first 512-byte block is not a C3D header)")
        fh.seek(512 * (head[0] - 1))
        par = fh.read(4)
    processor = {84: "intel", 85: "dec", 86: "mips"}.get(par[3] if len(par) == 4 else None)
    if processor is None:
        raise TrajectoryFileError(f"{path}: not a readable C3D file (no processor type in the parameter section)")
    order = ">" if processor == "mips" else "<"
    first, last = struct.unpack(order + "HH", head[6:10])
    rate = None if processor == "dec" else float(struct.unpack(order + "f", head[20:24])[0])
    return {"first_frame": int(first), "last_frame": int(last), "frame_rate": rate, "processor": processor}


def read_c3d(path) -> Trajectories:
    r"""Read the 3D points of a C3D file with ezc3d (units from ``POINT:UNITS``, rate ``POINT:RATE``).

    Frame numbers: horsemocap frame = the file's 1-based frame - 1 (the
    header's first frame word 4, 1-based, is frame ``first - 1``). Times:
    ``frame / rate`` (the file's 1-based frame - 1 over the rate, as Vicon
    Nexus counts), unless the file holds the parameter
    ``HORSEMOCAP:FIRST_TIME`` (written by :func:`write_c3d`: the exact time
    of the first frame, s, as text), then ``FIRST_TIME + (frame - first) /
    rate``; the rate is ``HORSEMOCAP:RATE`` (exact, as text) when the file
    has it and ``POINT:RATE`` is its 4-byte copy. Refused, naming the file: fewer frames of data than the header's
    first..last (a truncated file), a label used twice, an infinite
    coordinate, no positive rate, a unit not in m, mm, cm, dm.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> back = read_c3d(write_c3d(folder / "walk.c3d", walk))
    >>> back.names, back.frame.tolist(), back.time_s.tolist(), back.info["units"]
    (('marker1', 'marker2'), [0, 1], [0.0, 0.01], 'mm')
    >>> back.points[1].round(6).tolist()
    [[0.05, 1.0, 4.0], [nan, nan, nan]]
    """
    path = Path(path)
    if not path.is_file():
        raise TrajectoryFileError(f"{path}: file not found")
    try:
        import ezc3d
    except ImportError:  # pragma: no cover - ezc3d is a dependency
        raise TrajectoryFileError(f"{path}: reading C3D needs the ezc3d package (pip install ezc3d)") from None
    header = c3d_header(path)
    try:
        c = ezc3d.c3d(str(path))
    except Exception as exc:
        raise TrajectoryFileError(f"{path}: not a readable C3D file ({exc})") from None
    par = c["parameters"]["POINT"]
    units = _c3d_units(path, par)
    rate = _c3d_rate(path, par, header)
    names = _c3d_labels(path, par)
    data = np.asarray(c["data"]["points"], float)[:3]            # (3, k, n)
    if data.shape[1] != len(names):
        raise TrajectoryFileError(f"{path}: POINT:LABELS names {len(names)} points, the data hold {data.shape[1]}")
    n = data.shape[2]
    expected = _c3d_frame_count(header, par)
    if expected is not None and n != expected:
        raise TrajectoryFileError(f"{path}: the header says frames {header['first_frame']}..{header['last_frame']} "
                                  f"({expected} frames), the file holds data of {n}: a truncated or damaged C3D")
    pts = np.moveaxis(data, [0, 1, 2], [2, 1, 0]) * _UNITS[units]
    try:
        resid = np.asarray(c["data"]["meta_points"]["residuals"], float)[0].T
        pts[resid < 0] = np.nan                                     # C3D: a negative residual marks a gap
    except (KeyError, IndexError, ValueError):
        pass
    _refuse_infinite(path, pts, names, header["first_frame"])
    frame = header["first_frame"] - 1 + np.arange(n)
    point_rate = rate
    rate = _c3d_exact_rate(path, c["parameters"], rate)
    rate_from = ("parameter HORSEMOCAP:RATE (POINT:RATE's exact value)" if rate != point_rate
                 else "parameter POINT:RATE" if "RATE" in par else "the header's rate (words 11-12)")
    first_time = _c3d_text_number(path, c["parameters"], FIRST_TIME_PARAMETER, "a time in seconds")
    if first_time is None:
        time_s, origin = frame / rate, (f"the file's 1-based frame - 1 over POINT:RATE (first frame "
                                        f"{header['first_frame']}, {frame[0] / rate:.9g} s)")
    else:
        time_s, origin = first_time + (frame - frame[0]) / rate, f"parameter HORSEMOCAP:FIRST_TIME {first_time!r} s"
    info = {"format": "c3d", "units": units, "scale_to_m": _UNITS[units], "rate_hz": rate, "rate_from": rate_from,
            "time_origin": origin, "first_frame_1based": header["first_frame"]}
    return Trajectories(time_s, frame, names, pts, str(path), info)


def _c3d_units(path, par) -> str:
    accepted = f"one of {_UNITS_TEXT}"
    try:
        units = str(par["UNITS"]["value"][0]).strip().lower()
    except (KeyError, IndexError):
        raise TrajectoryFileError(f"{path}: parameter POINT:UNITS is missing (expected {accepted})") from None
    if units not in _UNITS:
        raise TrajectoryFileError(f"{path}: parameter POINT:UNITS is {units!r} (expected {accepted})")
    return units


def _c3d_rate(path, par, header) -> float:
    """POINT:RATE, or the header's rate when the parameter is missing; refused when not positive."""
    head = header["frame_rate"]
    head_text = "not decoded (DEC reals)" if head is None else f"{head:g}"
    try:
        rate = float(np.ravel(par["RATE"]["value"])[0])
    except (KeyError, IndexError):
        rate = None
    if rate is not None and rate > 0:
        return rate
    if rate is None and head is not None and head > 0:
        return head
    said = "is missing" if rate is None else f"is {rate:g}"
    raise TrajectoryFileError(f"{path}: no frame rate: the parameter POINT:RATE {said} and the header's rate "
                              f"(words 11-12) is {head_text}; expected a positive rate in Hz")


def _c3d_labels(path, par) -> tuple:
    try:
        names = tuple(str(s).strip() for s in par["LABELS"]["value"])
    except KeyError:
        raise TrajectoryFileError(f"{path}: parameter POINT:LABELS is missing") from None
    seen = set()
    for i, nm in enumerate(names):
        if nm in seen:
            raise TrajectoryFileError(f"{path}: parameter POINT:LABELS names the point {nm!r} twice (points "
                                      f"{names.index(nm) + 1} and {i + 1}); a label must name one point")
        seen.add(nm)
    return names


def _c3d_frame_count(header, par):
    """Frames the header announces (first..last); POINT:FRAMES when the 16-bit last frame is saturated."""
    if header["last_frame"] < 0xFFFF:
        return header["last_frame"] - header["first_frame"] + 1
    try:
        frames = int(np.ravel(par["FRAMES"]["value"])[0])
    except (KeyError, IndexError, ValueError, TypeError):
        return None
    return frames % 0x10000 if frames < 0 else frames


def _refuse_infinite(path, pts, names, first_1based) -> None:
    bad = np.argwhere(np.isinf(pts))
    if bad.size:
        i, j, a = bad[0]
        raise TrajectoryFileError(f"{path}: frame {first_1based + i} (1-based), point {names[j]!r}, "
                                  f"{'xyz'[a]}: expected a number, got {pts[i, j, a]}")
    with np.errstate(invalid="ignore"):
        far = np.argwhere(np.abs(pts) > MAX_COORDINATE_M)
    if far.size:
        i, j, a = far[0]
        raise TrajectoryFileError(f"{path}: frame {first_1based + i} (1-based), point {names[j]!r}, "
                                  f"{'xyz'[a]}: {pts[i, j, a]:g} m is beyond any position of a body "
                                  f"(|{'xyz'[a]}| <= {MAX_COORDINATE_M:g} m)")


def _c3d_text_number(path, params, parameter, what):
    """A number written as text in the parameter (group, name), or None when the file lacks it."""
    group, name = parameter
    try:
        text = str(np.ravel(params[group][name]["value"])[0]).strip()
    except (KeyError, IndexError):
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise TrajectoryFileError(f"{path}: parameter {group}:{name} is {text!r}: expected {what}")
    return value


def _c3d_exact_rate(path, params, rate: float) -> float:
    """HORSEMOCAP:RATE when the file has it and POINT:RATE is its 4-byte copy; else ``rate`` (POINT:RATE)."""
    exact = _c3d_text_number(path, params, RATE_PARAMETER, "a rate in Hz")
    if exact is not None and exact > 0 and float(np.float32(exact)) == float(np.float32(rate)):
        return exact
    return rate


def read_trajectories(path) -> Trajectories:
    r""":func:`read_c3d` for ``.c3d`` files, :func:`read_trajectories_csv` otherwise.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> walk.names
    ('marker1', 'marker2')
    """
    return read_c3d(path) if str(path).lower().endswith(".c3d") else read_trajectories_csv(path)


def frame_rate(traj: Trajectories, rate: float | None = None) -> float:
    r"""The frame rate (Hz) of ``traj``: ``rate`` if given, else from its times and frame numbers.

    The rate from the times is rounded to 9 significant digits when that
    moves it by less than 1e-9 of itself (the float noise of times such as
    ``k / 100``), so that a C3D written with it gives back the same times.

    Raises :class:`TrajectoryFileError` naming the file when ``rate`` is not a
    positive number, or when it is not given and the file has one frame (its
    rate is unknown).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> frame_rate(walk), frame_rate(walk, rate=120.0)
    (100.0, 120.0)
    """
    if rate is not None:
        if not (np.isfinite(rate) and rate > 0):
            raise TrajectoryFileError(f"{traj.source}: frame rate {rate}: expected a positive number of Hz")
        return float(rate)
    if traj.frame.size < 2:
        raise TrajectoryFileError(f"{traj.source}: a single frame: its frame rate is unknown; give it "
                                  "(horsemocap export --rate HZ)")
    estimate = float(1.0 / np.median(np.diff(traj.time_s) / np.diff(traj.frame)))
    rounded = float(f"{estimate:.9g}")            # 99.99999999999991 (the times' float noise) -> 100
    return rounded if abs(rounded - estimate) <= 1e-9 * estimate else estimate


def write_trc(path, traj: Trajectories, rate: float | None = None) -> Path:
    r"""Write an OpenSim TRC file (``PathFileType 4``, millimetres).

    ``rate``: the frame rate (Hz); default from the times (:func:`frame_rate`).
    Every frame number from the first to the last is a row (as in
    :func:`write_c3d`): one the trajectories lack is a row of empty values,
    its time ``time of the first frame + (frame - first) / rate``. Frame
    numbers are the C3D's, 1-based: horsemocap frame k is ``Frame#`` k + 1,
    and ``OrigDataStartFrame`` is the first frame + 1. Every data row ends
    with a tab, as OpenSim's own writer does (its reader drops one trailing
    empty field, so a row whose last marker is missing keeps its length).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")      # marker2 missing in frame 1
    >>> walk = read_trajectories(path)
    >>> trc = write_trc(folder / "walk.trc", walk)
    >>> trc.read_text().splitlines()[2].split("\t")     # rate, frames, markers, units, first frame
    ['100', '100', '2', '2', 'mm', '100', '1', '2']
    """
    from .store import atomic_write_text

    path = Path(path)
    rate = frame_rate(traj, rate)
    points, frames, times = _every_frame(traj, rate)
    n, k, _ = points.shape
    first = int(frames[0]) + 1 if n else 1
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             f"{rate:.6g}\t{rate:.6g}\t{n}\t{k}\tmm\t{rate:.6g}\t{first}\t{n}",
             "Frame#\tTime\t" + "".join(f"{nm}\t\t\t" for nm in traj.names),
             "\t\t" + "".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}\t" for i in range(k)), ""]
    for i in range(n):
        vals = ["" if not np.isfinite(v) else f"{1000 * v:.6f}" for v in points[i].ravel()]
        lines.append(f"{int(frames[i]) + 1}\t{times[i]:.9g}\t" + "".join(v + "\t" for v in vals))
    atomic_write_text(path, "\n".join(lines) + "\n")
    return path


def _every_frame(traj: Trajectories, rate: float):
    """Points (n, k, 3), frame numbers and times on every frame number from the first to the last.

    A frame number the file lacks is NaN, its time the first time plus
    (frame - first) / ``rate``; the file's own times are kept.
    """
    if traj.frame.size == 0:
        return traj.points, traj.frame, traj.time_s
    frames = np.arange(int(traj.frame[0]), int(traj.frame[-1]) + 1)
    full = np.full((frames.size, len(traj.names), 3), np.nan)
    full[traj.frame - traj.frame[0]] = traj.points
    times = traj.time_s[0] + (frames - frames[0]) / rate
    times[traj.frame - traj.frame[0]] = traj.time_s
    return full, frames, times


def write_c3d(path, traj: Trajectories, rate: float | None = None) -> Path:
    """Write a C3D file with ezc3d (``POINT:UNITS`` mm, gaps as residual -1).

    Frame numbers: horsemocap frame k is the C3D's 1-based frame k + 1 (the
    header's first frame word is the first frame + 1, as Mokka shows it);
    :func:`read_c3d` reads it back as k. Frame numbers the file lacks
    between the first and the last are gaps of every point. The exact time
    of the first frame is the parameter ``HORSEMOCAP:FIRST_TIME`` (seconds,
    as text: a C3D real has 4 bytes), so that reading the file back gives
    the same ``time_s`` (first time + (frame - first) / rate), and the exact
    rate in ``HORSEMOCAP:RATE`` (Hz, as text; ``POINT:RATE`` is its 4-byte
    copy). ``rate``: the frame rate (Hz); default from the times
    (:func:`frame_rate`). Written
    whole (a temporary file beside ``path``, renamed).

    Examples
    --------
    See :func:`read_c3d`.
    """
    import ezc3d

    path = Path(path)
    rate = frame_rate(traj, rate)
    if traj.frame.size and traj.frame[0] < 0:
        raise TrajectoryFileError(f"{traj.source}: field 'frame': the first frame is {traj.frame[0]}; a C3D file's "
                                  "frame numbers start at 0 or later")
    if traj.frame.size and traj.frame[-1] + 1 > 0xFFFF:
        raise TrajectoryFileError(f"{traj.source}: field 'frame': the last frame is {traj.frame[-1]}; a C3D "
                                  "header's frame numbers end at 65534")
    points, _, _ = _every_frame(traj, rate)
    n, k, _ = points.shape
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(traj.names)
    c.add_parameter("POINT", "UNITS", ["mm"])
    if traj.frame.size:
        c.add_parameter(*FIRST_TIME_PARAMETER, [repr(float(traj.time_s[0]))])
    c.add_parameter(*RATE_PARAMETER, [repr(float(rate))])
    c["header"]["points"]["first_frame"] = int(traj.frame[0]) if traj.frame.size else 0   # ezc3d: 0-based
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


def match_point_names(traj_names, static_names) -> dict:
    """Which trajectory point is which static-shot point.

    Names equal exactly are matched first; the rest are matched, only where
    unambiguous (one name on each side), after dropping a subject prefix
    (``Horse:marker1`` -> ``marker1``, the text up to the last ``:``) and
    ignoring case.

    Returns
    -------
    dict with ``pairs`` (list of (trajectory name, static name)),
    ``loose`` (the pairs matched the second way), ``unmatched`` (trajectory
    points not in the static shot) and ``hidden`` (static points not in the
    trajectories).

    Examples
    --------
    >>> match = match_point_names(["Horse:marker1", "Horse:marker2", "hoof"], ["marker1", "marker2", "saddle"])
    >>> match["pairs"]
    [('Horse:marker1', 'marker1'), ('Horse:marker2', 'marker2')]
    >>> match["unmatched"], match["hidden"]
    (['hoof'], ['saddle'])
    """
    pairs = [(nm, nm) for nm in traj_names if nm in static_names]
    rest_t = [nm for nm in traj_names if nm not in static_names]
    rest_s = [nm for nm in static_names if nm not in traj_names]

    def key(name):
        return name.rsplit(":", 1)[-1].strip().casefold()

    loose = []
    for nm in rest_t:
        same_t = [o for o in rest_t if key(o) == key(nm)]
        same_s = [o for o in rest_s if key(o) == key(nm)]
        if len(same_t) == 1 and len(same_s) == 1:
            loose.append((nm, same_s[0]))
    pairs += loose
    used_s = {s for _, s in pairs}
    return {"pairs": pairs, "loose": loose, "unmatched": [nm for nm in rest_t if nm not in dict(loose)],
            "hidden": [nm for nm in static_names if nm not in used_s]}


SPACING_FRAMES = 20_000
"""Frames (evenly spread) over which :func:`_median_spacing` takes the median of a longer record."""
SPACING_READ_FRAMES = 1000
"""Of those, the frames read into memory at a time (each read spans ``SPACING_READ_FRAMES`` times the
stride through the record): at ten points 240 kB in memory, a mapped record's pages let go after each read."""


def _median_spacing(points) -> float:
    """The median distance (m) between two points of one frame over the frames of (n, k, 3) ``points``
    (over every ``ceil(n / SPACING_FRAMES)``-th frame of a longer record)."""
    k = points.shape[1]
    if k < 2:
        return math.nan
    step = max(1, -(-points.shape[0] // SPACING_FRAMES))
    span = SPACING_READ_FRAMES * step
    points = np.concatenate([_read_frames(points, a, a + span, step) for a in range(0, points.shape[0], span)])
    i, j = np.triu_indices(k, 1)
    d = np.linalg.norm(points[:, i] - points[:, j], axis=2)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else math.nan


def _read_frames(points, start: int, stop: int, step: int = 1) -> np.ndarray:
    """``points[start:stop:step]`` as an array in memory; a memory-mapped record's pages read are let go
    (:func:`horsemocap.store.release_pages`)."""
    out = np.array(points[start:stop:step])
    release_pages(points)
    return out


def check_trajectory_input(traj: Trajectories, static: Trajectories) -> None:
    r"""Refuse a record whose units or time axis are not those the file claims.

    Raises :class:`TrajectoryFileError` naming the file when the median
    distance between the static shot's points (or the record's) lies outside
    :data:`MARKER_SPACING_M` (a file in millimetres or centimetres read as
    metres), when the two files' spacings differ by more than a factor 2 (one
    file in other units), or when the frame rate the times give lies outside
    :data:`FRAME_RATE_HZ` (a time column in milliseconds), or contradicts a
    rate the file states (a C3D's ``POINT:RATE``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> rows = "".join(f"{k},{k * 10},{n},{x + k},0,0\n" for k in range(3) for n, x in (("a", 0), ("b", 300)))
    >>> _ = (folder / "mm.csv").write_text("frame,time_s,point,x_m,y_m,z_m\n" + rows)   # mm and ms
    >>> record = read_trajectories(folder / "mm.csv")
    >>> try:
    ...     check_trajectory_input(record, record)
    ... except TrajectoryFileError as error:
    ...     print(str(error).split(";")[0].split(": ")[1])
    the static shot's points lie 300 'm' apart (median)
    """
    spacing = {}
    for what, rec in (("the static shot's points", static), ("the record's points", traj)):
        gap = _median_spacing(rec.points)
        spacing[what] = gap
        lo, hi = MARKER_SPACING_M
        if np.isfinite(gap) and not lo <= gap <= hi:
            likely = ("millimetres" if gap <= 1000 * hi else "other units") if gap > hi else "kilometres or other units"
            raise TrajectoryFileError(
                f"{rec.source}: {what} lie {gap:.6g} 'm' apart (median); markers on a body lie {lo:g} to {hi:g} m "
                f"apart, so the file's coordinates look like {likely}, not metres: write them in metres "
                f"({'x_m = x_mm / 1000' if gap > hi else 'x_m in metres'}) or give a C3D with POINT:UNITS")
    a, b = spacing.values()
    if np.isfinite(a) and np.isfinite(b) and max(a, b) > 2 * min(a, b):
        raise TrajectoryFileError(f"{traj.source}: its points lie {b:.4g} m apart (median), the static shot "
                                  f"{static.source}'s {a:.4g} m: the two files are in different units or of "
                                  "different bodies")
    _check_time_axis(traj)


def _check_time_axis(traj: Trajectories) -> None:
    """The rate from the times within :data:`FRAME_RATE_HZ` and equal to a rate the file states."""
    if traj.frame.size < 2:
        return
    estimate = frame_rate(traj)
    lo, hi = FRAME_RATE_HZ
    if not lo <= estimate <= hi:
        step = 1.0 / estimate
        hint = " (a time column in milliseconds?)" if estimate < lo else " (a time column in other units?)"
        raise TrajectoryFileError(f"{traj.source}: field 'time_s' steps by {step:.6g} per frame, a frame rate of "
                                  f"{estimate:.6g} Hz{hint}; expected seconds, {lo:g} to {hi:g} Hz")
    stated = traj.info.get("rate_hz")
    if stated:
        check_stated_rate(traj, stated, f"the file's stated rate ({traj.info.get('rate_from') or 'POINT:RATE'})")


def check_stated_rate(traj: Trajectories, rate: float, what: str = "--rate") -> None:
    r"""Refuse ``rate`` (Hz) when the record's times give another one (more than 0.1 % apart).

    A one-frame record has no rate of its own: any positive rate is taken.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> rows = "".join(f"{k},{k / 30!r},a,0,0,0\n" for k in range(4))
    >>> _ = (folder / "r30.csv").write_text("frame,time_s,point,x_m,y_m,z_m\n" + rows)
    >>> record = read_trajectories(folder / "r30.csv")
    >>> check_stated_rate(record, 30.0)     # agrees: nothing said
    >>> try:
    ...     check_stated_rate(record, 100.0)
    ... except TrajectoryFileError as error:
    ...     print("refused")
    refused
    """
    frame_rate(traj, rate)     # a positive finite number
    if traj.frame.size < 2:
        return
    estimate = frame_rate(traj)
    if abs(rate - estimate) > 1e-3 * estimate:
        raise TrajectoryFileError(f"{traj.source}: {what} {rate:g} Hz contradicts the times, which step by "
                                  f"{1 / estimate:.6g} s per frame ({estimate:.6g} Hz); leave the rate out or "
                                  "give the one the times say")


def _p99(values) -> float:
    finite = values[np.isfinite(values)]
    return float(np.percentile(finite, 99)) if finite.size else math.nan


class RunningPercentile:
    r"""The ``q``-th percentile (``np.percentile``'s linear rule) of values given a block at a time.

    Exact with memory bounded by the count: of at most ``count`` values (NaN
    and infinite ones are left out, as :func:`numpy.percentile` of the finite
    values) only the largest ``ceil((1 - q / 100) count) + 2`` are kept, which
    hold the two order statistics the percentile interpolates between.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> values = rng.normal(size=(1000, 4))
    >>> p = RunningPercentile(99, values.size)
    >>> for block in np.split(values, 10):
    ...     p.add(block)
    >>> bool(np.isclose(p.value(), np.percentile(values, 99), rtol=0, atol=1e-12))
    True
    """

    def __init__(self, q: float, count: int):
        if not 0 <= q <= 100 or count < 0:
            raise ValueError(f"percentile {q} of {count} values: expected 0 <= q <= 100 and a count >= 0")
        self.q = float(q)
        self.capacity = int(math.ceil((100 - self.q) * count / 100)) + 2
        self.count = 0
        self._top = np.empty(0)

    def add(self, values) -> None:
        """Take the finite ones of ``values`` (any shape)."""
        v = np.asarray(values, float).ravel()
        v = v[np.isfinite(v)]
        self.count += v.size
        merged = np.concatenate([self._top, v])
        if merged.size > self.capacity:
            merged = np.partition(merged, merged.size - self.capacity)[-self.capacity:]
        self._top = merged

    def value(self) -> float:
        """The percentile of the finite values taken (NaN without any)."""
        n = self.count
        if n == 0:
            return math.nan
        top = np.sort(self._top)
        skipped = n - top.size                        # values below the kept ones
        pos = self.q / 100 * (n - 1)
        lo = int(math.floor(pos))
        if lo < skipped:
            raise ValueError(f"{n} values: more than the {self.capacity} kept; give the count of all values")
        a = top[lo - skipped]
        b = top[min(lo + 1, n - 1) - skipped]
        frac = pos - lo
        # numpy's linear interpolation, evaluated from the nearer end
        return float(b - (b - a) * (1 - frac) if frac >= 0.5 else a + (b - a) * frac)


def kinematics_checks(traj: Trajectories, res: dict) -> list:
    """Plausibility checks of a kinematics result: speeds and accelerations within what bodies do.

    Each check is a dict ``name``, ``level`` ("ok", "warning", "unreliable"),
    ``value``, ``limit`` and ``message``; :func:`kinematics_verdict` gives
    the worst level. The raw speed (differences of the record's positions)
    and the smoothed marker speed are held to :data:`SPEED_LIMIT_MPS`, the
    acceleration to :data:`ACCELERATION_LIMIT_MPS2` (99th percentiles: a
    few spikes are the smoothing's business). The raw speed above it is a
    warning (the noise of a fast capture may reach it; the smoothing removes
    it), the smoothed speed or acceleration above it unreliable; frames
    whose times do not fall on the rate's grid are a warning.
    """
    mk = res["marker_kinematics"]
    return kinematics_checks_of_norms(traj, res["markers"], np.linalg.norm(mk.velocity, axis=2),
                                      np.linalg.norm(mk.acceleration, axis=2))


def kinematics_checks_of_norms(traj: Trajectories, markers, speed, acceleration) -> list:
    """:func:`kinematics_checks` from the markers' smoothed speeds and accelerations (n, k) (m/s, m/s^2)."""
    return kinematics_checks_of_percentiles(traj, markers, _p99(speed), _p99(acceleration))


def kinematics_checks_of_percentiles(traj: Trajectories, markers, speed_p99: float, acceleration_p99: float,
                                     chunk: int = 100_000) -> list:
    """:func:`kinematics_checks` from the 99th percentiles of the markers' smoothed speed (m/s) and
    acceleration (m/s^2) (:class:`RunningPercentile` of a record given a window at a time); the raw
    speed's percentile is taken ``chunk`` frames at a time."""
    checks = []
    t = traj.time_s
    if t.size >= 2:
        idx = [traj.names.index(nm) for nm in markers]
        raw = RunningPercentile(99, (t.size - 1) * len(idx))
        for a in range(0, t.size - 1, chunk):
            pts = _read_frames(traj.points, a, a + chunk + 1)[:, idx]
            raw.add(np.linalg.norm(np.diff(pts, axis=0), axis=2) / np.diff(t[a:a + chunk + 1])[:, None])
        checks.append(_limit_check("raw_marker_speed", raw.value(), SPEED_LIMIT_MPS, "m/s",
                                   "speed of the record's markers between frames", "warning"))
    checks.append(_limit_check("marker_speed", speed_p99, SPEED_LIMIT_MPS, "m/s", "smoothed speed of the markers"))
    checks.append(_limit_check("marker_acceleration", acceleration_p99,
                               ACCELERATION_LIMIT_MPS2, "m/s²", "smoothed acceleration of the markers"))
    if t.size >= 3:
        rate = frame_rate(traj)
        off = float(np.max(np.abs(t - (t[0] + (traj.frame - traj.frame[0]) / rate)))) * rate
        level = "warning" if off > 0.25 else "ok"
        checks.append({"name": "time_grid", "level": level, "value": off, "limit": 0.25,
                       "message": f"times off the {rate:.6g} Hz grid by up to {off:.3g} frame(s)"})
    return checks


def _limit_check(name, value, limit, unit, what, beyond: str = "unreliable") -> dict:
    level = beyond if value > limit else "ok"
    text = f"99th percentile of the {what}: {value:.4g} {unit}"
    if level != "ok":
        text += f", above the {limit:g} {unit} any body reaches (wrong units or time column, or noise)"
    return {"name": name, "level": level, "value": value, "limit": limit, "message": text}


def kinematics_verdict(checks) -> str:
    """The worst level of ``checks``: "ok", "warning" or "unreliable" (a "skipped" check counts for nothing).

    Examples
    --------
    >>> kinematics_verdict([{"level": "ok"}, {"level": "skipped"}, {"level": "warning"}])
    'warning'
    """
    order = ("ok", "warning", "unreliable")
    return max((c["level"] for c in checks if c["level"] in order), key=order.index, default="ok")


def kinematics_from_trajectories(traj: Trajectories, static: Trajectories, *, smoothing: str = "auto",
                                 events=None, noise_criterion: str | None = None):
    """Pose-trajectory kinematics of a rigid body from 3D markers and a static shot.

    The markers are the points present in both files (:func:`match_point_names`:
    exact names first, then without a subject prefix and case where that is
    unambiguous); the hidden points are those of the static shot absent from
    the trajectories (e.g. the saddle); trajectory points absent from the
    static shot are not used and listed as ``unmatched``.
    The static shot's first frame with every point finite is the model.
    ``events``: known times (s, the file's time axis) where the acceleration
    may jump, e.g. an impact's onset from a force plate
    (:func:`horsemocap.pose.fit_pose_trajectory`, ``events``; smoothing
    "auto" (default: gcv with harmonics on a periodic record, adaptive otherwise, and GCV with
    the noise's AR(1) correlation where the markers' rigidity residual shows correlated noise,
    :func:`horsemocap.pose.choose_smoothing`), "gcv" or "adaptive"). With events the record is smoothed without stride
    harmonics (the change points are for a non-periodic record; the two are
    not fitted together). ``noise_criterion``: how "auto" chooses under
    correlated noise (``rigid_body.pose.correlated_noise_criterion``: "loo",
    "gcv", "reml" or "risk"; None: its default).

    Returns
    -------
    dict with ``trajectory`` (:class:`horsemocap.pose.PoseTrajectory`),
    ``markers`` and ``hidden`` (names), ``marker_kinematics`` and
    ``hidden_kinematics`` (:class:`horsemocap.pose.PointKinematics`, (n, k, 3)),
    ``registration``, ``unmatched`` (trajectory points not used) and
    ``matched_loosely`` ([trajectory name, static name] pairs matched
    without prefix or case).
    """
    from . import pose
    from .basis_check import basis_resolution

    setup = kinematics_setup(traj, static)
    markers, hidden, model, model_all = setup["markers"], setup["hidden"], setup["model"], setup["model_all"]
    points, reg = setup["points"], setup["registration"]
    params = kinematics_params(smoothing, events, noise_criterion)
    # the markers go with the poses: "auto" measures the noise's correlation from their rigidity residual
    tr = pose.fit_pose_trajectory(traj.time_s, reg, model, params, points=points)
    mk = tr.points(traj.time_s, model)
    hk = tr.points(traj.time_s, model_all[len(markers):]) if hidden else None
    # a record too long for a knot at every frame: does the basis hold the (first hidden, else first) point?
    name, point = basis_point(setup)
    resolution = basis_resolution(tr, reg, model, point, params, points=points)
    return {"trajectory": tr, "markers": markers, "hidden": hidden, "marker_kinematics": mk,
            "hidden_kinematics": hk, "registration": reg, "unmatched": setup["unmatched"],
            "matched_loosely": setup["matched_loosely"], "basis_resolution": resolution, "basis_point": name}


def basis_point(setup: dict) -> tuple:
    """``(words, body point)`` the ``spline_basis`` check compares: the first hidden point of
    :func:`kinematics_setup`'s ``setup``, else its first marker.

    Examples
    --------
    >>> basis_point({"markers": ["a", "b", "c"], "hidden": ["saddle"], "model_all": np.eye(4, 3)})[0]
    'the hidden point saddle'
    """
    if setup["hidden"]:
        return f"the hidden point {setup['hidden'][0]}", setup["model_all"][len(setup["markers"])]
    return f"the marker {setup['markers'][0]}", setup["model_all"][0]


def kinematics_params(smoothing: str = "auto", events=None, noise_criterion: str | None = None):
    """The pose smoothing of :func:`kinematics_from_trajectories`: with known events the record is
    smoothed without stride harmonics; frames with two markers stay out of the smoothing;
    ``noise_criterion`` is the choice under correlated noise (``correlated_noise_criterion``; None: the
    parameter's default).

    Examples
    --------
    >>> kinematics_params("gcv", noise_criterion="reml").correlated_noise_criterion
    'reml'

    An unknown criterion is refused by name when the trajectory is fitted
    (:func:`horsemocap.pose.fit_pose_trajectory`).
    """
    from .params import PoseParams

    harmonics = "none" if events is not None and len(events) else "auto"
    given = {} if noise_criterion is None else {"correlated_noise_criterion": noise_criterion}
    return PoseParams(smoothing=smoothing, harmonics=harmonics, events=events, partial_frames=False, **given)


def kinematics_setup(traj: Trajectories, static: Trajectories, folder=None) -> dict:
    """The markers matched to the static shot, the model and the record's registration.

    What :func:`kinematics_from_trajectories` fits (its docstring says how the
    points are matched): a dict with ``markers``, ``hidden`` (names),
    ``model`` (the markers in the static shot), ``model_all`` (markers then
    hidden points), ``points`` (n, k, 3) of the markers, ``registration``,
    ``unmatched`` and ``matched_loosely``. With ``folder`` a long record's
    registration is memory-mapped there (:func:`horsemocap.streaming.register_in_chunks`).
    """
    from . import pose
    from .streaming import register_in_chunks

    match = match_point_names(traj.names, static.names)
    pairs = sorted(match["pairs"], key=lambda pr: traj.names.index(pr[0]))
    markers, hidden = [t for t, _ in pairs], match["hidden"]
    if len(markers) < 3:
        raise TrajectoryFileError(f"{traj.source}: only {len(markers)} point name(s) {markers} also in the static "
                                  f"shot {static.source}; a rigid body needs 3 non-collinear markers (the "
                                  f"trajectories name {list(traj.names)}, the static shot {list(static.names)})")
    static_order = [s for _, s in pairs] + hidden
    sp = static.subset(static_order)
    ok = np.flatnonzero(np.all(np.isfinite(sp), axis=(1, 2)))
    if ok.size == 0:
        raise TrajectoryFileError(f"{static.source}: no frame has every point {static_order} finite")
    points = _marker_points(traj, markers, folder)
    if not any(np.isfinite(_read_frames(points, a, a + READ_FRAMES)).all(axis=2).any()
               for a in range(0, len(points), READ_FRAMES)):
        raise TrajectoryFileError(f"{traj.source}: the markers {markers} are missing in every frame (all gaps)")
    model_all = sp[ok[0]]
    model = model_all[: len(markers)]
    pose.check_model_conditioning(model, name=f"static shot {static.source}")
    reg = register_in_chunks(points, model, names=markers, folder=folder)
    return {"markers": markers, "hidden": hidden, "model": model, "model_all": model_all, "points": points,
            "registration": reg, "unmatched": match["unmatched"],
            "matched_loosely": [list(pr) for pr in match["loose"]]}


READ_FRAMES = 100_000
"""Frames of a long record read into memory at a time when its markers are checked or copied: at ten
points 24 MB, small beside the registration's chunk, and few enough reads that their overhead is nil."""


def _marker_points(traj: Trajectories, markers, folder=None) -> np.ndarray:
    """The points (n, k, 3) of ``markers``: a view of the record when they follow one another in the file;
    otherwise a copy, made ``READ_FRAMES`` frames at a time into a memory-mapped file in ``folder`` when
    the record's points are themselves mapped and a folder is given (the record is not held in memory)."""
    idx = [traj.names.index(nm) for nm in markers]
    adjacent = idx == list(range(idx[0], idx[0] + len(idx)))
    if adjacent or folder is None or not isinstance(traj.points, np.memmap):
        return traj.subset(markers)
    n = len(traj.points)
    path = _scratch_path(folder, "markers-", ".npy")
    try:
        copy = np.lib.format.open_memmap(path, mode="w+", dtype=np.float64, shape=(n, len(idx), 3))
        for a in range(0, n, READ_FRAMES):
            copy[a:a + READ_FRAMES] = _read_frames(traj.points, a, a + READ_FRAMES)[:, idx]
            release_pages(copy)
        copy.flush()
        del copy
    except OSError as exc:
        raise _scratch_error(exc, path) from exc
    return np.load(path, mmap_mode="r")


def _scratch_path(folder, prefix: str, suffix: str) -> Path:
    """A new file of a unique name in the scratch ``folder`` (a second reader of the same folder does not
    overwrite a file the first one has mapped); :class:`horsemocap.store.ScratchWriteError` if it cannot be made."""
    try:
        handle, name = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=folder)
    except OSError as exc:
        raise _scratch_error(exc, Path(folder) / f"{prefix}*{suffix}") from exc
    os.close(handle)
    return Path(name)


def _scratch_error(exc: OSError, path) -> ScratchWriteError:
    """``exc``, raised writing the scratch file ``path``, as the error naming the file and its folder."""
    return ScratchWriteError(exc.errno, exc.strerror or str(exc), str(path))


def csv_field(text: str) -> str:
    """``text`` as the csv module writes one field (quoted where it holds a comma, a quote or a line end).

    Examples
    --------
    >>> csv_field("saddle"), csv_field("left, front")
    ('saddle', '"left, front"')
    """
    if any(c in text for c in ',"\r\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


def _number_rows(head, values) -> list:
    """Lines ``head[i] + ",%.9g" * columns`` of ``values`` (r, c); a NaN or infinite value is an empty field."""
    finite = np.isfinite(values).all(axis=1)
    fmt = "%s" + ",%.9g" * values.shape[1] + "\n"
    rows = values.tolist()
    lines = []
    for h, ok, row in zip(head, finite.tolist(), rows):
        if ok:
            lines.append(fmt % (h, *row))
        else:
            lines.append(h + "".join("," + ("%.9g" % v if math.isfinite(v) else "") for v in row) + "\n")
    return lines


def kinematics_block_text(frame, time_s, names, block, height, rms) -> tuple:
    """The rows of trajectories.csv, kinematics.csv and angular.csv of one block of frames, as text.

    ``frame``, ``time_s``, ``height``, ``rms`` (b,) of the block's frames;
    ``names`` the points of ``block.position`` (b, k, 3) etc.; ``block``: a
    :class:`horsemocap.streaming.KinematicsBlock`. Numbers are written with
    nine significant digits (``%.9g``), a non-finite one as an empty field;
    point names as the csv module quotes them; a note's commas become
    semicolons.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> one = np.ones((1, 1, 3))
    >>> b = SimpleNamespace(position=one, velocity=one * 2, acceleration=one * np.nan, omega=np.zeros((1, 3)),
    ...                     alpha=np.zeros((1, 3)), reason=np.array(["bridged gap, 1 frame"], object))
    >>> pos, kin, ang = kinematics_block_text([7], [0.035], ["a,b"], b, [0.1], [np.nan])
    >>> pos, kin, ang
    ('7,0.035,"a,b",1,1,1\\n', '7,0.035,"a,b",2,2,2,,,\\n', '7,0.035,0,0,0,0,0,0,0.1,,bridged gap; 1 frame\\n')
    """
    b, k = len(frame), len(names)
    t_text = ["" if not math.isfinite(v) else "%.9g" % v for v in np.asarray(time_s, float).tolist()]
    lead = ["%d,%s," % (f, tt) for f, tt in zip(np.asarray(frame).tolist(), t_text)]
    quoted = [csv_field(nm) for nm in names]
    head = [ld + nm for ld in lead for nm in quoted]
    pos = _number_rows(head, np.asarray(block.position, float).reshape(b * k, 3))
    kin = _number_rows(head, np.concatenate([block.velocity, block.acceleration], axis=2).reshape(b * k, 6))
    angular = np.column_stack([block.omega, block.alpha, height, rms])
    notes = {}
    for r in block.reason:
        if r not in notes:
            notes[r] = csv_field(str(r).replace(",", ";"))
    ang = [line[:-1] + "," + notes[r] + "\n"
           for line, r in zip(_number_rows([ld[:-1] for ld in lead], angular), block.reason)]
    return "".join(pos), "".join(kin), "".join(ang)


STREAM_BLOCK_ROWS = 200_000
"""Rows parsed at a time by :func:`read_trajectories_csv_to_disk`."""


def read_trajectories_csv_to_disk(path, folder, block_rows: int = STREAM_BLOCK_ROWS) -> Trajectories:
    r""":func:`read_trajectories_csv` with the points in a read-only memory-mapped file in ``folder``.

    The rows are parsed ``block_rows`` at a time and written to a compact
    binary file; the frames' numbers and times stay in memory (16 bytes a
    frame), the points go to a file ``points-*.npy`` (n, k, 3) of a unique
    name in ``folder`` and are mapped, not loaded; a scratch file that cannot
    be written (a full disk) ends with a
    :class:`horsemocap.store.ScratchWriteError` naming it and its folder. This takes a file whose frames come in order (each frame's
    rows together, frame numbers and times increasing) with every row
    readable and no (frame, point) twice; any other file (out of order, a
    bad row, a repeated point) is read by :func:`read_trajectories_csv`
    whole, which names the fault or places the rows as usual. The result is
    the same either way.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = folder / "walk.csv"
    >>> _ = path.write_text("frame,time_s,point,x_m,y_m,z_m\n"
    ...                     "0,0.0,marker1,0.0,1.0,4.0\n0,0.0,marker2,0.3,1.0,4.0\n"
    ...                     "1,0.01,marker1,0.05,1.0,4.0\n1,0.01,marker2,,,\n")
    >>> walk = read_trajectories_csv_to_disk(path, folder)
    >>> walk.names, type(walk.points).__name__, walk.points[1, 0].tolist()
    (('marker1', 'marker2'), 'memmap', [0.05, 1.0, 4.0])
    """
    path, folder = Path(path), Path(folder)
    rows_file = _scratch_path(folder, "rows-", ".bin")
    try:
        try:
            streamed = _stream_rows(path, rows_file, block_rows)
        except ScratchWriteError:
            raise
        except (OSError, UnicodeError, csv.Error):
            streamed = None                              # reading the input: the whole reader says what it is
        if streamed is None:
            return read_trajectories_csv(path)
        frames, times, names, n_rows = streamed
        points_file = _scratch_path(folder, "points-", ".npy")
        try:
            points = _place_rows(rows_file, points_file, frames.size, len(names), n_rows, block_rows)
        except OSError as exc:
            points_file.unlink(missing_ok=True)
            raise _scratch_error(exc, points_file) from exc
    finally:
        rows_file.unlink(missing_ok=True)
    return Trajectories(times, frames, tuple(names), points, str(path), _csv_info())


def read_trajectories_to_disk(path, folder) -> Trajectories:
    r""":func:`read_trajectories`, a CSV's points memory-mapped in ``folder``
    (:func:`read_trajectories_csv_to_disk`); a C3D is read whole.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "walk.csv").write_text("frame,time_s,point,x_m,y_m,z_m\n0,0.0,m1,0.0,1.0,4.0\n"
    ...                                      "1,0.01,m1,0.05,1.0,4.0\n")
    >>> walk = read_trajectories_to_disk(folder / "walk.csv", folder)
    >>> type(walk.points).__name__, walk.points[:, 0, 0].tolist()
    ('memmap', [0.0, 0.05])
    >>> _ = write_c3d(folder / "walk.c3d", walk)
    >>> type(read_trajectories_to_disk(folder / "walk.c3d", folder).points).__name__
    'ndarray'
    """
    if str(path).lower().endswith(".c3d"):
        return read_c3d(path)
    return read_trajectories_csv_to_disk(path, folder)


_ROW = np.dtype([("frame", np.int64), ("point", np.int32), ("xyz", np.float64, 3)])


def _stream_rows(path, rows_file, block_rows: int):
    """Parse the file in blocks into ``rows_file`` (frame index, point index, xyz); ``(frames, times, names,
    rows)``, or None for a file :func:`read_trajectories_csv_to_disk` leaves to the whole reader."""
    if not path.is_file():
        return None
    with open(path, newline="") as fh, _open_scratch(rows_file) as out:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            return None
        header, col, missing = _header_columns(header)
        if missing:
            return None
        cf, ct, cp, cx, cy, cz = (col[c] for c in TRAJECTORY_COLUMNS)
        n_fields = len(header)
        frames, times, names, index = array("q"), array("d"), [], {}
        seen, n_rows, block = set(), 0, []
        for row in reader:
            if not row or all(not c.strip() for c in row):
                continue
            usual = _usual_row(row, cf, ct, cp, cx, cy, cz, n_fields)
            if usual is not None:
                fr, tm, name, x, y, z = usual
            else:
                try:                                  # a missing point (empty coordinates), or a bad row
                    fr, tm, name, (x, y, z) = _csv_row(path, 0, row, col, n_fields)
                except TrajectoryFileError:
                    return None
            if not frames or fr != frames[-1]:
                if frames and (fr < frames[-1] or not tm > times[-1]):
                    return None                      # out of order, or times not increasing: the whole reader
                frames.append(fr)
                times.append(tm)
                seen = set()
            elif tm != times[-1]:
                return None
            j = index.get(name)
            if j is None:
                j = index[name] = len(names)
                names.append(name)
            if j in seen:
                return None
            seen.add(j)
            block.append((len(frames) - 1, j, (x, y, z)))
            if len(block) == block_rows:
                _write_rows(out, block, rows_file)
                n_rows, block = n_rows + len(block), []
        if block:
            _write_rows(out, block, rows_file)
            n_rows += len(block)
    if not frames:
        return None
    return np.frombuffer(frames, np.int64).copy(), np.frombuffer(times, float).copy(), names, n_rows


def _open_scratch(rows_file):
    """``rows_file`` opened for writing; :class:`horsemocap.store.ScratchWriteError` if it cannot be."""
    try:
        return open(rows_file, "wb")
    except OSError as exc:
        raise _scratch_error(exc, rows_file) from exc


def _write_rows(out, block: list, rows_file) -> None:
    """Append ``block`` (frame index, point index, xyz) to the scratch file ``out``; a failed write
    (a full disk) is a :class:`horsemocap.store.ScratchWriteError`, not a fault of the input."""
    try:
        np.array(block, _ROW).tofile(out)
    except OSError as exc:
        raise _scratch_error(exc, rows_file) from exc


def _place_rows(rows_file, points_file, n: int, k: int, n_rows: int, block_rows: int) -> np.ndarray:
    """The points (n, k, 3) of ``rows_file`` in a memory-mapped ``points_file`` (NaN where no row), filled
    ``block_rows`` rows at a time and returned read-only."""
    grid = np.lib.format.open_memmap(points_file, mode="w+", dtype=np.float64, shape=(n, k, 3))
    with open(rows_file, "rb") as fh:
        filled = 0
        for a in range(0, n_rows, block_rows):
            rows = np.fromfile(fh, _ROW, min(block_rows, n_rows - a))
            hi = int(rows["frame"][-1]) + 1
            grid[filled:hi] = np.nan
            grid[rows["frame"], rows["point"]] = rows["xyz"]
            filled = hi
            release_pages(grid)
    grid[filled:] = np.nan
    grid.flush()
    del grid
    return np.load(points_file, mmap_mode="r")
