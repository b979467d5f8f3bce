"""A long record with four or more markers under AR(1) noise: the pose smoothing in windows against the whole fit.

Five markers on a trotting back (the centroid and rotation of
``tests/test_left_out_smoothing.py``'s path, stride 1.5 Hz) sampled at
100 Hz with AR(1) noise over frames (correlation 0.8; 1, 1, 3 mm per
axis, independent between markers). The long record is smoothed in windows
(:func:`horsemocap.streaming.windowed_kinematics`, the smoothing settled on the
middle :data:`horsemocap.streaming.REPRESENTATIVE_FRAMES` frames) and, with
``--whole``, whole (:func:`horsemocap.pose.fit_pose_trajectory`); the hidden
point's acceleration is compared with the exact one (rms over the record
without 20 frames at each end, relative to the true rms).

    python benchmarks/bench_blend_settled.py --frames 6000 [--whole] [--seeds 0 1] [--settle-frames N] [--out FILE]

Run it with ``PYTHONPATH`` set to the checkout whose smoothing is measured.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from horsemocap import pose, streaming
from horsemocap.params import PoseParams

RATE_HZ = 100.0
SIGMA = np.array([1e-3, 1e-3, 3e-3])
HIDDEN = np.array([0.0, -0.15, 0.0])
STRIDE_HZ = 1.5
EDGE = 20


def _pose_path(t, ph):
    """The centroid (m) and rotation vector (rad): a trot whose stride phase wanders (the stride frequency
    within 2 % of :data:`STRIDE_HZ`, over 14 s) and whose amplitude swells by 15 % over 25 s, as a ridden
    horse's does: not exactly periodic."""
    wt = 2 * np.pi * STRIDE_HZ * t + 0.4 * np.sin(2 * np.pi * t / 14.0 + ph[0])
    gain = 1.0 + 0.15 * np.sin(2 * np.pi * t / 25.0 + ph[1])
    c = np.column_stack([3.0 * t + 0.02 * gain * np.sin(wt + ph[0]),
                         1.2 + gain * (0.04 * np.sin(2 * wt + ph[1]) + 0.01 * np.sin(3 * wt + ph[2])),
                         0.01 * gain * np.sin(wt + ph[2])])
    phi = np.column_stack([a * gain * np.sin((i + 1) * wt + ph[3 + i]) for i, a in enumerate((0.04, 0.02, 0.03))])
    return c, phi


def _point(t, ph, body_point):
    c, phi = _pose_path(t, ph)
    return c + Rotation.from_rotvec(phi).apply(body_point)


def long_trot(frames: int, seed: int = 0, markers: int = 5, rho: float = 0.8) -> dict:
    """The markers (AR(1) noise), the model and the hidden point's exact acceleration."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / RATE_HZ
    ph = rng.uniform(0, 6, 6)
    x = np.column_stack([rng.uniform(-0.25, 0.25, markers), rng.uniform(-0.03, 0.03, markers),
                         rng.uniform(-0.2, 0.2, markers)])
    x -= x.mean(0)
    c, phi = _pose_path(t, ph)
    clean = c[:, None] + np.einsum("kij,mj->kmi", Rotation.from_rotvec(phi).as_matrix(), x)
    white = rng.normal(0, 1, clean.shape) * np.sqrt(1 - rho ** 2)
    noisy = clean + lfilter([1.0], [1.0, -rho], white, axis=0) * SIGMA
    h = 1e-4
    acc = (_point(t + h, ph, HIDDEN) - 2 * _point(t, ph, HIDDEN) + _point(t - h, ph, HIDDEN)) / h ** 2
    return {"t": t, "markers": noisy, "model": x, "acc": acc}


def relative_error(estimate, truth, edge: int = EDGE) -> float:
    d = (estimate - truth)[edge:-edge]
    return float(np.sqrt(np.mean(np.sum(d ** 2, 1)) / np.mean(np.sum(truth[edge:-edge] ** 2, 1))))


def run(frames: int, seed: int, whole: bool, settle_frames: int = streaming.REPRESENTATIVE_FRAMES) -> dict:
    rec = long_trot(frames, seed)
    t, pts, x = rec["t"], rec["markers"], rec["model"]
    reg = pose.register_pose(pts, x)
    out = {"frames": frames, "seed": seed, "settle_frames": settle_frames}
    start = time.perf_counter()
    settled = streaming.settle_smoothing(t, reg, pts, x, PoseParams(), frames=settle_frames)
    blocks = list(streaming.windowed_kinematics(t, reg, pts, x, HIDDEN[None], PoseParams(), settled=settled))
    out["windows_s"] = round(time.perf_counter() - start, 1)
    acc = np.concatenate([b.acceleration[:, 0] for b in blocks])
    out["windows_error"] = relative_error(acc, rec["acc"])
    out["windows_blend"] = getattr(settled, "blend", None) is not None
    out["windows_reason_tail"] = (settled.choice or {}).get("reason", "")[-200:]
    if whole:
        start = time.perf_counter()
        tr = pose.fit_pose_trajectory(t, reg, x, PoseParams(), points=pts)
        out["whole_s"] = round(time.perf_counter() - start, 1)
        out["whole_error"] = relative_error(tr.point(t, HIDDEN).acceleration, rec["acc"])
        out["whole_reason_head"] = tr.smoothing_choice["reason"][:420]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=6000)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--whole", action="store_true", help="also fit the whole record at once")
    ap.add_argument("--out", help="append the results as JSON lines to this file")
    ap.add_argument("--settle-frames", type=int, default=streaming.REPRESENTATIVE_FRAMES,
                    help="frames at the record's middle the smoothing is settled on")
    args = ap.parse_args()
    for seed in args.seeds:
        result = {"checkout": os.environ.get("PYTHONPATH", ""), **run(args.frames, seed, args.whole, args.settle_frames)}
        print(json.dumps(result), flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(result) + "\n")


if __name__ == "__main__":
    main()
