"""The 16 virtual herd sessions: the thesis' chain of fits against the pose-trajectory estimator.

Each session is analysed once up to the motion frame (``pipeline.analyze``;
rendered into the cache on first use by ``virtuallab.herd_session``), then
the rigid-body and comfort steps are run for each variant on the same
detections. Printed per session and variant: the saddle's vertical
acceleration RMSE (% of its rms) and the errors (%) of the Wb/Wk-weighted rms
and VDV against the truth; then the medians and worst cases.

Usage: ``python benchmarks/bench_herd_kinematics.py [--set herd|hard] ['{"kinematics": "fits"}' ...]``
(``--set hard``: the 8 harder sessions of :mod:`horsemocap.virtuallab.hard` instead of the herd)
(default variants: fits; pose_spline with plain splines, with the stride's harmonics in every
component, and the default ``pose_harmonics: auto``; and the default with ``"pose_weights":
"equal"``: the pose registered with equal marker weights (Horn) instead of each marker's inverse
covariance from the triangulation, as before 2026-11-24).
"""
from __future__ import annotations

import json
import sys
from dataclasses import replace

import numpy as np

KEYS = ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    which = "herd"
    if "--set" in argv:
        i = argv.index("--set")
        which = argv[i + 1]
        del argv[i:i + 2]
    if which not in ("herd", "hard"):
        raise SystemExit(f"--set: expected herd or hard, got {which!r}")
    variants = [json.loads(a) for a in argv] or [
        {"kinematics": "fits"}, {"kinematics": "pose_spline", "pose_harmonics": "none"},
        {"kinematics": "pose_spline", "pose_harmonics": "all"}, {"kinematics": "pose_spline", "pose_harmonics": "auto"},
        {"kinematics": "pose_spline", "pose_harmonics": "auto", "pose_weights": "equal"}]
    from horsemocap import accuracy
    from horsemocap.pipeline import analyze, run_steps
    from horsemocap.virtuallab import GAITS, HORSES, herd_session, load_truth

    table = {i: [] for i in range(len(variants))}
    for i, v in enumerate(variants):
        print(f"variant {i}: {v}")
    print(f"{'session':24s} {'frames':>6s}  " + " | ".join(f"v{i}: Ay%  Wb%  Wk%  VDVb% VDVk%" for i in range(len(variants))))
    if which == "herd":
        sessions = [(f"{h} {g}", lambda h=h, g=g: herd_session(h, g)) for h in HORSES for g in GAITS]
    else:
        from horsemocap.virtuallab.hard import HARD_SESSIONS, hard_session
        sessions = [(name, lambda name=name: hard_session(name)) for name in HARD_SESSIONS]
    for name, make in sessions:
        folder = make()
        base = analyze(folder, None, {}, until="motion_frame", progress=lambda *a: None)
        truth = load_truth(folder)
        cells = []
        for i, v in enumerate(variants):
            a = run_steps(base.session, base.params.updated(v), base, ["rigid_body", "comfort"])
            st = accuracy.stage_errors(a, truth)
            ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, KEYS)
            row = [st["saddle_acc_y_rmse_pct_of_rms"], *(ce[k] for k in KEYS)]
            table[i].append(row)
            cells.append(" ".join(f"{x:5.1f}" for x in row))
        print(f"{name:24s} {st['frames']:6d}  " + " | ".join(cells), flush=True)
    for i, v in enumerate(variants):
        arr = np.abs(np.asarray(table[i]))
        med, worst = np.median(arr, axis=0), arr.max(axis=0)
        print(f"variant {i} {v}: saddle A_y median {med[0]:.1f} % (worst {worst[0]:.1f} %); median |error| "
              + ", ".join(f"{k} {m:.1f} % (worst {w:.1f} %)" for k, m, w in zip(KEYS, med[1:], worst[1:])))


if __name__ == "__main__":
    main()
