"""Check of thesis section 8.3 / Table 8.5: grid distances measured through the rig.

The thesis picked points A, B, C, D on the calibration grid (Figure 8.6),
reconstructed them with the vision system and compared the measured distances
with the true ones: AB = AC = 500 mm (10 squares of 50 mm along each board
axis) and AD = 707.1 mm (the diagonal), with errors of 2.2 %, 4.6 % and
2.8 %. Here every view seen by at least two cameras is reconstructed the same
way (linear triangulation of undistorted rays, thesis section 5.1) and the
same three distances are measured in each.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Rig
from .board import CalibrationError


def _normalized(cam, pixels: np.ndarray) -> np.ndarray:
    """Undistorted normalised coordinates of distorted pixels (inverse of eq. 3.7-3.10); NaN stays NaN."""
    return cam.pixels_to_normalized(np.asarray(pixels, float).reshape(-1, 2))


def triangulate(rig: Rig, pixels: dict) -> np.ndarray:
    """Linear (DLT) triangulation of points seen by several cameras.

    Parameters
    ----------
    rig : Rig
    pixels : dict[str, ndarray (N, 2)]
        Distorted pixels per camera; NaN rows are ignored.

    Returns
    -------
    ndarray (N, 3)
        Points in the world (reference camera) frame, metres; NaN where fewer
        than two cameras saw the point.
    """
    names = [n for n in pixels if n in rig.names]
    n = len(next(iter(pixels.values())))
    rows, seen = [], np.zeros(n, int)
    for c in names:
        x = _normalized(rig[c], pixels[c])
        ok = np.all(np.isfinite(x), axis=1)
        seen += ok
        P = np.hstack([rig[c].rotation_matrix, rig[c].translation[:, None]])
        x = np.where(ok[:, None], x, 0.0)
        w = ok[:, None].astype(float)                      # a camera that did not see the point adds zero rows
        rows.append((x[:, :1] * P[2] - P[0]) * w)
        rows.append((x[:, 1:2] * P[2] - P[1]) * w)
    A = np.stack(rows, axis=1)                             # (N, 2 * cameras, 4)
    _, _, Vt = np.linalg.svd(A)
    X = Vt[:, -1, :]
    out = X[:, :3] / X[:, 3:4]
    out[seen < 2] = np.nan
    return out


def _order_like_reference(rig: Rig, views: dict, ref: str, k: int) -> dict:
    """Corners of view ``k`` per camera, each camera's order reversed if that fits the reference better."""
    px = {ref: views[ref].corners[k]}
    for c, v in views.items():
        if c == ref or not np.all(np.isfinite(v.corners[k])):
            continue
        best = None
        for cand in (v.corners[k], v.corners[k][::-1]):
            X = triangulate(rig, {ref: px[ref], c: cand})
            err = np.nanmean(np.linalg.norm(rig[c].project(X) - cand, axis=1))
            if best is None or err < best[0]:
                best = (err, cand)
        px[c] = best[1]
    return px


@dataclass(frozen=True)
class GridCheck:
    """Table 8.5 for every view.

    Attributes
    ----------
    view_names : tuple of str
        Views reconstructed (seen by the reference camera and at least one other).
    segments : tuple of str
        ``("AB", "AC", "AD")``.
    actual_mm : ndarray (3,)
        True lengths of the segments.
    measured_mm : ndarray (views, 3)
    error_pct : ndarray (views, 3)
        ``100 * |measured - actual| / actual``.
    corners_idx : dict[str, int]
        Index of A, B, C, D in the board's corner list.
    points_m : ndarray (views, N, 3)
        Every reconstructed corner (reference frame).
    segment_error_pct : ndarray (views, S)
        Signed percent error of every segment of ``span`` squares along the
        board's rows and columns (not only AB and AC): its mean is the scale
        bias of the rig, its spread the noise of single points.
    """

    view_names: tuple
    segments: tuple
    actual_mm: np.ndarray
    measured_mm: np.ndarray
    error_pct: np.ndarray
    corners_idx: dict
    points_m: np.ndarray
    segment_error_pct: np.ndarray

    def summary(self) -> dict:
        """Mean absolute error of AB/AC/AD, and bias and RMS over every segment (percent)."""
        s = self.segment_error_pct
        return {"abcd_mean_abs_pct": float(np.nanmean(self.error_pct)),
                "abcd_max_pct": float(np.nanmax(self.error_pct)),
                "segments": int(np.isfinite(s).sum()),
                "segments_bias_pct": float(np.nanmean(s)),
                "segments_rms_pct": float(np.sqrt(np.nanmean(s**2)))}

    def table(self) -> str:
        """Table 8.5's layout: actual, measured (mean over views) and percent error."""
        lines = [f"{'':4s}{'Actual distance (mm)':>22s}{'Measured distance (mm)':>24s}"
                 f"{'Percent error in distance (%)':>31s}{'max error (%)':>15s}"]
        for j, s in enumerate(self.segments):
            lines.append(f"{s:4s}{self.actual_mm[j]:22.1f}{np.nanmean(self.measured_mm[:, j]):24.4f}"
                         f"{np.nanmean(self.error_pct[:, j]):31.4f}{np.nanmax(self.error_pct[:, j]):15.4f}")
        sm = self.summary()
        lines.append(f"({len(self.view_names)} views; measured = mean over views, error = mean of |error|)")
        lines.append(f"all {sm['segments']} segments of {self.actual_mm[0]:.0f} mm along rows and columns: "
                     f"bias {sm['segments_bias_pct']:+.4f} %, RMS {sm['segments_rms_pct']:.4f} %")
        return "\n".join(lines)


def grid_distance_check(rig: Rig, views: dict, square_m: float, span: int | None = None,
                        reference: str | None = None) -> GridCheck:
    """Distances between grid points measured through the rig (section 8.3, Table 8.5).

    Parameters
    ----------
    rig : Rig
    views : dict[str, BoardViews]
        Detected corners per camera (aligned: index ``k`` the same instant;
        :attr:`RigCalibration.views` is). Folders can be detected first with
        :func:`~.board.detect_views` and :func:`~.rig.align_views`.
    square_m : float
        True side of a square, metres.
    span : int, optional
        Squares between A and B (and A and C). Default ``min(10, cols-1,
        rows-1)``: 10 squares of 50 mm = the thesis' 500 mm.
    reference : str, optional
        Camera whose view must be present (default: the rig's first camera).

    Returns
    -------
    GridCheck
    """
    ref = reference or rig.names[0]
    first = next(iter(views.values()))
    cols, rows = first.inner_corners
    span = int(span or min(10, cols - 1, rows - 1))
    if span < 1 or span > min(cols, rows) - 1:
        raise CalibrationError(f"span {span} squares does not fit a {cols}x{rows} board")
    # A in the middle of the board's first row band, B along the columns, C along the rows
    i0 = (cols - 1 - span) // 2
    j0 = (rows - 1 - span) // 2
    idx = {"A": j0 * cols + i0, "B": j0 * cols + i0 + span, "C": (j0 + span) * cols + i0,
           "D": (j0 + span) * cols + i0 + span}
    segs = (("A", "B"), ("A", "C"), ("A", "D"))
    actual = 1000 * square_m * span * np.array([1.0, 1.0, np.sqrt(2.0)])
    gi, gj = np.meshgrid(np.arange(cols), np.arange(rows))
    gi, gj = gi.ravel(), gj.ravel()
    seg_a = np.concatenate([np.flatnonzero(gi + span < cols), np.flatnonzero(gj + span < rows)])
    seg_b = np.concatenate([np.flatnonzero(gi + span < cols) + span, np.flatnonzero(gj + span < rows) + span * cols])
    seg_len = 1000 * square_m * span
    names, meas, pts, segerr = [], [], [], []
    nv = len(first.names)
    for k in range(nv):
        if ref not in views or not np.all(np.isfinite(views[ref].corners[k])):
            continue
        seen = [c for c in views if c in rig.names and np.all(np.isfinite(views[c].corners[k]))]
        if len(seen) < 2:
            continue
        px = _order_like_reference(rig, {c: views[c] for c in seen}, ref, k)
        X = triangulate(rig, px)
        names.append(first.names[k])
        pts.append(X)
        meas.append([1000 * np.linalg.norm(X[idx[a]] - X[idx[b]]) for a, b in segs])
        segerr.append(100 * (1000 * np.linalg.norm(X[seg_a] - X[seg_b], axis=1) - seg_len) / seg_len)
    if not names:
        raise CalibrationError("grid_distance_check: no view is seen by the reference camera and another camera")
    meas = np.array(meas)
    return GridCheck(tuple(names), ("AB", "AC", "AD"), actual, meas, 100 * np.abs(meas - actual) / actual,
                     idx, np.array(pts), np.array(segerr))
