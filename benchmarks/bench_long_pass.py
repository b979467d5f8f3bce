"""A long pass through analyze's rigid-body step: the hidden saddle point's acceleration against exact truth.

The trot of ``bench_long_record_basis.py`` (1.7 Hz, stride frequency wandering
by 2 % over 14 s, 0.5 mm white noise) on three markers and on four, the saddle
a body point no camera sees; each record goes through
:func:`horsemocap.rigid.analyse_rigid_body` as the ``rigid_body`` step calls it
(default parameters, the static shot exact, the stride period given as the
motion frame gives it, without the thesis' chain, which nothing passed on uses).
Printed: the saddle's acceleration error (% of its rms, 20 frames at each end
left out), whether the pass was smoothed in windows, and the time. With
``--other-pass``, also the error of a 12 s pass of the same trot (another noise
draw) smoothed with the choices the long pass hands to a recording's other
passes (:func:`horsemocap.passes.pass_smoothing`), against its own choice.

    python benchmarks/bench_long_pass.py MARKERS N [N ...] [--other-pass] [--fps HZ]
"""
import argparse
import time

import numpy as np
from scipy.spatial.transform import Rotation

from types import SimpleNamespace

from horsemocap.params import AnalysisParams, RigidBodyParams
from horsemocap.passes import pass_smoothing
from horsemocap.rigid import PoseInput, analyse_rigid_body
from horsemocap.threads import blas_single_threaded

FPS = 100.0
MODELS = {3: np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15]]),
          4: np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15], [-0.20, -0.02, -0.15]])}
SADDLE = np.array([0.20, -0.10, -0.15])
STRIDE_HZ = 1.7


def s(t, a, f, p=0.0):
    return a * np.sin(2 * np.pi * f * t + p)


def warp(t):
    return t + 0.02 * 14 / (2 * np.pi) * np.sin(2 * np.pi * t / 14)


def path(t):
    u = warp(t)
    c = np.stack([1.5 * t + s(u, 0.01, 1.7), s(u, 0.03, 3.4) + s(u, 0.008, 6.8, 0.7) + 1.2,
                  s(u, 0.01, 1.7, 0.3)], -1)
    R = Rotation.from_rotvec(np.stack([s(u, 0.03, 1.7, 1.0), s(u, 0.05, 3.4, 0.2), s(u, 0.04, 1.7, 2.0)],
                                      -1)).as_matrix()
    return c, R


def saddle(t):
    c, R = path(t)
    return c + R @ SADDLE


def analysed(markers: int, n: int, seed: int = 0, settled=None, fps: float = FPS):
    """The rigid-body analysis of an n-frame pass, its saddle acceleration error (%) and its time (s)."""
    model = MODELS[markers]
    t = np.arange(n) / fps
    c, R = path(t)
    mk = np.einsum("kij,mj->kmi", R, model) + c[:, None]
    mk = mk + np.random.default_rng(seed).normal(0, 5e-4, mk.shape)
    h = 1e-3
    truth = (saddle(t + h) - 2 * saddle(t) + saddle(t - h)) / h ** 2
    params = RigidBodyParams(saddle_marker=markers)
    t0 = time.time()
    rb = analyse_rigid_body(t, mk, np.vstack([model, SADDLE]), params, period_s=1.0 / STRIDE_HZ,
                            static_index=np.arange(markers), thesis_chain=False, pose_input=PoseInput(settled=settled))
    took = time.time() - t0
    e = slice(20, n - 20)
    a = rb.saddle_acceleration
    err = 100 * np.sqrt(np.mean(np.sum((a[e] - truth[e]) ** 2, 1)) / np.mean(np.sum(truth[e] ** 2, 1)))
    return rb, err, took


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("markers", type=int, choices=sorted(MODELS))
    ap.add_argument("frames", type=int, nargs="+")
    ap.add_argument("--other-pass", action="store_true")
    ap.add_argument("--fps", type=float, default=FPS)
    args = ap.parse_args()
    m, rate = args.markers, args.fps
    with blas_single_threaded():
        for n in args.frames:
            rb, err, took = analysed(m, n, fps=rate)
            windows = getattr(rb.pose, "windows", None)
            how = "whole" if windows is None else f"{len(windows.plan)} windows"
            print(f"{m} markers, {n} frames ({n / rate:.0f} s at {rate:g} Hz): saddle acceleration error "
                  f"{err:.1f} % ({how}, {took:.0f} s)", flush=True)
            if args.other_pass:
                given = pass_smoothing(SimpleNamespace(rigid_body=SimpleNamespace(body=rb), params=AnalysisParams()))
                short = int(12 * rate)
                own = analysed(m, short, seed=7, fps=rate)[1]
                reused = analysed(m, short, seed=7, settled=given, fps=rate)[1]
                print(f"  a {short}-frame pass of the same trot: {reused:.1f} % with the long pass's smoothing, "
                      f"{own:.1f} % with its own", flush=True)
