"""Plausibility checks before and after the analysis, and the run's verdict.

A measuring instrument must not hand out wrong numbers quietly. Each check
is a pure function of a few numbers and returns a :class:`Check`: its name,
the figure measured, the unit, the ranges in which the figure is ``ok`` and
in which it is only a ``warning`` (beyond them it is ``unreliable``), the
input to look at and a message. A check that cannot be made (an image
folder has no container frame rate) is ``skipped`` and does not enter the
verdict. :func:`verdict` is the worst level of all checks.

Before the analysis (:func:`pre_checks`): the session's fps against each
video container's fps, the rig's image size against the frames and stills,
the camera matrices, the board square size, the marker diameter. After it
(:func:`post_checks`): the reprojection residuals per camera against the
calibration's own RMS and the markers' motion per frame, the horse's speed,
the stride frequency, the saddle's peak vertical acceleration, the share of
the saddle's vertical acceleration the static shot's pixel noise leaves
uncertain (:func:`check_static_shot`).

Plausible ranges of horse locomotion (approximate, for ridden horses):

- speed: walk about 6.4 km/h, trot 13-19 km/h, canter 16-27 km/h, gallop
  40-48 km/h on average; the sprint records are 70.76 km/h (Thoroughbred,
  Guinness World Records 2008) and about 88 km/h over a quarter mile
  (American Quarter Horse). Encyclopaedic values, e.g. Wikipedia "Horse
  gait"; H. M. Clayton, *The Dynamic Horse* (2004) gives the same order.
- stride frequency: about 0.8-1 Hz at walk, 1.3-1.6 Hz at trot, 1.5-2 Hz at
  canter, up to about 2.5 Hz (150-160 strides per minute) for racehorses at
  full gallop (Heglund, Taylor & McMahon, Science 186:1112, 1974, for the
  scaling of stride frequency with speed and size).
- saddle vertical acceleration: the trunk rises and falls some 3-10 cm once
  or twice per stride, so its acceleration A (2 pi f)^2 is of order 2-40 m/s^2
  from walk to gallop; the thesis measured a peak of 11.7 m/s^2 at canter
  (Dogan 2009, Table 8.7). More than 80 m/s^2 (8 g) at the saddle is not
  locomotion.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from .detection.timeshift import MIN_CURRENT_PX, MISS_PX
from .frames import HORSE_STRIDE_HZ
from .pose import predicted_registration_rms
from .rigid import RIGID_MOTION_HALF_WINDOW_S
from .sources import FrameSource, read_still
from .steps.base import longest_run
from .uncertainty import (SaddleScatter, StaticShotRefused, StaticShotUncertainty, saddle_scatter,
                          static_shot_uncertainty, written_saddle_sensitivity)

LEVELS = ("ok", "warning", "unreliable")
SKIPPED = "skipped"
FORMAT = "horsemocap-quality/1"


@dataclass(frozen=True)
class Check:
    """One plausibility check.

    Attributes
    ----------
    name : str
    figure : float or None
        The value measured (None when skipped).
    unit : str
    level : str
        ``"ok"``, ``"warning"``, ``"unreliable"`` or ``"skipped"``.
    ok, warning : (low, high)
        The figure is ``ok`` inside ``ok``, a ``warning`` inside ``warning``
        and ``unreliable`` outside it (None = unbounded on that side).
    threshold : str
        The ranges in words.
    input : str
        What to look at (a file, a field).
    message : str
    """

    name: str
    figure: float | None
    unit: str
    level: str
    ok: tuple
    warning: tuple
    threshold: str
    input: str
    message: str

    def to_dict(self) -> dict:
        d = asdict(self)
        d["ok"], d["warning"] = list(self.ok), list(self.warning)
        if d["figure"] is not None and not math.isfinite(d["figure"]):
            d["figure"] = str(d["figure"])  # JSON has no inf/nan
        return d


def _inside(x, rng) -> bool:
    lo, hi = rng
    return (lo is None or x >= lo) and (hi is None or x <= hi)


def _range_text(rng, unit) -> str:
    lo, hi = rng
    if lo is None and hi is None:
        return "any value"
    if lo is None:
        return f"<= {hi:g} {unit}"
    if hi is None:
        return f">= {lo:g} {unit}"
    return f"{lo:g}..{hi:g} {unit}"


def range_check(name, figure, unit, ok, warning, input_, what) -> Check:
    """A figure against an ``ok`` range and a wider ``warning`` range."""
    threshold = f"ok {_range_text(ok, unit)}; unreliable outside {_range_text(warning, unit)}"
    if figure is None:
        return Check(name, None, unit, SKIPPED, ok, warning, threshold, input_, f"{what}: not available")
    figure = float(figure)
    if not math.isfinite(figure):
        level = "unreliable"
    elif _inside(figure, ok):
        level = "ok"
    elif _inside(figure, warning):
        level = "warning"
    else:
        level = "unreliable"
    msg = f"{what} {figure:.4g} {unit}".rstrip() + ("" if level == "ok" else f" ({level}; {threshold})")
    return Check(name, figure, unit, level, ok, warning, threshold, input_, msg)


def verdict(checks) -> str:
    """The worst level of the checks (``skipped`` ones do not count); ``ok`` if none."""
    levels = [c.level for c in checks if c.level in LEVELS]
    return max(levels, key=LEVELS.index) if levels else "ok"


def quality_record(checks) -> dict:
    """The content of ``quality.json``."""
    return {"format": FORMAT, "verdict": verdict(checks), "checks": [c.to_dict() for c in checks]}


# ---------------------------------------------------------------------------
# checks before the analysis
# ---------------------------------------------------------------------------

def check_fps_against_container(session_fps: float, container_fps: dict, sources: dict,
                                input_="session.json 'fps'") -> Check:
    """The session's ``fps`` against each video container's frame rate.

    Accelerations scale with fps^2, so a relative fps error e gives about 2e
    in every acceleration and comfort figure. ``ok`` up to 0.5 % (29.97 vs
    30 is 0.1 %), ``warning`` up to 2.5 % (5 % in acceleration, the
    accuracy the end-to-end test asks of the comfort figures), beyond that
    ``unreliable`` (25 fps given for 30 fps videos: 17 %).

    Parameters
    ----------
    session_fps : float
    container_fps : dict
        Camera -> the container's frame rate, or None (an image folder, or a
        container that does not say).
    sources : dict
        Camera -> path (named in the message).
    """
    known = {c: f for c, f in container_fps.items() if f is not None and math.isfinite(f) and f > 0}
    ok, warn = (0.0, 0.5), (0.0, 2.5)
    if not known:
        return range_check("fps_vs_container", None, "%", ok, warn, input_,
                           "session fps against the video containers (image folders carry no frame rate)")
    dev = {c: 100 * abs(session_fps / f - 1) for c, f in known.items()}
    worst = max(dev, key=dev.get)
    check = range_check("fps_vs_container", dev[worst], "%", ok, warn, f"{input_} and {sources[worst]}",
                        f"session fps {session_fps:g} vs {known[worst]:g} in camera '{worst}' "
                        f"({sources[worst]}): deviation")
    return check


def check_image_size(rig_sizes: dict, image_sizes: dict, input_="rig.toml 'size'") -> Check:
    """The rig's image size per camera against the frames and stills.

    A calibration holds for one image size: other frames (a resized or
    cropped video) put every intrinsic parameter off. The figure is the
    number of images whose (width, height) differs from the rig's;
    any is ``unreliable``.

    Parameters
    ----------
    rig_sizes : dict
        Camera -> (width, height) of the rig.
    image_sizes : dict
        ``(camera, path)`` -> (width, height) of a frame or still.
    """
    bad = [(cam, path, wh) for (cam, path), wh in image_sizes.items()
           if cam in rig_sizes and tuple(wh) != tuple(rig_sizes[cam])]
    if not bad:
        return range_check("image_size", 0, "images", (0, 0), (0, 0), input_,
                           "images whose size differs from the rig's:")
    cam, path, wh = bad[0]
    c = range_check("image_size", len(bad), "images", (0, 0), (0, 0), f"{input_} and {path}",
                    "images whose size differs from the rig's:")
    return Check(c.name, c.figure, c.unit, c.level, c.ok, c.warning, c.threshold, c.input,
                 f"{path} is {wh[0]}x{wh[1]} px but the rig's camera '{cam}' was calibrated at "
                 f"{rig_sizes[cam][0]}x{rig_sizes[cam][1]} px ({len(bad)} image(s) differ): unreliable")


def camera_matrix_condition(matrix, size) -> float:
    """Condition number of ``K`` with pixels scaled by the image diagonal.

    About 1-3 for ordinary lenses (fx near the diagonal, the principal point
    near the centre); it grows as the lens gets extremely long or short and
    is infinite for a singular or non-finite matrix.
    """
    K = np.asarray(matrix, float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        return float("inf")
    d = math.hypot(*size) if size[0] > 0 and size[1] > 0 else 1.0
    Kn = np.diag([1 / d, 1 / d, 1.0]) @ K
    s = np.linalg.svd(Kn, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def check_camera_matrices(cameras, input_="rig.toml 'matrix'") -> Check:
    """Every camera matrix finite and well conditioned, its principal point in the image.

    Figure: the worst :func:`camera_matrix_condition`. ``ok`` up to 20 (a
    focal length up to some 20 image diagonals: a field of view of about
    3 deg), ``warning`` up to 1000, beyond (or non-finite, singular, a
    principal point outside the image, non-finite pose) ``unreliable``.

    Parameters
    ----------
    cameras : iterable of :class:`horsemocap.camera.Camera`
    """
    worst, worst_cam, problem = 0.0, None, None
    for cam in cameras:
        cond = camera_matrix_condition(cam.matrix, cam.size)
        pose_ok = np.all(np.isfinite(cam.rotation)) and np.all(np.isfinite(cam.translation)) \
            and np.all(np.isfinite(cam.distortions))
        cx, cy = (cam.matrix[0, 2], cam.matrix[1, 2]) if np.all(np.isfinite(cam.matrix)) else (np.nan, np.nan)
        if not pose_ok:
            problem, cond = f"camera '{cam.name}': non-finite distortion, rotation or translation", float("inf")
        elif not (0 <= cx <= cam.size[0] and 0 <= cy <= cam.size[1]):
            problem, cond = (f"camera '{cam.name}': principal point ({cx:.1f}, {cy:.1f}) outside the "
                             f"{cam.size[0]}x{cam.size[1]} image"), float("inf")
        if worst_cam is None or cond > worst:
            worst, worst_cam = cond, cam.name
    c = range_check("camera_matrices", worst, "", (None, 20.0), (None, 1000.0), input_,
                    f"worst condition number of a camera matrix (camera '{worst_cam}', pixels over the image diagonal):")
    if problem:
        return Check(c.name, c.figure, c.unit, "unreliable", c.ok, c.warning, c.threshold, c.input,
                     problem + ": unreliable")
    return c


def check_board_square(square_size_m, input_="session.json 'calibration.board.square_size_m'") -> Check:
    """Checkerboard square size: ``ok`` 5 mm-0.3 m, ``warning`` 2 mm-1 m.

    The calibration's translations (and every length and acceleration)
    scale with it: 10 "m" for 0.1 m makes a horse at 1771 km/h. Printed
    boards have squares of some millimetres to a few centimetres; the
    thesis' rig used a 0.8 x 1.5 m board with 100 mm squares.
    """
    return range_check("board_square_size", square_size_m, "m", (0.005, 0.3), (0.002, 1.0), input_,
                       "checkerboard square size" if square_size_m is not None else
                       "checkerboard square size (no board: the session gives a rig)")


def check_marker_diameter(diameter_m, input_="session.json 'markers.diameter_m'") -> Check:
    """Marker diameter: ``ok`` 1-20 cm, ``warning`` 5 mm-0.5 m (the thesis' stickers: some cm)."""
    return range_check("marker_diameter", diameter_m, "m", (0.01, 0.2), (0.005, 0.5), input_, "marker diameter")


# ---------------------------------------------------------------------------
# checks after the analysis
# ---------------------------------------------------------------------------

def check_horse_speed(speed_kmh, input_="comfort.csv 'vel_x_avg'") -> Check:
    """Average speed: ``ok`` 2-71 km/h (slow walk to the Thoroughbred record), ``warning`` 0.5-90 km/h."""
    return range_check("horse_speed", speed_kmh, "km/h", (2.0, 71.0), (0.5, 90.0), input_,
                       "average speed of the horse")


def check_stride_frequency(frequency_hz, input_="stride frequency = fps / period_frames",
                           faster_hz: float | None = None) -> Check:
    """Stride frequency: ``ok`` inside :data:`horsemocap.frames.HORSE_STRIDE_HZ` (0.7-2.7 Hz, walk to racing
    gallop), ``warning`` 0.4-3.5 Hz."""
    check = range_check("stride_frequency", frequency_hz, "Hz", HORSE_STRIDE_HZ, (0.4, 3.5), input_,
                        "stride frequency")
    if faster_hz is not None and check.level == "ok":   # ``faster_hz``: the record also repeats that fast
        check = replace(check, level="warning", message=(
            f"{check.message}; the record also repeats at {faster_hz:.3g} Hz, faster than a horse strides, and "
            "the period was taken twice as long or more: a gait with two alike beats per stride (a trot) "
            "does this; check the period (notebook 06) or give it (--period)"))
    return check


def check_saddle_acceleration(peak_mps2, input_="kinematics.csv 'ay_mps2' of the saddle, every frame") -> Check:
    """Peak vertical saddle acceleration: ``ok`` 0.5-40 m/s^2, ``warning`` 0.2-80 m/s^2 (see the module).

    ``peak_mps2``: the largest ``|ay|`` of the saddle written to kinematics.csv
    (:func:`written_saddle_acceleration`), over the whole record, its ends included.
    """
    return range_check("saddle_acceleration", peak_mps2, "m/s^2", (0.5, 40.0), (0.2, 80.0), input_,
                       "peak vertical acceleration of the saddle")


def written_saddle_acceleration(analysis) -> np.ndarray | None:
    """The saddle's vertical acceleration (m/s^2, motion frame, y down) per analysed frame, as kinematics.csv
    writes it (the rigid-body step's ``saddle_acceleration``, column y); None before that step."""
    rb = analysis.rigid_body
    if rb is None or rb.saddle_acceleration is None:
        return None
    return np.asarray(rb.saddle_acceleration, float)[:, 1]


#: The record's ends (its first and last half stride) against its middle (:func:`stride_repeat`): the rms
#: change from one stride to the next at an end, over that in the middle (floored at
#: ``STRIDE_CHANGE_FLOOR`` of the signal's rms): ``ok`` up to 2, ``warning`` up to 4, ``unreliable`` above.
END_RATIO = (2.0, 4.0)
#: A horse's strides differ a little; the middle's stride-to-stride change is taken as at least this share
#: of the acceleration's rms (so a perfectly repeating middle does not make every end look bad).
STRIDE_CHANGE_FLOOR = 0.1


def stride_repeat(values, period_frames: float) -> dict | None:
    """How well the record's ends repeat the stride, against its middle.

    For a stride period ``T`` (frames, rounded), each frame's value is
    compared with the same phase one stride inwards: ``x[k] - x[k + T]`` in
    the first half of the record, ``x[k] - x[k - T]`` in the second. The rms
    of these changes over the first half stride (``start``), the last half
    stride (``end``) and the frames between (``middle``) say whether the
    ends hold the same motion as the middle: a smoothing spline's end, a
    marker lost or biased near the record's end, show there and nowhere
    else. NaN frames are left out.

    Returns ``{"start", "end", "middle", "rms", "ratio"}`` (``ratio``: the
    larger end over ``max(middle, STRIDE_CHANGE_FLOOR * rms)``), or None when
    the record is shorter than two strides.

    Examples
    --------
    >>> t = np.arange(200)
    >>> x = np.sin(2 * np.pi * t / 40)
    >>> round(stride_repeat(x, 40)["ratio"], 3)
    0.0
    >>> x[-10:] += 3.0                      # the last frames wrong
    >>> stride_repeat(x, 40)["ratio"] > 4
    True
    """
    x = np.asarray(values, float)
    T = int(round(float(period_frames))) if period_frames and np.isfinite(period_frames) else 0
    n = x.size
    if T < 2 or n < 2 * T:
        return None
    k = np.arange(n)
    change = np.where(k < n / 2, x - np.roll(x, -T), x - np.roll(x, T))
    half = max(T // 2, 1)
    parts = {"start": change[:half], "end": change[n - half:], "middle": change[half:n - half]}

    def rms(v):
        v = v[np.isfinite(v)]
        return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")

    out = {key: rms(v) for key, v in parts.items()}
    out["rms"] = rms(x - np.nanmean(x))
    ref = max(out["middle"], STRIDE_CHANGE_FLOOR * out["rms"])
    out["ratio"] = float(max(out["start"], out["end"]) / ref) if ref > 0 else float("nan")
    return out


def check_record_ends(values, period_frames, input_="kinematics.csv 'ay_mps2' of the saddle: its first and last "
                                                   "half stride against the middle") -> Check:
    """Do the record's ends hold the same motion as its middle? (:func:`stride_repeat`).

    The comfort indicators use every written frame, the ends as much as the
    middle, and a pose trajectory is least constrained at its ends (one side
    only, a marker entering or leaving a view, a cover near the end): the
    ends get the same scrutiny as the middle. ``ok`` when each end repeats
    the stride within twice the middle's stride-to-stride change (or 10 % of
    the signal's rms), ``warning`` within 4 times, ``unreliable`` beyond.
    """
    ok, warn = END_RATIO
    threshold = f"ok <= {ok:g}; warning <= {warn:g}; unreliable above"
    rep = stride_repeat(values, period_frames) if values is not None else None
    if rep is None or not np.isfinite(rep["ratio"]):
        return Check("record_ends", None, "ratio", SKIPPED, (None, ok), (None, warn), threshold, input_,
                     "the record's ends against its middle: not available (no stride period, or under "
                     "two strides)")
    check = range_check("record_ends", rep["ratio"], "ratio", (None, ok), (None, warn), input_,
                        "stride-to-stride change at the record's ends over the middle's")
    what = (f"rms change from one stride to the next: first half stride {rep['start']:.3g}, last half stride "
            f"{rep['end']:.3g}, middle {rep['middle']:.3g} m/s^2 (signal rms {rep['rms']:.3g})")
    if check.level == "ok":
        msg = f"the record's ends repeat the stride as its middle does: {what}"
    else:
        msg = (f"the record's ends do not repeat the stride as its middle does: {what}; the saddle's acceleration "
               "there (and the comfort figures that use it) is suspect: a marker lost, biased or partly covered "
               "near an end, or the horse changed its motion; look at kinematics.csv's first and last frames")
    return replace(check, message=msg, threshold=threshold)


#: ``ok`` / ``warning`` bounds (%) of the saddle acceleration's difference between a long record's fit and the
#: same smoothing with a knot at every frame (:func:`check_spline_basis`): the 10 % to which the saddle's
#: acceleration is meant to hold, and half of it.
SPLINE_BASIS_PCT = (5.0, 10.0)


def check_spline_basis(resolution, point: str = "the saddle", input_: str | None = None) -> Check:
    """Does a long record's spline basis hold the saddle's motion? (:func:`horsemocap.basis_check.basis_resolution`).

    A record longer than a quintic spline fits with a knot at every frame
    (about 400 frames) has knots every few frames; where they are too far
    apart in seconds for the motion's fast part, the saddle's acceleration
    and every comfort figure lose that part whatever the smoothing. The
    record's middle, fitted again with a knot at every frame, says how much:
    ``ok`` within :data:`SPLINE_BASIS_PCT`'s first bound, ``warning`` within
    its second, ``unreliable`` beyond. ``point``: the body point compared,
    in words (the ``kinematics`` command's first hidden point).

    Examples
    --------
    >>> from horsemocap.basis_check import BasisResolution
    >>> check_spline_basis(BasisResolution(3, 0.06, (8.04, 15.94), (10.02, 13.96), 13.8)).level
    'unreliable'
    """
    ok, warn = SPLINE_BASIS_PCT
    threshold = f"ok <= {ok:g} %; warning <= {warn:g} %; unreliable above"
    if input_ is None:
        input_ = (f"{point}'s acceleration (kinematics.csv) on the pose record's middle, against the same smoothing "
                  "with a knot at every frame")
    r = resolution
    knots = f"a knot every {r.knot_step} frames ({1000 * r.knot_spacing_s:.0f} ms)"
    if not np.isfinite(r.difference_pct):
        return Check("spline_basis", None, "%", SKIPPED, (None, ok), (None, warn), threshold, input_,
                     f"the pose record's spline has {knots}; its effect on {point}'s acceleration: not "
                     f"available ({r.reason})")
    check = range_check("spline_basis", r.difference_pct, "%", (None, ok), (None, warn), input_,
                        f"{point}'s acceleration's change with a knot at every frame")
    what = (f"the pose record is longer than a spline fits with a knot at every frame, so its fit has {knots}; "
            f"fitted again with a knot at every frame ({r.stretch_s[0]:.2f}..{r.stretch_s[1]:.2f} s, the same "
            f"smoothing) {point}'s acceleration changes by {r.difference_pct:.1f} % rms over "
            f"{r.compared_s[0]:.2f}..{r.compared_s[1]:.2f} s (kinematics.csv's time_s)")
    if check.level == "ok":
        msg = f"{what}: the basis holds the motion"
    else:
        msg = (f"{what}: the knots are too far apart in time for the motion's fast part, which {point}'s "
               "acceleration (and every figure computed from it) then loses; a shorter recording (or pass) or a "
               "higher frame rate gives the spline a knot at every frame")
    return replace(check, message=msg, threshold=threshold)


def check_reprojection_residuals(residual_px: dict, motion_px_per_frame: dict, calibration_rms_px=None,
                                 input_="sync offsets and rig") -> Check:
    """Median reprojection residual per camera against the calibration and the markers' motion.

    A consistent point reprojects within the calibration's own error: its
    RMS over the board corners, ``e``. Above ``3 e`` the detections disagree
    with the rig more than its corners did: ``warning``. A sync error of k
    frames moves a marker by k times its image motion per frame ``m`` in
    one camera against the others; whole-frame sync leaves at most half a
    frame of phase between free-running cameras, so a residual above
    ``max(3 e, m / 2)`` cannot come from timing within a frame:
    ``unreliable`` (a one-frame error gives about ``m``). The figure is the
    worst camera's median residual; ``ok``/``warning`` are that camera's.

    Parameters
    ----------
    residual_px : dict
        Camera -> residuals (px) of the analysed frames' points.
    motion_px_per_frame : dict
        Camera -> median image displacement of a marker between frames (px).
    calibration_rms_px : float or None
        The rig's RMS reprojection error (``rig.toml`` metadata ``error``).
    """
    e = float(calibration_rms_px) if calibration_rms_px is not None and math.isfinite(calibration_rms_px) \
        and calibration_rms_px > 0 else None
    results = []
    for cam, r in residual_px.items():
        r = np.asarray(r, float)
        med = float(np.nanmedian(r)) if np.isfinite(r).any() else float("nan")
        m = float(motion_px_per_frame.get(cam, float("nan")))
        warn_at = 3 * e if e is not None else None
        unrel_at = max(3 * e if e is not None else 0.0, m / 2 if math.isfinite(m) else 0.0)
        if unrel_at <= 0:
            unrel_at = None
        ok = (None, warn_at if warn_at is not None else unrel_at)
        check = range_check("reprojection_residuals", med, "px", ok, (None, unrel_at), input_,
                            f"median reprojection residual of camera '{cam}'")
        results.append((LEVELS.index(check.level) if check.level in LEVELS else -1,
                        med / unrel_at if unrel_at else 0.0, cam, m, check))
    if not results:
        return range_check("reprojection_residuals", None, "px", (None, None), (None, None), input_,
                           "reprojection residuals")
    results.sort(key=lambda t: (t[0], t[1] if math.isfinite(t[1]) else math.inf))
    _, _, cam, m, check = results[-1]
    detail = (f" (calibration RMS {e:.3g} px" if e is not None else " (calibration RMS unknown") + \
        f", markers move {m:.3g} px per frame)"
    if check.level in ("warning", "unreliable"):
        detail += "; check the sync offsets (a frame off gives about one frame's motion) and the rig"
    return Check(check.name, check.figure, check.unit, check.level, check.ok, check.warning, check.threshold,
                 check.input, check.message + detail)


# ---------------------------------------------------------------------------
# gathering the inputs (reads the session's files; the checks above are pure)
# ---------------------------------------------------------------------------

def _image_sizes(session, rig_cams) -> dict:
    sizes = {}
    for cam in session.cameras:
        if cam not in rig_cams:
            continue
        f = FrameSource(session.motion[cam]).frame(0, color=False)
        sizes[(cam, session.motion[cam])] = (f.shape[1], f.shape[0])
        for group in (session.plumb, session.static):
            if group:
                img = read_still(group[cam], color=False)
                sizes[(cam, group[cam])] = (img.shape[1], img.shape[0])
    return sizes


def rig_checks(session, rig) -> list[Check]:
    """Image size and camera-matrix checks of a rig against a session's images."""
    rig_sizes = {c.name: c.size for c in rig.cameras}
    return [check_image_size(rig_sizes, _image_sizes(session, rig_sizes)), check_camera_matrices(rig.cameras)]


def pre_checks(session, rig=None) -> list[Check]:
    """Checks of a session before the analysis (``rig``: the rig it will use, if known)."""
    fps = {c: FrameSource(session.motion[c]).container_fps for c in session.cameras}
    checks = [check_fps_against_container(session.fps, fps, session.motion),
              check_board_square(session.board.square_size_m if session.board is not None else None),
              check_marker_diameter(session.marker_diameter_m)]
    if rig is not None:
        checks += rig_checks(session, rig)
    return checks


def marker_motion_px(marker_px: dict, segment=None) -> dict:
    """Camera -> median displacement of a marker between consecutive frames (px)."""
    out = {}
    for cam, px in marker_px.items():
        px = np.asarray(px, float)
        if segment is not None:
            px = px[segment[0]:segment[1]]
        d = np.linalg.norm(np.diff(px, axis=0), axis=-1)
        out[cam] = float(np.nanmedian(d)) if np.isfinite(d).any() else float("nan")
    return out


def _shift_residuals(v: dict) -> str:
    """``median residual A -> B px`` of a camera's sync check; a residual at the cap of
    :data:`horsemocap.detection.timeshift.MISS_PX` means the markers were not found there."""
    def px(x):
        if not math.isfinite(x):
            return "not measurable"
        return f"markers not found (>= {MISS_PX:g} px)" if x >= MISS_PX else f"{x:.2g} px"

    return f"median residual {px(v.current_px)} at the flash's offset -> {px(v.best_px)}"


def _markers_settle(check) -> bool:
    """Did the markers confirm the offset a camera kept between two flash candidates? Only if the check was
    decided and the others' markers fell on this camera's regions at that offset (median residual below
    :data:`horsemocap.detection.timeshift.MIN_CURRENT_PX`). The other candidate need not lie within the shifts
    tried: were it the flash, the kept offset would be off by its distance, and a moving horse's markers
    would not fall on the regions (held-out and fresh sessions: 0.07-0.13 px with runner-ups 50-128 frames
    away); a check that found no markers there settles nothing."""
    if check is None or not check.decided:
        return False
    return bool(math.isfinite(check.best_px) and check.best_px < MIN_CURRENT_PX)


def check_sync_by_markers(sync_check: dict, input_="sync offsets (the flash)", ambiguous=None) -> Check:
    """Did the markers confirm every camera's flash offset?

    ``sync_check``: camera -> :class:`horsemocap.steps.CameraSyncCheck` (the
    detect step's ``sync_check``; ``decided`` False where too few
    marker-frames of the other cameras fell into the camera to test a shift:
    not a confirmation; ``moved``: a round moved the camera; ``settled``:
    the last round moved none).
    The figure is the largest total shift in whole frames. No camera moved and
    every camera checked is ``ok``; a camera the markers moved, or could not
    check, is a ``warning`` (the results use the corrected offsets; the flash
    was found in another frame, so check it); corrections still moving when
    the rounds ran out are ``unreliable`` (the offsets used were never
    confirmed). ``ambiguous``: camera -> the frame of a second flash
    candidate nearly as likely (``flash_ambiguous`` of the sync step); such a
    camera the markers did not confirm (undecided, or no markers on its
    regions at the offset kept) is a ``warning``.
    """
    threshold = "no correction and every camera checked: ok; a correction or a camera unchecked: warning; " \
        "corrections still moving when the rounds ran out: unreliable"
    ambiguous = dict(ambiguous or {})
    unsure = {c: f for c, f in ambiguous.items() if not _markers_settle(sync_check.get(c))}
    unsure_text = ("two flash candidates of similar score and no check by the markers in " + ", ".join(
        f"camera '{c}' (frame {f} nearly as likely as the one taken)" for c, f in unsure.items()))
    if not sync_check:
        if unsure:
            return Check("sync_by_markers", None, "frames", "warning", (0, 0), (None, None), threshold, input_,
                         unsure_text + "; check the flash in those videos, or give the offsets (--offsets)")
        return Check("sync_by_markers", None, "frames", SKIPPED, (0, 0), (None, None), threshold, input_,
                     "the flash offsets checked by the markers: not available (offsets given, or fewer "
                     "than three cameras)")
    shifts = {c: int(v.shift) for c, v in sync_check.items()}
    worst = max(abs(v) for v in shifts.values())
    moved = [c for c, v in sync_check.items() if v.moved]
    undecided = [c for c, v in sync_check.items() if not v.decided]
    settled = all(v.settled for v in sync_check.values())
    level = "unreliable" if not settled else "warning" if moved or undecided or unsure else "ok"
    parts = [unsure_text] if unsure else []
    if moved:
        parts.append("the markers moved the flash offset of " + ", ".join(
            f"camera '{c}' by {shifts[c]:+d} frame(s) in all ({_shift_residuals(sync_check[c])})" for c in moved)
            + "; the results use the corrected offsets")
    if undecided:
        parts.append("the markers could not check the flash offset of " + ", ".join(
            f"camera '{c}' ({sync_check[c].n_points} marker-frames of the other cameras projected into it)"
            for c in undecided))
    if not settled:
        n = max(int(v.rounds) for v in sync_check.values())
        parts.append(f"after {n} rounds the markers still moved an offset: the offsets the results use were not "
                     "confirmed (the flash may be wrong in two cameras); give the offsets (--offsets) after "
                     "finding the flash in each video")
    if parts:
        cams = sorted(set(moved) | set(undecided) | set(unsure))
        msg = "; ".join(parts) + (f"; check the flash in the video of {', '.join(repr(c) for c in cams)}" if cams else "")
    else:
        msg = "the markers confirm every camera's flash offset"
    return Check("sync_by_markers", float(worst), "frames", level, (0, 0), (None, None), threshold, input_, msg)


#: Camera whose sub-frame offset moved this far (frames) from the flash's is a correction: the flash's whole
#: frame was wrong. Less only re-splits the offset between whole frames and the fraction (the whole-frame check
#: rounds a camera 0.9 frame after another to the next frame; the fraction moves with it).
FRACTION_CORRECTION_FRAMES = 0.5


def check_subframe_sync_by_markers(sync_check: dict, flash_fraction: dict, final_fraction: dict,
                                   sync_residual_px: dict, ambiguous=None,
                                   input_="sync offsets (the flash, refined by the markers)",
                                   flash_whole_frames: bool = False) -> Check:
    """Did the markers confirm every free-running camera's flash offset, fractions of a frame included?

    Free-running cameras expose a fraction of a frame after one another, so
    the whole-frame check of the flash (:func:`check_sync_by_markers`) rounds
    each camera's offset to the nearest whole frame of the others' markers:
    a camera 0.9 frame after the reference is "moved" by a frame, and with
    three cameras the rounds can chase one another between the two whole
    frames that bracket the true offset without settling. Those moves say
    nothing about the flash; what does is where the sub-frame fit ended:

    - the figure is the largest distance (frames) between a camera's offset
      with its fraction as the flash gave it (``flash_fraction``) and as the
      markers refined it (``final_fraction``);
    - a camera is confirmed when the others' markers fall on its positions
      at the refined offset: its median sync residual (``sync_residual_px``,
      :func:`horsemocap.subframe.others_residual`) is below
      :data:`horsemocap.detection.timeshift.MIN_CURRENT_PX`, the bar the
      whole-frame check sets genlocked cameras;
    - ``ok``: every camera within :data:`FRACTION_CORRECTION_FRAMES` of the
      flash and confirmed; ``warning``: a camera moved further (the flash was
      found in another frame: the results use the markers' offset) or is not
      confirmed (an ambiguous flash included); ``unreliable``: the whole-frame
      rounds did not settle and a camera is not confirmed (the offsets used
      were never checked).

    Parameters
    ----------
    sync_check : dict
        Camera -> :class:`horsemocap.steps.CameraSyncCheck` (the whole-frame check).
    flash_fraction, final_fraction : dict
        Camera -> offset with fraction (frames after the reference camera's).
    sync_residual_px : dict
        Camera -> median sync residual (px) at the refined offsets.
    ambiguous : dict, optional
        Camera -> the frame of a second flash candidate nearly as likely.
    flash_whole_frames : bool
        The flash lit every camera's first lit frame fully, so it gave whole frames only and the markers
        found every fraction: a camera then moved by less than a whole frame from the flash's is no correction
        (the flash only placed it within a frame).

    Examples
    --------
    >>> check_subframe_sync_by_markers({}, {"left": 0.0, "middle": 37.0}, {"left": 0.0, "middle": 36.44},
    ...                                {"left": 0.1, "middle": 0.04}, flash_whole_frames=True).level
    'ok'
    >>> c = check_subframe_sync_by_markers({}, {"left": 0.0, "middle": 26.25}, {"left": 0.0, "middle": 26.06},
    ...                                    {"left": 0.1, "middle": 0.04})
    >>> c.level, round(c.figure, 2)
    ('ok', 0.19)
    >>> check_subframe_sync_by_markers({}, {"left": 0.0, "middle": 27.25}, {"left": 0.0, "middle": 26.06},
    ...                                {"left": 0.1, "middle": 0.04}).level
    'warning'
    """
    limit = 1.0 if flash_whole_frames else FRACTION_CORRECTION_FRAMES
    threshold = (f"every camera within {limit:g} frame of the flash's offset and the others' "
                 f"markers on it (sync residual < {MIN_CURRENT_PX:g} px): ok; a camera moved further or not "
                 "confirmed: warning; whole-frame rounds unsettled and a camera not confirmed: unreliable")
    moved = {c: abs(float(final_fraction[c]) - float(flash_fraction[c])) for c in final_fraction if c in flash_fraction}
    resid = {c: float(v) for c, v in sync_residual_px.items()}
    unconfirmed = sorted(c for c, v in resid.items() if not (math.isfinite(v) and v < MIN_CURRENT_PX))
    corrected = sorted(c for c, v in moved.items() if v >= limit)
    settled = all(v.settled for v in sync_check.values())
    level = "unreliable" if unconfirmed and not settled else "warning" if corrected or unconfirmed else "ok"
    parts = []
    if corrected:
        parts.append("the markers moved the flash's offset of " + ", ".join(
            f"camera '{c}' from {flash_fraction[c]:.3f} to {final_fraction[c]:.3f} frames" for c in corrected)
            + "; the results use the markers' offsets; check the flash in those videos")
    if unconfirmed:
        amb = dict(ambiguous or {})
        parts.append("the others' markers do not fall on " + ", ".join(
            f"camera '{c}' (median sync residual {resid[c]:.3g} px"
            + (f"; flash frame {amb[c]} nearly as likely as the one taken" if c in amb else "") + ")"
            for c in unconfirmed) + ("; the whole-frame rounds did not settle: the offsets used were not confirmed; "
                                     "give the offsets (--offsets, fractions allowed)" if not settled else ""))
    whole = ("the flash lit every camera's first lit frame fully, so it gave whole frames only and the markers "
             "found the fractions; " if flash_whole_frames else "")
    msg = whole + ("; ".join(parts) if parts else (
        "the markers confirm every camera's offset to a fraction of a frame (largest move from the flash's "
        f"{max(moved.values(), default=0.0):.3f} frame; sync residuals "
        + ", ".join(f"{c} {v:.3g} px" for c, v in resid.items()) + ")"))
    figure = max(moved.values(), default=0.0)
    return Check("sync_by_markers", float(figure), "frames", level, (0, limit), (None, None),
                 threshold, input_, msg)


#: The sync residual (:func:`horsemocap.subframe.others_residual`, median per camera) of genlocked cameras,
#: where no timing error enters: the detection noise and the calibration alone. The bundled session and the
#: genlocked canter and sitting-trot sessions of the virtual laboratory give 0.018-0.050 px (640x480 to
#: 1280x720); real markers and a real calibration give more, so the calibration's own RMS, when the rig gives
#: it, replaces the floor when larger.
GENLOCKED_SYNC_RESIDUAL_PX = 0.05
#: A timing error of ``d`` frames in one camera puts its marker ``d`` times the markers' motion per frame from
#: the others' points; the fractions of a frame beyond the genlocked floor for ``ok`` and ``warning``.
SYNC_RESIDUAL_FRAMES = (0.05, 0.15)


def check_sync_residual(sync_residual_px: dict | None, motion_px_per_frame: dict, calibration_rms_px=None,
                        input_="sync offsets with fraction (analysis.json) and the rolling-shutter readout") -> Check:
    """The residual of free-running cameras' synchronisation after the sub-frame correction.

    The figure is the worst camera's median distance (px) of its positions
    at the reference camera's instants from the other cameras' markers
    projected into it (:func:`horsemocap.subframe.others_residual`). On
    genlocked cameras this is the detection and calibration floor ``g``
    (:data:`GENLOCKED_SYNC_RESIDUAL_PX`, or the calibration RMS when larger);
    a camera whose offset is ``d`` frames off adds about ``d m`` (``m`` the
    markers' image motion per frame). ``ok`` up to ``3 g + 0.05 m`` (within
    the floor's spread, or a twentieth of a frame), ``warning`` up to
    ``6 g + 0.15 m``, beyond ``unreliable`` (the cameras see the markers at
    instants the correction did not bring together: a wrong fraction, an
    unknown rolling shutter, a drifting rate). Skipped for genlocked
    sessions (``sync_residual_px`` None): there the reprojection residuals
    judge the same thing.

    Examples
    --------
    >>> check_sync_residual({"left": [0.05, 0.1], "right": [0.1, 0.12]}, {"left": 10.0, "right": 10.0}).level
    'ok'
    >>> check_sync_residual({"left": [0.05, 0.1], "right": [3.0, 3.2]}, {"left": 10.0, "right": 10.0}).level
    'unreliable'
    >>> check_sync_residual(None, {}).level
    'skipped'
    """
    e = float(calibration_rms_px) if calibration_rms_px is not None and math.isfinite(calibration_rms_px) \
        and calibration_rms_px > 0 else 0.0
    floor = max(GENLOCKED_SYNC_RESIDUAL_PX, e)
    ok_d, warn_d = SYNC_RESIDUAL_FRAMES
    if not sync_residual_px:
        return range_check("sync_residual", None, "px", (None, None), (None, None), input_,
                           "residual of the sub-frame synchronisation (genlocked cameras)")
    worst = None
    for cam, r in sync_residual_px.items():
        r = np.asarray(r, float)
        med = float(np.nanmedian(r)) if np.isfinite(r).any() else float("nan")
        m = float(motion_px_per_frame.get(cam, float("nan")))
        m = m if math.isfinite(m) else 0.0
        check = range_check("sync_residual", med, "px", (None, 3 * floor + ok_d * m), (None, 6 * floor + warn_d * m),
                            input_, f"median sync residual of camera '{cam}' (the others' markers projected into it)")
        key = (LEVELS.index(check.level), med / (6 * floor + warn_d * m) if math.isfinite(med) else math.inf)
        if worst is None or key > worst[0]:
            worst = (key, cam, m, med, check)
    _, cam, m, med, check = worst
    detail = (f" (markers move {m:.3g} px per frame: about {med / m:.3f} frame of timing)" if m > 0 else "")
    if check.level != "ok":
        detail += "; check the offsets' fractions (--offsets), the rolling-shutter readout and the frame rates"
    return replace(check, message=check.message + detail)


def check_marker_geometry(warnings, input_="the markers' layout (static shot) and the frames without a pose") -> Check:
    """Does the marker geometry support the pose the kinematics rest on?

    ``warnings``: the rigid-body step's conditioning messages
    (:func:`horsemocap.pipeline.conditioning`: a thin marker triangle whose
    predicted rotation noise exceeds 1 deg per frame, frames without a pose,
    the thesis versions near the eq. 6.35 singularity). The figure is their
    number: none is ``ok``, any is a ``warning`` (the results are written and
    the messages say which of them to distrust: angular results, far points).
    """
    threshold = "no conditioning warning: ok; any: warning"
    if warnings is None:
        return Check("marker_geometry", None, "warnings", SKIPPED, (0, 0), (None, None), threshold, input_,
                     "the rigid-body step's conditioning: not available")
    warnings = list(warnings)
    level = "ok" if not warnings else "warning"
    msg = "; ".join(warnings) if warnings else "the marker geometry supports the pose in every frame"
    return Check("marker_geometry", float(len(warnings)), "warnings", level, (0, 0), (None, None), threshold,
                 input_, msg)


#: The markers' shape error (median registration residual over the layout's RMS radius, %): ``ok`` up to 5 %,
#: ``warning`` up to 10 %, ``unreliable`` above. A shape error of x % turns the body by about x/100 rad, so a
#: point a layout's radius away errs by about the residual itself and the saddle, further away, by more: at
#: 10 % (about 6 deg) the saddle's path errs by tens of mm, the size of its motion. The residual holds the
#: triangulation's noise as well as any deformation: the thesis' narrow-baseline rig measures depth poorly and
#: its 16 herd sessions give 1.1-2.9 % (hard set 0.1-1.4 %, held-out sessions 0.1-0.7 %), so ``ok`` reaches
#: 5 %; skin sliding over a real horse's back adds a few percent of the markers' spread (a ``warning`` then says
#: the rigid-body assumption is strained). Wrong identities (a marker followed as another, a wrong sync) give
#: more: 18.5 and 21.4 % on the held-out sessions whose flash was found in the wrong frame in two cameras.
RIGIDITY_PCT = (5.0, 10.0)


def check_marker_rigidity(registration_rms_m, model_points, input_="the markers' identities and sync "
                                                                  "(the rigid-body registration)",
                          predicted_rms_m=None) -> Check:
    """Do the markers keep the static shot's shape? (the rigid-body step's assumption, section 6.1).

    The figure is the median registration residual in % of the markers'
    spread; the levels do not depend on why it is large. The message does:
    a residual within :data:`RIGIDITY_EXPLAINED_RATIO` times the one the
    triangulation's own scatter predicts
    (:func:`horsemocap.pose.predicted_registration_rms`) is said to be that
    scatter (noisy views, or views that disagree), not a shape the markers
    lost.

    Parameters
    ----------
    registration_rms_m : (n,) array
        RMS residual of the registration of the static shot's markers onto each frame's (m); NaN where
        no pose.
    model_points : (m, 3) array
        The markers in the static shot (m).
    predicted_rms_m : (n,) array, optional
        The residual the markers' covariances predict per frame (m).

    Examples
    --------
    A 20 mm residual on markers 190 mm from their centroid, as their noise predicts:

    >>> import numpy as np
    >>> model = np.array([[0.2, 0.0, 0.0], [-0.1, 0.17, 0.0], [-0.1, -0.17, 0.0], [0.0, 0.0, 0.19]])
    >>> c = check_marker_rigidity(np.full(9, 0.020), model, predicted_rms_m=np.full(9, 0.018))
    >>> c.level, "the triangulation's scatter" in c.message
    ('unreliable', True)
    """
    ok, warn = RIGIDITY_PCT
    threshold = f"ok <= {ok:g} %; warning <= {warn:g} %; unreliable above"
    r = np.asarray(registration_rms_m, float)
    model = np.asarray(model_points, float)
    if not np.isfinite(r).any() or model.ndim != 2 or len(model) < 3:
        return Check("marker_rigidity", None, "%", SKIPPED, (None, ok), (None, warn), threshold, input_,
                     "the markers' shape in the frames: not available")
    radius = float(np.sqrt(np.mean(np.sum((model - model.mean(0)) ** 2, axis=1))))
    med = float(np.nanmedian(r))
    figure = 100.0 * med / radius
    check = range_check("marker_rigidity", figure, "%", (None, ok), (None, warn), input_,
                        "the markers' shape error")
    what = (f"median registration residual {1000 * med:.2f} mm, {figure:.1f} % of the markers' spread "
            f"({1000 * radius:.0f} mm RMS radius)")
    if check.level == "ok":
        msg = f"the markers keep the static shot's shape: {what}"
    elif check.level == "warning":
        msg = (f"the markers deform against the static shot: {what}; the rigid-body assumption is strained "
               "(skin motion or a marker partly hidden): the saddle point and the angles carry errors of that order")
    else:
        msg = (f"the markers do not keep the static shot's shape: {what}: the tracked points are not the static "
               "shot's markers (wrong identities, a wrong sync offset, a marker followed as another); the "
               "kinematics and comfort numbers rest on the wrong points. Check the sync offsets (a flash found "
               "in the wrong frame), the markers' labels (04) and 'markers.count'")
    scatter = _explained_by_scatter(med, predicted_rms_m)
    if check.level != "ok" and scatter is not None:
        msg = (f"the markers' registration residual is the triangulation's scatter: {what}, against "
               f"{1000 * scatter:.2f} mm that the triangulated markers' own covariances predict for rigid markers. "
               "Either the cameras measure these markers this noisily (depth is the rig's least certain "
               "direction: closer cameras, a wider baseline or markers spread wider reduce it; see "
               "marker_geometry), or the views disagree (a wrong sync offset, a marker taken for another: see "
               "reprojection_residuals); the pose, the saddle point and the comfort figures carry errors of "
               "that order")
    return replace(check, message=msg, threshold=threshold)


#: A median registration residual within this multiple of the one the markers' covariances predict is that
#: scatter (:func:`check_marker_rigidity`): on rigid markers the ratio stays near 1 under white or correlated noise
#: (benchmarks/README.md); a marker that moves on the body, or a deformed static shot, adds to the residual only.
RIGIDITY_EXPLAINED_RATIO = 1.5


def _explained_by_scatter(median_rms: float, predicted_rms_m) -> float | None:
    """The predicted residual's median (m) if it explains ``median_rms``, else None."""
    if predicted_rms_m is None:
        return None
    pred = np.asarray(predicted_rms_m, float)
    if not np.isfinite(pred).any():
        return None
    scatter = float(np.nanmedian(pred))
    return scatter if scatter > 0 and median_rms <= RIGIDITY_EXPLAINED_RATIO * scatter else None


#: Share of the pose frames (%) with a marker left out of the pose for moving against the other markers' rigid
#: motion: ``ok`` up to 25 %, ``warning`` up to 50 %, ``unreliable`` above. The test compares each frame with the
#: median over its neighbours, which holds while most frames keep the rigid shape; past half of them it no longer
#: tells the moved marker from the others. The 25 % is half that breakdown: left-out frames that crowd into part
#: of the record at twice their mean share still leave the median a majority of rigid frames there.
LEFT_OUT_PCT = (25.0, 50.0)


def check_left_out_markers(left_out, fps: float, half_window_s: float = RIGID_MOTION_HALF_WINDOW_S,
                           input_="the pose registration's markers (a marker left out where it moved against "
                                  "the others' rigid motion)") -> Check:
    """How often a marker was left out of the pose for moving against the other markers' rigid motion.

    ``left_out`` (n, m) bool: the pose frames' markers left out
    (:func:`horsemocap.rigid.against_rigid_motion`). The figure is the share
    of frames with a marker left out (%), against :data:`LEFT_OUT_PCT`. A
    run of a marker's left-out frames longer than ``half_window_s`` makes it
    at least a ``warning``: the neighbouring frames' median the test compares
    with then follows the moved marker, and the run's further frames may pass
    unnoticed. With three markers no marker can be left out (skipped).

    Examples
    --------
    >>> lo = np.zeros((100, 4), bool); lo[40:45, 2] = True
    >>> c = check_left_out_markers(lo, 50.0)
    >>> c.level, c.figure
    ('ok', 5.0)
    >>> lo[10:70, 1] = True
    >>> check_left_out_markers(lo, 50.0).level
    'unreliable'
    """
    ok, warn = LEFT_OUT_PCT
    threshold = (f"ok <= {ok:g} % of frames and no run over {half_window_s:g} s; warning <= {warn:g} %; "
                 "unreliable above")
    lo = None if left_out is None else np.asarray(left_out, bool)
    if lo is None or lo.ndim != 2 or lo.shape[1] < 4 or lo.shape[0] == 0:
        return Check("left_out_markers", None, "%", SKIPPED, (None, ok), (None, warn), threshold, input_,
                     "markers left out of the pose: not tested (it takes four or more markers)")
    figure = 100.0 * float(lo.any(axis=1).mean())
    check = range_check("left_out_markers", figure, "%", (None, ok), (None, warn), input_,
                        "frames with a marker left out of the pose")
    runs = {}                                         # marker -> its longest run of left-out frames
    for j in np.flatnonzero(lo.any(axis=0)):
        start, stop = longest_run(lo[:, j])
        runs[int(j)] = stop - start
    per_marker = ", ".join(f"marker {j + 1}: {int(lo[:, j].sum())} frames (longest run {runs[j]})"
                           for j in runs)                                  # numbered from 1, as the plots
    long_runs = [j for j, r in runs.items() if r / float(fps) > half_window_s]
    if not runs:
        return replace(check, message="no marker moved against the others' rigid motion: every marker seen "
                                      "was in the pose")
    what = (f"{figure:.1f} % of the {lo.shape[0]} pose frames had a marker left out for moving against the "
            f"others' rigid motion ({per_marker}); the others gave the pose there")
    level = check.level
    if long_runs and level == "ok":
        level = "warning"
    if level == "ok":
        msg = what
    elif level == "warning":
        msg = (f"{what}: " + (f"marker {long_runs[0] + 1} moved for longer than {half_window_s:g} s, so the test may "
                              "miss the run's further frames" if long_runs else "a marker is often partly covered "
                              "or slides on the skin") + "; check that marker in the videos")
    else:
        msg = (f"{what}: most frames disagree with the markers' rigid shape, so the test cannot tell which "
               "marker moved (a marker covered for most of the record, skin sliding, or wrong identities); the "
               "pose and the saddle may rest on the wrong markers")
    return replace(check, level=level, message=msg)


#: The static shot's share of the saddle's vertical acceleration error (% of its rms, one standard deviation,
#: :func:`static_shot_of`): ``ok`` up to 2.5 %, ``warning`` up to 5 %, ``unreliable`` above. The saddle's
#: vertical acceleration is wanted within 10 % of its rms; the static shot is a single still, so the error it
#: leaves is one draw of a distribution whose spread this figure is, fixed for the whole record. At 5 % a
#: 10 % error is a two-standard-deviation draw (about one run in twenty): above it the still alone makes the
#: target a matter of luck. ``ok`` keeps a 10 % error four standard deviations away.
STATIC_SHOT_PCT = (2.5, 5.0)


def check_static_shot(uncertainty, input_: str | None = None, clip_frames: int | None = None) -> Check:
    """Is the saddle point placed precisely enough by the static shot? (thesis section 6.3).

    ``uncertainty``: :func:`static_shot_of` (a
    :class:`~horsemocap.uncertainty.StaticShotUncertainty`, or a :class:`StaticShotSkipped` saying why it
    could not be computed: skipped). The figure is the standard deviation of the written vertical
    acceleration's error that the still's pixel noise leaves in the saddle (% of its rms), against
    :data:`STATIC_SHOT_PCT`. ``clip_frames``: the frames a static clip averaged (None: one still per
    camera), so that a clip worth a single independent frame is still called a clip.

    Examples
    --------
    >>> check_static_shot(StaticShotSkipped("the rigid-body step has not run")).level
    'skipped'
    """
    ok, warn = STATIC_SHOT_PCT
    threshold = f"ok <= {ok:g} %; warning <= {warn:g} %; unreliable above"
    clip = clip_frames is not None or getattr(uncertainty, "independent_frames", 1.0) > 1
    if input_ is None:
        input_ = (f"the static shot ({'a clip per camera, averaged' if clip else 'one still per camera'}): the "
                  "markers' triangle and the saddle marker placed in it")
    if isinstance(uncertainty, StaticShotSkipped):
        return Check("static_shot", None, "%", SKIPPED, (None, ok), (None, warn), threshold, input_,
                     f"the static shot's effect on the saddle: not available ({uncertainty.reason})")
    shot = uncertainty
    check = range_check("static_shot", shot.pct_of_rms, "%", (None, ok), (None, warn), input_,
                        "the static shot's share of the saddle vertical acceleration's error")
    weighted = "".join(f", {w} rms {v:.1f} %" for w, v in shot.weighted_pct.items() if np.isfinite(v))
    noise = (f"the static clip's pixel noise ({shot.noise_px:.3g} px a frame, measured on the moving frames; its "
             f"average worth {shot.independent_frames:.1f} independent frames, a camera's constant centroid error "
             f"not averaged away)" if clip else
             f"the still's pixel noise ({shot.noise_px:.3g} px, measured on the moving frames)")
    what = (f"{noise} places the saddle "
            f"with standard deviations {', '.join(f'{1000 * v:.1f}' for v in shot.offset_sd_m)} mm (x, y, z) "
            f"relative to the markers, which moves its vertical acceleration by {shot.sd:.3g} m/s^2 rms, "
            f"{shot.pct_of_rms:.1f} % of its {shot.rms:.3g} m/s^2 (one standard deviation{weighted})")
    if check.level == "ok":
        msg = what
    elif check.level == "warning":
        msg = (f"{what}: the saddle's acceleration may be off by a few percent through the static shot alone; "
               "a wider marker triangle, a saddle marker closer to the markers or a longer static clip "
               "(averaged) narrows it")
    else:
        shot_is, record = (("this static clip", "record a longer static clip of the horse standing") if clip else
                           ("one still", "record the static shot as a clip of the horse standing"))
        msg = (f"{what}: {shot_is} cannot place the saddle well enough for its acceleration to be trusted "
               f"within 10 %; {record} (several seconds, averaged: "
               "the frame-to-frame noise shrinks, a camera's constant error does not), spread the markers wider "
               "(a thin triangle tilts about its long axis), put the saddle marker closer to them, or use cameras "
               "seeing the markers from more different directions")
    return replace(check, message=msg, threshold=threshold)


#: The per-frame pose's scatter at the saddle about the written trajectory, % of the saddle's own vertical motion
#: (rms each, :func:`saddle_scatter_of`): ``ok`` up to a third, ``warning`` up to 60 %, ``unreliable`` above.
#: Below a third the smoothing separates a motion three times its noise; as the scatter nears the motion's own
#: size every frame's saddle is as much noise as motion, and the acceleration (the motion's second derivative,
#: which weighs the noise's fast part most) is what the smoothing's model of the motion makes of it. The upper
#: limit was 100 %; measured on 26 sessions with correlated marker noise (benchmarks/README.md, free-running
#: laps): runs within the targets reached at most 52 % (one at 167 %, unreliable by then), while four runs at
#: 68-93 % ended exit 0 with Wb off by 7-24 %.
SADDLE_SCATTER_PCT = (100.0 / 3.0, 60.0)


SADDLE_SCATTER_INPUT = ("each frame's registration carrying the static shot's saddle, against kinematics.csv's "
                        "saddle height")


def check_saddle_scatter(scatter, input_: str = SADDLE_SCATTER_INPUT) -> Check:
    """Does the record resolve the saddle's motion? The moving frames' noise at the saddle against that motion.

    ``scatter``: :func:`saddle_scatter_of` (a :class:`~horsemocap.uncertainty.SaddleScatter`, or a
    :class:`ScatterSkipped` saying why it could not be measured: skipped). The figure is the per-frame pose's
    scatter about the written saddle height, % of the written height's own rms variation, against
    :data:`SADDLE_SCATTER_PCT`.
    The smoothing's criteria (white or correlated noise, markers left out) choose a smoothing for the noise they
    see; none can recover a motion the noise covers, and when the scatter reaches the motion's size the
    written acceleration stands on the criterion's model, not on the measurement. The figure is what the
    smoothing removed, so the check judges one way only: a smoothing that follows the noise passes it (see
    :func:`horsemocap.uncertainty.saddle_scatter`).

    Examples
    --------
    >>> from horsemocap.uncertainty import SaddleScatter
    >>> check_saddle_scatter(SaddleScatter(0.003, 0.03, 10.0, 200)).level
    'ok'
    >>> check_saddle_scatter(SaddleScatter(0.04, 0.03, 133.3, 200)).level
    'unreliable'
    """
    ok, warn = SADDLE_SCATTER_PCT
    threshold = f"ok <= {ok:.3g} %; warning <= {warn:g} %; unreliable above"
    if not isinstance(scatter, SaddleScatter):
        return Check("saddle_scatter", None, "%", SKIPPED, (None, ok), (None, warn), threshold, input_,
                     f"the moving frames' noise at the saddle: not available ({scatter.reason})")
    check = range_check("saddle_scatter", scatter.pct_of_motion, "%", (None, ok), (None, warn), input_,
                        "the moving frames' noise at the saddle")
    what = (f"each frame's own pose places the saddle {1000 * scatter.scatter_m:.3g} mm rms from the written "
            f"height ({scatter.frames} frames), {scatter.pct_of_motion:.1f} % of the saddle's "
            f"{1000 * scatter.motion_m:.3g} mm rms vertical motion")
    if check.level == "ok":
        msg = what
    elif check.level == "warning":
        msg = (f"{what}: the markers' noise at the saddle is a sizeable part of its motion, so the smoothing's "
               "choice moves the vertical acceleration (its fast part most); compare gaits and horses with care")
    else:
        msg = (f"{what}: the markers' noise at the saddle is near or above the saddle's motion, so the vertical "
               "acceleration is the smoothing's guess, not a measurement. Spread the markers wider (a thin "
               "triangle tilts about its long axis and swings the saddle), put one nearer the saddle, add a "
               "marker, or use cameras seeing the markers from more different directions")
    return replace(check, message=msg, threshold=threshold)


@dataclass(frozen=True)
class ScatterSkipped:
    """Why the moving frames' noise at the saddle could not be measured (:func:`saddle_scatter_of`).

    Examples
    --------
    >>> check_saddle_scatter(ScatterSkipped("the rigid-body step has not run")).level
    'skipped'
    """

    reason: str


def saddle_scatter_of(analysis) -> SaddleScatter | ScatterSkipped:
    """:func:`horsemocap.uncertainty.saddle_scatter` of an analysis: the rigid-body step's per-frame
    registration (the pose registration) and static saddle against the written saddle position, or why not.

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> from horsemocap.pipeline import analyze
    >>> before = analyze(default_session_dir(), until="sync", progress=lambda *a: None)
    >>> saddle_scatter_of(before)
    ScatterSkipped(reason='the rigid-body step has not run')
    """
    rb = analysis.rigid_body
    if rb is None or rb.saddle_position is None:
        return ScatterSkipped("the rigid-body step has not run")
    reg = getattr(rb.body, "pose_registration", None)
    if reg is None or np.asarray(reg.rotation).shape[0] != np.asarray(rb.saddle_position).shape[0]:
        return ScatterSkipped("no per-frame registration on the written frames")
    try:
        return saddle_scatter(reg.rotation, reg.translation, rb.body.static_saddle, rb.saddle_position)
    except ValueError as exc:
        return ScatterSkipped(str(exc))


def post_checks(analysis) -> list[Check]:
    """Checks of an analysis' results (only those whose steps have run)."""
    a_, s = analysis, analysis.session
    checks = []
    if a_.triangulate is not None and a_.detect is not None:
        a, b = a_.triangulate.segment
        resid = {c: np.asarray(r)[a:b] for c, r in a_.triangulate.residual_px.items()}
        checks.append(check_reprojection_residuals(resid, marker_motion_px(a_.detect.marker_px, (a, b)),
                                                   _calibration_rms(a_)))
    ambiguous = a_.sync.flash_ambiguous if a_.sync is not None else {}
    sync_residual = _sync_residuals(a_)
    if sync_residual is not None and a_.detect.sync_check:
        ref = s.reference_camera
        checks.append(check_subframe_sync_by_markers(a_.detect.sync_check, a_.sync.offsets_with_fraction(ref),
                                                     a_.detect.sync.offsets_with_fraction(ref),
                                                     {c: float(np.nanmedian(r)) if np.isfinite(r).any()
                                                      else float("nan") for c, r in sync_residual.items()},
                                                     ambiguous=ambiguous,
                                                     flash_whole_frames=a_.sync.offsets_from == "flashlight"
                                                     and not a_.sync.subframe_method
                                                     and a_.detect.sync.subframe_method == "markers"))
    elif a_.detect is not None and (a_.detect.sync_check or ambiguous):
        checks.append(check_sync_by_markers(a_.detect.sync_check, ambiguous=ambiguous))
    if sync_residual is not None:
        a, b = a_.triangulate.segment
        checks.append(check_sync_residual(sync_residual, marker_motion_px(a_.detect.marker_px, (a, b)),
                                          _calibration_rms(a_)))
    if a_.motion_frame is not None and a_.motion_frame.period_frames is not None:
        fast = a_.motion_frame.faster_period_frames
        checks.append(check_stride_frequency(s.fps / a_.motion_frame.period_frames,
                                             faster_hz=None if fast is None else s.fps / fast))
    if a_.rigid_body is not None:
        rb = a_.rigid_body
        checks.append(check_marker_geometry(rb.warnings))
        body = getattr(rb, "body", None)
        preg = getattr(body, "pose_registration", None)
        checks.append(check_marker_rigidity(rb.conditioning.registration_rms_m, rb.model,
                                            predicted_rms_m=None if preg is None
                                            else predicted_registration_rms(preg)))
        checks.append(check_left_out_markers(getattr(body, "left_out", None), s.fps))
        ay = written_saddle_acceleration(a_)
        peak = float(np.nanmax(np.abs(ay))) if ay is not None and np.isfinite(ay).any() else None
        checks.append(check_saddle_acceleration(peak))
        period = a_.motion_frame.period_frames if a_.motion_frame is not None else None
        checks.append(check_record_ends(ay, period))
        if getattr(body, "basis_resolution", None) is not None:
            checks.append(check_spline_basis(body.basis_resolution))
        checks.append(check_static_shot(static_shot_of(analysis),
                                        clip_frames=getattr(analysis.static, "frames_used", None)))
        checks.append(check_saddle_scatter(saddle_scatter_of(analysis)))
    if a_.comfort is not None and a_.comfort.indicators is not None:
        ind = a_.comfort.indicators
        checks.append(check_horse_speed(ind.get("vel_x_avg")))
    return checks


@dataclass(frozen=True)
class StaticShotSkipped:
    """Why the static shot's uncertainty could not be carried to the saddle (:func:`static_shot_of`).

    Examples
    --------
    >>> check_static_shot(StaticShotSkipped("the rigid-body step has not run")).message
    "the static shot's effect on the saddle: not available (the rigid-body step has not run)"
    """

    reason: str


def static_shot_of(analysis) -> StaticShotUncertainty | StaticShotSkipped:
    """The static shot's uncertainty carried to the written saddle vertical acceleration
    (:func:`horsemocap.uncertainty.static_shot_uncertainty`), or why it cannot be computed.

    The pixel noise is the session's own (``TriangulateResult.noise_px``, from the moving frames'
    reprojection residuals); the still's points are the rigid-body step's (its motion-frame static shot
    taken back to the world frame, the markers and saddle it matched); the saddle point's effect on the
    written acceleration is the chain's own (:func:`horsemocap.uncertainty.written_saddle_sensitivity`).

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> from horsemocap.pipeline import analyze
    >>> before = analyze(default_session_dir(), until="sync", progress=lambda *a: None)
    >>> static_shot_of(before)
    StaticShotSkipped(reason='the rigid-body step has not run')
    """
    rb, mf, tri = analysis.rigid_body, analysis.motion_frame, analysis.triangulate
    if rb is None or mf is None or tri is None or analysis.rig is None:
        return StaticShotSkipped("the rigid-body step has not run")
    if tri.noise_px is None or not np.isfinite(tri.noise_px):
        return StaticShotSkipped("no pixel noise measured (no point seen by two cameras with a residual)")
    axes = np.asarray(mf.frame.axes, float)
    world = np.asarray(mf.static, float) @ axes + np.asarray(mf.frame.origin, float)
    static_model = np.asarray(mf.static, float)[rb.static_order]
    try:
        G = written_saddle_sensitivity(rb.body, static_model)
        return static_shot_uncertainty(analysis.rig.rig, world, rb.static_order, rb.saddle_index, axes,
                                       tri.noise_px, G, written_saddle_acceleration(analysis),
                                       fs=float(analysis.session.fps), seen=_still_seen(analysis),
                                       independent_frames=_static_independent_frames(analysis))
    except StaticShotRefused as exc:       # the documented refusals; any other error is a fault, raised
        return StaticShotSkipped(str(exc))


def _static_independent_frames(analysis) -> float:
    """The independent frames the static shot averages (a clip, :class:`~horsemocap.steps.StaticResult`
    ``effective_frames``), 1 for one still per camera."""
    frames = getattr(analysis.static, "effective_frames", None)
    return 1.0 if frames is None else float(frames)


def _still_seen(analysis) -> dict | None:
    """Camera -> which of the static shot's points it saw (finite pixels), or None when the pixels are not kept."""
    static = analysis.static
    if static is None or static.static_px is None:
        return None
    return {c: np.isfinite(np.asarray(px, float)).all(-1) for c, px in static.static_px.items()}


def _calibration_rms(analysis) -> float | None:
    """The rig's RMS reprojection error (``rig.toml`` metadata ``error``), or None."""
    rms = analysis.rig.rig.metadata.get("error") if analysis.rig is not None else None
    try:
        return float(rms) if rms is not None else None
    except (TypeError, ValueError):
        return None


def _sync_residuals(analysis) -> dict | None:
    """Camera -> the analysed frames' sync residuals (px) of a free-running session; None when genlocked or
    not triangulated."""
    tri = analysis.triangulate
    if tri is None or analysis.detect is None or getattr(tri, "sync_residual_px", None) is None:
        return None
    a, b = tri.segment
    return {c: np.asarray(r, float)[a:b] for c, r in tri.sync_residual_px.items()}
