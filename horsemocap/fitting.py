"""Curve fits to the registered marker positions (thesis section 5.5).

- x-motion: a polynomial (``poly1`` by default, section 5.5.2.1).
- y and z: a Fourier series with its fundamental frequency fitted too
  (eq. 5.23), as MATLAB's ``fit(t, y, 'fourierN')`` does (Curve Fitting
  Toolbox documentation, "Fourier Series" and ``fit``): spectral start point,
  separable nonlinear least squares on ``w`` only, goodness of fit and 95 %
  confidence bounds as MATLAB reports them (section 5.5.1).
- The order rule of section 5.5.2.2: with E extremes (maxima and minima)
  counted on the smoothed data, the two proposed orders are ``N = E/2`` and
  ``N = E/2 + 1`` (:func:`proposed_orders`); :func:`choose_order` picks one.
- Velocity and acceleration are the analytic derivatives of the fitted
  curves (section 5.5.3); the positions used downstream stay the registered
  ones (section 5.5.2).

Symbols: ``g(t)`` data, ``g_F(t)`` fitted Fourier series (eq. 5.23),
``a_0, a_n, b_n, omega`` -> ``coefficients`` named ``a0, a1, b1, ..., w``;
``SSE`` (eq. 5.22) -> ``gof.sse``; ``P^m, V^m, A^m`` -> :class:`MotionFit`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from .probability import t_quantile

__all__ = [
    "GoodnessOfFit",
    "Fit",
    "MotionFit",
    "fit_polynomial",
    "fit_fourier",
    "fourier_start_point",
    "count_extremes",
    "proposed_orders",
    "choose_order",
    "top_harmonic_significant",
    "ORDER_RULES",
    "fit_motion",
]


@dataclass(frozen=True)
class GoodnessOfFit:
    """MATLAB's ``gof`` structure (section 5.5.1).

    ``sse = sum r^2`` (eq. 5.22), ``rsquare = 1 - sse/sst``, ``dfe = n - m``,
    ``adjrsquare = 1 - sse (n - 1) / (sst dfe)``, ``rmse = sqrt(sse / dfe)``.

    Examples
    --------
    >>> import numpy as np
    >>> fit = fit_polynomial([0.0, 1.0, 2.0, 3.0], [1.0, 3.0, 5.0, 8.0])
    >>> fit.gof.dfe, round(fit.gof.sse, 4), round(fit.gof.rsquare, 4)
    (2, 0.3, 0.9888)
    """

    sse: float
    rsquare: float
    dfe: int
    adjrsquare: float
    rmse: float

    def as_dict(self) -> dict:
        return {"sse": self.sse, "rsquare": self.rsquare, "dfe": self.dfe,
                "adjrsquare": self.adjrsquare, "rmse": self.rmse}


@dataclass(frozen=True)
class Fit:
    """A fitted curve (MATLAB ``cfit`` + ``gof``).

    Attributes
    ----------
    kind : "poly" or "fourier"
    order : int
        Polynomial degree or Fourier order N.
    coefficients : (m,)
        ``poly``: ``p1 .. p{d+1}`` (highest power first, MATLAB's order);
        ``fourier``: ``a0, a1, b1, ..., aN, bN, w`` (and ``c`` last, the
        slope of the optional linear trend, see :func:`fit_fourier`).
    names : tuple of str
    gof : GoodnessOfFit
    confint : (2, m)
        95 % confidence bounds (rows lower, upper), MATLAB ``confint``.
    t, y, residuals : (n,)
        The data used (finite points only) and ``y - g_F(t)``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(40) / 30.0                 # two periods of a 1.5 Hz stride at 30 fps
    >>> w = 2 * np.pi * 1.5
    >>> y = 0.3 + 0.05 * np.cos(w * t) + 0.02 * np.sin(2 * w * t)
    >>> fit = fit_fourier(t, y, order=2)
    >>> fit.label, fit.names
    ('fourier2', ('a0', 'a1', 'b1', 'a2', 'b2', 'w'))
    >>> round(fit.frequency, 4), round(float(fit.evaluate(0.0, derivative=2)), 4)   # w; -0.05 w^2
    (9.4248, -4.4413)
    """

    kind: str
    order: int
    coefficients: np.ndarray
    names: tuple
    gof: GoodnessOfFit
    confint: np.ndarray
    t: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)
    trend: bool = False

    @property
    def label(self) -> str:
        if self.kind == "poly":
            return f"poly{self.order}"
        return f"fourier{self.order}" + ("+trend" if self.trend else "")

    @property
    def frequency(self) -> float:
        """Fundamental angular frequency ``w`` (rad/s) of a Fourier fit."""
        if self.kind != "fourier":
            raise AttributeError("frequency: only Fourier fits have one")
        return float(self.coefficients[-2 if self.trend else -1])

    @property
    def harmonic_slice(self) -> slice:
        """Where ``a_N, b_N`` (the highest harmonic) sit in ``coefficients``."""
        return slice(2 * self.order - 1, 2 * self.order + 1)

    def evaluate(self, t, derivative: int = 0) -> np.ndarray:
        """The fitted curve or its 1st/2nd time derivative at ``t`` (section 5.5.3)."""
        t = np.asarray(t, float)
        c = self.coefficients
        if derivative not in (0, 1, 2):
            raise ValueError(f"derivative: expected 0, 1 or 2, got {derivative}")
        if self.kind == "poly":
            p = np.poly1d(c)
            return np.polyder(p, derivative)(t) if derivative else p(t)
        w = self.frequency
        out = np.full_like(t, c[0] if derivative == 0 else 0.0, dtype=float)
        if self.trend:
            out += c[-1] * t if derivative == 0 else (c[-1] if derivative == 1 else 0.0)
        for i in range(1, self.order + 1):
            a, b = c[2 * i - 1], c[2 * i]
            k = i * w
            cs, sn = np.cos(k * t), np.sin(k * t)
            if derivative == 0:
                out += a * cs + b * sn
            elif derivative == 1:
                out += k * (-a * sn + b * cs)
            else:
                out += -k * k * (a * cs + b * sn)
        return out

    def summary(self) -> str:
        """Text in the spirit of MATLAB's display of a fit and its gof."""
        lines = [f"{self.label}:"]
        for nm, c, lo, hi in zip(self.names, self.coefficients, *self.confint):
            lines.append(f"  {nm:>4} = {c: .5g}  ({lo: .5g}, {hi: .5g})")
        g = self.gof
        lines.append(f"  SSE: {g.sse:.4g}  R-square: {g.rsquare:.4f}  Adjusted R-square: "
                     f"{g.adjrsquare:.4f}  RMSE: {g.rmse:.4g}")
        return "\n".join(lines)


def _clean(t, y, name="y"):
    t = np.asarray(t, float).ravel()
    y = np.asarray(y, float).ravel()
    if t.shape != y.shape:
        raise ValueError(f"{name}: expected the same length as t ({t.size}), got {y.size}")
    ok = np.isfinite(t) & np.isfinite(y)
    return t[ok], y[ok]


def _goodness(y, resid, m):
    n = y.size
    sse = float(np.sum(resid ** 2))
    sst = float(np.sum((y - y.mean()) ** 2))
    dfe = int(n - m)
    rsq = 1 - sse / sst if sst > 0 else float("nan")
    adj = 1 - sse * (n - 1) / (sst * dfe) if (sst > 0 and dfe > 0) else float("nan")
    rmse = float(np.sqrt(sse / dfe)) if dfe > 0 else float("nan")
    return GoodnessOfFit(sse=sse, rsquare=float(rsq), dfe=dfe, adjrsquare=float(adj), rmse=rmse)


def _confint(J, coef, gof, level=0.95):
    """MATLAB ``confint``: ``b +- t * sqrt(diag(inv(J'J)) * sse/dfe)`` via QR."""
    if gof.dfe <= 0:
        return np.full((2, coef.size), np.nan)
    _, R = np.linalg.qr(J)
    try:
        Rinv = np.linalg.solve(R, np.eye(R.shape[0]))
        var = np.sum(Rinv ** 2, axis=1) * gof.sse / gof.dfe
    except np.linalg.LinAlgError:
        var = np.full(coef.size, np.inf)

    half = t_quantile((1 + level) / 2, gof.dfe) * np.sqrt(var)
    return np.vstack([coef - half, coef + half])


def fit_polynomial(t, y, degree: int = 1) -> Fit:
    """Least-squares polynomial ``p1 t^d + ... + p{d+1}`` (MATLAB ``polyd``).

    The x-motion fit of section 5.5.2.1 (degree 1: constant speed, the slope
    ``p1`` is ``V_x,avg``). NaN samples are ignored.

    Examples
    --------
    A horse at a constant 2 m/s: the slope ``p1`` is the speed.

    >>> import numpy as np
    >>> t = np.arange(10) * 0.1
    >>> fit = fit_polynomial(t, 2.0 * t + 1.0, degree=1)
    >>> fit.label, fit.coefficients.round(6).tolist()
    ('poly1', [2.0, 1.0])
    """
    t, y = _clean(t, y)
    if degree < 0:
        raise ValueError(f"degree: expected >= 0, got {degree}")
    if t.size < degree + 1:
        raise ValueError(f"y: a degree-{degree} polynomial needs {degree + 1} finite points, got {t.size}")
    J = np.vander(t, degree + 1)
    coef, *_ = np.linalg.lstsq(J, y, rcond=None)
    resid = y - J @ coef
    gof = _goodness(y, resid, degree + 1)
    names = tuple(f"p{i + 1}" for i in range(degree + 1))
    return Fit("poly", degree, coef, names, gof, _confint(J, coef, gof), t, y, resid)


def _fourier_design(t, w, order, trend=False):
    cols = [np.ones_like(t)]
    for i in range(1, order + 1):
        cols += [np.cos(i * w * t), np.sin(i * w * t)]
    if trend:
        cols.append(t)
    return np.column_stack(cols)


def _fourier_design_dw(t, w, order, trend=False):
    cols = [np.zeros_like(t)]
    for i in range(1, order + 1):
        cols += [-i * t * np.sin(i * w * t), i * t * np.cos(i * w * t)]
    if trend:
        cols.append(np.zeros_like(t))
    return np.column_stack(cols)


def fourier_start_point(t, y, order: int, trend: bool = False) -> float:
    """MATLAB's start point for ``w`` in ``fourierN`` (see notes).

    FFT of ``y - mean(y)``; ``k`` = index of the largest magnitude among the
    first ``floor(n/2)`` bins; ``wpeak = 2 pi max(0.5, k) / (t_end - t_1)``;
    try ``w = wpeak / j``, ``j = 1..N``, keep the one whose linear
    least-squares fit leaves the smallest residual. With ``trend`` the FFT
    is taken of ``y`` minus its least-squares line (not MATLAB).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(40) / 30.0                 # two periods of a 1.5 Hz stride at 30 fps
    >>> w = 2 * np.pi * 1.5
    >>> y = 0.3 + 0.05 * np.cos(w * t) + 0.02 * np.sin(2 * w * t)
    >>> round(float(fourier_start_point(t, y, order=2)), 4)      # near w = 9.4248
    9.6664
    """
    t, y = _clean(t, y)
    n = y.size
    yc = y - np.polyval(np.polyfit(t, y, 1), t) if trend else y - y.mean()
    mag = np.abs(np.fft.fft(yc))[: n // 2]
    k = int(np.argmax(mag))
    wpeak = 2 * np.pi * max(0.5, k) / (t[-1] - t[0])
    best = None
    for j in range(1, order + 1):
        w = wpeak / j
        A = _fourier_design(t, w, order, trend)
        c, *_ = np.linalg.lstsq(A, y, rcond=None)
        r = float(np.sum((y - A @ c) ** 2))
        if best is None or r < best[0]:
            best = (r, w)
    return best[1]


def fit_fourier(t, y, order: int, w0: float | None = None, start: str = "matlab",
                trend: bool = False) -> Fit:
    """Fourier series with fitted fundamental frequency (eq. 5.23), MATLAB
    ``fit(t, y, 'fourierN')``.

    ``g_F(t) = a0 + sum_{n=1..N} a_n cos(n w t) + b_n sin(n w t)``.
    The linear coefficients are eliminated (separable least squares /
    variable projection): a trust-region search over ``w`` alone minimises
    ``|y - A(w) A(w)^+ y|^2`` from the start point of
    :func:`fourier_start_point` (TolFun = TolX = 1e-6, at most 400
    iterations), with the Golub-Pereyra Jacobian of the projected residual.

    Parameters
    ----------
    t, y : (n,)
        Time (s) and data (NaN samples ignored); uniform spacing is assumed
        for the start point, as MATLAB does.
    order : int
        N >= 1 (MATLAB supports 1..8; larger values are allowed here).
    w0 : float, optional
        Override the start point.
    start : "matlab" or "all"
        ``"matlab"``: one search from the start point (MATLAB's behaviour).
        ``"all"`` (not MATLAB): a search from every candidate ``wpeak / j``,
        ``j = 1..N`` (and ``w0`` if given), keeping the smallest SSE. MATLAB's
        choice of ``j`` by the *linear* residual at the start can prefer a
        sub-multiple of the true frequency whose basin ends at a worse fit.
    trend : bool
        Add ``c t`` to eq. 5.23 (not in the thesis nor MATLAB's fourierN):
        a motion frame whose axes are off by a fraction of a degree gives the
        y and z coordinates a drift proportional to the forward speed
        (0.1 deg at 4.9 m/s: 8.5 mm/s), which a Fourier series cannot follow.
        The slope ``c`` is the last coefficient.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(40) / 30.0                 # two periods of a 1.5 Hz stride at 30 fps
    >>> w = 2 * np.pi * 1.5
    >>> y = 0.3 + 0.05 * np.cos(w * t) + 0.02 * np.sin(2 * w * t)
    >>> fit = fit_fourier(t, y, order=2)
    >>> round(fit.frequency, 6), round(float(fit.coefficients[0]), 6), round(float(fit.coefficients[4]), 6)
    (9.424778, 0.3, 0.02)
    """
    t, y = _clean(t, y)
    if order < 1:
        raise ValueError(f"order: expected a Fourier order >= 1, got {order}")
    m = 2 * order + 2 + int(trend)
    if t.size < m:
        raise ValueError(f"y: a fourier{order} fit has {m} coefficients and needs at least {m} "
                         f"finite points, got {t.size}")
    if start not in ("matlab", "all"):
        raise ValueError(f"start: expected 'matlab' or 'all', got {start!r}")
    if start == "all":
        n = y.size
        yc = y - np.polyval(np.polyfit(t, y, 1), t) if trend else y - y.mean()
        mag = np.abs(np.fft.fft(yc))[: n // 2]
        wpeak = 2 * np.pi * max(0.5, int(np.argmax(mag))) / (t[-1] - t[0])
        cands = [wpeak / j for j in range(1, order + 1)] + ([] if w0 is None else [float(w0)])
        fits = [fit_fourier(t, y, order, w0=w, trend=trend) for w in cands]
        return min(fits, key=lambda f: f.gof.sse)
    w_start = fourier_start_point(t, y, order, trend) if w0 is None else float(w0)

    def proj(w):
        A = _fourier_design(t, w, order, trend)
        U, S, Vt = np.linalg.svd(A, full_matrices=False)
        keep = S > S[0] * max(A.shape) * np.finfo(float).eps
        U, S, Vt = U[:, keep], S[keep], Vt[keep]
        c = Vt.T @ ((U.T @ y) / S)
        r = y - A @ c
        return A, U, S, Vt, c, r

    def fun(wv):
        return proj(wv[0])[5]

    def jac(wv):
        w = wv[0]
        A, U, S, Vt, c, r = proj(w)
        dA = _fourier_design_dw(t, w, order, trend)
        g = dA @ c
        term1 = g - U @ (U.T @ g)                        # P_perp dA c
        term2 = U @ ((Vt @ (dA.T @ r)) / S)              # (A^+)^T dA^T r
        return -(term1 + term2)[:, None]

    sol = optimize.least_squares(fun, [w_start], jac=jac, method="trf", ftol=1e-6, xtol=1e-6,
                                 gtol=1e-12, max_nfev=400)
    w = float(sol.x[0])
    A, _, _, _, c, r = proj(w)
    k = 2 * order + 1
    coef = np.r_[c[:k], w, c[k:]]
    J = np.column_stack([A[:, :k], _fourier_design_dw(t, w, order, trend) @ c, A[:, k:]])
    gof = _goodness(y, r, m)
    names = ("a0",) + tuple(f"{ab}{i}" for i in range(1, order + 1) for ab in "ab") + ("w",) + (("c",) if trend else ())
    return Fit("fourier", order, coef, names, gof, _confint(J, coef, gof), t, y, r, trend)


def count_extremes(y, min_prominence: float = 0.1) -> int:
    """Number of extremes E (maxima and minima) of a (smoothed) curve, the
    quantity the thesis asked the user to count (section 5.5.2.2).

    Interior turning points are counted with hysteresis (a zig-zag filter):
    a new extreme is accepted only after the curve has moved back by more
    than ``min_prominence`` times its peak-to-peak range, so ripples left by
    the smoothing are not counted. The end points are not extremes.

    Parameters
    ----------
    y : (n,)
        Smoothed data (NaN ignored).
    min_prominence : float
        Fraction of ``ptp(y)``; 0 counts every sign change of the slope.

    Examples
    --------
    >>> import numpy as np
    >>> count_extremes(np.cos(2 * np.pi * np.arange(100) / 50))   # two periods, ends excluded
    3
    """
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    if y.size < 3:
        return 0
    h = min_prominence * float(np.ptp(y))
    count, direction = 0, 0          # direction: +1 rising, -1 falling, 0 not yet known
    hi = lo = ext = y[0]
    for v in y[1:]:
        if direction == 0:
            hi, lo = max(hi, v), min(lo, v)
            if hi - lo > h:
                direction, ext = (1 if v == hi else -1), v
        elif direction == 1:
            if v > ext:
                ext = v
            elif ext - v > h:
                count, direction, ext = count + 1, -1, v
        else:
            if v < ext:
                ext = v
            elif v - ext > h:
                count, direction, ext = count + 1, 1, v
    return count


#: The automatic order rules of :func:`choose_order`.
ORDER_RULES = ("significant", "every_significant", "adjrsquare", "thesis")


def proposed_orders(n_extremes: int) -> tuple[int, int]:
    """The two Fourier orders of section 5.5.2.2: ``N = E/2`` and ``E/2 + 1``.

    A Fourier series of order N has at most 2N extremes per period of its
    fundamental, so at least ``E/2`` harmonics are needed to avoid
    under-fitting. For odd E, ``E/2`` is rounded *up* (``ceil(E/2)``; an order
    of ``floor(E/2)`` could not show E extremes); the order is at least 1.
    Returns ``(N1, N1 + 1)``; the thesis' suggested default is ``N1``.

    Examples
    --------
    >>> proposed_orders(4), proposed_orders(5)
    ((2, 3), (3, 4))
    """
    e = int(n_extremes)
    if e < 0:
        raise ValueError(f"n_extremes: expected >= 0, got {e}")
    n1 = max(1, -(-e // 2))
    return n1, n1 + 1


def choose_order(t, y, n_extremes: int | None = None, rule: str = "significant",
                 min_prominence: float = 0.1, w0: float | None = None, start: str = "matlab",
                 trend: bool = False) -> int:
    """Automatic choice between the two proposed orders (the thesis' ``fit_choice``).

    Rules
    -----
    ``"thesis"``
        Always ``N1 = E/2``, the thesis' suggested default.
    ``"adjrsquare"``
        The order with the larger adjusted R-square.
    ``"significant"`` (default)
        ``N1 + 1`` only if it has the larger adjusted R-square *and* at least
        one coefficient of its extra harmonic (``a_{N1+1}``, ``b_{N1+1}``) has
        a 95 % confidence interval excluding zero; otherwise ``N1``. This
        follows the thesis' advice to compare the numbers and the confidence
        intervals (section 5.5.1) and guards against over-fitting.
    ``"every_significant"``
        As ``"significant"``, but first the order is lowered from ``N1`` while
        its highest harmonic is not significant
        (:func:`top_harmonic_significant`), for when E counts extremes of
        noise; a lowered order is final (``N + 1`` is not tried again). It
        drops real high harmonics too, which lowers the weighted rms: not the
        default (``benchmarks/README.md`` has its errors on the herd).

    Parameters
    ----------
    t, y : (n,)
    n_extremes : int, optional
        E; counted with :func:`count_extremes` if omitted.
    w0, start, trend
        Passed to :func:`fit_fourier` (default: MATLAB's start rule, no trend).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(40) / 30.0                 # two periods of a 1.5 Hz stride at 30 fps
    >>> w = 2 * np.pi * 1.5
    >>> y = 0.3 + 0.05 * np.cos(w * t) + 0.02 * np.sin(2 * w * t)
    >>> choose_order(t, y), choose_order(t, y, rule="thesis")
    (2, 2)
    """
    if n_extremes is None:
        yy = np.asarray(y, float)
        if trend:
            ok = np.isfinite(yy)
            yy = yy[ok] - np.polyval(np.polyfit(np.asarray(t, float)[ok], yy[ok], 1), np.asarray(t, float)[ok])
        n_extremes = count_extremes(yy, min_prominence)
    n1, n2 = proposed_orders(n_extremes)
    if rule == "thesis":
        return n1
    if rule not in ORDER_RULES:
        raise ValueError(f"rule: expected one of {', '.join(map(repr, ORDER_RULES))}, got {rule!r}")
    f1 = fit_fourier(t, y, n1, w0=w0, start=start, trend=trend)
    if rule == "every_significant":
        lowered = False
        while f1.order > 1 and not top_harmonic_significant(f1):
            f1, lowered = fit_fourier(t, y, f1.order - 1, w0=w0, start=start, trend=trend), True
        if lowered:
            return f1.order
    f2 = fit_fourier(t, y, n2, w0=w0, start=start, trend=trend)
    better = f2.gof.adjrsquare > f1.gof.adjrsquare
    if rule == "adjrsquare":
        return n2 if better else n1
    return n2 if (better and top_harmonic_significant(f2)) else n1


def top_harmonic_significant(fit) -> bool:
    """Whether a Fourier fit's highest harmonic is there: ``a_N`` or ``b_N`` has a
    95 % confidence interval (MATLAB's ``confint``) that excludes zero.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(40) / 30.0                 # two periods of a 1.5 Hz stride at 30 fps
    >>> w = 2 * np.pi * 1.5
    >>> y = 0.3 + 0.05 * np.cos(w * t) + 0.02 * np.sin(2 * w * t)
    >>> top_harmonic_significant(fit_fourier(t, y, order=2))
    True
    """
    lo, hi = fit.confint[:, fit.harmonic_slice]
    return bool(np.any((lo > 0) | (hi < 0)))


@dataclass(frozen=True)
class MotionFit:
    """Fits of every marker and axis (section 5.5.2): ``fits[m][axis]``.

    Attributes
    ----------
    fits : tuple of tuples of Fit
        ``fits[m][0]`` polynomial (x), ``fits[m][1]``, ``fits[m][2]`` Fourier (y, z).
    orders : (m, 3) int
        Degree of the x fit, Fourier orders of y and z.
    n_extremes : (m, 3) int
        E counted for y and z (-1 for x, and where the orders were given).

    Examples
    --------
    See :func:`fit_motion`.
    """

    fits: tuple
    orders: np.ndarray
    n_extremes: np.ndarray

    def _eval(self, t, d):
        t = np.asarray(t, float)
        return np.stack([np.stack([f.evaluate(t, d) for f in fm], -1) for fm in self.fits], 1)

    def position(self, t) -> np.ndarray:
        """Fitted positions (n, m, 3) (not used downstream: the registered
        positions are kept, section 5.5.2)."""
        return self._eval(t, 0)

    def velocity(self, t) -> np.ndarray:
        """``V^m(t)`` (n, m, 3), analytic derivative of the fits (section 5.5.3)."""
        return self._eval(t, 1)

    def acceleration(self, t) -> np.ndarray:
        """``A^m(t)`` (n, m, 3), analytic second derivative (section 5.5.3)."""
        return self._eval(t, 2)


def fit_motion(t, positions, x_degree: int = 1, orders=None, rule: str = "significant",
               min_prominence: float = 0.1, w0: float | None = None, start: str = "matlab",
               trend: bool = False) -> MotionFit:
    """Fit every marker's registered motion-frame coordinates (section 5.5.2).

    Parameters
    ----------
    t : (n,)
        Time (s), eq. 5.13.
    positions : (n, m, 3)
        Registered positions in the motion frame (``MM^r``).
    x_degree : int
        Degree of the x-motion polynomial (``fit_type_x``, default poly1).
    orders : None, int, or array (m, 2)
        Fourier orders for (y, z) of each marker; ``None``: count E on the data
        and use :func:`choose_order` with ``rule``.
    rule, min_prominence
        See :func:`choose_order` and :func:`count_extremes`.
    w0 : float, optional
        Start point of every Fourier fit's ``w`` (rad/s), e.g. ``2 pi / T``
        from the period T entered in the thesis (section 8.4.1,
        ``period = 18``) or estimated by :mod:`horsemocap.frames`. Default:
        MATLAB's spectral start point, which on a record of about two
        periods may settle on half the stride frequency (then an order-N
        series holds only N/2 stride harmonics).
    start, trend
        See :func:`fit_fourier`.

    Examples
    --------
    One marker moving forward at 5 m/s, bouncing and swaying at 1.5 Hz:

    >>> import numpy as np
    >>> t = np.arange(90) / 30.0
    >>> w = 2 * np.pi * 1.5
    >>> positions = np.zeros((90, 1, 3))
    >>> positions[:, 0, 0] = 5.0 * t
    >>> positions[:, 0, 1] = 0.3 + 0.05 * np.cos(w * t) + 0.02 * np.sin(2 * w * t)
    >>> positions[:, 0, 2] = 0.1 * np.sin(w * t)
    >>> motion = fit_motion(t, positions, orders=[2, 1], w0=w)
    >>> motion.orders.tolist()
    [[1, 2, 1]]
    >>> motion.velocity([0.0])[0, 0].round(4).tolist()            # vx, vy, vz at t = 0 (vz = 0.1 w)
    [5.0, 0.377, 0.9425]
    """
    p = np.asarray(positions, float)
    if p.ndim != 3 or p.shape[2] != 3:
        raise ValueError(f"positions: expected (frames, markers, 3), got shape {p.shape}")
    t = np.asarray(t, float)
    if t.shape != (p.shape[0],):
        raise ValueError(f"t: expected {p.shape[0]} times, got shape {t.shape}")
    m = p.shape[1]
    if orders is not None:
        o = np.asarray(orders, int)
        o = np.broadcast_to(o, (m, 2)) if o.ndim < 2 else o
        if o.shape != (m, 2):
            raise ValueError(f"orders: expected an int or shape ({m}, 2), got {o.shape}")
    fits, used, ext = [], np.zeros((m, 3), int), np.full((m, 3), -1)
    for j in range(m):
        fj = [fit_polynomial(t, p[:, j, 0], x_degree)]
        used[j, 0] = x_degree
        for ax in (1, 2):
            if orders is None:
                y = p[:, j, ax]
                ok = np.isfinite(y)
                yy = y[ok] - np.polyval(np.polyfit(t[ok], y[ok], 1), t[ok]) if trend else y
                e = count_extremes(yy, min_prominence)
                ext[j, ax] = e
                n = choose_order(t, y, e, rule=rule, w0=w0, start=start, trend=trend)
            else:
                n = int(o[j, ax - 1])
            fj.append(fit_fourier(t, p[:, j, ax], n, w0=w0, start=start, trend=trend))
            used[j, ax] = n
        fits.append(tuple(fj))
    return MotionFit(tuple(fits), used, ext)
