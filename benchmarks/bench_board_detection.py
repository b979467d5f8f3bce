"""The board detectors' flags: time, corners and calibration, each flag against the flags as they are.

``calibration.board.detect_board`` tries OpenCV's classic detector
(``board.CLASSIC_FLAGS``) and, where it fails, ``findChessboardCornersSB``
(``board.SECTOR_FLAGS``); either way the corners are refined by
``cornerSubPix``. This compares the flags as they are ("now") with two
variants, each one flag apart: ``CALIB_CB_NORMALIZE_IMAGE`` added to the
classic detector's flags (as before 2026-11-24, evening) and
``CALIB_CB_ACCURACY`` added to the fallback's (as before 2026-11-24,
afternoon), on the bundled session's views and on calibration sets rendered
by the virtual laboratory (the views a session of each seed holds): the
detectors' time (one thread), the views each finds, how far the refined
corners move, and the rig calibrated from each against the truth (focal
length and principal point errors, px; baseline, %).

Usage: ``python benchmarks/bench_board_detection.py [--seeds 0-4] [--views 45]``
(about 40 s per rendered set). Prints a table and writes
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


VARIANTS = {"now": (0, 0), "with NORMALIZE_IMAGE": (cv2.CALIB_CB_NORMALIZE_IMAGE, 0),
            "with ACCURACY": (0, cv2.CALIB_CB_ACCURACY)}
"""Flags added to (``CLASSIC_FLAGS``, ``SECTOR_FLAGS``) in each variant."""


def _detect(image_dirs: dict, inner, classic_flags: int, sector_flags: int):
    """Every camera's views with these flags; (views, classic seconds, fallback seconds, fallback views)."""
    from horsemocap.calibration import board

    spent = {"classic": [0.0, 0], "sector": [0.0, 0]}
    originals = cv2.findChessboardCorners, cv2.findChessboardCornersSB

    def timed(function, kind):
        def run(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent[kind][0] += time.perf_counter() - t0
                spent[kind][1] += 1
        return run

    saved = board.CLASSIC_FLAGS, board.SECTOR_FLAGS
    board.CLASSIC_FLAGS, board.SECTOR_FLAGS = classic_flags, sector_flags
    cv2.findChessboardCorners, cv2.findChessboardCornersSB = timed(originals[0], "classic"), timed(originals[1], "sector")
    try:
        views = board.detect_cameras(image_dirs, inner, workers=1)
    finally:
        board.CLASSIC_FLAGS, board.SECTOR_FLAGS = saved
        cv2.findChessboardCorners, cv2.findChessboardCornersSB = originals
    return views, spent["classic"][0], spent["sector"][0], spent["sector"][1]


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
    """Every variant (:data:`VARIANTS`) on one set of views: times, views found, corner moves, rigs."""
    from horsemocap.calibration import board, calibrate_rig

    rows = {}
    for name, (add_classic, add_sector) in VARIANTS.items():
        views, classic_s, sector_s, calls = _detect(image_dirs, inner, board.CLASSIC_FLAGS | add_classic,
                                                    board.SECTOR_FLAGS | add_sector)
        cal = calibrate_rig(None, inner, square_m, reference=reference, views=views, pairs=False)
        row = {"classic_s": classic_s, "fallback_s": sector_s, "fallback_views": calls,
               "found": {c: int(np.isfinite(v.corners[:, 0, 0]).sum()) for c, v in views.items()}}
        if true_rig is not None:
            row["errors"] = _rig_errors(cal.rig, true_rig)
        rows[name] = (views, cal.rig, row)
    now_views, now_rig, _ = rows["now"]
    result = {}
    for name, (views, rig, row) in rows.items():
        if name != "now":
            diff = [np.abs(views[c].corners - now_views[c].corners) for c in views]
            moves = [np.nanmax(d) for d in diff if np.isfinite(d).any()]
            row["max_corner_move_px"] = float(max(moves)) if moves else 0.0
            row["rig_difference"] = {c: float(np.abs(rig[c].matrix - now_rig[c].matrix).max()) for c in rig.names}
        result[name] = row
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
    print(f"{'set':10} {'variant':22} {'classic s':>9} {'fallback':>8} {'s':>6} {'max move px':>11}  "
          "worst |error| (fx fy cx cy px, baseline %)  views found")
    for name, variants in sets.items():
        for variant, r in variants.items():
            line = (f"{name:10} {variant:22} {r['classic_s']:9.2f} {r['fallback_views']:8d} {r['fallback_s']:6.2f} "
                    f"{r.get('max_corner_move_px', 0.0):11.2e}")
            if "errors" in r:
                line += "  " + " ".join(f"{k} {max(abs(e[k]) for e in r['errors'].values() if k in e):.3f}"
                                        for k in ("fx", "fy", "cx", "cy", "baseline_pct"))
            print(line + f"  {r['found']}")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(sets, indent=1) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
