"""Whole-analysis time of ``horsemocap analyze`` with the compiled region core against pure Python.

The compiled candidate search (``horsemocap/detection/_regions.c`` with its
Python dispatch ``regions_core.py``) was kept only if it saved at least about
10 % of the whole analysis on the long session or the herd. This script
measures that: ``python -m horsemocap.cli analyze SESSION --out DIR`` in its
own process, once with the core (A) and once with
``HORSEMOCAP_PURE_PYTHON=1`` (B), in turn (A B A B ...) after one warm-up
each, every command into its own results folder (so the calibration is
cached after the warm-up, as for a repeated analysis). It prints, per
session, the median wall and CPU seconds of each and the median of the
ratios B / A taken pair by pair (a ratio of neighbouring runs holds when the
shared machine's speed drifts).

The core was removed after this measurement (results/regions_core_whole.txt).
To measure again, run this script on a checkout that still has it, built in
place::

    git worktree add /tmp/with-core 4de08fa        # any commit before the removal
    cd /tmp/with-core && python setup.py build_ext --inplace   # (setuptools >= 77)
    python benchmarks/bench_regions_core_whole.py --code /tmp/with-core

Sessions: the bundled one (``data_samples/horse2_canter``), the long session
(:func:`horsemocap.virtuallab.longsession.long_session`, ``--long-frames``
frames) and herd sessions (:func:`horsemocap.virtuallab.herd.herd_session`),
rendered into the cache on first use.

Usage: ``python benchmarks/bench_regions_core_whole.py --code CHECKOUT [--runs 5] [--long-frames 18000]
[--herd "Horse 1:rising_trot,Horse 2:walk,Horse 3:sitting_trot,Horse 4:canter"] [--skip-long]
[--out benchmarks/results/regions_core_whole.json]``
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PURE_PYTHON_ENV = "HORSEMOCAP_PURE_PYTHON"
HERD = "Horse 1:rising_trot,Horse 2:walk,Horse 3:sitting_trot,Horse 4:canter"


def timed(cmd: list, code: Path, pure: bool) -> dict:
    """Wall and CPU seconds of one command in its own process, run from ``code`` (its output discarded)."""
    env = dict(os.environ, PYTHONPATH=str(code))
    env.pop(PURE_PYTHON_ENV, None)
    if pure:
        env[PURE_PYTHON_ENV] = "1"
    before = os.times()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env, cwd=code)
    wall = time.perf_counter() - t0
    after = os.times()
    if proc.returncode not in (0, 3):          # 3: the quality verdict is unreliable; the analysis ran
        raise SystemExit(f"{' '.join(map(str, cmd))} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return {"wall_s": wall, "cpu_s": (after.children_user - before.children_user)
            + (after.children_system - before.children_system)}


def compare(session: Path, code: Path, runs: int) -> dict:
    """A (core) and B (pure Python) in turn, one warm-up each; medians and the pairwise ratio B / A."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = {name: [sys.executable, "-m", "horsemocap.cli", "analyze", str(session), "--out",
                      str(Path(tmp) / name)] for name in ("core", "python")}
        for name in cmd:                                   # warm-up: decoders, page cache, cached calibration
            timed(cmd[name], code, name == "python")
        rows = {"core": [], "python": []}
        for r in range(runs):
            for name in cmd:
                rows[name].append(timed(cmd[name], code, name == "python"))
            print(f"  run {r + 1}: core {rows['core'][-1]['wall_s']:.2f} s, python {rows['python'][-1]['wall_s']:.2f} s",
                  flush=True)
    out = {"session": str(session), "runs": rows}
    for what in ("wall_s", "cpu_s"):
        out[f"median_{what}"] = {k: statistics.median(x[what] for x in v) for k, v in rows.items()}
        out[f"ratio_python_over_core_{what}"] = statistics.median(
            b[what] / a[what] for a, b in zip(rows["core"], rows["python"]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--code", required=True, help="a checkout with the compiled core built in place")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--long-frames", type=int, default=18000)
    ap.add_argument("--skip-long", action="store_true")
    ap.add_argument("--herd", default=HERD, help="horse:gait,... (empty: none)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "regions_core_whole.json"))
    args = ap.parse_args()
    code = Path(args.code).resolve()
    check = subprocess.run([sys.executable, "-c", "import horsemocap.detection as d; print(d.ACTIVE_PATH)"],
                           capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(code)), cwd=code)
    if check.stdout.strip() != "compiled":
        raise SystemExit(f"--code {code}: the compiled core is not active there ({check.stdout.strip() or check.stderr})")
    from horsemocap.data import default_session_dir
    from horsemocap.virtuallab.herd import herd_session
    from horsemocap.virtuallab.longsession import long_session

    sessions = {"bundled": default_session_dir()}
    if not args.skip_long:
        sessions[f"long_{args.long_frames}"] = long_session(args.long_frames)
    for item in filter(None, args.herd.split(",")):
        horse, gait = item.split(":")
        sessions[f"{horse} {gait}"] = herd_session(horse.strip(), gait.strip())
    out = {"date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "cpus": os.cpu_count(),
           "load_before": os.getloadavg(), "code": str(code), "sessions": {}}
    for name, session in sessions.items():
        print(f"{name}: {session}", flush=True)
        r = out["sessions"][name] = compare(session, code, args.runs)
        print(f"  median wall: core {r['median_wall_s']['core']:.2f} s, python {r['median_wall_s']['python']:.2f} s; "
              f"python / core {r['ratio_python_over_core_wall_s']:.3f} (wall), "
              f"{r['ratio_python_over_core_cpu_s']:.3f} (CPU)", flush=True)
    out["load_after"] = os.getloadavg()
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
