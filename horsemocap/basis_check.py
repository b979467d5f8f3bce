"""Does the spline's basis hold the motion? A long record's fit against a fit with a knot at every frame.

A quintic smoothing spline has at most :data:`horsemocap.splines.MAX_BASIS`
basis functions: a record of more than about 400 samples gets a knot only
every few samples (:func:`horsemocap.splines.knot_step`). Where the knots are
further apart than the motion's fast part allows (which depends on the
motion's bandwidth in seconds, not on the number of frames: at 50 fps a knot
every 3 frames is 0.06 s, at 100 Hz a knot every 3 frames is 0.03 s), the fit
loses that part whatever its smoothing, and the saddle's acceleration with it.
No rule in frames can say where that starts for every gait and rate, so the
record itself is asked: the middle of the pose record is fitted again with a
knot at every frame and the same smoothing choices
(:func:`horsemocap.pose.settle_pose_smoothing`), and the two fits' accelerations
of the body point (the saddle) are compared over the middle half of that
stretch, away from its ends. With a basis fine enough they agree to the
smoothing's own few per cent; a coarse one differs by what it lost.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .params import PoseParams
from .pose import PoseRegistration, fit_pose_trajectory, settle_pose_smoothing
from .splines import FULL_BASIS_SAMPLES, knot_step
from .streaming import events_inside, slice_registration

__all__ = ["BasisResolution", "FULL_BASIS_FRAMES", "UNCAPPED_METHODS", "basis_resolution"]

#: The longest record a quintic spline fits with a knot at every sample (:func:`horsemocap.splines.knot_step` 1).
FULL_BASIS_FRAMES = FULL_BASIS_SAMPLES


@dataclass(frozen=True)
class BasisResolution:
    """A pose fit's acceleration against the same fit with a knot at every frame.

    Attributes
    ----------
    knot_step : int
        Samples between the knots of the checked fit (of its longest window, for a long pass in windows).
    knot_spacing_s : float
        The same in seconds (the record's median frame interval times ``knot_step``).
    stretch_s : (float, float)
        The first and last times of the frames fitted again with a knot at every frame (the record's time
        axis, kinematics.csv's ``time_s``).
    compared_s : (float, float)
        The first and last times whose accelerations are compared: the stretch's middle half, analysed frames
        only.
    difference_pct : float
        The rms of the difference of the body point's acceleration (3D) over ``compared_s``, % of its
        rms in the fine fit; NaN when the fine fit could not be made (``reason`` says why).
    reason : str
        Why no figure, or "".
    """

    knot_step: int
    knot_spacing_s: float
    stretch_s: tuple
    compared_s: tuple
    difference_pct: float
    reason: str = ""

    def shifted(self, seconds: float) -> "BasisResolution":
        """The same with its times moved by ``seconds`` (a window's own time axis onto the record's).

        Examples
        --------
        >>> BasisResolution(3, 0.06, (0.0, 7.9), (2.0, 5.9), 12.7).shifted(10.0).compared_s
        (12.0, 15.9)
        """
        return replace(self, stretch_s=tuple(v + seconds for v in self.stretch_s),
                       compared_s=tuple(v + seconds for v in self.compared_s))


#: Smoothing methods whose spline has no cap on its basis (nothing for the check to find): the interpolating
#: ``"none"`` and SciPy's cubic ``"gcv_cubic"`` (a knot at every sample).
UNCAPPED_METHODS = ("none", "gcv_cubic")


def _samples(registration: PoseRegistration, lo: int, hi: int) -> int:
    """Frames ``lo .. hi - 1`` with a pose (the samples a spline is fitted to)."""
    return int(np.count_nonzero(np.isfinite(np.asarray(registration.rotation)[lo:hi, 0, 0])))


def _knot_step_of(trajectory, registration: PoseRegistration) -> int:
    """The knot step of ``trajectory``'s fits (from the samples they were fitted to): its own record's, or for
    a windowed one its longest window's."""
    pieces = getattr(trajectory, "pieces", None)
    spans = [(w.lo, w.hi) for w in pieces] if pieces else [(0, np.asarray(trajectory.t).size)]
    return max(knot_step(_samples(registration, lo, hi)) for lo, hi in spans)


def _stretch(n: int, span: tuple) -> tuple:
    """The :data:`FULL_BASIS_FRAMES` frames of a record of ``n`` centred on the analysed ``span``."""
    middle = (span[0] + span[1]) // 2
    lo = min(max(0, middle - FULL_BASIS_FRAMES // 2), max(0, n - FULL_BASIS_FRAMES))
    return lo, min(n, lo + FULL_BASIS_FRAMES)


def basis_resolution(trajectory, registration: PoseRegistration, model, body_point, params: PoseParams = PoseParams(),
                     *, points=None, aperture=None, span: tuple | None = None) -> BasisResolution | None:
    """The acceleration ``trajectory`` gives ``body_point`` against a fit with a knot at every frame.

    Parameters
    ----------
    trajectory : horsemocap.pose.PoseTrajectory or horsemocap.pose_windows.WindowedPoseTrajectory
        The pose record's fit (its times ``t``, ``point`` and the choices it made).
    registration : PoseRegistration
        The per-frame registration it was fitted to (the whole record's).
    model : (m, 3)
        The marker model registered.
    body_point : (3,)
        The point whose acceleration is compared (the saddle), in the model's coordinates.
    params : PoseParams
        The pose smoothing's parameters the trajectory was fitted with.
    points, aperture
        As given to :func:`horsemocap.pose.fit_pose_trajectory`.
    span : (int, int), optional
        The record's frames whose values are reported (the analysed frames of a pose record widened
        by partial frames); the stretch is centred on them and only they are compared. Default: all.

    Returns
    -------
    BasisResolution, or None when the record's knots are at every sample already or the smoothing has no
    capped basis (:data:`UNCAPPED_METHODS`): nothing to compare.

    Examples
    --------
    A short record has a knot at every frame: nothing to check.

    >>> from types import SimpleNamespace
    >>> reg = SimpleNamespace(rotation=np.repeat(np.eye(3)[None], 300, 0))
    >>> print(basis_resolution(SimpleNamespace(t=np.arange(300) / 50.0), reg, None, np.zeros(3)))
    None
    """
    t = np.asarray(trajectory.t, float)
    if params.smoothing in UNCAPPED_METHODS:
        return None
    step = _knot_step_of(trajectory, registration)
    if step <= 1:
        return None
    span = (0, t.size) if span is None else (int(span[0]), int(span[1]))
    lo, hi = _stretch(t.size, span)
    quarter = (hi - lo) // 4
    a, b = max(lo + quarter, span[0]), min(hi - quarter, span[1])
    stretch_s, compared_s = (float(t[lo]), float(t[hi - 1])), (float(t[min(a, b - 1)]), float(t[max(b - 1, a)]))
    spacing = float(np.median(np.diff(t))) * step

    def without(reason):
        return BasisResolution(step, spacing, stretch_s, compared_s, float("nan"), reason)
    if b <= a:
        return without("the analysed frames hold no part of the stretch's middle")
    try:
        fine = fit_pose_trajectory(t[lo:hi], slice_registration(registration, lo, hi), model,
                                   replace(params, events=events_inside(params.events, t[lo], t[hi - 1])),
                                   points=None if points is None else np.asarray(points, float)[lo:hi],
                                   settled=settle_pose_smoothing(trajectory, params), aperture=aperture)
    except ValueError as exc:
        return without(f"the stretch could not be fitted again: {exc}")
    tc = t[a:b]
    acc = trajectory.point(tc, body_point).acceleration
    ref = fine.point(tc, body_point).acceleration
    ok = np.all(np.isfinite(acc) & np.isfinite(ref), axis=1)
    if not ok.any():
        return without("no frame of the stretch's middle has a pose in both fits")
    scale = float(np.sqrt(np.mean(np.sum(ref[ok] ** 2, 1))))
    diff = float(np.sqrt(np.mean(np.sum((acc[ok] - ref[ok]) ** 2, 1))))
    return BasisResolution(step, spacing, stretch_s, compared_s, 100 * diff / scale if scale > 0 else float("nan"))
