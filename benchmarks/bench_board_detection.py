"""The fallback board detector's flags: time, corners and calibration, with and without ``CALIB_CB_ACCURACY``.

``calibration.board.detect_board`` tries OpenCV's classic detector and, where
it fails, ``findChessboardCornersSB``; either way the corners are refined by
``cornerSubPix``. This compares the fallback with its flags as they are
(``board.SECTOR_FLAGS``) and with ``CALIB_CB_ACCURACY`` added, on the bundled
session's views and on calibration sets rendered by the virtual laboratory
(the views a session of each seed holds): the fallback's time (one thread),
how far the refined corners move, and the rig calibrated from each against
the truth (focal length and principal point errors, px; baseline, %).

Usage: ``python benchmarks/bench_board_detection.py [--seeds 0-4] [--views 45]``
(about 30 s per rendered set). Prints a table and writes
``benchmarks/results/board_detection.json``.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from bench_calibration import _seeds   # "0-4" or "0,2,5" (this folder is on the path when run)

OUT = Path(__file__).resolve().parent / "results" / "board_detection.json"


def _detect(image_dirs: dict, inner, flags: int):
    """Every camera's views with the fallback's ``flags``; (views, fallback seconds, fallback views)."""
    from horsemocap.calibration import board

    spent = [0.0, 0]
    original_sb = cv2.findChessboardCornersSB

    def timed_sb(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return original_sb(*args, **kwargs)
        finally:
            spent[0] += time.perf_counter() - t0
            spent[1] += 1

    saved = board.SECTOR_FLAGS
    board.SECTOR_FLAGS, cv2.findChessboardCornersSB = flags, timed_sb
    try:
        views = board.detect_cameras(image_dirs, inner, workers=1)
    finally:
        board.SECTOR_FLAGS, cv2.findChessboardCornersSB = saved, original_sb
    return views, spent[0], spent[1]


def _rig_errors(rig, true_rig) -> dict:
    out = {}
    for cam in rig:
        K, Kt = cam.matrix, true_rig[cam.name].matrix
        err = {"fx": K[0, 0] - Kt[0, 0], "fy": K[1, 1] - Kt[1, 1], "cx": K[0, 2] - Kt[0, 2], "cy": K[1, 2] - Kt[1, 2]}
        if np.linalg.norm(true_rig[cam.name].center) > 0:
            b, bt = np.linalg.norm(cam.center), np.linalg.norm(true_rig[cam.name].center)
            err["baseline_pct"] = 100 * (b - bt) / bt
        out[cam.name] = {k: float(v) for k, v in err.items()}
    return out


def compare(image_dirs: dict, inner, square_m: float, reference: str, true_rig=None) -> dict:
    """Both flag settings on one set of views: times, corner moves, rigs."""
    from horsemocap.calibration import board, calibrate_rig

    rows = {}
    for name, flags in (("now", board.SECTOR_FLAGS), ("with ACCURACY", board.SECTOR_FLAGS | cv2.CALIB_CB_ACCURACY)):
        views, seconds, calls = _detect(image_dirs, inner, flags)
        cal = calibrate_rig(None, inner, square_m, reference=reference, views=views, pairs=False)
        rows[name] = {"views": views, "seconds": seconds, "calls": calls, "rig": cal.rig,
                      "found": {c: int(np.isfinite(v.corners[:, 0, 0]).sum()) for c, v in views.items()}}
    a, b = rows["now"], rows["with ACCURACY"]
    moves = [np.nanmax(np.abs(a["views"][c].corners - b["views"][c].corners)) for c in a["views"]
             if np.isfinite(a["views"][c].corners - b["views"][c].corners).any()]
    result = {"fallback_views": a["calls"], "fallback_s_now": a["seconds"], "fallback_s_accuracy": b["seconds"],
              "found_now": a["found"], "found_accuracy": b["found"],
              "max_corner_move_px": float(max(moves)) if moves else 0.0,
              "rig_difference": {c: float(np.abs(a["rig"][c].matrix - b["rig"][c].matrix).max()) for c in a["rig"].names}}
    if true_rig is not None:
        result["errors_now"] = _rig_errors(a["rig"], true_rig)
        result["errors_accuracy"] = _rig_errors(b["rig"], true_rig)
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--views", type=int, default=45)
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()

    from horsemocap.data import default_session_dir
    from horsemocap.session import load_session
    from horsemocap.virtuallab import render_calibration_set

    cv2.setNumThreads(1)
    sets = {}
    s = load_session(default_session_dir())
    sets["bundled"] = compare(s.calibration_images, tuple(s.board.inner_corners), s.board.square_size_m,
                              s.cameras[0])
    for seed in _seeds(args.seeds):
        with tempfile.TemporaryDirectory() as tmp:
            cal_set = render_calibration_set(tmp, seed, args.views)
            b = cal_set["board"]
            sets[f"seed {seed}"] = compare(cal_set["images"], tuple(b["inner_corners"]), b["square_size_m"],
                                           cal_set["rig"].names[0], cal_set["rig"])
    print(f"{'set':10} {'fallback':>8} {'s now':>7} {'s ACC':>7} {'ratio':>6} {'max move px':>11}  "
          "worst |error| now / with ACCURACY (fx fy cx cy px, baseline %)")
    for name, r in sets.items():
        line = (f"{name:10} {r['fallback_views']:8d} {r['fallback_s_now']:7.2f} {r['fallback_s_accuracy']:7.2f} "
                f"{r['fallback_s_accuracy'] / max(r['fallback_s_now'], 1e-9):6.2f} {r['max_corner_move_px']:11.2e}")
        if "errors_now" in r:
            def worst(errs, key):
                return max(abs(e[key]) for e in errs.values() if key in e)
            line += "  " + " ".join(f"{k} {worst(r['errors_now'], k):.3f}/{worst(r['errors_accuracy'], k):.3f}"
                                    for k in ("fx", "fy", "cx", "cy", "baseline_pct"))
        if r["found_now"] != r["found_accuracy"]:
            line += f"  found {r['found_now']} vs {r['found_accuracy']}"
        print(line)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(sets, indent=1) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
