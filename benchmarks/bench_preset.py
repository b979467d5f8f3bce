"""The thesis preset beside the default: the bundled session and the 16 virtual herd sessions.

For each session, ``pipeline.analyze`` runs twice on the same input, once with
the automatic choices (``{}``) and once with ``{"preset": "thesis"}``
(:data:`horsemocap.params.PRESETS`), and both are compared with the
session's truth: the saddle's vertical acceleration error (RMSE, % of the
true rms) and the signed errors (%) of the Wb/Wk-weighted rms and VDV. The
weighting alone is measured too: the analytic indicators of the true motion
with the thesis' single-scalar weighting against ISO's per-harmonic one
(``herd.analytic_indicators``), so the part of the thesis chain's error that
is the weighting is told from the part that is the measurement.

Writes ``benchmarks/results/preset_thesis.json`` (read by notebook 14) and
prints a table. Usage: ``python benchmarks/bench_preset.py [--only NAME]``
(about 15-20 min on a loaded 2-core machine from the render cache; the
thesis chain's per-camera detection is the slow part).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

KEYS = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk")
PRESETS = {"default": {}, "thesis": {"preset": "thesis"}}
OUT = Path(__file__).parent / "results" / "preset_thesis.json"


def one(folder, params):
    from horsemocap import accuracy
    from horsemocap.pipeline import AnalysisError, analyze
    from horsemocap.virtuallab import load_truth

    t0 = time.perf_counter()
    try:
        a = analyze(folder, None, params, progress=lambda *x: None)
    except AnalysisError as exc:
        return {"completed": False, "error": str(exc)[:300], "seconds": time.perf_counter() - t0}
    truth = load_truth(folder)
    st = accuracy.stage_errors(a, truth)
    ind = a.comfort.indicators
    ce = accuracy.comfort_errors(ind, truth.comfort, KEYS) if ind else {}
    return {"completed": True, "seconds": time.perf_counter() - t0, "frames": int(st["frames"]),
            "saddle_acc_y_pct": float(st["saddle_acc_y_rmse_pct_of_rms"]),
            "comfort_error_pct": {k: float(v) for k, v in ce.items()},
            "indicators": {k: float(ind[k]) for k in KEYS} if ind else None,
            "warnings": list(a.rigid_body.warnings)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="only sessions whose name contains this")
    args = ap.parse_args()

    from horsemocap import herd
    from horsemocap.data import default_session_dir
    from horsemocap.virtuallab import GAITS, HORSES, herd_session

    sessions = [("bundled Horse 2 canter", default_session_dir(), None)]
    sessions += [(f"{h} {g}", None, (h, g)) for h in HORSES for g in GAITS]
    rows = []
    print(f"{'session':26s} {'preset':8s} {'s':>5s} {'frames':>6s} {'saddle_Ay_%':>11s} "
          + " ".join(f"{k + '_%':>14s}" for k in KEYS))
    for name, folder, hg in sessions:
        if args.only not in name:
            continue
        folder = folder or herd_session(*hg)
        row = {"session": name}
        if hg is not None:  # the weighting alone, on the true motion
            iso = herd.analytic_indicators(*hg, mode="iso")
            th = herd.analytic_indicators(*hg, mode="thesis")
            row["weighting_only_pct"] = {k: float(100 * (th[k] - iso[k]) / iso[k]) for k in KEYS}
        for label, params in PRESETS.items():
            r = one(folder, params)
            row[label] = r
            if r["completed"]:
                print(f"{name:26s} {label:8s} {r['seconds']:5.0f} {r['frames']:6d} {r['saddle_acc_y_pct']:11.1f} "
                      + " ".join(f"{r['comfort_error_pct'].get(k, np.nan):14.1f}" for k in KEYS), flush=True)
            else:
                print(f"{name:26s} {label:8s} {r['seconds']:5.0f}  stopped: {r['error'][:120]}", flush=True)
        rows.append(row)
    summary = {}
    for label in PRESETS:
        herd_rows = [r[label] for r in rows if r["session"] != "bundled Horse 2 canter" and r[label]["completed"]]
        if not herd_rows:
            continue
        summary[label] = {
            "herd_completed": len(herd_rows),
            "median_saddle_acc_y_pct": float(np.median([r["saddle_acc_y_pct"] for r in herd_rows])),
            "worst_saddle_acc_y_pct": float(np.max([r["saddle_acc_y_pct"] for r in herd_rows])),
            "median_abs_comfort_error_pct": {k: float(np.median([abs(r["comfort_error_pct"][k]) for r in herd_rows]))
                                             for k in KEYS},
            "sessions_with_warnings": sum(bool(r["warnings"]) for r in herd_rows)}
    w = [r["weighting_only_pct"] for r in rows if "weighting_only_pct" in r]
    if w:
        summary["weighting_only_median_pct"] = {k: float(np.median([x[k] for x in w])) for k in KEYS}
    print(json.dumps(summary, indent=1))
    if not args.only:
        OUT.write_text(json.dumps({"keys": KEYS, "rows": rows, "summary": summary}, indent=1) + "\n")
        print(f"written: {OUT}")


if __name__ == "__main__":
    main()
