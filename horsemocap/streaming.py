"""Pose-trajectory kinematics of a long record in overlapping windows, in time and memory linear in its length.

The smoothing of :func:`horsemocap.pose.fit_pose_trajectory` solves for the
whole record at once; its cost grows faster than the record's length. A
long record (a capture of minutes at a few hundred hertz) is smoothed here
in windows instead:

1. the smoothing is settled once, on a representative stretch (the
   :data:`REPRESENTATIVE_FRAMES` frames at the record's middle): what
   ``"auto"`` runs and the stride frequency of the harmonics (a record
   without harmonics: also the six smoothing parameters, lambda, of the
   centroid and rotation-vector components);
2. the record is cut into cores of :data:`WINDOW_FRAMES` frames; each core is
   fitted with a margin of frames on both sides (so the fit's ends, where a
   spline is least certain, fall outside the core) and with the settled
   smoothing: every window smooths with the same method and stride frequency
   (and lambdas where they are settled), so neighbouring windows estimate the
   same curve;
3. across each cut the two windows' values are blended over a band of frames
   around it (weights rising as a raised cosine), so the result has no step
   at the cut.

A fit with stride harmonics chooses its lambdas per window (its harmonics are
tested against the cutoff of a plain spline whose lambda is not the partial
spline's), as does an adaptive smoothing (its penalty's weight is local
anyway). A fit that blends the smoothing without and with the stride's
harmonics (the left-out choice with four or more markers under noise
correlated over frames) is carried whole instead: both routes' lambdas, the
harmonics each keeps and the blend's weight are settled on the
representative stretch (:func:`horsemocap.pose.settle_pose_smoothing`), and
every window fits both routes at them and blends them with that weight.

Only the current window's arrays live at a time: :func:`windowed_kinematics`
yields :class:`KinematicsBlock` s of consecutive frames for the caller to
write out. Analyze's long passes keep their windows' fits instead, as one
pose trajectory (:mod:`horsemocap.pose_windows`); a pass given the smoothing
settled on another pass fits it in every window
(:func:`settle_given_smoothing`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import pose
from .params import PoseParams
from .splines import CACHE_SAMPLES, FULL_BASIS_SAMPLES
from .progress import counter
from .store import release_pages

__all__ = ["WINDOW_FRAMES", "MARGIN_FRAMES", "MARGIN_DECAY", "kernel_margin", "REPRESENTATIVE_FRAMES", "KinematicsBlock", "SettledSmoothing",
           "WHOLE_RECORD_FRAMES", "GRID_TOLERANCE_S", "GRID_TOLERANCE_STEPS", "window_times", "point_kinematics",
           "representative_range", "register_in_chunks", "conditioning_warnings", "release_pages", "window_core", "window_plan", "slice_registration", "settle_smoothing",
           "settle_given_smoothing", "events_inside", "window_params", "window_fit", "blend_band", "windowed_kinematics"]

WINDOW_FRAMES = 1000
"""Frames of a window's core (the frames whose values the window gives)."""

MARGIN_FRAMES = 150
"""Least frames fitted on each side of a core (more where the smoothing's kernel is wider)."""

MARGIN_DECAY = 0.01
"""What is left of a cut's effect at the edge of a core: the margin is where the smoothing's kernel
has decayed to this fraction (:func:`kernel_margin`)."""

SPLINE_NULL_SPACE = 3
"""Degrees of freedom of the quintic spline's unpenalised polynomials (degree < 3)."""

REPRESENTATIVE_FRAMES = 4000
"""Frames at the record's middle on which the smoothing is settled."""

REGISTRATION_CHUNK = 50_000
"""Frames registered at a time by :func:`register_in_chunks`."""

WHOLE_RECORD_FRAMES = CACHE_SAMPLES
"""Records up to this many frames are smoothed whole (:func:`horsemocap.pose.fit_pose_trajectory`);
longer ones in windows. A quintic spline has at most :data:`horsemocap.splines.MAX_BASIS` basis
functions, so a longer record gets a knot only every few samples: one smoothed whole would lose the
fast part of its motion to the knot spacing (a second of a trot holds accelerations that a knot every
0.15 s cannot follow), whatever its smoothing. A window's core is shortened so that it fits this many
frames with its margins wherever half a window remains (:func:`window_core`), so a record smoothed
whole has knots no coarser than a usual window's."""

GRID_TOLERANCE_S = 1e-6
"""A window's times within this (s) of a uniform grid are fitted on the grid (:func:`window_times`): the
rounding of a time column written to the microsecond."""

GRID_TOLERANCE_STEPS = 1e-3
"""The same tolerance as a fraction of the frame interval, the smaller of the two applying: at rates of
tens of kilohertz a microsecond is a few percent of a frame, and moving a time by a fraction f of a
frame changes a finite-difference velocity by about f relative, so the grid is taken only where that
is at most 0.1 %."""

COMPONENTS = pose.POSE_COMPONENTS


@dataclass(frozen=True)
class KinematicsBlock:
    """Kinematics of the record's frames ``start .. stop - 1``.

    ``position``, ``velocity``, ``acceleration`` (b, k, 3) of the body points
    asked for, ``omega``, ``alpha`` (b, 3) of the body, ``reason`` (b,) why a
    frame is NaN (or that it bridges a gap; "" otherwise).
    """

    start: int
    stop: int
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    reason: np.ndarray


@dataclass(frozen=True)
class SettledSmoothing:
    """The smoothing every window runs: ``params``, ``lam`` (six, or None per component: chosen per
    window), ``fundamental_hz`` (None: no harmonics), ``choice`` (what ``"auto"`` ran and why, or
    None), ``margin`` (frames fitted each side of a core), ``info`` (the representative fit's
    per-component smoothing), ``window`` (frames of a core, :func:`window_core`) and ``blend``
    (a blend of the fits without and with the stride's harmonics settled on the representative
    stretch, :class:`horsemocap.pose.SettledPoseSmoothing`, that every window fits as it is; None:
    no blend), ``given`` (the choices settled on another record, a long recording's longest pass,
    :func:`settle_given_smoothing`, that every window fits as they are, or the correlated-error refit with the
    stride's harmonics settled on the representative stretch with its lambdas left to each window; None:
    settled here),
    ``aperture`` and ``expected_fundamental_hz`` (passed to every window's fit as
    :func:`horsemocap.pose.fit_pose_trajectory` takes them; None: not given)."""

    params: PoseParams
    lam: tuple
    fundamental_hz: float | None
    choice: dict | None
    margin: int
    info: dict
    window: int = WINDOW_FRAMES
    blend: pose.SettledPoseSmoothing | None = None
    given: pose.SettledPoseSmoothing | None = None
    aperture: object = None
    expected_fundamental_hz: float | None = None


def window_core(window: int, margin: int) -> int:
    """Frames of a core: ``window``, or fewer so that a core with its margins fits the splines' cache.

    The six components of a window share their B-spline basis and penalty
    (a pure function of the times) only when a window has at most
    :data:`horsemocap.splines.CACHE_SAMPLES` frames; otherwise each component
    builds them anew, half of a window's time. The core is shortened to fit
    when at least half of ``window`` remains.

    Examples
    --------
    >>> window_core(1000, 369), window_core(1000, 150), window_core(1000, 600)
    (862, 1000, 1000)
    """
    fitting = CACHE_SAMPLES - 2 * margin
    return fitting if window // 2 <= fitting < window else window


def window_plan(n: int, window: int = WINDOW_FRAMES, margin: int = MARGIN_FRAMES) -> list:
    """The windows over ``n`` frames: ``(lo, hi, core_lo, core_hi)`` index ranges.

    The cores tile ``0..n`` in order; each window fits ``lo..hi`` (the core and
    up to ``margin`` frames on each side). The last core takes a short rest
    (under half a window) rather than leaving a short window.

    Examples
    --------
    >>> window_plan(2400, window=1000, margin=100)
    [(0, 1100, 0, 1000), (900, 2400, 1000, 2400)]
    """
    if window < 1 or margin < 0:
        raise ValueError(f"window {window}, margin {margin}: expected a positive window and a margin >= 0")
    cuts = list(range(0, n, window)) + [n]
    if len(cuts) > 2 and cuts[-1] - cuts[-2] < window // 2:
        cuts.pop(-2)
    return [(max(0, a - margin), min(n, b + margin), a, b) for a, b in zip(cuts[:-1], cuts[1:])]


def slice_registration(reg: pose.PoseRegistration, lo: int, hi: int) -> pose.PoseRegistration:
    """The registration of frames ``lo .. hi - 1`` (every per-frame array sliced; the record's
    noise figures kept).

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> reg = pose.register_pose(np.repeat(model[None], 10, 0), model)
    >>> slice_registration(reg, 2, 5).rotation.shape
    (3, 3, 3)
    """
    n = reg.rotation.shape[0]
    fields = {}
    for f in dataclasses.fields(reg):
        value = getattr(reg, f.name)
        if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == n:
            fields[f.name] = value[lo:hi]
    return dataclasses.replace(reg, **fields)


def register_in_chunks(points, model, names=None, chunk: int = REGISTRATION_CHUNK,
                       folder=None) -> pose.PoseRegistration:
    """:func:`horsemocap.pose.register_pose` of ``points`` (n, m, 3), ``chunk`` frames at a time.

    Each frame's pose is its own; the marker noise ``noise_m`` pools the
    chunks' squared residuals over their degrees of freedom (``3 k - 6`` per
    frame of k markers), as one registration of the whole record does. The
    result's arrays are filled in place: the memory beyond them is one
    chunk's working arrays; with ``folder`` they are memory-mapped files
    there (:func:`release_pages` after each chunk), so that a long record's
    registration is not held in memory; each frame's ``reason`` is one of a
    few shared strings (an object array). Without marker weights or covariances.

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1], [0.1, 0.1, -0.2]])
    >>> rng = np.random.default_rng(1)
    >>> pts = model[None] + rng.normal(0, 1e-3, (50, 4, 3))
    >>> whole, parts = pose.register_pose(pts, model), register_in_chunks(pts, model, chunk=7)
    >>> bool(np.allclose(whole.rotation, parts.rotation)), bool(np.isclose(whole.noise_m, parts.noise_m))
    (True, True)
    """
    n = len(points)
    if n <= chunk:
        return pose.register_pose(np.asarray(points), model, names=names)
    kept, reasons, pooled, dof = {}, [], 0.0, 0.0
    for a in range(0, n, chunk):
        reg = pose.register_pose(np.asarray(points[a:a + chunk]), model, names=names)
        for f in dataclasses.fields(reg):
            value = getattr(reg, f.name)
            if f.name != "reason" and isinstance(value, np.ndarray) and value.ndim and value.shape[0] == reg.rms.size:
                if f.name not in kept:
                    shape = (n,) + value.shape[1:]
                    kept[f.name] = (np.empty(shape, value.dtype) if folder is None else np.lib.format.open_memmap(
                        Path(folder) / f"registration-{f.name}.npy", mode="w+", dtype=value.dtype, shape=shape))
                kept[f.name][a:a + value.shape[0]] = value
        names_of_reasons, which = np.unique(reg.reason, return_inverse=True)
        reasons.append(np.array(names_of_reasons.tolist(), dtype=object)[which.reshape(-1)])  # shared strings
        frames_dof = float(np.sum(np.where(np.isfinite(reg.rms), 3 * reg.n_markers - 6, 0)))
        if frames_dof > 0:
            pooled, dof = pooled + reg.noise_m ** 2 * frames_dof, dof + frames_dof
        release_pages(points, *kept.values())
    noise = float(np.sqrt(pooled / dof)) if dof > 0 else float("nan")
    return dataclasses.replace(reg, **kept, reason=np.concatenate(reasons), noise_m=noise)


def conditioning_warnings(registration: pose.PoseRegistration, chunk: int = REGISTRATION_CHUNK,
                          lever_m: float | None = None,
                          rotation_noise_limit_deg: float = pose.ROTATION_NOISE_LIMIT_DEG) -> list:
    """:func:`horsemocap.pose.conditioning_warnings` of a long record's registration, ``chunk`` frames at a time.

    The per-frame figures (:func:`horsemocap.pose.frame_rotation_std`, the
    triangle's height, the frames without a pose) are taken chunk by chunk
    and pooled (the rotation noise as the RMS over every frame with a pose),
    so the working memory is one chunk's; the messages are
    :func:`horsemocap.pose.conditioning_messages` of them (a registration with
    covariances is passed to :func:`horsemocap.pose.conditioning_warnings` whole).

    Examples
    --------
    >>> model = np.array([[0.0, 0, 0], [0.5, 0, 0], [0.2, 0.3, 0]])
    >>> conditioning_warnings(pose.register_pose(np.repeat(model[None], 5, axis=0), model), chunk=2)
    []
    """
    reg = registration
    n = reg.rotation.shape[0]
    if n <= chunk or reg.information is not None:
        return pose.conditioning_warnings(reg, lever_m, rotation_noise_limit_deg)
    sq, count, low, missing, first = np.zeros(3), 0, np.inf, 0, None
    for a in range(0, n, chunk):
        part = slice_registration(reg, a, min(n, a + chunk))
        std = pose.frame_rotation_std(part)
        seen = np.all(np.isfinite(std), axis=1)
        sq, count = sq + np.sum(std[seen] ** 2, axis=0), count + int(seen.sum())
        h = part.height[np.isfinite(part.rotation[:, 0, 0]) & (part.n_markers >= 3)]
        low = min(low, float(np.min(h))) if h.size else low
        bad = part.reason[part.reason != ""]
        missing += bad.size
        if bad.size:
            first = min(bad.tolist()) if first is None else min(first, min(bad.tolist()))
        release_pages(*(getattr(reg, f.name) for f in dataclasses.fields(reg)))
    rot_noise = float(np.degrees(np.max(np.sqrt(sq / count)))) if count else float("nan")
    figures = pose.ConditioningFigures(low if np.isfinite(low) else float("nan"), rot_noise, float(reg.noise_m),
                                       False, n, int(missing), "" if first is None else str(first))
    return pose.conditioning_messages(figures, lever_m, rotation_noise_limit_deg)


def representative_range(n: int, frames: int = REPRESENTATIVE_FRAMES) -> tuple[int, int]:
    """The frames ``lo .. hi - 1`` at the middle of ``n`` on which :func:`settle_smoothing` settles.

    Examples
    --------
    >>> representative_range(10_000, 4000)
    (3000, 7000)
    """
    lo = max(0, (n - frames) // 2)
    return lo, min(n, lo + frames)


def settle_smoothing(t, registration, points, model, params: PoseParams,
                     frames: int = REPRESENTATIVE_FRAMES, window: int = WINDOW_FRAMES, *, aperture=None,
                     expected_fundamental_hz: float | None = None) -> SettledSmoothing:
    """The smoothing of a long record, settled on its middle ``frames`` frames (module step 1).

    ``params.smoothing="auto"`` is run there (:func:`horsemocap.pose.choose_smoothing`) and the
    method it ran is kept, and the stride frequency of its harmonics; without harmonics the six
    lambdas of that fit are kept too (with harmonics, and for the adaptive smoothing, the lambdas
    are chosen per window); a blend of the fits without and with the harmonics is kept whole
    (``blend``: both routes' lambdas, harmonics and the weight). The margin is the widest of the
    components' :func:`kernel_margin` (those a window holds), at least :data:`MARGIN_FRAMES`; the
    core is :func:`window_core`. ``aperture`` and ``expected_fundamental_hz`` are given to the
    representative fit and kept for the windows' (:func:`horsemocap.pose.fit_pose_trajectory`).
    """
    lo, hi = representative_range(len(t), frames)
    sub_params = dataclasses.replace(params, events=events_inside(params.events, t[lo], t[hi - 1]))
    tr = pose.fit_pose_trajectory(t[lo:hi], slice_registration(registration, lo, hi), model, sub_params,
                                  points=None if points is None else points[lo:hi], aperture=aperture,
                                  expected_fundamental_hz=expected_fundamental_hz)
    info = tr.smoothing
    choice = tr.smoothing_choice
    method = params.smoothing
    if choice is not None:
        method = choice["method"]
    method = "gcv" if method == "gcv_ar1" else method
    f0 = info["cx"].get("fundamental_hz")
    f0 = None if f0 is None or not np.isfinite(f0) else float(f0)
    harmonics = params.harmonics if f0 is not None else "none"
    # a fit with harmonics tests them against the plain spline's cutoff, whose lambda is not the partial
    # spline's: there (and in the adaptive smoothing) each window chooses its lambdas
    per_window = method == "adaptive" or f0 is not None
    lam = tuple(None if per_window else float(info[c]["lam"]) for c in COMPONENTS)
    # a blend (and its stride frequency) settled as a long recording's passes settle it; else None
    blend = pose.settle_pose_smoothing(tr, sub_params)
    blend = blend if blend.blend_weights is not None else None
    if blend is not None:
        # the left-out choice's blend is the representative range's: every window fits its two routes at their
        # lambdas and blends them with its weight, and the record says so
        lam = blend.lam
        weight = pose.blend_weights_text(blend.blend_weights)
        choice = {**choice, "reason": choice["reason"] + "; on this long record the left-out choice and the "
                  f"blend's weight ({weight}) were settled on the representative range (frames {lo} to {hi - 1}): "
                  "every window fits both routes at those smoothing parameters and blends them with that weight"}
    elif choice is not None and f0 is not None and "cross_validation" in choice:
        # the left-out choice is the representative range's: the windows choose theirs as white-noise GCV
        # with the stride's harmonics, and the record says so
        choice = {**choice, "reason": choice["reason"] + "; on this long record the left-out choice was made on "
                  "the representative range only: each window chose its own smoothing by white-noise GCV with "
                  "the stride's harmonics"}
    given = None
    if choice is not None and f0 is not None and choice.get("correlated_harmonics"):
        # the correlated-error refit with the stride's harmonics: every window chooses its own smoothing
        # parameters under the same AR(1) correlation with those harmonics (the settled choice, its lambdas free)
        given = dataclasses.replace(pose.settle_pose_smoothing(tr, sub_params), lam=(None,) * len(COMPONENTS))
        choice = {**choice, "reason": choice["reason"] + "; on this long record the choice was made on the "
                  f"representative range (frames {lo} to {hi - 1}): each window chose its own smoothing parameters "
                  "under that correlation with the stride's harmonics"}
    frames_fitted = hi - lo
    if not per_window and blend is None and method == "gcv" and frames_fitted > FULL_BASIS_SAMPLES:
        # the representative stretch, fitted whole, has a knot only every few frames: its lambdas are those of a
        # basis coarser than any window's; chosen again on its middle with a knot at every frame
        lam, info, frames_fitted = _fine_basis_lambdas(t, registration, points, model, sub_params, tr, lo, hi,
                                                       aperture=aperture,
                                                       expected_fundamental_hz=expected_fundamental_hz)
    margin = _margin(frames_fitted, info, window)
    settled = dataclasses.replace(params, smoothing=method, harmonics=harmonics)
    return SettledSmoothing(settled, lam, f0, choice, margin, info, window_core(window, margin), blend, given,
                            aperture=aperture, expected_fundamental_hz=expected_fundamental_hz)


def _fine_basis_lambdas(t, registration, points, model, params: PoseParams, fitted, lo: int, hi: int, *,
                        aperture=None, expected_fundamental_hz=None) -> tuple:
    """``(lam, info, frames)``: the six smoothing parameters chosen again on the middle
    :data:`horsemocap.splines.FULL_BASIS_SAMPLES` frames of ``lo .. hi - 1`` (a knot at every frame) with the
    choices ``fitted`` (the stretch's fit) made there (its method, noise correlation, rotation weighting), the
    components' smoothing and the frames fitted.

    A smoothing parameter is a bandwidth whatever the record's length
    (:func:`horsemocap.splines.half_gain_frequency`), but the one GCV picks on a
    basis with a knot only every few frames is that basis's: too coarse to
    follow the motion's fast part, it takes that part for noise and smooths the
    rest more (on a 30 s trot at 100 Hz, 4000-frame stretch, the vertical's
    lambda about 80 times the fine basis's)."""
    a = lo + (hi - lo - FULL_BASIS_SAMPLES) // 2
    b = a + FULL_BASIS_SAMPLES
    choose = dataclasses.replace(pose.settle_pose_smoothing(fitted, params), lam=(None,) * len(COMPONENTS))
    fine = pose.fit_pose_trajectory(t[a:b], slice_registration(registration, a, b), model,
                                    dataclasses.replace(params, events=events_inside(params.events, t[a], t[b - 1])),
                                    points=None if points is None else points[a:b], settled=choose,
                                    aperture=aperture, expected_fundamental_hz=expected_fundamental_hz)
    info = fine.smoothing
    return tuple(float(info[c]["lam"]) for c in COMPONENTS), info, b - a


def _margin(frames: int, info: dict, window: int) -> int:
    """The widest of the components' :func:`kernel_margin` over ``frames`` (at least :data:`MARGIN_FRAMES`,
    at most ``window``)."""
    return min(max([MARGIN_FRAMES] + [kernel_margin(frames, info[c], window=window) for c in COMPONENTS]), window)


def settle_given_smoothing(t, registration, points, model, params: PoseParams, given: pose.SettledPoseSmoothing,
                           frames: int = REPRESENTATIVE_FRAMES, window: int = WINDOW_FRAMES, *, aperture=None,
                           expected_fundamental_hz: float | None = None) -> SettledSmoothing:
    """The smoothing of a long record whose choices were settled on another record (``given``).

    Nothing is chosen: the record's middle ``frames`` frames are fitted with
    ``given`` (:func:`horsemocap.pose.fit_pose_trajectory`'s ``settled``) only for the
    components' degrees of freedom, from which the margin is found as in
    :func:`settle_smoothing`; every window then fits ``given`` as it is.

    Examples
    --------
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> t = np.arange(300) / 50.0
    >>> reg = pose.register_pose(np.repeat(model[None], 300, 0) + np.outer(t, [1.0, 0, 0])[:, None], model)
    >>> given = pose.SettledPoseSmoothing("gcv", None, None, (1e-6,) * 6, (0,) * 6, (False,) * 3)
    >>> s = settle_given_smoothing(t, reg, None, model, PoseParams(), given, frames=200, window=1000)
    >>> s.given is given, s.lam[0], s.margin >= MARGIN_FRAMES
    (True, 1e-06, True)
    """
    lo, hi = representative_range(len(t), frames)
    sub_params = dataclasses.replace(params, events=events_inside(params.events, t[lo], t[hi - 1]))
    tr = pose.fit_pose_trajectory(t[lo:hi], slice_registration(registration, lo, hi), model, sub_params,
                                  points=None if points is None else points[lo:hi], settled=given,
                                  aperture=aperture, expected_fundamental_hz=expected_fundamental_hz)
    margin = _margin(hi - lo, tr.smoothing, window)
    return SettledSmoothing(dataclasses.replace(params, smoothing=given.method), tuple(given.lam),
                            given.fundamental_hz, tr.smoothing_choice, margin, tr.smoothing,
                            window_core(window, margin), None, given, aperture, expected_fundamental_hz)


def kernel_margin(frames: int, info: dict, decay: float = MARGIN_DECAY, window: int | None = None) -> int:
    """Frames beyond a cut after which a component's smoothing no longer feels the cut (to ``decay``).

    A quintic smoothing spline (penalty on the third derivative) acts as a
    kernel whose transfer function is ``1 / (1 + (w / w0)^6)``; its effective
    degrees of freedom over ``frames`` frames are ``edf = frames w0 / 3`` (w0
    in radians per frame), and the kernel decays as ``exp(-w0 |u| / 2)``
    (the poles nearest the real axis, ``w0 exp(i pi / 6)``). So a cut's
    effect falls to ``decay`` after ``2 frames ln(1 / decay) / (3 edf)``
    frames, with ``edf`` the spline's penalised part: ``info["edf"]`` less its
    polynomials (:data:`SPLINE_NULL_SPACE`) and the two columns of each stride
    harmonic (``info["harmonics"]``). A component whose spline is its
    polynomial alone (under one penalised degree of freedom), or whose
    kernel does not decay within a ``window`` (its margin longer than the
    core), is a trend at the scale of a window: each window fits its own,
    and it sets no margin (0).

    Examples
    --------
    A spline of 40 degrees of freedom over 4000 frames (kernel decay 72 frames):

    >>> kernel_margin(4000, {"edf": 40.0 + SPLINE_NULL_SPACE})
    308
    >>> kernel_margin(4000, {"edf": 5.05, "harmonics": 1})       # a trend and one harmonic
    0
    >>> kernel_margin(4000, {"edf": 8.0}, window=1000)            # decay 533 frames: margin 2456
    0
    """
    # a blend (horsemocap.splines.BlendedSpline) holds its harmonic part's columns at that part's weight
    harmonic_weight = float((info.get("blend_weights") or [0.0, 1.0])[1])
    edf = (float(info.get("edf", np.nan)) - SPLINE_NULL_SPACE
           - 2 * int(info.get("harmonics") or 0) * harmonic_weight)
    if not np.isfinite(edf) or edf < 1.0:
        return 0
    margin = int(np.ceil(2.0 * frames * np.log(1.0 / decay) / (3.0 * edf)))
    return 0 if window is not None and margin > window else margin


def events_inside(events, t0: float, t1: float):
    """The known change points strictly inside ``(t0, t1)``: those a stretch of the record fits (None: none
    given; an empty list, none inside, is fitted as none).

    Examples
    --------
    >>> events_inside([1.0, 2.5, 4.0], 1.0, 3.0), events_inside(None, 0.0, 1.0)
    ([2.5], None)
    """
    if events is None:
        return None
    return [e for e in events if t0 < e < t1]


def window_params(settled: SettledSmoothing, t, lo: int, hi: int) -> PoseParams:
    """The pose smoothing of window ``lo .. hi - 1``: ``settled.params`` with the known change points inside it
    moved onto its own time axis (:func:`window_times`, 0 at frame ``lo``).

    Examples
    --------
    >>> s = SettledSmoothing(PoseParams(events=[0.5, 1.5]), (None,) * 6, None, None, 10, {})
    >>> [float(e) for e in window_params(s, np.arange(100) / 50.0, 50, 100).events]   # frames 50..99: 1.0 .. 1.98 s
    [0.5]
    """
    events = events_inside(settled.params.events, t[lo], t[hi - 1])
    return dataclasses.replace(settled.params, events=None if events is None else [e - t[lo] for e in events])


def window_times(t, lo: int, hi: int, step: float) -> np.ndarray:
    """The times of frames ``lo .. hi - 1`` counted from the window's first frame; on the grid
    ``0, step, 2 step, ...`` where they lie within :data:`GRID_TOLERANCE_S` (or
    :data:`GRID_TOLERANCE_STEPS` of a step, the smaller) of it.

    The smoothing's basis and penalty are a pure function of the times
    (:func:`horsemocap.splines.smoothing_spline` keeps the last few): windows of
    one length whose times are the same grid share them, where each window's
    own clock times (``t0 + k step`` rounded differently at each ``t0``) would
    build them anew. Velocities and accelerations do not depend on the time
    origin; moving a time by less than a microsecond is the rounding of the
    time column itself.

    Examples
    --------
    >>> t = 1000.0 + np.arange(6) * 0.005
    >>> window_times(t, 2, 5, 0.005).tolist() == (np.arange(3) * 0.005).tolist()
    True
    >>> window_times(np.array([0.0, 0.1, 0.25]), 0, 3, 0.1).tolist()   # off the grid: its own times
    [0.0, 0.1, 0.25]
    """
    local = t[lo:hi] - t[lo]
    grid = np.arange(hi - lo) * step
    if local.size and np.max(np.abs(local - grid)) <= min(GRID_TOLERANCE_S, GRID_TOLERANCE_STEPS * step):
        return grid
    return local


def window_fit(t, registration, points, model, settled: SettledSmoothing, lo: int, hi: int, step: float):
    """The window's pose trajectory on its own times (:func:`window_times`) and those times, or None and
    the reason it has none (a ValueError's message)."""
    tl = window_times(t, lo, hi, step)
    params = window_params(settled, t, lo, hi)
    fixed = settled.given or settled.blend       # a choice fitted as it is (both routes of a blend at their lambdas)
    options = dict(points=None if points is None else points[lo:hi], aperture=settled.aperture,
                   expected_fundamental_hz=settled.expected_fundamental_hz)
    try:
        if fixed is not None:
            return pose.fit_pose_trajectory(tl, slice_registration(registration, lo, hi), model, params,
                                            settled=fixed, **options), tl, None
        return pose.fit_pose_trajectory(tl, slice_registration(registration, lo, hi), model, params,
                                        fundamental_hz=settled.fundamental_hz, lam=settled.lam, **options), tl, None
    except ValueError as exc:
        return None, tl, str(exc)


def point_kinematics(tr, t, body_points) -> tuple:
    """``(position, velocity, acceleration)`` (n, k, 3) of ``body_points`` (k, 3) and the body's
    ``omega``, ``alpha`` (n, 3) at times ``t`` of a :class:`horsemocap.pose.PoseTrajectory`.

    :meth:`horsemocap.pose.PoseTrajectory.point`'s rigid-body kinematics
    (``p = c + r``, ``v = c' + omega x r``, ``a = c'' + alpha x r + omega x (omega x r)``,
    ``r = R (X - mean(model))``) with the rotation, the centroid's derivatives and
    the angular rates evaluated once for all the points.

    Examples
    --------
    >>> from scipy.spatial.transform import Rotation
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> t = np.arange(40) / 20.0
    >>> R = Rotation.from_rotvec(np.outer(0.5 * t, [0, 0, 1])).as_matrix()
    >>> tr = pose.fit_pose_trajectory(t, pose.register_pose(np.einsum("kij,mj->kmi", R, model), model), model,
    ...                               PoseParams(smoothing="none"))
    >>> p, v, a, w, al = point_kinematics(tr, t, model)
    >>> bool(np.allclose(v, tr.points(t, model).velocity)), p.shape
    (True, (40, 3, 3))
    """
    R, w, al = tr.rotation(t), tr.omega(t), tr.alpha(t)
    c, dc, ddc = (tr.centre(t, d) for d in (0, 1, 2))
    pos, vel, acc = [], [], []
    for X in np.asarray(body_points, float):
        r = np.einsum("kij,j->ki", R, X - tr.model_centroid)
        pos.append(c + r)
        vel.append(dc + np.cross(w, r))
        acc.append(ddc + np.cross(al, r) + np.cross(w, np.cross(w, r)))
    return np.stack(pos, 1), np.stack(vel, 1), np.stack(acc, 1), w, al


def _evaluate(tr, tl, lo: int, a: int, b: int, body_points, registration, why: str | None) -> KinematicsBlock:
    """The window's kinematics at frames ``a .. b - 1`` (``tl``: the window's times from frame ``lo``; NaN
    with ``why`` without a trajectory)."""
    m = len(body_points)
    if tr is None:
        nan3, nank = np.full((b - a, 3), np.nan), np.full((b - a, m, 3), np.nan)
        reason = np.where(registration.reason[a:b] != "", registration.reason[a:b],
                          f"no pose trajectory in this stretch: {why}")
        return KinematicsBlock(a, b, nank, nank, nank, nan3, nan3, reason.astype(object))
    tw = tl[a - lo:b - lo]
    return KinematicsBlock(a, b, *point_kinematics(tr, tw, body_points),
                           np.asarray(tr.reason[a - lo:b - lo], dtype=object))


def _blend(left: KinematicsBlock, right: KinematicsBlock) -> KinematicsBlock:
    """Two windows' values over the same frames, weighted from ``left`` to ``right`` (raised cosine)."""
    n = left.stop - left.start
    w = 0.5 - 0.5 * np.cos(np.pi * (np.arange(n) + 0.5) / n)

    def mix(a, b):
        ww = w.reshape((n,) + (1,) * (a.ndim - 1))
        return (1 - ww) * a + ww * b

    reason = np.where(w < 0.5, left.reason, right.reason)
    return KinematicsBlock(left.start, left.stop, *(mix(getattr(left, f), getattr(right, f))
                                                    for f in ("position", "velocity", "acceleration", "omega",
                                                              "alpha")), reason)


def windowed_kinematics(t, registration, points, model, body_points, params: PoseParams = PoseParams(), *,
                        settled: SettledSmoothing | None = None, window: int = WINDOW_FRAMES, progress=None):
    """Kinematics of ``body_points`` over a long record, window by window (the module's steps 2 and 3).

    Parameters
    ----------
    t : (n,)
        The frames' times (s), increasing.
    registration : horsemocap.pose.PoseRegistration
        The record's registration (:func:`horsemocap.pose.register_pose`).
    points : (n, m, 3) or None
        The registered markers (the noise-correlation measure of ``"auto"``).
    model : (m, 3)
        The static shot's markers.
    body_points : (k, 3)
        Points in the static shot's frame whose kinematics are wanted.
    params : horsemocap.params.PoseParams
        The pose smoothing (``partial_frames`` is not used here).
    settled : SettledSmoothing, optional
        From :func:`settle_smoothing` (default: settled on this record).
    window : int
        Frames of a core at most (used when ``settled`` is not given; otherwise ``settled.window``).
    progress : callable, optional
        A progress callback taking counts (:mod:`horsemocap.progress`): windows done of all.

    Yields
    ------
    KinematicsBlock
        Consecutive blocks covering frames ``0 .. n - 1`` in order.

    Examples
    --------
    A body turning at a constant rate, smoothed in windows of 100 frames:

    >>> import numpy as np
    >>> from scipy.spatial.transform import Rotation
    >>> model = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [-0.2, -0.1, 0.1]])
    >>> t = np.arange(400) / 100.0
    >>> R = Rotation.from_rotvec(np.outer(0.5 * t, [0, 0, 1])).as_matrix()
    >>> pts = np.einsum("kij,mj->kmi", R, model)
    >>> reg = pose.register_pose(pts, model)
    >>> blocks = list(windowed_kinematics(t, reg, pts, model, model[:1], PoseParams(smoothing="gcv"), window=100))
    >>> blocks[0].start, blocks[-1].stop
    (0, 400)
    >>> float(np.round(np.concatenate([b.omega for b in blocks])[:, 2].mean(), 6))
    0.5
    """
    t = np.asarray(t, float)
    n = t.size
    body_points = np.asarray(body_points, float)
    params = dataclasses.replace(params, partial_frames=False)
    if settled is None:
        settled = settle_smoothing(t, registration, points, model, params, window=window)
    window = settled.window
    plan = window_plan(n, window, settled.margin)
    band = blend_band(settled)
    step = float(np.median(np.diff(t))) if n > 1 else 1.0
    tick = counter(progress, "kinematics", "smoothing the pose in windows", len(plan))
    pending = None                                 # the previous window's values over the next cut's band
    for j, (lo, hi, c0, c1) in enumerate(plan):
        tr, tl, why = window_fit(t, registration, points, model, settled, lo, hi, step)
        a = c0 if j == 0 else max(lo, c0 - band)
        b = c1 if j == len(plan) - 1 else min(hi, c1 + band)
        block = _evaluate(tr, tl, lo, a, b, body_points, registration, why)
        if pending is not None:
            yield _blend(pending, _part(block, pending.start, pending.stop))
        keep_to = b if j == len(plan) - 1 else c1 - band
        start = a if pending is None else pending.stop
        if keep_to > start:
            yield _part(block, start, keep_to)
        pending = None if j == len(plan) - 1 else _part(block, c1 - band, b)
        release_pages(points, *(getattr(registration, f.name) for f in dataclasses.fields(registration)))
        tick(j + 1)


def blend_band(settled: SettledSmoothing) -> int:
    """Frames on each side of a cut over which the two windows' values are blended: half the margin, at most
    a quarter of a core (so a core's two bands never meet), at least one.

    Examples
    --------
    >>> blend_band(SettledSmoothing(PoseParams(), (None,) * 6, None, None, 300, {}, window=1000))
    150
    """
    return max(1, min(settled.margin // 2, settled.window // 4))


def _part(block: KinematicsBlock, start: int, stop: int) -> KinematicsBlock:
    """Frames ``start .. stop - 1`` of ``block``."""
    i, k = start - block.start, stop - block.start
    return KinematicsBlock(start, stop, *(getattr(block, f)[i:k] for f in
                                          ("position", "velocity", "acceleration", "omega", "alpha", "reason")))
