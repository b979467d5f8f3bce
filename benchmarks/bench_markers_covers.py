"""More markers and partly covered markers: the default analysis against the truth.

Renders (into the cache, on demand, one at a time) the sessions of
:data:`horsemocap.virtuallab.covers.COVER_SESSIONS` named on the command line
(default: all) and runs the default analysis on each: the exit status the
command would give (3 when the verdict is unreliable, 2 when a step stops),
the verdict, the checks above ok, wrong identities, the saddle's vertical
acceleration error (% of its rms) and the Wb / Wk rms errors against the
truth, per camera the 2D values flagged as partly covered, and per marker
the frames left out of the pose for moving against the others' rigid motion.

Every line also gives the per-frame pose's saddle error before the pose
smoothing (``unsmoothed saddle y``: the registration's share of the error,
mm rms with the record's mean removed), so that a change of the registration
and a change of the smoothing can be told apart.

Usage: ``python benchmarks/bench_markers_covers.py [--cut] [--draws N] [--trace] [NAME ...]``
(``results/markers_covers.txt``: the run noted in benchmarks/README.md).
``--cut``: a session with more than three markers is also analysed cut to the
horse's own three (the same ride and the same noise: the extra markers' columns
dropped from the triangulated points and their points from the static shot
the rigid-body step reads),
and the marker model chosen is printed.
A name of the hard set (``hard.HARD_SESSIONS``) runs that session without marker noise (the ``noisy_<name>``
cover session's ride). ``--trace``: where each named session's error comes from: the analysis as measured, with
the static shot replaced by its true points, with the analysed frames' triangulated markers replaced by the true
ones, and both (as ``bench_marker_noise.py --trace`` does for the herd), with the static shot's error per point.
``--draws N``: for a session with more than three markers, N draws of
synthetic marker noise on the true markers (AR(1) over frames, each marker's
3D error shaped by its triangulation covariance; the scale and the lag-1
correlation measured from the render's own triangulation errors), analysed
with every marker and with each extra marker dropped (the same draw): the
expected effect of a marker, which one render's noise hides.
``--criteria``: with ``--draws N``, every marker only, the pose smoothing's
criteria under correlated noise compared on the same draws: ``gcv`` (the
correlated-error GCV), ``risk`` (the unbiased risk with the noise's covariance
known: its level and AR(1) correlation from the rigidity residual; four or
more markers) and ``reml`` (REML with the AR(1) correlation given); also
on the herd records with correlated marker noise (``marker-noise_horse2_canter``,
``marker-noise_horse2_sitting_trot``: ``bench_marker_noise.py``'s records).
Its output: ``results/markers_covers_criteria.txt`` (``--kept``: also each criterion with its
correlated choice kept where it smooths a component to the penalty's null space).
``--rule RULE``: the left-out choice picks its candidates by ``RULE`` (``pose.LEFT_OUT_RULES``: ``min`` the
default, ``one_se`` the most smoothing within one standard error of the minimum).
``--oracle``: per session, the saddle's vertical acceleration error (and Wb) with the left-out choice's
parameters multiplied by ``10^d``, all six by one ``d`` and each component alone (the left-out scores computed
once; ``--oracle --kept``: the stride-harmonics fallback to white noise switched off, so that the left-out
path is measured whatever the factor), ``results/markers_covers_oracle.txt``.
Each line names the pose smoothing's route: white noise, or the left-out choice without or with the stride's
harmonics (``pose.LEFT_OUT_HARMONICS``, the default: both routes scored, the lower kept; partial splines at
white-noise GCV with harmonics' parameters times ``10^s``) and both routes' left-out scores.
``--genlocked`` / ``--no-marker-noise``: each named session's ride with its cameras locked together / without
its marker noise (the rider's own sessions ``ride4_<gait>``: what the cameras' timing and the markers' noise each
cost; ``results/rides.txt``).
``--no-harmonic-left-out``: the left-out choice without the harmonic route; ``--harmonic-left-out --always``: the
harmonic route whatever its score (``results/markers_covers_harmonic_left_out.txt``).
The two routes are blended (``pose.LEFT_OUT_STACK = "pose"``, the default: the harmonic route's fit times ``w``
plus the plain route's times ``1 - w``, one ``w`` for the pose minimising the left-out score; the line's
``[stack score w [...]]``); ``--stack``: one ``w`` per pose component; ``--stack-weight W``: ``w`` fixed at
``W``; ``--stack-pose``: the default; ``--no-stack``: one route, the lower-scoring
(``results/markers_covers_stack.txt``).
"""
import dataclasses
import sys
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from horsemocap import accuracy, pipeline, pose, quality
from horsemocap.passes import pass_segment
from horsemocap.pipeline import AnalysisError, analyze, run_steps
from horsemocap.virtuallab import load_truth
from horsemocap.virtuallab.covers import COVER_SESSIONS, cover_session
from horsemocap.virtuallab.hard import HARD_SESSIONS, hard_session
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
        segment = r.segment
        if len(k) <= 3 and segment is not None:
            # three markers: every one must be triangulated in every analysed frame (the triangulate step's own
            # rule for a three-marker session), so the record is the longest such run inside the segment
            segment = pass_segment(r.points[:, k], segment) or segment
        return dataclasses.replace(r, points=r.points[:, k], residual_px=cut(r.residual_px), reason=r.reason[:, k],
                                   n_views=r.n_views[:, k], sync_residual_px=cut(r.sync_residual_px),
                                   covariance=None if r.covariance is None else r.covariance[:, k], segment=segment)

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


def unsmoothed_saddle_error_mm(a, truth) -> np.ndarray:
    """The per-frame pose's saddle (the registration, before the pose smoothing) against the truth: rms (mm) per
    axis of the true motion frame, each axis' mean over the record removed (a constant offset adds no
    acceleration)."""
    body = a.rigid_body.body
    reg = body.pose_registration
    seg = a.triangulate.segment
    frames = a.synchronisation.offsets[a.session.reference_camera] + np.arange(*seg)
    rows, known = accuracy._truth_rows(truth, frames)
    per_frame = np.einsum("kij,j->ki", reg.rotation, body.static_saddle) + reg.translation     # motion frame
    est = (per_frame @ a.motion_frame.axes) @ truth.motion_axes.T                             # true motion frame
    err = est[known] - np.asarray(truth.saddle_pos)[rows[known]] @ truth.motion_axes.T
    err = err - np.nanmean(err, axis=0)
    return 1000 * np.sqrt(np.nanmean(err ** 2, axis=0))


def run_cut(name: str, whole=None) -> str:
    """The session cut to the horse's own three markers: A_y, Wb, Wk against the truth; with ``whole`` (the
    analysis of every marker), its A_y on the frames the cut analysed too."""
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
    y_mm = unsmoothed_saddle_error_mm(a, _cut_truth(truth, keep))[1]
    (a0, b0), (a1, b1) = a.detect.segment, a.triangulate.segment
    same = ""
    if whole is not None:
        frames = a.synchronisation.offsets[a.session.reference_camera] + np.arange(a1, b1)
        same = (f"; every marker on these frames A_y {accuracy.saddle_acc_y_error_pct(whole, truth, frames):.1f} % "
                f"(cut {accuracy.saddle_acc_y_error_pct(a, _cut_truth(truth, keep)):.1f} %)")
    flagged = [f"{c.name}:{c.level}" for c in quality.post_checks(a) if c.level in ("warning", "unreliable")]
    return (f"{name + ' cut to 3':22s} markers {keep} {v:10s} A_y {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} % "
            f"Wb {ce['acc_y_Wb_rms']:+6.1f} % Wk {ce['acc_y_Wk_rms']:+6.1f} % unsmoothed saddle y {y_mm:.2f} mm "
            f"frames {a1}..{b1 - 1} (all markers' {a0}..{b0 - 1}) {flagged} model: {mc.source} "
            f"(p {mc.p_value:.2g}) {time.perf_counter() - t0:.0f}s{same}")


def run(name: str) -> str:
    return run_analysis(name)[0]


def run_analysis(name: str) -> tuple:
    """:func:`run`'s line and the analysis (None when it stopped)."""
    t0 = time.perf_counter()
    folder = _session_folder(name)
    try:
        a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{name:22s} exit 2 stopped: {str(exc)[:200]}", None
    except Exception as exc:                                   # noqa: BLE001 - a benchmark reports every failure
        return f"{name:22s} CRASH {exc!r}"[:300], None
    return _run_line(name, folder, a, t0), a


def _run_line(name: str, folder, a, t0: float) -> str:
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
            f"Wb {ce['acc_y_Wb_rms']:+6.1f} % Wk {ce['acc_y_Wk_rms']:+6.1f} % "
            f"unsmoothed saddle y {unsmoothed_saddle_error_mm(a, truth)[1]:.2f} mm partly_covered {covered} "
            f"left out of the pose {left_out} {bad} model: {_model_text(a)} {_route_text(a)}"
            f"{time.perf_counter() - t0:.0f}s" + "".join(f"\n    under the cover, {k}: {v}" for k, v in during.items()))


def _static_truth(truth, error: dict):
    """``static`` step result -> the same with each static point replaced by its true point (paired by least total
    distance); the measured points' error (mm, world) kept in ``error["mm"]`` (the true points' order)."""
    true = np.asarray(truth.static_pos, float)

    def replace_result(a, r):
        measured = np.asarray(r.static_points, float)
        rows, cols = linear_sum_assignment(np.linalg.norm(measured[:, None] - true[None], axis=-1))
        out = measured.copy()
        out[rows] = true[cols]
        error["mm"] = np.full_like(true, np.nan)
        error["mm"][cols] = 1000 * (measured[rows] - true[cols])
        return dataclasses.replace(r, static_points=out)
    return replace_result


def _triangulated_truth(truth):
    """``triangulate`` step result -> the same with the analysed frames' markers replaced by the true ones
    (the benchmark beside this one's, ``bench_marker_noise._true_markers``)."""
    from bench_marker_noise import _true_markers

    replace_true = _true_markers(truth)

    def keep_gaps(a, r):
        """The true markers where the measured ones are (a marker the run could not place stays missing)."""
        out = replace_true(a, r)
        return dataclasses.replace(out, points=np.where(np.isfinite(r.points), out.points, np.nan))
    return keep_gaps


class _Patched:
    """``pipeline.STEP_CALLS[step]``'s result passed through ``replace_result`` for each (step, replace_result)."""

    def __init__(self, *patches):
        self.patches, self.saved = patches, {}

    def __enter__(self):
        for step, replace_result in self.patches:
            original = self.saved[step] = pipeline.STEP_CALLS[step]
            pipeline.STEP_CALLS[step] = lambda a, pr, f=replace_result, original=original: f(a, original(a, pr))
        return self

    def __exit__(self, *exc):
        pipeline.STEP_CALLS.update(self.saved)


def run_trace(name: str) -> str:
    """Where a session's error comes from: the analysis as measured, with the static shot replaced by its true
    points, with the analysed frames' triangulated markers replaced by the true ones, and both; per variant A_y,
    Wb, Wk, the unsmoothed saddle error (mm rms, x y z of the motion frame), the verdict and the checks above ok;
    then the measured static shot's error per point (mm, world x y z; markers rear to front, then the saddle)."""
    folder = _session_folder(name)
    truth = load_truth(folder)
    static_error = {}
    variants = {"measured": (), "true static shot": (("static", _static_truth(truth, static_error)),),
                "true markers in the analysed frames": (("triangulate", _triangulated_truth(truth)),),
                "both true": (("static", _static_truth(truth, {})), ("triangulate", _triangulated_truth(truth)))}
    lines = [f"{name}"]
    for label, patches in variants.items():
        t0 = time.perf_counter()
        try:
            with _Patched(*patches):
                a = analyze(folder, None, {}, progress=lambda *x: None)
        except AnalysisError as exc:
            lines.append(f"  {label:36s} exit 2 stopped: {str(exc)[:160]}")
            continue
        checks = quality.post_checks(a)
        v = quality.verdict(checks)
        st = accuracy.stage_errors(a, truth)
        ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms"))
        bad = [f"{c.name}:{c.level}" for c in checks if c.level in ("warning", "unreliable")]
        lines.append(f"  {label:36s} A_y {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} % Wb {ce['acc_y_Wb_rms']:+6.1f} % "
                     f"Wk {ce['acc_y_Wk_rms']:+6.1f} % unsmoothed saddle "
                     f"{np.round(unsmoothed_saddle_error_mm(a, truth), 2).tolist()} mm exit "
                     f"{3 if v == 'unreliable' else 0} {v} {bad} {_route_text(a)}{time.perf_counter() - t0:.0f}s")
        print(lines[-1], flush=True)
    if "mm" in static_error:
        lines.append(f"  static shot error (mm, world x y z per point): {np.round(static_error['mm'], 1).tolist()}")
    return "\n".join(lines)


def _true_markers(a, truth) -> np.ndarray:
    """The true markers (world) in the rows of the triangulated points (NaN where the truth has no frame)."""
    pts = a.triangulate.points
    frames = a.synchronisation.offsets[a.session.reference_camera] + np.arange(len(pts))
    rows, known = accuracy._truth_rows(truth, frames)
    out = np.full(pts.shape, np.nan)
    out[known] = np.asarray(truth.marker_pos)[rows[known]]
    return out


def measured_noise(a, truth) -> tuple:
    """``(scale, rho)`` of the render's triangulation errors over the analysed frames (each marker's mean, the
    bias, removed): the rms Mahalanobis length per axis under the triangulation covariance, and the mean lag-1
    autocorrelation over markers and axes."""
    lo, hi = a.triangulate.segment
    err = (a.triangulate.points - _true_markers(a, truth))[lo:hi]
    cov = a.triangulate.covariance[lo:hi]
    d2, rhos = [], []
    for j in range(err.shape[1]):
        ok = np.all(np.isfinite(err[:, j]), axis=1) & np.all(np.isfinite(cov[:, j]), axis=(1, 2))
        e = err[ok, j] - err[ok, j].mean(axis=0)
        d2.append(np.einsum("ki,kij,kj->k", e, np.linalg.inv(cov[ok, j]), e))
        rhos += [np.corrcoef(e[1:, i], e[:-1, i])[0, 1] for i in range(3)]
    return float(np.sqrt(np.mean(np.concatenate(d2)) / 3)), float(np.clip(np.mean(rhos), 0.0, 0.99))


def _synthetic_points(a, truth, scale: float, rho: float, seed: int) -> np.ndarray:
    """The true markers plus AR(1) noise (lag-1 ``rho``) shaped by the triangulation covariance times
    ``scale**2``; NaN where the render's triangulation or the truth has none."""
    pts, cov = a.triangulate.points, a.triangulate.covariance
    seen = np.all(np.isfinite(pts), axis=2)
    chol = np.linalg.cholesky(np.where(seen[..., None, None], cov, np.eye(3)))
    rng = np.random.default_rng(seed)
    z = np.empty(pts.shape)
    z[0] = rng.standard_normal(pts.shape[1:])
    for k in range(1, len(z)):
        z[k] = rho * z[k - 1] + np.sqrt(1 - rho ** 2) * rng.standard_normal(pts.shape[1:])
    noisy = _true_markers(a, truth) + scale * np.einsum("kmij,kmj->kmi", chol, z)
    noisy = np.where(np.isfinite(noisy), noisy, pts)       # no truth there (the record's first frames): as rendered
    return np.where(seen[..., None], noisy, np.nan)


def _analyse_points(a, truth, points, keep) -> tuple:
    """A_y (%), Wb (%) and the unsmoothed saddle y error (mm) of ``a`` with its triangulated points replaced by
    ``points`` cut to ``keep``, from the smoothing on."""
    cut = _Cut(keep, truth)
    tri = cut._triangulate(a, dataclasses.replace(a.triangulate, points=points))
    given = {n: getattr(a, n) for n in pipeline.STEPS}
    given["triangulate"] = tri
    with cut:
        an = run_steps(a.session, a.params, given, ["smooth", "motion_frame", "rigid_body", "comfort"])
    ct = _cut_truth(truth, keep)
    ce = accuracy.comfort_errors(an.comfort.indicators, truth.comfort, ("acc_y_Wb_rms",))
    return (accuracy.stage_errors(an, ct)["saddle_acc_y_rmse_pct_of_rms"], ce["acc_y_Wb_rms"],
            unsmoothed_saddle_error_mm(an, ct)[1])


def run_draws(name: str, draws: int) -> str:
    """Every marker against each extra marker dropped, over ``draws`` draws of synthetic noise (same draw for
    every configuration): per draw A_y and the unsmoothed saddle y error, then the means and the paired
    difference."""
    folder = cover_session(name)
    truth = load_truth(folder)
    a = analyze(folder, None, {}, until="motion_frame", progress=lambda *x: None)
    m = a.triangulate.points.shape[1]
    own = kept_three(name)
    configs = {"all": list(range(m))}
    configs.update({f"no {j}": [i for i in range(m) if i != j] for j in range(m) if j not in own})
    scale, rho = measured_noise(a, truth)
    lines = [f"{name}: {draws} draws of synthetic noise, the triangulation covariance x {scale:.2f}^2, AR(1) "
             f"{rho:.2f} (measured on the render); configurations {configs}"]
    res = {c: [] for c in configs}
    for d in range(draws):
        points = _synthetic_points(a, truth, scale, rho, seed=d)
        text = f"  draw {d}:"
        for c, keep in configs.items():
            res[c].append(_analyse_points(a, truth, points, keep))
            ay, wb, y_mm = res[c][-1]
            text += f"  [{c}] A_y {ay:5.1f} % Wb {wb:+5.1f} % unsmoothed y {y_mm:.2f} mm"
        lines.append(text)
    base = np.array(res["all"])
    for c, v in res.items():
        v = np.array(v)
        text = (f"  [{c}] mean A_y {v[:, 0].mean():.1f} % rms Wb {np.sqrt(np.mean(v[:, 1] ** 2)):.1f} % mean "
                f"unsmoothed y {v[:, 2].mean():.2f} mm")
        if c != "all":
            diff = base[:, 0] - v[:, 0]
            text += (f"; all minus this: A_y {diff.mean():+.1f} (sd {diff.std(ddof=1) if draws > 1 else np.nan:.1f})"
                     f" points, unsmoothed y lower with all in {int(np.sum(base[:, 2] < v[:, 2]))}/{draws} draws")
        lines.append(text)
    return "\n".join(lines)


#: The herd records with correlated marker noise of ``--criteria`` (bench_marker_noise.py's recorded noise).
HERD_NOISE_SESSIONS = {"marker-noise_horse2_canter": ("Horse 2", "canter"),
                       "marker-noise_horse2_sitting_trot": ("Horse 2", "sitting_trot")}
CRITERIA = ("gcv", "risk", "reml")
#: ``--criteria --kept``: also the criteria with the correlated choice kept when it smooths a component to the
#: penalty's null space (``pose.fit_pose_trajectory`` otherwise takes the noise as white then).
KEPT_CRITERIA = ("risk kept", "reml kept")


def _session_folder(name: str):
    """A cover session, a herd record with correlated marker noise (``HERD_NOISE_SESSIONS``) or a hard session
    (``hard.HARD_SESSIONS``, without marker noise: the ``noisy_<name>`` cover sessions' rides)."""
    if name in HERD_NOISE_SESSIONS:
        from bench_marker_noise import noisy_session           # the benchmark beside this one
        from horsemocap.virtuallab.noise import MarkerNoise
        return noisy_session(*HERD_NOISE_SESSIONS[name], MarkerNoise(0.1, 0.8, 0.05))
    if name in HARD_SESSIONS and name not in COVER_SESSIONS:
        return hard_session(name)
    return cover_session(name)


class _Criterion:
    """The pose smoothing's criterion under correlated noise (the parameter
    ``rigid_body.pose.correlated_noise_criterion``) set to ``criterion`` for the rigid-body steps run while
    inside (``pipeline.STEP_CALLS["rigid_body"]`` with the analysis' parameters updated)."""

    def __init__(self, criterion: str):
        self.criterion = criterion

    def __enter__(self):
        self.saved = pipeline.STEP_CALLS["rigid_body"], pose.NULL_SPACE_EDF
        original, setting = self.saved[0], {"rigid_body.pose.correlated_noise_criterion": self.criterion.split()[0]}

        def with_criterion(a, pr, **kw):
            a.params = a.params.updated(setting)
            return original(a, pr, **kw)
        pipeline.STEP_CALLS["rigid_body"] = with_criterion
        if self.criterion.endswith("kept"):
            pose.NULL_SPACE_EDF = -1.0         # a component smoothed to the null space no longer means white noise
        return self

    def __exit__(self, *exc):
        pipeline.STEP_CALLS["rigid_body"], pose.NULL_SPACE_EDF = self.saved


def run_criteria(name: str, draws: int, criteria=CRITERIA) -> str:
    """Every marker, :data:`CRITERIA` on the same ``draws`` draws of synthetic noise: per draw A_y, Wb, Wk and
    whether the correlated-noise smoothing ran, then the mean A_y and rms Wb, Wk of each criterion."""
    folder = _session_folder(name)
    truth = load_truth(folder)
    a = analyze(folder, None, {}, until="motion_frame", progress=lambda *x: None)
    keep = list(range(a.triangulate.points.shape[1]))
    scale, rho = measured_noise(a, truth)
    lines = [f"{name}: {draws} draws, {len(keep)} markers, the triangulation covariance x {scale:.2f}^2, AR(1) "
             f"{rho:.2f} (measured on the render)"]
    res = {c: [] for c in criteria}
    for d in range(draws):
        points = _synthetic_points(a, truth, scale, rho, seed=d)
        text = f"  draw {d}:"
        for c in criteria:
            with _Criterion(c):
                an = _analysis_of_points(a, points, keep)
            ce = accuracy.comfort_errors(an.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms"))
            ay = accuracy.stage_errors(an, truth)["saddle_acc_y_rmse_pct_of_rms"]
            choice = an.rigid_body.body.pose.smoothing_choice or {}
            ran = ("white (fallback)" if "whole motion" in choice.get("reason", "") else
                   "white (stride fallback)" if "left the stride's harmonics" in choice.get("reason", "") else
                   "white" if "noise_correlation" not in choice else
                   f"left out s={choice['cross_validation']['cross_validation_decades']:g}"
                   if "cross_validation" in choice else "correlated")
            res[c].append((ay, ce["acc_y_Wb_rms"], ce["acc_y_Wk_rms"], not ran.startswith("white")))
            text += f"  [{c}] A_y {ay:5.1f} % Wb {ce['acc_y_Wb_rms']:+5.1f} % Wk {ce['acc_y_Wk_rms']:+5.1f} % {ran}"
        print(text, flush=True)
    for c, v in res.items():
        v = np.array(v, float)
        lines.append(f"  [{c}] mean A_y {v[:, 0].mean():.1f} % (sd {v[:, 0].std(ddof=1) if draws > 1 else np.nan:.1f})"
                     f" rms Wb {np.sqrt(np.mean(v[:, 1] ** 2)):.1f} % rms Wk {np.sqrt(np.mean(v[:, 2] ** 2)):.1f} %"
                     f"; correlated smoothing in {int(v[:, 3].sum())}/{draws} draws")
    base = np.array(res[criteria[0]], float)
    for c in criteria[1:]:
        diff = np.array(res[c], float)[:, 0] - base[:, 0]
        lines.append(f"  [{c}] minus [{criteria[0]}]: A_y {diff.mean():+.1f} (se {diff.std(ddof=1) / np.sqrt(draws):.1f}) "
                     f"points, lower in {int(np.sum(diff < 0))}/{draws} draws")
    return "\n".join(lines)


def _analysis_of_points(a, points, keep):
    """``a`` with its triangulated points replaced by ``points`` cut to ``keep``, analysed from the smoothing on."""
    cut = _Cut(keep, None)
    # three markers: _Cut keeps the longest run inside the segment in which the three are triangulated
    tri = cut._triangulate(a, dataclasses.replace(a.triangulate, points=points))
    given = {n: getattr(a, n) for n in pipeline.STEPS}
    given["triangulate"] = tri
    return run_steps(a.session, a.params, given, ["smooth", "motion_frame", "rigid_body", "comfort"])


#: ``--oracle``: the exponents ``d`` of the factors ``10^d`` on the left-out choice's parameters.
ORACLE_COMMON = (-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0)
ORACLE_COMPONENT = (-1.0, -0.5, 0.0, 0.5, 1.0, 1.5)


class _Scaled:
    """The left-out choice (``pose._left_out_choice``, what ``pose.marker_cross_validation_per_component``
    returns) with its result multiplied by ``10^shift`` (6,) while inside; the cross-validation itself runs
    once per set of points and route (its result kept)."""

    def __init__(self):
        self.shift, self.kept = np.zeros(6), {}

    def __enter__(self):
        self.saved = pose._left_out_choice
        original = self.saved

        def scaled(t, registration, points, model, base_lam, *args):
            key = (np.nan_to_num(np.asarray(points, float)).tobytes(), args[-1])
            if key not in self.kept:
                self.kept[key] = original(t, registration, points, model, base_lam, *args)
            lam, *rest = self.kept[key]
            return (lam * 10.0 ** self.shift, *rest)
        pose._left_out_choice = scaled
        return self

    def __exit__(self, *exc):
        pose._left_out_choice = self.saved


def run_oracle(name: str, keep_left_out: bool = False) -> str:
    """A_y (and Wb) against factors on the left-out choice's parameters: one common and per component."""
    folder = cover_session(name)
    truth = load_truth(folder)
    a = analyze(folder, None, {}, until="motion_frame", progress=lambda *x: None)
    saved = pose.STRIDE_RESIDUAL_LEVEL
    if keep_left_out:
        pose.STRIDE_RESIDUAL_LEVEL = 0.0           # no p value is below: the left-out path is never refused

    def measure(scaled, shift) -> str:
        scaled.shift = np.asarray(shift, float)
        an = run_steps(a.session, a.params, {n: getattr(a, n) for n in pipeline.STEPS}, ["rigid_body", "comfort"])
        ce = accuracy.comfort_errors(an.comfort.indicators, truth.comfort, ("acc_y_Wb_rms",))
        white = "cross_validation" not in (an.rigid_body.body.pose.smoothing_choice or {})
        return (f"{accuracy.stage_errors(an, truth)['saddle_acc_y_rmse_pct_of_rms']:.1f}/{ce['acc_y_Wb_rms']:+.1f}"
                + ("W" if white else ""))
    try:
        with _Scaled() as scaled:
            base = measure(scaled, np.zeros(6))
            if not scaled.kept:
                return f"{name:22s} no left-out choice (A_y/Wb {base} %)"
            info = next(iter(scaled.kept.values()))[1]
            lines = [f"{name:22s} A_y/Wb (%, W: white noise, the left-out path refused) at the left-out choice "
                     f"{base}, s = {info['cross_validation_component_decades']}"]
            lines.append("  all six " + " ".join(f"{d:+g}:{measure(scaled, np.full(6, d))}" for d in ORACLE_COMMON))
            for c, comp in enumerate(pose.POSE_COMPONENTS):
                row = [f"{d:+g}:{measure(scaled, np.eye(6)[c] * d)}" for d in ORACLE_COMPONENT]
                lines.append(f"  {comp:7s} " + " ".join(row))
    finally:
        pose.STRIDE_RESIDUAL_LEVEL = saved
    return "\n".join(lines)


def _variant(name: str, genlocked: bool, quiet: bool) -> str:
    """A cover session's ride with its cameras locked together (``genlocked``) and/or without its marker noise
    (``quiet``), registered in ``COVER_SESSIONS`` under a new name (rendered into the cache like the others)."""
    if name not in COVER_SESSIONS:
        raise SystemExit(f"--genlocked / --no-marker-noise: {name!r} is not a cover session (covers.COVER_SESSIONS)")
    sc = COVER_SESSIONS[name]
    tag = "_genlocked" * genlocked + "_no_marker_noise" * quiet
    COVER_SESSIONS[name + tag] = dataclasses.replace(
        sc, name=name + tag, free_running=None if genlocked else sc.free_running,
        marker_noise=None if quiet else sc.marker_noise)
    return name + tag


def _route_text(a) -> str:
    """The pose smoothing's route: the left-out choice with or without the stride's harmonics, its left-out score
    (m/s^2 rms) and ``s``, or white noise (the stride fallback or no correlated noise)."""
    choice = a.rigid_body.body.pose.smoothing_choice or {}
    cv = choice.get("cross_validation")
    if cv is None:
        if choice.get("correlated_harmonics"):
            return f"route: correlated with harmonics (AR(1) {choice['noise_correlation']:.2f})"
        if "noise_correlation" in choice:
            return f"route: correlated (AR(1) {choice['noise_correlation']:.2f})"
        return "route: white" + (" (stride fallback)" if "left the stride's harmonics" in choice.get("reason", "")
                                 else " (null-space fallback)" if "whole motion for noise" in choice.get("reason", "")
                                 else "")
    harmonic = ("stack" if cv.get("stack_fundamental_hz") else "harmonics" if cv.get("fundamental_hz")
                else "plain")
    routes = "".join(f" [{k} {v[0]:.5g} {'w' if k == 'stack' else 's'} {v[1]}]"
                     for k, v in cv.get("routes", {}).items())
    return (f"route: left-out {harmonic} score {cv['cross_validation_score']:.5g} "
            f"s {cv['cross_validation_component_decades']}{routes} ")


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
    draws = int(args[args.index("--draws") + 1]) if "--draws" in args else 0
    valued = ("--draws", "--compare", "--rule", "--stack-weight")
    names = [x for i, x in enumerate(args) if not x.startswith("--") and (i == 0 or args[i - 1] not in valued)]
    if "--harmonic-left-out" in args:
        pose.LEFT_OUT_HARMONICS = "always" if "--always" in args else True
    if "--no-harmonic-left-out" in args:
        pose.LEFT_OUT_HARMONICS = False
    if "--rule" in args:
        pose.LEFT_OUT_RULE = args[args.index("--rule") + 1]
    if "--stack" in args:
        pose.LEFT_OUT_STACK = True
    if "--stack-pose" in args:
        pose.LEFT_OUT_STACK = "pose"
    if "--stack-weight" in args:
        pose.LEFT_OUT_STACK = float(args[args.index("--stack-weight") + 1])
    if "--no-stack" in args:
        pose.LEFT_OUT_STACK = False
    if "--genlocked" in args or "--no-marker-noise" in args:
        names = [_variant(n, genlocked="--genlocked" in args, quiet="--no-marker-noise" in args)
                 for n in names or list(COVER_SESSIONS)]
    if "--trace" in args:
        for n in names:
            print(run_trace(n), flush=True)
        sys.exit(0)
    if "--oracle" in args:
        for n in names:
            print(run_oracle(n, keep_left_out="--kept" in args), flush=True)
        sys.exit(0)
    if "--criteria" in args:
        chosen = CRITERIA + (KEPT_CRITERIA if "--kept" in args else ())
        if "--compare" in args:
            chosen = tuple(args[args.index("--compare") + 1].split(","))
        for n in names:
            print(run_criteria(n, max(draws, 1), chosen), flush=True)
        sys.exit(0)
    for n in names or list(COVER_SESSIONS):
        if draws:
            if n in COVER_SESSIONS and len(COVER_SESSIONS[n].horse().marker_body) > 3:
                print(run_draws(n, draws), flush=True)
            continue
        line, whole = run_analysis(n)
        print(line, flush=True)
        if cut and n in COVER_SESSIONS and len(COVER_SESSIONS[n].horse().marker_body) > 3:
            print(run_cut(n, whole), flush=True)
