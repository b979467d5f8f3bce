"""The AR(1) recursion in NumPy, the same bits as :func:`scipy.signal.lfilter`.

:func:`ar1_filter` is ``scipy.signal.lfilter([1], [1, -rho], x, axis)``
written with NumPy alone, so that loading the analysis does not load
:mod:`scipy.signal` (which loads :mod:`scipy.stats` with it). It does the
same floating-point operations in the same order as ``lfilter``, so it
gives the same bits.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ar1_filter"]


def ar1_filter(x, rho: float, axis: int = 0) -> np.ndarray:
    """The first-order recursion ``y_k = x_k + rho y_(k-1)`` (``y_0 = x_0``) along ``axis``.

    Parameters
    ----------
    x : array_like
        Real samples (a NaN or an infinite sample propagates along the
        recursion, as in ``lfilter``).
    rho : float
        The recursion's coefficient (the lag-1 correlation of an AR(1) process).
    axis : int
        The axis the recursion runs along.

    Returns
    -------
    ndarray
        ``y``, shaped as ``x`` (float).

    Raises
    ------
    TypeError
        ``x`` is complex.

    Examples
    --------
    >>> ar1_filter([1.0, 0.0, 0.0, 2.0], 0.5).tolist()
    [1.0, 0.5, 0.25, 2.125]
    """
    values = np.asarray(x)
    if np.iscomplexobj(values):
        raise TypeError(f"ar1_filter: x must be real, got complex samples (dtype {values.dtype})")
    samples = np.moveaxis(values.astype(float, copy=False), axis, 0)
    out = np.empty_like(samples)
    # lfilter's own operations on purpose (/ 1.0, 1.0 *, * 0.0): an inf sample gives NaN next, as in lfilter
    a1 = -float(rho) / 1.0
    state = np.zeros(samples.shape[1:])
    with np.errstate(invalid="ignore"):   # inf * 0.0 is NaN, silently, as in lfilter
        for k in range(samples.shape[0]):
            current = samples[k]
            out[k] = state + 1.0 * current
            state = current * 0.0 - out[k] * a1
    return np.moveaxis(out, 0, axis)
