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

from dataclasses import dataclass

import numpy as np

from .params import PoseParams
from .pose import PoseRegistration, fit_pose_trajectory, settle_pose_smoothing
from .splines import MAX_BASIS, knot_step
from .streaming import slice_registration

__all__ = ["BasisResolution", "FULL_BASIS_FRAMES", "basis_resolution"]

#: The longest record a quintic spline fits with a knot at every sample (:func:`horsemocap.splines.knot_step` 1).
FULL_BASIS_FRAMES = MAX_BASIS - 4


@dataclass(frozen=True)
class BasisResolution:
    """A pose fit's acceleration against the same fit with a knot at every frame.

    Attributes
    ----------
    knot_step : int
        Frames between the knots of the checked fit (of its windows, for a long pass in windows).
    knot_spacing_s : float
        The same in seconds (the record's median frame interval times ``knot_step``).
    stretch : (int, int)
        The pose record's frames ``lo .. hi - 1`` fitted again with a knot at every frame.
    compared : (int, int)
        The frames whose accelerations are compared (the stretch's middle half).
    difference_pct : float
        The rms of the difference of the body point's acceleration (3D) over ``compared``, % of its
        rms in the fine fit; NaN when the fine fit could not be made (``reason`` says why).
    reason : str
        Why no figure, or "".
    """

    knot_step: int
    knot_spacing_s: float
    stretch: tuple
    compared: tuple
    difference_pct: float
    reason: str = ""


def _knot_step_of(trajectory) -> int:
    """The knot step of ``trajectory``'s fits: its own record's, or for a windowed one its longest window's."""
    pieces = getattr(trajectory, "pieces", None)
    if pieces:
        return max(knot_step(p.hi - p.lo) for p in pieces)
    return knot_step(np.asarray(trajectory.t).size)


def basis_resolution(trajectory, registration: PoseRegistration, model, body_point, params: PoseParams = PoseParams(),
                     *, points=None, aperture=None) -> BasisResolution | None:
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

    Returns
    -------
    BasisResolution, or None when the record's knots are at every frame already (nothing to compare).

    Examples
    --------
    A short record has a knot at every frame: nothing to check.

    >>> from types import SimpleNamespace
    >>> print(basis_resolution(SimpleNamespace(t=np.arange(300) / 50.0), None, None, np.zeros(3)))
    None
    """
    t = np.asarray(trajectory.t, float)
    step = _knot_step_of(trajectory)
    if step <= 1:
        return None
    n = t.size
    lo = max(0, (n - FULL_BASIS_FRAMES) // 2)
    hi = min(n, lo + FULL_BASIS_FRAMES)
    quarter = (hi - lo) // 4
    compared = (lo + quarter, hi - quarter)
    spacing = float(np.median(np.diff(t))) * step
    try:
        fine = fit_pose_trajectory(t[lo:hi], slice_registration(registration, lo, hi), model, params,
                                   points=None if points is None else np.asarray(points, float)[lo:hi],
                                   settled=settle_pose_smoothing(trajectory, params), aperture=aperture)
    except ValueError as exc:
        return BasisResolution(step, spacing, (lo, hi), compared, float("nan"),
                               f"the stretch could not be fitted again: {exc}")
    tc = t[compared[0]:compared[1]]
    a = trajectory.point(tc, body_point).acceleration
    b = fine.point(tc, body_point).acceleration
    ok = np.all(np.isfinite(a) & np.isfinite(b), axis=1)
    if not ok.any():
        return BasisResolution(step, spacing, (lo, hi), compared, float("nan"),
                               "no frame of the stretch's middle has a pose in both fits")
    scale = float(np.sqrt(np.mean(np.sum(b[ok] ** 2, 1))))
    diff = float(np.sqrt(np.mean(np.sum((a[ok] - b[ok]) ** 2, 1))))
    return BasisResolution(step, spacing, (lo, hi), compared, 100 * diff / scale if scale > 0 else float("nan"))
