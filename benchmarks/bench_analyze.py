"""End-to-end time and memory of ``horsemocap analyze``, per stage.

Runs the analysis of the bundled default session and of a long virtual
session (a few thousand frames per camera, rendered by the virtual
laboratory into the cache on first use) and prints seconds per step, total
seconds, frames per second and the peak resident memory of the process.

Usage: ``python benchmarks/bench_analyze.py [--long-frames 3000] [--skip-long]``
Each session runs in its own process so the peak memory is its own.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
from horsemocap.pipeline import analyze
t0 = time.perf_counter()
a = analyze(sys.argv[1], sys.argv[2], progress=lambda *x: None)
total = time.perf_counter() - t0
seg = a.results["triangulate"]["segment"]
print(json.dumps({"timings": a.timings, "total_s": total, "synced_frames": a.results["sync"]["n_frames"],
                  "analysed_frames": seg[1] - seg[0],
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def run(session: Path) -> dict:
    with tempfile.TemporaryDirectory() as out:
        proc = subprocess.run([sys.executable, "-c", CHILD, str(session), out], capture_output=True, text=True)
    if proc.returncode:
        raise SystemExit(proc.stderr)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def show(name: str, r: dict) -> None:
    print(f"\n{name}: {r['synced_frames']} synchronised frames per camera, {r['analysed_frames']} analysed")
    for step, s in r["timings"].items():
        print(f"  {step:<14s} {s:8.3f} s")
    fps = r["synced_frames"] * 3 / r["total_s"]
    print(f"  {'total':<14s} {r['total_s']:8.3f} s   ({fps:.0f} camera-frames/s), peak memory {r['peak_rss_mb']:.0f} MB")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--long-frames", type=int, default=3000)
    ap.add_argument("--skip-long", action="store_true")
    args = ap.parse_args()
    from horsemocap.data import cache_dir, default_session_dir

    show("default session", run(default_session_dir()))
    if not args.skip_long:
        from horsemocap.virtuallab import render_session

        t0 = time.perf_counter()
        long_dir = cache_dir() / f"long_{args.long_frames}"
        if not (long_dir / "session.json").is_file():
            render_session(long_dir, n_motion_frames=args.long_frames, calibration_views=0)
        print(f"\n(long session ready in {time.perf_counter() - t0:.1f} s: {long_dir})")
        show(f"long session ({args.long_frames} frames)", run(long_dir))


if __name__ == "__main__":
    main()
