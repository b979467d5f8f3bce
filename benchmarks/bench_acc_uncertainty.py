"""The saddle vertical acceleration's own uncertainty estimate against its actual error, session by session.

For each session folder (cached virtual-laboratory renders with their truth, and the bundled session) runs the
default analysis (:func:`horsemocap.pipeline.analyze`, what ``horsemocap analyze`` runs), the actual error of
the saddle's vertical acceleration against the truth (% of the true rms,
:func:`horsemocap.accuracy.stage_errors`) and the estimate of :func:`horsemocap.uncertainty.saddle_vertical_uncertainty`
(% of the estimated rms, with its parts), and the verdict of the quality checks.

Usage: ``python benchmarks/bench_acc_uncertainty.py [PATTERN ...]`` (glob patterns of folder names under the
virtual laboratory's cache, default the herd, hard, free-running, cover and marker-noise renders, plus
``bundled``); one analysis at a time.
"""
import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np

from horsemocap import accuracy, quality
from horsemocap.data import cache_dir
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.uncertainty import saddle_vertical_uncertainty
from horsemocap.virtuallab import load_truth

DEFAULT = ("bundled", "horse*_*", "hard-*", "free_*", "marker-noise_*", "cover-*")
BUNDLED = Path(__file__).resolve().parents[1] / "data_samples" / "horse2_canter"


def folders(patterns):
    root = Path(cache_dir()) / "virtuallab"
    for p in patterns:
        if p == "bundled":
            yield BUNDLED
            continue
        for f in sorted(root.glob(p)):
            if f.is_dir() and not f.name.endswith(".partial") and (f / "truth").exists():
                yield f


def estimate(a):
    rb = a.rigid_body
    pose = rb.body.pose
    return saddle_vertical_uncertainty(pose, rb.model, rb.saddle_static, rb.alpha, rb.saddle_acceleration)


def run(folder: Path, dump=None) -> str:
    t0 = time.perf_counter()
    try:
        a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{folder.name[:44]:44s} stopped: {str(exc)[:80]}"
    truth = load_truth(folder)
    err = accuracy.stage_errors(a, truth)["saddle_acc_y_rmse_pct_of_rms"]
    checks = quality.post_checks(a)
    v = quality.verdict(checks)
    flagged = ",".join(c.name for c in checks if c.level in ("warning", "unreliable"))
    if a.rigid_body is None or a.rigid_body.body.pose is None:
        return f"{folder.name[:44]:44s} {err:7.1f}  no pose trajectory  {v}"
    if dump is not None:     # the inputs of the estimate and the error, to study the estimate without re-running
        with open(Path(dump) / f"{folder.name}.pkl", "wb") as fh:
            pickle.dump({"rigid_body": a.rigid_body, "error_pct": err, "verdict": v, "flagged": flagged}, fh)
    u = estimate(a)
    return (f"{folder.name[:44]:44s} {err:7.1f} {u.pct_of_rms:7.1f}  {100 * u.noise / u.rms:6.1f} "
            f"{100 * u.unresolved / u.rms:6.1f} {100 * u.static_offset / u.rms:6.1f}  {v:10s} {flagged}  "
            f"({time.perf_counter() - t0:.0f} s)")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("patterns", nargs="*", default=list(DEFAULT))
    parser.add_argument("--dump", help="folder to pickle each run's rigid-body result and error into")
    args = parser.parse_args()
    print(f"{'session':44s} {'err %':>7s} {'est %':>7s}  {'noise':>6s} {'unres':>6s} {'static':>6s}  verdict", flush=True)
    for f in folders(args.patterns):
        print(run(f, args.dump), flush=True)


if __name__ == "__main__":
    sys.exit(main())
