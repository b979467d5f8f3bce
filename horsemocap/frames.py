"""The motion reference frame (thesis section 5.3) and the free-fall check (8.3).

Thesis section 5.3, Appendix A step 7
(``convert_smoothed_camera_to_motion_reference_frame.m``):

- ``u1``: unit vector of the net displacement of a chosen marker over one or
  two periods of the gait, eq. 5.6 ``u1 = (x(T) - x(0)) / |x(T) - x(0)|`` or
  eq. 5.7 with ``2T``: the x-motion direction.
- ``u2e``: the gravity direction estimated from a plumb with two markers,
  from the upper marker (tail) to the lower one (tip): *downward*.
- eq. 5.8 ``u3 = u1 x u2e / |u1 x u2e|`` (z-motion), eq. 5.9
  ``u2 = u3 x u1`` (the corrected gravity, y-motion, downward).
- eq. 5.10 ``R_CM = [u1 | u2 | u3]``, eq. 5.11 ``x_C = R_CM x_M``, eq. 5.12
  ``x_M = R_CM^-1 x_C = R_CM^T x_C``. The origin stays at the reference
  camera's centre (the thesis rotates only).
- eq. 5.13 ``t = (k - 1)/fps`` with 1-based frames ``k``; here frames are
  0-based, so ``t = k/fps``.

The thesis user typed the period (``period = 18`` frames for Horse 2 canter);
:func:`estimate_period` finds it from the data.

The free-fall check of section 8.3 (:func:`free_fall_g`): the ball's position
projected on gravity, a quadratic fitted against time, ``g`` = twice the
quadratic coefficient (thesis: 9.5 m/s^2, 3.6 % off).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

__all__ = [
    "MotionFrame",
    "STANDARD_GRAVITY",
    "estimate_period",
    "stride_period",
    "HORSE_STRIDE_HZ",
    "autocorrelation",
    "gravity_from_plumb",
    "motion_frame",
    "motion_frame_from_record",
    "to_motion_frame",
    "time_axis",
    "free_fall_g",
    "angle_deg",
    "rmse_per_axis",
]

STANDARD_GRAVITY = 9.81  # m/s^2, the value the thesis compares with (section 8.3)


@dataclass(frozen=True)
class MotionFrame:
    """The motion reference frame of thesis section 5.3.

    Attributes
    ----------
    axes : ndarray, shape (3, 3)
        Rows ``u1`` (x-motion), ``u2`` (y-motion, gravity, down), ``u3``
        (z-motion) in world (reference camera) coordinates: ``axes = R_CM^T``
        (eq. 5.10), so ``x_M = axes @ (x_C - origin)`` (eq. 5.12).
    origin : ndarray, shape (3,)
        Origin in world coordinates (the reference camera's centre, zeros).
    period_frames : float
        Period ``T`` in frames used for ``u1``.
    marker : int
        Marker whose net displacement defines ``u1``.
    n_periods : int
        1 (eq. 5.6) or 2 (eq. 5.7).
    gravity_estimated : ndarray, shape (3,)
        ``u2e`` from the plumb.
    gravity_correction_deg : float
        Angle between ``u2e`` and the corrected ``u2``.

    Examples
    --------
    See :func:`motion_frame`.
    """

    axes: np.ndarray
    origin: np.ndarray
    period_frames: float
    marker: int
    n_periods: int
    gravity_estimated: np.ndarray
    gravity_correction_deg: float

    @property
    def R_CM(self) -> np.ndarray:
        """``R_CM = [u1 | u2 | u3]`` (eq. 5.10)."""
        return self.axes.T

    @property
    def x_direction(self) -> np.ndarray:
        return self.axes[0]

    @property
    def gravity(self) -> np.ndarray:
        """The corrected gravity direction ``u2`` (down)."""
        return self.axes[1]


def angle_deg(a, b) -> float:
    """Angle in degrees between two vectors.

    Examples
    --------
    >>> angle_deg([1, 0, 0], [0, 1, 0]), round(angle_deg([1, 0, 0], [1, 1, 0]), 6)
    (90.0, 45.0)
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _unit(v, what):
    v = np.asarray(v, float)
    nrm = np.linalg.norm(v)
    if not np.isfinite(nrm) or nrm < 1e-12:
        raise ValueError(f"{what}: zero or undefined vector {v.tolist()}; cannot normalise")
    return v / nrm


# ---------------------------------------------------------------------------
# period
# ---------------------------------------------------------------------------

def autocorrelation(signal, max_lag: int | None = None) -> np.ndarray:
    """Normalised autocorrelation of one or several detrended signals.

    Parameters
    ----------
    signal : array_like, shape (n,) or (n, k)
        Time on axis 0; each column has its mean and linear trend removed.
    max_lag : int, optional
        Largest lag (default ``n - 1``).

    Returns
    -------
    ndarray, shape (max_lag + 1,)
        ``r[L] = sum_t s[t] s[t+L] / sum_t s[t]^2`` summed over columns, with
        the overlap-length correction ``n / (n - L)`` (unbiased estimate), so
        a periodic signal scores close to 1 at its period even when the
        record holds only one or two periods.

    Examples
    --------
    >>> import numpy as np
    >>> r = autocorrelation(np.sin(2 * np.pi * np.arange(90) / 18))
    >>> round(float(r[18]), 3), round(float(r[9]), 3)       # one period, half a period
    (0.988, -1.0)
    """
    s = np.asarray(signal, float)
    if s.ndim == 1:
        s = s[:, None]
    s = s[:, np.all(np.isfinite(s), axis=0)]
    n = s.shape[0]
    if n < 4 or s.shape[1] == 0:
        raise ValueError(f"autocorrelation: need at least 4 finite samples per column, got shape {np.shape(signal)}")
    t = np.arange(n, dtype=float)
    A = np.stack([np.ones(n), t], axis=1)
    coef, *_ = np.linalg.lstsq(A, s, rcond=None)
    raw = s - s.mean(axis=0)
    s = s - A @ coef
    max_lag = n - 1 if max_lag is None else int(min(max_lag, n - 1))
    energy = np.sum(s * s)
    if energy <= 1e-20 * max(float(np.sum(raw * raw)), 1e-300):
        raise ValueError("autocorrelation: the signal is constant (or a straight line): no period to find")
    r = np.empty(max_lag + 1)
    for L in range(max_lag + 1):
        r[L] = np.sum(s[: n - L] * s[L:]) / energy * n / (n - L)
    return r


#: A horse's stride rate (Hz): the slowest walk to a racing gallop (also the ok range of
#: :func:`horsemocap.quality.check_stride_frequency`).
HORSE_STRIDE_HZ = (0.7, 2.7)


def estimate_period(signal_or_points, fps: float | None = None, gravity=None,
                    min_period: float = 3.0, min_overlap: float = 0.4, refine: bool = True,
                    harmonics: int = 2, max_rate_hz: float | None = None) -> float:
    """Period of the gait in frames, from the data (thesis: typed by the user).

    The vertical motion of the markers is periodic (thesis 5.3, 5.5.2.2). The
    period is the lag of the first prominent peak (at least 0.8 of the highest
    one, so not a multiple of the period) of the autocorrelation of the
    detrended signal, refined by a parabola through the peak and its two
    neighbours, then by a least-squares Fourier fit (``refine``).

    Parameters
    ----------
    signal_or_points : array_like
        ``(n,)`` a signal (e.g. a marker's vertical coordinate), ``(n, k)``
        several signals, ``(n, 3)`` / ``(n, m, 3)`` positions. Positions are
        projected on ``gravity`` if given; otherwise all their detrended
        coordinates are used together (the x-motion trend is removed by the
        detrending, the periodic parts add up).
    fps : float, optional
        Frames per second; only checked (the result is in frames).
    gravity : array_like, shape (3,), optional
        Direction to project positions on.
    min_period : float
        Smallest period considered (frames).
    min_overlap : float
        Smallest fraction of the record that must overlap at the chosen lag
        (the record must hold at least ``1/(1 - min_overlap)`` ... periods;
        0.4 admits a lag of up to 60 % of the record, so 2 periods).
    refine : bool
        Refine the autocorrelation lag by a least-squares fit of a linear
        trend plus a Fourier series (``harmonics`` terms) over ``[0.85, 1.15]``
        times the lag (the autocorrelation of a short record is biased).
    harmonics : int
        Harmonics in the refinement model.
    max_rate_hz : float, optional
        The fastest the motion can repeat (with ``fps``; a horse's stride:
        ``HORSE_STRIDE_HZ[1]``). A period found shorter than ``1 / max_rate_hz``
        is a part of the real one (a trot's two alike bounces per stride: its
        vertical motion repeats at twice the stride rate): the period is then
        searched again among lags of at least ``fps / max_rate_hz`` frames, and
        the shorter one kept only when the record is too short to show a longer
        one.

    Returns
    -------
    float
        Period in frames (divide by ``fps`` for seconds).

    Examples
    --------
    >>> import numpy as np
    >>> bounce = np.sin(2 * np.pi * np.arange(90) / 18)      # period 18 frames
    >>> round(estimate_period(bounce, fps=30.0), 3)
    18.0
    """
    return _estimate_period(signal_or_points, fps, gravity, min_period, min_overlap, refine, harmonics,
                            max_rate_hz)[0]


def _estimate_period(signal_or_points, fps=None, gravity=None, min_period: float = 3.0, min_overlap: float = 0.4,
                     refine: bool = True, harmonics: int = 2, max_rate_hz: float | None = None) -> tuple:
    """:func:`estimate_period` and the faster period it searched past (or None): see :func:`stride_period`."""
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    a = np.asarray(signal_or_points, float)
    if a.ndim == 3:
        if a.shape[-1] != 3:
            raise ValueError(f"positions: expected shape (frames, markers, 3), got {a.shape}")
        sig = a @ _unit(gravity, "gravity") if gravity is not None else a.reshape(a.shape[0], -1)
    elif a.ndim == 2 and gravity is not None:
        if a.shape[-1] != 3:
            raise ValueError(f"positions: expected shape (frames, 3) with gravity, got {a.shape}")
        sig = a @ _unit(gravity, "gravity")
    elif a.ndim in (1, 2):
        sig = a
    else:
        raise ValueError(f"expected a signal (n,) / (n, k) or positions (n, m, 3), got shape {a.shape}")
    if sig.ndim == 1:
        sig = sig[:, None]
    n = sig.shape[0]
    max_lag = int(np.floor(n * (1.0 - min_overlap)))
    if max_lag < min_period + 1:
        raise ValueError(f"estimate_period: {n} frames are too few to find a period of at least {min_period} frames")
    r = autocorrelation(sig, max_lag)
    # candidate peaks: local maxima beyond the first zero crossing (the main lobe)
    below = np.flatnonzero(r < 0)
    start = max(int(below[0]) if below.size else 1, int(np.ceil(min_period)))
    peaks = [L for L in range(max(start, 1), max_lag) if r[L] >= r[L - 1] and r[L] >= r[L + 1]]
    if not peaks:
        # the record may end before the first full peak: use the maximum beyond the main lobe
        L = int(np.argmax(r[start:max_lag + 1])) + start
        if L >= max_lag or r[L] <= 0:
            raise ValueError("estimate_period: no periodic component found (no autocorrelation peak); "
                             "give the period explicitly")
        peaks = [L]
    best = max(r[L] for L in peaks)
    L = next((L for L in peaks if r[L] >= 0.8 * best), None)  # first prominent peak (not a harmonic of it)
    if L is None or best <= 0:          # every peak negative: nothing repeats
        raise ValueError("estimate_period: no periodic component found (no positive autocorrelation peak); "
                         "give the period explicitly")
    lag = float(L)
    if 0 < L < r.size - 1:
        y0, y1, y2 = r[L - 1], r[L], r[L + 1]
        den = y0 - 2 * y1 + y2
        shift = 0.5 * (y0 - y2) / den if den < 0 else 0.0
        lag = float(L + np.clip(shift, -0.5, 0.5))
    period = lag if not refine else _refine_period(sig, lag, harmonics)
    if max_rate_hz is not None and fps is not None and fps / period > max_rate_hz:
        try:
            longer = estimate_period(sig, fps, min_period=max(min_period, fps / max_rate_hz), min_overlap=min_overlap,
                                     refine=refine, harmonics=harmonics)
        except ValueError:      # the record cannot show a longer period: the faster one stays (and is flagged)
            return period, None
        return longer, (period if abs(longer - period) > 0.5 else None)
    return period, None


def stride_period(points, fps: float, gravity=None, max_rate_hz: float = HORSE_STRIDE_HZ[1]) -> tuple:
    """The gait's period (frames) of :func:`estimate_period` with a horse's stride as the bound, and the
    faster period the record also showed.

    Returns
    -------
    period : float
        ``estimate_period(points, fps, gravity=gravity, max_rate_hz=max_rate_hz)``.
    faster : float or None
        The period first found when it was faster than ``max_rate_hz`` and a longer one was taken (more
        than half a frame apart), else None: the record also repeats that fast (a trot's two alike beats).

    Examples
    --------
    A record that repeats every 9 frames at 30 fps (3.3 Hz, faster than a horse
    strides) is taken at 18 frames, and the 9 frames reported:

    >>> import numpy as np
    >>> period, faster = stride_period(np.sin(2 * np.pi * np.arange(90) / 9), fps=30.0)
    >>> round(period, 3), round(faster, 3)
    (18.0, 9.0)
    """
    return _estimate_period(points, fps, gravity, max_rate_hz=max_rate_hz)


def _fourier_sse(sig: np.ndarray, period: float, harmonics: int) -> float:
    n = sig.shape[0]
    t = np.arange(n, dtype=float)
    cols = [np.ones(n), t]
    for h in range(1, harmonics + 1):
        w = 2 * np.pi * h / period
        cols += [np.cos(w * t), np.sin(w * t)]
    A = np.stack(cols, axis=1)
    coef, *_ = np.linalg.lstsq(A, sig, rcond=None)
    r = sig - A @ coef
    return float(np.sum(r * r))


def _refine_period(sig: np.ndarray, lag: float, harmonics: int) -> float:
    """Least-squares refinement of the period near the autocorrelation peak.

    Minimises over ``T`` in ``[0.85, 1.15] x lag`` the residual of a linear
    trend plus a Fourier series of ``harmonics`` terms with fundamental ``T``
    (all columns together). The autocorrelation of a record holding one or
    two periods is biased by a fraction of a frame; this fit is not.
    """
    sig = sig[:, np.all(np.isfinite(sig), axis=0)]
    if sig.shape[0] < 2 * harmonics + 4:
        return lag
    res = minimize_scalar(lambda T: _fourier_sse(sig, T, harmonics), bounds=(0.85 * lag, 1.15 * lag),
                          method="bounded", options={"xatol": 1e-4})
    return float(res.x) if res.success else lag


# ---------------------------------------------------------------------------
# gravity and the motion frame
# ---------------------------------------------------------------------------

def gravity_from_plumb(tip_world, tail_world) -> np.ndarray:
    """Estimated gravity direction ``u2e`` from the plumb's two markers (thesis 5.3).

    Parameters
    ----------
    tip_world : array_like, shape (3,) or (n, 3)
        The LOWER marker (tip of the gravity vector), world frame.
    tail_world : array_like, shape (3,) or (n, 3)
        The UPPER marker (tail), world frame. Several observations are averaged.

    Returns
    -------
    ndarray, shape (3,)
        Unit vector from tail to tip: pointing DOWN (y-motion direction).

    Examples
    --------
    >>> gravity_from_plumb(tip_world=[0.0, 2.0, 0.0], tail_world=[0.0, 0.0, 0.0])
    array([0., 1., 0.])
    """
    tip = np.asarray(tip_world, float).reshape(-1, 3)
    tail = np.asarray(tail_world, float).reshape(-1, 3)
    if tip.shape != tail.shape:
        raise ValueError(f"gravity_from_plumb: tip {tip.shape} and tail {tail.shape} differ in shape")
    ok = np.all(np.isfinite(tip), axis=1) & np.all(np.isfinite(tail), axis=1)
    if not ok.any():
        raise ValueError("gravity_from_plumb: no finite tip/tail pair (the plumb markers were not triangulated)")
    d = (tip[ok] - tail[ok]).mean(axis=0)
    return _unit(d, "gravity_from_plumb (tip - tail)")


def _position_at(track: np.ndarray, frame: float) -> np.ndarray:
    """Linear interpolation of a (n, 3) track at a fractional 0-based frame."""
    k0 = int(np.floor(frame))
    f = frame - k0
    if f < 1e-12:
        return track[k0]
    return (1 - f) * track[k0] + f * track[k0 + 1]


def motion_frame(points, gravity, marker: int = 0, period: float | None = None,
                 n_periods: int | None = None, fps: float | None = None) -> MotionFrame:
    """The motion reference frame (thesis eq. 5.6-5.12).

    Parameters
    ----------
    points : array_like, shape (n_frames, n_markers, 3)
        Smoothed marker positions in the world (camera) frame, ``CM_L``.
    gravity : array_like, shape (3,)
        Estimated gravity direction ``u2e`` (down), from :func:`gravity_from_plumb`.
    marker : int
        The marker whose net displacement defines ``u1`` (thesis: typed 1, 2 or 3; 0-based here).
    period : float, optional
        ``T`` in frames; default :func:`estimate_period` on the vertical
        component of all markers. May be fractional (positions are
        interpolated linearly between frames).
    n_periods : {1, 2}, optional
        Eq. 5.6 (one period) or 5.7 (two). Default: 2 if the record holds
        two periods (frame ``2T`` exists), else 1.
    fps : float, optional
        Passed to :func:`estimate_period` (checks only).

    Returns
    -------
    MotionFrame

    Examples
    --------
    >>> import numpy as np
    >>> frames = np.arange(90)                     # 3 s at 30 fps
    >>> points = np.zeros((90, 3, 3))              # three markers moving along x at 5 m/s, bouncing with 18 frames' period
    >>> for m in range(3):
    ...     points[:, m, 0] = 5.0 * frames / 30.0 + 0.3 * m
    ...     points[:, m, 1] = 0.05 * np.sin(2 * np.pi * frames / 18)
    ...     points[:, m, 2] = 4.0
    >>> frame = motion_frame(points, gravity=[0.0, 1.0, 0.0])
    >>> round(frame.period_frames, 3), frame.n_periods
    (18.0, 2)
    >>> bool(np.allclose(frame.axes, np.eye(3), atol=1e-6))     # x along the travel, y down, z across
    True
    """
    p = np.asarray(points, float)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"points: expected shape (frames, markers, 3), got {p.shape}")
    n, m, _ = p.shape
    if not (0 <= int(marker) < m):
        raise ValueError(f"marker {marker} out of range: the points hold {m} markers (0-based)")
    marker = int(marker)
    u2e = _unit(gravity, "gravity")
    if period is None:
        period = estimate_period(p, fps, gravity=u2e)
    period = float(period)
    if not (period > 0):
        raise ValueError(f"period must be positive (frames), got {period}")
    last = n - 1
    if n_periods is None:
        n_periods = 2 if 2 * period <= last + 1e-9 else 1
    if n_periods not in (1, 2):
        raise ValueError(f"n_periods must be 1 (eq. 5.6) or 2 (eq. 5.7), got {n_periods}")
    end = n_periods * period
    if end > last + 1e-9:
        raise ValueError(
            f"motion_frame: {n_periods} period(s) of {period:.2f} frames need frame {end:.2f}, "
            f"but the record ends at frame {last} (0-based); use n_periods=1 or a shorter period")
    track = p[:, marker]
    end = min(end, last)
    if not np.all(np.isfinite(track[[0, int(np.floor(end)), min(int(np.ceil(end)), last)]])):
        raise ValueError(f"motion_frame: marker {marker} is NaN at frame 0 or near frame {end:.2f}; "
                         "choose another marker or smooth with nan='omit' first")
    u1 = _unit(_position_at(track, end) - track[0], f"net displacement of marker {marker}")  # eq. 5.6/5.7
    u3 = _unit(np.cross(u1, u2e), "u1 x u2e (x-motion parallel to gravity?)")  # eq. 5.8
    u2 = np.cross(u3, u1)  # eq. 5.9
    axes = np.stack([u1, u2, u3])
    return MotionFrame(axes=axes, origin=np.zeros(3), period_frames=period, marker=marker,
                       n_periods=int(n_periods), gravity_estimated=u2e,
                       gravity_correction_deg=angle_deg(u2, u2e))


def motion_frame_from_record(points, gravity, period: float | None = None) -> MotionFrame:
    """The motion reference frame without a period (not in the thesis).

    ``u1`` is the net displacement of the markers' centroid from the first to
    the last frame in which every marker is finite, made orthogonal to the
    plumb's gravity ``u2e``; ``u2 = u2e`` (down) and ``u3 = u1 x u2``. The
    thesis (eq. 5.6/5.7, :func:`motion_frame`) takes the displacement over
    exactly one or two periods so that the periodic sway cancels; over a
    whole record the sway left over is at most its amplitude against the
    whole travel (e.g. 20 mm over 5 m: 0.2 deg), and no period is needed, so
    a transition, a single step or any non-periodic record has a frame too.

    Parameters
    ----------
    points : (n, m, 3)
        Marker positions (world frame), NaN allowed.
    gravity : (3,)
        ``u2e`` (down) from :func:`gravity_from_plumb`.
    period : float, optional
        Kept in :attr:`MotionFrame.period_frames` (NaN if not known); not used.

    Returns
    -------
    MotionFrame
        ``marker = -1`` (the centroid), ``n_periods = 0``.

    Examples
    --------
    >>> import numpy as np
    >>> frames = np.arange(90)                     # 3 s at 30 fps
    >>> points = np.zeros((90, 3, 3))              # three markers moving along x at 5 m/s, bouncing with 18 frames' period
    >>> for m in range(3):
    ...     points[:, m, 0] = 5.0 * frames / 30.0 + 0.3 * m
    ...     points[:, m, 1] = 0.05 * np.sin(2 * np.pi * frames / 18)
    ...     points[:, m, 2] = 4.0
    >>> frame = motion_frame_from_record(points, gravity=[0.0, 1.0, 0.0])
    >>> bool(np.allclose(frame.axes, np.eye(3))), frame.marker, frame.n_periods
    (True, -1, 0)
    """
    p = np.asarray(points, float)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"points: expected shape (frames, markers, 3), got {p.shape}")
    u2 = _unit(gravity, "gravity")
    ok = np.flatnonzero(np.all(np.isfinite(p), axis=(1, 2)))
    if ok.size < 2:
        raise ValueError("motion_frame_from_record: fewer than 2 frames with every marker finite")
    c = p[ok].mean(axis=1)
    d = c[-1] - c[0]
    d_h = d - (d @ u2) * u2
    if np.linalg.norm(d_h) < 1e-6 * max(np.linalg.norm(d), 1e-300) or np.linalg.norm(d_h) < 1e-9:
        raise ValueError(f"motion_frame_from_record: the markers' net displacement {d.round(4).tolist()} m "
                         "has no horizontal part; the direction of travel is undefined")
    u1 = _unit(d_h, "horizontal net displacement")
    u3 = np.cross(u1, u2)
    axes = np.stack([u1, u2, u3])
    return MotionFrame(axes=axes, origin=np.zeros(3), period_frames=float("nan") if period is None else float(period),
                       marker=-1, n_periods=0, gravity_estimated=u2, gravity_correction_deg=0.0)


def to_motion_frame(points, frame: MotionFrame) -> np.ndarray:
    """Positions in the motion frame, ``x_M = R_CM^T (x_C - origin)`` (eq. 5.12).

    ``points`` is any array of shape ``(..., 3)`` in world coordinates
    (thesis ``CM_L`` -> ``MM``).

    Examples
    --------
    >>> import numpy as np
    >>> frames = np.arange(90)                     # 3 s at 30 fps
    >>> points = np.zeros((90, 3, 3))              # three markers moving along x at 5 m/s, bouncing with 18 frames' period
    >>> for m in range(3):
    ...     points[:, m, 0] = 5.0 * frames / 30.0 + 0.3 * m
    ...     points[:, m, 1] = 0.05 * np.sin(2 * np.pi * frames / 18)
    ...     points[:, m, 2] = 4.0
    >>> frame = motion_frame_from_record(points, gravity=[0.0, 1.0, 0.0])
    >>> to_motion_frame(np.array([1.0, 2.0, 3.0]), frame).round(6)
    array([1., 2., 3.])
    """
    p = np.asarray(points, float)
    if p.shape[-1] != 3:
        raise ValueError(f"points: last axis must hold x, y, z; got shape {p.shape}")
    return (p - frame.origin) @ frame.axes.T


def time_axis(n: int, fps: float) -> np.ndarray:
    """Time of each frame, eq. 5.13 ``t = (k - 1)/fps`` with 1-based ``k``: ``t = k/fps`` 0-based.

    Examples
    --------
    >>> time_axis(4, fps=30.0).round(4)
    array([0.    , 0.0333, 0.0667, 0.1   ])
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    return np.arange(int(n)) / float(fps)


def rmse_per_axis(estimate, truth) -> np.ndarray:
    """Root-mean-square error per coordinate (last axis) over the finite entries.

    Examples
    --------
    >>> import numpy as np
    >>> rmse_per_axis(np.array([[1.0, 0.0, 0.0], [1.0, 0.0, np.nan]]), np.zeros((2, 3)))
    array([1., 0., 0.])
    """
    e = np.asarray(estimate, float) - np.asarray(truth, float)
    e = e.reshape(-1, e.shape[-1])
    ok = np.all(np.isfinite(e), axis=1)
    if not ok.any():
        return np.full(e.shape[-1], np.nan)
    return np.sqrt(np.mean(e[ok] ** 2, axis=0))


# ---------------------------------------------------------------------------
# free fall (section 8.3)
# ---------------------------------------------------------------------------

def free_fall_g(points_world, gravity, fps: float, g_reference: float = STANDARD_GRAVITY) -> dict:
    """Gravitational acceleration from a falling ball (thesis section 8.3, Figure 8.5).

    The ball's position is projected on the gravity direction (``CM_g``,
    positive downward), a quadratic ``s(t) = c0 + c1 t + c2 t^2`` is fitted
    by least squares, and ``g = 2 c2`` (velocity ``c1 + 2 c2 t``,
    acceleration ``2 c2``).

    Parameters
    ----------
    points_world : array_like, shape (n, 3)
        Ball centre per frame, world frame; NaN frames are left out (counted
        in ``n_missing``).
    gravity : array_like, shape (3,)
        Gravity direction (down).
    fps : float
        Frames per second (time ``t = k/fps``, eq. 5.13).
    g_reference : float
        The value compared with (thesis: 9.81 m/s^2).

    Returns
    -------
    dict
        ``g`` (m/s^2), ``error_pct`` (``100 |g - g_ref| / g_ref``), ``g_std``
        (standard error from the fit), ``coefficients`` (c0, c1, c2),
        ``t`` (s), ``position`` (m, along gravity), ``fitted``, ``velocity``,
        ``acceleration`` (of the fit, on ``t``), ``rmse`` (m), ``n_used``,
        ``n_missing``.

    Examples
    --------
    A ball dropped in front of the cameras, half a second at 30 fps:

    >>> import numpy as np
    >>> t = np.arange(15) / 30.0
    >>> fall = np.stack([np.zeros(15), 0.5 * 9.81 * t ** 2, np.full(15, 3.0)], axis=1)
    >>> result = free_fall_g(fall, gravity=[0.0, 1.0, 0.0], fps=30.0)
    >>> round(result["g"], 6), round(result["error_pct"], 6), result["n_used"]
    (9.81, 0.0, 15)
    """
    p = np.asarray(points_world, float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points_world: expected shape (frames, 3), got {p.shape}")
    u = _unit(gravity, "gravity")
    t = time_axis(p.shape[0], fps)
    s = p @ u
    ok = np.isfinite(s)
    if ok.sum() < 4:
        raise ValueError(f"free_fall_g: need at least 4 frames with the ball triangulated, got {int(ok.sum())}")
    A = np.stack([np.ones(ok.sum()), t[ok], t[ok] ** 2], axis=1)
    coef, *_ = np.linalg.lstsq(A, s[ok], rcond=None)
    res = s[ok] - A @ coef
    dof = max(int(ok.sum()) - 3, 1)
    sigma2 = float(res @ res) / dof
    cov = sigma2 * np.linalg.inv(A.T @ A)
    g = 2.0 * coef[2]
    fitted = coef[0] + coef[1] * t + coef[2] * t**2
    return {
        "g": float(g),
        "error_pct": float(100.0 * abs(g - g_reference) / g_reference),
        "g_std": float(2.0 * np.sqrt(cov[2, 2])),
        "g_reference": float(g_reference),
        "coefficients": coef,
        "t": t,
        "position": s,
        "fitted": fitted,
        "velocity": coef[1] + 2.0 * coef[2] * t,
        "acceleration": np.full_like(t, g),
        "rmse": float(np.sqrt(np.mean(res**2))),
        "n_used": int(ok.sum()),
        "n_missing": int((~ok).sum()),
    }
