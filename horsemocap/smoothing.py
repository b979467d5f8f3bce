"""Robust local regression smoothing: MATLAB's ``smooth(y, span, 'rloess')``.

Thesis section 5.2.2 (and Appendix A step 6): every camera-frame coordinate
of every marker is smoothed with MATLAB's ``smooth(y, 0.1, 'rloess')``, a
robust locally weighted quadratic regression over 10 % of the points. The
thesis compares it with moving average and ``lowess`` (Figure 5.2): the
robust versions resist outliers, the plain ones are pulled by them.

The rules implemented here are those of MathWorks' documentation of
``smooth`` ("Curve Fitting Toolbox: Smoothing Data", sections *Moving
Average Filtering*, *Local Regression Smoothing* and *Robust Smoothing
Procedure*; https://www.mathworks.com/help/curvefit/smoothing-data.html and
https://www.mathworks.com/help/curvefit/smooth.html) and of the behaviour of
``smooth.m`` (MATLAB R2009a, the thesis' version), as follows:

1. **Span.** A span below 1 is a fraction of the number of points ``n``:
   ``span = ceil(span * n)``; then ``floor``, at most ``n``. A span of 1
   returns ``y`` unchanged. For uniformly spaced ``x`` (always so for
   ``smooth(y, ...)``) an even span is made odd, ``span = 2 floor(span/2) + 1``
   (n = 100 -> 11, n = 89 -> 9, n = 91 -> 11). (If that exceeds ``n``, which
   MATLAB does not guard, we use the largest odd number <= n.)
2. **Local fit.** At each ``x_i`` a weighted least-squares polynomial in
   ``x - x_i`` (degree 2 for loess, 1 for lowess) is fitted over the ``span``
   nearest points (ties at the farthest distance included). For uniform data
   this is the window ``[i-h, i+h]``, shifted at the ends so that it always
   holds ``span`` points (asymmetric windows, no padding or reflection). The
   smoothed value is the fit's constant term.
3. **Tricube weights** ``w = (1 - (d/dmax)^3)^3`` with ``d = |x - x_i|`` and
   ``dmax`` the largest distance in the window, so the farthest point gets
   zero weight. ``smooth.m`` works with square roots of weights, ``(1 -
   (d/dmax)^3)^1.5``, and if all of them are below ``sqrt(eps)`` it sets
   them all to one; we do the same.
4. **Robust iterations** (``rloess``/``rlowess``): exactly 5, no
   convergence test. Residuals ``r = y - ys``; scale ``s = max(1e8 * eps *
   max|y|, median|r|)`` (the median of the absolute residuals); bisquare
   weights ``(1 - (r/(6 s))^2)^2`` for ``|r| < 6 s``, else 0. Each local
   fit is redone with tricube x robust weights, over the ``span`` nearest
   points *among those with non-zero robust weight* (so an outlier with zero
   weight is replaced by the next nearest point, as MATLAB's
   ``iKNearestNeighbours`` does).

The local fits of a pass are solved together (:func:`_window_fits`: every
window's weighted least squares at once through NumPy's batched
pseudo-inverse); with repeated ``x`` values they are solved one by one, as
``smooth.m`` does. Both give the same values to rounding.

Note that statsmodels' ``lowess`` (local linear, 3 iterations, another
scale) and Pose2Sim's loess filter (not robust) are different methods.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = [
    "span_points",
    "minimum_span",
    "effective_span",
    "smooth",
    "rloess",
    "loess",
    "lowess",
    "rlowess",
    "moving_average",
    "smooth_positions",
]

_EPS = np.finfo(float).eps
_SEPS = math.sqrt(_EPS)
ROBUST_ITERATIONS = 5


def _check_y(y, name="y") -> np.ndarray:
    arr = np.asarray(y, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array of samples, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name}: empty array")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(
            f"{name}: NaN or inf at sample(s) {bad[:10].tolist()}{'...' if bad.size > 10 else ''}; "
            "smoothing needs finite values (fill or drop the missing samples first, "
            "or use smooth_positions(..., nan='omit'))")
    return arr


def span_points(span: float, n: int, uniform: bool = True) -> int:
    """Number of points in the smoothing window, as MATLAB's ``smooth`` computes it.

    Parameters
    ----------
    span : float
        A fraction of the points if ``< 1`` (thesis: 0.1), else a number of points.
    n : int
        Number of samples.
    uniform : bool
        Uniformly spaced ``x``: an even span is rounded up to odd.

    Returns
    -------
    int
        ``ceil(span * n)`` (fraction) or ``span``, floored, at most ``n``,
        odd for uniform data (n = 100, span = 0.1 -> 11; n = 89 -> 9).

    Examples
    --------
    >>> span_points(0.1, 100), span_points(0.1, 89), span_points(0.1, 91)
    (11, 9, 11)
    """
    if not np.isfinite(span) or span <= 0:
        raise ValueError(f"span must be a positive number (fraction < 1 or a number of points), got {span!r}")
    if span < 1:
        span = math.ceil(span * n)
    k = min(int(math.floor(span)), n)
    if uniform and k > 1:
        k = 2 * (k // 2) + 1
        if k > n:  # MATLAB does not guard this; keep the window inside the data
            k = n if n % 2 == 1 else n - 1
    return max(k, 1)


def _k_nearest(k: int, i: int, x: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Indices of the ``k`` points of ``x[inside]`` nearest to ``x[i]`` (ties included).

    MATLAB ``smooth.m``'s ``iKNearestNeighbours``.
    """
    if np.count_nonzero(inside) <= k:
        return np.flatnonzero(inside)
    d = np.abs(x - x[i])
    dk = np.sort(d[inside])[k - 1]
    return np.flatnonzero((d <= dk) & inside)


def _sqrt_tricube(d: np.ndarray) -> np.ndarray:
    """Square roots of the tricube weights ``(1 - (d/dmax)^3)^3`` (``smooth.m``)."""
    dmax = d.max()
    if dmax > 0:
        d = d / dmax
    w = (1.0 - d**3) ** 1.5
    if np.all(w < _SEPS):
        w = np.ones_like(w)
    return w


def _local_fit(x, y, i, idx, degree, sqrt_robust=None) -> float:
    x1 = x[idx] - x[i]
    w = _sqrt_tricube(np.abs(x1))
    if sqrt_robust is not None:
        w = w * sqrt_robust[idx]
    V = np.vander(x1, degree + 1, increasing=True) * w[:, None]
    b, *_ = np.linalg.lstsq(V, w * y[idx], rcond=None)
    return float(b[0])


def _sqrt_bisquare(r: np.ndarray, max_abs_y: float) -> np.ndarray:
    """Square roots of bisquare robust weights (``smooth.m``'s ``iBisquareWeights``)."""
    s = max(1e8 * _EPS * max_abs_y, float(np.median(np.abs(r))))
    u = r / (6.0 * s)
    return np.where(np.abs(u) < 1, np.abs(1.0 - u**2), 0.0)


def _uniform_first_pass(y: np.ndarray, k: int, degree: int) -> np.ndarray:
    """Non-robust local fits for uniform x, as linear filters (``unifloess``)."""
    n = y.size
    h = (k - 1) // 2
    out = np.empty(n)
    # interior: the same coefficients at every point
    j = np.arange(k, dtype=float) - h
    w = _sqrt_tricube(np.abs(j))
    V = np.vander(j, degree + 1, increasing=True) * w[:, None]
    alpha = np.linalg.pinv(V)[0] * w  # row giving b[0] from y
    if n > 2 * h:
        windows = np.lib.stride_tricks.sliding_window_view(y, k)
        out[h:n - h] = windows @ alpha
    # ends: the first / last k points, fit centred on the j-th point
    for jj in range(min(h, n)):
        xw = np.arange(k, dtype=float) - jj
        w = _sqrt_tricube(np.abs(xw))
        V = np.vander(xw, degree + 1, increasing=True) * w[:, None]
        a = np.linalg.pinv(V)[0] * w
        out[jj] = a @ y[:k]
        out[n - 1 - jj] = a @ y[::-1][:k]
    return out


def _nearest_windows(x: np.ndarray, k: int, inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every point's :func:`_k_nearest` window at once, for strictly increasing ``x``.

    Returns ``(cols, member)``, both ``(n, W)``: row ``i`` lists candidate
    indices and which of them are among the ``k`` points of ``x[inside]``
    nearest to ``x[i]`` (ties at the farthest distance included), exactly the
    set :func:`_k_nearest` gives. With distinct sorted ``x`` those points are
    ``k`` consecutive ones among the inside points, around the insertion
    position ``p`` of ``x[i]``: the ``2 k + 1`` inside points from ``p - k``
    hold them (any point beyond has ``k`` inside points strictly nearer).
    """
    n = x.size
    pts = np.flatnonzero(inside)
    m = pts.size
    if m <= k:                                   # every inside point, for every i
        cols = np.broadcast_to(pts, (n, m))
        return cols, np.ones((n, m), bool)
    width = min(2 * k + 1, m)
    start = np.clip(np.searchsorted(x[pts], x) - k, 0, m - width)
    cols = pts[start[:, None] + np.arange(width)]
    d = np.abs(x[cols] - x[:, None])
    dk = np.partition(d, k - 1, axis=1)[:, k - 1]
    return cols, d <= dk[:, None]


def _window_tricube(dist: np.ndarray, member: np.ndarray) -> np.ndarray:
    """:func:`_sqrt_tricube` of every row's window (its members; 0 for the other columns)."""
    d = np.where(member, dist, 0.0)
    dmax = d.max(axis=1, keepdims=True)
    d = np.divide(d, dmax, out=d, where=dmax > 0)
    w = np.where(member, (1.0 - d**3) ** 1.5, 0.0)
    tiny = ~np.any(member & (w >= _SEPS), axis=1)             # smooth.m: all below sqrt(eps) -> ones
    w[tiny] = member[tiny]
    return w


def _window_fits(x, y, cols, member, degree, sqrt_robust=None, at=None) -> np.ndarray:
    """:func:`_local_fit` of every row's window at once (batched weighted least squares).

    Row ``r`` fits at ``x[at[r]]`` (default: row ``i`` at ``x[i]``) over
    ``cols[r][member[r]]`` with the weights of :func:`_sqrt_tricube` (times
    ``sqrt_robust``); the other columns get weight zero, which leaves the
    least-squares solution unchanged. Solved by the pseudo-inverse (SVD: the
    minimum-norm solution, as ``lstsq``, with ``lstsq``'s cutoff ``max(rows,
    columns) * eps`` of the window's own points): the fits agree with the
    one-by-one ``lstsq`` to rounding.
    """
    x1 = x[cols] - (x if at is None else x[at])[:, None]
    w = _window_tricube(np.abs(x1), member)
    if sqrt_robust is not None:
        w = w * sqrt_robust[cols]
    V = (x1[:, :, None] ** np.arange(degree + 1)) * w[:, :, None]
    rows = member.sum(axis=1)
    pinv = np.empty((cols.shape[0], degree + 1, cols.shape[1]))
    for r in np.unique(rows):
        sel = rows == r
        pinv[sel] = np.linalg.pinv(V[sel], rcond=max(int(r), degree + 1) * _EPS)
    return np.einsum("ij,ij->i", pinv[:, 0, :], w * y[cols])


def _local_regression(x, y, span, degree, robust, iterations=ROBUST_ITERATIONS, windows="matlab"):
    n = y.size
    x = np.asarray(x, float)
    order = np.argsort(x, kind="stable")
    if np.any(order != np.arange(n)):
        xs, ys = x[order], y[order]
        out = np.empty(n)
        out[order] = _local_regression(xs, ys, span, degree, robust, iterations, windows)
        return out
    dx = np.diff(x)
    uniform = bool(n < 3 or np.all(np.abs(dx - dx.mean()) <= 1e-12 * max(1.0, abs(dx.mean()) * n)))
    k = span_points(span, n, uniform=uniform)
    if k == 1:
        return y.copy()
    if np.any(dx == 0):                            # repeated x: the fits one by one (the same rules)
        return _local_regression_loop(x, y, k, degree, robust, iterations, windows, uniform)
    everywhere = np.ones(n, bool)
    first = _nearest_windows(x, k, everywhere)
    c = _uniform_first_pass(y, k, degree) if uniform else _window_fits(x, y, *first, degree)
    if not robust or k <= 2:
        return c
    max_abs_y = float(np.max(np.abs(y)))
    if windows == "fixed":                         # the first pass' windows and their tricube weights
        cols, member = first
        tricube = _window_tricube(np.abs(x[cols] - x[:, None]), member)
    for _ in range(iterations):
        rw = _sqrt_bisquare(y - c, max_abs_y)
        new = np.empty(n)
        rest = np.arange(n)
        if windows == "fixed":                     # MATLAB's rule where too few points keep a weight
            kept = np.count_nonzero(rw[cols] * tricube, axis=1) > degree
            at = np.flatnonzero(kept)
            if at.size:
                new[at] = _window_fits(x, y, cols[at], member[at], degree, rw, at=at)
            rest = np.flatnonzero(~kept)
        if rest.size:
            cols_r, member_r = _nearest_windows(x, k, rw > 0)
            new[rest] = _window_fits(x, y, cols_r[rest], member_r[rest], degree, rw, at=rest)
        c = new
    return c


def _local_regression_loop(x, y, k, degree, robust, iterations, windows, uniform):
    """The local fits one by one (any ``x``, repeated values included): MATLAB ``smooth.m``'s loop."""
    n = y.size
    if uniform:
        c = _uniform_first_pass(y, k, degree)
    else:
        c = np.empty(n)
        everywhere = np.ones(n, bool)
        for i in range(n):
            if i > 0 and x[i] == x[i - 1]:
                c[i] = c[i - 1]
                continue
            c[i] = _local_fit(x, y, i, _k_nearest(k, i, x, everywhere), degree)
    if not robust or k <= 2:
        return c
    max_abs_y = float(np.max(np.abs(y)))
    for _ in range(iterations):
        rw = _sqrt_bisquare(y - c, max_abs_y)
        inside = rw > 0
        everywhere = np.ones(n, bool)
        new = np.empty(n)
        for i in range(n):
            if i > 0 and x[i] == x[i - 1]:
                new[i] = new[i - 1]
                continue
            if windows == "fixed":
                idx = _k_nearest(k, i, x, everywhere)
                if np.count_nonzero(rw[idx] * _sqrt_tricube(np.abs(x[idx] - x[i]))) > degree:
                    new[i] = _local_fit(x, y, i, idx, degree, rw)
                    continue
            new[i] = _local_fit(x, y, i, _k_nearest(k, i, x, inside), degree, rw)
        c = new
    return c


def minimum_span(method: str) -> int:
    """Smallest span whose interior local fit actually smooths.

    With tricube weights the two farthest points of a symmetric window get
    zero weight, so a window of ``span`` points fits ``degree + 1``
    coefficients to ``span - 2`` points. When these are equal (span 5 for a
    quadratic, 3 for a line) the fit interpolates: the interior is returned
    unchanged, every interior residual is zero, the robust scale ``median|r|``
    collapses and the robust iterations reject every point near the ends,
    whose windows then slide inwards and extrapolate (MATLAB does exactly
    this; the thesis' 38 frames x 0.1 give span 5). The minimum is the
    smallest odd span with more points of non-zero weight than coefficients:
    7 for (r)loess, 5 for (r)lowess, 3 for the moving average.

    Examples
    --------
    >>> minimum_span("rloess"), minimum_span("lowess"), minimum_span("moving")
    (7, 5, 3)
    """
    degree = {"loess": 2, "rloess": 2, "lowess": 1, "rlowess": 1, "moving": -1}[method.lower()]
    k = degree + 4
    return k if k % 2 == 1 else k + 1


def effective_span(n: int, span: float = 0.1, method: str = "rloess", min_span=None) -> int:
    """Number of points per window that :func:`smooth` will use for ``n`` samples.

    Examples
    --------
    The thesis' 38 frames: MATLAB's 10 % gives 5 points, too few to smooth.

    >>> effective_span(38), effective_span(38, min_span="auto")
    (5, 7)
    """
    k = span_points(span, n, uniform=True) if method != "moving" else None
    if k is None:
        k = math.ceil(span * n) if span < 1 else int(math.floor(span))
        k = min(k, n)
        k = k - 1 if k % 2 == 0 else k
    if min_span is not None:
        floor = minimum_span(method) if min_span == "auto" else int(min_span)
        if k < floor:
            k = min(floor, n if n % 2 == 1 else n - 1)
    return max(int(k), 1)


def smooth(y, span: float = 0.1, method: str = "rloess", x=None, min_span=None,
           windows: str = "matlab") -> np.ndarray:
    """MATLAB ``smooth(y, span, method)`` (or ``smooth(x, y, span, method)``).

    Parameters
    ----------
    y : array_like, shape (n,)
        Samples (one coordinate of one marker over the frames, thesis ``CM``).
        NaN is not allowed.
    span : float
        Fraction of the points (< 1) or number of points; thesis: 0.1.
    method : {"rloess", "loess", "rlowess", "lowess", "moving"}
    x : array_like, optional
        Abscissae (default ``0..n-1``: uniform).
    min_span : None, "auto" or int
        ``None`` (default): MATLAB's span exactly. ``"auto"``: raise a span
        too small to smooth to :func:`minimum_span`; an int: at least that
        many points. Not MATLAB: say so where it is used.
    windows : {"matlab", "fixed"}
        Robust iterations: ``"matlab"`` re-chooses each window among the
        points of non-zero robust weight (``smooth.m``); ``"fixed"`` keeps the
        first pass' windows and only multiplies the weights (Cleveland 1979),
        falling back to MATLAB's rule when too few points keep a weight.

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    A local quadratic fit reproduces a parabola exactly; the robust version
    ignores a spike that pulls the plain one:

    >>> import numpy as np
    >>> x = np.arange(30.0)
    >>> y = 0.5 * x ** 2 - 3 * x + 1
    >>> bool(np.allclose(smooth(y, 0.3, "loess"), y))
    True
    >>> spiked = y.copy()
    >>> spiked[15] += 100.0
    >>> round(abs(float(smooth(spiked, 0.3, "rloess")[15] - y[15])), 6)
    0.0
    >>> round(float(smooth(spiked, 0.3, "loess")[15] - y[15]), 3)
    39.663
    """
    y = _check_y(y)
    method = method.lower()
    if windows not in ("matlab", "fixed"):
        raise ValueError(f"windows must be 'matlab' or 'fixed', got {windows!r}")
    if min_span is not None:
        if min_span != "auto" and not (isinstance(min_span, (int, np.integer)) and min_span >= 1):
            raise ValueError(f"min_span must be None, 'auto' or a positive int, got {min_span!r}")
        if x is None and method in ("loess", "rloess", "lowess", "rlowess", "moving"):
            k = effective_span(y.size, span, method, min_span)
            if k > effective_span(y.size, span, method, None):
                span = k
    if method == "moving":
        if x is not None:
            raise ValueError("moving average: only uniformly spaced samples are supported (x must be None)")
        return moving_average(y, span)
    table = {"loess": (2, False), "rloess": (2, True), "lowess": (1, False), "rlowess": (1, True)}
    if method not in table:
        raise ValueError(f"method must be one of {sorted(table) + ['moving']}, got {method!r}")
    degree, robust = table[method]
    xv = np.arange(y.size, dtype=float) if x is None else np.asarray(x, float)
    if xv.shape != y.shape:
        raise ValueError(f"x has shape {xv.shape}, y has shape {y.shape}; expected the same")
    if not np.all(np.isfinite(xv)):
        raise ValueError("x: NaN or inf not allowed")
    return _local_regression(xv, y, span, degree, robust, windows=windows)


def rloess(y, span: float = 0.1) -> np.ndarray:
    """Robust local quadratic regression, MATLAB ``smooth(y, span, 'rloess')``.

    The thesis' smoother (section 5.2.2, Appendix A step 6): quadratic local
    fits with tricube weights over ``span`` (fraction) of the points, then 5
    bisquare robust iterations with the scale 6 x median absolute residual.
    See the module docstring for the exact rules (span rounding, the ends).

    Parameters
    ----------
    y : array_like, shape (n,)
        Uniformly spaced samples, finite.
    span : float
        Fraction of the points (thesis: 0.1) or a number of points.

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    >>> import numpy as np
    >>> x = np.arange(30.0)
    >>> y = 0.5 * x ** 2 - 3 * x + 1
    >>> y[15] += 100.0                      # an outlier
    >>> round(float(rloess(y, 0.3)[15]), 6)  # the parabola's value at 15: 68.5
    68.5
    """
    return smooth(y, span, "rloess")


def loess(y, span: float = 0.1) -> np.ndarray:
    """Local quadratic regression, MATLAB ``smooth(y, span, 'loess')`` (not robust).

    Examples
    --------
    >>> import numpy as np
    >>> y = 0.5 * np.arange(30.0) ** 2
    >>> bool(np.allclose(loess(y, 0.3), y))   # a quadratic is kept exactly
    True
    """
    return smooth(y, span, "loess")


def lowess(y, span: float = 0.1) -> np.ndarray:
    """Local linear regression, MATLAB ``smooth(y, span, 'lowess')`` (not robust).

    Examples
    --------
    >>> import numpy as np
    >>> line = 2 * np.arange(30.0) + 1
    >>> bool(np.allclose(lowess(line, 0.3), line))
    True
    """
    return smooth(y, span, "lowess")


def rlowess(y, span: float = 0.1) -> np.ndarray:
    """Robust local linear regression, MATLAB ``smooth(y, span, 'rlowess')``.

    Examples
    --------
    >>> import numpy as np
    >>> line = 2 * np.arange(30.0) + 1
    >>> line[10] += 50.0                       # an outlier
    >>> round(float(rlowess(line, 0.3)[10]), 6)  # the line's value: 21
    21.0
    """
    return smooth(y, span, "rlowess")


def moving_average(y, span: float = 5) -> np.ndarray:
    """Moving average, MATLAB ``smooth(y, span, 'moving')``.

    The span (points, or a fraction of them if < 1) is made odd (an even
    span loses one point); near the ends the window shrinks symmetrically,
    so ``ys[0] = y[0]``, ``ys[1] = mean(y[0:3])``, ... (MATLAB documentation
    of ``smooth``, "Moving Average Filtering").

    Examples
    --------
    >>> moving_average([1.0, 2.0, 3.0, 4.0, 10.0], 3)
    array([ 1.        ,  2.        ,  3.        ,  5.66666667, 10.        ])
    """
    y = _check_y(y)
    n = y.size
    if not np.isfinite(span) or span <= 0:
        raise ValueError(f"span must be positive, got {span!r}")
    if span < 1:
        span = math.ceil(span * n)
    k = min(int(math.floor(span)), n)
    if k % 2 == 0:
        k -= 1
    if k <= 1:
        return y.copy()
    h = (k - 1) // 2
    out = np.empty(n)
    csum = np.concatenate([[0.0], np.cumsum(y)])
    for i in range(n):
        r = min(h, i, n - 1 - i)
        out[i] = (csum[i + r + 1] - csum[i - r]) / (2 * r + 1)
    return out


def _runs(mask: np.ndarray):
    """(start, stop) of the runs of True in a 1-D boolean mask."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def smooth_positions(points, span: float = 0.1, method: str = "rloess", nan: str = "raise",
                     min_span="auto", windows: str = "fixed") -> np.ndarray:
    """Smooth every coordinate of every marker over time (thesis 5.2.2, App. A step 6).

    The thesis smooths each coordinate with ``smooth(y, 0.1, 'rloess')``.
    On short records (the thesis and the default session: 38 frames) MATLAB's
    rules break down: 10 % is 5 points, the interior is not smoothed at all
    and the robust iterations extrapolate at the ends. The defaults here therefore differ from MATLAB in two
    documented ways: the span is at least :func:`minimum_span` (7 for
    rloess) and the robust iterations keep the first pass' windows
    (``windows="fixed"``, Cleveland 1979) instead of re-choosing them among
    the points of non-zero weight. ``min_span=None, windows="matlab"`` is
    MATLAB exactly (as :func:`rloess`). Notebook 06 compares them.

    Parameters
    ----------
    points : array_like, shape (n_frames, n_markers, 3)
        Marker positions (thesis ``CM_L``, camera frame), time on axis 0.
    span : float
        Thesis: 0.1 (10 % of the frames).
    method : str
        ``"rloess"`` (thesis), ``"loess"``, ``"rlowess"``, ``"lowess"`` or ``"moving"``.
    nan : {"raise", "omit"}
        ``"raise"``: NaN is an error naming the marker, axis and frames.
        ``"omit"``: each run of consecutive finite samples is smoothed on
        its own, with the window the whole record would use (at most the
        run's length; runs of 1-2 samples are kept as measured): a local fit
        never bridges a gap, where the motion is unknown. NaN stays NaN.
    min_span : "auto", None or int
        Default ``"auto"``: a span too small to smooth is raised to
        :func:`minimum_span` (7 points for rloess). MATLAB does not do this:
        on the thesis' 38 frames, ``smooth(y, 0.1, 'rloess')`` uses 5 points,
        leaves the interior unchanged and ruins the ends (notebook 06 shows
        it). ``None`` reproduces MATLAB exactly.
    windows : {"fixed", "matlab"}
        See :func:`smooth` (default ``"fixed"``, see above).

    Returns
    -------
    ndarray, same shape as ``points``.

    Examples
    --------
    One marker over 20 frames, a frame missing on y:

    >>> import numpy as np
    >>> points = np.zeros((20, 1, 3))
    >>> points[:, 0, 0] = np.arange(20.0) ** 2
    >>> points[5, 0, 1] = np.nan
    >>> smoothed = smooth_positions(points, span=0.5, method="loess", nan="omit")
    >>> bool(np.allclose(smoothed[:, 0, 0], points[:, 0, 0])), bool(np.isnan(smoothed[5, 0, 1]))
    (True, True)
    """
    p = np.asarray(points, float)
    if p.ndim != 3:
        raise ValueError(f"points: expected shape (frames, markers, 3), got {p.shape}")
    if nan not in ("raise", "omit"):
        raise ValueError(f"nan must be 'raise' or 'omit', got {nan!r}")
    out = np.full_like(p, np.nan)
    for m in range(p.shape[1]):
        for a in range(p.shape[2]):
            col = p[:, m, a]
            ok = np.isfinite(col)
            if ok.all():
                out[:, m, a] = smooth(col, span, method, min_span=min_span, windows=windows)
                continue
            if nan == "raise":
                bad = np.flatnonzero(~ok)
                raise ValueError(
                    f"points: marker {m}, axis {'xyz'[a] if a < 3 else a}: NaN at frame(s) "
                    f"{bad[:10].tolist()}{'...' if bad.size > 10 else ''}; use nan='omit' to smooth "
                    "the remaining frames")
            k = effective_span(p.shape[0], span, method, min_span)
            for lo, hi in _runs(ok):
                length = hi - lo
                if length < 3:
                    out[lo:hi, m, a] = col[lo:hi]  # too short to smooth: kept as measured
                    continue
                kk = min(k, length if length % 2 == 1 else length - 1)
                out[lo:hi, m, a] = (moving_average(col[lo:hi], kk) if method == "moving"
                                    else smooth(col[lo:hi], kk, method, windows=windows))
    return out
