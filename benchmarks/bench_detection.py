"""Detection throughput against bare OpenCV, timed in the same run.

Bare OpenCV = per frame ``cvtColor(RGB2GRAY) + threshold + connectedComponentsWithStats``
on the whole frame (the least any detector must do). ``detect_markers`` runs
the thesis chain (threshold, labels, area, window, distance, cross-product
filters) plus weighted centres, with

* ``auto``: every choice automatic (threshold, first frame, labels, ...);
* ``given``: the parameters of the automatic run given back (a repeated run);
* ``full-frame``: given parameters but a window as large as the image, i.e.
  the filters without the speed the thesis' sliding window brings.

Ratio = throughput of detect_markers / throughput of bare OpenCV (>= 1 is
faster than bare OpenCV). Frames: synthetic RGB, dark noisy background, 3
anti-aliased markers moving across, pseudo markers (blob, rail, glints).

Usage: ``python benchmarks/bench_detection.py [--frames N] [--repeat R]``
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace

import cv2
import numpy as np

from horsemocap import detection as det
from horsemocap.virtuallab.render import add_image_disc as add_disc


def make_frames(n, size, seed=0):
    W, H = size
    s = W / 640
    rng = np.random.default_rng(seed)
    frames = np.empty((n, H, W, 3), np.uint8)
    base = np.full((H, W), 30.0, np.float32)
    add_disc(base, 0.82 * W, 0.2 * H, 14 * s, 200)
    base[int(0.85 * H):int(0.85 * H) + int(3 * s), 10:W - 10] += 190
    noise = rng.normal(0, 3, (8, H, W)).astype(np.float32)
    for k in range(n):
        img = base.copy()
        for _ in range(4):
            img[rng.integers(3, H - 3), rng.integers(3, W - 3)] += 220
        cu, cv = 0.2 * W + 0.6 * W * k / n, 0.5 * H + 3 * s * np.sin(2 * np.pi * k / 12)
        for du, dv in ((-30, 2), (0, -3), (26, 1.5)):
            add_disc(img, cu + du * s, cv + dv * s, 3 * s, 210)
        img += noise[k % 8]
        g = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        frames[k] = g[..., None]
    return frames


def bare_opencv(frames, threshold):
    for f in frames:
        g = cv2.cvtColor(f, cv2.COLOR_RGB2GRAY)
        b = cv2.threshold(g, threshold, 255, cv2.THRESH_BINARY)[1]
        cv2.connectedComponentsWithStats(b, connectivity=8)


def best_time(fn, repeat):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts)


def interleaved(fns, repeat):
    """Best time of each function over ``repeat`` rounds, the functions taking turns.

    Taking turns in each round makes the ratios robust to the load of a
    shared machine, which changes from second to second.
    """
    best = [np.inf] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t = time.perf_counter()
            fn()
            best[i] = min(best[i], time.perf_counter() - t)
    return best


def run(size, n, repeat):
    frames = make_frames(n, size)
    auto = det.detect_markers(frames, 3)
    p = auto.params
    full = replace(p, window=(4 * size[0], 4 * size[1]))
    t_bare, t_auto, t_given, t_full = interleaved(
        [lambda: bare_opencv(frames, p.threshold), lambda: det.detect_markers(frames, 3),
         lambda: det.detect_markers(frames, 3, p), lambda: det.detect_markers(frames, 3, full)], repeat)
    found = auto.all_found.mean()
    print(f"{size[0]}x{size[1]}, {n} frames, all markers found in {100 * found:.0f} % of frames")
    print(f"  bare OpenCV        {1e3 * t_bare / n:7.3f} ms/frame")
    for name, t in (("auto", t_auto), ("given", t_given), ("full-frame", t_full)):
        print(f"  detect {name:11s} {1e3 * t / n:7.3f} ms/frame   ratio {t_bare / t:5.2f}")
    return {"bare": t_bare / n, "auto": t_auto / n, "given": t_given / n, "full": t_full / n}


def run_session():
    """The same ratios on the default session's videos (if rendered)."""
    from horsemocap.data import default_session_dir
    from horsemocap.sources import FrameSource
    session = default_session_dir()
    for cam in ("left", "middle", "right"):
        path = session / "motion" / f"{cam}.avi"
        if not path.exists():
            print(f"default session: {path} not found, skipped")
            return
        frames = FrameSource(path).read()
        n = len(frames)
        auto = det.detect_markers(frames, 3)
        p = auto.params
        t_bare, t_auto, t_given = interleaved(
            [lambda: bare_opencv(frames, p.threshold), lambda: det.detect_markers(frames, 3),
             lambda: det.detect_markers(frames, 3, p)], 3)
        print(f"default session {cam}: {n} frames {frames.shape[2]}x{frames.shape[1]}, bare "
              f"{1e3 * t_bare / n:.3f} ms/frame; auto ratio {t_bare / t_auto:.2f}, given ratio {t_bare / t_given:.2f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-session", action="store_true", help="skip the default session's videos")
    a = ap.parse_args(argv)
    cv2.setNumThreads(1)
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, 1 OpenCV thread; candidate search: pure Python")
    run((640, 480), a.frames, a.repeat)
    run((1920, 1080), max(10, a.frames // 2), a.repeat)
    if not a.no_session:
        run_session()


if __name__ == "__main__":
    main()
