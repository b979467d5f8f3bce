"""Digital (IIR) frequency-weighting filters for sampled acceleration, on :mod:`scipy.signal`.

A vibration meter weights an accelerometer's signal with a causal digital
filter: each analogue second-order section of the weighting
(:func:`horsemocap.vibration.analog_sections`) mapped by the bilinear
transform. This module designs that filter (:func:`weighting_filter`),
measures how far it departs from the analogue weighting
(:func:`digital_weighting_error`), applies it or the DFT weighting
(:func:`apply_weighting`) and computes the comfort indicators of a sampled
record (:func:`comfort_from_samples`).

The analysis itself weights the fitted harmonics of the saddle's motion at
their own frequencies (:mod:`horsemocap.vibration`) and does not import this
module.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import signal as sp_signal

from .vibration import (
    EU_2002_44_EC,
    THIRD_OCTAVE_HZ,
    ExposureValues,
    analog_sections,
    crest_factor,
    fft_weighting,
    indicators_from_values,
    rms,
    vdv,
    weighting,
)

__all__ = ["DigitalWeightingWarning", "weighting_filter", "digital_weighting_error", "apply_weighting",
           "comfort_from_samples"]


class DigitalWeightingWarning(UserWarning):
    """The sampling rate makes the digital weighting filter inaccurate.

    Examples
    --------
    See :func:`weighting_filter`.
    """


def _design_sos(name, fs, band_limiting=True):
    dropped = []
    sos = []
    for b, a, w0 in analog_sections(name, band_limiting=band_limiting):
        f0 = w0 / (2 * math.pi)
        if f0 >= 0.45 * fs:
            # a section near or above Nyquist (the 100 Hz low-pass at low fs)
            # cannot be mapped; in-band it is ~1, keep its DC gain.
            dropped.append(f0)
            sos_gain = np.polyval(b, 0.0) / np.polyval(a, 0.0)
            sos.append(np.array([sos_gain, 0, 0, 1.0, 0, 0]))
            continue
        n = max(len(b), len(a))
        bb = np.concatenate([np.zeros(n - len(b)), b])
        aa = np.concatenate([np.zeros(n - len(a)), a])
        fs_eff = w0 / (2.0 * math.tan(w0 / (2.0 * fs)))
        bz, az = sp_signal.bilinear(bb, aa, fs=fs_eff)
        bz = np.concatenate([bz, np.zeros(3 - len(bz))])
        az = np.concatenate([az, np.zeros(3 - len(az))])
        sos.append(np.concatenate([bz / az[0], az / az[0]]))
    return np.vstack(sos), dropped


def digital_weighting_error(name, fs: float, freq_hz) -> np.ndarray:
    """Relative error ``|H(f)|/|W(f)| - 1`` of :func:`weighting_filter` at ``freq_hz``.

    Examples
    --------
    At 200 Hz the digital Wb follows the analogue one closely up to 20 Hz:

    >>> import numpy as np
    >>> bool(np.all(np.abs(digital_weighting_error("Wb", 200.0, [1.0, 5.0, 20.0])) < 0.01))
    True
    """
    sos, _ = _design_sos(name, fs)
    f = np.asarray(freq_hz, dtype=float)
    _, h = sp_signal.sosfreqz(sos, worN=f, fs=fs)
    return np.abs(h) / np.abs(weighting(name, f)) - 1.0


def weighting_filter(name, fs: float, *, tol: float = 0.05, f_max_hz: float = 20.0,
                     warn: bool = True) -> np.ndarray:
    """Digital (IIR) weighting filter for a signal sampled at ``fs`` Hz.

    Each analogue section is mapped by the bilinear transform pre-warped at
    its own characteristic frequency; a section at or above 0.45 fs (the
    100 Hz band-limiting low-pass when fs < 222 Hz) is replaced by its DC
    gain (the recorder's anti-alias filter band-limits instead).

    Parameters
    ----------
    name : {"Wb", "Wk", "Wd"}
    fs : float
        Sampling rate in Hz.
    tol : float
        Largest accepted relative error of ``|H|`` against ``|W|`` (0.05: 5 %).
    f_max_hz : float
        Top of the band checked: 0.5 Hz to ``min(f_max_hz, 0.49 fs)`` (the
        one-third-octave centres and 200 frequencies between; the band's top
        is where a bilinear design errs most). Default 20 Hz: people are most sensitive
        to whole-body vibration from 1 to 20 Hz (thesis 7.1) and a horse's
        saddle motion lies below it. The error at any rate and frequency is
        :func:`digital_weighting_error`'s: small at 200 Hz, large near a
        video's Nyquist frequency (see the examples).
    warn : bool
        Issue :class:`DigitalWeightingWarning` when the error exceeds ``tol``
        somewhere in the band.

    Returns
    -------
    sos : ndarray (n_sections, 6)
        For :func:`scipy.signal.sosfilt`.

    Examples
    --------
    >>> import warnings
    >>> from scipy.signal import sosfilt
    >>> sos = weighting_filter("Wk", 200.0)
    >>> sos.shape                                 # four second-order sections
    (4, 6)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = weighting_filter("Wk", 30.0)      # a video's rate: too slow for a digital Wk
    >>> caught[0].category.__name__
    'DigitalWeightingWarning'
    """
    if not fs > 0:
        raise ValueError(f"weighting_filter: fs must be > 0, got {fs}")
    sos, dropped = _design_sos(name, fs)
    if warn:
        # every frequency of the band, not only the third-octave centres: the bilinear transform puts a
        # zero at fs/2 for sections of lower numerator degree, so at a video's rate the error grows fast
        # between the last centre below 0.45 fs and 0.49 fs, where no centre checks it
        top = min(float(f_max_hz), 0.49 * fs)
        f = np.unique(np.concatenate([THIRD_OCTAVE_HZ[(THIRD_OCTAVE_HZ >= 0.5) & (THIRD_OCTAVE_HZ <= top)],
                                      np.geomspace(0.5, top, 200) if top > 0.5 else []]))
        if f.size:
            err = digital_weighting_error(name, fs, f)
            i = int(np.argmax(np.abs(err)))
            if abs(err[i]) > tol:
                warnings.warn(
                    f"digital {name} filter at fs = {fs:g} Hz deviates from the analogue "
                    f"weighting by {100 * err[i]:+.1f}% at {f[i]:g} Hz (tolerance "
                    f"{100 * tol:.0f}%, band 0.5-{top:g} Hz"
                    + (f"; sections at {', '.join(f'{x:g}' for x in dropped)} Hz lie above "
                       f"0.45 fs and were replaced by their DC gain" if dropped else "")
                    + "); sample faster, or weight the "
                    f"spectrum (apply_weighting(..., method='fft') or comfort_indicators on "
                    f"the Fourier fit)", DigitalWeightingWarning, stacklevel=2)
    return sos


def apply_weighting(signal, fs: float, name, *, method: str = "iir", axis: int = 0) -> np.ndarray:
    """Frequency-weight a sampled acceleration signal (thesis eq. 7.1-7.2).

    Parameters
    ----------
    signal : array_like
        Acceleration samples, time on ``axis``.
    fs : float
        Sampling rate in Hz.
    name : {"Wb", "Wk", "Wd"}
    method : {"iir", "fft"}
        ``"iir"``: the digital filter of :func:`weighting_filter` (causal, as
        a vibration meter; warns when fs is too low). ``"fft"``: multiply the
        DFT by the analogue ``W(f)`` at each bin (exact for a periodic record,
        e.g. whole gait cycles; no warping at any fs).

    Examples
    --------
    A 4 Hz sine of amplitude 1 m/s^2 through the digital Wk filter at 200 Hz: once the filter's start-up
    has passed (the last 5 of 10 s), its weighted rms is ``|Wk(4 Hz)| / sqrt(2)``, as the DFT weighting
    (:func:`horsemocap.vibration.fft_weighting`) gives over whole periods.

    >>> import numpy as np
    >>> fs = 200.0
    >>> t = np.arange(2000) / fs
    >>> weighted = apply_weighting(np.sin(2 * np.pi * 4 * t), fs, "Wk")
    >>> round(float(rms(weighted[1000:])), 3), round(float(abs(weighting("Wk", 4.0)) / np.sqrt(2)), 3)
    (0.684, 0.684)
    """
    x = np.asarray(signal, dtype=float)
    if method == "iir":
        sos = weighting_filter(name, fs)
        return sp_signal.sosfilt(sos, x, axis=axis)
    if method == "fft":
        return fft_weighting(x, fs, name, axis=axis)
    raise ValueError(f"apply_weighting: method must be 'iir' or 'fft', got {method!r}")


def comfort_from_samples(acc_y, fs: float, vel_x_avg_mps: float = float("nan"),
                         amplitude_y_m: float = float("nan"), *, method: str = "fft",
                         mode: str = "iso", f_dominant_hz: float | None = None,
                         f0_hz: float = float("nan"),
                         limits: ExposureValues = EU_2002_44_EC) -> dict:
    """Comfort indicators from sampled vertical acceleration (an accelerometer).

    The record is taken whole: tau = ``len(acc_y) / fs``.

    Parameters
    ----------
    acc_y : array_like (n,)
        Vertical acceleration samples, m/s^2.
    fs : float
        Sampling rate, Hz.
    method : {"fft", "iir"}
        How to weight (:func:`apply_weighting`); "fft" suits whole gait
        cycles, "iir" a long record (the filter's start-up transient is
        included, as in a vibration meter).
    mode : {"iso", "thesis"}
        ``"thesis"`` multiplies by ``|W(f_dominant_hz)|`` (default: the
        largest peak of the spectrum).

    Examples
    --------
    Two seconds of a 2 Hz, 3 m/s^2 accelerometer signal at 100 Hz:

    >>> import numpy as np
    >>> acc = 3 * np.cos(2 * np.pi * 2.0 * np.arange(200) / 100.0)
    >>> ind = comfort_from_samples(acc, fs=100.0)
    >>> ind["duration_s"], round(ind["acc_y_Wk_rms"], 4)
    (2.0, 1.1273)
    """
    x = np.asarray(acc_y, dtype=float)
    if x.ndim != 1 or x.size < 4:
        raise ValueError(f"comfort_from_samples: acc_y must be 1-D with >= 4 samples, got {x.shape}")
    if not np.all(np.isfinite(x)):
        bad = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(f"comfort_from_samples: acc_y has a non-finite value at sample {bad}")
    tau = x.size / fs
    x0 = x - x.mean()
    if mode == "iso":
        awb = apply_weighting(x0, fs, "Wb", method=method)
        awk = apply_weighting(x0, fs, "Wk", method=method)
        cf = float(np.max(np.abs(awb)) / rms(awb))
    elif mode == "thesis":
        if f_dominant_hz is None:
            spec = np.abs(np.fft.rfft(x0))
            f_dominant_hz = float(np.fft.rfftfreq(x.size, 1 / fs)[1 + np.argmax(spec[1:])])
        awb = abs(weighting("Wb", f_dominant_hz)) * x0
        awk = abs(weighting("Wk", f_dominant_hz)) * x0
        cf = float(crest_factor(x0))
    else:
        raise ValueError(f"mode must be 'iso' or 'thesis', got {mode!r}")
    return indicators_from_values(float(rms(awb)), float(rms(awk)), float(vdv(awb, fs)),
                                  float(vdv(awk, fs)), float(np.max(np.abs(x0))), cf, tau,
                                  vel_x_avg_mps * 3.6, amplitude_y_m, f0_hz=f0_hz, limits=limits)
