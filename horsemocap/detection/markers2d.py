"""``markers_2d.csv`` (spec ``docs/sessions.md``): its one writer and the marker names.

:func:`marker_label` names marker ``i`` in every result file (``marker1``,
``marker2``, ...); :func:`markers_2d_rows`, :func:`markers_2d_csv_text` and
:func:`write_markers_2d_csv` turn the detections of every camera into the
file (``horsemocap.results`` writes the same text).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..store import atomic_write_text

__all__ = [
    "marker_label",
    "markers_2d_rows",
    "markers_2d_csv_text",
    "write_markers_2d_csv",
]


def marker_label(index: int) -> str:
    """The name of marker ``index`` (0-based) in every result file: ``marker1``, ``marker2``, ..."""
    return f"marker{int(index) + 1}"


def _px_text(value: float) -> str:
    return f"{float(value):.9g}" if np.isfinite(value) else ""


def markers_2d_rows(camera: str, track, frame_offset: int = 0, reason=None, residual_px=None) -> list[list]:
    """Rows ``[camera, frame, marker, u_px, v_px, reason, residual_px]`` of ``markers_2d.csv``.

    Parameters
    ----------
    camera : str
    track : MarkerTrack or ndarray (frames, markers, 2)
        The detections (a track's ``marker_px``), NaN where not found.
    frame_offset : int
        Index in the camera's own motion source of the track's first frame.
    reason : ndarray (frames, markers) of str, optional
        Why a value is missing or was rejected (``""``: used); default the
        track's own ``reason``, else empty.
    residual_px : ndarray (frames, markers), optional
        Reprojection residual of the centre against the triangulated point.

    Returns
    -------
    list of list
        ``frame`` = track index + ``frame_offset``, ``marker`` =
        :func:`marker_label`, ``u_px``/``v_px`` to 9 significant digits,
        ``""`` where the marker was not found; ``reason`` and
        ``residual_px`` (4 decimals) empty where unknown.
    """
    px = np.asarray(getattr(track, "marker_px", track), float)
    why = reason if reason is not None else getattr(track, "reason", None)
    why = np.full(px.shape[:2], "", dtype=object) if why is None else np.asarray(why, dtype=object)
    res = np.full(px.shape[:2], np.nan) if residual_px is None else np.asarray(residual_px, float)
    n, M = px.shape[:2]
    u, v = _column_text(px[..., 0], _px_text), _column_text(px[..., 1], _px_text)
    r = _column_text(res, lambda x: f"{x:.4f}")
    names = [marker_label(m) for m in range(M)]
    frames = np.repeat(np.arange(n) + int(frame_offset), M).tolist()
    return [[camera, f, names[i % M], a, b, str(w), e]
            for i, (f, a, b, w, e) in enumerate(zip(frames, u, v, why.ravel().tolist(), r, strict=True))]


def _column_text(values: np.ndarray, text) -> list:
    """``text(x)`` of every finite value (row-major), ``""`` elsewhere; a long record is mostly empty."""
    flat = np.asarray(values, float).ravel()
    out = [""] * flat.size
    for i in np.flatnonzero(np.isfinite(flat)).tolist():
        out[i] = text(flat[i])
    return out


def markers_2d_csv_text(tracks: dict, frame_offsets: dict | None = None, reasons: dict | None = None,
                        residuals: dict | None = None) -> str:
    """The text of ``markers_2d.csv`` (spec ``sessions.md``: ``camera,frame,marker,u_px,v_px,reason,residual_px``).

    ``tracks`` maps camera -> :class:`MarkerTrack` or ``marker_px`` array;
    ``frame_offsets`` maps camera -> source index of its first frame (0 if
    absent); ``reasons`` and ``residuals`` map camera -> (frames, markers)
    arrays (see :func:`markers_2d_rows`). The pipeline's results and
    :func:`write_markers_2d_csv` both use this.
    """
    lines = ["camera,frame,marker,u_px,v_px,reason,residual_px"]
    for cam, tr in tracks.items():
        off = (frame_offsets or {}).get(cam, 0)
        lines.extend(",".join(str(x) for x in r) for r in markers_2d_rows(
            cam, tr, off, (reasons or {}).get(cam), (residuals or {}).get(cam)))
    return "\n".join(lines) + "\n"


def write_markers_2d_csv(path, tracks: dict, frame_offsets: dict | None = None, reasons: dict | None = None,
                         residuals: dict | None = None) -> Path:
    """Write ``markers_2d.csv`` atomically (:func:`markers_2d_csv_text`)."""
    return atomic_write_text(path, markers_2d_csv_text(tracks, frame_offsets, reasons, residuals))
