"""End-to-end time and memory of ``analyze``, per step, against decoding alone.

Runs the analysis of the bundled default session and of the long session of
issue 16 (3 cameras x ``--long-frames`` frames after the flash, ten minutes
at 30 fps by default: the horse passes every 30 s, the arena is empty in
between; composed into the render cache on first use by
:func:`horsemocap.virtuallab.longsession.long_session`, never committed).
For the long session the same run also reads every frame of every video as
gray (decode-only: the floor of the pipeline, as ``bench_floor.py``), before
and after the analysis, and prints the pipeline's throughput as a fraction
of decode-only (issue 16's target: at least 0.5), the peak resident memory
of each process and the analysis' progress lines with their times.

Usage: ``python benchmarks/bench_analyze.py [--long-frames 18000] [--skip-long] [--skip-default]
[--out benchmarks/results/analyze_long.json]``

``--demo-rounds N [--compare-with CHECKOUT]`` instead times the bundled ``horsemocap demo`` into a
new results folder (calibration not cached) and again into the same folder, against its floor
``horsemocap calibrate`` (the session's three view folders) + decode-only of its videos, in N
interleaved rounds (results/analyze_demo.json); with ``--compare-with`` another checkout's demo and
calibrate take turns in the same rounds.
``--demo-phases N [--compare-with CHECKOUT]`` times a fresh ``horsemocap demo`` (new results folder, board
cache warm) in N rounds alternating with the other checkout: wall and CPU (user + sys, the forked copies
included), when each milestone's line appeared (the first output line, the sync, detect, rigid-body and
comfort lines, the results line), each step's own seconds from analysis.json and the load average
(results/demo_phases.json).
Each measurement runs in its own process so the peak memory is its own.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
import cv2
cv2.setNumThreads(1)
from horsemocap.pipeline import analyze
lines = []
t0 = time.perf_counter()

class Progress:
    counts = True
    def __call__(self, step, message, done=None, total=None):
        if done is None or done == total or done % 3000 == 0:
            text = f"{step}: {message}" + (f" {done}/{total}" if done is not None else "")
            lines.append((round(time.perf_counter() - t0, 1), text))
            print(f"  [{time.perf_counter() - t0:7.1f} s] {text}", file=sys.stderr, flush=True)

a = analyze(sys.argv[1], sys.argv[2], progress=Progress())
total = time.perf_counter() - t0
seg = a.triangulate.segment
import horsemocap.pipeline
print(json.dumps({"code": horsemocap.pipeline.__file__, "timings": a.timings, "total_s": total,
                  "synced_frames": a.synchronisation.n_frames,
                  "analysed_frames": seg[1] - seg[0], "segment": list(seg), "progress_lines": len(lines),
                  "cpu_s": sum(resource.getrusage(resource.RUSAGE_SELF)[:2]),
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

DECODE = r"""
import json, resource, sys, time
import cv2
cv2.setNumThreads(1)
from horsemocap.session import load_session
from horsemocap.sources import FrameSource
s = load_session(sys.argv[1])
t0 = time.perf_counter()
n = 0
for c in s.cameras:
    for _ in FrameSource(s.motion[c]).iter_frames(color=False):
        n += 1
print(json.dumps({"camera_frames": n, "seconds": time.perf_counter() - t0,
                  "cpu_s": sum(resource.getrusage(resource.RUSAGE_SELF)[:2]),
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def child(code: str, *args, pythonpath=None) -> dict:
    env = dict(os.environ, PYTHONPATH=str(pythonpath)) if pythonpath else None
    # run from the checkout itself: "python -c" puts the working folder first on the import path
    proc = subprocess.run([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE, text=True, env=env,
                          cwd=str(pythonpath) if pythonpath else None)
    if proc.returncode:
        raise SystemExit(f"child failed ({proc.returncode})")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(session: Path, pythonpath=None) -> dict:
    with tempfile.TemporaryDirectory() as out:
        return child(CHILD, session, out, pythonpath=pythonpath)


def show(name: str, r: dict) -> None:
    print(f"\n{name} ({r['code']}): {r['synced_frames']} synchronised frames per camera, {r['analysed_frames']} analysed "
          f"(frames {r['segment'][0]}..{r['segment'][1] - 1}), {r['progress_lines']} progress lines")
    for step, s in r["timings"].items():
        print(f"  {step:<14s} {s:8.3f} s")
    fps = r["synced_frames"] * 3 / r["total_s"]
    print(f"  {'total':<14s} {r['total_s']:8.3f} s   ({fps:.0f} camera-frames/s), CPU {r['cpu_s']:.1f} s, "
          f"peak memory {r['peak_rss_mb']:.0f} MB",
          flush=True)


def load():
    return tuple(round(x, 2) for x in os.getloadavg())


def timed(cmd, pythonpath=None, cwd=None) -> dict:
    """Wall and CPU seconds of one command in its own process (its output discarded, its failure an error)."""
    env = dict(os.environ, PYTHONPATH=str(pythonpath)) if pythonpath else None
    before = os.times()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t0
    after = os.times()
    if proc.returncode:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return {"wall_s": wall, "cpu_s": (after.children_user - before.children_user)
            + (after.children_system - before.children_system), "load": load()[0]}


def demo_rounds(rounds: int, compare_with=None) -> dict:
    """The bundled ``horsemocap demo`` into a new results folder and again into the same one, against its floor.

    Floor (issue 16): ``horsemocap calibrate`` of the session's three view folders (board detection,
    each camera, the pairs, the joint rig) + decode-only of its three videos, each in its own process.
    Interleaved rounds (each code's fresh run, its repeated run, then the floor), medians.
    """
    import statistics

    from horsemocap.data import default_session_dir

    session = default_session_dir()
    codes = {"this": Path(__file__).resolve().parents[1]}
    if compare_with:
        codes["compared"] = Path(compare_with).resolve()
    demo = [sys.executable, "-m", "horsemocap.cli", "demo", "--out"]
    cal = [sys.executable, "-m", "horsemocap.cli", "calibrate"] + [str(session / "calibration" / c)
                                                                    for c in ("left", "middle", "right")]
    rows = {f"{k} {what}": [] for k in codes for what in ("fresh", "repeated", "calibrate")}
    rows["decode"] = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for name, code in codes.items():
                out = Path(tmp) / f"{name}-{r}"
                rows[f"{name} fresh"].append(timed(demo + [str(out)], code, cwd=code))
                rows[f"{name} repeated"].append(timed(demo + [str(out)], code, cwd=code))
                rows[f"{name} calibrate"].append(timed(cal + ["--board", "7x14", "--square", "0.1", "--out",
                                                              str(Path(tmp) / f"rig-{name}-{r}.toml")], code, cwd=code))
            dec = child(DECODE, session)
            rows["decode"].append({"wall_s": dec["seconds"], "cpu_s": dec["cpu_s"], "load": load()[0]})
            print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]['wall_s']:.2f} s" for k, v in rows.items()), flush=True)
    med = {k: {"wall_s": statistics.median(x["wall_s"] for x in v), "cpu_s": statistics.median(x["cpu_s"] for x in v),
               "loads": [x["load"] for x in v]} for k, v in rows.items()}
    for name in codes:
        floor = med[f"{name} calibrate"]["wall_s"] + med["decode"]["wall_s"]
        med[f"{name} ratio fresh / (calibrate + decode)"] = med[f"{name} fresh"]["wall_s"] / floor
    return {"session": str(session), "rounds": rounds, "codes": {k: str(v) for k, v in codes.items()},
            "runs": rows, "medians": med}


#: A fresh demo's milestones: name -> the text of the output line that marks it (its first appearance).
DEMO_MILESTONES = {"first_line": "analysing the bundled", "sync": "sync: offsets", "detect": "detect: left camera",
                   "rigid_body": "marker model", "comfort": "comfort: indicators", "results": "results:"}


def demo_phases_run(code: Path, out: Path) -> dict:
    """One fresh ``horsemocap demo`` of checkout ``code`` into ``out``: wall, CPU, milestones, steps, load."""
    import shutil
    import threading

    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ, PYTHONPATH=str(code), PYTHONUNBUFFERED="1")
    seen, load_before = {}, load()[0]
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "horsemocap.cli", "demo", "--out", str(out)], env=env, cwd=code,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def watch(stream):
        for line in stream:
            now = time.perf_counter() - t0
            for name, text in DEMO_MILESTONES.items():
                if text in line:
                    seen.setdefault(name, round(now, 3))

    readers = [threading.Thread(target=watch, args=(s,)) for s in (proc.stdout, proc.stderr)]
    for r in readers:
        r.start()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    for r in readers:
        r.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"demo of {code} failed ({proc.returncode})")
    steps = json.loads((out / "analysis.json").read_text())["timings_s"]
    return {"wall_s": round(wall, 3), "cpu_s": round(usage.ru_utime + usage.ru_stime, 3), "load": load_before,
            "milestones_s": seen, "steps_s": steps}


def demo_phases(rounds: int, compare_with=None) -> dict:
    """:func:`demo_phases_run` of this checkout and ``compare_with`` in ``rounds`` alternating rounds."""
    codes = {"this": Path(__file__).resolve().parents[1]}
    if compare_with:
        codes["compared"] = Path(compare_with).resolve()
    runs = {k: [] for k in codes}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for name, code in codes.items():
                got = demo_phases_run(code, Path(tmp) / f"{name}-{r}")
                runs[name].append(got)
                print(f"round {r + 1} {name}: load {got['load']:.1f}, wall {got['wall_s']:.2f} s, CPU "
                      f"{got['cpu_s']:.2f} s; " + ", ".join(f"{k} {v:.2f}" for k, v in got["milestones_s"].items())
                      + "; steps " + ", ".join(f"{k} {v:.2f}" for k, v in got["steps_s"].items() if v >= 0.01),
                      flush=True)
    return {"rounds": rounds, "codes": {k: str(v) for k, v in codes.items()}, "runs": runs}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--long-frames", type=int, default=18000)
    ap.add_argument("--skip-long", action="store_true")
    ap.add_argument("--skip-default", action="store_true")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "analyze_long.json"))
    ap.add_argument("--demo-rounds", type=int, default=0,
                    help="time `horsemocap demo` fresh and repeated against calibrate + decode in this many "
                         "interleaved rounds (results/analyze_demo.json), then stop")
    ap.add_argument("--compare-with", default=None,
                    help="another checkout of horsemocap (e.g. the code before a change): its analyze is run too")
    ap.add_argument("--demo-phases", type=int, default=0,
                    help="time a fresh `horsemocap demo` (milestones, steps, CPU) in this many rounds alternating "
                         "with --compare-with (results/demo_phases.json), then stop")
    args = ap.parse_args()
    from horsemocap.data import default_session_dir

    out = {"date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "cpus": os.cpu_count(),
           "load_before": load()}
    print(f"load average {out['load_before']}", flush=True)
    if args.demo_phases:
        out["demo_phases"] = demo_phases(args.demo_phases, args.compare_with)
        out["load_after"] = load()
        path = Path(__file__).parent / "results" / "demo_phases.json"
        path.write_text(json.dumps(out, indent=1) + "\n")
        print(f"load average after {out['load_after']}; wrote {path}")
        return
    if args.demo_rounds:
        out["demo"] = demo_rounds(args.demo_rounds, args.compare_with)
        for k, v in out["demo"]["medians"].items():
            print(f"  {k:<42s} " + (f"{v:.2f}" if isinstance(v, float) else
                                   f"{v['wall_s']:6.2f} s wall, {v['cpu_s']:6.2f} s CPU (load {v['loads']})"))
        out["load_after"] = load()
        print(f"load average after {out['load_after']}")
        path = Path(__file__).parent / "results" / "analyze_demo.json"
        path.write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {path}")
        return
    if not args.skip_default:
        out["default"] = run(default_session_dir())
        show("default session", out["default"])
        if args.compare_with:
            out["default_compared"] = run(default_session_dir(), args.compare_with)
            show(f"default session, code of {args.compare_with}", out["default_compared"])
    if not args.skip_long:
        from horsemocap.virtuallab.longsession import long_session

        t0 = time.perf_counter()
        long_dir = long_session(args.long_frames, progress=lambda m: print(m, flush=True))
        print(f"\n(long session ready in {time.perf_counter() - t0:.1f} s: {long_dir})", flush=True)
        dec1 = child(DECODE, long_dir)
        print(f"decode-only: {dec1['camera_frames']} camera-frames in {dec1['seconds']:.1f} s", flush=True)
        r = run(long_dir)
        show(f"long session ({args.long_frames} frames)", r)
        dec2 = child(DECODE, long_dir)
        print(f"decode-only again: {dec2['seconds']:.1f} s", flush=True)
        if args.compare_with:
            rc = run(long_dir, args.compare_with)
            show(f"long session, code of {args.compare_with}", rc)
            dec3 = child(DECODE, long_dir)
            print(f"decode-only a third time: {dec3['seconds']:.1f} s", flush=True)
            out["long_compared"] = {"code": args.compare_with, "analyze": rc, "decode_s": dec3["seconds"],
                                    "throughput_ratio": 0.5 * (dec2["seconds"] + dec3["seconds"]) / rc["total_s"]}
            print(f"long session, code of {args.compare_with}: throughput "
                  f"{out['long_compared']['throughput_ratio']:.2f} of decode-only (decode {dec2['seconds']:.1f} and "
                  f"{dec3['seconds']:.1f} s around it)", flush=True)
        dec_s = 0.5 * (dec1["seconds"] + dec2["seconds"])
        ratio = dec_s / r["total_s"]
        cpu_ratio = 0.5 * (dec1["cpu_s"] + dec2["cpu_s"]) / r["cpu_s"]
        out["long"] = {"session": str(long_dir), "frames_after_flash": args.long_frames, "analyze": r,
                       "decode_s": [dec1["seconds"], dec2["seconds"]], "camera_frames": dec1["camera_frames"],
                       "decode_peak_rss_mb": dec1["peak_rss_mb"], "throughput_ratio": ratio,
                       "decode_cpu_s": [dec1["cpu_s"], dec2["cpu_s"]], "cpu_ratio": cpu_ratio}
        print(f"\nlong session: analyze {r['total_s']:.1f} s, decode-only {dec_s:.1f} s (mean of "
              f"{dec1['seconds']:.1f}, {dec2['seconds']:.1f}) for {dec1['camera_frames']} camera-frames: "
              f"throughput {ratio:.2f} of decode-only (target >= 0.5); CPU time analyze {r['cpu_s']:.1f} s, "
              f"decode-only {dec1['cpu_s']:.1f} / {dec2['cpu_s']:.1f} s (ratio {cpu_ratio:.2f}); peak memory analyze "
              f"{r['peak_rss_mb']:.0f} MB, decode {dec1['peak_rss_mb']:.0f} MB", flush=True)
    out["load_after"] = load()
    print(f"load average after {out['load_after']}")
    if not args.skip_long:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
