"""Short gaps of the 3D marker positions bridged by interpolation.

A marker hidden in every camera for a few frames (a hand, a rein) has no 3D
position there; :func:`bridge_gaps` fills a gap of at most ``max_gap`` frames
by a cubic spline through the measured frames on both sides (the analysis
marks those frames ``interpolated``); :func:`default_max_gap` is 0.1 s of
frames.

Example
-------
>>> import numpy as np
>>> t = np.arange(20.0)
>>> points = np.stack([t, t ** 2, np.zeros(20)], axis=1)[:, None]       # (20, 1, 3)
>>> points[8:10] = np.nan
>>> filled, interpolated = bridge_gaps(points, default_max_gap(30.0))
>>> np.flatnonzero(interpolated[:, 0]).tolist(), bool(np.allclose(filled, np.stack([t, t ** 2, 0 * t], 1)[:, None]))
([8, 9], True)
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["default_max_gap", "bridge_gaps"]


def default_max_gap(fps: float) -> int:
    """Longest gap bridged by interpolation: 0.1 s of frames, at least 2 (a few frames)."""
    return max(2, int(round(0.1 * float(fps))))


def bridge_gaps(points: np.ndarray, max_gap: int, context: int = 4):
    """Fill short runs of missing 3D positions by cubic interpolation.

    A run of at most ``max_gap`` NaN frames of one marker, with at least two
    measured frames on each side, is filled by a cubic spline through up to
    ``context`` measured frames on each side, within ``2 * context`` frames of
    the gap; longer runs and the record's ends stay NaN.

    Parameters
    ----------
    points : (n, M, 3)
    max_gap : int
    context : int

    Returns
    -------
    filled : (n, M, 3)
    interpolated : (n, M) bool
    """
    out = np.array(points, float, copy=True)
    n, M = out.shape[:2]
    interp = np.zeros((n, M), bool)
    for m in range(M):
        ok = np.all(np.isfinite(out[:, m]), axis=1)
        k = 0
        while k < n:
            if ok[k]:
                k += 1
                continue
            a = k
            while k < n and not ok[k]:
                k += 1
            b = k                                           # missing a..b-1
            if b - a > max_gap:
                continue
            left = np.flatnonzero(ok[:a])[-context:]
            right = np.flatnonzero(ok[b:])[:context] + b
            left = left[left >= a - 2 * context]              # anchors near the gap only (not across
            right = right[right < b + 2 * context]            # another gap, far from this one)
            if len(left) < 2 or len(right) < 2:
                continue
            t = np.concatenate([left, right])
            cs = CubicSpline(t, out[t, m], axis=0)
            out[a:b, m] = cs(np.arange(a, b))
            interp[a:b, m] = True
    return out, interp
