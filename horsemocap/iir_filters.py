"""Recursive (IIR) filters in NumPy: the AR(1) recursion, the bilinear transform, second-order sections.

The few digital-filter operations the analysis uses, written with NumPy
alone so that loading the analysis does not load :mod:`scipy.signal` (which
loads :mod:`scipy.stats` with it). Each one does the same floating-point
operations in the same order as its SciPy counterpart, so it gives the
same bits:

- :func:`ar1_filter`: ``scipy.signal.lfilter([1], [1, -rho], x, axis)``;
- :func:`bilinear`: ``scipy.signal.bilinear(b, a, fs)``;
- :func:`sos_frequency_response`: ``scipy.signal.freqz_sos(sos, worN=f, fs=fs)[1]``;
- :func:`sos_filter`: ``scipy.signal.sosfilt(sos, x, axis)``.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["ar1_filter", "bilinear", "sos_frequency_response", "sos_filter"]

#: Leading numerator coefficients at or below this (after normalising) are dropped, as SciPy does.
NEGLIGIBLE_COEFFICIENT = 1e-14


def ar1_filter(x, rho: float, axis: int = 0) -> np.ndarray:
    """The first-order recursion ``y_k = x_k + rho y_(k-1)`` (``y_0 = x_0``) along ``axis``.

    Parameters
    ----------
    x : array_like
        Real samples.
    rho : float
        The recursion's coefficient (the lag-1 correlation of an AR(1) process).
    axis : int
        The axis the recursion runs along.

    Returns
    -------
    ndarray
        ``y``, shaped as ``x`` (float).

    Examples
    --------
    >>> ar1_filter([1.0, 0.0, 0.0, 2.0], 0.5).tolist()
    [1.0, 0.5, 0.25, 2.125]
    """
    samples = np.moveaxis(np.asarray(x, dtype=float), axis, 0)
    out = np.empty_like(samples)
    a1 = -float(rho) / 1.0
    state = np.zeros(samples.shape[1:])
    for k in range(samples.shape[0]):
        current = samples[k]
        out[k] = state + 1.0 * current
        state = current * 0.0 - out[k] * a1
    return np.moveaxis(out, 0, axis)


def bilinear(b, a, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Digital filter ``(beta, alpha)`` of the analogue ``b(s) / a(s)`` by the bilinear transform.

    ``s = 2 fs (z - 1) / (z + 1)``, without pre-warping (pass a pre-warped
    ``fs`` to match a chosen frequency).

    Parameters
    ----------
    b, a : array_like
        Real analogue numerator and denominator, highest power of ``s`` first.
    fs : float
        Sampling rate (Hz), > 0.

    Returns
    -------
    beta, alpha : ndarray
        Digital numerator and denominator in powers of ``z^-1``, ``alpha[0] = 1``.

    Examples
    --------
    The first-order low-pass ``1 / (s + 1)`` at ``fs = 0.5`` (``2 fs = 1``):

    >>> beta, alpha = bilinear([1.0], [1.0, 1.0], 0.5)
    >>> beta.tolist(), alpha.tolist()
    ([0.5, 0.5], [1.0, 0.0])
    """
    b, a = (np.trim_zeros(np.atleast_1d(np.asarray(v, dtype=float)), "f") for v in (b, a))
    if b.ndim != 1 or a.ndim != 1 or a.size == 0 or b.size == 0:
        raise ValueError(f"bilinear: b and a must be 1-d coefficient lists, not all zero; got {b!r} and {a!r}")
    if not (math.isfinite(fs) and fs > 0):
        raise ValueError(f"bilinear: fs must be a positive finite sampling rate, got {fs!r}")
    fac = np.sqrt(fs * 2)
    zp1 = np.polynomial.Polynomial((+1, 1)) / fac
    zm1 = np.polynomial.Polynomial((-1, 1)) * fac
    n = max(len(a), len(b)) - 1
    numerator = sum(b_ * zp1 ** (n - q) * zm1 ** q for q, b_ in enumerate(b[::-1]))
    denominator = sum(a_ * zp1 ** (n - p) * zm1 ** p for p, a_ in enumerate(a[::-1]))
    return _normalized(numerator.coef[::-1].copy(), denominator.coef[::-1].copy())


def _normalized(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``num / den[0], den / den[0]`` with negligible leading numerator terms dropped (as SciPy's normalize)."""
    den = np.trim_zeros(den, "f")
    if den.size == 0:
        den = np.zeros(1)
    num, den = num / den[0], den / den[0]
    leading = 0
    while leading < num.size - 1 and abs(num[leading]) <= NEGLIGIBLE_COEFFICIENT:
        leading += 1
    if leading:
        warnings.warn(f"bilinear: {leading} leading numerator coefficient(s) negligible and dropped: the "
                      "filter is badly conditioned", RuntimeWarning, stacklevel=3)
    return num[leading:], den


def _check_sos(sos) -> np.ndarray:
    sos = np.atleast_2d(np.asarray(sos, dtype=float))
    if sos.ndim != 2 or sos.shape[1] != 6 or sos.shape[0] == 0:
        raise ValueError(f"sos: expected second-order sections of shape (n_sections, 6), got {sos.shape}")
    if not np.all(sos[:, 3] == 1):
        raise ValueError(f"sos: each section's a0 (column 3) must be 1, got {sos[:, 3].tolist()}")
    return sos


def sos_frequency_response(sos, freq_hz, fs: float) -> np.ndarray:
    """Complex response ``H(exp(2 pi i f / fs))`` of cascaded second-order sections at ``freq_hz``.

    Parameters
    ----------
    sos : array_like, shape (n_sections, 6)
        ``[b0, b1, b2, 1, a1, a2]`` per section.
    freq_hz : array_like
        Frequencies (Hz).
    fs : float
        Sampling rate (Hz).

    Returns
    -------
    ndarray
        Complex response at each frequency.

    Examples
    --------
    A two-sample average passes DC and stops the Nyquist frequency:

    >>> h = sos_frequency_response([[0.5, 0.5, 0.0, 1.0, 0.0, 0.0]], [0.0, 50.0], 100.0)
    >>> [round(float(abs(v)), 12) for v in h]
    [1.0, 0.0]
    """
    sos = _check_sos(sos)
    w = 2 * math.pi * np.atleast_1d(np.asarray(freq_hz, dtype=float)) / fs
    zm1 = np.exp(-1j * w)
    h = 1.
    for row in sos:
        h *= _polyval(zm1, row[:3]) / _polyval(zm1, row[3:])
    return h


def _polyval(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``c[0] x^(n-1) + ... + c[n-1]`` by Horner's scheme on ascending ``x`` powers (SciPy's order)."""
    value = np.full(x.shape, c[-1], dtype=np.result_type(c, x))
    for i in range(2, c.shape[0] + 1):
        value = c[-i] + value * x
    return value


def sos_filter(sos, x, axis: int = -1) -> np.ndarray:
    """Filter ``x`` along ``axis`` by cascaded second-order sections (direct form II transposed, zero start).

    Parameters
    ----------
    sos : array_like, shape (n_sections, 6)
        ``[b0, b1, b2, 1, a1, a2]`` per section.
    x : array_like
        Real samples.
    axis : int
        The time axis.

    Returns
    -------
    ndarray
        The filtered samples, shaped as ``x``.

    Examples
    --------
    One section ``y_k = x_k + 0.5 y_(k-1)`` on an impulse:

    >>> sos_filter([[1.0, 0.0, 0.0, 1.0, -0.5, 0.0]], [1.0, 0.0, 0.0]).tolist()
    [1.0, 0.5, 0.25]
    """
    sections = [tuple(float(c) for c in row) for row in _check_sos(sos)]
    signals = np.moveaxis(np.asarray(x, dtype=float), axis, -1)
    shape = signals.shape
    rows = signals.reshape(-1, shape[-1])
    out = np.array([_sos_filter_row(sections, row.tolist()) for row in rows], dtype=float).reshape(shape)
    return np.moveaxis(out, -1, axis)


def _sos_filter_row(sections, samples: list) -> list:
    """One signal through the sections, sample by sample (SciPy's operation order)."""
    state = [[0.0, 0.0] for _ in sections]
    out = []
    for x_cur in samples:
        for (b0, b1, b2, _, a1, a2), z in zip(sections, state):
            x_new = b0 * x_cur + z[0]
            z[0] = b1 * x_cur - a1 * x_new + z[1]
            z[1] = b2 * x_cur - a2 * x_new
            x_cur = x_new
        out.append(x_cur)
    return out
