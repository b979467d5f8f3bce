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
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline, make_smoothing_spline
from scipy.optimize import minimize_scalar

__all__ = ["SmoothingSpline", "smoothing_spline", "MAX_BASIS"]

MAX_BASIS = 400
"""Largest number of B-spline basis functions of a quintic smoothing spline."""

GCV_GAMMA = 1.4
"""Cost of a degree of freedom in the GCV score ``n RSS / (n - gamma tr H)^2``: 1.4, the
value Kim and Gu (2004, J. R. Statist. Soc. B 66, 337-356) recommend against GCV's known
tendency to undersmooth; with plain GCV (1.0) the roll of the Horse 1 canter record (41 frames)
was left almost unsmoothed (saddle vertical acceleration 63 % off, 12.9 % with 1.4)."""


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
    """

    spline: BSpline
    info: dict

    def __call__(self, t, derivative: int = 0) -> np.ndarray:
        t = np.asarray(t, float)
        if derivative == 0:
            return self.spline(t)
        return self.spline.derivative(derivative)(t)


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


def _quintic_gcv(x, y, w, lam, weight=None, noise=None, m=3, gamma=None):
    n = x.size
    k = 2 * m - 1
    gamma = GCV_GAMMA if gamma is None else gamma
    # knots at the samples (every step-th one for long records), leaving out the m nearest each
    # end so that the basis has at most n functions and B^T W B is non-singular
    step = max(1, int(np.ceil(n / (MAX_BASIS - k + 1))))
    inner = x[m:-m:step]
    inner = inner[(inner > x[0]) & (inner < x[-1])]
    knots = np.r_[[x[0]] * (k + 1), inner, [x[-1]] * (k + 1)]
    B = BSpline.design_matrix(x, knots, k).toarray()
    P = _penalty(knots, k, m, weight)
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
    T = Li.T @ U                       # coefficients c = T (z / (1 + lam d))
    Z = Bw @ T                         # weighted fitted values = Z (z / (1 + lam d))
    z = Z.T @ (sw * y)
    yw = sw * y

    def fit(lmb):
        f = z / (1 + lmb * d)
        r = yw - Z @ f
        return f, float(r @ r), float(np.sum(1 / (1 + lmb * d)))

    def gcv(loglam):
        _, rss, tr = fit(10.0 ** loglam)
        return n * rss / max(n - gamma * tr, 1e-9) ** 2

    if noise is not None:
        def gcv(loglam):  # noqa: F811  (unbiased risk with the noise known: Mallows' C_p / UBRE)
            _, rss, tr = fit(10.0 ** loglam)
            return rss / n + 2 * noise ** 2 * tr / n

    if lam is None:
        # the scale of lam: penalty eigenvalues span many decades; search the range they give
        pos = d[d > 1e-12 * max(d.max(), 1e-300)]
        lo, hi = -np.log10(pos.max()) - 2, -np.log10(pos.min()) + 2
        grid = np.linspace(lo, hi, 60)
        scores = [gcv(g) for g in grid]
        i = int(np.argmin(scores))
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        res = minimize_scalar(gcv, bounds=(a, b), method="bounded", options={"xatol": 1e-3})
        lam = 10.0 ** float(res.x if res.fun <= scores[i] else grid[i])
    f, rss, tr = fit(lam)
    spline = BSpline(knots, T @ f, k)
    return spline, {"lam": float(lam), "edf": tr, "rms_residual": float(np.sqrt(rss / w.sum())),
                    "n": n, "order": k, "method": "gcv" if noise is None else "noise",
                    "noise": float("nan") if noise is None else float(noise)}


def _adaptive(x, y, w, lam):
    """Two passes: GCV with a uniform penalty, then GCV of the global scale of a penalty
    weighted by the inverse local roughness of the first fit (a locally adaptive spline)."""
    s1, info1 = _quintic_gcv(x, y, w, None)
    d3 = s1.derivative(3)
    # local roughness: the first pass' third derivative squared, averaged over a window
    # of the record's own effective resolution (n / edf samples)
    width = max(2.0, x.size / max(info1["edf"], 1.0)) * float(np.median(np.diff(x)))
    grid = np.linspace(x[0], x[-1], 8 * x.size)
    r = d3(grid) ** 2
    xs = grid[::8]
    g = np.exp(-0.5 * ((grid[:, None] - xs[None]) / width) ** 2)
    rs = (g * r[:, None]).sum(0) / g.sum(0)
    floor = 1e-3 * rs.max() if rs.max() > 0 else 1.0

    def weight(t):
        return 1.0 / (np.interp(t, xs, rs) + floor)

    s2, info2 = _quintic_gcv(x, y, w, lam, weight)
    info2["method"] = "adaptive"
    return s2, info2


def smoothing_spline(t, y, *, method: str = "gcv", order: int = 5, lam: float | None = None,
                     weights=None, noise: float | None = None) -> SmoothingSpline:
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
        residuals); ``"none"``: interpolating spline of the same order.
    noise : float
        Standard deviation of the samples' noise (``method="noise"``).
    order : 5 or 3
        Quintic (penalty on the 3rd derivative) or cubic (SciPy's
        ``make_smoothing_spline``, penalty on the 2nd).
    lam : float, optional
        Smoothing parameter (for the same units of t and y); chosen if None.
    weights : (n,), optional
        Inverse variances of the samples.
    """
    x = np.asarray(t, float)
    y = np.asarray(y, float)
    if x.ndim != 1 or x.shape != y.shape:
        raise ValueError(f"t, y: expected two 1-D arrays of the same length, got {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("t, y: samples must be finite (leave missing frames out)")
    if np.any(np.diff(x) <= 0):
        raise ValueError("t: times must increase")
    if method not in ("gcv", "adaptive", "noise", "none"):
        raise ValueError(f"method: expected 'gcv', 'adaptive', 'noise' or 'none', got {method!r}")
    if method == "noise" and not (noise is not None and np.isfinite(noise) and noise > 0):
        raise ValueError(f"noise: method 'noise' needs a positive noise level, got {noise!r}")
    if method == "adaptive" and order != 5:
        raise ValueError("method 'adaptive' is a quintic spline: order must be 5")
    if order not in (3, 5):
        raise ValueError(f"order: expected 3 or 5, got {order!r}")
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
    if method == "noise":
        if order != 5:
            raise ValueError("method 'noise' is a quintic spline: order must be 5")
        s, info = _quintic_gcv(x, y, w, lam, noise=noise)
    else:
        s, info = (_adaptive if method == "adaptive" else _quintic_gcv)(x, y, w, lam)
    return SmoothingSpline(s, info)
