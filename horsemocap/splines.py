"""Smoothing splines whose smoothing is chosen from the data (not in the thesis).

Used by :mod:`horsemocap.pose` for the pose trajectory. Two kinds:

- ``order=5`` (default): a quintic smoothing spline minimising
  ``sum w_i (y_i - f(t_i))^2 + lam * integral f'''(t)^2 dt`` (Woltring 1986,
  GCVSPL with ``m = 3``, the usual choice in biomechanics for
  accelerations). Its natural boundary conditions make the 3rd and 4th
  derivatives vanish at the record's ends, so the *acceleration* is free
  there. Built on SciPy's B-splines (:class:`scipy.interpolate.BSpline`,
  its design matrix and derivatives); the smoothing parameter ``lam``
  minimises the generalised cross-validation score
  ``GCV(lam) = n RSS_w / (n - tr H)^2`` (Craven and Wahba 1979), computed
  for every ``lam`` from one eigen-decomposition (Demmler-Reinsch basis).
  Long records use a knot at every k-th sample (at most
  :data:`MAX_BASIS` basis functions: a penalised regression spline).
- ``order=3``: SciPy's :func:`scipy.interpolate.make_smoothing_spline`
  (cubic, penalty on ``f''``, GCV), whose natural boundary conditions force
  the acceleration to zero at both ends of the record.

``method="none"`` interpolates (no smoothing; ``lam = 0``).

With ``fundamental_hz`` the quintic spline becomes a *partial spline* (Wahba 1990,
"Spline models for observational data", ch. 6): ``f = h + s`` with ``h`` the first K harmonics
of the fundamental, unpenalised, and the penalty on the remainder ``s`` only. A periodic motion
(a steady gait) then keeps its harmonics whole (a plain smoothing spline flattens the higher
ones) and the natural boundary conditions act only on the small non-periodic remainder. K = 0
(a plain spline) is always a candidate: K and ``lam`` minimise the same criterion, so a record
that is not periodic keeps the plain spline. :func:`estimate_fundamental` finds the fundamental
from the record. With a noise level known (``harmonic_noise``) only the harmonics larger than
that noise are candidates: a periodic error of the measurement is not told from motion by the
data alone.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache
from math import factorial

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline, make_smoothing_spline
from scipy.linalg import solve_triangular, svd as _lapack_svd
from scipy.optimize import minimize_scalar

from .aperture import Aperture
from .iir_filters import ar1_filter

__all__ = ["SmoothingSpline", "BlendedSpline", "blend_splines", "robust_svd", "ChangePointError", "HarmonicTerms", "EventTerms", "truncated_power_columns",
           "smoothing_spline", "harmonic_columns", "harmonic_amplitudes",
           "estimate_fundamental", "robust_weighted_spline", "residual_log_likelihood", "half_gain_frequency",
           "common_smoothing", "MAX_BASIS", "FULL_BASIS_SAMPLES", "knot_step"]

HUBER_K = 1.345
"""Huber's tuning constant (in robust standard deviations) of :func:`robust_weighted_spline`: 95 %
efficiency at normal errors (Huber 1981, "Robust statistics", sec. 4.6)."""

MAX_BASIS = 400
"""Largest number of B-spline basis functions of a quintic smoothing spline."""

CACHE_SAMPLES = 1600
"""Records of at most this many samples keep their spline basis cached (:func:`_basis`,
:func:`_gcv_basis`; four records each, about 57 MB at most together); a longer record recomputes
it. The caches are keyed by the times (and weights) alone: :data:`MAX_BASIS` is read when a basis
is first built, so changing it takes effect for records not yet cached."""

MAX_GRID = 4000
"""Most trial frequencies of :func:`estimate_fundamental` on a grid; longer records use the
periodogram's peaks."""

GCV_GAMMA = 1.4
"""Cost of a degree of freedom in the GCV score ``n RSS / (n - gamma tr H)^2``: 1.4, the
value Kim and Gu (2004, J. R. Statist. Soc. B 66, 337-356) recommend against GCV's known
tendency to undersmooth (with plain GCV, 1.0, the roll of a short record can be left almost
unsmoothed)."""


class ChangePointError(ValueError):
    """Change points (``events``) a spline cannot fit: outside the record, unresolved by the samples, or
    with a smoothing that has no change points."""


@dataclass(frozen=True)
class SmoothingSpline:
    """A fitted smoothing spline: call ``s(t, derivative)``.

    Attributes
    ----------
    spline : scipy.interpolate.BSpline
    info : dict
        ``lam`` (the smoothing parameter), ``edf`` (effective degrees of
        freedom, trace of the hat matrix), ``rms_residual`` (data units),
        ``n`` (samples), ``order``, ``method``.
    aperture : horsemocap.aperture.Aperture or None
        The samples' temporal aperture the spline was fitted through
        (``aperture`` of :func:`smoothing_spline`): the spline is the motion,
        :meth:`observed` what a sample saw of it.
    """

    spline: BSpline
    info: dict
    harmonics: "HarmonicTerms | None" = None
    events: "EventTerms | None" = None
    aperture: "Aperture | None" = None

    def __call__(self, t, derivative: int = 0) -> np.ndarray:
        t = np.asarray(t, float)
        out = self.spline(t) if derivative == 0 else self.spline.derivative(derivative)(t)
        if self.harmonics is not None:
            out = out + self.harmonics(t, derivative)
        if self.events is not None:
            out = out + self.events(t, derivative)
        return out

    def observed(self, t) -> np.ndarray:
        """What a sample at each ``t`` observed of the spline: the spline averaged over the samples'
        aperture, or the spline itself without one (the fitted values its residuals are taken from).

        Examples
        --------
        A spline fitted through a 20 ms exposure: its observed values are the data it was fitted to
        (exact data, a light smoothing), its values at the instants are the motion itself.

        >>> import numpy as np
        >>> from horsemocap.aperture import box_aperture
        >>> t = np.arange(50) / 25.0
        >>> a = box_aperture(0.02)
        >>> y = a.average(lambda u: np.sin(2 * np.pi * 3.0 * u), t)
        >>> s = smoothing_spline(t, y, lam=1e-14, aperture=a)
        >>> bool(np.allclose(s.observed(t), y, atol=1e-5)), bool(np.allclose(s(t), y, atol=1e-3))
        (True, False)
        >>> bool(np.allclose(s(t)[5:-5], np.sin(2 * np.pi * 3.0 * t[5:-5]), atol=1e-4))
        True
        """
        return self(t) if self.aperture is None else self.aperture.average(self, t)


@dataclass(frozen=True)
class BlendedSpline:
    """A weighted sum of fitted splines of the same samples: call ``s(t, derivative)``.

    Two linear smoothers of the same data blended with weights that sum to
    one are again a linear smoother of that data: its values, derivatives
    and observed values are the weighted sums of the parts', and its
    effective degrees of freedom (the trace of its hat matrix) the weighted
    sum of theirs. Made by :func:`blend_splines`.

    Attributes
    ----------
    parts : tuple of splines
        The blended fits (:class:`SmoothingSpline` or anything with ``__call__(t, derivative)``,
        ``observed(t)`` and ``info``).
    weights : tuple of float
        Each part's weight, in [0, 1], summing to one.
    info : dict
        ``method`` ``"blend"``, ``lam`` None (each part has its own: ``parts[k].info["lam"]``),
        ``edf`` (the weighted sum of the parts'), ``blend_weights``, ``n`` and ``order`` (the parts'
        when they agree).
    """

    parts: tuple
    weights: tuple
    info: dict

    def __call__(self, t, derivative: int = 0) -> np.ndarray:
        return sum(w * s(t, derivative) for w, s in zip(self.weights, self.parts))

    def observed(self, t) -> np.ndarray:
        """What a sample at each ``t`` observed of the blend: the weighted sum of the parts' observed values."""
        return sum(w * s.observed(t) for w, s in zip(self.weights, self.parts))


def blend_splines(first, second, weight: float) -> BlendedSpline:
    """``weight * second + (1 - weight) * first``: two fits of the same samples blended (:class:`BlendedSpline`).

    Parameters
    ----------
    first, second : SmoothingSpline
        Fits of the same samples (e.g. a plain smoothing spline and a partial spline with harmonics).
    weight : float
        The second fit's weight, in [0, 1].

    Returns
    -------
    BlendedSpline

    Raises
    ------
    ValueError
        A weight outside [0, 1] or not finite.

    Examples
    --------
    A straight line and a parabola fitted to the same samples, blended one quarter to three quarters:

    >>> import numpy as np
    >>> t = np.linspace(0.0, 1.0, 21)
    >>> line = smoothing_spline(t, 2 * t, lam=1e-3)
    >>> parabola = smoothing_spline(t, t ** 2, lam=1e-12)
    >>> b = blend_splines(line, parabola, 0.75)
    >>> round(float(b(0.5)), 6), round(float(b(0.5, 2)), 4), b.info["blend_weights"]
    (0.4375, 1.5, [0.25, 0.75])
    >>> bool(np.isclose(b.info["edf"], 0.25 * line.info["edf"] + 0.75 * parabola.info["edf"]))
    True
    """
    w = float(weight)
    if not (np.isfinite(w) and 0.0 <= w <= 1.0):
        raise ValueError(f"weight: expected the second fit's weight in [0, 1], got {weight!r}")
    weights = (1.0 - w, w)
    infos = (first.info, second.info)
    info = {"method": "blend", "lam": None, "edf": float(sum(v * i["edf"] for v, i in zip(weights, infos))),
            "blend_weights": [float(v) for v in weights]}
    for key in ("n", "order"):
        if infos[0].get(key) is not None and infos[0].get(key) == infos[1].get(key):
            info[key] = infos[0][key]
    return BlendedSpline((first, second), weights, info)


@dataclass(frozen=True)
class EventTerms:
    """``e(t) = sum_j b_j (t - tau_j)_+^k``: the unpenalised change-point part of a partial spline
    (:func:`smoothing_spline` with ``events``); with ``k = 2`` a jump ``2 b_j`` of the acceleration
    at each ``tau_j``.

    Attributes
    ----------
    times : (J,)
        The events ``tau_j`` (s).
    coef : (J,)
        ``b_j``.
    degree : int
        ``k``.
    """

    times: np.ndarray
    coef: np.ndarray
    degree: int = 2

    def __call__(self, t, derivative: int = 0) -> np.ndarray:
        t = np.asarray(t, float)
        cols = truncated_power_columns(t.ravel(), self.times, self.degree, derivative)
        return (cols @ np.asarray(self.coef, float)).reshape(t.shape)


def truncated_power_columns(t, times, degree: int = 2, derivative: int = 0) -> np.ndarray:
    """``(t - tau_j)_+^degree`` for each ``tau_j`` in ``times`` (n, J), or their ``derivative``-th
    derivatives (``degree! / (degree - d)! (t - tau)_+^(degree - d)``; the ``degree``-th is a step,
    higher ones zero away from ``tau``)."""
    t = np.asarray(t, float)
    times = np.atleast_1d(np.asarray(times, float))
    if derivative > degree:
        return np.zeros((t.size, times.size))
    u = t[:, None] - times[None]
    scale = factorial(degree) / factorial(degree - derivative)
    if derivative == degree:
        return scale * (u > 0).astype(float)
    return scale * np.clip(u, 0, None) ** (degree - derivative)


@dataclass(frozen=True)
class HarmonicTerms:
    """``h(t) = sum_k a_k cos(2 pi k f (t - t0)) + b_k sin(2 pi k f (t - t0))``, k = 1..K.

    The unpenalised periodic part of a partial smoothing spline
    (:func:`smoothing_spline` with ``fundamental_hz``).

    Attributes
    ----------
    frequency_hz : float
        The fundamental ``f``.
    cos, sin : (K,)
        ``a_k``, ``b_k``.
    t0 : float
        Time origin.
    """

    frequency_hz: float
    cos: np.ndarray
    sin: np.ndarray
    t0: float = 0.0

    def __call__(self, t, derivative: int = 0) -> np.ndarray:
        t = np.asarray(t, float)
        cols = harmonic_columns(t.ravel(), self.frequency_hz, len(self.cos), self.t0, derivative)
        return (cols @ np.r_[self.cos, self.sin]).reshape(t.shape)


def _penalty(knots, k, m, weight=None):
    """``P_ij = integral v(t) B_i^(m) B_j^(m)`` for B-splines of degree k (Gauss-Legendre;
    exact for ``v = 1``); ``weight`` is ``v`` as a function of t (default 1)."""
    nb = len(knots) - k - 1
    xs = np.unique(knots)
    g, gw = np.polynomial.legendre.leggauss(k - m + 1)
    a, b = xs[:-1], xs[1:]
    pts = (0.5 * (b - a)[:, None] * (g[None] + 1) + a[:, None]).ravel()
    wts = (0.5 * (b - a)[:, None] * gw[None]).ravel()
    D = np.zeros((pts.size, nb))
    for j in range(nb):
        c = np.zeros(nb)
        c[j] = 1.0
        D[:, j] = BSpline(knots, c, k, extrapolate=False).derivative(m)(pts)
    D = np.nan_to_num(D)
    if weight is not None:
        wts = wts * weight(pts)
    return D.T @ (wts[:, None] * D)


def _basis(x_bytes: bytes, m: int, aperture=None):
    """:func:`_basis_of`, cached for records of at most :data:`CACHE_SAMPLES` samples."""
    if len(x_bytes) <= 8 * CACHE_SAMPLES:
        return _basis_cached(x_bytes, m, aperture)
    return _basis_of(x_bytes, m, aperture)


def _gcv_basis(x_bytes: bytes, w_bytes: bytes, m: int, aperture=None):
    """:func:`_gcv_basis_of`, cached for records of at most :data:`CACHE_SAMPLES` samples."""
    if len(x_bytes) <= 8 * CACHE_SAMPLES:
        return _gcv_basis_cached(x_bytes, w_bytes, m, aperture)
    return _gcv_basis_of(x_bytes, w_bytes, m, aperture)


def _design_matrix(x, knots, k: int, aperture=None) -> np.ndarray:
    """The B-spline basis at the samples ``x`` (n, p); with an ``aperture``
    (:class:`horsemocap.aperture.Aperture`) each sample's row is the basis averaged over its aperture, as the
    sample observed it (the end pieces' polynomials continued beyond the record)."""
    if aperture is None:
        return BSpline.design_matrix(x, knots, k).toarray()
    return aperture.average(lambda u: BSpline.design_matrix(u, knots, k, extrapolate=True).toarray(), x)


def _basis_of(x_bytes: bytes, m: int, aperture=None):
    """Knots, design matrix, penalty and the penalty's eigen-decomposition of the samples' times
    (``x_bytes``: the float64 bytes of x). A pure function of the times, cached: the six pose
    components and the re-smoothings of one trajectory share their times (the penalty's quadrature
    and its decomposition were half of the pose fit's time). The arrays are read-only. With an ``aperture``
    the design matrix is the basis each sample observed (:func:`_design_matrix`)."""
    x = np.frombuffer(x_bytes, float)
    k = 2 * m - 1
    knots = _knots(x, m)          # at most n basis functions: B^T W B is non-singular
    B = _design_matrix(x, knots, k, aperture)
    P = _penalty(knots, k, m)
    d, U = np.linalg.eigh((P + P.T) / 2)
    for a in (knots, B, P, d, U):
        a.flags.writeable = False
    return knots, B, P, d, U


def _gcv_basis_of(x_bytes: bytes, w_bytes: bytes, m: int, aperture=None):
    """Demmler-Reinsch basis of the quintic smoothing spline with a uniform penalty (``T``, ``d``, ``Z``
    of :func:`_quintic_gcv`), a pure function of the times and weights, cached like :func:`_basis`."""
    knots, B, P, _, _ = _basis(x_bytes, m, aperture)
    out = _demmler_reinsch(B, P, np.frombuffer(w_bytes, float))
    for a in out:
        a.flags.writeable = False
    return out


_basis_cached = lru_cache(maxsize=4)(_basis_of)
_gcv_basis_cached = lru_cache(maxsize=4)(_gcv_basis_of)


def _demmler_reinsch(B, P, w):
    """``T, d, Z``: ``c = T (z / (1 + lam d))`` are the coefficients, ``Z (z / (1 + lam d))`` the
    weighted fitted values, ``z = Z^T (sqrt(w) y)``."""
    sw = np.sqrt(w)
    Bw = B * sw[:, None]
    G = Bw.T @ Bw
    scale = np.trace(G) / G.shape[0]
    G += 1e-13 * scale * np.eye(G.shape[0])
    L = np.linalg.cholesky(G)
    Li = np.linalg.solve(L, np.eye(L.shape[0]))
    Pt = Li @ P @ Li.T
    d, U = np.linalg.eigh((Pt + Pt.T) / 2)
    d = np.clip(d, 0, None)
    T = Li.T @ U
    return T, d, Bw @ T


def ar1_correlation_times(Z, rho: float) -> np.ndarray:
    """``C Z`` for the AR(1) correlation matrix ``C_ij = rho^|i - j|`` (n, p), in O(n p).

    ``C z = f + b - z`` with the forward ``f_i = z_i + rho f_(i-1)`` and the
    backward ``b_i = z_i + rho b_(i+1)`` recursions.

    Examples
    --------
    >>> import numpy as np
    >>> C = 0.5 ** np.abs(np.subtract.outer(np.arange(4), np.arange(4)))
    >>> z = np.arange(4.0)[:, None]
    >>> bool(np.allclose(ar1_correlation_times(z, 0.5), C @ z))
    True
    """
    Z = np.asarray(Z, float)
    forward = ar1_filter(Z, rho)
    backward = ar1_filter(Z[::-1], rho)[::-1]
    return forward + backward - Z


#: The AR(1) correlations :func:`reml_ar1_smoothing` profiles over when none are given.
REML_AR1_CORRELATIONS = np.r_[0.0, np.arange(0.1, 0.96, 0.05), 0.98]


def _ar1_whiten(A, rho: float) -> np.ndarray:
    """``A`` (n, ...) decorrelated along axis 0 for unit-variance AR(1) noise of lag-1 correlation ``rho``
    (Prais-Winsten: the first row kept, then ``(a_k - rho a_(k-1)) / sqrt(1 - rho^2)``)."""
    A = np.asarray(A, float)
    out = np.empty_like(A)
    out[0] = A[0]
    out[1:] = (A[1:] - rho * A[:-1]) / np.sqrt(1 - rho * rho)
    return out


def reml_ar1_smoothing(t, y, correlations=None, m: int = 3) -> dict:
    """The quintic smoothing spline's ``lam`` and the noise's AR(1) correlation by restricted maximum likelihood.

    The spline in mixed-model form, ``y = X b + Z u + e`` (``X`` the penalty's null space, the
    polynomials of degree < m; ``Z`` the penalised part with ``u ~ N(0, sigma^2 / lam I)``) with an
    AR(1) noise ``e ~ N(0, sigma^2 C)``, ``C_ij = rho^|i - j|`` (Krivobokova and Kauermann 2007 show
    the likelihood choice far less misled by correlated errors than GCV). For each ``rho`` the data are
    decorrelated (Prais-Winsten), the unpenalised columns projected out and the restricted
    log-likelihood, with ``sigma^2`` profiled, minimised over ``lam``::

        -2 l_R = (n - m) log(q(lam) / (n - m)) + sum_j log(1 + s_j^2 / lam) + log|C| + log|X~^T X~|

    with ``s_j`` the singular values of the projected, decorrelated ``Z`` and ``q`` the quadratic
    form ``rss0 + sum_j z_j^2 lam / (s_j^2 + lam)``. The best ``(lam, rho)`` over ``correlations`` is
    returned; ``lam`` is that of :func:`smoothing_spline` (``lam=`` gives the ordinary spline with it).
    Dense: O(n^3) per correlation.

    Parameters
    ----------
    t, y : (n,)
        Increasing times and finite samples.
    correlations : sequence of float in [0, 1), optional
        The AR(1) correlations profiled (one value: the correlation given). Default
        :data:`REML_AR1_CORRELATIONS`.

    Returns
    -------
    dict
        ``lam``, ``noise_correlation`` and ``score`` (``-2 l_R`` up to a constant).

    Examples
    --------
    A sine under AR(1) noise of correlation 0.8: the correlation is recovered with the smoothing.

    >>> import numpy as np
    >>> t = np.arange(400) / 100.0
    >>> e = ar1_filter(np.random.default_rng(0).normal(0, 0.006, t.size), 0.8)
    >>> out = reml_ar1_smoothing(t, np.sin(2 * np.pi * 0.5 * t) + e)
    >>> round(out["noise_correlation"], 1)
    0.8
    """
    x = np.ascontiguousarray(t, float)
    y = np.asarray(y, float)
    if x.shape != y.shape or x.ndim != 1 or not np.all(np.isfinite(y)) or np.any(np.diff(x) <= 0):
        raise ValueError(f"t, y: expected increasing times and finite samples of one shape, got {x.shape}, {y.shape}")
    rhos = REML_AR1_CORRELATIONS if correlations is None else np.atleast_1d(np.asarray(correlations, float))
    if np.any((rhos < 0) | (rhos >= 1)):
        raise ValueError(f"correlations: expected values in [0, 1), got {rhos}")
    n = x.size
    _, B, _, d, U = _basis(x.tobytes(), m)
    X = B @ U[:, :m]
    Z = (B @ U[:, m:]) / np.sqrt(np.clip(d[m:], 1e-14 * d[-1], None))[None]
    best = None
    for rho in rhos:
        Xw, Zw, yw = _ar1_whiten(X, rho), _ar1_whiten(Z, rho), _ar1_whiten(y, rho)
        Q1, Rx = np.linalg.qr(Xw)
        M = Zw - Q1 @ (Q1.T @ Zw)
        r = yw - Q1 @ (Q1.T @ yw)
        Uu, s, _ = robust_svd(M)
        keep = s > 1e-10 * s.max()
        z = Uu[:, keep].T @ r
        s2 = s[keep] ** 2
        rss0 = max(float(r @ r - z @ z), 0.0)
        const = (n - 1) * np.log(1 - rho * rho) + 2 * float(np.sum(np.log(np.abs(np.diag(Rx)))))

        def score(loglam, s2=s2, z=z, rss0=rss0, const=const):
            lam = 10.0 ** loglam
            quad = rss0 + float(np.sum(z * z * lam / (s2 + lam)))
            return (n - m) * np.log(max(quad, 1e-300) / (n - m)) + float(np.sum(np.log1p(s2 / lam))) + const

        pos = s2[s2 > 1e-12 * s2.max()]
        lam, sc = _choose_lam(score, np.log10(pos.min()) - 2, np.log10(pos.max()) + 2)
        if best is None or sc < best["score"]:
            best = {"lam": float(lam), "noise_correlation": round(float(rho), 6), "score": float(sc)}
    return best


def _quintic_gcv(x, y, w, lam, weight=None, noise=None, m=3, gamma=None, correlation=None, aperture=None):
    """The quintic smoothing spline with ``lam`` chosen by GCV (``noise``: unbiased risk; ``correlation``:
    the AR(1) coefficient of the noise, GCV with ``tr(H C)`` for ``tr(H)``, Opsomer, Wang and Yang 2001; with
    both, the unbiased risk with ``tr(H C)``)."""
    n = x.size
    k = 2 * m - 1
    gamma = GCV_GAMMA if gamma is None else gamma
    x = np.ascontiguousarray(x, float)
    w = np.ascontiguousarray(w, float)
    if weight is None:
        knots = _basis(x.tobytes(), m, aperture)[0]
        T, d, Z = _gcv_basis(x.tobytes(), w.tobytes(), m, aperture)
    else:
        knots, B = _basis(x.tobytes(), m, aperture)[:2]
        T, d, Z = _demmler_reinsch(B, _penalty(knots, k, m, weight), w)
    sw = np.sqrt(w)
    z = Z.T @ (sw * y)
    yw = sw * y

    def fit(lmb):
        f = z / (1 + lmb * d)
        r = yw - Z @ f
        return f, float(r @ r), float(np.sum(1 / (1 + lmb * d)))

    def gcv(loglam):
        _, rss, tr = fit(10.0 ** loglam)
        return n * rss / max(n - gamma * tr, 1e-9) ** 2

    if correlation is not None and correlation != 0:
        # tr(H C) = sum_k (z_k^T C z_k) / (1 + lam d_k) with H = Z diag(1 / (1 + lam d)) Z^T
        q = np.einsum("ij,ij->j", Z, ar1_correlation_times(Z, float(correlation)))

        def gcv(loglam):  # noqa: F811  (correlated-error GCV)
            lmb = 10.0 ** loglam
            _, rss, _ = fit(lmb)
            return n * rss / max(n - gamma * float(np.sum(q / (1 + lmb * d))), 1e-9) ** 2

    if noise is not None:
        # unbiased risk with the noise known: Mallows' C_p / UBRE; with ``correlation`` its covariance is
        # noise^2 C and the penalty on the fit's freedom is tr(H C) (the correlated-error C_p)
        q = None if not correlation else np.einsum("ij,ij->j", Z, ar1_correlation_times(Z, float(correlation)))

        def gcv(loglam):  # noqa: F811
            lmb = 10.0 ** loglam
            _, rss, tr = fit(lmb)
            return rss / n + 2 * noise ** 2 * (tr if q is None else float(np.sum(q / (1 + lmb * d)))) / n

    if lam is None:
        # the scale of lam: penalty eigenvalues span many decades; search the range they give
        pos = d[d > 1e-12 * max(d.max(), 1e-300)]
        lam, _ = _choose_lam(gcv, -np.log10(pos.max()) - 2, -np.log10(pos.min()) + 2)
    f, rss, tr = fit(lam)
    spline = BSpline(knots, T @ f, k)
    info = {"lam": float(lam), "edf": tr, "rms_residual": float(np.sqrt(rss / w.sum())),
            "n": n, "order": k, "method": "gcv" if noise is None else "noise",
            "noise": float("nan") if noise is None else float(noise)}
    if correlation is not None:
        info["noise_correlation"] = float(correlation)
    return spline, info


def common_smoothing(t, Y, scales=None, noise_correlation: float | None = None, m: int = 3) -> dict:
    """One smoothing parameter for several series sampled at the same times: pooled GCV.

    The quintic smoothing spline's filter depends on ``lam`` alone, not on the
    series' units (:func:`half_gain_frequency`), so one ``lam`` smooths every
    column of ``Y`` to the same bandwidth, as for the six components of a rigid
    body's pose: a point of the body then follows one filter of its measured
    path, and no component's lighter smoothing sets its acceleration's noise.
    ``lam`` minimises the GCV score pooled over the columns, each divided by
    its scale (its noise, so that each counts in units of its own noise),
    ``n sum_j |(I - H) y_j / s_j|^2 / (n - gamma tr(H C))^2``, with ``C`` the
    AR(1) correlation of ``noise_correlation`` (the identity without it: plain
    GCV) and ``gamma`` the GCV inflation of :func:`smoothing_spline`.

    Parameters
    ----------
    t : (n,)
        Increasing times.
    Y : (n, p)
        Finite samples, one series per column.
    scales : (p,), optional
        Positive scale of each column (default 1).
    noise_correlation : float, optional
        AR(1) lag-1 correlation of the noise, in (-1, 1).

    Returns
    -------
    dict
        ``lam``, ``edf`` (the fit's effective degrees of freedom) and ``half_gain_hz``.

    Examples
    --------
    Two noisy sines at 1 Hz, one in millimetres and one in metres: one smoothing for both.

    >>> import numpy as np
    >>> t = np.arange(400) / 100.0
    >>> rng = np.random.default_rng(0)
    >>> Y = np.column_stack([1000 * np.sin(2 * np.pi * t), np.cos(2 * np.pi * t)])
    >>> Y += rng.normal(0, 1, (400, 2)) * [10, 0.01]
    >>> out = common_smoothing(t, Y, scales=[10, 0.01])
    >>> bool(2.0 < out["half_gain_hz"] < 10.0)
    True
    """
    x = np.ascontiguousarray(t, float)
    Y = np.asarray(Y, float)
    n = x.size
    if Y.ndim != 2 or Y.shape[0] != n or not np.all(np.isfinite(Y)):
        raise ValueError(f"Y: expected finite samples of shape ({n}, p), got {Y.shape}")
    sc = np.ones(Y.shape[1]) if scales is None else np.asarray(scales, float)
    if sc.shape != (Y.shape[1],) or not np.all(sc > 0):
        raise ValueError(f"scales: expected {Y.shape[1]} positive scales, got {scales!r}")
    _, d, Z = _gcv_basis(x.tobytes(), np.ones(n).tobytes(), m)
    Ys = Y / sc
    z = Z.T @ Ys
    outside = float(np.sum(Ys * Ys) - np.sum(z * z))           # the part of the data no spline fits
    z2 = np.sum(z * z, axis=1)
    q = (np.ones(d.size) if not noise_correlation else
         np.einsum("ij,ij->j", Z, ar1_correlation_times(Z, float(noise_correlation))))

    def score(loglam):
        g = 1 / (1 + 10.0 ** loglam * d)
        rss = outside + float(np.sum((1 - g) ** 2 * z2))
        return n * rss / max(n - GCV_GAMMA * float(np.sum(q * g)), 1e-9) ** 2

    pos = d[d > 1e-12 * max(d.max(), 1e-300)]
    lam, _ = _choose_lam(score, -np.log10(pos.max()) - 2, -np.log10(pos.min()) + 2)
    return {"lam": lam, "edf": float(np.sum(1 / (1 + lam * d))),
            "half_gain_hz": half_gain_frequency(lam, float(np.median(np.diff(x))))}


def harmonic_columns(t, frequency_hz: float, order: int, t0: float = 0.0, derivative: int = 0) -> np.ndarray:
    """``[cos(2 pi k f (t - t0)) ..., sin(2 pi k f (t - t0)) ...]`` for k = 1..order, (n, 2 order),
    or their ``derivative``-th derivatives (``d^j/dt^j cos(w t) = w^j cos(w t + j pi/2)``, sin alike)."""
    t = np.asarray(t, float)
    k = np.arange(1, order + 1)
    w = 2 * np.pi * frequency_hz * k
    arg = (t[:, None] - t0) * w[None] + derivative * np.pi / 2
    s = w[None] ** derivative
    return np.hstack([s * np.cos(arg), s * np.sin(arg)])


def _harmonic_subset(t, frequency_hz: float, indices, t0: float = 0.0, aperture=None) -> np.ndarray:
    """:func:`harmonic_columns` of the harmonics ``indices`` only (1-based): cosines, then sines; with an
    ``aperture``, as each sample observed them (averaged over it)."""
    K = max(indices)
    idx = np.asarray(indices) - 1
    cols = (harmonic_columns(t, frequency_hz, K, t0) if aperture is None else
            aperture.average(lambda u: harmonic_columns(u, frequency_hz, K, t0), t))
    return np.hstack([cols[:, idx], cols[:, K + idx]])


#: The most samples a quintic smoothing spline fits with a knot at every sample (:func:`knot_step` 1).
FULL_BASIS_SAMPLES = MAX_BASIS - 4


def knot_step(n: int, m: int = 3) -> int:
    """Samples between the knots of a smoothing spline of degree ``2m - 1`` over ``n`` samples: 1 (a knot at
    every sample, the exact smoothing spline) up to ``MAX_BASIS - 2m + 2`` samples, more beyond, so that the
    basis keeps at most :data:`MAX_BASIS` functions.

    Examples
    --------
    >>> knot_step(396), knot_step(397), knot_step(1600)
    (1, 2, 5)
    """
    return max(1, int(np.ceil(n / (MAX_BASIS - (2 * m - 1) + 1))))


def _knots(x, m):
    """Knots of the quintic (degree ``2m - 1``) smoothing spline: at the samples (every step-th one for
    long records, :func:`knot_step`), leaving out the m nearest each end so that the basis has at most n
    functions."""
    n, k = x.size, 2 * m - 1
    step = knot_step(n, m)
    inner = x[m:-m:step]
    inner = inner[(inner > x[0]) & (inner < x[-1])]
    return np.r_[[x[0]] * (k + 1), inner, [x[-1]] * (k + 1)]


def _choose_lam(score, lo: float, hi: float, grid_scores=None):
    """``(lam, score)`` minimising ``score(log10 lam)``: a grid of 60 over ``[lo, hi]``, refined.

    ``grid_scores``: optional, the scores of a whole grid at once, the same numbers as ``score`` gives
    one point at a time."""
    grid = np.linspace(lo, hi, 60)
    scores = grid_scores(grid) if grid_scores is not None else [score(g) for g in grid]
    i = int(np.argmin(scores))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = minimize_scalar(score, bounds=(a, b), method="bounded", options={"xatol": 1e-3})
    if res.fun <= scores[i]:
        return 10.0 ** float(res.x), float(res.fun)
    return 10.0 ** float(grid[i]), float(scores[i])


def _harmonic_set(order) -> tuple:
    """The harmonics (1-based indices) a candidate ``order`` names: an int K means 1..K."""
    if np.ndim(order) == 0:
        return tuple(range(1, int(order) + 1))
    return tuple(sorted(int(k) for k in order))


def robust_svd(a):
    """The thin SVD ``(u, s, vt)`` of ``a`` by LAPACK's divide and conquer (``gesdd``, NumPy's), and by the
    slower QR iteration (``gesvd``) when the former does not converge, as it rarely does on
    ill-conditioned matrices. A matrix with NaN or inf raises NumPy's ``LinAlgError`` as before.

    Examples
    --------
    >>> a = np.array([[3.0, 0.0], [4.0, 5.0], [0.0, 0.0]])
    >>> u, s, vt = robust_svd(a)
    >>> bool(np.allclose(u * s @ vt, a)), u.shape
    (True, (3, 2))
    """
    try:
        return np.linalg.svd(a, full_matrices=False)
    except np.linalg.LinAlgError:
        if not np.all(np.isfinite(a)):      # not a convergence failure: NaN or inf in the matrix
            raise
        return _lapack_svd(a, full_matrices=False, lapack_driver="gesvd")


#: Bytes of the projected bases' SVDs :func:`_projected_svd` keeps (the least recently used dropped first).
SVD_CACHE_BYTES = 64 * 2 ** 20
_svd_cache: OrderedDict = OrderedDict()
_svd_cache_lock = threading.Lock()


def _projected_svd(Zw, Q1, yw, key=None):
    """The penalised basis ``Zw`` with the unpenalised columns (orthonormal ``Q1``) projected out, by
    its SVD: singular values ``s`` (the negligible ones dropped), right vectors ``Wt`` and the data's
    coordinates ``z`` (mixed-model form of :func:`_partial_quintic`).

    ``key``, a hashable that determines ``Zw`` and ``Q1`` (the samples' times and weights, the
    harmonics, the aperture), keeps the SVD (up to :data:`SVD_CACHE_BYTES`): it does not depend on the
    data or the smoothing parameter, and a choice that fits the same times at many smoothing parameters
    (leaving each marker out) would otherwise compute the same SVD again for each. The values are the
    same bits either way.
    """
    with _svd_cache_lock:
        found = None if key is None else _svd_cache.get(key)
        if found is not None:
            _svd_cache.move_to_end(key)
    if found is None:
        V, s, Wt = robust_svd(Zw - Q1 @ (Q1.T @ Zw))
        keep = s > 1e-12 * s.max()
        found = (V[:, keep], s[keep], Wt[keep])
        if key is not None:
            _keep_svd(key, found)
    V, s, Wt = found
    return s, Wt, V.T @ yw


def _keep_svd(key, arrays) -> None:
    """Keep ``arrays`` (read-only from now on) under ``key``, dropping the least recently used SVDs beyond
    :data:`SVD_CACHE_BYTES`; an SVD larger than that alone is not kept."""
    size = sum(a.nbytes for a in arrays)
    if size > SVD_CACHE_BYTES:
        return
    for a in arrays:
        a.flags.writeable = False
    with _svd_cache_lock:
        _svd_cache[key] = arrays
        total = sum(sum(a.nbytes for a in v) for v in _svd_cache.values())
        while total > SVD_CACHE_BYTES:
            _, dropped = _svd_cache.popitem(last=False)
            total -= sum(a.nbytes for a in dropped)


def _mixed_model_coefficients(s, Wt, z, lam, Q1, Rx, yw, Zw, penalty_basis):
    """The fit at ``lam`` of the mixed-model form: the spline's coefficients ``c`` and the
    unpenalised columns' ``beta`` (``penalty_basis`` = ``(U0, Up, dp)``, the penalty's null and
    positive eigenvectors and eigenvalues; the first ``U0.shape[1]`` entries of ``beta`` are U0's)."""
    U0, Up, dp = penalty_basis
    u = Wt.T @ (s / (s * s + lam) * z)
    beta = solve_triangular(Rx, Q1.T @ (yw - Zw @ u))
    return U0 @ beta[:U0.shape[1]] + Up @ (u / np.sqrt(dp)), beta


def _partial_quintic(x, y, w, lam, fundamental_hz, orders, noise=None, m=3, gamma=None, aperture=None,
                     correlation=None):
    """Partial smoothing spline: ``f = s + h``, ``h`` harmonics of ``fundamental_hz`` (unpenalised), ``s`` a
    spline of degree ``2m - 1`` with the penalty ``lam integral s^(m)^2``.

    ``orders`` are the candidate sets of harmonics: each an int K (harmonics 1..K; 0 = none) or a
    sequence of harmonic indices (e.g. ``(2, 4)``).

    Mixed-model form: with the penalty ``P = U diag(d) U^T`` (its m null vectors, the polynomials of
    degree < m, ``U0``) the coefficients are ``c = U0 b0 + U+ d+^(-1/2) u`` and the problem is a ridge
    regression of ``y`` on ``Z = B U+ d+^(-1/2)`` (penalty ``lam |u|^2``) after the unpenalised columns
    ``X = [B U0, harmonics]`` are projected out; one SVD of the projected ``Z`` gives the fit, the
    residual and the trace of the hat matrix for every ``lam``. The number of harmonics (``orders``,
    0 = none) and ``lam`` minimise the same criterion as :func:`_quintic_gcv` (GCV with ``gamma`` or,
    with ``noise`` given, the unbiased risk).

    ``correlation``: the noise's AR(1) lag-1 correlation ``rho``; the criterion's ``tr(H)`` becomes
    ``tr(H C)`` with ``C_ij = rho^|i-j|`` (correlated-error GCV, Opsomer, Wang and Yang 2001, as
    :func:`_quintic_gcv`). The hat matrix is ``H = Q1 Q1^T + V diag(s^2 / (s^2 + lam)) V^T`` (``Q1`` the
    unpenalised columns' orthonormal basis, ``V`` the projected basis' left singular vectors), so
    ``tr(H C) = tr(Q1^T C Q1) + sum_k (v_k^T C v_k) s_k^2 / (s_k^2 + lam)``: an unpenalised harmonic costs
    the criterion what the correlated noise at its frequency can imitate (about ``(1 + rho) / (1 - rho)``
    for a slow one), not one degree of freedom.
    """
    n = x.size
    k = 2 * m - 1
    gamma = GCV_GAMMA if gamma is None else gamma
    x_bytes = np.ascontiguousarray(x, float).tobytes()
    knots, B, _, d, U = _basis(x_bytes, m, aperture)
    U0, Up, dp = U[:, :m], U[:, m:], np.clip(d[m:], 1e-14 * d[-1], None)
    sw = np.sqrt(w)
    yw = sw * y
    Zw = sw[:, None] * (B @ Up) / np.sqrt(dp)[None]
    X0w = sw[:, None] * (B @ U0)
    basis_key = (x_bytes, np.ascontiguousarray(w, float).tobytes(), m, aperture)
    t0 = float(x[0])
    best = None
    ZtZ = Zty = None
    for K in map(_harmonic_set, orders):
        X = X0w if not K else np.hstack([X0w, sw[:, None] * _harmonic_subset(x, fundamental_hz, K, t0, aperture)])
        q = X.shape[1]
        if q >= n - 2:
            continue
        Q1, Rx = np.linalg.qr(X)
        if np.min(np.abs(np.diag(Rx))) < 1e-9 * np.max(np.abs(np.diag(Rx))):
            continue                               # harmonics not resolved by the samples
        yq = Q1.T @ yw
        if n <= CACHE_SAMPLES:
            # the SVD of the projected basis itself (cached): the eigenvalues of its Gram matrix square its
            # condition number, and a fit at a small lam then no longer follows lam
            s, Wt, z = _projected_svd(Zw, Q1, yw, key=basis_key + (K, float(fundamental_hz) if K else None))
        else:
            # a record longer than a window (knots every five samples or more): the same from the p x p Gram
            # matrix of the projected basis, M^T M = Z^T Z - (Q1^T Z)^T (Q1^T Z), n p^2 once rather than an
            # n x p SVD per K; its smallest singular values are lost (below 1e-6 of the largest), so a small
            # lam smooths more than it says
            if ZtZ is None:
                ZtZ, Zty = Zw.T @ Zw, Zw.T @ yw
            QZ = Q1.T @ Zw
            ev, Wv = np.linalg.eigh(ZtZ - QZ.T @ QZ)
            keep = ev > 1e-12 * ev.max()
            s, Wt = np.sqrt(ev[keep]), Wv[:, keep].T
            z = (Wt @ (Zty - QZ.T @ yq)) / s
        s2 = s * s
        rss0 = max(float(yw @ yw - yq @ yq - z @ z), 0.0)
        # each column's share of tr(H C): ones for white noise, v_k^T C v_k under AR(1) noise
        q, cw = _correlated_traces(Zw, Q1, s, Wt, correlation) if correlation else (q, None)

        def fit(lmb, s2=s2, z=z, rss0=rss0, q=q, cw=cw):
            shrink = s2 / (s2 + lmb)
            r = z * (1 - shrink)
            return shrink, rss0 + float(r @ r), q + float(shrink.sum() if cw is None else shrink @ cw)

        def criterion(rss, tr):
            if noise is None:
                return n * rss / max(n - gamma * tr, 1e-9) ** 2
            return rss / n + 2 * noise ** 2 * tr / n

        def score(loglam, fit=fit, criterion=criterion):
            _, rss, tr = fit(10.0 ** loglam)
            return criterion(rss, tr)

        def grid_scores(loglams, s2=s2, z=z, rss0=rss0, q=q, criterion=criterion, cw=cw):
            # fit() on every grid point at once: the same elementwise operations, each row's dot product
            # and sum as fit's own (same bits), without NumPy's cost per call on short vectors
            shrink = s2 / (s2 + np.array([10.0 ** g for g in loglams])[:, None])
            r = z * (1 - shrink)
            return [criterion(rss0 + float(ri @ ri), q + float(si.sum() if cw is None else si @ cw))
                    for ri, si in zip(r, shrink)]

        if lam is None:
            # the range the shrinkage factors s2 / (s2 + lam) span
            pos = s2[s2 > 1e-12 * max(s2.max(), 1e-300)]
            lk, sc = _choose_lam(score, np.log10(pos.min()) - 2, np.log10(pos.max()) + 2, grid_scores)
        else:
            lk, sc = float(lam), score(np.log10(lam))
        if best is None or sc < best[0]:
            best = (sc, K, lk, Q1, Rx, s, Wt, z, fit)
    if best is None:
        raise ValueError(f"y: {n} samples are too few for a partial spline with harmonics {list(orders)}")
    sc, K, lk, Q1, Rx, s, Wt, z, fit = best
    c, beta = _mixed_model_coefficients(s, Wt, z, lk, Q1, Rx, yw, Zw, (U0, Up, dp))
    spline = BSpline(knots, c, k)
    harm = None
    if K:
        cos, sin = np.zeros(max(K)), np.zeros(max(K))
        idx = np.asarray(K) - 1
        cos[idx], sin[idx] = beta[m:m + len(K)], beta[m + len(K):]
        harm = HarmonicTerms(float(fundamental_hz), cos, sin, t0)
    shrink, rss, tr = fit(lk)
    info = {"lam": float(lk), "edf": float(Q1.shape[1] + shrink.sum()) if correlation else tr,
            "rms_residual": float(np.sqrt(rss / w.sum())), "n": n,
            "order": k, "method": "gcv" if noise is None else "noise",
            "noise": float("nan") if noise is None else float(noise),
            "harmonics": len(K), "harmonic_indices": list(K),
            "fundamental_hz": float(fundamental_hz)}
    if correlation:
        info["noise_correlation"] = float(correlation)
        info["edf_correlated"] = tr          # tr(H C): the degrees of freedom the correlated criterion charged
    return spline, harm, info


def _correlated_traces(Zw, Q1, s, Wt, rho: float) -> tuple[float, np.ndarray]:
    """``(tr(Q1^T C Q1), v_k^T C v_k per k)`` for :func:`_partial_quintic`'s correlated-error criterion: the
    unpenalised columns' and each penalised direction's share of ``tr(H C)`` under AR(1) noise of lag-1
    correlation ``rho`` (``V = (Zw - Q1 Q1^T Zw) Wt^T / s``, the projected basis' left singular vectors)."""
    V = ((Zw - Q1 @ (Q1.T @ Zw)) @ Wt.T) / s
    q = float(np.einsum("ij,ij->", Q1, ar1_correlation_times(Q1, rho)))
    return q, np.einsum("ij,ij->j", V, ar1_correlation_times(V, rho))


def estimate_fundamental(t, Y, *, min_cycles: float = 2.0, max_hz: float | None = None,
                         max_order: int = 6) -> tuple[float, float]:
    """The fundamental frequency of a record's periodic part, from all its components at once.

    For each trial frequency ``f`` and number of harmonics ``K`` every component is fitted by least
    squares with a quadratic in t plus K harmonics of f; the score is the Bayesian information
    criterion of all components together, ``sum_c n log(RSS_c / n) + p log(n_total)`` with p the
    number of coefficients: a sub-multiple ``f/2`` reproduces the harmonics of ``f`` only with twice
    as many coefficients and loses. The best grid frequency (steps of ``1 / (8 T)``) is refined by a
    bounded search.

    Parameters
    ----------
    t : (n,)
    Y : (n, c)
        Components (any units: each is scored by its own residual).
    min_cycles : float
        The lowest frequency tried has this many cycles in the record. Default 2: the record
        must show its motion repeat once whole. With 1.5 a frequency near the lowest tried,
        with many harmonics, can fit a short record's non-periodic part (half the stride
        frequency taken on a record of a few strides).
    max_hz : float, optional
        Highest frequency tried (default a fifth of the sampling rate).
    max_order : int
        Most harmonics tried.

    Returns
    -------
    frequency_hz : float
    gain : float
        BIC of the periodic model minus that of the quadratic alone, per sample (negative: the
        harmonics explain the record).

    Raises
    ------
    ValueError
        A record too short for ``min_cycles`` cycles, or no period resolved: the best frequency
        is the lowest tried (the bound of the search: a non-periodic record, whose "harmonics"
        would only fit its trend).
    """
    t = np.asarray(t, float)
    Y = np.asarray(Y, float).reshape(t.size, -1)
    n, nc = Y.shape
    T = float(t[-1] - t[0])
    fs = 1.0 / float(np.median(np.diff(t)))
    fmax = fs / 5 if max_hz is None else float(max_hz)
    fmin = min_cycles / T
    if not fmax > fmin:
        raise ValueError(f"t: a record of {T:.3g} s at {fs:.3g} Hz is too short for {min_cycles} cycles")
    X0 = _trend_columns(t)
    Ys = (Y - Y.mean(0)) / np.maximum(Y.std(0), 1e-300)

    def rss(X):
        coef, *_ = np.linalg.lstsq(X, Ys, rcond=None)
        r = Ys - X @ coef
        return np.maximum((r * r).sum(0), 1e-300)

    def bic_of(X):
        return float(n * np.sum(np.log(rss(X) / n)) + X.shape[1] * nc * np.log(n * nc))

    bic0 = bic_of(X0)

    def bic(f):
        out = np.inf
        for K in range(1, max_order + 1):
            if K * f >= fs / 2 or 3 + 2 * K >= n - 2:
                break
            out = min(out, bic_of(np.hstack([X0, harmonic_columns(t, f, K, t[0])])))
        return out

    grid = np.arange(fmin, fmax, 1.0 / (8 * T))
    if grid.size > MAX_GRID:
        # a long record: the trial frequencies are the largest peaks of the summed periodogram of
        # the detrended components (resampled to a uniform grid, padded 4 times) and their halves
        # and thirds, each refined below
        coef, *_ = np.linalg.lstsq(X0, Ys, rcond=None)
        r = Ys - X0 @ coef
        tu = np.linspace(t[0], t[-1], n)
        ru = np.column_stack([np.interp(tu, t, r[:, c]) for c in range(nc)])
        P = (np.abs(np.fft.rfft(ru, 4 * n, axis=0)) ** 2).sum(1)
        fr = np.fft.rfftfreq(4 * n, tu[1] - tu[0])
        peak = np.flatnonzero((P[1:-1] > P[:-2]) & (P[1:-1] >= P[2:])) + 1
        peak = peak[(fr[peak] >= fmin) & (fr[peak] <= fmax)]
        top = fr[peak[np.argsort(P[peak])[::-1][:8]]]
        cand = np.unique(np.concatenate([top / j for j in (1, 2, 3)]))
        grid = cand[(cand >= fmin) & (cand <= fmax)]
        if grid.size == 0:
            raise ValueError(f"t: no periodic component between {fmin:.3g} and {fmax:.3g} Hz")
    scores = np.array([bic(f) for f in grid])
    i = int(np.argmin(scores))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    if (b - a) > 2.0 / (8 * T) + 1e-12:
        a, b = grid[i] - 1.0 / (8 * T), grid[i] + 1.0 / (8 * T)
    res = minimize_scalar(bic, bounds=(a, b), method="bounded", options={"xatol": 1e-6 / T})
    f, sc = (float(res.x), float(res.fun)) if res.fun <= scores[i] else (float(grid[i]), float(scores[i]))
    if f <= fmin * (1 + 1e-3):
        # the best frequency is the lowest one tried: the periodic model explains the record's
        # non-periodic part (a lift, a drift), not a period the record shows
        raise ValueError(f"t: no period resolved: the best fit is the lowest frequency tried ({f:.3g} Hz, "
                         f"{min_cycles:g} cycles in the {T:.3g} s record)")
    return f, (sc - bic0) / (n * nc)


def _trend_columns(t: np.ndarray) -> np.ndarray:
    """``1, u, u^2`` with ``u`` the time centred and scaled by the record's length (a drift's columns)."""
    u = (t - t.mean()) / max(float(t[-1] - t[0]), 1e-12)
    return np.column_stack([np.ones(t.size), u, u * u])


def harmonic_amplitudes(t, y, frequency_hz: float, order: int, weights=None) -> np.ndarray:
    """Amplitudes ``sqrt(a_k^2 + b_k^2)`` of harmonics 1..order of ``frequency_hz`` in ``y(t)``: weighted
    least squares of ``y`` on a quadratic in t and the harmonics together (the quadratic takes a
    drift, so that a trend does not leak into the low harmonics)."""
    t = np.asarray(t, float)
    w = np.ones(t.size) if weights is None else np.asarray(weights, float)
    X = np.hstack([_trend_columns(t), harmonic_columns(t, frequency_hz, order, t[0])])
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(X * sw[:, None], sw * np.asarray(y, float), rcond=None)
    return np.hypot(coef[3:3 + order], coef[3 + order:])


def _significant_harmonics(x, y, w, fundamental_hz, candidates, noise):
    """The candidate harmonics whose amplitude exceeds ``noise``, and every candidate's amplitude.

    A partial spline takes an unpenalised harmonic whole, and a periodic error of the measurement
    (a detection bias repeating with the stride) with it: repeating with the stride, it does not
    average out over strides, so no number of cycles tells it from motion, and a test against the
    residual variance (an F test per harmonic) keeps it. Its size is at most that of the
    per-sample noise (``noise``, known from elsewhere: the registration residual propagated to the
    component), so a harmonic smaller than that noise's standard deviation (one standard
    deviation) is left to the penalised spline. Through a temporal aperture the amplitudes compared
    are those observed (the aperture's gain included), not the motion's: the periodic error guarded
    against is in the observations, bounded by their noise, so the two are compared there."""
    K = max(candidates)
    if 3 + 2 * K >= x.size - 2:
        return [], np.zeros(0)       # too few samples to measure the amplitudes: no harmonic
    amp = harmonic_amplitudes(x, y, fundamental_hz, K, w)[np.asarray(candidates) - 1]
    keep = [k for k, a in zip(candidates, amp) if a > noise]
    return keep, amp


def _adaptive(x, y, w, lam, aperture=None):
    """Two passes: GCV with a uniform penalty, then GCV of the global scale of a penalty
    weighted by the inverse local roughness of the first fit (a locally adaptive spline)."""
    s1, info1 = _quintic_gcv(x, y, w, None, aperture=aperture)
    weight = _roughness_weight(x, lambda t, derivative: s1.derivative(derivative)(t), info1["edf"])
    s2, info2 = _quintic_gcv(x, y, w, lam, weight, aperture=aperture)
    info2["method"] = "adaptive"
    return s2, info2


def _event_quintic(x, y, w, lam, events, degree=2, weight=None, m=3, gamma=None, aperture=None):
    """Partial smoothing spline with change points: ``f = s + sum_j b_j (t - tau_j)_+^degree``, the
    truncated powers at ``events`` unpenalised (Wahba 1990, ch. 6), ``s`` a spline of degree
    ``2m - 1`` with the penalty ``lam integral v(t) s^(m)^2`` (``v`` = ``weight``, default 1).

    Mixed-model form as :func:`_partial_quintic`: the penalty's null space and the event columns
    are projected out of the penalised basis and one SVD gives the fit for every ``lam``; ``lam``
    minimises GCV with ``gamma``. Returns ``(spline, EventTerms, info)``."""
    n = x.size
    k = 2 * m - 1
    gamma = GCV_GAMMA if gamma is None else gamma
    knots, B, _, d, U = _basis(np.ascontiguousarray(x, float).tobytes(), m, aperture)
    if weight is not None:
        P = _penalty(knots, k, m, weight)
        d, U = np.linalg.eigh((P + P.T) / 2)
    U0, Up, dp = U[:, :m], U[:, m:], np.clip(d[m:], 1e-14 * d[-1], None)
    sw = np.sqrt(w)
    yw = sw * y
    Zw = sw[:, None] * (B @ Up) / np.sqrt(dp)[None]
    steps = (truncated_power_columns(x, events, degree) if aperture is None else
             aperture.average(lambda u: truncated_power_columns(u, events, degree), x))
    X = sw[:, None] * np.hstack([B @ U0, steps])
    q = X.shape[1]
    if q >= n - 2:
        raise ValueError(f"y: {n} samples are too few for a spline with {len(events)} event(s)")
    Q1, Rx = np.linalg.qr(X)
    if np.min(np.abs(np.diag(Rx))) < 1e-9 * np.max(np.abs(np.diag(Rx))):
        raise ChangePointError(f"events: {list(events)} are not resolved by the samples (too close to each other "
                         "or to the record's ends)")
    yq = Q1.T @ yw
    sv, Wt, z = _projected_svd(Zw, Q1, yw)
    s2 = sv * sv
    rss0 = max(float(yw @ yw - yq @ yq - z @ z), 0.0)

    def fit(lmb):
        shrink = s2 / (s2 + lmb)
        r = z * (1 - shrink)
        return rss0 + float(r @ r), q + float(shrink.sum())

    def score(loglam):
        rss, tr = fit(10.0 ** loglam)
        return n * rss / max(n - gamma * tr, 1e-9) ** 2

    if lam is None:
        pos = s2[s2 > 1e-12 * max(s2.max(), 1e-300)]
        lam, _ = _choose_lam(score, np.log10(pos.min()) - 2, np.log10(pos.max()) + 2)
    c, beta = _mixed_model_coefficients(sv, Wt, z, lam, Q1, Rx, yw, Zw, (U0, Up, dp))
    rss, tr = fit(lam)
    terms = EventTerms(np.asarray(events, float).copy(), beta[m:].copy(), degree)
    return BSpline(knots, c, k), terms, {"lam": float(lam), "edf": tr, "rms_residual": float(np.sqrt(rss / w.sum())),
                                         "n": n, "order": k, "method": "gcv", "events": [float(e) for e in events],
                                         "event_degree": degree}


def _roughness_weight(x, fit1, edf, events=()):
    """Penalty weight ``v(t)`` of the adaptive spline: the inverse of the first fit's squared third
    derivative averaged over a Gaussian window of the record's effective resolution (``n / edf``
    samples), the window not reaching across an event (the regimes before and after a change point
    are smoothed apart), with a floor of 1e-3 of its largest value."""
    width = max(2.0, x.size / max(edf, 1.0)) * float(np.median(np.diff(x)))
    grid = np.linspace(x[0], x[-1], 8 * x.size)
    r = fit1(grid, 3) ** 2
    xs = grid[::8]
    g = np.exp(-0.5 * ((grid[:, None] - xs[None]) / width) ** 2)
    for tau in events:
        g = g * ((grid[:, None] < tau) == (xs[None] < tau))
    rs = (g * r[:, None]).sum(0) / np.maximum(g.sum(0), 1e-300)
    floor = 1e-3 * rs.max() if rs.max() > 0 else 1.0

    def weight(t):
        return 1.0 / (np.interp(t, xs, rs) + floor)

    return weight


def _adaptive_events(x, y, w, lam, events, degree=2, aperture=None):
    """:func:`_adaptive` with change points: both passes are partial splines with the truncated
    powers at ``events`` (:func:`_event_quintic`), and the roughness window stops at the events."""
    s1, e1, info1 = _event_quintic(x, y, w, None, events, degree, aperture=aperture)

    def first(t, derivative):
        return s1.derivative(derivative)(t) + e1(t, derivative)

    weight = _roughness_weight(x, first, info1["edf"], events)
    s2, e2, info2 = _event_quintic(x, y, w, lam, events, degree, weight, aperture=aperture)
    info2["method"] = "adaptive"
    return s2, e2, info2


def _check_noise_correlation(rho, method, order, events) -> None:
    """A clear error for a ``noise_correlation`` of :func:`smoothing_spline` that cannot be used."""
    if rho is None:
        return
    if not (np.isfinite(rho) and -1 < rho < 1):
        raise ValueError(f"noise_correlation: expected a lag-1 autocorrelation in (-1, 1), got {rho!r}")
    if method not in ("gcv", "noise", "reml") or order != 5 or (events is not None and len(events)):
        raise ValueError("noise_correlation: the correlated-error GCV and C_p are the quintic 'gcv' and 'noise' "
                         "splines (with or without harmonics) without events only")


def half_gain_frequency(lam: float, dt: float, mean_weight: float = 1.0) -> float:
    """The frequency (Hz) at which a quintic smoothing spline passes half of a sinusoid's amplitude.

    Away from the record's ends, a quintic smoothing spline of uniformly
    sampled data (interval ``dt``, weights of mean ``mean_weight``, penalty
    ``lam`` on the third derivative, as :func:`smoothing_spline`) acts as the
    filter ``1 / (1 + lam dt (2 pi f)^6 / mean_weight)``: its gain is 1/2 at
    ``f = (mean_weight / (lam dt))^(1/6) / (2 pi)``, the number a
    biomechanist compares with a Butterworth filter's cutoff. Where a signal's
    power equals the noise's, a Wiener filter's gain is 1/2 too.

    Examples
    --------
    >>> import numpy as np
    >>> dt = 0.01
    >>> lam = 1 / (dt * (2 * np.pi * 6.0) ** 6)
    >>> round(half_gain_frequency(lam, dt), 6)
    6.0
    >>> t = np.arange(600) * dt
    >>> s = smoothing_spline(t, np.sin(2 * np.pi * 6.0 * t), lam=lam)
    >>> round(float(np.std(s(t)[100:-100]) / np.std(np.sin(2 * np.pi * 6.0 * t)[100:-100])), 2)
    0.5
    """
    return float((mean_weight / (dt * max(float(lam), 1e-300))) ** (1 / 6) / (2 * np.pi))


def _harmonic_spline(x, y, w, lam, fundamental_hz, method, noise, max_harmonics, harmonic_cutoff,
                     harmonic_noise, aperture=None, correlation=None) -> SmoothingSpline:
    """:func:`smoothing_spline` with unpenalised harmonics of ``fundamental_hz`` (a partial quintic spline)."""
    dt = float(np.median(np.diff(x)))
    kmax = int(min(max_harmonics, np.floor(0.4 / dt / fundamental_hz - 1e-9)))
    nz = noise if method == "noise" else None
    cutoff = float("nan")
    if harmonic_cutoff:
        # harmonics only where the plain spline passes the signal: below its cutoff frequency
        # (gain about 1/2 of 1 / (1 + lam dt (2 pi f)^6 / w)), so that a harmonic the noise
        # hides from the plain spline is not taken whole. The plain spline's criterion takes the noise as
        # white even with a ``correlation``: the correlated-error GCV without harmonics is the fit that takes
        # a stride's slow motion for correlated noise (its cutoff can fall to nothing), and the partial
        # spline's own correlated criterion then charges each candidate harmonic what that noise imitates
        s0, info0 = _quintic_gcv(x, y, w, lam, noise=nz, aperture=aperture)
        cutoff = half_gain_frequency(info0["lam"], dt, float(np.mean(w)))
        kmax = min(kmax, int(np.floor(cutoff / fundamental_hz + 1e-9)))
        if kmax < 1:
            if correlation:      # no harmonic to try: the plain spline under the noise model asked for
                s0, info0 = _quintic_gcv(x, y, w, lam, noise=nz, aperture=aperture, correlation=correlation)
            info0.update(harmonics=0, fundamental_hz=float(fundamental_hz), cutoff_hz=cutoff)
            return SmoothingSpline(s0, info0, None, aperture=aperture)
    candidates = list(range(1, max(kmax, 0) + 1))
    amplitude = np.zeros(0)
    if harmonic_noise is not None and candidates:
        candidates, amplitude = _significant_harmonics(x, y, w, fundamental_hz, candidates, harmonic_noise)
    # nested candidate sets: none, the first significant harmonic, the first two, ...
    sets = [tuple(candidates[:j]) for j in range(len(candidates) + 1)]
    s, harm, info = _partial_quintic(x, y, w, lam, fundamental_hz, sets, noise=nz, aperture=aperture,
                                     correlation=correlation)
    info["cutoff_hz"] = cutoff
    info["harmonic_amplitudes"] = amplitude.tolist()
    if harmonic_noise is not None:
        info["harmonic_noise"] = float(harmonic_noise)     # the level the harmonics were tested at
    return SmoothingSpline(s, info, harm, aperture=aperture)


def _check_method_options(x, method: str, order: int, fundamental_hz, events, weights, noise, noise_correlation,
                          harmonic_noise) -> None:
    """:func:`smoothing_spline`'s method and the options it allows with it: a clear error for any other."""
    if method not in ("gcv", "adaptive", "noise", "reml", "none"):
        raise ValueError(f"method: expected 'gcv', 'adaptive', 'noise', 'reml' or 'none', got {method!r}")
    if method == "reml" and (order != 5 or fundamental_hz is not None or (events is not None and len(events))
                             or weights is not None):
        raise ValueError("method 'reml' is the quintic spline without harmonics, events or weights only")
    _check_noise_correlation(noise_correlation, method, order, events)
    if method == "noise" and not (noise is not None and np.isfinite(noise) and noise > 0):
        raise ValueError(f"noise: method 'noise' needs a positive noise level, got {noise!r}")
    if method == "adaptive" and order != 5:
        raise ValueError("method 'adaptive' is a quintic spline: order must be 5")
    if order not in (3, 5):
        raise ValueError(f"order: expected 3 or 5, got {order!r}")
    if harmonic_noise is not None and not (np.isfinite(harmonic_noise) and harmonic_noise >= 0):
        raise ValueError(f"harmonic_noise: expected a finite noise level >= 0, got {harmonic_noise!r}")
    if fundamental_hz is not None:
        if not (np.isfinite(fundamental_hz) and fundamental_hz > 0):
            raise ValueError(f"fundamental_hz: expected a positive frequency, got {fundamental_hz!r}")
        if order != 5 or method not in ("gcv", "noise"):
            raise ValueError("fundamental_hz: harmonics are fitted by the quintic 'gcv' or 'noise' spline only")
    if events is not None and len(events):
        ev = np.asarray(events, float)
        if ev.ndim != 1 or not np.all(np.isfinite(ev)) or np.any((ev <= x[0]) | (ev >= x[-1])):
            raise ChangePointError(f"events: expected finite times inside the record ({x[0]:.6g}, {x[-1]:.6g}), got {events!r}")
        if order != 5 or method not in ("gcv", "adaptive") or fundamental_hz is not None:
            raise ChangePointError("events: change points are fitted by the quintic 'gcv' or 'adaptive' spline "
                             "without harmonics only")


def smoothing_spline(t, y, *, method: str = "gcv", order: int = 5, lam: float | None = None,
                     weights=None, noise: float | None = None, fundamental_hz: float | None = None,
                     max_harmonics: int = 10, harmonic_cutoff: bool = False,
                     harmonic_noise: float | None = None, events=None,
                     event_degree: int = 2, noise_correlation: float | None = None,
                     aperture=None) -> SmoothingSpline:
    """Fit a smoothing spline to samples ``y(t)``; its smoothing chosen by GCV.

    Parameters
    ----------
    t, y : (n,)
        Increasing times and finite samples.
    method : "gcv", "adaptive", "noise" or "none"
        ``"gcv"``: ``lam`` minimises generalised cross-validation (unless
        given); ``"adaptive"``: a second GCV pass with a penalty weighted by
        the first pass' local roughness; ``"noise"``: ``lam`` minimises the
        unbiased risk ``RSS/n + 2 noise^2 tr(H)/n`` (Mallows' C_p) with the
        sample noise ``noise`` measured elsewhere (e.g. from registration
        residuals); ``"reml"``: ``lam`` by restricted maximum likelihood
        (:func:`reml_ar1_smoothing`, with the AR(1) ``noise_correlation`` given,
        white without); ``"none"``: interpolating spline of the same order.
    noise : float
        Standard deviation of the samples' noise (``method="noise"``).
    order : 5 or 3
        Quintic (penalty on the 3rd derivative) or cubic (SciPy's
        ``make_smoothing_spline``, penalty on the 2nd).
    lam : float, optional
        Smoothing parameter (for the same units of t and y); chosen if None.
    weights : (n,), optional
        Inverse variances of the samples.
    fundamental_hz : float, optional
        A partial spline (``method`` "gcv" or "noise", order 5): ``f = s + h`` with ``h`` the
        first K harmonics of this frequency, *not* penalised, and the penalty acting on the
        spline ``s`` alone (Wahba 1990, ch. 6). K (0 to ``max_harmonics``, below 0.8 of the
        Nyquist frequency) is chosen with ``lam`` by the same criterion; K = 0 is the plain
        smoothing spline. A periodic motion's harmonics are then kept whole (the smoothing no
        longer flattens their peaks) and the spline's end effects act only on the remainder.
    max_harmonics : int
        Most harmonics tried with ``fundamental_hz``.
    harmonic_cutoff : bool
        With ``fundamental_hz``: try only the harmonics below the cutoff frequency of the plain
        smoothing spline (its smoothing chosen first by the same criterion). A harmonic above it
        is one the noise hides, or a periodic error of the measurement (a marker's detection
        bias or skin movement repeating with the stride), which an unpenalised term would take
        whole.
    harmonic_noise : float, optional
        With ``fundamental_hz``: the standard deviation of the samples' noise (data units, measured
        elsewhere, e.g. predicted from registration residuals). Only the harmonics whose amplitude
        (:func:`harmonic_amplitudes`, least squares with a quadratic) exceeds it are candidates,
        in increasing order (a trot's pitch may keep the 2nd harmonic without the 1st); a smaller
        one cannot be told from a periodic error of the measurement and is left to the penalised
        spline. ``info["harmonic_amplitudes"]`` holds every candidate's amplitude.
    events : sequence of float, optional
        Change points (s; known from elsewhere, e.g. an impact seen by a force plate): a partial spline ``f = s + sum_j b_j
        (t - tau_j)_+^event_degree`` with the truncated powers unpenalised (``method`` "gcv" or
        "adaptive", order 5, no ``fundamental_hz``). With ``event_degree = 2`` the acceleration
        may jump at each ``tau_j`` (an impact), which a smoothing spline with knots at the samples
        spreads over many samples; ``"adaptive"`` also smooths each side's roughness apart. An
        empty sequence is the plain spline. At ``t = tau_j`` itself the jumped derivative takes its
        value from before the jump (``(t - tau)_+^0 = 0`` there): an event placed exactly on a sample
        leaves that sample on the calm side, one placed a hair before it moves the sample to the other
        side, and on a sharp onset that one sample can change the record's acceleration error by several
        points.
    noise_correlation : float, optional
        ``method="gcv"`` (order 5, with or without harmonics, no events): the noise's lag-1 autocorrelation
        ``rho`` (an AR(1) error, measured elsewhere, e.g. from a rigid cluster's residuals).
        GCV assumes independent errors and, with positively correlated ones, takes the slow
        noise for signal; with ``rho`` the criterion is ``n RSS / (n - gamma tr(H C))^2`` with
        ``C_ij = rho^|i-j|`` (correlated-error GCV, Opsomer, Wang and Yang 2001). With
        ``fundamental_hz`` the harmonics, unpenalised, are charged in ``tr(H C)`` what the
        correlated noise at their frequencies can imitate (the partial spline's criterion);
        ``harmonic_cutoff``'s plain pre-fit takes the noise as white.
        ``method="noise"``: the noise's covariance is ``noise^2 C``, known, and ``lam`` minimises
        the unbiased risk ``RSS/n + 2 noise^2 tr(H C)/n`` (Mallows' C_p for correlated errors),
        which estimates nothing about the noise from the data it smooths.
    aperture : horsemocap.aperture.Aperture, optional
        Each sample is the motion averaged over this temporal aperture (a
        camera's exposure, an interlaced frame's two fields): the quintic
        spline's basis, harmonics and change points are averaged over it at
        every sample, so the spline fits what the samples observed and
        estimates the motion itself (``s.observed(t)`` is the fit at the
        samples). Not with ``order=3``, ``"reml"`` or ``"none"``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 101)
    >>> s = smoothing_spline(t, np.sin(2 * np.pi * t), noise_correlation=0.5)
    >>> bool(abs(s(0.25) - 1) < 1e-3), s.info["noise_correlation"]
    (True, 0.5)
    """
    x = np.asarray(t, float)
    y = np.asarray(y, float)
    if x.ndim != 1 or x.shape != y.shape:
        raise ValueError(f"t, y: expected two 1-D arrays of the same length, got {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("t, y: samples must be finite (leave missing frames out)")
    if np.any(np.diff(x) <= 0):
        raise ValueError("t: times must increase")
    _check_method_options(x, method, order, fundamental_hz, events, weights, noise, noise_correlation,
                          harmonic_noise)
    if aperture is not None and (order != 5 or method in ("reml", "none")):
        raise ValueError(f"aperture: a temporal aperture is fitted by the quintic 'gcv', 'noise' and 'adaptive' "
                         f"splines only, got method={method!r}, order={order}")
    n = x.size
    w = np.ones(n) if weights is None else np.asarray(weights, float)
    if w.shape != (n,) or np.any(w <= 0):
        raise ValueError("weights: expected n positive weights")
    if n < order + 1:
        raise ValueError(f"y: a smoothing spline of degree {order} needs at least {order + 1} samples, got {n}")
    if method == "none":
        s = make_interp_spline(x, y, k=order)
        return SmoothingSpline(s, {"lam": 0.0, "edf": float(n), "rms_residual": 0.0, "n": n,
                                   "order": order, "method": "none"})
    if order == 3:
        s = make_smoothing_spline(x, y, w=w, lam=lam)
        r = y - s(x)
        return SmoothingSpline(s, {"lam": float("nan") if lam is None else float(lam), "edf": float("nan"),
                                   "rms_residual": float(np.sqrt(np.sum(w * r * r) / w.sum())), "n": n,
                                   "order": 3, "method": "gcv"})
    if fundamental_hz is not None:
        return _harmonic_spline(x, y, w, lam, fundamental_hz, method, noise, max_harmonics, harmonic_cutoff,
                                harmonic_noise, aperture, noise_correlation)
    if events is not None and len(events):
        ev = sorted(float(e) for e in events)
        fn = _adaptive_events if method == "adaptive" else _event_quintic
        s, et, info = fn(x, y, w, lam, ev, event_degree, aperture=aperture)
        return SmoothingSpline(s, info, None, et, aperture)
    if method == "noise":
        if order != 5:
            raise ValueError("method 'noise' is a quintic spline: order must be 5")
        s, info = _quintic_gcv(x, y, w, lam, noise=noise, correlation=noise_correlation, aperture=aperture)
    elif method == "adaptive":
        s, info = _adaptive(x, y, w, lam, aperture)
    elif method == "reml":
        if lam is None:
            lam = reml_ar1_smoothing(x, y, correlations=[noise_correlation or 0.0])["lam"]
        s, info = _quintic_gcv(x, y, w, lam, correlation=noise_correlation)
        info["method"] = "reml"
    else:
        s, info = _quintic_gcv(x, y, w, lam, correlation=noise_correlation, aperture=aperture)
    return SmoothingSpline(s, info, aperture=aperture)


def robust_weighted_spline(t, y, variance, *, iterations: int = 2, huber_k: float = HUBER_K,
                           **kwargs) -> SmoothingSpline:
    """Smoothing spline weighted by each sample's predicted variance, made robust to where the
    prediction fails (Huber M-estimation by iteratively reweighted fits).

    The weights start at ``1 / variance`` (the smoothing spline's weighted least squares with
    inverse variances, Wahba 1990, ch. 1; only their ratios matter: the criterion, GCV or the
    harmonics' choice, is invariant to their scale). After each fit the standardised residuals
    ``z_i = r_i / sqrt(variance_i)`` are compared with their robust scale ``s = 1.4826 median |z| /
    sqrt(1 - edf / n)`` (the normal-consistent MAD, corrected for the residuals of a smoother being
    smaller than the noise by about that factor; without it the calibrated test below sits low and
    can take a harmonic the noise made; the factor over-corrects where the smoother takes more than
    half the samples), and a sample with ``|z_i| > huber_k s`` has its weight multiplied by
    ``huber_k s / |z_i|`` (Huber's weights; Huber 1981, sec. 7.8; for smoothing splines Cox 1983,
    Ann. Statist. 11, 530-551): a sample whose error the linearised prediction underestimates (a
    registration far from its linear regime) no longer pulls the spline. ``iterations`` reweighted
    fits follow the first.

    ``harmonic_noise="unit weight"`` (with ``fundamental_hz``): the harmonics' noise test uses the
    standard deviation of a sample of unit weight, ``1 / sqrt(mean(1 / variance))``, the noise level
    the weighted amplitudes are measured at (the RMS of the standard deviations would be set by the
    worst samples, which the weights discount). ``harmonic_noise="calibrated"``: the first fit as with
    "unit weight"; each reweighted fit then tests the harmonics against that noise times the robust
    scale ``s`` of the previous fit's standardised residuals (the prediction corrected by what the
    residuals show: ``s`` is 1 when the predicted variances are right) and tries every harmonic that
    passes, below 0.4 of the sampling rate, without ``harmonic_cutoff``: the plain spline's cutoff
    is set by the noise of the worst frames (which the weights discount) and can fall below a stride
    harmonic that carries much of the saddle acceleration. With
    ``iterations=0`` it is "unit weight".

    Parameters
    ----------
    t, y : (n,)
        As :func:`smoothing_spline`.
    variance : (n,)
        Each sample's predicted noise variance (positive; a scale common to all may be wrong).
    iterations : int
        Reweighted fits after the first (0: the weighted fit alone).
    huber_k : float
        Huber's constant in robust standard deviations.
    **kwargs
        Passed to :func:`smoothing_spline` (not ``weights``).

    Returns
    -------
    SmoothingSpline
        ``info`` also holds ``weights`` ("inverse variance, Huber"), ``downweighted`` (samples whose
        final Huber factor is below 1) and ``robust_scale`` (``s``).
    """
    y = np.asarray(y, float)
    v = np.asarray(variance, float)
    if v.shape != y.shape or not np.all(np.isfinite(v) & (v > 0)):
        raise ValueError(f"variance: expected {y.shape} positive finite variances, got shape {v.shape}")
    if "weights" in kwargs:
        raise ValueError("weights: given by variance (and the Huber factors) here")
    if not (np.isfinite(huber_k) and huber_k > 0) or int(iterations) < 0:
        raise ValueError(f"huber_k, iterations: expected a positive constant and a count >= 0, got {huber_k!r}, {iterations!r}")
    w0 = 1.0 / v
    calibrated = False
    if isinstance(kwargs.get("harmonic_noise"), str):
        if kwargs["harmonic_noise"] not in ("unit weight", "calibrated"):
            raise ValueError("harmonic_noise: expected a noise level, 'unit weight' or 'calibrated', "
                             f"got {kwargs['harmonic_noise']!r}")
        calibrated = kwargs["harmonic_noise"] == "calibrated"
        kwargs["harmonic_noise"] = unit_noise = float(1.0 / np.sqrt(np.mean(w0)))
    factor = np.ones_like(w0)
    scale = float("nan")
    for it in range(int(iterations) + 1):
        w = w0 * factor
        fit_kwargs = kwargs
        if calibrated and it > 0:
            # the harmonics tested against the weighted fit's own noise: the unit-weight frame's predicted
            # noise times the robust scale of the standardised residuals, with no plain spline's cutoff
            fit_kwargs = {**kwargs, "harmonic_noise": scale * unit_noise, "harmonic_cutoff": False}
        spline = smoothing_spline(t, y, weights=w / w.mean(), **fit_kwargs)
        if it == int(iterations):
            break
        z = (y - spline.observed(t)) * np.sqrt(w0)
        # the residuals of a smoother are smaller than the noise by about sqrt(1 - edf / n)
        scale = 1.4826 * float(np.median(np.abs(z))) / np.sqrt(max(1.0 - spline.info["edf"] / y.size, 0.1))
        if not scale > 0:
            break
        factor = np.minimum(1.0, huber_k * scale / np.maximum(np.abs(z), 1e-300))
    spline.info.update(weights="inverse variance, Huber", downweighted=int(np.sum(factor < 1)),
                       robust_scale=scale)
    return spline


def residual_log_likelihood(spline, t, y, variance=None) -> float:
    """Akaike's criterion (as a log-likelihood, higher is better) of a fit's residuals under a noise
    model ``r_i ~ N(0, s^2 variance_i)`` with the scale ``s`` unknown (its maximum likelihood value):
    ``-1/2 (sum log variance_i + n log(sum r_i^2 / variance_i / n)) - edf`` (constants dropped;
    Akaike 1974). ``variance`` None is the equal-variance model. Two fits of the same samples under
    two noise models (e.g. predicted per-sample variances against equal ones) are compared by it."""
    y = np.asarray(y, float)
    v = np.ones_like(y) if variance is None else np.asarray(variance, float)
    r = y - getattr(spline, "observed", spline)(np.asarray(t, float))    # a sample's fit through its aperture
    n = y.size
    s2 = max(float(np.sum(r * r / v)) / n, 1e-300)
    return float(-0.5 * (np.sum(np.log(v)) + n * np.log(s2)) - spline.info["edf"])
