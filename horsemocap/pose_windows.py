"""A long pass's pose trajectory made of overlapping windows, evaluated like one fitted whole.

A quintic smoothing spline has at most :data:`horsemocap.splines.MAX_BASIS`
basis functions, so a pose trajectory fitted whole over more than
:data:`horsemocap.streaming.WHOLE_RECORD_FRAMES` frames gets a knot only every
few frames and loses the fast part of its motion (the saddle's acceleration)
whatever its smoothing. :func:`windowed_pose_trajectory` smooths such a record
as the ``kinematics`` command does (:mod:`horsemocap.streaming`): the smoothing
settled once on a representative stretch, the windows fitted with it, and
gives a :class:`WindowedPoseTrajectory` with the methods of
:class:`horsemocap.pose.PoseTrajectory` that the rigid-body step and its
consumers call (``point``, ``points``, ``omega``, ``alpha``, ``rotation``,
``centre``, ``smoothing``, ``smoothing_choice``, ``windows``): each time is
evaluated in the window whose core holds it, and across a cut the two windows'
values are blended over :func:`horsemocap.streaming.blend_band` frames with the
raised cosine of :func:`horsemocap.streaming.windowed_kinematics`, so at the
frames both give the same kinematics.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from . import pose, streaming
from .params import PoseParams

__all__ = ["PoseWindow", "PoseWindows", "WindowedPoseTrajectory", "windowed_pose_trajectory"]


@dataclass(frozen=True)
class PoseWindow:
    """One window: it fits frames ``lo .. hi - 1`` and gives the values of ``core_lo .. core_hi - 1``
    (blended with its neighbours' near the cuts); ``times`` its own time axis from frame ``lo``
    (:func:`horsemocap.streaming.window_times`); ``trajectory`` its fit, or None and ``why``."""

    lo: int
    hi: int
    core_lo: int
    core_hi: int
    times: np.ndarray
    trajectory: pose.PoseTrajectory | None
    why: str = ""


@dataclass(frozen=True)
class PoseWindows:
    """How a long pass was smoothed in windows: ``frames`` of the pose record, ``plan`` (one
    ``(lo, hi, core_lo, core_hi)`` per window, :func:`horsemocap.streaming.window_plan`),
    ``window_frames`` (a core at most), ``margin_frames``, ``band_frames`` (blended on each side of
    a cut) and ``settled_on_s`` (the times of the representative stretch's first and last frames, on the
    record's own time axis: analyze's ``time_s``, 0 at the first analysed frame)."""

    frames: int
    plan: tuple
    window_frames: int
    margin_frames: int
    band_frames: int
    settled_on_s: tuple

    def to_dict(self) -> dict:
        """The record for ``analysis.json`` (counts only; the plan follows from them).

        Examples
        --------
        >>> PoseWindows(3000, ((0, 1150, 0, 1000),), 1000, 150, 75, (0.0, 29.99)).to_dict()["count"]
        1
        """
        return {"frames": self.frames, "count": len(self.plan), "window_frames": self.window_frames,
                "margin_frames": self.margin_frames, "blend_frames": 2 * self.band_frames,
                "settled_on_s": [round(float(v), 6) for v in self.settled_on_s]}

    def text(self) -> str:
        """The progress line's words.

        Examples
        --------
        >>> PoseWindows(3000, ((0, 1150, 0, 1000),) * 3, 1000, 150, 75, (0.0, 29.99)).text()
        '3000 frames smoothed in 3 windows of 1000 frames (margin 150; smoothing settled on 0..29.99 s)'
        """
        return (f"{self.frames} frames smoothed in {len(self.plan)} windows of {self.window_frames} frames "
                f"(margin {self.margin_frames}; smoothing settled on {self.settled_on_s[0]:.6g}.."
                f"{self.settled_on_s[1]:.6g} s)")


@dataclass(frozen=True)
class WindowedPoseTrajectory:
    """A pose trajectory made of windows (:func:`windowed_pose_trajectory`).

    Attributes
    ----------
    t : (n,)
        The pose record's times.
    pieces : tuple of PoseWindow
        The windows in order.
    settled : horsemocap.streaming.SettledSmoothing
        The smoothing every window ran.
    windows : PoseWindows
        The plan, in words and for ``analysis.json``.
    registration : horsemocap.pose.PoseRegistration
        The whole record's registration.
    model_centroid : (3,)
        Mean of the model: body points are given relative to it.
    valid, reason : (n,)
        Frames with a value, and why a frame has none (or that it bridges a gap), as the window
        whose values a frame takes says.
    """

    t: np.ndarray
    pieces: tuple
    settled: streaming.SettledSmoothing
    windows: PoseWindows
    registration: pose.PoseRegistration
    model_centroid: np.ndarray
    valid: np.ndarray
    reason: np.ndarray

    def _middle(self) -> pose.PoseTrajectory | None:
        """The fit of the window whose core holds the record's middle frame (None: it has none)."""
        mid = self.t.size // 2
        return next(w.trajectory for w in self.pieces if w.core_lo <= mid < w.core_hi)

    @property
    def smoothing(self) -> dict:
        """Per component, the smoothing of the window at the record's middle (a window's basis is fine
        enough for the motion; the representative stretch's, fitted whole, may not be), or where that window
        has no fit the representative stretch's. What :func:`horsemocap.pose.settle_pose_smoothing` reuses
        on a long recording's other passes."""
        middle = self._middle()
        return self.settled.info if middle is None else middle.smoothing

    @property
    def smoothing_choice(self) -> dict | None:
        """What ``smoothing="auto"`` ran and why, settled on the representative stretch (None: named); its
        ``half_gain_hz`` that of the window at the record's middle (:attr:`smoothing`)."""
        choice, middle = self.settled.choice, self._middle()
        if choice is None or middle is None:
            return choice
        return {**choice, "half_gain_hz": middle.half_gain_hz}

    def _position(self, t) -> np.ndarray:
        """Each time's position among the record's frames (fractional between two; NaN outside the record,
        whose values are then NaN as a whole fit's are)."""
        t = np.asarray(t, float)
        x = np.interp(t, self.t, np.arange(self.t.size, dtype=float))
        return np.where((t >= self.t[0] - 1e-9) & (t <= self.t[-1] + 1e-9), x, np.nan)

    def _blended(self, t, value, tail: tuple, mix) -> np.ndarray:
        """``value(trajectory, local_times)`` of the window holding each time; near a cut the left window's
        and the right one's mixed by ``mix(left, right, weight)`` (NaN where a window has no fit)."""
        x = self._position(t)
        out = np.full((x.size,) + tail, np.nan)
        band = self.windows.band_frames
        for j, win in enumerate(self.pieces):
            start = -np.inf if j == 0 else win.core_lo - band - 0.5
            stop = np.inf if j == len(self.pieces) - 1 else win.core_hi + band - 0.5
            rows = np.flatnonzero((x > start) & (x < stop))
            if not rows.size:
                continue
            local = np.interp(x[rows] - win.lo, np.arange(win.times.size, dtype=float), win.times)
            v = np.full((rows.size,) + tail, np.nan) if win.trajectory is None else value(win.trajectory, local)
            rising = x[rows] < win.core_lo + band - 0.5 if j else np.zeros(rows.size, bool)
            out[rows[~rising]] = v[~rising]
            if rising.any():
                w = 0.5 - 0.5 * np.cos(np.pi * (x[rows[rising]] - (win.core_lo - band) + 0.5) / (2 * band))
                out[rows[rising]] = mix(out[rows[rising]], v[rising], w)
        return out

    def _linear(self, t, value, tail: tuple) -> np.ndarray:
        return self._blended(t, value, tail, _mix_linear)

    def rotation(self, t) -> np.ndarray:
        """``R(t)`` (n, 3, 3); across a cut the two windows' rotations interpolated along the geodesic."""
        return self._blended(t, lambda tr, u: tr.rotation(u), (3, 3), _mix_rotation)

    def omega(self, t) -> np.ndarray:
        """Angular velocity (rad/s) in the motion frame (n, 3)."""
        return self._linear(t, lambda tr, u: tr.omega(u), (3,))

    def alpha(self, t) -> np.ndarray:
        """Angular acceleration (rad/s^2) in the motion frame (n, 3)."""
        return self._linear(t, lambda tr, u: tr.alpha(u), (3,))

    def centre(self, t, derivative: int = 0) -> np.ndarray:
        """The model centroid's smoothed position, velocity or acceleration (n, 3)."""
        return self._linear(t, lambda tr, u: tr.centre(u, derivative), (3,))

    def point(self, t, body_point) -> pose.PointKinematics:
        """Kinematics of a body point given in the static shot (model) frame
        (:meth:`horsemocap.pose.PoseTrajectory.point` of each window, blended)."""
        X = np.asarray(body_point, float)
        if X.shape != (3,):
            raise ValueError(f"body_point: expected (3,) in the static shot's frame, got {X.shape}")
        k = self.points(t, X[None])
        return pose.PointKinematics(k.position[:, 0], k.velocity[:, 0], k.acceleration[:, 0])

    def points(self, t, body_points) -> pose.PointKinematics:
        """:meth:`point` for several points (k, 3) -> arrays (n, k, 3)."""
        X = np.asarray(body_points, float)
        both = self._linear(t, lambda tr, u: np.stack(streaming.point_kinematics(tr, u, X)[:3], 1),
                            (3,) + X.shape)
        return pose.PointKinematics(both[:, 0], both[:, 1], both[:, 2])


def _mix_linear(left, right, w):
    """``(1 - w) left + w right`` (the blend of :func:`horsemocap.streaming.windowed_kinematics`)."""
    ww = w.reshape((w.size,) + (1,) * (left.ndim - 1))
    return (1 - ww) * left + ww * right


def _mix_rotation(left, right, w):
    """The rotation a fraction ``w`` of the way from ``left`` to ``right`` (n, 3, 3), NaN where either is."""
    out = np.full(left.shape, np.nan)
    ok = np.isfinite(left).all(axis=(1, 2)) & np.isfinite(right).all(axis=(1, 2))
    if ok.any():
        a, b = Rotation.from_matrix(left[ok]), Rotation.from_matrix(right[ok])
        out[ok] = (a * Rotation.from_rotvec(w[ok, None] * (a.inv() * b).as_rotvec())).as_matrix()
    return out


def windowed_pose_trajectory(t, registration: pose.PoseRegistration, model, params: PoseParams = PoseParams(), *,
                             points=None, settled: pose.SettledPoseSmoothing | None = None,
                             aperture=None, expected_fundamental_hz: float | None = None,
                             window: int = streaming.WINDOW_FRAMES,
                             frames: int = streaming.REPRESENTATIVE_FRAMES) -> WindowedPoseTrajectory:
    """The pose trajectory of a long record, smoothed in windows (the module docstring).

    Called as :func:`horsemocap.pose.fit_pose_trajectory` is.

    Parameters
    ----------
    t : (n,)
        The frames' times (s), increasing.
    registration : horsemocap.pose.PoseRegistration
        The record's registration (:func:`horsemocap.pose.register_pose`).
    model : (m, 3)
        The static shot's markers (or the moving frames' mean shape).
    params : horsemocap.params.PoseParams
        The pose smoothing.
    points : (n, m, 3), optional
        The registered markers.
    settled : horsemocap.pose.SettledPoseSmoothing, optional
        Choices settled on another record (a long recording's longest pass), fitted by every window
        as they are (:func:`horsemocap.streaming.settle_given_smoothing`); default: settled on this
        record's middle ``frames`` frames (:func:`horsemocap.streaming.settle_smoothing`).
    aperture, expected_fundamental_hz
        As :func:`horsemocap.pose.fit_pose_trajectory` takes them, for every fit.
    window : int
        Frames of a core at most (:func:`horsemocap.streaming.window_core`).
    frames : int
        Frames of the representative stretch.

    Returns
    -------
    WindowedPoseTrajectory

    Examples
    --------
    A body turning at a constant rate, in windows of 100 frames:

    >>> from scipy.spatial.transform import Rotation
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> t = np.arange(400) / 100.0
    >>> R = Rotation.from_rotvec(np.outer(0.5 * t, [0, 0, 1])).as_matrix()
    >>> pts = np.einsum("kij,mj->kmi", R, model)
    >>> tr = windowed_pose_trajectory(t, pose.register_pose(pts, model), model, PoseParams(smoothing="gcv"),
    ...                               points=pts, window=100)
    >>> len(tr.windows.plan), float(np.round(tr.omega(t)[:, 2].mean(), 6))
    (4, 0.5)
    """
    t = np.asarray(t, float)
    fit = dict(aperture=aperture, expected_fundamental_hz=expected_fundamental_hz)
    if settled is None:
        how = streaming.settle_smoothing(t, registration, points, model, params, frames, window, **fit)
    else:
        how = streaming.settle_given_smoothing(t, registration, points, model, params, settled, frames, window,
                                               **fit)
    plan = tuple(streaming.window_plan(t.size, how.window, how.margin))
    step = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    pieces = tuple(_pose_window(t, registration, points, model, how, step, *p) for p in plan)
    lo, hi = streaming.representative_range(t.size, frames)
    band = streaming.blend_band(how)
    valid, reason = _frame_state(pieces, registration, band, t.size)
    return WindowedPoseTrajectory(t, pieces, how, PoseWindows(t.size, plan, how.window, how.margin, band,
                                                              (float(t[lo]), float(t[hi - 1]))),
                                  registration, np.asarray(model, float).mean(0), valid, reason)


def _pose_window(t, registration, points, model, settled, step, lo, hi, core_lo, core_hi) -> PoseWindow:
    """One window's fit (:func:`horsemocap.streaming.window_fit`)."""
    tr, tl, why = streaming.window_fit(t, registration, points, model, settled, lo, hi, step)
    return PoseWindow(lo, hi, core_lo, core_hi, tl, tr, why or "")


def _frame_state(pieces, registration, band: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Each frame's ``valid`` and ``reason``: those of the window whose blend weight there is at least a half."""
    valid, reason = np.zeros(n, bool), np.full(n, "", dtype=object)
    for j, win in enumerate(pieces):
        a = 0 if j == 0 else win.core_lo
        b = n if j == len(pieces) - 1 else win.core_hi
        if win.trajectory is None:
            reason[a:b] = np.where(registration.reason[a:b] != "", registration.reason[a:b],
                                   f"no pose trajectory in this stretch: {win.why}")
        else:
            valid[a:b] = win.trajectory.valid[a - win.lo:b - win.lo]
            reason[a:b] = win.trajectory.reason[a - win.lo:b - win.lo]
    return valid, reason
