"""Herd sessions with realistic marker noise: correlated over frames, with per-marker biases.

Renders short records (3 fully visible strides, genlocked thesis rig, no
calibration views) of herd sessions with
``render_session(marker_noise=MarkerNoise(...))`` into the cache, runs
``pipeline.analyze`` with the automatic choices and prints the saddle's
vertical acceleration error (% of rms) and the errors of the Wb/Wk-weighted
rms against the truth, with what the pose smoothing chose and why.

Usage: ``python benchmarks/bench_marker_noise.py [--sigma 0.3 --rho 0.8 --bias 0.2] [--trace]``
(a few minutes per session on first use; writes
``benchmarks/results/marker_noise.txt``). ``--trace``: where the error comes
from, appended to that file: each session also with the static shot replaced by
its true markers, with the analysed frames' triangulated markers replaced by
the true ones (the static shot as measured), and the static shot's error per
point.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from horsemocap import accuracy
from horsemocap.data import cache_dir
from horsemocap import pipeline
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.virtuallab import load_truth
from horsemocap.virtuallab.herd import RENDER_VERSION, herd_seed, render_into_cache, short_record
from horsemocap.virtuallab.horse import saddle_motion
from horsemocap.virtuallab.noise import MarkerNoise
from horsemocap.virtuallab.rig import FPS, thesis_rig
from horsemocap.virtuallab.session import Scene, render_session

HERE = Path(__file__).resolve().parent
SESSIONS = (("Horse 2", "canter"), ("Horse 2", "sitting_trot"))
KEYS = ("acc_y_Wb_rms", "acc_y_Wk_rms")


def noisy_session(horse: str, gait: str, noise: MarkerNoise) -> Path:
    """A short herd record with ``noise``, rendered into the cache on first use."""
    blob = json.dumps({"v": RENDER_VERSION, "h": horse, "g": gait, "noise": noise.to_dict(), "strides": 3},
                      sort_keys=True)
    key = hashlib.sha256(blob.encode()).hexdigest()[:12]
    folder = cache_dir() / "virtuallab" / f"marker-noise_{horse.lower().replace(' ', '')}_{gait}-{key}"
    seed = herd_seed(horse, gait)

    def render(tmp):
        scene = Scene(thesis_rig(), saddle_motion(horse, gait), seed)
        offsets, n_after = short_record(scene, FPS, 8, None, strides=3.0)
        render_session(tmp, horse, gait, seed=seed, calibration_views=0, n_motion_frames=n_after,
                       name=f"marker_noise_{gait}", marker_noise=noise)

    return render_into_cache(folder, render, "benchmarks/bench_marker_noise.py")


TRACE_HEADER = "Trace (bench_marker_noise.py --trace)"


def _replaced(step: str, replace_result):
    """``pipeline.STEP_CALLS`` with ``step``'s result passed through ``replace_result`` (a context for one run)."""
    original = pipeline.STEP_CALLS[step]

    class _Patch:
        def __enter__(self):
            pipeline.STEP_CALLS[step] = lambda a, pr: replace_result(a, original(a, pr))

        def __exit__(self, *exc):
            pipeline.STEP_CALLS[step] = original
    return _Patch()


def _true_markers(truth):
    """A triangulate result with the analysed frames' markers replaced by the true ones."""
    def replace_result(a, r):
        s0, s1 = r.segment
        frames = a.detect.sync.offsets[a.session.reference_camera] + np.arange(s0, s1)
        rows, known = accuracy._truth_rows(truth, frames)
        pts = np.array(r.points, float)
        pts[np.arange(s0, s1)[known]] = np.asarray(truth.marker_pos)[rows][known]
        return dataclasses.replace(r, points=pts)
    return replace_result


def trace(noise: MarkerNoise) -> list:
    """Each session: measured, with the true static shot, with the true markers in the analysed frames."""
    lines = [TRACE_HEADER, f"marker noise {noise.to_dict()}; saddle A_y error %, Wb %, omega rms error (rad/s, x y z)",
             f"{'session':24s} {'variant':34s} {'A_y_%':>6s} {'Wb_%':>6s}  omega"]
    for horse, gait in SESSIONS:
        folder = noisy_session(horse, gait, noise)
        truth = load_truth(folder)
        static_error = {}

        def true_static(a, r):
            static_error["mm"] = 1000 * (np.asarray(r.static_points, float) - truth.static_pos)
            return dataclasses.replace(r, static_points=np.asarray(truth.static_pos, float))
        for label, patch in (("measured", None), ("static shot replaced by the truth", ("static", true_static)),
                             ("analysed frames' markers true", ("triangulate", _true_markers(truth)))):
            if patch is None:
                a = analyze(folder, None, {}, progress=lambda *x: None)
            else:
                with _replaced(*patch):
                    a = analyze(folder, None, {}, progress=lambda *x: None)
            st = accuracy.stage_errors(a, truth)
            ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, KEYS)
            lines.append(f"{horse + ' ' + gait:24s} {label:34s} {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} "
                         f"{ce[KEYS[0]]:6.1f}  {np.round(st['omega'], 2)}")
            print(lines[-1], flush=True)
        err = np.round(static_error["mm"], 1)
        lines.append(f"{'':24s} static shot error (mm, x y z per point, world): {err.tolist()}")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma", type=float, default=0.3, help="AR(1) part's standard deviation per axis (px)")
    ap.add_argument("--rho", type=float, default=0.8, help="its lag-1 autocorrelation")
    ap.add_argument("--bias", type=float, default=0.2, help="per-marker bias standard deviation per axis (px)")
    ap.add_argument("--trace", action="store_true", help="where the error comes from (appended to the results)")
    args = ap.parse_args(argv)
    noise = MarkerNoise(args.sigma, args.rho, args.bias)
    if args.trace:
        path = HERE / "results" / "marker_noise.txt"
        old = path.read_text().split("\n" + TRACE_HEADER)[0].rstrip("\n") + "\n" if path.exists() else ""
        path.write_text(old + "\n" + "\n".join(trace(noise)) + "\n")
        return 0
    lines = [f"Herd records with marker noise {noise.to_dict()} (3 strides, genlocked, pipeline defaults)",
             f"{'session':24s} {'frames':>6s} {'saddle_Ay_%':>11s} " + " ".join(f"{k + '_%':>14s}" for k in KEYS)
             + "  pose smoothing chosen"]
    for horse, gait in SESSIONS:
        t0 = time.perf_counter()
        folder = noisy_session(horse, gait, noise)
        name = f"{horse} {gait}"
        try:
            a = analyze(folder, None, {}, progress=lambda *x: None)
        except AnalysisError as exc:
            lines.append(f"{name:24s} stopped: {str(exc)[:150]}")
            continue
        truth = load_truth(folder)
        st = accuracy.stage_errors(a, truth)
        ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, KEYS)
        pose_fit = getattr(a.rigid_body.body, "pose", None)
        choice = (pose_fit.smoothing_choice if pose_fit is not None else None) or {}
        lines.append(f"{name:24s} {st['frames']:6d} {st['saddle_acc_y_rmse_pct_of_rms']:11.1f} "
                     + " ".join(f"{ce[k]:14.1f}" for k in KEYS) + f"  {choice.get('reason', '')}"
                     + f"  ({time.perf_counter() - t0:.0f} s)")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    (HERE / "results" / "marker_noise.txt").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
