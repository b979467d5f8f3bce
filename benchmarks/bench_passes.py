"""A long recording with several passes: ``analyze`` beside raw OpenCV decoding, in one run.

    python benchmarks/bench_passes.py [--frames 1200] [--period 10] [--rounds 2] [--session DIR] [--per-pass N]

The long session of :mod:`horsemocap.virtuallab.longsession` (``--frames``
frames per camera after the flash, a pass every ``--period`` seconds;
composed into the render cache when absent, or ``--session``) is analysed
(``horsemocap.pipeline.analyze`` into a new folder, every pass) and its
three videos are decoded alone (OpenCV, gray, one after another, one OpenCV
thread: the floor), each in its own process, taking turns for ``--rounds``
rounds. Printed: the load average before and after, each round's times, the
median throughput ratio decode / analyze (1 = the analysis as fast as
decoding its videos) and the passes found with their verdicts. With
``--per-pass N`` each pass other than the longest is also timed in this
process (CPU, the least of N runs) through the later steps as the pipeline
runs them (every choice made on the pass) and as :mod:`horsemocap.passes`
runs them (the pose smoothing settled on the longest pass, no thesis' chain),
with the Wb/Wk rms and VDV of both. Results in ``results/passes.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analyze import DECODE, child, load  # noqa: E402

CHILD = r"""
import json, resource, sys, tempfile, time
import cv2
cv2.setNumThreads(1)
from horsemocap.pipeline import analyze
t0 = time.perf_counter()
with tempfile.TemporaryDirectory() as out:
    a = analyze(sys.argv[1], out, progress=lambda *args, **kw: None)
total = time.perf_counter() - t0
passes = [] if a.passes is None else [
    {"pass": p.index, "frames": list(p.run), "verdict": p.verdict, "duration_s": p.duration_s,
     "acc_y_Wb_rms": (p.indicators or {}).get("acc_y_Wb_rms")} for p in a.passes.passes]
print(json.dumps({"timings": a.timings, "total_s": total, "synced_frames": a.synchronisation.n_frames,
                  "passes": passes, "combined": a.passes.combined if a.passes else None,
                  "cpu_s": sum(resource.getrusage(resource.RUSAGE_SELF)[:2]),
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def per_pass(session, repeats: int) -> list:
    """Each extra pass' later steps timed both ways (see the module docstring), with their comfort."""
    from horsemocap import passes as P
    from horsemocap.pipeline import analyze, run_steps
    a = analyze(session, progress=lambda *args: None)
    run_later = lambda given, steps: run_steps(a.session, a.params, given, steps, lambda *args: None)  # noqa: E731
    settled = P.pass_smoothing(a)
    tri, det = a.triangulate, a.detect
    rows = []
    for i, run in enumerate(P.pass_runs(a), 1):
        segment = P.pass_segment(tri.points, run)
        if (run[0] <= tri.segment[0] and tri.segment[1] <= run[1]) or segment is None:
            continue
        given = {n: getattr(a, n) for n in ("sync", "rig", "plumb", "static")}
        given["detect"], given["triangulate"] = det.replace(segment=run), tri.replace(segment=segment)
        row = {"pass": i, "frames": list(segment)}
        for label in ("per_pass", "settled"):
            cpu = []
            for _ in range(repeats):
                c0 = time.process_time()
                if label == "per_pass":
                    comfort = run_later(given, P.PASS_STEPS).comfort
                else:
                    comfort = P._later_steps(run_later, given, settled)[0]["comfort"]
                cpu.append(time.process_time() - c0)
            ind = comfort.indicators
            row[label] = {"cpu_s": min(cpu), **{k: ind[k] for k in ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb")}}
        rows.append(row)
        before, after = row["per_pass"], row["settled"]
        print(f"  pass {i} (frames {segment[0]}..{segment[1] - 1}): "
              f"CPU {before['cpu_s']:.3f} -> {after['cpu_s']:.3f} s; "
              + ", ".join(f"{k} {before[k]:.4f} -> {after[k]:.4f} ({100 * (after[k] / before[k] - 1):+.2f} %)"
                          for k in ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb")), flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1200)
    ap.add_argument("--period", type=float, default=10.0)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--session", type=Path)
    ap.add_argument("--per-pass", type=int, default=0, metavar="N")
    args = ap.parse_args()
    repo = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(repo))
    if args.session is None:
        from horsemocap.virtuallab.longsession import long_session
        args.session = long_session(args.frames, pass_period_s=args.period, progress=print)
    before = load()
    print(f"session {args.session}; load average before {before}", flush=True)
    rounds = []
    for r in range(args.rounds):
        dec = child(DECODE, args.session, pythonpath=repo)
        an = child(CHILD, args.session, pythonpath=repo)
        ratio = dec["seconds"] / an["total_s"]
        rounds.append({"decode": dec, "analyze": an, "ratio": ratio, "load": load()})
        print(f"round {r + 1}: decode-only {dec['seconds']:.1f} s ({dec['camera_frames']} camera-frames), analyze "
              f"{an['total_s']:.1f} s (CPU {an['cpu_s']:.1f} s; " + ", ".join(
                  f"{k} {v:.1f}" for k, v in an["timings"].items() if v >= 0.5)
              + f"): ratio {ratio:.2f}; load {load()}", flush=True)
    last = rounds[-1]["analyze"]
    for p in last["passes"]:
        print(f"  pass {p['pass']}: frames {p['frames'][0]}..{p['frames'][1] - 1}, {p['verdict']}, "
              f"{p['duration_s']:.2f} s, Wb rms {p['acc_y_Wb_rms']}")
    truth = json.loads((Path(args.session) / "truth" / "truth.json").read_text()).get("extras", {}).get("long_session")
    if truth:                       # each true pass (motion frames after the flash = synchronised frames)
        n = truth["pass_frames"]
        inside = [sum(1 for p in last["passes"] if s <= p["frames"][0] and p["frames"][1] <= s + n)
                  for s in truth["pass_starts"]]
        print(f"passes found {len(last['passes'])}; true passes {len(inside)}, with exactly one found pass inside "
              f"its frames: {sum(k == 1 for k in inside)}")
    median = statistics.median(r["ratio"] for r in rounds)
    after = load()
    print(f"median decode / analyze throughput ratio {median:.2f} (target >= 0.7); load average before {before}, "
          f"after {after}; {os.cpu_count()} processors")
    extra = {}
    if args.per_pass:
        print(f"each extra pass' later steps, choices per pass -> settled on the longest (load {load()}):")
        extra = {"per_pass": per_pass(args.session, args.per_pass), "per_pass_load": load()}
    out = Path(__file__).resolve().parent / "results" / "passes.json"
    out.write_text(json.dumps({"session": str(args.session), "rounds": rounds, "median_ratio": median,
                               "load_before": before, "load_after": after, **extra}, indent=1))


if __name__ == "__main__":
    main()
