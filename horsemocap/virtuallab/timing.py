"""When an ordinary video camera exposes its frames and rows.

Consumer cameras (camcorders, phones, action cameras) are not genlocked:
each runs on its own crystal clock, so

- its frames start a fraction of a frame after another camera's
  (``phase_frames``, uniformly distributed from one recording to the next);
- its rate differs from the nominal one by tens of ppm
  (``rate_offset_ppm``: a clock fast by ``p`` ppm runs at
  ``nominal_fps (1 + p 1e-6)``), so the fraction drifts over a long record;
- each frame is exposed for ``exposure_s`` (motion blur over that time);
- a CMOS sensor reads its rows one after another (rolling shutter): row
  ``r`` of ``H`` starts ``r / H * rolling_shutter_s`` after row 0;
- an interlaced camera (PAL DV: 720 x 576 at 25 frames of two fields)
  exposes the odd and even rows as two fields half a frame apart.

A light switched on during an exposure brightens that frame in proportion to
the part of the exposure after the switch-on (:func:`flash_fraction`): the
partial first lit frame times the flash within the frame.

The functions here are pure: they give instants in seconds on a common
clock (the scene's), from a camera's :class:`CameraTiming` and the instant
its frame 0 starts.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .horse import GAITS, saddle_motion

#: Interlacing orders: which field (rows ``r % 2``) is exposed first.
INTERLACE_ORDERS = ("bottom_first", "top_first")


@dataclass(frozen=True)
class CameraTiming:
    """How one camera's frames fall in time.

    Attributes
    ----------
    phase_frames : float
        This camera's frame start after the reference camera's, as a fraction
        of a frame in ``[0, 1)`` (0 = genlocked to the reference).
    rate_offset_ppm : float
        Clock error: the camera runs at ``nominal_fps (1 + ppm 1e-6)``.
    nominal_fps : float
        The frame rate the file says (25, 30, 50, 60; the NTSC-family
        30000/1001 is a nominal rate too).
    exposure_s : float or None
        Exposure of a frame (of a field, interlaced). ``None``: half a frame,
        ``1 / (2 nominal_fps)``, the "180 degree shutter" video cameras use
        in automatic exposure under arena lights (1/60 s at 30 fps).
    rolling_shutter_s : float
        Readout time: row ``r`` of ``H`` starts ``r / H * rolling_shutter_s``
        after row 0 (0: a global shutter; 10-30 ms in phones and action cameras).
    interlaced : {None, "bottom_first", "top_first"}
        Interlaced fields: the rows of one parity are exposed half a frame
        after the others. ``"bottom_first"`` (PAL DV): the bottom field, the
        odd rows counted from 0, comes first.

    Examples
    --------
    >>> t = CameraTiming(nominal_fps=25.0)
    >>> t.exposure
    0.02
    >>> t.fps
    25.0
    >>> CameraTiming(nominal_fps=30.0, rate_offset_ppm=100.0).fps
    30.003
    """

    phase_frames: float = 0.0
    rate_offset_ppm: float = 0.0
    nominal_fps: float = 30.0
    exposure_s: float | None = None
    rolling_shutter_s: float = 0.0
    interlaced: str | None = None

    def __post_init__(self):
        if not 0.0 <= self.phase_frames < 1.0:
            raise ValueError(f"CameraTiming.phase_frames: expected a fraction of a frame in [0, 1), "
                             f"got {self.phase_frames!r}")
        if not self.nominal_fps > 0:
            raise ValueError(f"CameraTiming.nominal_fps: expected a positive frame rate, got {self.nominal_fps!r}")
        if self.exposure_s is not None and not 0.0 <= self.exposure_s <= 1.0 / self.nominal_fps:
            raise ValueError(f"CameraTiming.exposure_s: expected 0 .. one frame (1/{self.nominal_fps} s), "
                             f"got {self.exposure_s!r}")
        if not 0.0 <= self.rolling_shutter_s < 1.0 / self.nominal_fps:
            raise ValueError(f"CameraTiming.rolling_shutter_s: expected 0 .. less than one frame, "
                             f"got {self.rolling_shutter_s!r}")
        if self.interlaced is not None and self.interlaced not in INTERLACE_ORDERS:
            raise ValueError(f"CameraTiming.interlaced: expected None or one of {INTERLACE_ORDERS}, "
                             f"got {self.interlaced!r}")

    @property
    def fps(self) -> float:
        """The true frame rate, ``nominal_fps (1 + rate_offset_ppm 1e-6)``."""
        return self.nominal_fps * (1.0 + self.rate_offset_ppm * 1e-6)

    @property
    def exposure(self) -> float:
        """Exposure time (s): ``exposure_s``, or half a nominal frame (the virtual camera's own default, the
        usual 180-degree shutter; the analysis assumes the same when a session does not say,
        :func:`horsemocap.subframe.exposure_seconds`, but the laboratory does not read the analysis' code)."""
        return 0.5 / self.nominal_fps if self.exposure_s is None else float(self.exposure_s)

    @property
    def field_delay_s(self) -> float:
        """Delay of the second field (half a frame) or 0 when progressive."""
        return 0.5 / self.fps if self.interlaced else 0.0

    def to_dict(self) -> dict:
        """JSON-ready fields (``exposure_s`` resolved)."""
        d = asdict(self)
        d["exposure_s"] = self.exposure
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "CameraTiming":
        """Inverse of :meth:`to_dict` (unknown keys are an error naming them)."""
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"camera timing: unknown fields {sorted(unknown)}; expected "
                             f"{sorted(cls.__dataclass_fields__)}")
        return cls(**d)


def frame_start_times(timing: CameraTiming, n: int, t0: float = 0.0) -> np.ndarray:
    """Exposure start of row 0 of frames ``0 .. n-1`` (s).

    Frame ``k`` starts at ``t0 + k / fps`` with the camera's true rate
    ``fps = nominal_fps (1 + ppm 1e-6)``; ``t0`` is the start of frame 0
    (the phase is the caller's: it places ``t0``).

    Examples
    --------
    >>> frame_start_times(CameraTiming(nominal_fps=25.0), 3, t0=1.0)
    array([1.  , 1.04, 1.08])

    A clock 100 ppm fast is 1 ms ahead after 10 s (300 frames at 30 fps):

    >>> fast = CameraTiming(nominal_fps=30.0, rate_offset_ppm=100.0)
    >>> drift = 10.0 - frame_start_times(fast, 301)[300]
    >>> round(float(drift) * 1e3, 4)
    0.9999
    """
    return t0 + np.arange(int(n)) / timing.fps


def row_time(timing: CameraTiming, frame_start, row, height: int):
    """Exposure start of image row ``row`` (may be fractional) of a frame (s).

    ``frame_start + field * field_delay + row / height * rolling_shutter_s``:
    rows are read one after another over the readout time, and in an
    interlaced frame the rows of the second field (``row % 2 == 0`` when
    bottom field first) start half a frame later. Arrays broadcast.

    Examples
    --------
    A 30 ms readout, 1080 rows: the middle row starts 15 ms after row 0.

    >>> rs = CameraTiming(nominal_fps=30.0, rolling_shutter_s=0.03)
    >>> round(float(row_time(rs, 0.0, 540, 1080)), 6)
    0.015

    PAL, bottom field first: row 1 is in the first field, row 0 in the second, 20 ms later.

    >>> pal = CameraTiming(nominal_fps=25.0, interlaced="bottom_first")
    >>> [round(float(row_time(pal, 0.0, r, 576)), 6) for r in (0, 1, 2, 3)]
    [0.02, 0.0, 0.02, 0.0]
    """
    row = np.asarray(row, float)
    t = np.asarray(frame_start, float) + row / float(height) * timing.rolling_shutter_s
    if timing.interlaced:
        second = (np.rint(row).astype(int) % 2 == 0) if timing.interlaced == "bottom_first" \
            else (np.rint(row).astype(int) % 2 == 1)
        t = t + np.where(second, timing.field_delay_s, 0.0)
    return t if t.ndim else float(t)


def field_start_times(timing: CameraTiming, frame_start) -> tuple:
    """Exposure starts of a frame's fields, in exposure order (one for a progressive frame).

    Examples
    --------
    >>> field_start_times(CameraTiming(nominal_fps=25.0, interlaced="bottom_first"), 0.0)
    (0.0, 0.02)
    >>> field_start_times(CameraTiming(nominal_fps=30.0), 1.5)
    (1.5,)
    """
    s = float(frame_start)
    return (s, s + timing.field_delay_s) if timing.interlaced else (s,)


def field_rows(timing: CameraTiming, field: int, height: int) -> np.ndarray:
    """Image rows exposed in field ``field`` (0 = first, 1 = second) of an interlaced frame.

    Examples
    --------
    >>> field_rows(CameraTiming(nominal_fps=25.0, interlaced="bottom_first"), 0, 6)
    array([1, 3, 5])
    >>> field_rows(CameraTiming(nominal_fps=25.0, interlaced="top_first"), 0, 6)
    array([0, 2, 4])
    """
    if not timing.interlaced:
        return np.arange(height)
    first_parity = 1 if timing.interlaced == "bottom_first" else 0
    parity = first_parity if field == 0 else 1 - first_parity
    return np.arange(parity, height, 2)


def flash_fraction(timing: CameraTiming, frame_start, onset_s: float, offset_s: float | None = None):
    """Part of an exposure starting at ``frame_start`` during which a light is on (0..1).

    The light switches on at ``onset_s`` (and off at ``offset_s``, if given);
    a frame's brightness rises in proportion to the part of its exposure
    ``[frame_start, frame_start + exposure]`` with the light on. A zero
    exposure is lit when its instant is inside the lit interval.

    Examples
    --------
    A 1/60 s exposure at 30 fps; the flash switches on a quarter into it:

    >>> t = CameraTiming(nominal_fps=30.0)
    >>> round(float(flash_fraction(t, 0.0, onset_s=0.25 / 60)), 6)
    0.75
    >>> float(flash_fraction(t, 0.0, onset_s=-1.0)), float(flash_fraction(t, 0.0, onset_s=1.0))
    (1.0, 0.0)

    Switched off half-way through:

    >>> round(float(flash_fraction(t, 0.0, onset_s=-1.0, offset_s=0.5 / 60)), 6)
    0.5
    """
    start = np.asarray(frame_start, float)
    e = timing.exposure
    off = np.inf if offset_s is None else float(offset_s)
    if e <= 0:
        out = ((start >= onset_s) & (start < off)).astype(float)
    else:
        dark_before = np.clip(onset_s - start, 0.0, e)
        dark_after = np.clip(start + e - off, 0.0, e) if np.isfinite(off) else 0.0
        out = np.clip(e - dark_before - dark_after, 0.0, e) / e
    return out if out.ndim else float(out)


def draw_free_running(rng: np.random.Generator, fps: float, cameras=("left", "middle", "right"), *,
                      reference: str = "left", max_ppm: float = 100.0, max_readout_s: float = 0.030,
                      exposure_s: float | None = None, interlaced: str | None = None) -> dict:
    """Draw the timings of a set of free-running cameras.

    The reference camera has phase 0; every other camera's phase is uniform
    in ``[0, 1)``. Every camera's rate offset is uniform in
    ``+-max_ppm``; its rolling-shutter readout is uniform in
    ``[0, min(max_readout_s, 0.9 / fps)]`` (a sensor reads its rows
    within a frame; ``max_readout_s = 0``: global shutters; an interlaced
    camera has none).

    Returns
    -------
    dict
        camera name -> :class:`CameraTiming`.

    Examples
    --------
    >>> timings = draw_free_running(np.random.default_rng(0), 30.0)
    >>> sorted(timings), timings["left"].phase_frames
    (['left', 'middle', 'right'], 0.0)
    >>> all(abs(t.rate_offset_ppm) <= 100 and 0 <= t.rolling_shutter_s <= 0.03 for t in timings.values())
    True
    """
    if reference not in cameras:
        raise ValueError(f"draw_free_running: reference {reference!r} is not one of the cameras {tuple(cameras)}")
    out = {}
    for cam in cameras:
        phase = 0.0 if cam == reference else float(rng.uniform(0.0, 1.0))
        ppm = float(rng.uniform(-max_ppm, max_ppm))
        longest = min(max_readout_s, 0.9 / fps)
        readout = float(rng.uniform(0.0, longest)) if (longest > 0 and not interlaced) else 0.0
        out[cam] = CameraTiming(phase_frames=phase, rate_offset_ppm=ppm, nominal_fps=float(fps),
                                exposure_s=exposure_s, rolling_shutter_s=readout, interlaced=interlaced)
    return out


@dataclass(frozen=True)
class FractionCost:
    """What a timing error of a fraction of a frame costs a horse at a gait (see :func:`fraction_cost`).

    Attributes
    ----------
    gait : str
    fps : float
    fraction : float
        Frames.
    delay_ms : float
        The fraction in milliseconds.
    travel_mm : float
        The saddle's travel along the path in that time (its mean speed x delay).
    acc_y_pct : float
        Rms of the saddle's vertical acceleration read that late against the true one, % of its rms.
    """

    gait: str
    fps: float
    fraction: float
    delay_ms: float
    travel_mm: float
    acc_y_pct: float


def fraction_cost(horse: str, gait: str, fps: float, fraction: float, samples: int = 400) -> FractionCost:
    """What a view ``fraction`` of a frame late costs: the saddle's travel, and its vertical acceleration.

    Two cameras whose frames fall ``fraction / fps`` seconds apart see
    each marker where it was at two instants: ``travel_mm`` apart along the
    path (the saddle's mean speed times the delay) for a marker moving with
    the horse. The vertical acceleration the comfort indices weigh, read
    that late (``a_y(t + delay)`` against ``a_y(t)`` over a stride of the
    analytic saddle motion, :func:`horsemocap.virtuallab.horse.saddle_motion`),
    is off by ``acc_y_pct`` % of its rms: about ``2 pi f delay`` for a
    component at ``f`` Hz, so the stride's higher harmonics weigh most. A
    camera that far off in time moves the triangulated points by part of
    these (its share of the views).

    Examples
    --------
    Half a frame at 30 fps at canter (about 4.9 m/s): 8 cm of travel.

    >>> c = fraction_cost("Horse 2", "canter", 30.0, 0.5)
    >>> round(c.delay_ms, 1), round(c.travel_mm)
    (16.7, 81)
    >>> fraction_cost("Horse 2", "canter", 60.0, 0.25).acc_y_pct < c.acc_y_pct
    True
    """
    motion = saddle_motion(horse, gait)
    delay = float(fraction) / float(fps)
    t = np.linspace(0.0, motion.period_s, int(samples), endpoint=False) + 1.0
    down = motion.gravity
    a_now = motion.saddle(t)[2] @ down
    a_late = motion.saddle(t + delay)[2] @ down
    pct = 100.0 * float(np.sqrt(np.mean((a_late - a_now) ** 2)) / np.std(a_now))
    return FractionCost(gait=gait, fps=float(fps), fraction=float(fraction), delay_ms=1e3 * delay,
                        travel_mm=1e3 * motion.gait.speed_mps * delay, acc_y_pct=pct)


def fraction_costs(horse: str = "Horse 2", fps_values=(25.0, 30.0, 50.0, 60.0), fractions=(0.1, 0.25, 0.5),
                   gaits=GAITS) -> list:
    """:func:`fraction_cost` for every gait, frame rate and fraction (a list of :class:`FractionCost`).

    Examples
    --------
    >>> rows = fraction_costs(fps_values=(30.0,), fractions=(0.5,), gaits=("walk", "canter"))
    >>> [(r.gait, round(r.travel_mm)) for r in rows]
    [('walk', 28), ('canter', 81)]
    """
    return [fraction_cost(horse, g, f, x) for g in gaits for f in fps_values for x in fractions]
