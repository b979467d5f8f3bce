"""The saddle vertical acceleration's own uncertainty estimate against its actual error, session by session.

For each session folder (cached virtual-laboratory renders with their truth, and the bundled session) runs the
default analysis (:func:`horsemocap.pipeline.analyze`, what ``horsemocap analyze`` runs), the actual error of
the saddle's vertical acceleration against the truth (% of the true rms,
:func:`horsemocap.accuracy.stage_errors`) and the estimate of
:func:`horsemocap.uncertainty.saddle_vertical_uncertainty` (% of the estimated rms): its total with the
unresolved harmonics up to their detection floor (``est``), the total with their measured amplitudes alone
(``est0``), and the parts (noise, unresolved harmonics with the floor, static-shot tilt); then the verdict of
the quality checks and the checks flagged.

Usage: ``python benchmarks/bench_acc_uncertainty.py [--dump DIR] [PATTERN ...]`` (glob patterns of folder
names under the virtual laboratory's cache, default the herd, hard, free-running, marker-noise and cover
renders, plus ``bundled``); one analysis at a time. ``--dump DIR`` pickles each run's rigid-body result and
error; ``--reuse DIR`` prints the table from those pickles without analysing again.
"""
import argparse
import pickle
import sys
import time
from pathlib import Path

from horsemocap import accuracy, quality
from horsemocap.data import cache_dir
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.uncertainty import saddle_vertical_uncertainty
from horsemocap.virtuallab import load_truth

DEFAULT = ("bundled", "horse*_*", "hard-*", "free_*", "marker-noise_*", "cover-*")
BUNDLED = Path(__file__).resolve().parents[1] / "data_samples" / "horse2_canter"
HEAD = (f"{'session':44s} {'err %':>6s} {'est %':>6s} {'est0 %':>6s}  {'noise':>5s} {'unres':>5s} {'static':>6s}"
        "  verdict (checks flagged)")


def folders(patterns):
    root = Path(cache_dir()) / "virtuallab"
    for p in patterns:
        if p == "bundled":
            yield BUNDLED
            continue
        for f in sorted(root.glob(p)):
            if f.is_dir() and not f.name.endswith(".partial") and (f / "truth").exists():
                yield f


def row(name: str, record: dict) -> str:
    rb = record["rigid_body"]
    args = (rb.body.pose, rb.model, rb.saddle_static, rb.alpha, rb.saddle_acceleration)
    u, u0 = saddle_vertical_uncertainty(*args), saddle_vertical_uncertainty(*args, detection_sd=0.0)
    return (f"{name[:44]:44s} {record['error_pct']:6.1f} {u.pct_of_rms:6.1f} {u0.pct_of_rms:6.1f}  "
            f"{100 * u.noise / u.rms:5.1f} {100 * u.unresolved / u.rms:5.1f} {100 * u.static_offset / u.rms:6.1f}  "
            f"{record['verdict']} ({record['flagged'] or 'none'})")


def run(folder: Path, dump=None) -> str:
    t0 = time.perf_counter()
    try:
        a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{folder.name[:44]:44s} stopped: {str(exc)[:80]}"
    truth = load_truth(folder)
    checks = quality.post_checks(a)
    record = {"rigid_body": a.rigid_body, "error_pct": accuracy.stage_errors(a, truth)["saddle_acc_y_rmse_pct_of_rms"],
              "verdict": quality.verdict(checks),
              "flagged": ",".join(c.name for c in checks if c.level in ("warning", "unreliable"))}
    if a.rigid_body is None or a.rigid_body.body.pose is None:
        return f"{folder.name[:44]:44s} {record['error_pct']:6.1f}  no pose trajectory  {record['verdict']}"
    if dump is not None:     # the estimate's inputs and the error, to study the estimate without analysing again
        with open(Path(dump) / f"{folder.name}.pkl", "wb") as fh:
            pickle.dump(record, fh)
    return row(folder.name, record) + f"  ({time.perf_counter() - t0:.0f} s)"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("patterns", nargs="*", default=list(DEFAULT))
    parser.add_argument("--dump", help="folder to pickle each run's rigid-body result and error into")
    parser.add_argument("--reuse", help="folder of pickles written by --dump: the table without analysing")
    args = parser.parse_args()
    print(HEAD, flush=True)
    if args.reuse:
        for f in sorted(Path(args.reuse).glob("*.pkl")):
            with open(f, "rb") as fh:
                print(row(f.stem, pickle.load(fh)), flush=True)
        return
    for f in folders(args.patterns):
        print(run(f, args.dump), flush=True)


if __name__ == "__main__":
    sys.exit(main())
