"""The static shot's uncertainty carried to the saddle's vertical acceleration, against its actual error.

For each session folder (cached virtual-laboratory renders with their truth, and the bundled session) runs the
default analysis (:func:`horsemocap.pipeline.analyze`, what ``horsemocap analyze`` runs) and prints: the actual
error of the saddle's vertical acceleration against the truth (% of the true rms,
:func:`horsemocap.accuracy.stage_errors`), the Wb/Wk-weighted rms errors, the static shot's estimate
(:func:`horsemocap.quality.static_shot_of`: the still's pixel noise through the cameras' Jacobians, the marker
model and the saddle's placement, then through the chain that wrote the acceleration run on the saddle point moved
along x, y, z (:func:`horsemocap.uncertainty.written_saddle_sensitivity`), % of the written rms), the part of the
actual error the still's actual error explains (the same linear chain fed with the truth's static points instead
of a covariance), the pixel noise used, and the verdict with the checks flagged.

Usage: ``python benchmarks/bench_acc_uncertainty.py [--dump DIR] [--reuse DIR] [--cuts] [--set NAME=VALUE ...]
[PATTERN ...]``
(glob patterns of folder names under the virtual laboratory's cache, default the herd, hard, free-running,
marker-noise and cover renders, plus ``bundled``); one analysis at a time. ``--dump DIR`` pickles each run's
numbers; ``--reuse DIR`` prints the table from those pickles without analysing again. ``--cuts``: also the
spread rigs cut to the horse's own three markers (``bench_markers_covers.py --cut``). ``--set`` gives analysis
parameters by their dotted names (``--set rigid_body.kinematics=fits``; a value read as JSON when it parses).
"""
import argparse
import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np

from horsemocap import accuracy, quality
from horsemocap.data import cache_dir
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.uncertainty import saddle_offset_map, written_saddle_sensitivity
from horsemocap.virtuallab import load_truth

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_markers_covers as bmc  # noqa: E402  (the spread rigs' three-marker cut)

DEFAULT = ("bundled", "horse*_*", "hard-*", "free_*", "marker-noise_*", "cover-*")
CUTS = ("spread4_canter", "spread4_rising_trot", "spread5_canter", "spread5_rising_trot")
BUNDLED = Path(__file__).resolve().parents[1] / "data_samples" / "horse2_canter"
HEAD = (f"{'session':44s} {'A_y %':>6s} {'Wb %':>6s} {'Wk %':>6s} {'est %':>6s} {'still %':>7s} {'Wb sd':>5s} "
        f"{'px':>5s} {'check':10s} verdict (other checks flagged)")
BAD_PCT = 10.0        # a run whose saddle vertical acceleration is off by more than this is wrong


def folders(patterns):
    root = Path(cache_dir()) / "virtuallab"
    for p in patterns:
        if p == "bundled":
            yield BUNDLED
            continue
        for f in sorted(root.glob(p)):
            if f.is_dir() and not f.name.endswith(".partial") and (f / "truth").exists():
                yield f


def still_explains(a, truth, u) -> float:
    """Rms (% of the written rms) of the vertical acceleration error the still's actual error causes:
    the measured static points against the truth's, through the same linear chain as the estimate."""
    rb, mf = a.rigid_body, a.motion_frame
    axes = np.asarray(mf.frame.axes, float)
    measured = np.asarray(mf.static, float)
    true_motion = (np.asarray(truth.static_pos, float) - mf.frame.origin) @ axes.T
    world = measured @ axes + mf.frame.origin
    match = [int(np.argmin(np.linalg.norm(np.asarray(truth.static_pos) - p, axis=1))) for p in world]
    rows = [int(i) for i in rb.static_order] + [int(rb.saddle_index)]
    err = (measured[rows] - true_motion[[match[i] for i in rows]]).reshape(-1)
    offset = saddle_offset_map(measured[rows[:-1]], measured[rows[-1]]) @ err
    g = written_saddle_sensitivity(rb.body, measured[rows[:-1]])[:, 1, :] @ offset
    return 100 * float(np.sqrt(np.nanmean(g ** 2))) / u.rms


def record_of(name, a, truth) -> dict:
    checks = quality.post_checks(a)
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms")) \
        if a.comfort is not None and a.comfort.indicators is not None else {}
    u = quality.static_shot_of(a)
    others = [c for c in checks if c.name != "static_shot"]
    rec = {"name": name, "error_pct": accuracy.stage_errors(a, truth)["saddle_acc_y_rmse_pct_of_rms"],
           "wb": ce.get("acc_y_Wb_rms", np.nan), "wk": ce.get("acc_y_Wk_rms", np.nan),
           "verdict": quality.verdict(others), "checks": [c.to_dict() for c in others],
           "flagged": ",".join(c.name for c in others if c.level in ("warning", "unreliable"))}
    if isinstance(u, quality.StaticShotSkipped):
        rec.update(estimate=None, why=u.reason)
    else:
        rec.update(estimate=u.pct_of_rms, noise_px=u.noise_px, wb_sd=u.weighted_pct.get("Wb", np.nan), offset_sd_mm=(1000 * u.offset_sd_m).tolist(),
                   explained=still_explains(a, truth, u))
    return rec


def levels(rec: dict) -> tuple[str, str]:
    """The static_shot check's level (:data:`horsemocap.quality.STATIC_SHOT_PCT`) and the verdict with it."""
    ok, warn = quality.STATIC_SHOT_PCT
    est = rec.get("estimate")
    level = "skipped" if est is None else "ok" if est <= ok else "warning" if est <= warn else "unreliable"
    both = [rec["verdict"]] + ([level] if level != "skipped" else [])
    return level, max(both, key=quality.LEVELS.index)


def row(rec: dict) -> str:
    est = (f"{rec['estimate']:6.1f} {rec['explained']:7.1f} {rec['wb_sd']:5.1f} {rec['noise_px']:5.2f}"
           if rec.get("estimate") is not None else f"{'-':>6s} {'-':>7s} {'-':>5s} {'-':>5s}")
    level, verdict = levels(rec)
    return (f"{rec['name'][:44]:44s} {rec['error_pct']:6.1f} {rec['wb']:+6.1f} {rec['wk']:+6.1f} {est} {level:10s} "
            f"{verdict} ({rec['flagged'] or 'none'})")


def summary(records) -> list:
    """How the check separates: the wrong runs (> BAD_PCT) and how they end, the good runs it flags."""
    bad = [r for r in records if not r["error_pct"] <= BAD_PCT]
    good = [r for r in records if r["error_pct"] <= BAD_PCT]
    lines = [f"runs wrong by more than {BAD_PCT:g} % (A_y): {len(bad)}; ending unreliable with the check: "
             f"{sum(levels(r)[1] == 'unreliable' for r in bad)}, before it: "
             f"{sum(r['verdict'] == 'unreliable' for r in bad)}; flagged unreliable by static_shot itself: "
             f"{sum(levels(r)[0] == 'unreliable' for r in bad)}"]
    for r in bad:
        lines.append(f"  {r['name'][:44]:44s} A_y {r['error_pct']:6.1f} %: static_shot {levels(r)[0]}, "
                     f"verdict {levels(r)[1]}")
    lines.append(f"good runs (A_y within {BAD_PCT:g} %): {len(good)}; static_shot unreliable on "
                 f"{sum(levels(r)[0] == 'unreliable' for r in good)}, warning on "
                 f"{sum(levels(r)[0] == 'warning' for r in good)}; verdict unreliable with the check "
                 f"{sum(levels(r)[1] == 'unreliable' for r in good)} (before it "
                 f"{sum(r['verdict'] == 'unreliable' for r in good)})")
    for r in good:
        if levels(r)[0] in ("warning", "unreliable"):
            lines.append(f"  {r['name'][:44]:44s} A_y {r['error_pct']:6.1f} %: static_shot {levels(r)[0]} "
                         f"({r['estimate']:.1f} %)")
    return lines


def parameters(assignments) -> dict:
    """``["a.b=1", ...]`` -> ``{"a": {"b": 1}}``: analysis parameters by their dotted names."""
    out: dict = {}
    for text in assignments:
        name, sep, value = text.partition("=")
        if not sep:
            raise SystemExit(f"--set {text!r}: expected NAME=VALUE")
        try:
            value = json.loads(value)
        except json.JSONDecodeError:
            pass
        *sections, last = name.split(".")
        node = out
        for key in sections:
            node = node.setdefault(key, {})
        node[last] = value
    return out


def run(folder: Path, dump=None, cut=None, params=None) -> str:
    t0 = time.perf_counter()
    name = folder.name if cut is None else f"{cut} cut to 3"
    try:
        if cut is None:
            truth = load_truth(folder)
            a = analyze(folder, None, params or {}, progress=lambda *x: None)
        else:
            full = load_truth(folder)
            keep = bmc.kept_three(cut)
            with bmc._Cut(keep, full):
                a = analyze(folder, None, params or {}, progress=lambda *x: None)
            truth = bmc._cut_truth(full, keep)
    except AnalysisError as exc:
        return f"{name[:44]:44s} stopped: {str(exc)[:80]}"
    rec = record_of(name, a, truth)
    if dump is not None:
        with open(Path(dump) / f"{name}.pkl", "wb") as fh:
            pickle.dump(rec, fh)
    return row(rec) + f"  ({time.perf_counter() - t0:.0f} s)"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("patterns", nargs="*", default=list(DEFAULT))
    parser.add_argument("--dump", help="folder to pickle each run's numbers into")
    parser.add_argument("--reuse", help="folder of pickles written by --dump: the table without analysing")
    parser.add_argument("--cuts", action="store_true", help="also the spread rigs cut to three markers")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="an analysis parameter by its dotted name (repeatable)")
    args = parser.parse_args()
    params = parameters(args.set)
    print(HEAD, flush=True)
    if args.reuse:
        records = []
        for f in sorted(Path(args.reuse).glob("*.pkl")):
            with open(f, "rb") as fh:
                records.append(pickle.load(fh))
            print(row(records[-1]), flush=True)
        print("\n".join(summary(records)))
        return
    for f in folders(args.patterns):
        print(run(f, args.dump, params=params), flush=True)
    if args.cuts:
        for c in CUTS:
            print(run(bmc.cover_session(c), args.dump, cut=c, params=params), flush=True)


if __name__ == "__main__":
    sys.exit(main())
