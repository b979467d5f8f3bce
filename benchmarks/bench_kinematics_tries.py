"""Smoothers tried on the ringing fixtures that let the acceleration jump (issue 13): a negative result.

Each row smooths the six pose components (centroid and rotation vector of
:func:`horsemocap.pose.fit_pose_trajectory`'s registration) another way and scores the hidden
point's velocity and acceleration and the body's omega and alpha against the truth (RMSE as a
percentage of the truth's rms, median of the draws), as ``bench_kinematics.py`` does:

- ``adaptive``: the library's adaptive spline (the reference);
- ``one-sided xN``: the adaptive penalty ``1 / roughness`` re-weighted N times, the roughness
  (the last fit's squared 3rd derivative) averaged over a one-sided Gaussian window, the larger of
  the left and right averages (an edge-keeping envelope: the window does not average the quiet
  side into the ringing's onset);
- ``oracle weight``: the same one-sided weight taken from the noise-free markers' interpolating
  spline (the truth's roughness: what any data-driven weight could reach at best);
- ``IRLS L1 / Cauchy``: the penalty weight ``1/(|f'''| + 0.1 rms)`` or ``1/(1 + (f'''/0.5 rms)^2)``
  pointwise, 3 iteratively re-weighted passes with GCV; the smoothing-spline form of a
  Rauch-Tung-Striebel smoother of the constant-acceleration model whose white jerk is heavy-tailed
  (L1 / Student-t with one degree of freedom), the spline's penalty weight being the inverse
  process-noise intensity (Wahba 1978; Kohn and Ansley 1987);
- ``L1 trend k``: discrete L1 trend filtering, ``min |y - x|^2 + lam |D^(k+1) x|_1`` (k = 2:
  the acceleration piecewise constant; k = 3: piecewise linear), by IRLS; derivatives by central
  differences at the samples; ``lam = c sigma`` with ``sigma`` the component's noise from the
  registration (:func:`horsemocap.pose.pose_noise`) and ``c`` the best of 0.1-100 *chosen on the
  truth* (an upper bound of what a risk estimate could choose);
- ``onset scan``: not a smoother. For every midpoint ``tau`` the gain of one unpenalised
  ``(t - tau)_+^2`` column (an acceleration jump) against the adaptive spline, each component's
  ``(x' M y)^2 / (x' M x)`` over its registration noise, summed over the six (``M = I - H``):
  the best ``tau`` and its gain, and the best gain more than 50 ms from the true onset. A jump
  can be detected only if the second is well below the first on both fixtures.

``--detect`` (2026-11-24): the onset scan recalibrated and used (:func:`_detect_onsets`): each
component's score over its own residual variance, the best ``tau`` accepted beyond a bootstrap's (or
Bonferroni's) 95 % of the scan's maximum, the adaptive spline refitted with the accepted events, repeated
(at most 3); scored on all six fixtures (adaptive, adaptive + detected events, adaptive + the true onset).
Negative: no statistic and threshold tried finds the onset on issue13 without false events elsewhere
(``benchmarks/README.md``, ``results/kinematics_ringing_onset_detect.txt``).

Targets (issue 13): acceleration < 15 %, omega < 10 %. Usage:
``python benchmarks/bench_kinematics_tries.py [--draws 3] [--fixture issue13|second]``
(``results/kinematics_ringing_tries*.txt``);
``python benchmarks/bench_kinematics_tries.py --detect [--draws 3] [--fixtures a,b] [--statistic score|criterion]
[--threshold bootstrap|fit_bootstrap|refit_bootstrap|bonferroni] [--replicates 200] [--max-events 3]``
(run with ``OMP_NUM_THREADS=1``: the dense hat matrices are 60 times slower with threads on a loaded machine).
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bench_kinematics import FIXTURES, score


def _one_sided_weight(x, s, edf):
    """``v(t) = 1 / (max(left, right) windowed f'''^2 + floor)`` of spline ``s``."""
    width = max(2.0, x.size / max(edf, 1.0)) * float(np.median(np.diff(x)))
    grid = np.linspace(x[0], x[-1], 8 * x.size)
    r = s.derivative(3)(grid) ** 2
    xs = grid[::8]
    dx = grid[:, None] - xs[None]
    g = np.exp(-0.5 * (dx / width) ** 2)
    sides = [g * (dx <= 0), g * (dx >= 0)]
    rs = np.maximum(*[(gs * r[:, None]).sum(0) / np.maximum(gs.sum(0), 1e-300) for gs in sides])
    floor = 1e-3 * rs.max()
    return lambda t: 1.0 / (np.interp(t, xs, rs) + floor)


def _one_sided(passes, truth=None):
    from horsemocap.splines import SmoothingSpline, _quintic_gcv

    def fit(t, y, i):
        w = np.ones_like(t)
        s, info = _quintic_gcv(t, y, w, None)
        for _ in range(passes):
            rough = s if truth is None else truth[i].spline
            s, info = _quintic_gcv(t, y, w, None, _one_sided_weight(t, rough, info["edf"]))
        return SmoothingSpline(s, info)
    return fit


def _irls(kind):
    from horsemocap.splines import SmoothingSpline, _quintic_gcv

    def fit(t, y, i):
        w = np.ones_like(t)
        s, info = _quintic_gcv(t, y, w, None)
        grid = np.linspace(t[0], t[-1], 8 * t.size)
        for _ in range(3):
            j = s.derivative(3)(grid)
            rms = np.sqrt(np.mean(j * j))
            v = 1 / (np.abs(j) + 0.1 * rms) if kind == "l1" else 1 / (1 + (j / (0.5 * rms)) ** 2)
            v = v / v.max()
            s, info = _quintic_gcv(t, y, w, None, lambda tt, v=v: np.interp(tt, grid, v))
        return SmoothingSpline(s, info)
    return fit


class _Discrete:
    """Samples and their central-difference derivatives, read at the sample times."""

    def __init__(self, t, x):
        dt = t[1] - t[0]
        a = np.empty_like(x)
        a[1:-1] = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt ** 2
        a[0], a[-1] = a[1], a[-2]
        self.t, self.d, self.info = t, (x, np.gradient(x, dt), a), {}

    def __call__(self, t, derivative=0):
        return np.interp(t, self.t, self.d[derivative])


def _trend_filter(y, lam, k, iterations=30):
    """L1 trend filtering of order k by iteratively re-weighted least squares."""
    n = y.size
    D = sp.eye(n, format="csr")
    for _ in range(k + 1):
        D = D[1:] - D[:-1]
    x = y.copy()
    for it in range(iterations):
        z = np.abs(D @ x)
        wts = lam / (z + 1e-6 * max(z.max(), 1e-300) + 1e-12) if it else np.full(z.size, lam / np.std(D @ y))
        x = spla.spsolve((sp.eye(n) + D.T @ sp.diags(wts) @ D).tocsc(), y)
    return x


def _components(d):
    from horsemocap import pose
    reg = pose.register_pose(d["markers"], d["model"])
    tr = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(smoothing="gcv", harmonics="none"))
    return reg, tr, np.column_stack([reg.centre, tr.rotvec_data])


def _score(d, tr0, fits):
    return score(d, dataclasses.replace(tr0, centre_splines=tuple(fits[:3]), rotvec_splines=tuple(fits[3:])))


def _onset_scan(t, Y, sigma, onset):
    from horsemocap.splines import _basis, _penalty, _quintic_gcv, _roughness_weight, truncated_power_columns
    taus = 0.5 * (t[5:-6] + t[6:-5])
    X = truncated_power_columns(t, taus, 2)
    knots, B = _basis(np.ascontiguousarray(t).tobytes(), 3)[:2]
    gain = np.zeros(taus.size)
    for i in range(Y.shape[1]):
        s1, info1 = _quintic_gcv(t, Y[:, i], np.ones_like(t), None)
        wt = _roughness_weight(t, lambda u, dd: s1.derivative(dd)(u), info1["edf"])
        _, info = _quintic_gcv(t, Y[:, i], np.ones_like(t), None, wt)
        P = _penalty(knots, 5, 3, wt)
        M = np.eye(t.size) - B @ np.linalg.solve(B.T @ B + info["lam"] * P, B.T)
        MX = M @ X
        gain += (MX.T @ Y[:, i]) ** 2 / np.einsum("ij,ij->j", X, MX) / sigma[i] ** 2
    far = np.abs(taus - onset) > 0.05
    best = int(np.argmax(gain))
    return taus[best], gain[best], gain[far].max(), taus[far][np.argmax(gain[far])]


def _adaptive_hat(t, y, events):
    """The adaptive spline of ``y`` (with unpenalised ``(t - tau)_+^2`` at ``events``) as a linear
    smoother: its hat matrix ``H`` (n, n), rebuilt from the library's fit (its ``lam`` and roughness
    weight: :func:`horsemocap.splines._adaptive` / ``_adaptive_events``), and the library's spline."""
    from horsemocap.splines import (_basis, _event_quintic, _penalty, _quintic_gcv, _roughness_weight,
                                    smoothing_spline, truncated_power_columns)
    w = np.ones_like(t)
    if events:
        s1, e1, info1 = _event_quintic(t, y, w, None, events)

        def first(u, dd):
            return s1.derivative(dd)(u) + e1(u, dd)
    else:
        s1, info1 = _quintic_gcv(t, y, w, None)

        def first(u, dd):
            return s1.derivative(dd)(u)
    wt = _roughness_weight(t, first, info1["edf"], events or ())
    lib = smoothing_spline(t, y, method="adaptive", events=events or None)
    knots, B = _basis(np.ascontiguousarray(t).tobytes(), 3)[:2]
    P = _penalty(knots, 5, 3, wt)
    X = np.hstack([B, truncated_power_columns(t, events, 2)]) if events else B
    A = X.T @ X
    A[:B.shape[1], :B.shape[1]] += lib.info["lam"] * P
    A += 1e-12 * np.trace(A) / A.shape[0] * np.eye(A.shape[0])
    H = X @ np.linalg.solve(A, X.T)
    return H, lib


def _detect_onsets(t, Y, *, threshold="bootstrap", replicates=200, max_events=3, level=0.95, rng=None,
                   statistic="score"):
    """Change points detected from the data: for every midpoint ``tau`` the score of one unpenalised
    ``(t - tau)_+^2`` column against the adaptive spline (with the events accepted so far) per
    component, ``z_i = (M x)' y_i / (s_i |M x|)`` (``M = I - H``, ``s_i^2 = RSS_i / (n - edf_i)`` the
    component's own residual variance: ``z_i ~ N(0, 1)`` under white noise of that variance), summed
    over the six components, ``G = sum z_i^2`` (chi2(6) at one ``tau``). The best ``tau`` is accepted
    when its ``G`` exceeds ``threshold``: ``"bonferroni"`` chi2(6) at ``(1 - level) / #taus``;
    ``"bootstrap"`` the ``level`` quantile of ``max G`` over ``replicates`` Gaussian residual vectors of
    the same variances through the same ``M`` (the smoother held fixed); ``"fit_bootstrap"`` the same
    with the data ``y* = H y + e*`` (a parametric bootstrap from the adaptive fit, the smoother held
    fixed: ``M y* = M H y + M e*`` carries the smoother's bias on its own fit); ``"refit_bootstrap"``
    the parametric bootstrap itself: ``y* = H y + e*`` smoothed again by the adaptive spline (its ``lam``
    and weight chosen again) and scanned, ``replicates`` times. Repeated while accepted, at
    most ``max_events``. ``statistic="criterion"``: ``z_i^2 = ((M x)' y_i)^2 / (s_i^2 x' M x)`` instead (the
    penalised criterion's drop when the column is added, the smoother held fixed: the earlier scan's
    gain, over the component's own residual variance instead of the registration's noise).
    Returns ``(events, log)``, log rows ``(tau, G, threshold, accepted)``."""
    from scipy.stats import chi2

    from horsemocap.splines import truncated_power_columns
    rng = np.random.default_rng(0) if rng is None else rng
    n = t.size
    taus = 0.5 * (t[5:-6] + t[6:-5])
    X = truncated_power_columns(t, taus, 2)
    events, log = [], []
    for _ in range(max_events):
        G = np.zeros(taus.size)
        Gb = np.zeros((taus.size, replicates))
        for i in range(Y.shape[1]):
            H, _ = _adaptive_hat(t, Y[:, i], events)
            M = np.eye(n) - H
            MX = M @ X
            r = M @ Y[:, i]
            s2 = float(r @ r) / (n - np.trace(H))
            q = np.einsum("ij,ij->j", MX, MX) if statistic == "score" else np.einsum("ij,ij->j", X, MX)
            # a column the smoother reproduces (x' M x at rounding level, negative: tau at the record's
            # start) carries no jump: left out
            q = np.where(q > 1e-13 * np.einsum("ij,ij->j", X, X), q, np.inf)
            norm = np.sqrt(s2 * q)
            G += (MX.T @ Y[:, i] / norm) ** 2
            if threshold == "refit_bootstrap":
                fit = H @ Y[:, i]
                for b in range(replicates):
                    yb = fit + rng.normal(0, np.sqrt(s2), n)
                    Hb, _ = _adaptive_hat(t, yb, events)
                    MXb = (np.eye(n) - Hb) @ X
                    rb = yb - Hb @ yb
                    s2b = float(rb @ rb) / (n - np.trace(Hb))
                    qb = (np.einsum("ij,ij->j", MXb, MXb) if statistic == "score"
                          else np.einsum("ij,ij->j", X, MXb))
                    qb = np.where(qb > 1e-13 * np.einsum("ij,ij->j", X, X), qb, np.inf)
                    Gb[:, b] += (MXb.T @ yb) ** 2 / (s2b * qb)
            elif threshold != "bonferroni":
                e = rng.normal(0, np.sqrt(s2), (n, replicates))
                if threshold == "fit_bootstrap":
                    e += (M @ (H @ Y[:, i]))[:, None]       # y* = H y + e*: the smoother's own bias of its fit
                Gb += (MX.T @ e / norm[:, None]) ** 2
        near = np.zeros(taus.size, bool)
        for e in events:
            near |= np.abs(taus - e) < 3.5 * float(np.median(np.diff(t)))
        G[near] = 0
        Gb[near] = 0
        best = int(np.argmax(G))
        thr = (float(chi2.isf((1 - level) / taus.size, Y.shape[1])) if threshold == "bonferroni"
               else float(np.quantile(Gb.max(0), level)))
        ok = G[best] > thr
        log.append((float(taus[best]), float(G[best]), thr, bool(ok)))
        if not ok:
            break
        events = sorted(events + [float(taus[best])])
    return events, log


def detect_main(argv):
    """``--detect``: the data-driven onset detection (:func:`_detect_onsets`) on every fixture."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--detect", action="store_true")
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--fixtures", default=",".join(FIXTURES))
    ap.add_argument("--threshold", default="bootstrap", choices=["bootstrap", "fit_bootstrap", "refit_bootstrap", "bonferroni"])
    ap.add_argument("--statistic", default="score", choices=["score", "criterion"])
    ap.add_argument("--replicates", type=int, default=200)
    ap.add_argument("--max-events", type=int, default=3)
    args = ap.parse_args(argv)
    from horsemocap import pose, synthetic
    print(f"onset detection, statistic {args.statistic}, threshold {args.threshold}: per draw the scans (tau s, G, threshold, accepted), "
          "then the errors (vel, acc, omega, alpha %) of adaptive, adaptive + detected events, adaptive + true onset")
    for name in args.fixtures.split(","):
        fx = FIXTURES[name]
        onset = fx.get("ring_start_s", 2.8) if fx.get("ring_scale", 1.0) else None
        rows = {"adaptive": [], "detected": [], "true onset": []}
        t0 = time.perf_counter()
        for seed in range(args.draws):
            d = synthetic.lift_with_ringing(seed=seed, **fx)
            reg, tr0, Y = _components(d)
            ev, log = _detect_onsets(d["t"], Y, threshold=args.threshold, rng=np.random.default_rng(seed),
                                     statistic=args.statistic, replicates=args.replicates,
                                     max_events=args.max_events)
            print(f"{name} draw {seed} (true onset {onset}): "
                  + "; ".join(f"{a:.3f} {g:.1f}/{th:.1f}{'*' if ok else ''}" for a, g, th, ok in log)
                  + f" -> events {[round(e, 3) for e in ev]}")
            for row, e in (("adaptive", None), ("detected", ev or None),
                           ("true onset", None if onset is None else [onset])):
                tr = pose.fit_pose_trajectory(d["t"], reg, d["model"],
                                              PoseParams(smoothing="adaptive", harmonics="none", events=e))
                rows[row].append(score(d, tr))
        for row, res in rows.items():
            print(f"  {name:12s} {row:11s} " + " ".join(f"{v:6.1f}" for v in np.median(res, 0))
                  + "  acc per draw " + " ".join(f"{r[1]:5.1f}" for r in res))
        print(f"  ({(time.perf_counter() - t0) / args.draws:.1f} s per draw)", flush=True)


def main():
    import sys
    if "--detect" in sys.argv:
        return detect_main(sys.argv[1:])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--fixture", default="issue13", choices=sorted(FIXTURES))
    args = ap.parse_args()
    from horsemocap import pose, splines, synthetic

    fx = FIXTURES[args.fixture]
    onset = fx.get("ring_start_s", 2.8)
    print(f"fixture {args.fixture}: {fx}")
    draws = [synthetic.lift_with_ringing(seed=s, **fx) for s in range(args.draws)]
    data = [_components(d) for d in draws]
    sigmas = [pose.pose_noise(reg, d["markers"], d["model"]) for d, (reg, _, _) in zip(draws, data)]
    truth = []
    for d in draws:
        reg = pose.register_pose(d["markers_true"], d["model"])
        tr = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(smoothing="none", harmonics="none"))
        truth.append(list(tr.centre_splines) + list(tr.rotvec_splines))
    rows = {"adaptive": lambda k: (lambda t, y, i: splines.smoothing_spline(t, y, method="adaptive")),
            "one-sided x1": lambda k: _one_sided(1), "one-sided x2": lambda k: _one_sided(2),
            "one-sided x3": lambda k: _one_sided(3), "oracle weight": lambda k: _one_sided(1, truth[k]),
            "IRLS L1": lambda k: _irls("l1"), "IRLS Cauchy": lambda k: _irls("cauchy")}
    print(f"{'smoother':16s} {'vel_%':>6s} {'acc_%':>6s} {'omega_%':>7s} {'alpha_%':>7s}  acc_% per draw   time_s")
    for name, make in rows.items():
        res, t0 = [], time.perf_counter()
        for k, (d, (reg, tr0, Y)) in enumerate(zip(draws, data)):
            fit = make(k)
            res.append(_score(d, tr0, [fit(d["t"], Y[:, i], i) for i in range(6)]))
        print(f"{name:16s} " + " ".join(f"{v:6.1f}" for v in np.median(res, 0))
              + "  " + " ".join(f"{r[1]:5.1f}" for r in res) + f"  {(time.perf_counter() - t0) / len(draws):6.1f}")
    for order in (2, 3):
        best = None
        for c in (0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0):
            res = []
            for d, (reg, tr0, Y), sigma in zip(draws, data, sigmas):
                res.append(_score(d, tr0, [_Discrete(d["t"], _trend_filter(Y[:, i], c * sigma[i], order))
                                           for i in range(6)]))
            if best is None or np.median(res, 0)[1] < best[1][1]:
                best = (c, np.median(res, 0), res)
        name = f"L1 trend k={order}"
        print(f"{name:16s} " + " ".join(f"{v:6.1f}" for v in best[1]) + "  "
              + " ".join(f"{r[1]:5.1f}" for r in best[2]) + f"  (lam = {best[0]} sigma, best on the truth)")
    print(f"onset scan (true onset {onset} s): best tau, its gain; best gain > 50 ms from the onset, its tau")
    for k, (d, (reg, tr0, Y), sigma) in enumerate(zip(draws, data, sigmas)):
        tau, g, gfar, taufar = _onset_scan(d["t"], Y, sigma, onset)
        print(f"  draw {k}: {tau:.3f} s {g:6.1f}; {gfar:6.1f} at {taufar:.3f} s")
    print("targets (issue 13): hidden-point acceleration < 15 %, omega < 10 % of their rms")


if __name__ == "__main__":
    main()
