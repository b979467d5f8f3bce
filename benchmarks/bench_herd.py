"""The 16 virtual herd sessions through the whole pipeline, against their truth.

Renders each (horse, gait) session into the cache on first use
(``virtuallab.herd_session``), runs ``pipeline.analyze`` with the automatic
choices, and prints per session: whether it completed (else the step and
message), the analysed frames, the saddle's vertical acceleration error (% of
rms) and the errors of the weighted rms and VDV against the truth; then the
Spearman rank correlations of the indicators with the riders' grades
(thesis Table 8.8) from the pipeline and from the truth.

Usage: ``python benchmarks/bench_herd.py [--mode iso|thesis]`` (about 15 min
on first use on 2 cores, most of it rendering; about 2 min from the cache).

``--hard`` runs the harder virtual laboratory instead
(:data:`horsemocap.virtuallab.hard.HARD_SESSIONS`, issue 17: 720p/1080p,
30-100 fps, wide and toed-in rigs, a stirrup, a reflector crossing the markers,
a marker hidden in one camera, markers near the border, speed changes),
rendered on demand into the cache (about 15-25 min on first use on a loaded
2-core machine); it prints, per session, the same columns plus the 2D
identity swaps and median centroid error against the truth. ``--only NAME``
restricts to sessions whose name contains NAME.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mode", default="iso", choices=["iso", "thesis"])
    ap.add_argument("--params", default="{}", help="JSON analysis parameters, e.g. '{\"smoothing_method\": \"rloess\"}'")
    ap.add_argument("--hard", action="store_true", help="run the hard set (issue 17) instead of the herd")
    ap.add_argument("--only", default="", help="only sessions whose name contains this")
    args = ap.parse_args()
    if args.hard:
        return run_hard(args)

    from horsemocap import accuracy, herd
    from horsemocap.pipeline import AnalysisError, analyze
    from horsemocap.virtuallab import GAITS, HORSES, herd_session, load_truth

    keys = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk")
    table, done, errors = {}, 0, []
    print(f"{'session':28s} {'render_s':>8s} {'analyse_s':>9s} {'frames':>6s} {'saddle_Ay_%':>11s} "
          + " ".join(f"{k + '_%':>14s}" for k in keys))
    for horse in HORSES:
        for gait in GAITS:
            t0 = time.perf_counter()
            folder = herd_session(horse, gait)
            t1 = time.perf_counter()
            name = f"{horse} {gait}"
            try:
                a = analyze(folder, None, {"weighting_mode": args.mode, **json.loads(args.params)},
                            progress=lambda *x: None)
            except AnalysisError as exc:
                print(f"{name:28s} {t1 - t0:8.1f} {'-':>9s}  stopped: {str(exc)[:150]}")
                continue
            t2 = time.perf_counter()
            truth = load_truth(folder)
            st = accuracy.stage_errors(a, truth)
            ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, keys)
            table[(horse, gait)] = a.comfort.indicators
            errors.append((st["saddle_acc_y_rmse_pct_of_rms"], *(abs(ce[k]) for k in keys)))
            done += 1
            print(f"{name:28s} {t1 - t0:8.1f} {t2 - t1:9.1f} {st['frames']:6d} {st['saddle_acc_y_rmse_pct_of_rms']:11.1f} "
                  + " ".join(f"{ce[k]:14.1f}" for k in keys))
    print(f"\n{done} of {len(HORSES) * len(GAITS)} sessions analysed")
    if errors:
        med = np.median(np.asarray(errors), axis=0)
        print(f"median saddle A_y error {med[0]:.1f} % of rms; median |error| "
              + ", ".join(f"{k} {m:.1f} %" for k, m in zip(keys, med[1:])))
    if done == len(HORSES) * len(GAITS):
        for label, tab in (("pipeline", table), ("truth", herd.herd_indicators("analytic", mode=args.mode))):
            comp = herd.compare(tab)
            print(f"\nrank correlations with the riders' grades ({label}):")
            for c in comp:
                print(f"  {c}")


def run_hard(args):
    """The hard set through the whole pipeline: what completes, and how wrong it is."""
    from horsemocap import accuracy
    from horsemocap.pipeline import AnalysisError, analyze
    from horsemocap.virtuallab import load_truth
    from horsemocap.virtuallab.hard import HARD_SESSIONS, hard_session

    keys = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk")
    names = [n for n in HARD_SESSIONS if args.only in n]
    print(f"{'session':40s} {'render_s':>8s} {'analyse_s':>9s} {'frames':>6s} {'swaps':>5s} {'med_px':>6s} "
          f"{'saddle_Ay_%':>11s} " + " ".join(f"{k + '_%':>14s}" for k in keys))
    done, worst = 0, {}
    for name in names:
        t0 = time.perf_counter()
        folder = hard_session(name)
        t1 = time.perf_counter()
        try:
            a = analyze(folder, None, {"weighting_mode": args.mode, **json.loads(args.params)},
                        progress=lambda *x: None)
        except AnalysisError as exc:
            print(f"{name:40s} {t1 - t0:8.1f} {'-':>9s}  stopped: {str(exc)[:200]}")
            continue
        except Exception as exc:  # a crash is a result here too: report it and go on
            print(f"{name:40s} {t1 - t0:8.1f} {'-':>9s}  crashed: {type(exc).__name__}: {str(exc)[:200]}")
            continue
        t2 = time.perf_counter()
        truth = load_truth(folder)
        e2 = accuracy.errors_2d(a, truth)
        swaps = sum(v["swaps"] for v in e2.values())
        med = max(v["median"] for v in e2.values())
        st = accuracy.stage_errors(a, truth)
        ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, keys)
        done += 1
        for k, v in (("saddle_Ay", st["saddle_acc_y_rmse_pct_of_rms"]), *ce.items()):
            worst[k] = max(worst.get(k, 0.0), abs(v))
        print(f"{name:40s} {t1 - t0:8.1f} {t2 - t1:9.1f} {st['frames']:6d} {swaps:5d} {med:6.3f} "
              f"{st['saddle_acc_y_rmse_pct_of_rms']:11.1f} " + " ".join(f"{ce[k]:14.1f}" for k in keys))
    print(f"\n{done} of {len(names)} hard sessions analysed")
    if worst:
        print("worst |error| over the analysed ones: " + ", ".join(f"{k} {v:.1f} %" for k, v in worst.items()))


if __name__ == "__main__":
    main()
