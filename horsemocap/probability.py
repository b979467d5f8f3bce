"""Two tail probabilities of the classical tests: Student's t quantile and the F survival function.

The analysis needs only these two; they are the special functions of
:mod:`scipy.special` (``stdtrit``, ``fdtrc``) with the edge cases of
``scipy.stats.t.ppf`` and ``scipy.stats.f.sf`` (a degree of freedom that
is not positive or a NaN argument gives NaN; the ends of the support give
the ends of the range), so the numbers are the same bits as
``scipy.stats`` gives, without loading that package.
"""
from __future__ import annotations

import numpy as np
from scipy.special import fdtrc, stdtrit

__all__ = ["t_quantile", "f_survival"]


def t_quantile(q, df):
    """Quantile of Student's t distribution with ``df`` degrees of freedom at probability ``q``.

    Parameters
    ----------
    q : float or array_like
        Probability in [0, 1].
    df : float or array_like
        Degrees of freedom (> 0; need not be an integer).

    Returns
    -------
    float or ndarray
        ``t`` with ``P(T <= t) = q``: -inf at ``q = 0``, inf at ``q = 1``,
        NaN for ``q`` outside [0, 1] or ``df <= 0``.

    Examples
    --------
    The two-sided 95 % factor of a confidence interval with 10 degrees of freedom:

    >>> round(float(t_quantile(0.975, 10)), 4)
    2.2281
    """
    q, df = np.broadcast_arrays(np.asarray(q, dtype=float), np.asarray(df, dtype=float))
    valid = df > 0
    inside = valid & (q > 0) & (q < 1)
    out = np.full(q.shape, np.nan)
    out[valid & (q == 0)] = -np.inf
    out[valid & (q == 1)] = np.inf
    if np.any(inside):
        out[inside] = stdtrit(df[inside], q[inside])
    return out[()] if out.ndim == 0 else out


def f_survival(x, dfn, dfd):
    """Upper tail ``P(F > x)`` of the F distribution with ``dfn`` and ``dfd`` degrees of freedom.

    Parameters
    ----------
    x : float or array_like
        The F statistic.
    dfn, dfd : float or array_like
        Numerator and denominator degrees of freedom (> 0; need not be integers).

    Returns
    -------
    float or ndarray
        The p-value of the F test: 1 for ``x <= 0``, 0 for ``x = inf``, NaN
        for a NaN ``x`` or a degree of freedom that is not positive.

    Examples
    --------
    The 5 % critical value of F(3, 20) is about 3.10:

    >>> round(float(f_survival(3.0984, 3, 20)), 3)
    0.05
    """
    x, dfn, dfd = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, dfn, dfd)))
    valid = (dfn > 0) & (dfd > 0)
    inside = valid & (x > 0) & (x < np.inf)
    out = np.zeros(x.shape)
    out[~valid | np.isnan(x)] = np.nan
    out[valid & (x <= 0)] = 1.0
    if np.any(inside):
        out[inside] = fdtrc(dfn[inside], dfd[inside], x[inside])
    return out[()] if out.ndim == 0 else out
