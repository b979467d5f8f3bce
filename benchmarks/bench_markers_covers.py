"""More markers and partly covered markers: the default analysis against the truth.

Renders (into the cache, on demand, one at a time) the sessions of
:data:`horsemocap.virtuallab.covers.COVER_SESSIONS` named on the command line
(default: all) and runs the default analysis on each: the exit status the
command would give (3 when the verdict is unreliable, 2 when a step stops),
the verdict, the checks above ok, wrong identities, the saddle's vertical
acceleration error (% of its rms) and the Wb / Wk rms errors against the
truth, per camera the 2D values flagged as partly covered, and per marker
the frames left out of the pose for moving against the others' rigid motion.

Usage: ``python benchmarks/bench_markers_covers.py [--cut] [NAME ...]``
(``results/markers_covers.txt``: the run noted in benchmarks/README.md).
``--cut``: a session with more than three markers is also analysed cut to the
horse's own three (the same ride and the same noise: the extra markers' columns
dropped from the triangulated points and their points from the static shot
the rigid-body step reads),
and the marker model chosen is printed.
"""
import dataclasses
import sys
import time

import numpy as np

from horsemocap import accuracy, pipeline, quality
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.virtuallab import load_truth
from horsemocap.virtuallab.covers import COVER_SESSIONS, cover_session
from horsemocap.virtuallab.horse import HERD


def kept_three(name: str) -> list:
    """Indices (in the session's marker order) of the herd horse's own three markers."""
    sc = COVER_SESSIONS[name]
    body = sc.horse().marker_body
    own = HERD[sc.base.horse].marker_body
    return [int(np.argmin(np.linalg.norm(body - m, axis=1))) for m in own]


class _Cut:
    """``pipeline.STEP_CALLS`` with the triangulated markers and the static shot's (in the motion frame, as the
    rigid-body step reads them) cut to ``keep``; detection and identification see every marker."""

    def __init__(self, keep, truth):
        self.keep, self.truth = list(keep), truth
        self.saved = {}

    def _motion_frame(self, a, r):
        pts = np.asarray(a.static.static_points, float)       # the static shot (world), rows as r.static's
        m = len(self.truth.static_pos) - 1                    # the truth's static points: markers, then the saddle
        drop = [j for j in range(m) if j not in self.keep]
        gone = {int(np.argmin(np.linalg.norm(pts - self.truth.static_pos[j], axis=1))) for j in drop}
        rows = [i for i in range(len(pts)) if i not in gone]
        return dataclasses.replace(r, static=np.asarray(r.static)[rows])

    def _triangulate(self, a, r):
        k = self.keep
        cut = lambda d: None if d is None else {c: np.asarray(v)[:, k] for c, v in d.items()}  # noqa: E731
        return dataclasses.replace(r, points=r.points[:, k], residual_px=cut(r.residual_px), reason=r.reason[:, k],
                                   n_views=r.n_views[:, k], sync_residual_px=cut(r.sync_residual_px),
                                   covariance=None if r.covariance is None else r.covariance[:, k])

    def __enter__(self):
        for step, f in (("motion_frame", self._motion_frame), ("triangulate", self._triangulate)):
            original = self.saved[step] = pipeline.STEP_CALLS[step]
            pipeline.STEP_CALLS[step] = lambda a, pr, f=f, original=original: f(a, original(a, pr))
        return self

    def __exit__(self, *exc):
        pipeline.STEP_CALLS.update(self.saved)


def _cut_truth(truth, keep):
    """The truth with its markers cut to ``keep`` (the saddle and the comfort unchanged)."""
    static = np.asarray(truth.static_pos)
    cut = {k: np.asarray(getattr(truth, k))[:, keep] for k in ("marker_pos", "marker_vel", "marker_acc")}
    return dataclasses.replace(truth, **cut, static_pos=np.vstack([static[keep], static[-1:]]))


def run_cut(name: str) -> str:
    """The session cut to the horse's own three markers: A_y, Wb, Wk against the truth."""
    t0 = time.perf_counter()
    folder = cover_session(name)
    truth = load_truth(folder)
    keep = kept_three(name)
    try:
        with _Cut(keep, truth):
            a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{name + ' cut to 3':22s} markers {keep} exit 2 stopped: {str(exc)[:160]}"
    st = accuracy.stage_errors(a, _cut_truth(truth, keep))
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms"))
    v = quality.verdict(quality.post_checks(a))
    mc = a.rigid_body.body.model_choice
    return (f"{name + ' cut to 3':22s} markers {keep} {v:10s} A_y {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} % "
            f"Wb {ce['acc_y_Wb_rms']:+6.1f} % Wk {ce['acc_y_Wk_rms']:+6.1f} % model: {mc.source} "
            f"(p {mc.p_value:.2g}) {time.perf_counter() - t0:.0f}s")


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
            f"left out of the pose {left_out} {bad} model: {_model_text(a)} "
            f"{time.perf_counter() - t0:.0f}s" + "".join(f"\n    under the cover, {k}: {v}" for k, v in during.items()))


def _model_text(a) -> str:
    mc = getattr(a.rigid_body.body, "model_choice", None)
    return "-" if mc is None else f"{mc.source} (p {mc.p_value:.2g})"


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
    args = sys.argv[1:]
    cut = "--cut" in args
    for n in [x for x in args if x != "--cut"] or list(COVER_SESSIONS):
        print(run(n), flush=True)
        if cut and len(COVER_SESSIONS[n].horse().marker_body) > 3:
            print(run_cut(n), flush=True)
