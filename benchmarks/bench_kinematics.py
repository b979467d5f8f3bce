"""Pose-trajectory kinematics on a non-periodic rigid motion with ringing (issue 13).

:func:`horsemocap.synthetic.lift_with_ringing`: a marker box lifted, held, set
down and ringing at 10 Hz, 100 Hz, 0.3 mm marker noise, exact truth. For each
pose smoothing (the default gcv with the stride harmonics, ``harmonics="auto"``, which a
non-periodic record should leave out; plain gcv, adaptive, cubic) the hidden point's velocity and acceleration and the body's
omega and alpha are compared with the truth (RMSE of the vector error as a
percentage of the truth's rms), over several noise draws. The thesis' chain
of fits is not run: it needs a periodic record.

Rows ``+event``: the same smoothing with the ringing's onset given as a known change point
(``events`` of :func:`horsemocap.pose.fit_pose_trajectory`: an unpenalised ``(t - tau)_+^2``, a
jump of the acceleration; as from a force plate). The onset is the fixture's, not detected.

``--fixture second``: another non-periodic motion built the same way with other numbers (200 Hz,
6 Hz and 14 Hz modes, 0.5 s decay, 30 ms onset from 2.9 s), to check that a smoother is not
tuned to the first.

Usage: ``python benchmarks/bench_kinematics.py [--draws 3] [--fixture issue13|second]``

Smoothers tried without the onset given (a one-sided roughness envelope, heavy-tailed jerk, L1 trend
filtering, a scan for the onset), none meeting the targets: ``bench_kinematics_tries.py``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


FIXTURES = {"issue13": {},
            "second": {"fps": 200.0, "ring_hz": 6.0, "second_ring_hz": 14.0, "ring_decay_s": 0.5,
                       "ring_rise_s": 0.03, "ring_start_s": 2.9}}


def pct(est, true):
    return 100 * np.sqrt(np.nanmean(np.sum((est - true) ** 2, -1))) / np.sqrt(np.mean(np.sum(true ** 2, -1)))


def score(d, tr):
    """The hidden point's velocity and acceleration and the body's omega and alpha of a pose trajectory
    ``tr`` against the fixture ``d``'s truth (:func:`pct` each)."""
    k = tr.point(d["t"], d["hidden_body"])
    return (pct(k.velocity, d["hidden_vel"]), pct(k.acceleration, d["hidden_acc"]),
            pct(tr.omega(d["t"]), d["omega"]), pct(tr.alpha(d["t"]), d["alpha"]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--fixture", default="issue13", choices=sorted(FIXTURES))
    args = ap.parse_args()
    print(f"fixture {args.fixture}: {FIXTURES[args.fixture]}")
    from horsemocap import pose, synthetic

    print(f"{'smoothing':13s} {'draw':>4s} {'noise_mm':>8s} {'vel_%':>6s} {'acc_%':>6s} {'omega_%':>7s} "
          f"{'alpha_%':>7s} {'time_s':>6s}")
    onset = FIXTURES[args.fixture].get("ring_start_s", 2.8)
    for method, order, harmonics, events in (("gcv", 5, "auto", None), ("gcv", 5, "none", None),
                                             ("adaptive", 5, "none", None), ("gcv", 3, "none", None),
                                             ("gcv", 5, "none", [onset]), ("adaptive", 5, "none", [onset])):
        res = []
        for seed in range(args.draws):
            d = synthetic.lift_with_ringing(seed=seed, **FIXTURES[args.fixture])
            t0 = time.perf_counter()
            reg = pose.register_pose(d["markers"], d["model"])
            tr = pose.fit_pose_trajectory(d["t"], reg, d["model"], smoothing=method, order=order,
                                          harmonics=harmonics, events=events)
            row = score(d, tr)
            res.append(row)
            name = (method + ("" if order == 5 else "_cubic") + ("" if harmonics == "none" else "+harm")
                    + ("" if events is None else "+event"))
            print(f"{name:13s} {seed:4d} {1000 * reg.noise_m:8.3f} " + " ".join(f"{v:6.1f}" for v in row)
                  + f" {time.perf_counter() - t0:6.1f}")
        print(f"{'median':13s} {'':4s} {'':8s} " + " ".join(f"{v:6.1f}" for v in np.median(res, axis=0)))
    print("targets (issue 13): hidden-point acceleration < 15 %, omega < 10 % of their rms")


if __name__ == "__main__":
    main()
