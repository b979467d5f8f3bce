"""Pose-trajectory kinematics on a non-periodic rigid motion with ringing (issue 13).

:func:`horsemocap.synthetic.lift_with_ringing`: a marker box lifted, held, set
down and ringing at 10 Hz, 100 Hz, 0.3 mm marker noise, exact truth. For each
pose smoothing (the default gcv with the stride harmonics, ``harmonics="auto"``, which a
non-periodic record should leave out; plain gcv, adaptive, cubic) the hidden point's velocity and acceleration and the body's
omega and alpha are compared with the truth (RMSE of the vector error as a
percentage of the truth's rms), over several noise draws. The thesis' chain
of fits is not run: it needs a periodic record.

Row ``auto``: the default smoothing (:func:`horsemocap.pose.choose_smoothing`: gcv with the stride
harmonics on a periodic record, adaptive on a record without a fundamental, as these); the rows print
what ran and why.

Rows ``+event``: the same smoothing with the ringing's onset given as a known change point
(``events`` of :func:`horsemocap.pose.fit_pose_trajectory`: an unpenalised ``(t - tau)_+^2``, a
jump of the acceleration; as from a force plate). The onset is the fixture's, not detected.

``--fixture second``: another non-periodic motion built the same way with other numbers (200 Hz,
6 Hz and 14 Hz modes, 0.5 s decay, 30 ms onset from 2.9 s), to check that a smoother is not
tuned to the first.

Fixtures ``noring`` (no ringing), ``ring4hz`` (4 Hz, 0.6 s decay, 100 Hz), ``ring25hz200`` (25 Hz,
0.15 s decay, 200 Hz) and ``ringmoving`` (the ring from 2.4 s, during the set-down, 40 ms onset): other
non-periodic motions, not used to develop the L-spline (notch) smoothing of the ringing, a negative
result moved out of the package: ``bench_kinematics_modal.py`` (its row ``modal``, the modes it finds).

Row ``oracle_lti`` (uses the truth): the best a time-invariant linear smoother can do
(:func:`oracle_time_invariant`): a bound for a notch / L-spline or a stochastic cycle with constant
parameters.

``--covariance``: the markers' noise as a triangulation gives it (:func:`triangulated_noise`): each
marker's covariance ``R diag(s_depth^2, s^2, s^2) R^T``, the depth axis along the mean viewing
direction of the cameras that see it, ``s_depth / s`` 3-10 per marker (at 0.25 px the herd rig's
markers have 14.7 / 6.8 / 64.6 mm in x / y / z, benchmarks/README.md), ``s`` per marker and over time
(stretches seen by two cameras instead of three: variance x 2-4, the depth axis from those two), scaled
so that the mean marker variance is the fixture's (0.3 mm per axis); the noise drawn from these
covariances and the covariances passed to :func:`horsemocap.pose.register_pose`, as the pipeline does.
``--covariance strong``: a larger variation (:data:`NOISE_VARIATION`), a check beyond that model.
Row ``gcv_equal``: gcv with ``rotation_weights="equal"`` (row ``gcv`` weights each rotation component's
frames by their predicted variance when the registration has information matrices, ``"auto"``).

Usage: ``python benchmarks/bench_kinematics.py [--draws 3] [--fixture NAME] [--rows gcv,oracle_lti,...]
[--covariance [strong]]``

Smoothers tried without the onset given (a one-sided roughness envelope, heavy-tailed jerk, L1 trend
filtering, a scan for the onset), none meeting the targets: ``bench_kinematics_tries.py``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


FIXTURES = {"issue13": {},
            "second": {"fps": 200.0, "ring_hz": 6.0, "second_ring_hz": 14.0, "ring_decay_s": 0.5,
                       "ring_rise_s": 0.03, "ring_start_s": 2.9},
            # fixtures the modal smoothing (bench_kinematics_modal.py) was not developed on
            "noring": {"ring_scale": 0.0},
            "ring4hz": {"ring_hz": 4.0, "ring_decay_s": 0.6},
            "ring25hz200": {"fps": 200.0, "ring_hz": 25.0, "ring_decay_s": 0.15},
            "ringmoving": {"ring_start_s": 2.4, "ring_rise_s": 0.04}}

ROWS = {"auto": ("auto", 5, "auto", False),
        "gcv+harm": ("gcv", 5, "auto", False), "gcv": ("gcv", 5, "none", False),
        "adaptive": ("adaptive", 5, "none", False), "gcv_cubic": ("gcv", 3, "none", False),
        "gcv+event": ("gcv", 5, "none", True), "adaptive+event": ("adaptive", 5, "none", True),
        "oracle_lti": ("gcv", 5, "none", False), "gcv_equal": ("gcv", 5, "none", False)}
ROTATION_WEIGHTS = {"gcv_equal": "equal"}     # rotation_weights of a row; "auto" otherwise
# --covariance: the variation of the markers' noise (triangulated_noise's keywords); "strong" a check beyond the
# two-of-three-cameras stretches (x 2-10, twice as many and longer, markers 0.5-2 times each other's sigma)
NOISE_VARIATION = {"triangulation": {},
                   "strong": {"lost_factor": (2.0, 10.0), "lost_stretches": 4, "lost_s": (0.5, 1.5),
                              "marker_scale": (0.5, 2.0)}}

# the rig of --covariance: three cameras 4 m in front of the box (y up), 1.5 m high, 35 deg apart
CAMERAS = np.array([[4 * np.sin(a), 1.5, -4 * np.cos(a)] for a in np.radians([-35.0, 0.0, 35.0])])


def pct(est, true):
    from horsemocap.accuracy import rmse_pct_of_rms

    return rmse_pct_of_rms(est, true)


def score(d, tr):
    """The hidden point's velocity and acceleration and the body's omega and alpha of a pose trajectory
    ``tr`` against the fixture ``d``'s truth (:func:`pct` each)."""
    k = tr.point(d["t"], d["hidden_body"])
    return (pct(k.velocity, d["hidden_vel"]), pct(k.acceleration, d["hidden_acc"]),
            pct(tr.omega(d["t"]), d["omega"]), pct(tr.alpha(d["t"]), d["alpha"]))


def triangulated_noise(markers_true, t, noise_m, seed, cameras=CAMERAS, depth_ratio=(3.0, 10.0),
                       lost_factor=(2.0, 4.0), lost_stretches=2, lost_s=(0.3, 1.0), marker_scale=(0.7, 1.4)):
    """Per-frame anisotropic marker covariances as a triangulation gives them, and noise drawn from them.

    Each marker ``m`` at frame ``k``: ``C = s^2 (d_m^2 u u^T + (I - u u^T))`` with ``u`` the mean of the
    unit directions from the marker to the cameras that see it, ``d_m`` (depth / across) drawn in
    ``depth_ratio``, ``s^2`` a per-marker scale (``marker_scale``, squared) times ``f`` in ``lost_factor``
    for ``lost_stretches`` stretches of ``lost_s`` seconds in which one camera (random) does not see the
    marker (1 elsewhere; where stretches overlap the first holds: a marker always has two cameras). The
    whole is scaled so that the mean of ``trace(C) / 3`` is ``noise_m^2``.

    Returns
    -------
    markers : (n, m, 3) ``markers_true`` plus the noise; cov : (n, m, 3, 3); info : dict (the fraction
    of marker-frames seen by two cameras, the depth ratios).
    """
    rng = np.random.default_rng(10_000 + seed)
    n, m, _ = markers_true.shape
    seen = np.ones((n, m, len(cameras)), bool)
    factor = np.ones((n, m))
    for j in range(m):
        for _ in range(lost_stretches):
            length = int(round(rng.uniform(*lost_s) / (t[1] - t[0])))
            start = rng.integers(0, n - length)
            frames = start + np.flatnonzero(seen[start:start + length, j].all(-1))   # one camera lost at most
            seen[frames, j, rng.integers(len(cameras))] = False
            factor[frames, j] = rng.uniform(*lost_factor)
    rays = cameras[None, None] - markers_true[:, :, None]
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    u = np.sum(rays * seen[..., None], axis=2)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    ratio = rng.uniform(*depth_ratio, size=m)
    s2 = rng.uniform(*marker_scale, size=m) ** 2 * factor
    uu = u[..., :, None] * u[..., None, :]
    cov = s2[..., None, None] * ((ratio[None, :, None, None] ** 2 - 1) * uu + np.eye(3))
    cov *= noise_m ** 2 / np.mean(np.trace(cov, axis1=-2, axis2=-1) / 3)
    noise = np.einsum("nmij,nmj->nmi", np.linalg.cholesky(cov), rng.standard_normal((n, m, 3)))
    return markers_true + noise, cov, {"two_cameras": float(np.mean(seen.sum(-1) < len(cameras))),
                                      "depth_ratio": ratio}


def oracle_time_invariant(d, reg, tr):
    """A bound for time-invariant linear smoothers (any notch or L-spline, a stochastic cycle with
    constant parameters, a Wiener filter): each pose component's cosine transform (DCT-II, the mirror
    extension at the ends) multiplied by the oracle gain ``X_k^2 / (X_k^2 + N_k^2)`` of the truth's
    coefficient ``X_k`` (the noise-free markers registered) and this draw's noise ``N_k``, the
    derivatives from the quintic interpolant of the result (as the modal smoothing of
    ``bench_kinematics_modal.py``). Uses the truth."""
    from dataclasses import replace

    from scipy.fft import dct, idct
    from scipy.interpolate import make_interp_spline
    from scipy.spatial.transform import Rotation

    from horsemocap import pose, splines

    true = pose.register_pose(d["markers_true"], d["model"])
    ref = Rotation.from_matrix(tr.reference)
    X = np.column_stack([true.centre, pose.unwrap_rotvec((Rotation.from_matrix(true.rotation) * ref.inv()).as_rotvec())])
    Y = np.column_stack([reg.centre, tr.rotvec_data])
    xk, nk = dct(X, norm="ortho", axis=0), dct(Y - X, norm="ortho", axis=0)
    F = idct(xk ** 2 / np.maximum(xk ** 2 + nk ** 2, 1e-300) * dct(Y, norm="ortho", axis=0), norm="ortho", axis=0)
    ss = [splines.SmoothingSpline(make_interp_spline(d["t"], F[:, i], k=5), {}) for i in range(6)]
    return replace(tr, centre_splines=tuple(ss[:3]), rotvec_splines=tuple(ss[3:]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--fixture", default="issue13", choices=sorted(FIXTURES))
    ap.add_argument("--rows", default=",".join(ROWS), help="comma-separated rows: " + ", ".join(ROWS))
    ap.add_argument("--covariance", nargs="?", const="triangulation", choices=sorted(NOISE_VARIATION),
                    help="triangulation-like anisotropic per-frame marker noise, covariances to register_pose "
                         "('strong': a larger variation over time and markers)")
    args = ap.parse_args()
    unknown = sorted(set(args.rows.split(",")) - set(ROWS))
    if unknown:
        ap.error(f"--rows: unknown {unknown} (rows: {', '.join(ROWS)}; the modal row: bench_kinematics_modal.py)")
    print(f"fixture {args.fixture}: {FIXTURES[args.fixture]}"
          + (f" (--covariance {args.covariance}: triangulation-like marker noise and covariances, "
             f"{NOISE_VARIATION[args.covariance] or 'two of three cameras x 2-4'})" if args.covariance else ""))
    from horsemocap import pose, synthetic

    print(f"{'smoothing':13s} {'draw':>4s} {'noise_mm':>8s} {'vel_%':>6s} {'acc_%':>6s} {'omega_%':>7s} "
          f"{'alpha_%':>7s} {'time_s':>6s}")
    onset = FIXTURES[args.fixture].get("ring_start_s", 2.8)
    for name in args.rows.split(","):
        method, order, harmonics, with_onset = ROWS[name]
        events = [onset] if with_onset else None
        res = []
        for seed in range(args.draws):
            d = synthetic.lift_with_ringing(seed=seed, **FIXTURES[args.fixture])
            cov = None
            if args.covariance:
                d["markers"], cov, noise_info = triangulated_noise(d["markers_true"], d["t"], d["noise_m"], seed,
                                                                   **NOISE_VARIATION[args.covariance])
                if name == args.rows.split(",")[0]:
                    print(f"{'':13s} draw {seed}: two cameras on {100 * noise_info['two_cameras']:.0f} % of "
                          f"marker-frames, depth / across " + " ".join(f"{r:.1f}" for r in noise_info["depth_ratio"]))
            t0 = time.perf_counter()
            reg = pose.register_pose(d["markers"], d["model"], covariance=cov)
            tr = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(
                smoothing="gcv_cubic" if order == 3 else method, harmonics=harmonics, events=events,
                rotation_weights=ROTATION_WEIGHTS.get(name, "auto")))
            if name == "oracle_lti":
                tr = oracle_time_invariant(d, reg, tr)
            row = score(d, tr)
            res.append(row)
            if method == "auto" and seed == 0:
                ran = tr.smoothing["cx"]
                print(f"{'':13s} auto ran {ran['smoothing_method']}: {ran['smoothing_reason']}")
            if args.covariance and method == "gcv" and order == 5:
                print(f"{'':13s} draw {seed} rotation weights: "
                      + " ".join(str(tr.smoothing[c].get("weights", "equal")) for c in ("phix", "phiy", "phiz")))
            print(f"{name:13s} {seed:4d} {1000 * reg.noise_m:8.3f} " + " ".join(f"{v:6.1f}" for v in row)
                  + f" {time.perf_counter() - t0:6.1f}")
        print(f"{'median':13s} {'':4s} {'':8s} " + " ".join(f"{v:6.1f}" for v in np.median(res, axis=0)))
    print("targets (issue 13): hidden-point acceleration < 15 %, omega < 10 % of their rms")


if __name__ == "__main__":
    main()
