"""More markers and partly covered markers: the default analysis against the truth.

Renders (into the cache, on demand, one at a time) the sessions of
:data:`horsemocap.virtuallab.covers.COVER_SESSIONS` named on the command line
(default: all) and runs the default analysis on each: the exit status the
command would give (3 when the verdict is unreliable, 2 when a step stops),
the verdict, the checks above ok, wrong identities, the saddle's vertical
acceleration error (% of its rms) and the Wb / Wk rms errors against the
truth, per camera the 2D values flagged as partly covered, and per marker
the frames left out of the pose for moving against the others' rigid motion.

Usage: ``python benchmarks/bench_markers_covers.py [NAME ...]``
(``results/markers_covers.txt``: the run noted in benchmarks/README.md).
"""
import sys
import time

import numpy as np

from horsemocap import accuracy, quality
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.virtuallab import load_truth
from horsemocap.virtuallab.covers import COVER_SESSIONS, cover_session


def run(name: str) -> str:
    t0 = time.perf_counter()
    folder = cover_session(name)
    try:
        a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{name:22s} exit 2 stopped: {str(exc)[:200]}"
    except Exception as exc:                                   # noqa: BLE001 - a benchmark reports every failure
        return f"{name:22s} CRASH {exc!r}"[:300]
    checks = quality.post_checks(a)
    v = quality.verdict(checks)
    truth = load_truth(folder)
    ide = accuracy.identification_errors(a, truth)
    st = accuracy.stage_errors(a, truth)
    if a.comfort is None or a.comfort.indicators is None:
        why = a.comfort.reason if a.comfort is not None else "no comfort step"
        return f"{name:22s} markers {a.session.marker_count} exit {3 if v == 'unreliable' else 0} {v} no comfort: {why}"
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms"))
    bad = [f"{c.name}:{c.level}" for c in checks if c.level in ("warning", "unreliable")]
    covered = {c: int(np.sum(r == "partly_covered")) for c, r in a.detect.reason.items()}
    during = _reasons_under_covers(a, truth)
    lo = a.rigid_body.body.left_out
    left_out = {} if lo is None else {int(m): int(lo[:, m].sum()) for m in np.flatnonzero(lo.any(axis=0))}
    return (f"{name:22s} markers {a.session.marker_count} exit {3 if v == 'unreliable' else 0} {v:10s} "
            f"wrong {ide['wrong_total']:3d} A_y {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} % "
            f"Wb {ce['acc_y_Wb_rms']:+6.1f} % Wk {ce['acc_y_Wk_rms']:+6.1f} % partly_covered {covered} "
            f"left out of the pose {left_out} {bad} "
            f"{time.perf_counter() - t0:.0f}s" + "".join(f"\n    under the cover, {k}: {v}" for k, v in during.items()))


def _reasons_under_covers(a, truth) -> dict:
    """Per camera: the reasons the covered marker's 2D values got while more than 5 % of it was covered."""
    out = {}
    off = a.synchronisation.offsets
    for key, frac in truth.extras.items():
        if not key.startswith("cover_fraction__"):
            continue
        _, name, cam = key.split("__")
        marker = truth.extras[f"cover_{name}"]["marker"]
        frames = np.flatnonzero(np.asarray(frac) > 0.05) - off[cam]
        r = a.detect.reason[cam]
        frames = frames[(frames >= 0) & (frames < len(r))]
        labels, counts = np.unique(r[frames, marker], return_counts=True)
        out[f"{name} {cam}"] = {str(lab) or "used": int(n) for lab, n in zip(labels, counts)}
    return out


if __name__ == "__main__":
    for n in sys.argv[1:] or list(COVER_SESSIONS):
        print(run(n), flush=True)
