"""The camera's temporal aperture: what one observation of a moving point averages over time.

A camera does not sample a marker at an instant. Its sensor collects light
for the exposure time ``e``, so a marker's centroid is the mean of its
positions over a box of length ``e`` around the frame's instant; an
interlaced camera exposes its two fields half a frame apart, and a frame's
centroid measured as the mean of its two fields' centres (as
:mod:`horsemocap.detection.fields` measures it) is the mean of two such boxes,
centred a quarter of a frame before and after the frame's instant. For a
harmonic of frequency ``f`` the box passes ``sinc(f e)`` of its amplitude and
the two fields' mean ``cos(pi f d)`` (``d``: the fields' delay), so a fit that
takes each observation for the motion at one instant estimates a low-passed
motion: its accelerations, whose weight lies in the higher harmonics, come out
too small.

An :class:`Aperture` is that average as a quadrature: times relative to the
observation's instant and weights summing to 1, so that the observation of a
trajectory ``s`` at ``t`` is ``sum_q w_q s(t + o_q)``. Each box is split at
the observation's instant and integrated by Gauss-Legendre nodes on each part:
exact for a polynomial of degree ``2 GAUSS_NODES - 1`` on each part, so for the
quintic smoothing spline whose knots are the observations' instants
(:mod:`horsemocap.splines`) and any box shorter than the frame interval, exact.
A smoothing spline fitted with the aperture (``aperture`` of
:func:`horsemocap.splines.smoothing_spline`) has its basis averaged the same
way: it estimates the motion itself, and its derivatives are the unblurred
motion's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .session import INTERLACE_ORDERS
from .subframe import exposure_seconds

__all__ = ["Aperture", "GAUSS_NODES", "box_aperture", "camera_aperture", "mean_aperture", "session_aperture"]

#: Gauss-Legendre nodes on each half of a box (exact for a polynomial of degree 5 on each half).
GAUSS_NODES = 3


@dataclass(frozen=True)
class Aperture:
    """One observation's average over time: ``y(t) = sum_q weights[q] s(t + offsets_s[q])``.

    Attributes
    ----------
    offsets_s : tuple of float
        The quadrature's times relative to the observation's instant (s).
    weights : tuple of float
        Their weights (positive, summing to 1).
    description : str
        What the aperture models, for the analysis' record.

    Examples
    --------
    The mean of a sinusoid over a 20 ms box: its amplitude times sinc(f e).

    >>> import numpy as np
    >>> a = box_aperture(0.02)
    >>> t = np.array([0.1, 0.2])
    >>> np.allclose(a.average(lambda u: np.sin(2 * np.pi * 8.0 * u), t),
    ...             np.sinc(8.0 * 0.02) * np.sin(2 * np.pi * 8.0 * t))
    True
    """

    offsets_s: tuple
    weights: tuple
    description: str = ""

    def __post_init__(self):
        o, w = np.asarray(self.offsets_s, float), np.asarray(self.weights, float)
        if o.ndim != 1 or o.shape != w.shape or o.size == 0:
            raise ValueError(f"aperture: expected as many offsets as weights (at least one), got {o.shape} and {w.shape}")
        if not (np.all(np.isfinite(o)) and np.all(np.isfinite(w)) and np.all(w > 0) and abs(w.sum() - 1) < 1e-9):
            raise ValueError(f"aperture: expected finite offsets and positive weights summing to 1, got {self.weights}")

    def average(self, f, t, *args) -> np.ndarray:
        """``sum_q w_q f(t + o_q, *args)``: what an observation at each ``t`` sees of ``f``."""
        t = np.asarray(t, float)
        return sum(w * np.asarray(f(t + o, *args), float) for o, w in zip(self.offsets_s, self.weights))

    def gain(self, frequency_hz) -> np.ndarray:
        """The complex gain of the aperture at each frequency (1 at 0 Hz; real for a symmetric aperture)."""
        f = np.asarray(frequency_hz, float)
        return sum(w * np.exp(2j * np.pi * f * o) for o, w in zip(self.offsets_s, self.weights))


def _box_nodes(start: float, stop: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights (summing to ``stop - start``) of ``[start, stop]``."""
    g, gw = np.polynomial.legendre.leggauss(GAUSS_NODES)
    return 0.5 * (stop - start) * (g + 1) + start, 0.5 * (stop - start) * gw


def _boxes(centres, exposure_s: float, description: str) -> Aperture:
    """The mean of boxes of ``exposure_s`` centred at each of ``centres`` (s), each split at 0."""
    offsets, weights = [], []
    for c in centres:
        a, b = c - exposure_s / 2, c + exposure_s / 2
        parts = [(a, b)] if (a >= 0 or b <= 0) else [(a, 0.0), (0.0, b)]
        for lo, hi in parts:
            o, w = _box_nodes(lo, hi)
            offsets.extend(o)
            weights.extend(w / (exposure_s * len(centres)))
    return Aperture(tuple(float(v) for v in offsets), tuple(float(v) for v in weights), description)


def box_aperture(exposure_s: float) -> Aperture:
    """A progressive frame exposed for ``exposure_s`` around its instant.

    Examples
    --------
    >>> a = box_aperture(0.008)
    >>> len(a.offsets_s), round(sum(a.weights), 12), round(max(a.offsets_s), 4) <= 0.004
    (6, 1.0, True)
    """
    if not (np.isfinite(exposure_s) and exposure_s > 0):
        raise ValueError(f"exposure_s: expected a positive exposure time (s), got {exposure_s!r}")
    return _boxes([0.0], float(exposure_s), f"exposure {1e3 * exposure_s:.3g} ms")


def camera_aperture(fps: float, exposure_s: float | None = None, interlaced: bool = False) -> Aperture | None:
    """The aperture of a camera's frame: its exposure box and, interlaced, the mean of its two fields.

    Parameters
    ----------
    fps : float
        The frame rate; an interlaced frame's fields are ``1 / (2 fps)`` apart.
    exposure_s : float, optional
        The exposure time (of each field when interlaced), at most one frame (one field, interlaced);
        None or 0: the observation is taken at its instant (an interlaced frame's fields each at theirs).
    interlaced : bool
        The frame's centroid is the mean of its two fields' centres.

    Returns
    -------
    Aperture, or None when there is nothing to model (a progressive frame taken at its instant).

    Examples
    --------
    PAL: fields 20 ms apart, each exposed 20 ms. A harmonic of 8.4 Hz keeps cos(pi 8.4 0.02) sinc(8.4 0.02)
    of its amplitude.

    >>> import numpy as np
    >>> a = camera_aperture(25.0, 0.02, interlaced=True)
    >>> bool(np.isclose(a.gain(8.4).real, np.cos(np.pi * 8.4 * 0.02) * np.sinc(8.4 * 0.02)))
    True
    >>> camera_aperture(25.0) is None, camera_aperture(25.0, 0.0) is None
    (True, True)
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: expected a positive frame rate, got {fps!r}")
    longest = (0.5 if interlaced else 1.0) / fps
    if exposure_s is not None and not (np.isfinite(exposure_s) and 0 <= exposure_s <= longest * (1 + 1e-9)):
        raise ValueError(f"exposure_s: expected an exposure time from 0 to one {'field' if interlaced else 'frame'} "
                         f"({longest:.6g} s at {fps:g} fps), got {exposure_s!r}")
    if not exposure_s:
        exposure_s = None
    if exposure_s is None and not interlaced:
        return None
    delay = 0.5 / fps
    centres = [-delay / 2, delay / 2] if interlaced else [0.0]
    fields = f"two fields {1e3 * delay:.3g} ms apart" if interlaced else ""
    if exposure_s is None:
        return Aperture(tuple(centres), tuple([1.0 / len(centres)] * len(centres)), fields + ", each at its instant")
    box = f"exposure {1e3 * exposure_s:.3g} ms"
    return _boxes(centres, float(exposure_s), f"{fields}, each {box}" if interlaced else box)


def mean_aperture(apertures) -> Aperture | None:
    """The mean of several cameras' apertures (a camera without one observes at its instant); None if
    none has one.

    A marker's 3D position is triangulated from every camera that sees it;
    to first order it is a weighted mean of their observations, here taken
    with equal weights.

    Examples
    --------
    >>> a = mean_aperture([box_aperture(0.01), None])
    >>> round(sum(a.weights), 12), 0.0 in a.offsets_s
    (1.0, True)
    """
    given = list(apertures)
    if all(a is None for a in given):
        return None
    if len({a for a in given}) == 1:
        return given[0]
    offsets, weights, names = [], [], []
    for a in given:
        a = Aperture((0.0,), (1.0,), "at its instant") if a is None else a
        offsets.extend(a.offsets_s)
        weights.extend(w / len(given) for w in a.weights)
        names.append(a.description)
    return Aperture(tuple(offsets), tuple(weights), "mean of the cameras': " + "; ".join(names))


def session_aperture(fps: float, timings) -> Aperture | None:
    """The aperture of a session's observations from its cameras' ``camera_timing`` (camera -> its entry:
    ``exposure_s``, ``interlaced``; docs/sessions.md; or a list of entries, the cameras then named by
    position): :func:`mean_aperture` of :func:`camera_aperture`.

    A camera with an entry but no ``exposure_s`` is exposed for the documented default, half a frame
    (:func:`horsemocap.subframe.exposure_seconds`, as the synchronisation times the flash);
    ``exposure_s`` 0 is an instant; a camera without an entry (``{}``) is taken at its instants. None
    when no camera has anything to model. An exposure longer than a frame (than a field, interlaced)
    is an error naming the camera's field.

    Examples
    --------
    >>> session_aperture(25.0, {"left": {}, "right": {}}) is None
    True
    >>> session_aperture(25.0, {c: {"exposure_s": 0.02, "interlaced": "bottom_first"} for c in "abc"}).description
    'two fields 20 ms apart, each exposure 20 ms'
    >>> session_aperture(25.0, {"left": {"rolling_shutter_s": 0.02}}).description
    'exposure 20 ms'
    """
    out = []
    for camera, timing in (timings.items() if isinstance(timings, dict) else enumerate(timings)):
        if not timing:
            out.append(None)
            continue
        interlaced = timing.get("interlaced") in INTERLACE_ORDERS
        if not interlaced and timing.get("interlaced") not in (None, False):
            raise ValueError(f"metadata.camera_timing.{camera}.interlaced: expected one of {list(INTERLACE_ORDERS)} "
                             f"or null/false, got {timing['interlaced']!r}")
        try:
            out.append(camera_aperture(fps, exposure_seconds(timing, fps), interlaced))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"metadata.camera_timing.{camera}.exposure_s: {exc}".replace(": exposure_s:", ":")) \
                from None
    return mean_aperture(out)
