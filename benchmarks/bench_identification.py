"""Marker identification on the harder virtual sessions and the herd, against the truth (issue 17).

For each session (rendered into the cache on first use, never into the
repository): runs ``pipeline.analyze`` with the default multi-view
identification (or ``--method thesis``), and prints the identity errors
(a used 2D centre more than 3 px from its own marker's true projection),
the median 2D centroid error, the share of marker-frames seen by two or more
cameras that got a 3D position, the saddle's vertical acceleration error and
the Wb/Wk rms errors. A session that stops prints the step and the message.

With ``--speed SESSION``: throughput of detection + identification against
bare OpenCV on the same frames in the same run. The first ``--frames`` frames
after the flash of every camera are decoded into memory (RGB) once; bare
OpenCV = per frame and camera ``cvtColor(RGB2GRAY) + threshold +
connectedComponentsWithStats`` on the whole frame; identification =
:func:`~horsemocap.detection.identify_markers` on the same RGB frames, gray
conversion included. Ratio = bare time / identification time (>= 1: faster
than bare OpenCV). Best of ``--repeat`` alternating rounds, one OpenCV thread.

Usage: ``python benchmarks/bench_identification.py [--set hard|herd|all] [--method multiview|thesis]
[--session PATH ...] [--speed SESSION [--frames N] [--repeat R]]``
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def sessions(which):
    from horsemocap.virtuallab import GAITS, HORSES, herd_session

    out = []
    if which in ("hard", "all"):
        from horsemocap.virtuallab.hard import HARD_SESSIONS, hard_session
        out += [(name, lambda name=name: hard_session(name)) for name in HARD_SESSIONS]
    if which in ("herd", "all"):
        out += [(f"{h} {g}", lambda h=h, g=g: herd_session(h, g)) for h in HORSES for g in GAITS]
    return out


def measure(name, folder, method, params):
    from horsemocap import accuracy
    from horsemocap.pipeline import AnalysisError, analyze
    from horsemocap.virtuallab import load_truth

    t0 = time.perf_counter()
    try:
        a = analyze(folder, None, {"detection_method": method, **params}, progress=lambda *x: None)
    except AnalysisError as exc:
        print(f"{name:34s} stopped: {str(exc)[:200]}", flush=True)
        return None
    t1 = time.perf_counter()
    truth = load_truth(folder)
    ide = accuracy.identification_errors(a, truth)
    st = accuracy.stage_errors(a, truth)
    keys = ("acc_y_Wb_rms", "acc_y_Wk_rms")
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, keys)
    meds = [c["median_px"] for c in ide["cameras"].values()]
    # the worst camera's; a camera without any correct centre has none (NaN) and is named, not maxed over
    med = max((m for m in meds if np.isfinite(m)), default=float("nan"))
    empty = [cam for cam, c in ide["cameras"].items() if not np.isfinite(c["median_px"])]
    if empty:
        print(f"{name:34s} no correct 2D centre in camera(s) {', '.join(empty)}", flush=True)
    cover = 100.0 * ide["with_3d"] / max(ide["seen_by_two"], 1)
    row = {"wrong": ide["wrong_total"], "median_px": med, "cover_pct": cover,
           "saddle": st["saddle_acc_y_rmse_pct_of_rms"], "Wb": ce["acc_y_Wb_rms"], "Wk": ce["acc_y_Wk_rms"],
           "frames": st["frames"], "seconds": t1 - t0}
    print(f"{name:34s} {row['frames']:6d} {row['wrong']:6d} {med:9.3f} {cover:8.1f} {row['saddle']:9.1f} "
          f"{row['Wb']:7.1f} {row['Wk']:7.1f} {row['seconds']:7.1f}", flush=True)
    return row


class _GrayOnAccess:
    """RGB frames in memory, converted to gray when indexed (the last few kept, as FrameSequence)."""

    def __init__(self, rgb, keep=16):
        self.rgb, self.keep, self.cache = rgb, keep, {}

    def __len__(self):
        return len(self.rgb)

    def __getitem__(self, k):
        import cv2

        g = self.cache.pop(k, None)
        if g is None:
            g = cv2.cvtColor(self.rgb[k], cv2.COLOR_RGB2GRAY)
        self.cache[k] = g
        while len(self.cache) > self.keep:
            self.cache.pop(next(iter(self.cache)))
        return g


def speed(folder, n_frames, repeat):
    import cv2

    from horsemocap.detection import identify_markers
    from horsemocap.pipeline import resolve_params, run_steps
    from horsemocap.session import load_session
    from horsemocap.sources import FrameSource

    cv2.setNumThreads(1)
    s = load_session(folder)
    a = run_steps(s, resolve_params(s), {}, ["sync", "rig", "plumb", "static"])
    off = a.synchronisation.offsets
    n = min(n_frames, a.synchronisation.n_frames)
    rgb = {c: FrameSource(s.motion[c]).read(off[c], off[c] + n) for c in s.cameras}
    rig, static = a.rig.rig, a.static.static_points
    thr = {}

    def ours():
        idn = identify_markers({c: _GrayOnAccess(rgb[c]) for c in s.cameras}, rig, static, s.marker_count)
        thr.update(idn.thresholds)

    def bare():
        for c in s.cameras:
            for f in rgb[c]:
                g = cv2.cvtColor(f, cv2.COLOR_RGB2GRAY)
                b = cv2.threshold(g, thr.get(c, 128), 255, cv2.THRESH_BINARY)[1]
                cv2.connectedComponentsWithStats(b, connectivity=8)

    best = {"ours": np.inf, "bare": np.inf}
    for _ in range(repeat):
        for name, fn in (("ours", ours), ("bare", bare)):
            t0 = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    W, H = rig[s.cameras[0]].size
    per = n * len(s.cameras)
    print(f"{Path(folder).name}: {W}x{H}, {len(s.cameras)} cameras x {n} frames; bare OpenCV "
          f"{1000 * best['bare'] / per:.2f} ms/frame, identification {1000 * best['ours'] / per:.2f} ms/frame, "
          f"ratio {best['bare'] / best['ours']:.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="hard", choices=["hard", "herd", "all"])
    ap.add_argument("--method", default="multiview", choices=["multiview", "thesis"])
    ap.add_argument("--params", default="{}", help="JSON analysis parameters")
    ap.add_argument("--session", nargs="*", help="session folders instead of a set")
    ap.add_argument("--speed", metavar="SESSION", help="throughput against bare OpenCV on this session")
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print("candidate search: pure Python", flush=True)
    if args.speed:
        speed(args.speed, args.frames, args.repeat)
        return
    params = json.loads(args.params)
    print(f"{'session':34s} {'frames':>6s} {'wrong':>6s} {'med2D_px':>9s} {'3D_%':>8s} {'saddle_%':>9s} "
          f"{'Wb_%':>7s} {'Wk_%':>7s} {'time_s':>7s}")
    todo = [(Path(p).name, lambda p=p: Path(p)) for p in args.session] if args.session else sessions(args.set)
    rows = {}
    for name, get in todo:
        rows[name] = measure(name, get(), args.method, params)
    done = [r for r in rows.values() if r]
    print(f"\n{len(done)} of {len(rows)} sessions analysed; wrong identities in total: "
          f"{sum(r['wrong'] for r in done)}")
    if done:
        for k in ("median_px", "cover_pct", "saddle", "Wb", "Wk"):
            v = np.abs([r[k] for r in done])
            print(f"  {k}: median {np.median(v):.3f}, worst {v.max() if k != 'cover_pct' else v.min():.3f}")


if __name__ == "__main__":
    main()
