"""Synchronisation to a fraction of a frame, and 2D tracks at common instants.

Free-running cameras (camcorders, phones) expose their frames a fraction of
a frame after one another; the flashlight of thesis eq. 3.11-3.14 only
settles whole frames. Conventions used here: after the whole-frame offsets,
camera ``c``'s synchronised frame ``k`` is exposed at the reference camera's
instant ``k + phase[c]`` (in reference frames); ``phase`` is 0 for the
reference camera and for genlocked cameras. Camera ``c``'s frame
``k + offset_with_fraction[c]`` therefore shows the reference camera's frame
``k``, with ``offset_with_fraction[c] = offsets[c] - offsets[ref] - phase[c]``.

- :func:`flash_onset` -- the flash's onset inside a frame from the partial
  first lit frame against a fully lit one (given the exposure as a fraction
  of the frame).
- :func:`flash_phases` -- every camera's phase from the flash onsets.
- :class:`TrackInterpolant` -- a camera's 2D tracks as cubic functions of
  time on the frames where each marker is seen (NaN outside).
- :func:`refine_phases` -- each camera's phase (and, over a long record, rate
  ratio) that puts its tracks on the other cameras' triangulated markers.
- :func:`linearised_phases` -- the same phases from one least-squares step of
  the markers' residuals linearised at a trial phase (a few triangulations
  instead of the search's hundreds).
- :func:`tracks_at_reference_instants` -- every camera's tracks interpolated
  to the reference camera's instants.
- :func:`others_residual` -- how far each camera's positions lie from the
  other cameras' markers projected into it (the sync residual).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import minimize

from .reconstruction import triangulate

__all__ = ["FlashOnset", "exposure_fraction", "exposure_seconds", "readout_frames", "flash_onset", "flash_row_delay", "flash_phases",
           "nearest_frames", "TrackInterpolant", "PhaseFit", "phase_residual", "fit_phase", "joint_residual",
           "refine_phases", "linearised_phases", "seen_chunks", "drift_is_measured", "camera_frames", "largest_phase", "whole_frames_gained", "drift_text", "tracks_at_reference_instants", "points_at_shifted_instants",
           "rolling_shutter_frames", "others_residual", "timing_floor", "residual_curve", "observation_instants",
           "OUTSIDE_TRACK"]

#: Exposure as a fraction of the frame when the session does not say (the "180 degree shutter").
DEFAULT_EXPOSURE_FRACTION = 0.5
#: A frame at least this share of the fully lit level counts as fully lit.
FULLY_LIT = 0.98
#: A first lit frame at or below this share of the flash's brightness is dark: the flash was not found there.
UNLIT = 0.05
#: Reason of a 2D position that cannot be interpolated (the instant is outside a run of seen frames).
OUTSIDE_TRACK = "outside_track"
#: Phases searched around the flash's estimate (frames either side) and the grid step (frames).
SEARCH_HALF_WIDTH = 1.0
GRID_STEP = 0.05
#: A run's cubic is extended this far (frames) beyond its first and last seen frame.
EXTEND_FRAMES = 1.0
#: Delay of an interlaced frame's second field (frames).
INTERLACED_FIELD_FRAMES = 0.5
#: Chunks of the record over which the phase is fitted separately (spread -> uncertainty, slope -> rate).
CHUNKS = 5
#: A trend of the chunks' phases is a clock's drift when it is DRIFT_Z standard errors from zero, adds DRIFT_MIN_FRAMES
#: of phase over their span and is within RATE_MAX_PPM of the reference's rate (:func:`drift_is_measured`).
DRIFT_Z = 3.0
DRIFT_MIN_FRAMES = 0.05
RATE_MAX_PPM = 1500.0
#: A chunk is cut where the markers are unseen for more than this many frames (a second at 25 fps: the horse
#: left the views, :func:`seen_chunks`); pieces shorter than CHUNK_MIN_FRAMES are not measured.
CHUNK_GAP_FRAMES = 25
CHUNK_MIN_FRAMES = 4
#: A chunk's phase is first searched on this grid about the camera's line (frames), then refined jointly.
CHUNK_GRID_FRAMES = np.arange(-0.25, 0.26, GRID_STEP)
#: The joint refinement of the phases: its tolerance (frames), of the residual (px) and most simplex steps.
#: From its first steps of GRID_STEP the simplex shrinks to REFINE_TOLERANCE in about nine halvings, a few
#: dozen steps for the two or three free phases of a rig; 400 leaves a wide margin while it still bounds the
#: cost of a residual that never settles (each step triangulates the whole record once).
REFINE_TOLERANCE = 1e-4
REFINE_RESIDUAL_TOLERANCE_PX = 1e-6
REFINE_MAX_STEPS = 400
#: The linearised phases (:func:`linearised_phases`): the step (frames) of the finite differences of the markers'
#: residuals in each camera's phase (a tenth of a frame: the secant over the phases that matter, well above the
#: interpolation's rounding), the cut (robust standard deviations of the residual components) beyond which a
#: component is an outlier (a marker the triangulation cannot fit), and the least-squares passes that drop them.
LINEAR_STEP = 0.1
LINEAR_OUTLIER_SIGMAS = 4.0
LINEAR_PASSES = 3
#: Fewest residual components (two per camera and marker-frame) per phase for :func:`linearised_phases`, for the
#: whole record and for each of its :data:`CHUNKS` chunks.
LINEAR_MIN_COMPONENTS = 10


@dataclass(frozen=True)
class FlashOnset:
    """When, inside a camera's frames, the flash switched on.

    Attributes
    ----------
    onset_frames : float
        The onset in this camera's frame numbering (frame ``k`` exposes from ``k`` to ``k + exposure``).
    uncertainty_frames : float
        Standard deviation of ``onset_frames`` (the dark gap between exposures cannot be resolved).
    partial : bool
        The first lit frame was partly lit (the onset fell inside its exposure).
    lit_fraction : float
        Brightness of the first lit frame as a share of the fully lit level.
    """

    onset_frames: float
    uncertainty_frames: float
    partial: bool
    lit_fraction: float


def exposure_fraction(timing: dict, fps: float) -> float:
    """A camera's exposure as a fraction of its frame period from its ``metadata.camera_timing`` entry:
    ``exposure_s`` times the frame rate, or exactly :data:`DEFAULT_EXPOSURE_FRACTION` when the entry gives
    none (:func:`exposure_seconds` in frames).

    Examples
    --------
    >>> exposure_fraction({}, 29.97), exposure_fraction({"exposure_s": 0.008}, 25.0)
    (0.5, 0.2)
    >>> exposure_fraction({"exposure_s": 0}, 25.0)
    0.0
    """
    given = timing.get("exposure_s")
    return DEFAULT_EXPOSURE_FRACTION if given is None else float(given) * float(fps)


def readout_frames(timing: dict, fps: float) -> float:
    """A camera's rolling-shutter readout in frames from its ``metadata.camera_timing`` entry: ``rolling_shutter_s``
    times the frame rate, 0 when the entry gives none (a global shutter).

    Examples
    --------
    >>> readout_frames({"rolling_shutter_s": 0.02}, 25.0), readout_frames({}, 25.0)
    (0.5, 0.0)
    """
    return float(timing.get("rolling_shutter_s") or 0.0) * float(fps)


def exposure_seconds(timing: dict, fps: float) -> float:
    """A camera's exposure time (s) from its ``metadata.camera_timing`` entry (docs/sessions.md): its
    ``exposure_s``, or :data:`DEFAULT_EXPOSURE_FRACTION` of the frame period (half a frame) when the entry
    gives none. ``exposure_s`` 0 is an instant, not the default.

    With :func:`exposure_fraction`, the one place the default is applied: the synchronisation times the
    flash with the fraction and the pose trajectory is fitted through the aperture this gives
    (:func:`horsemocap.aperture.session_aperture`).

    Examples
    --------
    >>> exposure_seconds({}, 25.0), exposure_seconds({"exposure_s": 0.008}, 25.0)
    (0.02, 0.008)
    >>> exposure_seconds({"exposure_s": 0}, 25.0)
    0.0
    """
    given = timing.get("exposure_s")
    return DEFAULT_EXPOSURE_FRACTION / fps if given is None else float(given)


def flash_onset(signal, off_level: float, on_level: float, first_on: int,
                exposure_fraction: float = DEFAULT_EXPOSURE_FRACTION) -> FlashOnset:
    """The flash's onset to a fraction of a frame, from the first lit frames' brightness.

    A frame exposed over ``[k, k + e]`` (``e`` the exposure as a fraction of
    the frame) is lit in proportion to the part of its exposure after the
    onset ``T``: ``b = (k + e - T) / e``. The first frame with any light
    (``b > 0``, found from ``first_on`` backwards) gives ``T = k + e (1 - b)``
    when partly lit; a fully lit first frame only says that ``T`` fell in the
    dark gap ``[k - 1 + e, k]`` (the middle is taken, uncertainty that of a
    uniform spread over the gap).

    Parameters
    ----------
    signal : (n,) array
        Mean brightness of the flash's region in every frame (index = frame).
    off_level, on_level : float
        Brightness before and after the switch.
    first_on : int
        A frame where the flash is on (e.g. the detection's first frame above half).
    exposure_fraction : float
        Exposure / frame period in [0, 1]. An instant (0) is never partly lit: its first lit frame
        only says that the onset fell in the frame period before it.

    Examples
    --------
    Half-frame exposures; frame 3 is lit 60 %: the onset is 0.2 frame into frame 3.

    >>> o = flash_onset([0, 0, 0, 0.6, 1, 1], 0.0, 1.0, 3, 0.5)
    >>> round(o.onset_frames, 3), o.partial
    (3.2, True)
    >>> o = flash_onset([0, 0, 0, 1, 1, 1], 0.0, 1.0, 3, 0.5)
    >>> round(o.onset_frames, 3), round(o.uncertainty_frames, 3), o.partial
    (2.75, 0.144, False)

    A frame said to be lit that is dark (a flash found in the wrong frame) gives no fraction; the
    markers' whole-frame check corrects such an offset:

    >>> flash_onset([0, 0, 0, 0, 1, 1], 0.0, 1.0, 2, 0.5).partial
    False

    An instantaneous exposure: a half-bright first frame is noise on a lit frame, the onset anywhere in
    the period before it.

    >>> o = flash_onset([0, 0, 0, 0.6, 1, 1], 0.0, 1.0, 3, 0.0)
    >>> round(o.onset_frames, 3), round(o.uncertainty_frames, 3), o.partial
    (2.5, 0.289, False)
    """
    if not 0.0 <= exposure_fraction <= 1.0:
        raise ValueError(f"flash_onset: exposure_fraction must be in [0, 1], got {exposure_fraction!r}")
    s = np.asarray(signal, float)
    span = float(on_level) - float(off_level)
    if not np.isfinite(span) or span <= 0:
        raise ValueError(f"flash_onset: the on level ({on_level}) must be above the off level ({off_level})")
    b = np.clip((s - off_level) / span, 0.0, 1.0)
    k = int(first_on)
    while k > 0 and b[k - 1] > 1.0 - FULLY_LIT:      # an earlier frame already caught some light
        k -= 1
    e = float(exposure_fraction)
    if b[k] <= UNLIT:       # the frame said to be lit is dark: the flash was not found here, no fraction to read
        return FlashOnset(float(k), 0.5, False, float(b[k]))
    if b[k] < FULLY_LIT and e > 0.0:
        return FlashOnset(k + e * (1.0 - float(b[k])), 0.02 * e, True, float(b[k]))
    gap = 1.0 - e
    return FlashOnset(k - gap / 2.0, float(max(gap / np.sqrt(12.0), 0.02 * e)), False, float(b[k]))


def flash_row_delay(region, readout_frames: float) -> float:
    """How much later than row 0 a rolling shutter exposes the flash's rows (frames).

    :func:`flash_onset` times a frame by its row 0 (frame ``k`` exposes from ``k``); under a rolling
    shutter that reads ``height`` rows in ``readout_frames``, the flash's rows (the region's mean row
    ``v``) start exposing ``v / height x readout_frames`` later, so the onset in row-0 time is that much
    later than the brightness alone says (the markers' instants take the same rows' times:
    :func:`rolling_shutter_frames`). Without a readout (global shutter, interlaced fields) it is 0.

    Parameters
    ----------
    region : (h, w) array of bool
        The flash's pixels (:attr:`horsemocap.sync.FlashDetection.region`).
    readout_frames : float
        Time from row 0's exposure start to the last row's (frames).

    Examples
    --------
    >>> region = np.zeros((480, 640), bool); region[350:370, 100:120] = True
    >>> round(flash_row_delay(region, 0.5), 4)           # rows 350-369: mean 359.5
    0.3745
    >>> flash_row_delay(region, 0.0)
    0.0
    """
    readout = float(readout_frames)
    rows = np.nonzero(np.asarray(region, bool).any(axis=1))[0]
    if readout <= 0.0 or not rows.size:
        return 0.0
    weights = np.asarray(region, bool)[rows].sum(axis=1)
    return float(np.average(rows, weights=weights) / np.asarray(region).shape[0] * readout)


def flash_phases(onsets: dict, offsets: dict, reference: str) -> tuple[dict, dict]:
    """Each camera's phase after the whole-frame offsets, from the flash onsets.

    ``phase[c] = (offsets[c] - offsets[ref]) - (onset[c] - onset[ref])``:
    camera ``c``'s synchronised frame ``k`` is at the reference camera's
    instant ``k + phase[c]``.

    Returns
    -------
    (phase, uncertainty) : dict, dict
        Camera -> frames.

    Examples
    --------
    >>> on = {"left": FlashOnset(3.03, 0.01, True, 0.94), "middle": FlashOnset(16.75, 0.14, False, 1.0)}
    >>> ph, unc = flash_phases(on, {"left": 3, "middle": 17}, "left")
    >>> round(ph["middle"], 2), round(unc["middle"], 2)
    (0.28, 0.14)
    """
    ref = onsets[reference]
    phase, unc = {}, {}
    for c, o in onsets.items():
        if c == reference:
            phase[c], unc[c] = 0.0, 0.0
            continue
        phase[c] = float((offsets[c] - offsets[reference]) - (o.onset_frames - ref.onset_frames))
        unc[c] = float(np.hypot(o.uncertainty_frames, ref.uncertainty_frames))
    return phase, unc


def nearest_frames(offsets: dict, phase: dict) -> tuple[dict, dict]:
    """Whole-frame offsets of the frames nearest in time, and the phases left (within half a frame).

    Camera ``c``'s synchronised frame ``k`` is at reference instant ``k +
    phase[c]``; a phase above half a frame means its next frame is nearer
    in time: the offset takes the whole frames, ``offsets[c] -
    round(phase[c])``, and the phase keeps the rest. The same instants, with
    the frames compared whole (identification, the markers' whole-frame
    check) at most half a frame apart.

    Examples
    --------
    >>> nearest_frames({"left": 2, "middle": 12, "right": 21}, {"left": 0.0, "middle": -0.24, "right": 0.63})
    ({'left': 2, 'middle': 12, 'right': 20}, {'left': 0.0, 'middle': -0.24, 'right': -0.37})
    """
    whole = {c: int(np.round(phase.get(c, 0.0))) for c in offsets}
    return ({c: int(o) - whole[c] for c, o in offsets.items()},
            {c: round(float(phase.get(c, 0.0)) - whole[c], 12) for c in offsets})


class TrackInterpolant:
    """One camera's 2D marker tracks as cubic functions of time.

    Each marker's track is split into runs of frames where it is seen, a run
    going on across gaps of at most ``max_gap`` unseen frames; each run of
    two or more frames is a cubic spline (a straight line for two) over the
    observations' times. An instant is read from its run's spline only when
    an observation of the run lies within :data:`EXTEND_FRAMES` of it (so
    a run reaches that far beyond its ends, and across a gap only that far
    from its edges); elsewhere it is NaN.

    Parameters
    ----------
    marker_px : (n, m, 2) array
        Centroids per frame (NaN where not seen).
    times : (n,) or (n, m) array, optional
        Each observation's instant (default: the frame index); e.g. the frame
        time plus the row time of a rolling shutter.
    max_gap : int
        Longest run of unseen frames a spline spans (0: runs of consecutive
        frames only).

    Examples
    --------
    >>> px = np.zeros((5, 1, 2)); px[:, 0, 0] = np.arange(5) ** 2; px[2] = np.nan
    >>> track = TrackInterpolant(px)
    >>> track([0.5, 2.5, 3.5, 5.5])[:, 0, 0]
    array([ 0.5,  5.5, 12.5,  nan])

    Spanning the one-frame gap, the cubic through frames 0, 1, 3 and 4
    follows the parabola across it:

    >>> TrackInterpolant(px, max_gap=1)([0.5, 2.5, 3.5, 5.5])[:, 0, 0]
    array([ 0.25,  6.25, 12.25,   nan])
    """

    def __init__(self, marker_px, times=None, max_gap: int = 0):
        px = np.asarray(marker_px, float)
        if px.ndim != 3 or px.shape[2] != 2:
            raise ValueError(f"TrackInterpolant: marker_px must be (frames, markers, 2), got {px.shape}")
        self.n, self.m = px.shape[:2]
        t = np.arange(self.n, dtype=float) if times is None else np.asarray(times, float)
        t = np.broadcast_to(t[:, None] if t.ndim == 1 else t, (self.n, self.m))
        self.runs = [[] for _ in range(self.m)]      # per marker: (sorted observation times, spline or line)
        seen = np.all(np.isfinite(px), axis=2) & np.isfinite(t)
        for j in range(self.m):
            idx = np.flatnonzero(seen[:, j])
            if idx.size == 0:
                continue
            breaks = np.flatnonzero(np.diff(idx) > int(max_gap) + 1) + 1
            for run in np.split(idx, breaks):
                if run.size >= 2:
                    tt = t[run, j]
                    order = np.argsort(tt)
                    self.runs[j].append((tt[order], CubicSpline(tt[order], px[run[order], j])))

    def __call__(self, instants) -> np.ndarray:
        """Positions ``(len(instants), m, 2)`` at the given instants (frames), NaN where no observation of a
        run lies within :data:`EXTEND_FRAMES`."""
        q = np.asarray(instants, float)
        out = np.full((q.size, self.m, 2), np.nan)
        for j, runs in enumerate(self.runs):
            for tt, spline in runs:
                inside = (_nearest_distance(tt, q) <= EXTEND_FRAMES) & ~np.isfinite(out[:, j, 0])
                if inside.any():
                    out[inside, j] = spline(q[inside])
        return out


def _nearest_distance(sorted_times: np.ndarray, instants: np.ndarray) -> np.ndarray:
    """Distance of every instant to the nearest of ``sorted_times`` (ascending, at least one)."""
    i = np.clip(np.searchsorted(sorted_times, instants), 1, max(len(sorted_times) - 1, 1))
    lower = np.abs(instants - sorted_times[i - 1])
    upper = np.abs(sorted_times[np.minimum(i, len(sorted_times) - 1)] - instants)
    return np.minimum(lower, upper)


def camera_frames(reference_frames, phase: float = 0.0, rate_ratio: float = 1.0) -> np.ndarray:
    """The camera's frames (its own time) at the reference instants ``reference_frames``.

    Camera ``c``'s synchronised frame ``j`` is exposed at the reference
    instant ``phase + rate_ratio x j``: its phase at frame 0 plus its clock's
    drift (``rate_ratio`` reference frames per frame of its own, its frame
    period over the reference's: above 1 its clock is slower and it gains
    ``rate_ratio - 1`` frame of phase per frame). The reference instant
    ``k`` is therefore its frame ``(k - phase) / rate_ratio``.

    Examples
    --------
    A camera 0.25 frame behind at frame 0 whose clock runs 100 ppm slow
    (its phase 0.35 frame after 1000 frames):

    >>> [round(float(j), 4) for j in camera_frames(np.array([0.0, 1000.0]), 0.25, 1.0001)]
    [-0.25, 999.65]
    """
    return (np.asarray(reference_frames, float) - float(phase)) / float(rate_ratio)


def largest_phase(phase: float, rate_ratio: float, n_frames: int) -> float:
    """The largest phase (absolute, frames) a camera has over frames ``0 .. n_frames - 1``: at frame 0 or at
    the last, as its clock drifts (:func:`camera_frames`).

    Examples
    --------
    >>> largest_phase(0.02, 1.0001, 2701), largest_phase(-0.3, 1.0, 100)
    (0.29, 0.3)
    """
    return round(max(abs(float(phase)), abs(float(phase) + (float(rate_ratio) - 1.0) * max(n_frames - 1, 0))), 12)


#: Frames after which a camera at an NTSC-family rate (30000/1001 fps) labelled with the round one (30) has gained a
#: whole frame on a camera at the round rate: 1001.
NTSC_FRAMES_PER_GAINED_FRAME = 1001


def whole_frames_gained(rate_ratio: float, n_frames: int) -> np.ndarray:
    """The whole frames a camera's drifting clock has gained on the reference's by each synchronised frame.

    Its frame nearest the reference instant ``k`` is about ``k - (rate_ratio - 1) k`` (:func:`camera_frames`,
    the phase at frame 0 left aside, within a frame as the offsets leave it): ``gained[k]`` is
    ``(rate_ratio - 1) k`` rounded, 0 over the whole record while the drift stays under half a frame. The
    identification reads the camera's frame ``k - gained[k]`` at the reference instant ``k``
    (:class:`~horsemocap.detection.candidates.ClockFollowingFrames`), so the delay between the frames it compares
    stays within half a frame of the phase at frame 0 whatever the drift (the phase itself is left to the
    offsets, as without a drift).

    Examples
    --------
    A camera at 30000/1001 fps labelled 30 (1000 ppm slow against a true 30): a frame gained every 1000.

    >>> g = whole_frames_gained(1.001, 2001)
    >>> int(g[499]), int(g[501]), int(g[1600]), int(g[2000])
    (0, 1, 2, 2)
    >>> int(np.abs(whole_frames_gained(1.0001, 4000)).max())      # 100 ppm: under half a frame over 4000
    0
    """
    return np.round((float(rate_ratio) - 1.0) * np.arange(int(n_frames))).astype(int)


def drift_text(rate_ratio: float, n_frames: int) -> str:
    """A camera's clock drift in words ("" at rate 1): how much longer or shorter its frames are than the
    reference's (ppm; ``rate_ratio`` reference frames per frame of its own, :func:`camera_frames`)
    and the phase that adds over the record.

    Examples
    --------
    A camera whose clock runs 132 ppm fast has frames 132 ppm shorter:

    >>> print(drift_text(1 / 1.000132, 2800))
     (its frames 132 ppm shorter than the reference's: -0.369 frame of phase over the record)
    >>> drift_text(1.0, 2800)
    ''
    """
    if rate_ratio == 1.0:
        return ""
    ppm = 1e6 * (rate_ratio - 1.0)
    return (f" (its frames {abs(ppm):.0f} ppm {'longer' if ppm > 0 else 'shorter'} than the reference's: "
            f"{(rate_ratio - 1.0) * max(n_frames - 1, 0):+.3f} frame of phase over the record)")


def tracks_at_reference_instants(marker_px: dict, phase: dict, rate_ratio: dict | None = None,
                                 times: dict | None = None, max_gap: int = 0) -> tuple[dict, dict]:
    """Every camera's tracks interpolated to the reference camera's instants.

    Camera ``c``'s synchronised frame ``k`` is at reference instant
    ``k + phase[c]`` (times ``rate_ratio[c]`` per frame over the record, when
    given); the reference instant ``k`` is then its frame
    ``(k - phase[c]) / rate_ratio[c]``. A camera at phase 0 (and rate 1) is
    returned as it is. ``max_gap``: the longest run of unseen frames a
    track's spline spans (:class:`TrackInterpolant`); an instant is read
    only within :data:`EXTEND_FRAMES` of an observation.

    Returns
    -------
    (marker_px, outside) : dict, dict
        Camera -> (n, m, 2) positions at the reference instants; camera ->
        (n, m) bool: seen in the frames but not interpolable at the instant
        (reason :data:`OUTSIDE_TRACK`).

    Examples
    --------
    >>> px = {"a": np.arange(8.0).reshape(4, 1, 2), "b": np.arange(8.0).reshape(4, 1, 2)}
    >>> out, outside = tracks_at_reference_instants(px, {"a": 0.0, "b": 0.5})
    >>> out["b"][:, 0, 0]
    array([-1.,  1.,  3.,  5.])
    """
    rate_ratio = rate_ratio or {}
    times = times or {}
    out, outside = {}, {}
    for c, px in marker_px.items():
        px = np.asarray(px, float)
        ratio = float(rate_ratio.get(c, 1.0))
        if float(phase.get(c, 0.0)) == 0.0 and ratio == 1.0 and c not in times:
            out[c], outside[c] = px, np.zeros(px.shape[:2], bool)
            continue
        k = np.arange(len(px), dtype=float)
        out[c] = TrackInterpolant(px, times.get(c), max_gap)(camera_frames(k, phase.get(c, 0.0), ratio))
        outside[c] = np.all(np.isfinite(px), axis=2) & ~np.all(np.isfinite(out[c]), axis=2)
    return out, outside


def points_at_shifted_instants(points, shift: float, rate_ratio: float = 1.0) -> np.ndarray:
    """Positions at instants ``k + shift + (rate_ratio - 1) k`` (frames) read from ``points`` sampled at
    frames ``k``, linearly (NaN where either neighbouring sample is missing or outside the record).

    A camera whose synchronised frame ``k`` is at reference instant ``k + phase`` sees the markers the other
    cameras place at reference instants as they were ``phase`` frames later (its clock running at
    ``rate_ratio`` times the reference's: ``phase + rate_ratio k``, :func:`camera_frames`).

    Examples
    --------
    >>> p = np.arange(5.0).reshape(5, 1, 1) * 10
    >>> points_at_shifted_instants(p, 0.25)[:, 0, 0]
    array([ 2.5, 12.5, 22.5, 32.5,  nan])
    >>> points_at_shifted_instants(p, -1.5)[:, 0, 0]
    array([nan, nan,  5., 15., 25.])
    >>> points_at_shifted_instants(p, 0.0, 1.1)[:, 0, 0]
    array([ 0., 11., 22., 33., nan])
    """
    p = np.asarray(points, float)
    n = len(p)
    k = np.arange(n)
    s = float(shift) + (float(rate_ratio) - 1.0) * k
    whole = np.floor(s).astype(int)
    w = s - whole
    lo, hi = k + whole, k + whole + 1
    ok = (lo >= 0) & np.where(w > 0, hi < n, lo < n)
    out = np.full_like(p, np.nan)
    exact = ok & (w == 0)
    between = ok & (w > 0)
    out[exact] = p[lo[exact]]
    wb = w[between].reshape((-1,) + (1,) * (p.ndim - 1))
    out[between] = (1.0 - wb) * p[lo[between]] + wb * p[hi[between]]
    return out


def rolling_shutter_frames(marker_px, height: int, readout_frames: float) -> np.ndarray:
    """Each observation's instant in its camera's frames: frame index + row / height x readout.

    Examples
    --------
    >>> px = np.array([[[10.0, 0.0]], [[10.0, 240.0]]])
    >>> rolling_shutter_frames(px, 480, 0.5)[:, 0]
    array([0.  , 1.25])
    """
    px = np.asarray(marker_px, float)
    return np.arange(len(px), dtype=float)[:, None] + px[..., 1] / float(height) * float(readout_frames)


def observation_instants(marker_px, height: int, readout_frames: float = 0.0, interlaced: bool = False) -> np.ndarray:
    """Each observation's instant in its camera's frames: the frame index, plus the row time of a rolling
    shutter, plus a quarter of a frame for an interlaced camera.

    A rolling shutter starts row ``r`` of ``height`` ``r / height x readout``
    after row 0 (:func:`rolling_shutter_frames`). An interlaced frame holds
    two fields exposed half a frame apart (PAL DV: 20 ms); a marker's blob
    takes its rows from both fields alike, so its centroid is the mean of
    the two fields' positions: to first order the position half-way between
    the fields, a quarter of a frame after the first field's start. (Which
    field comes first does not change that instant.)

    Examples
    --------
    >>> px = np.array([[[10.0, 0.0]], [[10.0, 240.0]]])
    >>> observation_instants(px, 480, 0.5)[:, 0]
    array([0.  , 1.25])
    >>> observation_instants(px, 480, interlaced=True)[:, 0]
    array([0.25, 1.25])
    """
    return rolling_shutter_frames(marker_px, height, readout_frames) + (INTERLACED_FIELD_FRAMES / 2.0 if interlaced else 0.0)


def phase_residual(camera, points: np.ndarray, track: TrackInterpolant, phases, rate: float = 0.0,
                   frames=None) -> np.ndarray:
    """Median distance (px) of the projected points from the camera's tracks, for every trial phase.

    ``points`` (n, m, 3) are the others' markers at the reference instants;
    at phase ``p`` the camera's position at reference instant ``k`` is its
    track at frame ``k - p - rate (k - k_mid)``. NaN where no marker-frame compares.
    """
    k = np.arange(len(points), dtype=float) if frames is None else np.asarray(frames, float)
    proj = camera.project(points[k.astype(int)])
    mid = 0.5 * (k[0] + k[-1]) if k.size else 0.0
    out = np.full(len(phases), np.nan)
    for i, p in enumerate(phases):
        d = np.linalg.norm(track(k - p - rate * (k - mid)) - proj, axis=2)
        if np.isfinite(d).any():
            out[i] = float(np.nanmedian(d))
    return out


def _parabolic_minimum(grid, values) -> float:
    """The minimum of a sampled curve refined by a parabola through the best sample and its neighbours."""
    i = int(np.nanargmin(values))
    if 0 < i < len(grid) - 1 and np.all(np.isfinite(values[i - 1:i + 2])):
        y0, y1, y2 = values[i - 1:i + 2]
        den = y0 - 2 * y1 + y2
        if den > 0:
            return float(grid[i] + 0.5 * (y0 - y2) / den * (grid[1] - grid[0]))
    return float(grid[i])


@dataclass(frozen=True)
class PhaseFit:
    """One camera's phase fitted to the other cameras' markers.

    Attributes
    ----------
    phase : float
        Frames (reference instants) after the whole-frame offset, at frame 0 (the camera's phase at frame
        ``k`` is ``phase + (rate_ratio - 1) k``: :func:`camera_frames`).
    uncertainty : float
        Standard error of ``phase`` from the spread of the chunks' phases (when a rate ratio is kept: the
        standard error of their line's value at frame 0).
    rate_ratio : float
        Reference frames per frame of this camera (its frame period over the reference's; above 1 its clock
        is slower; :func:`camera_frames`), 1 when no drift is measured (:func:`drift_is_measured`).
    residual_px : float
        Median residual at the fitted phase.
    n_points : int
        Marker-frames compared.
    timing_floor_frames : float
        The camera's sync residual at the fitted phases over its markers' image speed
        (:func:`timing_floor`): the timing error the residual left cannot tell from noise and
        calibration (NaN when not measured).
    """

    phase: float
    uncertainty: float
    rate_ratio: float
    residual_px: float
    n_points: int
    timing_floor_frames: float = float("nan")


def fit_phase(camera, points: np.ndarray, track: TrackInterpolant, center: float,
              half_width: float = SEARCH_HALF_WIDTH, step: float = GRID_STEP) -> PhaseFit | None:
    """The phase minimising :func:`phase_residual` (grid, then a parabola), with its uncertainty and rate.

    The record's frames with a 3D point are cut into :data:`CHUNKS` chunks;
    each chunk's phase is fitted alike. Their spread over ``sqrt(chunks)`` is
    the uncertainty; a straight line through them over time gives the drift
    (rate ratio), kept only when :func:`drift_is_measured` (``phase`` is then the one at frame 0, as
    :class:`PhaseFit` says; :func:`phase_residual` reads it about the middle of the frames compared).
    None when fewer than 10 marker-frames compare.

    Examples
    --------
    See ``tests/test_subframe_sync.py`` (a synthetic rig with a known phase).
    """
    have = np.flatnonzero(np.all(np.isfinite(points), axis=(1, 2)))
    if have.size < 10:
        return None
    grid = np.arange(center - half_width, center + half_width + step / 2, step)
    curve = phase_residual(camera, points, track, grid, frames=have)
    if not np.isfinite(curve).any():
        return None
    best = _parabolic_minimum(grid, curve)
    fine = np.arange(best - 3 * step, best + 3.5 * step, step)
    chunk_phase, chunk_mid = [], []
    for part in np.array_split(have, CHUNKS):
        if part.size < 4:
            continue
        c = phase_residual(camera, points, track, fine, frames=part)
        if np.isfinite(c).any():
            chunk_phase.append(_parabolic_minimum(fine, c))
            chunk_mid.append(float(part.mean()))
    unc = float(np.std(chunk_phase, ddof=1) / np.sqrt(len(chunk_phase))) if len(chunk_phase) > 2 else step
    res = phase_residual(camera, points, track, [best], frames=have)[0]
    ratio = 1.0
    if len(chunk_phase) > 2:
        _, slope, se, _ = _drift_line(chunk_phase, chunk_mid)
        if drift_is_measured(slope, se, float(np.ptp(chunk_mid))):
            ratio = 1.0 + slope
            best = best - slope * 0.5 * float(have[0] + have[-1])      # the phase at frame 0, as PhaseFit's
    return PhaseFit(phase=best, uncertainty=max(unc, 1e-3), rate_ratio=ratio, residual_px=float(res),
                    n_points=int(have.size * points.shape[1]))


def joint_residual(rig, tracks: dict, phase: dict, frames: np.ndarray, rate_ratio: dict | None = None) -> float:
    """Median reprojection residual (px) of every camera's tracks at the reference instants ``frames``.

    Each camera's track is read at its frame ``(k - phase[c]) / rate_ratio[c]``
    (:func:`camera_frames`; rate 1 when not given); the markers
    are triangulated from all cameras together (joint) and the residual is
    taken over every camera and marker-frame. NaN when nothing triangulates.
    """
    k = np.asarray(frames, float)
    rate_ratio = rate_ratio or {}
    at_ref = {c: tr(camera_frames(k, phase.get(c, 0.0), rate_ratio.get(c, 1.0))) for c, tr in tracks.items()}
    tri = triangulate(rig, at_ref, mode="joint", max_residual_px=None)
    r = np.concatenate([np.ravel(v) for v in tri.residual_px.values()])
    r = r[np.isfinite(r)]
    return float(np.median(r)) if r.size else float("nan")


def _axis_fit(rig, tracks, phase, cam, frames, grid):
    """The best phase of ``cam`` on ``grid`` (the others fixed; every phase constant over ``frames``),
    refined by a parabola; NaN when nothing compares."""
    curve = np.array([joint_residual(rig, tracks, {**phase, cam: g}, frames) for g in grid])
    return _parabolic_minimum(grid, curve) if np.isfinite(curve).any() else float("nan")


def residual_curve(rig, marker_px: dict, phase: dict, camera: str, trials, times: dict | None = None,
                   rate_ratio: dict | None = None) -> np.ndarray:
    """The markers' joint residual (px, :func:`joint_residual`) for trial phases of one camera, the others fixed.

    The curve :func:`refine_phases` minimises along ``camera``'s axis:
    every camera's tracks (:class:`TrackInterpolant`, observation instants
    ``times``) read at the reference instants with ``phase`` (and
    ``rate_ratio``: :func:`camera_frames`), ``camera``'s phase at frame 0
    replaced by each trial, and triangulated together.

    Examples
    --------
    Three cameras in a row see two markers moving across; the middle
    camera's frames fall 0.3 frame after the reference's:

    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> rig = Rig(tuple(Camera(n, (640, 480), K, translation=[x, 0.0, 0.0])
    ...                 for n, x in (("left", 0.5), ("middle", 0.0), ("right", -0.5))))
    >>> def points(k):
    ...     k = np.asarray(k, float)[:, None, None]
    ...     bounce = 0.01 * np.sin(k) * np.array([0.0, 1.0, 0.0])
    ...     return np.array([[0.1, 0.0, 4.0], [-0.2, 0.1, 5.0]]) + k * np.array([0.02, 0.004, 0.0]) + bounce
    >>> k = np.arange(30.0)
    >>> px = {"left": rig["left"].project(points(k)), "middle": rig["middle"].project(points(k + 0.3)),
    ...       "right": rig["right"].project(points(k))}
    >>> trials = np.array([0.0, 0.3, 0.6])
    >>> curve = residual_curve(rig, px, {"left": 0.0, "middle": 0.0, "right": 0.0}, "middle", trials)
    >>> float(trials[np.argmin(curve)])
    0.3
    """
    times = times or {}
    tracks = {c: TrackInterpolant(px, times.get(c)) for c, px in marker_px.items()}
    frames = np.arange(len(next(iter(marker_px.values()))), dtype=float)
    return np.array([joint_residual(rig, tracks, {**phase, camera: float(g)}, frames, rate_ratio) for g in trials])


def refine_phases(rig, marker_px: dict, phase: dict, reference: str, times: dict | None = None,
                  half_width: float = SEARCH_HALF_WIDTH, step: float = 0.1, rate_ratio: dict | None = None) -> dict:
    """The cameras' phases that make the markers of all cameras meet, searched jointly.

    Every non-reference camera's phase is searched within ``half_width``
    frames of ``phase`` (the flash's estimate) on a grid of ``step``: all
    combinations for up to two cameras, coordinate by coordinate (three
    passes) for more; the residual is :func:`joint_residual` (the tracks
    interpolated in time, triangulated by all cameras together). The phases
    are then refined together (a simplex: the cameras' phases are coupled
    through the joint triangulation); the frames that show markers are
    cut into :data:`CHUNKS` chunks (:func:`seen_chunks`), each chunk's phase
    gives the uncertainty (spread over ``sqrt(chunks)``, combined with
    :func:`timing_floor`: the residual left, in frames) and, when their
    trend is a clock's drift (:func:`drift_is_measured`), the rate ratio: the
    camera's clock runs at another rate than the reference's, its phase
    then the one at frame 0 (:func:`camera_frames`), refined again with
    the rates. Over a long recording of several passes a constant phase
    would be the drift's average, wrong at every pass but one.

    Parameters
    ----------
    times : dict, optional
        Camera -> (n, m) instant of each observation in its own frames
        (frame index plus the rolling shutter's row time).
    rate_ratio : dict, optional
        Camera -> the rate ratio an earlier measurement gave, ``phase`` then its phase at frame 0: each chunk's
        phase is searched about that line rather than about the record's constant phase (a drift of frames
        over several passes leaves the constant phase more than a frame from the chunks' at either end, out of
        their search). The rate itself is measured again from the chunks.

    Returns
    -------
    dict
        Camera -> :class:`PhaseFit` for every non-reference camera that could
        be fitted.
    """
    times = times or {}
    tracks = {c: TrackInterpolant(px, times.get(c)) for c, px in marker_px.items()}
    n = len(next(iter(marker_px.values())))
    frames = np.arange(n, dtype=float)
    free = [c for c in marker_px if c != reference]
    start = {c: float(phase.get(c, 0.0)) for c in marker_px}
    start[reference] = 0.0
    axes = {c: np.arange(start[c] - half_width, start[c] + half_width + step / 2, step) for c in free}
    best, best_value = dict(start), joint_residual(rig, tracks, start, frames)
    if len(free) <= 2:
        for combo in np.array(np.meshgrid(*[axes[c] for c in free], indexing="ij")).reshape(len(free), -1).T:
            trial = {**start, **dict(zip(free, combo))}
            v = joint_residual(rig, tracks, trial, frames)
            if np.isfinite(v) and not v >= best_value:
                best, best_value = trial, v
    else:
        for _ in range(3):
            for c in free:
                g = _axis_fit(rig, tracks, best, c, frames, axes[c])
                if np.isfinite(g):
                    best[c] = g
    best = _refine_jointly(rig, tracks, best, free, frames)
    given = {c: (start[c], float(rate_ratio[c]) - 1.0) for c in free
             if rate_ratio and float(rate_ratio.get(c, 1.0)) != 1.0}
    drift = _drifts(rig, tracks, best, free, seen_chunks(marker_px), _seen_by_camera(marker_px), given)
    rate = {**{c: 1.0 for c in marker_px}, **{c: d.rate_ratio for c, d in drift.items()}}
    if any(d.rate_ratio != 1.0 for d in drift.values()):     # the phases at frame 0, refined with the rates
        best = _refine_jointly(rig, tracks, {**best, **{c: d.phase for c, d in drift.items() if d.rate_ratio != 1.0}},
                               free, frames, rate)
    fits = {}
    floor = timing_floor(rig, marker_px, best, times, rate)
    residual = joint_residual(rig, tracks, best, frames, rate)
    for c in free:
        unc = drift[c].uncertainty
        if np.isfinite(floor.get(c, np.nan)):
            unc = float(np.hypot(unc, floor[c]))
        fits[c] = PhaseFit(phase=float(best[c]), uncertainty=unc, rate_ratio=float(rate[c]),
                           residual_px=residual, n_points=int(n),
                           timing_floor_frames=float(floor.get(c, np.nan)))
    return fits


def seen_chunks(marker_px: dict, chunks: int = CHUNKS) -> list:
    """The record's frames in which two or more cameras see a marker, cut into ``chunks`` runs of equal count,
    each cut again where the markers are unseen for more than :data:`CHUNK_GAP_FRAMES`.

    The chunks over which :func:`refine_phases` measures each camera's phase
    again (their spread: its uncertainty; their trend: its clock's drift).
    A recording of several passes of the horse through the views is cut by
    the frames that show it, not by its length (the empty arena between
    passes measures nothing), and no chunk spans two passes (its phase
    would be neither's when the clock drifts). Pieces of fewer than
    :data:`CHUNK_MIN_FRAMES` frames are left out.

    Examples
    --------
    >>> px = np.full((50, 1, 2), np.nan)
    >>> px[2:8] = px[40:46] = 1.0
    >>> [part.tolist() for part in seen_chunks({"a": px, "b": px}, chunks=3)]
    [[2.0, 3.0, 4.0, 5.0], [42.0, 43.0, 44.0, 45.0]]
    """
    seen = sum(v.astype(int) for v in _seen_by_camera(marker_px).values())
    frames = np.flatnonzero(np.asarray(seen) >= 2).astype(float)
    out = []
    for part in np.array_split(frames, chunks):
        cuts = np.flatnonzero(np.diff(part) > CHUNK_GAP_FRAMES) + 1
        out += [piece for piece in np.split(part, cuts) if piece.size >= CHUNK_MIN_FRAMES]
    return out


def _seen_by_camera(marker_px: dict) -> dict:
    """Camera -> (n,) bool: the frames in which it sees a marker."""
    return {c: np.any(np.all(np.isfinite(np.asarray(px, float)), axis=-1), axis=-1) for c, px in marker_px.items()}


@dataclass(frozen=True)
class _Drift:
    """A camera's phase at frame 0 (``phase``; the constant phase when the drift is not significant), its rate
    ratio and the phase's standard error from its chunks."""
    phase: float
    rate_ratio: float
    uncertainty: float


def _drifts(rig, tracks, best: dict, free: list, parts: list, seen: dict, given: dict | None = None) -> dict:
    """Camera -> :class:`_Drift` of every camera of ``free`` from the chunks' phases (:func:`_chunk_phases`).

    A straight line through a camera's chunk phases over time: its slope is
    the camera clock's drift, kept as the rate ratio ``1 + slope`` when
    :func:`drift_is_measured`, the line's value at frame 0 then its phase
    and the value's standard error its uncertainty; the chunks are then
    measured again from the lines (a chunk's simplex stops near where it
    starts when the markers are noisy: from the record's constant phase,
    the drift comes out short). Without a drift: ``best``, and the chunks'
    spread over ``sqrt(chunks)``. A camera measured in fewer than three
    chunks keeps ``best`` with :data:`GRID_STEP` as its uncertainty.
    ``given``: camera -> a line ``(phase at frame 0, slope)`` an earlier
    measurement gave, the chunks measured first about it instead of ``best``;
    the second measurement starts from the constant phases and the drifts
    this one confirmed only (a given line the chunks do not confirm, kept,
    would pull every camera's chunk phases with it: they are fitted
    together).
    """
    constant = {c: (float(best[c]), 0.0) for c in free}
    given = {c: (float(p), float(v)) for c, (p, v) in (given or {}).items() if c in constant}
    out = _lines_drift(_chunk_phases(rig, tracks, best, {**constant, **given}, parts, seen), best)
    drifting = {c: (d.phase, d.rate_ratio - 1.0) for c, d in out.items() if d.rate_ratio != 1.0}
    if not drifting and not given:
        return out
    return _lines_drift(_chunk_phases(rig, tracks, best, {**constant, **drifting}, parts, seen), best)


def _lines_drift(chunks: dict, best: dict) -> dict:
    """Camera -> :class:`_Drift` from its chunks' phases and middles (:func:`_drifts`)."""
    out = {}
    for c, (ph, mid) in chunks.items():
        if len(ph) < 3:
            out[c] = _Drift(float(best[c]), 1.0, GRID_STEP)
            continue
        intercept, slope, se, intercept_se = _drift_line(ph, mid)
        if drift_is_measured(slope, se, float(np.ptp(mid))):
            out[c] = _Drift(intercept, 1.0 + slope, max(intercept_se, 1e-3))
        else:
            out[c] = _Drift(float(best[c]), 1.0, _spread(ph))
    return out


def drift_is_measured(slope: float, slope_se: float, span_frames: float) -> bool:
    """Is a trend of the chunks' phases a camera clock's drift? (:func:`refine_phases`)

    Three conditions: the slope is more than :data:`DRIFT_Z` standard errors
    from zero (the chunks share the marker noise's slow part, so their
    scatter understates it: 3, not 2); it adds at least
    :data:`DRIFT_MIN_FRAMES` of phase over the chunks' span (less moves no
    point measurably: a twentieth of a frame, the phase the markers tell
    from zero elsewhere); and it is a rate a camera keeps, within
    :data:`RATE_MAX_PPM` of the reference's (video crystals are made to
    +-100 ppm or better, and a camera at 30000/1001 fps labelled 30, as
    files of the NTSC family often are, is 999 ppm slow beside one at 30;
    a steeper trend over a short record is the noise).

    Examples
    --------
    132 ppm over 2700 frames, and the same trend over a pass of 80 frames:

    >>> drift_is_measured(132e-6, 5e-6, 2700.0), drift_is_measured(132e-6, 5e-6, 80.0)
    (True, False)
    >>> drift_is_measured(999e-6, 5e-6, 300.0)          # 30000/1001 fps beside 30 fps, 10 s
    True
    >>> drift_is_measured(2.5e-3, 2e-4, 80.0)           # 2500 ppm: not a camera's rate
    False
    """
    return (abs(slope) > DRIFT_Z * slope_se and abs(slope) * span_frames >= DRIFT_MIN_FRAMES
            and abs(slope) <= RATE_MAX_PPM * 1e-6)


def _chunk_phases(rig, tracks, best: dict, lines: dict, parts: list, seen: dict) -> dict:
    """Camera -> (its phases, the chunks' middles): in each chunk the phases of the cameras of ``lines`` that
    see a marker there (``seen``: camera -> (n,) bool) refined together (:func:`_refine_jointly` over the
    chunk's frames, constant over it, from each camera's line ``(phase at frame 0, slope)`` at the chunk's
    middle, searched first on :data:`CHUNK_GRID_FRAMES` about it; the others at ``best``). Together: the cameras' phases are coupled through the joint
    triangulation, so one camera's drift would move another's phase were they measured one at a time. A
    camera that sees nothing in a chunk has no phase there; a chunk in which nothing triangulates is left out."""
    out = {c: ([], []) for c in lines}
    for part in parts:
        mid = float(part.mean())
        here = [c for c in lines if seen[c][part.astype(int)].any()]
        start = {**best, **{c: lines[c][0] + lines[c][1] * mid for c in here}}
        if not here or not np.isfinite(joint_residual(rig, tracks, start, part)):
            continue
        for c in here:           # each camera on a grid about its line first: the simplex alone, on a noisy
            grid = start[c] + CHUNK_GRID_FRAMES   # chunk's rough median residual, stops near where it starts
            g = _axis_fit(rig, tracks, start, c, part, grid)
            start[c] = g if np.isfinite(g) else start[c]
        found = _refine_jointly(rig, tracks, start, here, part)
        for c in here:
            out[c][0].append(float(found[c]))
            out[c][1].append(mid)
    return out


def _drift_line(chunk_phase: list, chunk_mid: list) -> tuple[float, float, float, float]:
    """The least-squares line through the chunks' phases over time: its value at frame 0, its slope, the
    slope's standard error and the standard error of its value at frame 0 (n - 2 degrees of freedom)."""
    ph, mid = np.asarray(chunk_phase, float), np.asarray(chunk_mid, float)
    slope, intercept = np.polyfit(mid, ph, 1)
    resid = ph - (intercept + slope * mid)
    sd = float(np.sqrt(np.sum(resid ** 2) / max(len(ph) - 2, 1)))
    sxx = float(np.sum((mid - mid.mean()) ** 2))
    if sxx <= 0:
        return float(intercept), float(slope), np.inf, np.inf
    return (float(intercept), float(slope), sd / np.sqrt(sxx),
            sd * float(np.sqrt(1.0 / len(ph) + mid.mean() ** 2 / sxx)))


def linearised_phases(rig, marker_px: dict, phase: dict, reference: str, times: dict | None = None) -> dict:
    """The cameras' phases from one least-squares step of the markers' residuals linearised at ``phase``.

    Every camera's tracks (:class:`TrackInterpolant`, instants ``times``)
    are read at the reference instants with ``phase`` and triangulated
    together; the reprojection residuals (two components per camera and
    marker-frame) are differentiated in each non-reference camera's phase
    by a finite step of :data:`LINEAR_STEP` frames. The least-squares phase
    correction (components beyond :data:`LINEAR_OUTLIER_SIGMAS` robust
    standard deviations dropped, :data:`LINEAR_PASSES` passes) costs a
    triangulation per camera, against :func:`refine_phases`' hundreds;
    it is that search's answer when the phases are within a fraction of a
    frame of ``phase`` (the tracks nearly straight over it), and no search:
    a phase far off is only said to be far. The uncertainty is the
    correction's spread over the record's :data:`CHUNKS` chunks combined
    with :func:`timing_floor` at the phases found, as :func:`refine_phases`'.

    Parameters
    ----------
    rig : Rig
        The cameras (three or more).
    marker_px : dict
        Camera -> (n, m, 2) centroids of the synchronised frames (NaN where not seen).
    phase : dict
        Camera -> the trial phase (frames) the residuals are linearised at.
    reference : str
        The camera whose phase is 0.
    times : dict, optional
        Camera -> (n, m) instant of each observation in its own frames.

    Returns
    -------
    dict
        Camera -> :class:`PhaseFit` (``rate_ratio`` 1, ``residual_px`` the
        joint residual at the phases found, ``n_points`` the residual
        components used over two) for every non-reference camera; empty
        when a camera's phase is not determined (fewer than
        :data:`LINEAR_MIN_COMPONENTS` components, the phases not separable,
        or fewer than three chunks to measure the spread).

    Examples
    --------
    Three cameras in a row see two markers moving across; the middle
    camera's frames fall 0.3 frame and the right camera's 0.1 frame before
    the reference's:

    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> rig = Rig(tuple(Camera(n, (640, 480), K, translation=[x, 0.0, 0.0])
    ...                 for n, x in (("left", 0.5), ("middle", 0.0), ("right", -0.5))))
    >>> def points(k):
    ...     k = np.asarray(k, float)[:, None, None]
    ...     bounce = 0.01 * np.sin(k) * np.array([0.0, 1.0, 0.0])
    ...     return np.array([[0.1, 0.0, 4.0], [-0.2, 0.1, 5.0]]) + k * np.array([0.02, 0.004, 0.0]) + bounce
    >>> k = np.arange(30.0)
    >>> px = {"left": rig["left"].project(points(k)), "middle": rig["middle"].project(points(k + 0.3)),
    ...       "right": rig["right"].project(points(k - 0.1))}
    >>> fits = linearised_phases(rig, px, {"left": 0.0, "middle": 0.0, "right": 0.0}, "left")
    >>> {c: round(f.phase, 2) for c, f in fits.items()}
    {'middle': 0.3, 'right': -0.1}
    """
    times = times or {}
    tracks = {c: TrackInterpolant(px, times.get(c)) for c, px in marker_px.items()}
    cams = list(marker_px)
    free = [c for c in cams if c != reference]
    n = len(next(iter(marker_px.values())))
    k = np.arange(n, dtype=float)
    start = {c: float(phase.get(c, 0.0)) for c in cams}
    start[reference] = 0.0

    def components(trial):           # (n, 2 x cameras x markers) reprojection residuals of the joint points
        at_ref = {c: tr(k - trial[c]) for c, tr in tracks.items()}
        points = triangulate(rig, at_ref, mode="joint", max_residual_px=None).points
        return np.concatenate([rig[c].project(points) - at_ref[c] for c in cams], axis=-1).reshape(n, -1)

    r0 = components(start)
    J = np.stack([(components({**start, c: start[c] + LINEAR_STEP}) - r0) / LINEAR_STEP for c in free], axis=-1)
    usable = np.isfinite(r0) & np.all(np.isfinite(J), axis=-1)
    if not free or usable.sum() < LINEAR_MIN_COMPONENTS * len(free) \
            or np.linalg.matrix_rank(J[usable]) < len(free):
        return {}
    keep = usable
    for _ in range(LINEAR_PASSES):
        step = np.linalg.lstsq(J[keep], -r0[keep], rcond=None)[0]
        spread = 1.4826 * float(np.median(np.abs((r0 + J @ step)[usable])))
        keep = usable & (np.abs(r0 + J @ step) <= max(LINEAR_OUTLIER_SIGMAS * spread, 1e-9))
    chunk_steps = []
    for part in np.array_split(np.arange(n), CHUNKS):
        sel = np.zeros_like(keep)
        sel[part] = keep[part]
        if sel.sum() >= LINEAR_MIN_COMPONENTS * len(free) and np.linalg.matrix_rank(J[sel]) == len(free):
            chunk_steps.append(np.linalg.lstsq(J[sel], -r0[sel], rcond=None)[0])
    if len(chunk_steps) < 3:        # no spread to measure: not determined (a default would understate nothing)
        return {}
    found = {**start, **{c: start[c] + float(s) for c, s in zip(free, step)}}
    floor = timing_floor(rig, marker_px, found, times)
    residual = joint_residual(rig, tracks, found, k)
    fits = {}
    for i, c in enumerate(free):
        unc = _spread([float(s[i]) for s in chunk_steps])
        if np.isfinite(floor.get(c, np.nan)):
            unc = float(np.hypot(unc, floor[c]))
        fits[c] = PhaseFit(phase=found[c], uncertainty=unc, rate_ratio=1.0, residual_px=residual,
                           n_points=int(keep.sum()) // 2, timing_floor_frames=float(floor.get(c, np.nan)))
    return fits


def _refine_jointly(rig, tracks: dict, phase: dict, free: list, frames: np.ndarray, rate_ratio: dict | None = None) -> dict:
    """The phases of ``free`` moved together to the least :func:`joint_residual` (Nelder-Mead simplex from
    ``phase``, first steps of :data:`GRID_STEP`, to :data:`REFINE_TOLERANCE` frames and
    :data:`REFINE_RESIDUAL_TOLERANCE_PX`).

    The cameras' phases are coupled through the joint triangulation: a camera's best phase moves with
    the others' errors, so refining one camera at a time, the others held at their coarse-grid values,
    leaves each off by a share of the others' error; the simplex moves them together.
    """
    start = np.array([float(phase[c]) for c in free])

    def cost(x):
        v = joint_residual(rig, tracks, {**phase, **dict(zip(free, x))}, frames, rate_ratio)
        return v if np.isfinite(v) else np.inf

    simplex = np.vstack([start] + [start + GRID_STEP * np.eye(len(free))[i] for i in range(len(free))])
    with np.errstate(invalid="ignore"):      # a vertex where nothing triangulates costs inf
        res = minimize(cost, start, method="Nelder-Mead",
                       options=dict(initial_simplex=simplex, xatol=REFINE_TOLERANCE, fatol=REFINE_RESIDUAL_TOLERANCE_PX,
                                    maxiter=REFINE_MAX_STEPS))
    if not np.isfinite(res.fun) or res.fun > cost(start):
        return dict(phase)
    return {**phase, **{c: float(v) for c, v in zip(free, res.x)}}


def timing_floor(rig, marker_px: dict, phase: dict, times: dict | None = None, rate_ratio: dict | None = None) -> dict:
    """Camera -> the timing error (frames) its sync residual cannot rule out: residual / image speed.

    With every camera's tracks at the reference instants (``phase``,
    :func:`tracks_at_reference_instants`), a camera ``d`` frames off puts
    its markers about ``d`` times their image speed (px per frame) from the
    other cameras' markers projected into it (:func:`others_residual`). The
    median residual left at the fitted phases is also made of detection
    noise and calibration error, which the residual cannot tell from a
    timing error: its median over the median image speed is how well the
    markers time the camera, whatever the chunks' agreement (the chunks
    share the calibration and the tracks' interpolation, so their spread
    misses these). NaN where the camera has no residual or its markers do
    not move.

    Examples
    --------
    Three cameras in a row see two markers moving 3-4 px per frame across
    the image; the middle camera's view lies 0.4 px off (noise or
    calibration), as a timing error of about a tenth of a frame would put it:

    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> rig = Rig(tuple(Camera(n, (640, 480), K, translation=[x, 0.0, 0.0])
    ...                 for n, x in (("left", 0.5), ("middle", 0.0), ("right", -0.5))))
    >>> t = np.arange(20.0)[:, None, None]
    >>> points = np.array([[0.1, 0.0, 4.0], [-0.2, 0.1, 5.0]]) + t * np.array([0.02, 0.0, 0.0])
    >>> px = {c.name: c.project(points) for c in rig.cameras}
    >>> px["middle"] = px["middle"] + [0.0, 0.4]
    >>> floor = timing_floor(rig, px, {"left": 0.0, "middle": 0.0, "right": 0.0})
    >>> round(floor["middle"], 2)
    0.11
    """
    at_ref, _ = tracks_at_reference_instants(marker_px, phase, rate_ratio, times)
    resid = others_residual(rig, at_ref)
    out = {}
    for c, px in at_ref.items():
        speed = np.linalg.norm(np.diff(np.asarray(px, float), axis=0), axis=-1)
        r, v = resid[c][np.isfinite(resid[c])], speed[np.isfinite(speed)]
        out[c] = float(np.median(r) / np.median(v)) if r.size and v.size and np.median(v) > 0 else float("nan")
    return out


def _spread(chunk_phase: list) -> float:
    """Standard error of the phase from the chunks' spread (:data:`GRID_STEP` from fewer than three chunks)."""
    if len(chunk_phase) < 3:
        return GRID_STEP
    return max(float(np.std(np.asarray(chunk_phase, float), ddof=1) / np.sqrt(len(chunk_phase))), 1e-3)


def others_residual(rig, marker_px: dict) -> dict:
    """Camera -> (n, m) distance (px) of its positions from the other cameras' markers projected into it.

    For every camera the markers are triangulated from the OTHER cameras
    alone (joint, no residual limit) and projected into it; the distance to
    its own position at the same instant is left by a timing error (a
    camera ``d`` frames off lies about ``d`` times the markers' motion per
    frame from the others' points) as well as by the detection noise and
    the calibration. Evaluated on the cameras' positions at common instants
    (e.g. :func:`tracks_at_reference_instants`), it is the residual of the
    synchronisation after the sub-frame correction. NaN where this camera
    or fewer than two others see the marker.

    Parameters
    ----------
    rig : Rig
        The cameras (at least three, indexed by name).
    marker_px : dict
        Camera -> (n, m, 2) positions at the same instants.

    Examples
    --------
    Three cameras in a row see two markers; the middle camera's view is
    then shifted by 2 px, as a timing error would move it:

    >>> from horsemocap.camera import Camera, Rig
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> rig = Rig(tuple(Camera(n, (640, 480), K, translation=[x, 0.0, 0.0])
    ...                 for n, x in (("left", 0.5), ("middle", 0.0), ("right", -0.5))))
    >>> points = np.array([[[0.1, 0.0, 4.0], [-0.2, 0.1, 5.0]]])
    >>> px = {c.name: c.project(points) for c in rig.cameras}
    >>> px["middle"] = px["middle"] + [2.0, 0.0]
    >>> round(float(np.nanmedian(others_residual(rig, px)["middle"])), 3)
    2.0
    """
    out = {}
    for cam, px in marker_px.items():
        px = np.asarray(px, float)
        others = {o: p for o, p in marker_px.items() if o != cam}
        if len(others) < 2:
            out[cam] = np.full(px.shape[:2], np.nan)
            continue
        points = triangulate(rig, others, mode="joint", max_residual_px=None).points
        out[cam] = np.linalg.norm(px - rig[cam].project(points), axis=-1)
    return out
