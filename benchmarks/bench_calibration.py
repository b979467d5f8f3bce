"""How far the thesis' calibration puts the markers, over many calibration sets.

For each seed the virtual laboratory renders the checkerboard views a session
of that seed would hold (all boards near the path, 7.5-8 m from the cameras,
as in thesis section 8.2), the rig is calibrated from them as the pipeline
does, and the exact projections of the default session's markers are
triangulated with it (``accuracy.calibration_draws``). The marker error in
the true motion axes is split into the constant offset (the datum) and the
motion error. Prints a row per draw and the spread, and merges every number
into ``benchmarks/results/calibration_draws.json`` (read by notebook 06; rows
of the same protocol, views and seed are replaced, the others kept).

Usage: ``python benchmarks/bench_calibration.py [--seeds 0-9] [--views 45 90] [--protocol path|depths]``
(about 20 s per 45-view draw, 40 s per 90-view draw on this machine).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent / "results" / "calibration_draws.json"


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def _jsonable(row: dict) -> dict:
    def conv(v):
        if isinstance(v, dict):
            return {k: conv(x) for k, x in v.items()}
        if isinstance(v, np.ndarray):
            return [float(x) for x in v]
        if isinstance(v, np.floating):
            return float(v)
        return v
    return conv(row)


def main():
    from horsemocap.virtuallab.calibration import PROTOCOLS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--views", type=int, nargs="+", default=[45, 90])
    ap.add_argument("--protocol", default="path", choices=sorted(PROTOCOLS),
                    help="where the boards stand (virtuallab.calibration.PROTOCOLS)")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()

    from horsemocap.accuracy import calibration_draws
    from horsemocap.data import data_samples_dir
    from horsemocap.virtuallab import load_truth

    truth = load_truth(data_samples_dir() / "horse2_canter")
    rows = []
    print(f"{'views':>5s} {'seed':>4s} {'time_s':>6s} {'dfx_left':>8s} {'dcy_left':>8s} "
          f"{'offset_x_mm':>11s} {'offset_y_mm':>11s} {'offset_z_mm':>11s} {'motion_x_mm':>11s} {'motion_y_mm':>11s}")
    for n_views in args.views:
        for seed in _seeds(args.seeds):
            t0 = time.perf_counter()
            row = calibration_draws(truth, [seed], n_views, protocol=args.protocol)[0]
            row["time_s"] = time.perf_counter() - t0
            rows.append(_jsonable(row))
            ie = row["intrinsic_error"]["left"]
            o, m = 1000 * row["offset_m"], 1000 * row["motion_rmse_m"]
            print(f"{n_views:5d} {seed:4d} {row['time_s']:6.1f} {ie[0]:8.2f} {ie[3]:8.2f} "
                  f"{o[0]:11.2f} {o[1]:11.2f} {o[2]:11.2f} {m[0]:11.2f} {m[1]:11.2f}", flush=True)
    print("\nspread over the draws (mm): mean |offset| and std of the offset per axis; worst motion RMSE")
    for n_views in args.views:
        sel = [r for r in rows if r["n_views"] == n_views]
        off = 1000 * np.array([r["offset_m"] for r in sel])
        mot = 1000 * np.array([r["motion_rmse_m"] for r in sel])
        print(f"{n_views} views, {len(sel)} draws: |offset| mean {np.round(np.abs(off).mean(0), 2)}, "
              f"std {np.round(off.std(0, ddof=1), 2) if len(sel) > 1 else '-'}, "
              f"motion RMSE max {np.round(mot.max(0), 2)}")
    _merge(Path(args.out), rows, " ".join(["python benchmarks/bench_calibration.py", f"--seeds {args.seeds}",
                                            "--views", *map(str, args.views), f"--protocol {args.protocol}"]))
    print(f"wrote {args.out}")


def _merge(path: Path, rows: list, command: str) -> None:
    """Add ``rows`` to the results file, replacing rows of the same (protocol, views, seed)."""
    old = json.loads(path.read_text()) if path.is_file() else {}

    def key(r):
        return r.get("protocol", "path"), r["n_views"], r["seed"]

    new_keys = {key(r) for r in rows}
    kept = [r for r in old.get("rows", []) if key(r) not in new_keys]
    out = {"session": "data_samples/horse2_canter", "commands": old.get("commands", []) + [command],
           "rows": sorted(kept + rows, key=lambda r: (key(r)[0] != "path", key(r)[1], key(r)[2]))}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, indent=1))
    tmp.replace(path)


if __name__ == "__main__":
    main()
