"""Detection noise through the kinematics (notebook 14's study) for each kinematics variant.

On the bundled session (Horse 2, canter) the detections are replaced by the
true projections plus white noise of sigma pixels
(:func:`horsemocap.accuracy.noise_study`, 3 draws per sigma, medians) and
the steps from triangulation to the comfort indicators are run again with
each variant of the parameters. Printed: variant, sigma, draws, the saddle's
vertical acceleration RMSE (% of its rms) and the indicator errors (%).

Usage: ``python benchmarks/bench_noise_kinematics.py [--sigmas 0.1 0.25 0.5] ['{"kinematics": "fits"}' ...]``
(default variants: fits; pose_spline with ``pose_harmonics`` none, all and auto, the default; and
the default with ``"pose_weights": "equal"``: the pose registered with equal marker weights
(Horn) instead of each marker's inverse covariance from the triangulation, as before 2026-11-24).
"""
from __future__ import annotations

import argparse
import json


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigmas", type=float, nargs="+", default=[0.0, 0.1, 0.25, 0.5])
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("variants", nargs="*")
    args = ap.parse_args(argv)
    variants = [json.loads(a) for a in args.variants] or [
        {"kinematics": "fits"}, {"kinematics": "pose_spline", "pose_harmonics": "none"},
        {"kinematics": "pose_spline", "pose_harmonics": "all"}, {"kinematics": "pose_spline", "pose_harmonics": "auto"},
        {"kinematics": "pose_spline", "pose_harmonics": "auto", "pose_weights": "equal"}]
    from horsemocap import accuracy
    from horsemocap.data import default_session_dir
    from horsemocap.pipeline import analyze
    from horsemocap.virtuallab import load_truth

    folder = default_session_dir()
    base = analyze(folder, None, {}, until="motion_frame", progress=lambda *a: None)
    truth = load_truth(folder)
    for v in variants:
        rows = accuracy.noise_study(base, truth, sigmas_px=args.sigmas, repeats=args.draws,
                                    params=accuracy.with_params(base, **v))
        for r in rows:
            if not r["draws"]:
                print(json.dumps(v), r["sigma_px"], 0, "failed:", r["failed"], flush=True)
                continue
            print(json.dumps(v), r["sigma_px"], r["draws"], f"{r['saddle_acc_y_pct']:.1f}",
                  {k: round(x, 1) for k, x in r["comfort_pct"].items()}, flush=True)
    print("target (issue 13): saddle acceleration error below 20 % at 0.25 px")


if __name__ == "__main__":
    main()
