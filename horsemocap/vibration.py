"""Whole-body vibration: frequency weightings and the rider's comfort indicators.

Thesis chapter 7 (eq. 7.1-7.25, Tables 7.1-7.2, Figure 7.1) and section 8.4.1
(Table 8.7). The saddle's vertical acceleration ``A_y`` (motion frame, y along
gravity, positive DOWN) is frequency weighted with ``W_b`` (BS 6841) and
``W_k`` (ISO 2631-1), then reduced to

* the weighted r.m.s. ``a_w,rms`` (eq. 7.3-7.4), the peak (7.5-7.6), the crest
  factor (7.7) and the vibration dose value VDV (7.8-7.9);
* the daily exposure times to reach the EU Directive 2002/44/EC action and
  limit values (Table 7.2) by A(8) (eq. 7.10-7.13) and by VDV (7.14-7.17);
* the allowable daily distances ``V_x,avg * T`` (eq. 7.18-7.25).

The weightings
--------------
Every weighting is the product of analogue second-order sections (ISO 2631-1
Annex A, ISO 8041 Table 3 -- the parameter table is reproduced in e.g. the
Larson Davis HVM200 manual, "source: ISO 8041"):

* band limiting: high-pass ``s^2 / (s^2 + s w1/Q1 + w1^2)`` and low-pass
  ``w2^2 / (s^2 + s w2/Q2 + w2^2)`` (Butterworth, Q1 = Q2 = 1/sqrt(2));
* acceleration-velocity transition ``(1 + s/w3) / (1 + s/(Q4 w4) + s^2/w4^2)``;
* upward step ``(s^2 + s w5/Q5 + w5^2) / (s^2 + s w6/Q6 + w6^2)``;
* a gain ``K``.

With w = 2 pi f:

======  ====  ===  ====  ====  ====  ====  ====  ====  ====  =====
 name    f1    f2   f3    f4    Q4    f5    Q5    f6    Q6    K
======  ====  ===  ====  ====  ====  ====  ====  ====  ====  =====
 Wb     0.4   100  16    16    0.55  2.5   0.9   4.0   0.95  1.024
 Wk     0.4   100  12.5  12.5  0.63  2.37  0.91  3.35  0.91  1
 Wd     0.4   100  2.0   2.0   0.63  --    --    --    --    1
======  ====  ===  ====  ====  ====  ====  ====  ====  ====  =====

Two ways of writing ``W_b``: BS 6841 (1987) writes the upward step as
``(1 + s/(Q5 w5) + s^2/w5^2) / (1 + s/(Q6 w6) + s^2/w6^2)`` (unity at low
frequency) with ``K = 0.4``; ISO 2631-4 / ISO 8041 write it as above (value
``(f5/f6)^2`` at low frequency) with ``K = 1.024``. Both are the same filter:
``0.4 * (4.0/2.5)^2 = 1.024`` exactly (:func:`weighting_bs6841_wb` checks it).

The thesis (section 7.2.1) derived closed forms of ``|W_b(f)|`` and
``|W_k(f)|`` from Rimell and Mansfield (2007); they are not printed, so this
module starts again from the standards' definitions.

A sampled record is weighted here by the DFT (:func:`fft_weighting`); the
digital (IIR) weighting filters of a vibration meter, and the comfort of an
accelerometer's samples, are in :mod:`horsemocap.weighting_filters`.

Weighting modes
---------------
``mode="iso"`` (default, what the standards mean): each harmonic of the
fitted vertical acceleration is multiplied by the complex ``W(f)`` at its
own frequency; the weighted time history is re-synthesised and its rms,
peak and VDV computed. ``mode="thesis"``: one real scalar ``|W(f_dom)|`` at
the dominant harmonic (largest acceleration amplitude) multiplies the whole
signal, eq. 7.1-7.2 read literally ``A_wb(t) = W_b . A_y(t)``. This is what
Table 8.7 shows: its ``W_k/W_b`` ratio is the same for rms and VDV
(3.7007/3.1906 = 4.3997/3.7932 = 1.1599) and its crest factor is equal for
both weightings (eq. 7.7), which only a scalar weighting gives.

The VDV exposure time (a typo in eq. 7.14-7.17)
-----------------------------------------------
Eq. 7.14-7.17 print ``T = tau (VDV_threshold / VDV)`` and put the *action*
value into the limit equations 7.16-7.17. VDV grows with the fourth root of
time, so the time to reach a threshold is ``T = tau (VDV_threshold/VDV)^4``,
with the action value in the action equations and the limit value in the
limit ones. Table 8.7 was computed that way, with ``tau = 1.2 s`` (two
periods of 18 frames at 30 fps): e.g. 1.2 (21/3.7932)^4 s = 0.3131 h, its
``TVDV_limit_Wb``. This module implements the correct form.
"""
from __future__ import annotations

import csv
import html
import io
import math
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import optimize

from .store import atomic_write_bytes, atomic_write_text

__all__ = [
    "WeightingParameters", "WEIGHTINGS", "WB_BS6841", "EU_2002_44_EC", "ExposureValues",
    "THIRD_OCTAVE_HZ", "COMFORT_KEYS", "DIRECTIVE_KEYS", "COMFORT_UNITS", "THESIS_TABLE_8_7",
    "Harmonics",
    "weighting", "weighting_bs6841_wb", "analog_sections", "fft_weighting",
    "harmonics_from_fourier", "harmonics_from_periodic_samples", "synthesize", "dominant_frequency",
    "rms", "vdv", "crest_factor", "time_to_a8", "time_to_vdv", "exposure_times",
    "allowable_distances", "indicators_from_values",
    "comfort_indicators", "directive_indicators", "directive_axis", "saddle_comfort",
    "fit_harmonics", "estimate_fundamental", "weighted_histories",
    "comfort_table_rows", "write_comfort_csv", "read_comfort_csv",
    "write_comfort_spreadsheet",
]

# ---------------------------------------------------------------------------
# Weighting definitions
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class WeightingParameters:
    """Parameters of a frequency weighting (ISO 2631-1 Annex A, ISO 8041).

    Frequencies in Hz; ``inf`` removes a section (e.g. no upward step).
    ``step_form`` is ``"iso"`` (upward step -> (f5/f6)^2 at low frequency)
    or ``"bs6841"`` (upward step -> 1 at low frequency).

    Examples
    --------
    >>> wk = WEIGHTINGS["Wk"]
    >>> wk.f5, wk.f6, wk.K
    (2.37, 3.35, 1.0)
    """

    name: str
    f1: float
    f2: float
    f3: float
    f4: float
    Q4: float
    f5: float = math.inf
    Q5: float = 1.0
    f6: float = math.inf
    Q6: float = 1.0
    K: float = 1.0
    Q1: float = 1.0 / math.sqrt(2.0)
    Q2: float = 1.0 / math.sqrt(2.0)
    step_form: str = "iso"
    source: str = ""


WEIGHTINGS: dict[str, WeightingParameters] = {
    "Wb": WeightingParameters("Wb", 0.4, 100.0, 16.0, 16.0, 0.55, 2.5, 0.9, 4.0, 0.95, 1.024,
                              source="ISO 2631-4:2001 Table A.1 / ISO 8041; vertical, "
                                     "BS 6841:1987 (thesis Table 7.1)"),
    "Wk": WeightingParameters("Wk", 0.4, 100.0, 12.5, 12.5, 0.63, 2.37, 0.91, 3.35, 0.91, 1.0,
                              source="ISO 2631-1:1997 Table A.2; vertical, seated"),
    "Wd": WeightingParameters("Wd", 0.4, 100.0, 2.0, 2.0, 0.63,
                              source="ISO 2631-1:1997 Table A.2; horizontal"),
}
"""The weightings by name (thesis Table 7.1): ``Wb``, ``Wk``, ``Wd``."""

WB_BS6841 = WeightingParameters("Wb", 0.4, 100.0, 16.0, 16.0, 0.55, 2.5, 0.9, 4.0, 0.95, 0.4,
                                step_form="bs6841", source="BS 6841:1987, K = 0.4")
"""``W_b`` as BS 6841 writes it (K = 0.4, upward step unity at low frequency)."""

THIRD_OCTAVE_HZ = np.array([0.1, 0.125, 0.16, 0.2, 0.25, 0.315, 0.4, 0.5, 0.63, 0.8, 1.0,
                            1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0, 10.0, 12.5, 16.0,
                            20.0, 25.0, 31.5, 40.0, 50.0, 63.0, 80.0, 100.0, 125.0, 160.0,
                            200.0, 250.0, 315.0, 400.0])
"""Nominal one-third-octave centre frequencies (Hz) of ISO 2631-1 Table 3."""


def _params(name) -> WeightingParameters:
    if isinstance(name, WeightingParameters):
        return name
    try:
        return WEIGHTINGS[name]
    except KeyError:
        raise ValueError(f"unknown frequency weighting {name!r}; expected one of "
                         f"{sorted(WEIGHTINGS)}") from None


def analog_sections(name, *, band_limiting: bool = True) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """The weighting's analogue sections as ``(b, a, w0)`` polynomials in ``s``.

    ``b`` and ``a`` are coefficients in descending powers of ``s`` (as
    :func:`scipy.signal.freqs`), ``w0`` (rad/s) the section's characteristic
    frequency (used to pre-warp the digital filter). The gain ``K`` is folded
    into the first section.

    Parameters
    ----------
    name : {"Wb", "Wk", "Wd"} or WeightingParameters
    band_limiting : bool
        Include the 0.4 Hz high-pass and 100 Hz low-pass (ISO 2631-1 Table 3
        values include them).

    Examples
    --------
    >>> len(analog_sections("Wk"))          # high-pass, low-pass, transition, upward step
    4
    >>> len(analog_sections("Wd", band_limiting=False))   # Wd has no upward step
    1
    """
    p = _params(name)
    tp = 2.0 * math.pi
    secs = []
    if band_limiting:
        w1, w2 = tp * p.f1, tp * p.f2
        secs.append((np.array([1.0, 0.0, 0.0]), np.array([1.0, w1 / p.Q1, w1 * w1]), w1))
        secs.append((np.array([w2 * w2]), np.array([1.0, w2 / p.Q2, w2 * w2]), w2))
    if math.isfinite(p.f4):
        w3, w4 = tp * p.f3, tp * p.f4
        num = np.array([1.0 / w3, 1.0]) if math.isfinite(p.f3) else np.array([1.0])
        secs.append((num, np.array([1.0 / (w4 * w4), 1.0 / (p.Q4 * w4), 1.0]), w4))
    if math.isfinite(p.f5) and math.isfinite(p.f6):
        w5, w6 = tp * p.f5, tp * p.f6
        if p.step_form == "iso":
            num = np.array([1.0, w5 / p.Q5, w5 * w5])
            den = np.array([1.0, w6 / p.Q6, w6 * w6])
        elif p.step_form == "bs6841":
            num = np.array([1.0 / (w5 * w5), 1.0 / (p.Q5 * w5), 1.0])
            den = np.array([1.0 / (w6 * w6), 1.0 / (p.Q6 * w6), 1.0])
        else:
            raise ValueError(f"step_form must be 'iso' or 'bs6841', got {p.step_form!r}")
        secs.append((num, den, math.sqrt(w5 * w6)))
    b0, a0, w0 = secs[0]
    secs[0] = (b0 * p.K, a0, w0)
    return secs


def weighting(name, freq_hz, *, band_limiting: bool = True) -> np.ndarray:
    """Complex frequency response ``W(f)`` of ``"Wb"``, ``"Wk"`` or ``"Wd"``.

    The analogue definition (ISO 2631-1 Annex A); ``|W|`` is the weighting
    factor of thesis Figure 7.1 and ISO 2631-1 Table 3, ``angle(W)`` its phase.

    Parameters
    ----------
    name : {"Wb", "Wk", "Wd"}
    freq_hz : array_like
        Frequencies in Hz (>= 0).
    band_limiting : bool
        Include the 0.4-100 Hz band limiting (default, as the standards'
        tables do).

    Returns
    -------
    complex ndarray, shape of ``freq_hz``

    Examples
    --------
    The weighting factors of ISO 2631-1 Table 3 (Wk, 1 to 16 Hz):

    >>> import numpy as np
    >>> np.abs(weighting("Wk", [1.0, 4.0, 8.0, 16.0])).round(3)
    array([0.482, 0.967, 1.036, 0.769])
    """
    f = np.asarray(freq_hz, dtype=float)
    if np.any(f < 0) or not np.all(np.isfinite(f)):
        raise ValueError("weighting: freq_hz must be finite and >= 0")
    s = 2j * math.pi * f
    out = np.ones(f.shape, dtype=complex)
    for b, a, _ in analog_sections(name, band_limiting=band_limiting):
        out *= np.polyval(b, s) / np.polyval(a, s)
    return out


def weighting_bs6841_wb(freq_hz, *, band_limiting: bool = True) -> np.ndarray:
    """``W_b`` written as BS 6841 does (K = 0.4, other upward-step normalisation).

    Identical to ``weighting("Wb", f)`` (K = 1.024); kept to show it.

    Examples
    --------
    >>> import numpy as np
    >>> f = [0.5, 5.0, 50.0]
    >>> bool(np.allclose(weighting_bs6841_wb(f), weighting("Wb", f)))
    True
    """
    return weighting(WB_BS6841, freq_hz, band_limiting=band_limiting)


# ---------------------------------------------------------------------------
# Weighting a sampled signal
# ---------------------------------------------------------------------------


def fft_weighting(signal, fs: float, name, *, axis: int = 0) -> np.ndarray:
    """Frequency-weight sampled acceleration by the DFT (thesis eq. 7.1-7.2).

    The DFT of the record is multiplied by the analogue ``W(f)`` at each bin
    and transformed back: exact for a periodic record (e.g. whole gait
    cycles), with no warping at any sampling rate. The causal digital
    filter of a vibration meter is
    :func:`horsemocap.weighting_filters.apply_weighting` with ``method="iir"``.

    Parameters
    ----------
    signal : array_like
        Acceleration samples, time on ``axis``.
    fs : float
        Sampling rate in Hz.
    name : {"Wb", "Wk", "Wd"}
    axis : int
        The time axis.

    Returns
    -------
    ndarray
        The weighted samples, shaped as ``signal``.

    Examples
    --------
    A 4 Hz sine of amplitude 1 m/s^2 over whole periods: its weighted rms is
    ``|Wk(4 Hz)| / sqrt(2)``.

    >>> import numpy as np
    >>> fs = 100.0
    >>> t = np.arange(1000) / fs
    >>> weighted = fft_weighting(np.sin(2 * np.pi * 4 * t), fs, "Wk")
    >>> round(float(rms(weighted)), 4), round(float(abs(weighting("Wk", 4.0)) / np.sqrt(2)), 4)
    (0.6839, 0.6839)
    """
    x = np.asarray(signal, dtype=float)
    n = x.shape[axis]
    spec = np.fft.rfft(x, axis=axis)
    w = weighting(name, np.fft.rfftfreq(n, 1.0 / fs))
    shape = [1] * x.ndim
    shape[axis] = -1
    return np.fft.irfft(spec * w.reshape(shape), n=n, axis=axis)


# ---------------------------------------------------------------------------
# Harmonics of the fitted motion
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Harmonics:
    """A real signal as a sum of harmonics: ``x(t) = offset + Re(sum c_k exp(2j pi f_k t))``.

    Attributes
    ----------
    freq_hz : ndarray (n,)
    amplitude : complex ndarray (n,)
        ``c_k``; ``|c_k|`` is the harmonic's amplitude.
    offset : float

    Examples
    --------
    >>> h = Harmonics(freq_hz=[1.0], amplitude=[2.0], offset=0.5)
    >>> h.evaluate([0.0, 0.25, 0.5]).round(6)
    array([ 2.5,  0.5, -1.5])
    """

    freq_hz: np.ndarray
    amplitude: np.ndarray
    offset: float = 0.0

    def __post_init__(self):
        f = np.atleast_1d(np.asarray(self.freq_hz, dtype=float))
        c = np.atleast_1d(np.asarray(self.amplitude, dtype=complex))
        if f.shape != c.shape or f.ndim != 1:
            raise ValueError(f"Harmonics: freq_hz {f.shape} and amplitude {c.shape} must be "
                             "1-D of the same length")
        if np.any(f <= 0):
            raise ValueError("Harmonics: frequencies must be > 0 (put the mean in offset)")
        object.__setattr__(self, "freq_hz", f)
        object.__setattr__(self, "amplitude", c)

    def evaluate(self, t) -> np.ndarray:
        return synthesize(self, t)


def harmonics_from_fourier(coefficients, derivative: int = 2) -> Harmonics:
    """Harmonics of a MATLAB ``fourierN`` fit or of its time derivatives.

    ``y(t) = a0 + sum_i a_i cos(i w t) + b_i sin(i w t)`` (thesis eq. 5.x,
    coefficients in MATLAB order ``a0, a1, b1, ..., aN, bN, w``). The
    ``d``-th derivative has harmonics ``c_i = (j i w)^d (a_i - j b_i)`` at
    ``f_i = i w / (2 pi)``.

    Parameters
    ----------
    coefficients : array_like, length 2N + 2
    derivative : int
        0 position, 1 velocity, 2 acceleration.

    Examples
    --------
    The position ``y = 0.02 cos(w t) + 0.01 sin(2 w t)`` at 2 Hz: its
    acceleration's harmonics at 2 and 4 Hz, ``(2 pi 2)^2 0.02`` and
    ``(2 pi 4)^2 0.01`` m/s^2 in amplitude.

    >>> import numpy as np
    >>> h = harmonics_from_fourier([0.1, 0.02, 0.0, 0.0, 0.01, 2 * np.pi * 2.0], derivative=2)
    >>> h.freq_hz
    array([2., 4.])
    >>> np.abs(h.amplitude).round(4)
    array([3.1583, 6.3165])
    """
    c = np.asarray(coefficients, dtype=float).ravel()
    if c.size < 4 or c.size % 2:
        raise ValueError(f"harmonics_from_fourier: expected a0, a1, b1, ..., aN, bN, w "
                         f"(even length >= 4), got {c.size} values")
    w = c[-1]
    if not w > 0:
        raise ValueError(f"harmonics_from_fourier: the fundamental w must be > 0 rad/s, got {w}")
    a, b = c[1:-1:2], c[2:-1:2]
    i = np.arange(1, a.size + 1)
    amp = (1j * i * w) ** derivative * (a - 1j * b)
    return Harmonics(i * w / (2 * math.pi), amp, c[0] if derivative == 0 else 0.0)


def harmonics_from_periodic_samples(samples, duration_s: float, n_periods: int = 1,
                                    max_harmonic: int | None = None) -> Harmonics:
    """Harmonics of a periodic signal sampled uniformly over whole periods.

    ``samples`` cover ``[0, duration_s)`` (no repeated end point) =
    ``n_periods`` periods; the DFT bins at multiples of ``n_periods`` are the
    harmonics of the fundamental ``n_periods / duration_s`` (exact for a
    band-limited signal with enough samples). Used for analytic motions
    (the virtual laboratory's truth) and for whole-cycle accelerometer data.

    Examples
    --------
    >>> import numpy as np
    >>> samples = 1 + np.cos(2 * np.pi * np.arange(8) / 8)     # one period in 8 samples
    >>> h = harmonics_from_periodic_samples(samples, duration_s=1.0)
    >>> h.offset, float(h.freq_hz[0]), round(float(abs(h.amplitude[0])), 6)
    (1.0, 1.0, 1.0)
    """
    x = np.asarray(samples, dtype=float)
    if x.ndim != 1 or x.size < 4:
        raise ValueError(f"samples must be 1-D with >= 4 values, got shape {x.shape}")
    n = x.size
    spec = np.fft.rfft(x) / n
    k_max = (spec.size - 1) // n_periods
    if max_harmonic is not None:
        k_max = min(k_max, int(max_harmonic))
    k = np.arange(1, k_max + 1)
    f0 = n_periods / duration_s
    # one-sided amplitudes: twice the bin, except the Nyquist bin of an even count, which has no mirror
    factor = np.where(2 * k * n_periods == n, 1.0, 2.0)
    return Harmonics(k * f0, factor * spec[k * n_periods], float(spec[0].real))


def _as_harmonics(x) -> Harmonics:
    if isinstance(x, Harmonics):
        return x
    if hasattr(x, "coefficients"):  # a fitting.Fit of the vertical POSITION
        return harmonics_from_fourier(x.coefficients, derivative=2)
    if isinstance(x, tuple) and len(x) == 2:
        return Harmonics(x[0], x[1])
    raise TypeError("expected Harmonics, (freq_hz, complex amplitudes) of the acceleration, "
                    "or a Fourier Fit of the vertical position (with .coefficients); for "
                    "sampled acceleration use horsemocap.weighting_filters.comfort_from_samples("
                    "acc_y, fs, ...) or saddle_comfort(t, position, acceleration, velocity)")


def synthesize(harmonics: Harmonics, t) -> np.ndarray:
    """Evaluate ``offset + Re(sum c_k exp(2j pi f_k t))`` at times ``t`` (s).

    Examples
    --------
    >>> synthesize(Harmonics([1.0], [2.0], 0.5), [0.0, 0.25, 0.5]).round(6)
    array([ 2.5,  0.5, -1.5])
    """
    t = np.asarray(t, dtype=float)
    ph = np.exp(2j * math.pi * np.multiply.outer(t, harmonics.freq_hz))
    return harmonics.offset + (ph @ harmonics.amplitude).real


def dominant_frequency(harmonics: Harmonics) -> float:
    """Frequency (Hz) of the harmonic with the largest amplitude.

    Examples
    --------
    >>> dominant_frequency(Harmonics([2.0, 4.0], [1.0, 3.0]))
    4.0
    """
    return float(harmonics.freq_hz[int(np.argmax(np.abs(harmonics.amplitude)))])


# ---------------------------------------------------------------------------
# Indicators (eq. 7.3-7.9) and exposures (eq. 7.10-7.25)
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ExposureValues:
    """Daily exposure action (EAV) and limit (ELV) values, thesis Table 7.2.

    Examples
    --------
    >>> EU_2002_44_EC.a8_action, EU_2002_44_EC.a8_limit, EU_2002_44_EC.vdv_limit
    (0.5, 1.15, 21.0)
    """

    a8_action: float = 0.5      # m/s^2, A(8)
    a8_limit: float = 1.15      # m/s^2
    vdv_action: float = 9.1     # m/s^1.75
    vdv_limit: float = 21.0     # m/s^1.75
    source: str = "EU Directive 2002/44/EC (Physical Agents, vibration), whole-body"


EU_2002_44_EC = ExposureValues()


def rms(samples, axis: int = 0) -> np.ndarray:
    """Root mean square (eq. 7.3-7.4) of uniformly sampled values over the record.

    Examples
    --------
    >>> float(rms([3.0, -3.0, 3.0, -3.0]))
    3.0
    """
    x = np.asarray(samples, dtype=float)
    return np.sqrt(np.mean(x * x, axis=axis))


def vdv(samples, fs: float, axis: int = 0) -> np.ndarray:
    """Vibration dose value ``(int a^4 dt)^(1/4)`` (eq. 7.8-7.9), m/s^1.75.

    Examples
    --------
    A steady 2 m/s^2 for one second (100 samples at 100 Hz):

    >>> float(vdv([2.0] * 100, fs=100.0))
    2.0
    """
    x = np.asarray(samples, dtype=float)
    return (np.sum(x ** 4, axis=axis) / fs) ** 0.25


def crest_factor(samples, axis: int = 0) -> np.ndarray:
    """Peak over rms (eq. 7.5-7.7).

    Examples
    --------
    >>> round(float(crest_factor([1.0, -1.0, 1.0, -3.0])), 4)     # 3 / sqrt(3)
    1.7321
    """
    x = np.asarray(samples, dtype=float)
    return np.max(np.abs(x), axis=axis) / rms(x, axis=axis)


def time_to_a8(a_rms, threshold: float) -> np.ndarray:
    """Hours to reach an A(8) threshold: ``8 (threshold / a_rms)^2`` (eq. 7.10-7.13).

    Examples
    --------
    A weighted rms of 1 m/s^2 reaches the action value 0.5 m/s^2 in 2 h:

    >>> float(time_to_a8(1.0, 0.5))
    2.0
    """
    a = np.asarray(a_rms, dtype=float)
    return 8.0 * (threshold / a) ** 2


def time_to_vdv(vdv_value, duration_s: float, threshold: float) -> np.ndarray:
    """Hours to reach a VDV threshold: ``tau (threshold / VDV)^4 / 3600``.

    The corrected eq. 7.14-7.17 (the thesis prints the ratio without the
    fourth power; its Table 8.7 was computed with it). ``VDV`` was measured
    over ``duration_s`` = tau seconds.

    Examples
    --------
    A VDV of 10.5 m/s^1.75 over one hour reaches 21 m/s^1.75 in ``2^4`` hours:

    >>> float(time_to_vdv(10.5, 3600.0, 21.0))
    16.0
    """
    v = np.asarray(vdv_value, dtype=float)
    return duration_s * (threshold / v) ** 4 / 3600.0


def exposure_times(a_rms=None, vdv_value=None, duration_s=None,
                   limits: ExposureValues = EU_2002_44_EC) -> dict:
    """Times (h) to reach the action and limit values by A(8) and/or VDV.

    Returns a dict with ``TA_8_action``, ``TA_8_limit`` (when ``a_rms`` is
    given) and ``TVDV_action``, ``TVDV_limit`` (when ``vdv_value`` and
    ``duration_s`` are given).

    Examples
    --------
    >>> times = exposure_times(a_rms=1.0)
    >>> float(times["TA_8_action"]), round(float(times["TA_8_limit"]), 2)
    (2.0, 10.58)
    """
    out = {}
    if a_rms is not None:
        out["TA_8_action"] = time_to_a8(a_rms, limits.a8_action)
        out["TA_8_limit"] = time_to_a8(a_rms, limits.a8_limit)
    if vdv_value is not None:
        if duration_s is None:
            raise ValueError("exposure_times: a VDV needs the duration it was measured over")
        out["TVDV_action"] = time_to_vdv(vdv_value, duration_s, limits.vdv_action)
        out["TVDV_limit"] = time_to_vdv(vdv_value, duration_s, limits.vdv_limit)
    return out


def allowable_distances(speed_kmh, times_h: dict) -> dict:
    """``Distance_<T> = V_x,avg T`` in km (eq. 7.18-7.25) for each time in ``times_h``.

    Examples
    --------
    >>> allowable_distances(18.0, {"TA_8_action": 2.0})
    {'Distance_TA_8_action': 36.0}
    """
    return {f"Distance_{k}": speed_kmh * v for k, v in times_h.items()}


COMFORT_KEYS = (
    "acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk", "acc_y_max", "crest_factor_y",
    "TA_8_action_Wb", "TA_8_action_Wk", "TA_8_limit_Wb", "TA_8_limit_Wk",
    "TVDV_action_Wb", "TVDV_action_Wk", "TVDV_limit_Wb", "TVDV_limit_Wk",
    "Distance_TA_8_action_Wb", "Distance_TA_8_action_Wk", "Distance_TA_8_limit_Wb",
    "Distance_TA_8_limit_Wk", "Distance_TVDV_action_Wb", "Distance_TVDV_action_Wk",
    "Distance_TVDV_limit_Wb", "Distance_TVDV_limit_Wk", "vel_x_avg", "amplitude_y",
    "duration_s", "f0_hz", "period_s",
)
"""The indicators of ``comfort.csv`` (docs/sessions.md), in Table 8.7's order."""


def _unit(k: str) -> str:
    """The unit of an indicator of :data:`COMFORT_KEYS` or :data:`DIRECTIVE_KEYS`."""
    if k.startswith("Distance_"):
        return "km"
    if k.startswith("T"):
        return "h"
    if k.startswith("VDV"):
        return "m/s^1.75"
    return {"crest_factor_y": "1", "vel_x_avg": "km/h", "amplitude_y": "m",
            "duration_s": "s", "f0_hz": "Hz", "period_s": "s"}.get(k, "m/s^2")   # the rest: accelerations


DIRECTIVE_KEYS = (
    "acc_x_Wd_rms", "acc_y_Wk_rms_iso", "acc_z_Wd_rms", "VDV_x_Wd", "VDV_y_Wk_iso", "VDV_z_Wd",
    "A_w_directive", "VDV_directive",
    "TA_8_action_directive", "TA_8_limit_directive", "TVDV_action_directive", "TVDV_limit_directive",
    "Distance_TA_8_action_directive", "Distance_TA_8_limit_directive",
    "Distance_TVDV_action_directive", "Distance_TVDV_limit_directive",
)
"""The three-axis indicators of the EU Directive 2002/44/EC (:func:`directive_indicators`): optional
rows of ``comfort.csv`` after :data:`COMFORT_KEYS` (the thesis' indicators are the vertical axis's only).
``acc_y_Wk_rms_iso`` and ``VDV_y_Wk_iso`` are the vertical values the Directive compares, each harmonic
weighted at its own frequency: ``acc_y_Wk_rms`` and ``VDV_y_Wk`` in the ``"iso"`` weighting mode, not in
``"thesis"``."""

#: The Directive's axis factors (Annex B, as ISO 2631-1 for health): 1.4 on the horizontal axes (Wd), 1 vertical (Wk)
DIRECTIVE_HORIZONTAL_FACTOR = 1.4


def _directive_axes(x: float, y: float, z: float) -> dict:
    """The three axes' values as the Directive compares them: ``{"fore-aft": 1.4 x, "vertical": y, "lateral": 1.4 z}``."""
    k = DIRECTIVE_HORIZONTAL_FACTOR
    return {"fore-aft": k * x, "vertical": y, "lateral": k * z}


COMFORT_UNITS = {k: _unit(k) for k in COMFORT_KEYS + DIRECTIVE_KEYS}
"""Unit of each indicator, as in thesis Table 8.7 (and of the Directive's three-axis rows)."""

THESIS_TABLE_8_7 = {
    "acc_y_Wb_rms": 3.1906, "acc_y_Wk_rms": 3.7007, "VDV_y_Wb": 3.7932, "VDV_y_Wk": 4.3997,
    "acc_y_max": 11.6971, "crest_factor_y": 1.6245,
    "TA_8_action_Wb": 0.1965, "TA_8_action_Wk": 0.1460, "TA_8_limit_Wb": 1.0393,
    "TA_8_limit_Wk": 0.7725, "TVDV_action_Wb": 0.0110, "TVDV_action_Wk": 0.0061,
    "TVDV_limit_Wb": 0.3131, "TVDV_limit_Wk": 0.1730,
    "Distance_TA_8_action_Wb": 3.4653, "Distance_TA_8_action_Wk": 2.5758,
    "Distance_TA_8_limit_Wb": 18.3313, "Distance_TA_8_limit_Wk": 13.6259,
    "Distance_TVDV_action_Wb": 0.1947, "Distance_TVDV_action_Wk": 0.1076,
    "Distance_TVDV_limit_Wb": 5.5228, "Distance_TVDV_limit_Wk": 3.0514,
    "vel_x_avg": 17.6376, "amplitude_y": 0.3002,
}
"""Thesis Table 8.7 as printed (Horse 2, canter CCW; ``TVDV_T_*`` named ``TVDV_*``).

Reference data for comparisons, never an input of the analysis."""


def indicators_from_values(acc_y_Wb_rms, acc_y_Wk_rms, VDV_y_Wb, VDV_y_Wk, acc_y_max,
                           crest_factor_y, duration_s, vel_x_avg_kmh, amplitude_y_m,
                           *, f0_hz=float("nan"), limits: ExposureValues = EU_2002_44_EC) -> dict:
    """Times and distances (eq. 7.10-7.25) from known rms, VDV and speed.

    The building block of :func:`comfort_indicators`; also what reproduces
    Table 8.7 from its own printed rms, VDV and ``vel_x_avg`` (km/h).
    Returns the dict of :data:`COMFORT_KEYS`.

    Examples
    --------
    Table 8.7's times from its own rms, VDV and speed (tau = 1.2 s):

    >>> T = THESIS_TABLE_8_7
    >>> ind = indicators_from_values(T["acc_y_Wb_rms"], T["acc_y_Wk_rms"], T["VDV_y_Wb"], T["VDV_y_Wk"],
    ...                              T["acc_y_max"], T["crest_factor_y"], 1.2, T["vel_x_avg"], T["amplitude_y"])
    >>> round(ind["TA_8_limit_Wb"], 4), round(ind["TVDV_limit_Wb"], 4)     # Table 8.7: 1.0393, 0.3131
    (1.0393, 0.3131)
    """
    out = {"acc_y_Wb_rms": float(acc_y_Wb_rms), "acc_y_Wk_rms": float(acc_y_Wk_rms),
           "VDV_y_Wb": float(VDV_y_Wb), "VDV_y_Wk": float(VDV_y_Wk),
           "acc_y_max": float(acc_y_max), "crest_factor_y": float(crest_factor_y)}
    times = {}
    for w, r, v in (("Wb", acc_y_Wb_rms, VDV_y_Wb), ("Wk", acc_y_Wk_rms, VDV_y_Wk)):
        for k, t in exposure_times(r, v, duration_s, limits).items():
            times[f"{k}_{w}"] = float(t)
    order = ["TA_8_action", "TA_8_limit", "TVDV_action", "TVDV_limit"]
    for k in order:
        for w in ("Wb", "Wk"):
            out[f"{k}_{w}"] = times[f"{k}_{w}"]
    for k in order:
        for w in ("Wb", "Wk"):
            out[f"Distance_{k}_{w}"] = float(vel_x_avg_kmh) * times[f"{k}_{w}"]
    out["vel_x_avg"] = float(vel_x_avg_kmh)
    out["amplitude_y"] = float(amplitude_y_m)
    out["duration_s"] = float(duration_s)
    out["f0_hz"] = float(f0_hz)
    out["period_s"] = 1.0 / float(f0_hz) if f0_hz and np.isfinite(f0_hz) else float("nan")
    return {k: out[k] for k in COMFORT_KEYS}


def weighted_histories(harmonics, duration_s: float, *, mode: str = "iso",
                       n_samples: int | None = None) -> dict:
    """The vertical acceleration and its Wb/Wk-weighted versions over ``[0, tau)``.

    Parameters
    ----------
    harmonics : Harmonics, (freq_hz, amplitudes) or a Fourier Fit of position
        The saddle's vertical acceleration ``A_y`` (eq. 7.1-7.2).
    duration_s : float
        tau, the analysed time (two gait periods in the thesis).
    mode : {"iso", "thesis"}
        See the module docstring.
    n_samples : int, optional
        Time samples over tau (default: at least 64 per period of the highest
        harmonic and 4096).

    Returns
    -------
    dict with ``t``, ``A_y``, ``A_wb``, ``A_wk`` (arrays), ``W_b``, ``W_k``
    (complex weights per harmonic, or the scalar of thesis mode broadcast)
    and ``f_dominant_hz``.

    Examples
    --------
    >>> hist = weighted_histories(Harmonics([2.0], [3.0]), duration_s=1.0)
    >>> sorted(hist)
    ['A_wb', 'A_wk', 'A_y', 'W_b', 'W_k', 'f_dominant_hz', 't']
    >>> hist["f_dominant_hz"], hist["t"].size
    (2.0, 4096)
    """
    h = _as_harmonics(harmonics)
    if not duration_s > 0:
        raise ValueError(f"duration_s must be > 0, got {duration_s}")
    if mode not in ("iso", "thesis"):
        raise ValueError(f"mode must be 'iso' or 'thesis', got {mode!r}")
    if n_samples is None:
        n_samples = max(4096, int(math.ceil(64 * duration_s * h.freq_hz.max())))
    t = np.arange(n_samples) * (duration_s / n_samples)
    a_y = synthesize(h, t)
    f_dom = dominant_frequency(h)
    out = {"t": t, "A_y": a_y, "f_dominant_hz": f_dom}
    for w in ("Wb", "Wk"):
        if mode == "iso":
            ww = weighting(w, h.freq_hz)
            hw = Harmonics(h.freq_hz, h.amplitude * ww, 0.0)
            out[f"A_w{w[1]}"] = synthesize(hw, t)
        else:
            ww = np.full(h.freq_hz.shape, abs(weighting(w, f_dom)), dtype=complex)
            out[f"A_w{w[1]}"] = ww[0].real * (a_y - h.offset)
        out[f"W_{w[1]}"] = ww
    return out


def comfort_indicators(acc_y, duration_s: float | None = None, vel_x_avg_mps: float = float("nan"),
                       amplitude_y_m: float = float("nan"), *, mode: str = "iso",
                       peak: float | None = None, f0_hz: float | None = None,
                       limits: ExposureValues = EU_2002_44_EC,
                       n_samples: int | None = None) -> dict:
    """Comfort indicators of thesis Table 8.7 from the fitted vertical acceleration.

    Parameters
    ----------
    acc_y : Harmonics, (freq_hz, complex amplitudes), or a Fourier Fit
        The saddle marker's vertical acceleration ``A_y`` (eq. 7.1-7.2; y
        down along gravity -- the sign does not matter). A
        ``horsemocap.fitting`` Fit (``.coefficients`` in MATLAB order) is
        taken as the fit of the vertical POSITION and differentiated twice
        (:func:`harmonics_from_fourier`).
    duration_s : float, optional
        tau, the analysed time; default two periods of the fundamental (the
        thesis' choice: 1.2 s at canter, two periods of 18 frames at 30 fps).
    vel_x_avg_mps : float
        Mean speed along the motion direction, m/s (reported in km/h).
    amplitude_y_m : float
        Half the peak-to-peak of the fitted vertical position over tau (the
        thesis does not define ``amplitude_y``; this is the spec's choice).
    mode : {"iso", "thesis"}
        ``"iso"``: each harmonic weighted by ``W(f_k)`` (the standards);
        ``"thesis"``: one scalar ``|W(f_dominant)|`` (Table 8.7). In
        ``"iso"`` ``crest_factor_y`` is that of the Wb-weighted signal; in
        ``"thesis"`` it is the same for Wb, Wk and the unweighted signal.
    peak : float, optional
        ``acc_y_max`` (unweighted peak |A_y|, m/s^2) if known from elsewhere
        (e.g. measured samples); default the peak of the fitted signal over
        tau. In thesis mode it also sets the crest factor (peak / rms of A_y).
    f0_hz : float, optional
        Fundamental frequency (default the lowest harmonic's).
    limits : ExposureValues
        Table 7.2 (EU Directive 2002/44/EC).

    Returns
    -------
    dict
        Exactly :data:`COMFORT_KEYS` (m/s^2, m/s^1.75, h, km, km/h, m, s, Hz).

    Examples
    --------
    A pure 2 Hz vertical acceleration of amplitude 3 m/s^2 at 5 m/s: tau is two
    periods (1 s), the Wk rms is ``3 |Wk(2 Hz)| / sqrt(2)`` and the crest factor
    of a sine ``sqrt(2)``.

    >>> import numpy as np
    >>> ind = comfort_indicators(Harmonics([2.0], [3.0]), vel_x_avg_mps=5.0)
    >>> ind["duration_s"], ind["period_s"], ind["vel_x_avg"]
    (1.0, 0.5, 18.0)
    >>> round(ind["acc_y_Wk_rms"], 4), round(float(3 * abs(weighting("Wk", 2.0)) / np.sqrt(2)), 4)
    (1.1273, 1.1273)
    >>> round(ind["crest_factor_y"], 4)
    1.4142
    """
    h = _as_harmonics(acc_y)
    f0 = float(h.freq_hz.min()) if f0_hz is None else float(f0_hz)
    tau = 2.0 / f0 if duration_s is None else float(duration_s)
    hist = weighted_histories(h, tau, mode=mode, n_samples=n_samples)
    n = hist["t"].size
    fs = n / tau
    a_y = hist["A_y"] - h.offset
    acc_max = float(np.max(np.abs(a_y))) if peak is None else float(peak)
    r = {w: float(rms(hist[f"A_w{w}"])) for w in ("b", "k")}
    v = {w: float(vdv(hist[f"A_w{w}"], fs)) for w in ("b", "k")}
    if mode == "iso":
        cf = float(np.max(np.abs(hist["A_wb"]))) / r["b"]
    else:
        cf = acc_max / float(rms(a_y))
    return indicators_from_values(r["b"], r["k"], v["b"], v["k"], acc_max, cf, tau,
                                  vel_x_avg_mps * 3.6, amplitude_y_m, f0_hz=f0, limits=limits)


def directive_indicators(acc_x, acc_y, acc_z, duration_s: float, vel_x_avg_mps: float = float("nan"), *,
                         limits: ExposureValues = EU_2002_44_EC, n_samples: int | None = None) -> dict:
    """The EU Directive 2002/44/EC's daily exposure of the saddle, from all three axes.

    The thesis (and Table 8.7) judges the vertical axis alone, weighted with Wb or Wk. The Directive
    (Annex B, whole-body vibration, after ISO 2631-1 for health) takes the *highest* of
    ``1.4 a_wx``, ``1.4 a_wy`` (horizontal, Wd) and ``a_wz`` (vertical, Wk), and the same for the VDV.
    In the motion frame the horizontal axes are x (fore-aft) and z (lateral), the vertical is y. A
    canter's fore-aft surge can decide it (:func:`directive_axis` names the deciding axis).

    Every harmonic is weighted at its own frequency (the ``"iso"`` mode of :func:`comfort_indicators`,
    whatever mode the thesis' indicators use: this is the standard's computation, which the thesis
    does not make).

    Parameters
    ----------
    acc_x, acc_y, acc_z : Harmonics or (freq_hz, complex amplitudes)
        The saddle's acceleration along x (fore-aft), y (vertical) and z (lateral) in the motion frame,
        as harmonic series (a constant term is ignored: it is not vibration).
    duration_s : float
        tau, the analysed time (the VDV is measured over it and scaled by eq. 7.14-7.17, corrected).
    vel_x_avg_mps : float
        Mean speed, m/s (the distances).
    limits : ExposureValues
        Table 7.2 (EU Directive 2002/44/EC).
    n_samples : int, optional
        Time samples over tau (as :func:`weighted_histories`).

    Returns
    -------
    dict
        Exactly :data:`DIRECTIVE_KEYS`: the weighted rms and VDV of x and z (Wd) and y (Wk), unscaled, ``A_w_directive`` and
        ``VDV_directive`` (the highest of the scaled axes, m/s^2 and m/s^1.75), the times (h) to the action and
        limit values by A(8) and by VDV, and the distances (km) at the mean speed.

    Examples
    --------
    The same 2 Hz, 3 m/s^2 oscillation fore-aft and vertically: the fore-aft one
    decides (1.4 times its Wd-weighted rms beats the vertical's Wk-weighted one).

    >>> same = Harmonics([2.0], [3.0])
    >>> ind = directive_indicators(same, same, Harmonics([2.0], [0.1]), duration_s=1.0)
    >>> round(ind["acc_x_Wd_rms"], 4), round(ind["acc_y_Wk_rms_iso"], 4)
    (1.8885, 1.1273)
    >>> round(ind["A_w_directive"], 4)                # 1.4 * 1.8885
    2.6439
    """
    tau = float(duration_s)
    axes = {"x": (_as_harmonics(acc_x), "Wd"), "y": (_as_harmonics(acc_y), "Wk"), "z": (_as_harmonics(acc_z), "Wd")}
    if n_samples is None:
        n_samples = max(4096, int(math.ceil(64 * tau * max(h.freq_hz.max() for h, _ in axes.values()))))
    t = np.arange(n_samples) * (tau / n_samples)
    fs = n_samples / tau
    a_w, v_w = {}, {}
    for axis, (h, w) in axes.items():
        hist = synthesize(Harmonics(h.freq_hz, h.amplitude * weighting(w, h.freq_hz), 0.0), t)
        a_w[axis], v_w[axis] = float(rms(hist)), float(vdv(hist, fs))
    a_dir = max(_directive_axes(a_w["x"], a_w["y"], a_w["z"]).values())
    v_dir = max(_directive_axes(v_w["x"], v_w["y"], v_w["z"]).values())
    times = exposure_times(a_dir, v_dir, tau, limits)
    speed_kmh = float(vel_x_avg_mps) * 3.6
    out = {"acc_x_Wd_rms": a_w["x"], "acc_y_Wk_rms_iso": a_w["y"], "acc_z_Wd_rms": a_w["z"],
           "VDV_x_Wd": v_w["x"], "VDV_y_Wk_iso": v_w["y"], "VDV_z_Wd": v_w["z"],
           "A_w_directive": a_dir, "VDV_directive": v_dir}
    for name, hours in times.items():
        out[f"{name}_directive"] = float(hours)
        out[f"Distance_{name}_directive"] = speed_kmh * float(hours)
    return {key: out[key] for key in DIRECTIVE_KEYS}


def directive_axis(indicators: dict, by: str = "rms") -> str:
    """Which axis decides the Directive's exposure: ``"fore-aft"`` (x), ``"vertical"`` (y) or ``"lateral"`` (z).

    ``by="rms"``: the axis of ``A_w_directive`` (the highest of ``1.4 acc_x_Wd_rms``, ``acc_y_Wk_rms_iso``,
    ``1.4 acc_z_Wd_rms``); ``by="vdv"``: the axis of ``VDV_directive``. ``indicators`` holds the keys of
    :data:`DIRECTIVE_KEYS` (:func:`saddle_comfort`, :func:`directive_indicators`). Ties go to the first of
    fore-aft, vertical, lateral.

    Examples
    --------
    >>> directive_axis({"acc_x_Wd_rms": 2.0, "acc_y_Wk_rms_iso": 2.5, "acc_z_Wd_rms": 0.5})
    'fore-aft'
    >>> directive_axis({"acc_x_Wd_rms": 1.0, "acc_y_Wk_rms_iso": 2.5, "acc_z_Wd_rms": 0.5})
    'vertical'
    """
    keys = {"rms": ("acc_x_Wd_rms", "acc_y_Wk_rms_iso", "acc_z_Wd_rms"),
            "vdv": ("VDV_x_Wd", "VDV_y_Wk_iso", "VDV_z_Wd")}.get(by)
    if keys is None:
        raise ValueError(f"directive_axis: by must be 'rms' or 'vdv', got {by!r}")
    scaled = _directive_axes(*(indicators[key] for key in keys))
    return max(scaled, key=scaled.get)


def fit_harmonics(t, y, f0_hz: float, n_harmonics: int) -> Harmonics:
    """Linear least-squares fit ``y ~ offset + sum_k a_k cos + b_k sin(2 pi k f0 t)``.

    Non-finite samples are left out of the fit (their count is the caller's
    to report). Returns the :class:`Harmonics` of the fit.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(300) / 100.0
    >>> y = 0.5 + 0.2 * np.cos(2 * np.pi * 1.5 * t) + 0.1 * np.sin(2 * np.pi * 3.0 * t)
    >>> h = fit_harmonics(t, y, f0_hz=1.5, n_harmonics=2)
    >>> round(h.offset, 6), np.abs(h.amplitude).round(6)
    (0.5, array([0.2, 0.1]))
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(t) & np.isfinite(y)
    if ok.sum() < 2 * n_harmonics + 1:
        raise ValueError(f"fit_harmonics: {ok.sum()} finite samples cannot fit {n_harmonics} "
                         "harmonics (need 2N + 1)")
    k = np.arange(1, n_harmonics + 1)
    arg = 2 * math.pi * f0_hz * np.multiply.outer(t[ok], k)
    A = np.hstack([np.ones((ok.sum(), 1)), np.cos(arg), np.sin(arg)])
    coef, *_ = np.linalg.lstsq(A, y[ok], rcond=None)
    a, b = coef[1:n_harmonics + 1], coef[n_harmonics + 1:]
    return Harmonics(k * f0_hz, a - 1j * b, float(coef[0]))


def _harmonic_residual(t, y, f0, f_max):
    n = max(1, int(f_max // f0))
    h = fit_harmonics(t, y, f0, n)
    return float(np.nanmean((y - synthesize(h, t)) ** 2))


def estimate_fundamental(t, y, *, f_min_hz: float = 0.5, f_max_hz: float = 15.0) -> float:
    """Fundamental frequency (Hz) of a periodic record, e.g. the gait's stride.

    The periodogram's highest peak above ``f_min_hz`` is a first guess; its
    sub-harmonics ``f/2`` and ``f/3`` are taken instead when their harmonic
    series explains clearly more of the signal (a trot's vertical motion
    repeats twice per stride, but the stride's own terms are there too); the
    choice is refined by minimising the residual of :func:`fit_harmonics`
    (harmonics up to ``f_max_hz``), as MATLAB's ``fourierN`` fits ``w``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(300) / 100.0
    >>> y = 0.2 * np.cos(2 * np.pi * 1.5 * t) + 0.1 * np.sin(2 * np.pi * 3.0 * t)
    >>> round(estimate_fundamental(t, y), 4)
    1.5
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(t) & np.isfinite(y)
    t, y = t[ok], y[ok]
    if t.size < 8:
        raise ValueError(f"estimate_fundamental: need >= 8 finite samples, got {t.size}")
    dt = float(np.median(np.diff(t)))
    n = 16 * t.size
    yy = (y - y.mean()) * np.hanning(t.size)
    spec = np.abs(np.fft.rfft(yy, n))
    f = np.fft.rfftfreq(n, dt)
    band = f >= f_min_hz
    f_peak = float(f[band][np.argmax(spec[band])])
    var = float(np.var(y))
    best = f_peak
    best_res = _harmonic_residual(t, y, f_peak, f_max_hz)
    record = t[-1] - t[0]
    for d in (2, 3):
        fs_ = f_peak / d
        if fs_ < f_min_hz or fs_ * record < 1.0:
            continue
        r = _harmonic_residual(t, y, fs_, f_max_hz)
        if r < best_res - 0.01 * var:
            best, best_res = fs_, r
    res = optimize.minimize_scalar(lambda q: _harmonic_residual(t, y, q, f_max_hz),
                                   bounds=(best * 0.95, best * 1.05), method="bounded",
                                   options={"xatol": 1e-6})
    return float(res.x) if res.fun <= best_res else best


def saddle_comfort(t, position, acceleration, velocity, *, mode: str = "iso",
                   f0_hz: float | None = None, n_periods: int = 2, f_max_hz: float = 15.0,
                   peak: float | None = None, limits: ExposureValues = EU_2002_44_EC) -> dict:
    """Comfort indicators of the saddle marker (thesis 7.2, Table 8.7).

    What the pipeline calls with the saddle's fitted kinematics in the motion
    frame (x along the path, y down along gravity). The vertical acceleration
    ``A_y`` is represented as a harmonic series of the stride frequency
    ``f0`` (estimated, or given), so the weighting is exact at every
    harmonic whatever the camera's frame rate; tau = ``n_periods`` periods
    (two in the thesis).

    Parameters
    ----------
    t : (n,) seconds
    position, acceleration, velocity : (n, 3)
        Saddle marker ``P^S``, ``A^S``, ``V^S`` in the motion frame (m, m/s^2, m/s).
    mode : {"iso", "thesis"}
        See :func:`comfort_indicators`.
    f0_hz : float, optional
        Fundamental (stride) frequency; default :func:`estimate_fundamental`
        of the vertical position.
    n_periods : int
        tau in periods.
    f_max_hz : float
        Highest harmonic kept (below the Nyquist frequency of ``t``).

    Returns
    -------
    dict of :data:`COMFORT_KEYS` then :data:`DIRECTIVE_KEYS` (the Directive's three axes,
    :func:`directive_indicators`, from the harmonics of x and z fitted as y's). ``vel_x_avg`` is the mean
    x-velocity (the constant of its harmonic fit, i.e. the mean over whole periods); ``amplitude_y`` half
    the peak-to-peak of the fitted vertical position over tau.

    Examples
    --------
    A saddle bouncing 2 cm at 2 Hz while moving at 5 m/s, filmed at 30 fps for 4 s:

    >>> import numpy as np
    >>> t = np.arange(120) / 30.0
    >>> w = 2 * np.pi * 2.0
    >>> position, acceleration, velocity = np.zeros((3, 120, 3))
    >>> position[:, 1] = 0.02 * np.cos(w * t)
    >>> acceleration[:, 1] = -0.02 * w ** 2 * np.cos(w * t)
    >>> velocity[:, 0] = 5.0
    >>> ind = saddle_comfort(t, position, acceleration, velocity)
    >>> round(ind["f0_hz"], 4), round(ind["amplitude_y"], 4), round(ind["vel_x_avg"], 4)
    (2.0, 0.02, 18.0)
    >>> round(ind["acc_y_Wk_rms"], 4), round(float(0.02 * w ** 2 * abs(weighting("Wk", 2.0)) / np.sqrt(2)), 4)
    (1.1868, 1.1868)
    """
    t = np.asarray(t, dtype=float)
    pos = np.asarray(position, dtype=float)
    acc = np.asarray(acceleration, dtype=float)
    vel = np.asarray(velocity, dtype=float)
    for name, arr in (("position", pos), ("acceleration", acc), ("velocity", vel)):
        if arr.shape != (t.size, 3):
            raise ValueError(f"saddle_comfort: {name} must have shape ({t.size}, 3), got {arr.shape}")
    fs = 1.0 / float(np.median(np.diff(t)))
    f_top = min(f_max_hz, 0.45 * fs)
    if f0_hz is None:
        f0_hz = estimate_fundamental(t, pos[:, 1], f_max_hz=f_top)
    n_h = max(1, int(f_top // f0_hz))
    h_acc = fit_harmonics(t, acc[:, 1], f0_hz, n_h)
    h_acc = Harmonics(h_acc.freq_hz, h_acc.amplitude, 0.0)   # a mean acceleration is not vibration
    h_pos = fit_harmonics(t, pos[:, 1], f0_hz, n_h)
    tau = n_periods / f0_hz
    tt = np.linspace(0.0, tau, 2048, endpoint=False)
    y = synthesize(h_pos, tt)
    amp = 0.5 * float(y.max() - y.min())
    v_x = fit_harmonics(t, vel[:, 0], f0_hz, n_h).offset   # mean over whole periods
    out = comfort_indicators(h_acc, tau, v_x, amp, mode=mode, peak=peak, f0_hz=f0_hz, limits=limits)
    h_x, h_z = (fit_harmonics(t, acc[:, i], f0_hz, n_h) for i in (0, 2))
    out.update(directive_indicators(h_x, h_acc, h_z, tau, v_x, limits=limits))
    return out


# ---------------------------------------------------------------------------
# The comfort table: rows, comfort.csv, spreadsheet
# ---------------------------------------------------------------------------


def comfort_table_rows(indicators: dict) -> list[tuple[str, float, str]]:
    """``[(indicator, value, unit), ...]`` in :data:`COMFORT_KEYS` order, then the
    :data:`DIRECTIVE_KEYS` when the indicators have them (all or none).

    Raises ``KeyError`` naming the first missing indicator.

    Examples
    --------
    >>> rows = comfort_table_rows(comfort_indicators(Harmonics([2.0], [3.0])))
    >>> rows[0][0], rows[0][2], len(rows)
    ('acc_y_Wb_rms', 'm/s^2', 27)
    """
    missing = [k for k in COMFORT_KEYS if k not in indicators]
    if missing:
        raise KeyError(f"comfort indicators lack {missing[0]!r} (and {len(missing) - 1} more)")
    optional = [k for k in DIRECTIVE_KEYS if k in indicators]
    if optional and len(optional) != len(DIRECTIVE_KEYS):
        lack = [k for k in DIRECTIVE_KEYS if k not in indicators]
        raise KeyError(f"comfort indicators have some of the Directive's rows but lack {lack[0]!r}")
    return [(k, float(indicators[k]), COMFORT_UNITS[k]) for k in COMFORT_KEYS + tuple(optional)]


def write_comfort_csv(path, indicators: dict) -> Path:
    """Write ``comfort.csv`` (columns ``indicator,value,unit``; docs/sessions.md).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = write_comfort_csv(folder / "comfort.csv", comfort_indicators(Harmonics([2.0], [3.0])))
    >>> path.read_text().splitlines()[0]
    'indicator,value,unit'
    >>> round(read_comfort_csv(path)["acc_y_Wk_rms"], 4)
    1.1273
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["indicator", "value", "unit"])
    for k, v, u in comfort_table_rows(indicators):
        w.writerow([k, repr(v), u])
    return atomic_write_text(path, buf.getvalue())


def read_comfort_csv(path) -> dict:
    """Read a ``comfort.csv``; errors name the file, line and what was expected.

    Examples
    --------
    See :func:`write_comfort_csv`.
    """
    path = Path(path)
    with path.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows or rows[0] != ["indicator", "value", "unit"]:
        raise ValueError(f"{path}: header must be 'indicator,value,unit', got {rows[:1]}")
    out = {}
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != 3:
            raise ValueError(f"{path}, line {i}: expected 3 fields, got {len(row)}")
        try:
            out[row[0]] = float(row[1])
        except ValueError:
            raise ValueError(f"{path}, line {i}: value of {row[0]!r} is not a number: "
                             f"{row[1]!r}") from None
    missing = [k for k in COMFORT_KEYS if k not in out]
    if missing:
        raise ValueError(f"{path}: missing indicator {missing[0]!r}")
    return out


def _xlsx_sheet(rows) -> str:
    def cell(ref, v):
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if not math.isfinite(v):
                return f'<c r="{ref}" t="inlineStr"><is><t>{html.escape(str(v), quote=False)}</t></is></c>'
            return f'<c r="{ref}"><v>{repr(float(v))}</v></c>'
        return f'<c r="{ref}" t="inlineStr"><is><t>{html.escape(str(v), quote=False)}</t></is></c>'
    lines = []
    for r, row in enumerate(rows, start=1):
        cells = "".join(cell(f"{'ABCDEFGHIJ'[c]}{r}", v) for c, v in enumerate(row))
        lines.append(f'<row r="{r}">{cells}</row>')
    return ('<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            '<worksheet xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main">'
            '<cols><col min="1" max="1" width="28" customWidth="1"/>'
            '<col min="2" max="2" width="14" customWidth="1"/>'
            '<col min="3" max="3" width="10" customWidth="1"/></cols>'
            f'<sheetData>{"".join(lines)}</sheetData></worksheet>')


def write_comfort_spreadsheet(path, indicators: dict, *, title: str = "comfort") -> Path:
    """Write the comfort table as an Excel workbook (``.xlsx``).

    The thesis saved its indicators "in a format which is compatible with
    EXCEL" (section 8.4.1). A minimal Office Open XML workbook is written
    with the standard library (zipfile + XML): numbers are stored as numbers
    (a CSV is re-parsed by Excel with the locale's decimal separator, so in
    Turkish or German settings ``3.19`` would be misread), and no dependency
    is added. One sheet, columns indicator / value / unit.

    Examples
    --------
    >>> import tempfile, pathlib, zipfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> path = write_comfort_spreadsheet(folder / "comfort.xlsx", comfort_indicators(Harmonics([2.0], [3.0])))
    >>> "xl/worksheets/sheet1.xml" in zipfile.ZipFile(path).namelist()
    True
    """
    rows = [("indicator", "value", "unit")] + comfort_table_rows(indicators)
    sheet = title[:31] or "comfort"
    files = {
        "[Content_Types].xml":
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
            '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
            '<Default Extension="xml" ContentType="application/xml"/>'
            '<Override PartName="/xl/workbook.xml" ContentType="application/vnd.openxmlformats-officedocument.spreadsheetml.sheet.main+xml"/>'
            '<Override PartName="/xl/worksheets/sheet1.xml" ContentType="application/vnd.openxmlformats-officedocument.spreadsheetml.worksheet+xml"/>'
            '</Types>',
        "_rels/.rels":
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
            '<Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/officeDocument" Target="xl/workbook.xml"/>'
            '</Relationships>',
        "xl/workbook.xml":
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            '<workbook xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main" '
            'xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships">'
            f'<sheets><sheet name="{html.escape(sheet)}" sheetId="1" r:id="rId1"/></sheets></workbook>',
        "xl/_rels/workbook.xml.rels":
            '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>\n'
            '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
            '<Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/worksheet" Target="worksheets/sheet1.xml"/>'
            '</Relationships>',
        "xl/worksheets/sheet1.xml": _xlsx_sheet(rows),
    }
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, text in files.items():
            info = zipfile.ZipInfo(name, date_time=(2009, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, text.encode("utf-8"))
    return atomic_write_bytes(path, buf.getvalue())


def marker_comfort(t, positions, accelerations, velocities, *, mode: str = "iso",
                   f0_hz: float | None = None, **kwargs) -> list[dict]:
    """Comfort indicators of every visible marker (Appendix A step 10, ``performance_measure.m``).

    The thesis computes the performance measures of the visible markers
    before it turns to the hidden saddle marker; this is
    :func:`saddle_comfort` applied to each marker's kinematics in turn.

    Parameters
    ----------
    t : (n,) seconds
    positions, accelerations, velocities : (n, M, 3)
        The markers' fitted kinematics in the motion frame (m, m/s^2, m/s).
    mode, f0_hz, **kwargs
        As :func:`saddle_comfort`; give the stride frequency ``f0_hz`` so
        every marker is weighted on the same harmonics.

    Returns
    -------
    list of M dicts of :data:`COMFORT_KEYS`; a marker whose frames are all
    missing gets ``None``, never a silent zero.

    Examples
    --------
    One marker bouncing 2 cm at 2 Hz (as in :func:`saddle_comfort`):

    >>> import numpy as np
    >>> t = np.arange(120) / 30.0
    >>> w = 2 * np.pi * 2.0
    >>> positions, accelerations, velocities = np.zeros((3, 120, 1, 3))
    >>> positions[:, 0, 1] = 0.02 * np.cos(w * t)
    >>> accelerations[:, 0, 1] = -0.02 * w ** 2 * np.cos(w * t)
    >>> velocities[:, 0, 0] = 5.0
    >>> [round(m["acc_y_Wk_rms"], 4) for m in marker_comfort(t, positions, accelerations, velocities, f0_hz=2.0)]
    [1.1868]
    """
    pos = np.asarray(positions, float)
    acc = np.asarray(accelerations, float)
    vel = np.asarray(velocities, float)
    t = np.asarray(t, float)
    if pos.ndim != 3 or pos.shape[2] != 3 or acc.shape != pos.shape or vel.shape != pos.shape \
            or pos.shape[0] != t.size:
        raise ValueError(f"marker_comfort: positions, accelerations and velocities must have shape "
                         f"({t.size}, M, 3), got {pos.shape}, {acc.shape}, {vel.shape}")
    out = []
    for m in range(pos.shape[1]):
        ok = np.all(np.isfinite(pos[:, m]), 1) & np.all(np.isfinite(acc[:, m]), 1) & np.all(np.isfinite(vel[:, m]), 1)
        if ok.sum() < 4:
            out.append(None)
            continue
        out.append(saddle_comfort(t[ok], pos[ok, m], acc[ok, m], vel[ok, m], mode=mode, f0_hz=f0_hz, **kwargs))
    return out


def half_peak_to_peak(positions) -> np.ndarray:
    """Half the peak-to-peak of each marker's y and z position, ``(M, 2)`` in metres.

    The per-marker amplitudes the thesis saves with its fits (Appendix A
    step 9, ``Z_amplitudes_marker*``): ``(max - min) / 2`` over the finite
    frames given (``amplitude_y`` of :func:`saddle_comfort` is the same over
    the fitted harmonic position of tau); NaN for a marker with no finite
    frame.

    Parameters
    ----------
    positions : (n, M, 3)
        Positions in the motion frame (x, y, z).

    Examples
    --------
    >>> import numpy as np
    >>> y = np.array([1.0, 3.0, 2.0])
    >>> positions = np.stack([np.zeros(3), y, np.zeros(3)], axis=-1)[:, None, :]   # (3 frames, 1 marker, 3)
    >>> half_peak_to_peak(positions)
    array([[1., 0.]])
    """
    p = np.asarray(positions, float)
    if p.ndim != 3 or p.shape[2] != 3:
        raise ValueError(f"half_peak_to_peak: positions must have shape (n, M, 3), got {p.shape}")
    out = np.full((p.shape[1], 2), np.nan)
    for m in range(p.shape[1]):
        for j, axis in enumerate((1, 2)):
            v = p[:, m, axis]
            v = v[np.isfinite(v)]
            if v.size:
                out[m, j] = 0.5 * (v.max() - v.min())
    return out


def unit_text(unit: str) -> str:
    """A unit for plain text and figure labels: ``m/s^2`` -> ``m/s²``, ``m/s^1.75`` -> ``m/s^1.75``
    (no superscript decimal point in Unicode) and ``"1"`` -> ``""``.

    Examples
    --------
    >>> unit_text("m/s^2"), unit_text("m/s^1.75"), unit_text("1")
    ('m/s²', 'm/s^1.75', '')
    """
    if unit == "1":
        return ""
    sup = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")

    return re.sub(r"\^(-?[0-9]+)(?![0-9.])", lambda m: m.group(1).translate(sup), unit)
