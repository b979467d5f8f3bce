"""A long three-marker record smoothed whole against in windows: the spline basis's cap.

Three markers trotting at 1.7 Hz (the centroid and rotation of
``tests/test_streaming.py``'s trot) whose stride frequency wanders by 2 % over
14 s, 0.5 mm white noise, the hidden point's exact acceleration (central
differences of the exact path, 1 ms). Each length is fitted whole
(:func:`horsemocap.pose.fit_pose_trajectory`, the kinematics command's default
parameters) and in windows (:func:`horsemocap.streaming.windowed_kinematics`,
the smoothing settled on the middle); the hidden point's acceleration error (%
of its rms, 20 frames at each end left out) and the time of each.

    python benchmarks/bench_long_record_basis.py RATE_HZ N [N ...]
"""
import sys
import time

import numpy as np
from scipy.spatial.transform import Rotation
from horsemocap import pose, streaming
from horsemocap.io3d import kinematics_params
FPS = float(sys.argv[1])
MODEL = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15]])
HIDDEN = np.array([0.20, -0.10, -0.15])
def s(t, a, f, p=0.0): return a * np.sin(2 * np.pi * f * t + p)
def warp(t): return t + 0.02 * 14 / (2 * np.pi) * np.sin(2 * np.pi * t / 14)
def path(t):
    u = warp(t)
    c = np.stack([1.5 * t + s(u, 0.01, 1.7), s(u, 0.03, 3.4) + s(u, 0.008, 6.8, 0.7) + 1.2, s(u, 0.01, 1.7, 0.3)], -1)
    R = Rotation.from_rotvec(np.stack([s(u, 0.03, 1.7, 1.0), s(u, 0.05, 3.4, 0.2), s(u, 0.04, 1.7, 2.0)], -1)).as_matrix()
    return c, R
def hidden(t):
    c, R = path(t); return c + R @ HIDDEN
for n in [int(a) for a in sys.argv[2:]]:
    t = np.arange(n) / FPS
    c, R = path(t)
    mk = np.einsum("kij,mj->kmi", R, MODEL) + c[:, None] + np.random.default_rng(0).normal(0, 5e-4, (n, 3, 3))
    h = 1e-3
    acc = (hidden(t + h) - 2 * hidden(t) + hidden(t - h)) / h ** 2
    reg = pose.register_pose(mk, MODEL)
    e = slice(20, n - 20)
    def err(a): return 100 * np.sqrt(np.mean(np.sum((a[e] - acc[e]) ** 2, 1)) / np.mean(np.sum(acc[e] ** 2, 1)))
    t0 = time.time()
    fit = pose.fit_pose_trajectory(t, reg, MODEL, kinematics_params(), points=mk)
    w = err(fit.points(t, HIDDEN[None]).acceleration[:, 0]); tw = time.time() - t0
    t0 = time.time()
    settled = streaming.settle_smoothing(t, reg, mk, MODEL, kinematics_params(), window=streaming.WINDOW_FRAMES)
    blocks = list(streaming.windowed_kinematics(t, reg, mk, MODEL, np.vstack([MODEL, HIDDEN]), kinematics_params(), settled=settled))
    a = np.concatenate([b.acceleration for b in blocks], 0)[:, -1]
    print(f"{FPS:g} Hz n {n} ({n / FPS:.0f} s): whole {w:.1f} % ({tw:.0f} s)  windows {err(a):.1f} % ({time.time() - t0:.0f} s)", flush=True)
