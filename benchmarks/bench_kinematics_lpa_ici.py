"""LPA-ICI with directional windows on the six ringing fixtures (issue 13): a negative result.

Local polynomial approximation with the intersection-of-confidence-intervals rule (Katkovnik 1999,
IEEE TSP 47(9); Katkovnik, Egiazarian & Astola 2006, ch. 6; relative ICI: Lerga, Vrankic & Sucic 2011,
IEEE SPL 18(3)) on the six pose components, with left, right and symmetric windows fused by their
inverse variances: one-sided windows should let the samples after the ringing's onset use only the
ringing side without locating the onset. Measured 2026-11-25 (``results/kinematics_ringing_lpa_ici.txt``):
no variant beats ``adaptive`` on issue13 (best 21.0 % against 18.4 %, with Gamma chosen on the truth) and
every one is worse on the other five fixtures (2-35 times on noring). At 100 Hz a 10 Hz ringing is
polynomial over 4-6 samples only, where a one-sided second-derivative estimate is too noisy for the ICI
rule to stop in the right place.

For each sample i, side s in {L, R, S} (left: offsets -(h-1)..0, right: 0..h-1, symmetric:
-(h-1)/2..(h-1)/2, h odd) and window size h, a degree-m least-squares polynomial gives the value, 1st and
2nd derivative at t_i as linear filters g: est = sum_k g[k] y[i+k], std = sigma ||g||. ICI, per
derivative order and side: the largest h whose interval est +- Gamma std still meets all smaller ones.
Fusion: weights 1/std^2 of each side's chosen window.

Usage: ``OMP_NUM_THREADS=1 python benchmarks/bench_kinematics_lpa_ici.py`` (about a minute).

Rows (median over seeds 0-2 of hidden-point acceleration % / omega %):
  adaptive            the library's adaptive quintic spline (cached, common.py)
  LRS m4 G1.5         LPA-ICI, sides L, R, S fused by inverse variances, degree 4, windows 5..41 samples
                      (every admissible size), ICI per derivative order, Gamma 1.5 (literature), noise MAD
  LRS m4 G1.5 regnoise  the same with the registration's noise (pose_noise) instead of the MAD
  LRS m4 GCV          Gamma per component from leave-one-out CV of the fused value estimate (grid 0.5-4)
  LRS m3 GCV          the same, degree 3
  S m4 G2             symmetric windows only, degree 4, Gamma 2 (its best on issue13: chosen on the truth)
  LRS m4 RICI GCV     relative ICI (Rc 0.85), Gamma by CV
  hybrid              adaptive, replaced by LRS m4 G1.5 where the ICI's left/right windows for the 2nd
                      derivative differ by a factor >= 3 (an edge), dilated by 2 samples, per component
  Gamma curve         LRS m4 over Gamma 0.75-3
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from bench_kinematics import FIXTURES, score
from bench_kinematics_tries import _components

def poly_filters(offsets, m, dt, nder=3):
    """Rows r = 0..nder-1: the LS degree-m polynomial's r-th derivative at offset 0 as weights on the
    samples at ``offsets`` (integers), sample spacing ``dt``."""
    k = np.asarray(offsets, float) * dt
    Phi = np.column_stack([k ** j / math.factorial(j) for j in range(m + 1)])
    G = np.linalg.pinv(Phi)                     # (m+1, len): coefficients = derivatives at 0
    return G[:nder]


def window_offsets(side, h):
    if side == "L":
        return np.arange(-(h - 1), 1)
    if side == "R":
        return np.arange(0, h)
    half = (h - 1) // 2
    return np.arange(-half, half + 1)


def default_hs(side, m, hmax=41, hmin=None, count=10):
    """Geometric window sizes (samples) from the smallest that determines a degree-m fit (+1) to hmax."""
    lo = max(m + 2, 3) if hmin is None else hmin
    hs = np.unique(np.round(np.geomspace(lo, hmax, count)).astype(int))
    if side == "S":
        hs = np.unique(hs | 1)                  # odd
        hs = hs[hs >= max(lo, 3)]
    return [int(h) for h in hs]


def directional_estimates(y, dt, m, side, hs, nder=3):
    """est (nh, nder, n) NaN where the window does not fit; norms (nh, nder) = ||g||; g0 (nh, nder)
    the weight on the centre sample (for cross-validation)."""
    n = y.size
    est = np.full((len(hs), nder, n), np.nan)
    norms = np.zeros((len(hs), nder))
    g0 = np.zeros((len(hs), nder))
    for j, h in enumerate(hs):
        off = window_offsets(side, h)
        if off.size > n:
            continue
        G = poly_filters(off, m, dt, nder)
        norms[j] = np.linalg.norm(G, axis=1)
        g0[j] = G[:, np.flatnonzero(off == 0)[0]]
        win = sliding_window_view(y, off.size)            # win[p] = y[p : p+len]
        vals = win @ G.T                                  # (n-len+1, nder): estimate at i = p - off[0]
        i0 = -off[0]
        est[j, :, i0:i0 + vals.shape[0]] = vals.T
    return est, norms, g0


def ici_select(est, std, gamma, rc=None):
    """est (nh, n), std (nh,): index of the ICI window per sample (-1 if none fits). rc: RICI threshold."""
    lo = est - gamma * std[:, None]
    hi = est + gamma * std[:, None]
    lo = np.where(np.isnan(lo), np.inf, lo)                # a window that does not fit breaks the chain
    hi = np.where(np.isnan(hi), -np.inf, hi)
    L = np.maximum.accumulate(lo, axis=0)
    U = np.minimum.accumulate(hi, axis=0)
    ok = L <= U
    if rc is not None:
        ok &= (U - L) / (2 * gamma * std[:, None]) >= rc
    ok = np.logical_and.accumulate(ok, axis=0)
    return ok.sum(0) - 1


def lpa_ici(y, dt, sigma, *, m=3, gamma=1.5, sides=("L", "R", "S"), hmax=41, hs=None, rc=None,
            gammas=None, select="each", grid="geom", hmedian=0):
    """Fused LPA-ICI estimates of value, 1st and 2nd derivative at the samples.

    gammas: optional per-derivative Gamma (3,) overriding gamma.  select="each": ICI separately on each
    derivative's estimates; "value": the windows chosen by ICI on the value estimate, used for all three.
    hmedian: k > 0 median-filters the chosen window indices over 2k+1 samples (Katkovnik et al. 2006).
    grid="geom": default_hs (10 geometric sizes); "dense": every admissible size up to hmax.  Returns (F (3, n), info) with info
    holding the chosen windows per side and derivative and the centre weight of the fused value
    estimate (for leave-one-out cross-validation)."""
    n = y.size
    gam = np.full(3, gamma, float) if gammas is None else np.asarray(gammas, float)
    num = np.zeros((3, n))
    den = np.zeros((3, n))
    cen = np.zeros(n)
    chosen = {}
    edge = [x for x in ("L", "R") if x not in sides]      # used only where no chosen side's window fits
    for s in list(sides) + edge:
        if s in edge and np.all(den[0] > 0):
            continue
        if isinstance(hs, dict):
            hset = hs[s]
        elif hs:
            hset = hs
        elif grid == "dense":
            hset = [h for h in range(max((m if np.isscalar(m) else m[s]) + 2, 3), hmax + 1) if s != "S" or h % 2]
        else:
            hset = default_hs(s, m, hmax)
        ms = m[s] if isinstance(m, dict) else m          # degree per side (dict) or common
        if grid == "dense" and isinstance(m, dict):
            hset = [h for h in range(max(ms + 2, 3), hmax + 1) if s != "S" or h % 2]
        est, norms, g0 = directional_estimates(y, dt, ms, s, hset)
        for r in range(3):
            std = sigma * norms[:, r]
            if select == "each" or r == 0:
                idx = ici_select(est[:, r], std, gam[r], rc)
                if hmedian:                 # median filter of the chosen window index over 2*hmedian+1 samples
                    from scipy.ndimage import median_filter
                    idx = np.where(idx >= 0, median_filter(idx, 2 * hmedian + 1, mode="nearest"), idx)
                    idx = np.minimum(idx, np.sum(np.isfinite(est[:, r]), 0) - 1)   # keep inside the record
            ok = idx >= 0
            ii = np.clip(idx, 0, None)
            e = est[ii, r, np.arange(n)]
            v = std[ii] ** 2
            w = np.where(ok, 1.0 / v, 0.0)
            if s in edge:
                w = np.where(den[r] > 0, 0.0, w) * 1e-30       # tiny: only the edge sides there
            num[r] += w * np.where(ok, e, 0.0)
            den[r] += w
            if r == 0:
                cen += w * g0[ii, 0]
            chosen[(s, r)] = np.where(ok, np.asarray(hset)[ii], 0)
    F = num / den
    return F, {"chosen": chosen, "centre_weight": cen / den[0], "var": 1.0 / den}


def cv_score(y, F0, centre_weight):
    """Leave-one-out cross-validation of the value estimate (the windows held fixed)."""
    r = (y - F0) / np.maximum(1.0 - centre_weight, 1e-3)
    return float(np.mean(r * r))


def mad_sigma(y, order=3):
    """Noise std from the MAD of the order-th differences (white noise: var = C(2k, k) sigma^2)."""
    d = np.diff(y, order)
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / math.sqrt(math.comb(2 * order, order)))


class Discrete:
    """Values and derivatives given at the sample times (spline interface ``(t, derivative)``)."""

    def __init__(self, t, F):
        self.t, self.F, self.info = t, np.asarray(F), {}

    def __call__(self, t, derivative=0):
        return np.interp(t, self.t, self.F[derivative])


def truth_components(d, tr):
    from scipy.spatial.transform import Rotation

    from horsemocap import pose
    true = pose.register_pose(d["markers_true"], d["model"])
    ref = Rotation.from_matrix(tr.reference)
    return np.column_stack([true.centre,
                            pose.unwrap_rotvec((Rotation.from_matrix(true.rotation) * ref.inv()).as_rotvec())])


def load(name, seed):
    """dict: d, tr0, Y (n,6), X (truth, n,6), sig_reg (6,), A (3, n, 6) adaptive values/derivatives at
    the samples, adaptive_score (vel, acc, omega, alpha), adaptive_time."""
    from horsemocap import pose, splines, synthetic
    d = synthetic.lift_with_ringing(seed=seed, **FIXTURES[name])
    reg, tr0, Y = _components(d)
    X = truth_components(d, tr0)
    sig = pose.pose_noise(reg, d["markers"], d["model"])
    t0 = time.perf_counter()
    fits = [splines.smoothing_spline(d["t"], Y[:, i], method="adaptive") for i in range(6)]
    ta = time.perf_counter() - t0
    A = np.stack([np.column_stack([f(d["t"], r) for f in fits]) for r in range(3)])
    rec = {"d": d, "tr0": tr0, "Y": Y, "X": X, "sig_reg": sig, "A": A,
           "adaptive_score": _score_fits(d, tr0, fits), "adaptive_time": ta}
    return rec


def _score_fits(d, tr0, fits):
    return score(d, dataclasses.replace(tr0, centre_splines=tuple(fits[:3]), rotvec_splines=tuple(fits[3:])))


def score_arrays(rec, F):
    """F (3, n, 6): value, 1st, 2nd derivative of the six components at the samples -> (vel, acc, om, al) %."""
    t = rec["d"]["t"]
    return _score_fits(rec["d"], rec["tr0"], [Discrete(t, F[:, :, i]) for i in range(6)])


GRID = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0)
CURVE = (0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)


def fit(rec, gamma, noise="mad", **kw):
    t = rec["d"]["t"]; dt = t[1] - t[0]; Y = rec["Y"]
    F = np.zeros((3,) + Y.shape); infos = []
    for i in range(6):
        s = rec["sig_reg"][i] if noise == "reg" else mad_sigma(Y[:, i])
        g = gamma[i] if np.ndim(gamma) else gamma
        F[:, :, i], info = lpa_ici(Y[:, i], dt, s, gamma=g, **kw)
        info["cv"] = cv_score(Y[:, i], F[0, :, i], info["centre_weight"]) / s ** 2
        infos.append(info)
    return F, infos


def fit_cv(rec, **kw):
    cvs = np.array([[inf["cv"] for inf in fit(rec, g, **kw)[1]] for g in GRID])
    gam = np.array(GRID)[np.argmin(cvs, 0)]
    return fit(rec, gam, **kw)[0], gam


def hybrid(rec, ratio=3.0, dilate=2, **kw):
    F, infos = fit(rec, 1.5, m=4, sides=("L", "R", "S"), grid="dense", **kw)
    H = rec["A"].copy(); frac = []
    for i, inf in enumerate(infos):
        hl, hr = inf["chosen"][("L", 2)].astype(float), inf["chosen"][("R", 2)].astype(float)
        flag = np.maximum(hl, hr) >= ratio * np.maximum(np.minimum(hl, hr), 1)
        flag = np.convolve(flag, np.ones(2 * dilate + 1), "same") > 0
        H[:, flag, i] = F[:, flag, i]; frac.append(flag.mean())
    return H, float(np.mean(frac))


ROWS = {"LRS m4 G1.5": lambda r: fit(r, 1.5, m=4, sides=("L", "R", "S"), grid="dense")[0],
        "LRS m4 G1.5 regnoise": lambda r: fit(r, 1.5, "reg", m=4, sides=("L", "R", "S"), grid="dense")[0],
        "LRS m4 GCV": lambda r: fit_cv(r, m=4, sides=("L", "R", "S"), grid="dense")[0],
        "LRS m3 GCV": lambda r: fit_cv(r, m=3, sides=("L", "R", "S"), grid="dense")[0],
        "S m4 G2": lambda r: fit(r, 2.0, m=4, sides=("S",), grid="dense")[0],
        "LRS m4 RICI GCV": lambda r: fit_cv(r, m=4, sides=("L", "R", "S"), grid="dense", rc=0.85)[0],
        "hybrid": lambda r: hybrid(r)[0]}

if __name__ == "__main__":
    import warnings
    warnings.simplefilter("ignore")
    table = {}
    for name in FIXTURES:
        recs = [load(name, s) for s in range(3)]
        table[(name, "adaptive")] = (np.median([r["adaptive_score"] for r in recs], 0),
                                     np.mean([r["adaptive_time"] for r in recs]))
        for row, f in ROWS.items():
            res, tt = [], []
            for r in recs:
                t0 = time.perf_counter(); F = f(r); tt.append(time.perf_counter() - t0)
                res.append(score_arrays(r, F))
            table[(name, row)] = (np.median(res, 0), np.mean(tt), [x[1] for x in res])
        for g in CURVE:
            res = [score_arrays(r, fit(r, g, m=4, sides=("L", "R", "S"), grid="dense")[0]) for r in recs]
            table[(name, f"curve {g}")] = (np.median(res, 0), 0)
        gams = [fit_cv(r, m=4, sides=("L", "R", "S"), grid="dense")[1] for r in recs]
        fr = [hybrid(r)[1] for r in recs]
        print(f"{name}: CV Gammas (LRS m4) per draw " + "; ".join(",".join(f"{x:g}" for x in g) for g in gams)
              + f"; hybrid fraction of samples replaced {100*np.mean(fr):.1f} %", flush=True)
        for key in [k for k in table if k[0] == name]:
            v = table[key]
            extra = (" acc per draw " + " ".join(f"{a:5.1f}" for a in v[2])) if len(v) > 2 else ""
            print(f"  {key[1]:22s} acc {v[0][1]:6.1f}  omega {v[0][2]:5.1f}  (vel {v[0][0]:5.1f} alpha {v[0][3]:6.1f})"
                  + (f"  {v[1]:.2f} s/record" if v[1] else "") + extra, flush=True)
    print("\nmarkdown: acc / omega medians")
    cols = ["adaptive"] + list(ROWS)
    print("| fixture | " + " | ".join(cols) + " |")
    for name in FIXTURES:
        print(f"| {name} | " + " | ".join(f"{table[(name, c)][0][1]:.1f} / {table[(name, c)][0][2]:.1f}" for c in cols) + " |")
    print("\nGamma curve LRS m4 (acc / omega)")
    print("| fixture | " + " | ".join(f"G {g}" for g in CURVE) + " |")
    for name in FIXTURES:
        print(f"| {name} | " + " | ".join(f"{table[(name, f'curve {g}')][0][1]:.1f} / {table[(name, f'curve {g}')][0][2]:.1f}" for g in CURVE) + " |")
