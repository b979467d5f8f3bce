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
point. ``--static-seconds S``: each session also with its static shot a clip of
``S`` seconds of the horse standing (its marker noise evolving over the clip),
averaged by the static step; the still and the clip side by side, with the
static markers' error against the truth (writes
``benchmarks/results/marker_noise_static_clip.txt``). ``--herd``: every horse at
every gait (16 sessions) instead of the two above, with each run's verdict and
the checks it flagged, and whether a run off the targets (A_y 10 %, Wb/Wk 5 %)
ended unreliable (writes ``benchmarks/results/marker_noise_herd.txt``; with
``--static-seconds`` every session with its static clip).
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

from scipy.optimize import linear_sum_assignment

from horsemocap import accuracy, quality
from horsemocap.data import cache_dir
from horsemocap import pipeline
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.reconstruction import triangulate
from horsemocap.virtuallab import load_truth
from horsemocap.virtuallab.herd import RENDER_VERSION, herd_seed, render_into_cache, short_record
from horsemocap.virtuallab.covers import LOWER_FLANK, UPPER_BACK, horse_with_markers
from horsemocap.virtuallab.horse import GAITS, HERD, HORSES, saddle_motion
from horsemocap.virtuallab.noise import MarkerNoise
from horsemocap.virtuallab.rig import FPS, thesis_rig
from horsemocap.virtuallab.session import Scene, render_session

HERE = Path(__file__).resolve().parent
SESSIONS = (("Horse 2", "canter"), ("Horse 2", "sitting_trot"))
KEYS = ("acc_y_Wb_rms", "acc_y_Wk_rms")
#: Every horse at every gait (``--herd``).
HERD_SESSIONS = tuple((h, g) for h in HORSES for g in GAITS)


def noisy_session(horse: str, gait: str, noise: MarkerNoise, static_frames: int = 1, extra_markers=()) -> Path:
    """A short herd record with ``noise``, rendered into the cache on first use; ``static_frames`` > 1: its
    static shot a clip of that many frames (``render_session(static_frames=...)``); ``extra_markers``: body-frame
    centres of markers added to the horse's three (:func:`horsemocap.virtuallab.covers.horse_with_markers`)."""
    spec = {"v": RENDER_VERSION, "h": horse, "g": gait, "noise": noise.to_dict(), "strides": 3}
    if static_frames != 1:
        spec["static_frames"] = int(static_frames)
    if extra_markers:
        spec["extra_markers"] = [list(map(float, m)) for m in extra_markers]
    blob = json.dumps(spec, sort_keys=True)
    key = hashlib.sha256(blob.encode()).hexdigest()[:12]
    spread = f"_spread{3 + len(extra_markers)}" if extra_markers else ""
    folder = cache_dir() / "virtuallab" / f"marker-noise{spread}_{horse.lower().replace(' ', '')}_{gait}-{key}"
    seed = herd_seed(horse, gait)

    def render(tmp):
        scene = Scene(thesis_rig(), saddle_motion(horse, gait), seed)
        if extra_markers:
            motion = dataclasses.replace(scene.motion, horse=horse_with_markers(HERD[horse], extra_markers))
            scene = dataclasses.replace(scene, motion=motion)
        offsets, n_after = short_record(scene, FPS, 8, None, strides=3.0)
        render_session(tmp, horse, gait, seed=seed, calibration_views=0, n_motion_frames=n_after,
                       name=f"marker_noise_{gait}", marker_noise=noise, static_frames=static_frames,
                       scene=scene if extra_markers else None)

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


def trace(noise: MarkerNoise, sessions=SESSIONS, variants=None, extra_markers=()) -> list:
    """Each session: measured, with the true static shot, with the true markers in the analysed frames
    (``variants``: a subset of those labels, default all)."""
    lines = [TRACE_HEADER, f"marker noise {noise.to_dict()}; saddle A_y error %, Wb %, omega rms error (rad/s, x y z)",
             f"{'session':24s} {'variant':34s} {'A_y_%':>6s} {'Wb_%':>6s}  omega"]
    for horse, gait in sessions:
        folder = noisy_session(horse, gait, noise, 1, extra_markers)
        truth = load_truth(folder)
        static_error = {}

        def true_static(a, r):
            static_error["mm"] = 1000 * (np.asarray(r.static_points, float) - truth.static_pos)
            return dataclasses.replace(r, static_points=np.asarray(truth.static_pos, float))
        for label, patch in (("measured", None), ("static shot replaced by the truth", ("static", true_static)),
                             ("analysed frames' markers true", ("triangulate", _true_markers(truth)))):
            if variants is not None and label not in variants:
                continue
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
        if "mm" in static_error:
            err = np.round(static_error["mm"], 1)
            lines.append(f"{'':24s} static shot error (mm, x y z per point, world): {err.tolist()}")
    return lines


def static_error_mm(static_points, truth_points) -> np.ndarray:
    """Each true static point's error (mm, world x y z), the measured points paired with the true ones by least
    total distance."""
    measured, true = np.asarray(static_points, float), np.asarray(truth_points, float)
    rows, cols = linear_sum_assignment(np.linalg.norm(measured[:, None] - true[None], axis=-1))
    err = np.full_like(true, np.nan)
    err[cols] = measured[rows] - true[cols]
    return 1000 * err


def static_error_from_noise(truth, noise: MarkerNoise, seed: int, frames: int) -> dict:
    """The static points' error (mm, world) that the marker noise alone makes: the true points projected into
    every camera, the noise's pixel offsets added, triangulated; for the still (the offsets at time 0), the
    clip (their mean over its frames' times, as the render draws them) and the biases alone."""
    points = np.asarray(truth.static_pos, float)
    noise = dataclasses.replace(noise, frame_rate_hz=FPS)
    clip_t = noise.static_clip_times(frames, 0.0)
    offsets = {"still": lambda c: noise.offsets(seed, c, [0.0], len(points))[0],
               f"clip {frames}": lambda c: noise.offsets(seed, c, clip_t, len(points)).mean(0),
               "bias only": lambda c: noise.bias(seed, c, len(points))}
    out = {}
    for label, offset in offsets.items():
        px = {cam.name: (cam.project(points) + offset(cam.name))[None] for cam in truth.rig}
        out[label] = 1000 * (triangulate(truth.rig, px).points[0] - points)
    return out


def static_clip_comparison(noise: MarkerNoise, seconds: float) -> list:
    """Each session with its static shot a still and a clip of ``seconds``: saddle A_y, Wb, Wk errors, the
    static markers' error and the static_shot check."""
    frames = max(2, int(round(seconds * FPS)))
    lines = [f"Static shot as a still or a clip of {frames} frames ({seconds:g} s at {FPS:g} fps), averaged; marker "
             f"noise {noise.to_dict()} (3 strides, genlocked, pipeline defaults)",
             f"{'session':24s} {'static':14s} {'A_y_%':>6s} {'Wb_%':>6s} {'Wk_%':>6s} {'static_rms_mm':>13s} "
             f"{'worst_mm':>8s} {'check_%':>7s}  clip: frames used / independent, scatter mm, lag-1"]
    for horse, gait in SESSIONS:
        for label, count in (("still", 1), (f"clip {frames}", frames)):
            t0 = time.perf_counter()
            folder = noisy_session(horse, gait, noise, count)
            a = analyze(folder, None, {}, progress=lambda *x: None)
            truth = load_truth(folder)
            st = accuracy.stage_errors(a, truth)
            ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, KEYS)
            err = static_error_mm(a.static.static_points, truth.static_pos)
            dist = np.linalg.norm(err, axis=-1)
            shot = quality.static_shot_of(a)
            check = getattr(shot, "pct_of_rms", float("nan"))
            clip = ""
            if a.static.frames_used is not None:
                clip = (f"{a.static.frames_used} / {a.static.effective_frames:.1f}, "
                        f"{np.round(1000 * a.static.scatter_m, 1).tolist()}, {a.static.scatter_lag1:.2f}")
            lines.append(f"{horse + ' ' + gait:24s} {label:14s} {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} "
                         f"{ce[KEYS[0]]:6.1f} {ce[KEYS[1]]:6.1f} {np.sqrt(np.mean(dist ** 2)):13.1f} "
                         f"{dist.max():8.1f} {check:7.2f}  {clip}  ({time.perf_counter() - t0:.0f} s)")
            lines.append(f"{'':24s} static error (mm, x y z per point, world): {np.round(err, 1).tolist()}")
            print("\n".join(lines[-2:]), flush=True)
        model = static_error_from_noise(truth, noise, herd_seed(horse, gait), frames)
        lines.append(f"{'':24s} the marker noise alone (true points, offsets added, triangulated), mm rms and "
                     "x y z per point:")
        lines += [f"{'':26s}{label:10s} {np.sqrt(np.mean(np.sum(e ** 2, -1))):5.1f}  {np.round(e, 1).tolist()}"
                  for label, e in model.items()]
        print("\n".join(lines[-4:]), flush=True)
    return lines


def herd_run(horse: str, gait: str, noise: MarkerNoise, static_frames: int = 1, extra_markers=()) -> str:
    """One herd session with ``noise``: errors against the truth, the verdict and the checks flagged."""
    t0 = time.perf_counter()
    folder = noisy_session(horse, gait, noise, static_frames, extra_markers)
    name = f"{horse} {gait}"
    try:
        a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{name:24s} exit 2 stopped: {str(exc)[:150]}"
    truth = load_truth(folder)
    st = accuracy.stage_errors(a, truth)
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, KEYS)
    checks = quality.post_checks(a)
    v = quality.verdict(checks)
    a_y = st["saddle_acc_y_rmse_pct_of_rms"]
    off = abs(a_y) > 10 or any(abs(ce[k]) > 5 for k in KEYS)
    judged = ("off, unreliable" if v == "unreliable" else "OFF, NOT FLAGGED") if off else (
        "within, unreliable" if v == "unreliable" else "within")
    flagged = ",".join(f"{c.name}:{c.level}" for c in checks if c.level in ("warning", "unreliable")) or "none"
    return (f"{name:24s} {st['frames']:6d} {a_y:7.1f} " + " ".join(f"{ce[k]:+7.1f}" for k in KEYS)
            + f"  exit {3 if v == 'unreliable' else 0} {v:10s} {judged:18s} [{flagged}]"
            + f"  ({time.perf_counter() - t0:.0f} s)")


def herd_table(noise: MarkerNoise, static_frames: int = 1, extra_markers=()) -> list:
    """Every horse at every gait with ``noise``: one line per session (:func:`herd_run`) and a summary."""
    still = "a still" if static_frames == 1 else f"a clip of {static_frames} frames, averaged"
    rig = (f", {3 + len(extra_markers)} markers (added, body frame: {[list(m) for m in extra_markers]})"
           if extra_markers else "")
    lines = [f"The herd with marker noise {noise.to_dict()}, static shot {still}{rig} (3 strides, genlocked, "
             "pipeline defaults)",
             f"{'session':24s} {'frames':>6s} {'A_y_%':>7s} {'Wb_%':>7s} {'Wk_%':>7s}  verdict, against the "
             "targets (A_y 10 %, Wb/Wk 5 %), checks flagged"]
    for horse, gait in HERD_SESSIONS:
        lines.append(herd_run(horse, gait, noise, static_frames, extra_markers))
        print(lines[-1], flush=True)
    rows = [ln for ln in lines[2:] if " exit 2 " not in ln]
    lines.append(f"{len(rows)} analysed: within {sum(' within ' in r for r in rows)}, within but unreliable "
                 f"{sum('within, unreliable' in r for r in rows)}, off and unreliable "
                 f"{sum('off, unreliable' in r for r in rows)}, off and not flagged "
                 f"{sum('NOT FLAGGED' in r for r in rows)}; stopped {len(lines) - 2 - len(rows)}")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma", type=float, default=0.3, help="AR(1) part's standard deviation per axis (px)")
    ap.add_argument("--rho", type=float, default=0.8, help="its lag-1 autocorrelation")
    ap.add_argument("--bias", type=float, default=0.2, help="per-marker bias standard deviation per axis (px)")
    ap.add_argument("--trace", action="store_true", help="where the error comes from (appended to the results)")
    ap.add_argument("--static-seconds", type=float, default=None,
                    help="also a static clip of this length (s), averaged: results/marker_noise_static_clip.txt")
    ap.add_argument("--herd", action="store_true",
                    help="every horse at every gait, verdicts: results/marker_noise_herd.txt")
    ap.add_argument("--spread", type=int, choices=(4, 5), default=None,
                    help="with --herd: four (a marker high behind the cantle) or five markers (and one low on the "
                         "flank), the spread rigs' markers on the thesis rig: results/marker_noise_herd_spreadN.txt")
    args = ap.parse_args(argv)
    noise = MarkerNoise(args.sigma, args.rho, args.bias)
    static_frames = 1 if args.static_seconds is None else max(1, int(round(args.static_seconds * FPS)))
    extra = () if args.spread is None else (UPPER_BACK, LOWER_FLANK)[:args.spread - 3]
    if args.herd:
        path = HERE / "results" / ("marker_noise_herd.txt" if not extra else f"marker_noise_herd_spread{args.spread}.txt")
        if args.trace:               # the static shot's share: each session again with its true static shot
            old = path.read_text().split("\n" + TRACE_HEADER)[0].rstrip("\n") + "\n" if path.exists() else ""
            lines = trace(noise, HERD_SESSIONS, ("static shot replaced by the truth",), extra)
            path.write_text(old + "\n" + "\n".join(lines) + "\n")
            return 0
        lines = herd_table(noise, static_frames, extra)
        path.write_text("\n".join(lines) + "\n")
        return 0
    if args.static_seconds is not None:
        lines = static_clip_comparison(noise, args.static_seconds)
        path = HERE / "results" / "marker_noise_static_clip.txt"
        kept = [block for block in (path.read_text().split("\n\n") if path.exists() else [])
                if block.strip() and block.splitlines()[0] != lines[0]]      # other clip lengths or noises
        path.write_text("\n\n".join([b.strip("\n") for b in kept] + ["\n".join(lines)]) + "\n")
        print("\n".join(lines))
        return 0
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
