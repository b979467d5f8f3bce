"""Real-data benchmark of the pose-trajectory kinematics: public C3D files, rigid four-marker clusters.

The four-marker protocol: three markers of a rigid cluster are the visible
triangle, the fourth is held out as the hidden point (its position in a
static frame taken from the file: the first frame with all four markers).

- reference: the measured fourth marker's own Savitzky-Golay derivatives
  (order 4, window 0.25 s); its angular velocity from all four markers'
  Savitzky-Golay positions and velocities (the same filter; least squares
  ``v_i - v_c = omega x (p_i - p_c)``);
- ours: ``horsemocap.io3d.kinematics_from_trajectories`` with its defaults
  (three markers + the static frame), and with ``smoothing="gcv"`` (the plain
  criterion) for comparison;
- naive peer 1: per-frame Kabsch of the three onto the static frame, then
  Savitzky-Golay (order 3, window 0.15 s) of the predicted point; omega from
  the Savitzky-Golay-smoothed and differentiated rotation matrices;
- naive peer 2: the same predicted point and rotation matrices, low-passed by
  a 4th-order zero-lag Butterworth (2nd order forward and backward) at a
  Winter residual-analysis cutoff, derivatives by central differences.

No filter is shared between the reference and any method. Errors: rms over
the frames inside the record (0.25 s from each end) where both are defined,
in % of the reference's rms.

Run: ``python benchmarks/bench_real_c3d.py`` (writes benchmarks/results/real_c3d.txt).
``--criteria``: instead, three principled smoothing choices under correlated noise, none the default
(the discrepancy principle with the rigidity residual's noise level, restricted maximum likelihood
with AR(1) errors, its correlation profiled or given by the rigidity residual), appended to
real_c3d.txt as its last section (a few minutes: the likelihood is dense).
"""
from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.signal import butter, filtfilt, savgol_filter
from scipy.spatial.transform import Rotation

from horsemocap import io3d, pose, splines

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data_samples" / "real_c3d"

#: (case, file, the three visible markers, the hidden fourth, first frame, frames)
CASES = [
    ("OptiTrack: wheel (turning)", "kinematics_basket_sprint.c3d",
     ["SWL:Marker1", "SWL:Marker2", "SWL:Marker3"], "SWL:Marker4", 1400, 600),
    ("OptiTrack: wheelchair frame", "kinematics_basket_sprint.c3d",
     ["WheelchairL:Marker1", "WheelchairL:Marker2", "WheelchairL:Marker3"], "WheelchairL:Marker4", 600, 600),
    ("OptiTrack: arm cluster", "kinematics_basket_sprint.c3d",
     ["ArmL:Marker1", "ArmL:Marker2", "ArmL:Marker3"], "ArmL:Marker4", 600, 600),
    ("OptiTrack: head (tennis)", "kinematics_tennis_serve.c3d",
     ["Derrick:LFHD", "Derrick:RFHD", "Derrick:LBHD"], "Derrick:RBHD", 0, 600),
    ("Vicon: box", "markers_analogs.c3d",
     ["boite:gauche_ext", "boite:gauche_int", "boite:droite_int"], "boite:droite_ext", 0, 580),
    ("Vicon: pelvis (skin)", "markers_analogs.c3d",
     ["Daphnee:ASISr", "Daphnee:ASISl", "Daphnee:PSISr"], "Daphnee:PSISl", 0, 580),
    ("Vicon: arm (skin)", "markers_analogs.c3d",
     ["Daphnee:ARMl", "Daphnee:ARMm", "Daphnee:ARMp_up"], "Daphnee:ARMp_do", 0, 580),
]
REFERENCE_S, REFERENCE_ORDER = 0.25, 4
PEER_SG_S, PEER_SG_ORDER = 0.15, 3
EDGE_S = 0.25


def _odd(n):
    n = max(int(round(n)), 5)
    return n if n % 2 else n + 1


def _sg(x, rate, seconds, order, deriv=0):
    return savgol_filter(x, _odd(seconds * rate), order, deriv=deriv, delta=1 / rate, axis=0)


def _kabsch(points, model):
    """Per-frame rotations (n, 3, 3) and translations of the model onto the points (NaN where missing)."""
    n = len(points)
    R = np.full((n, 3, 3), np.nan)
    tr = np.full((n, 3), np.nan)
    mc = model.mean(0)
    for k in range(n):
        p = points[k]
        if not np.isfinite(p).all():
            continue
        pc = p.mean(0)
        rot, _ = Rotation.align_vectors(p - pc, model - mc)
        R[k] = rot.as_matrix()
        tr[k] = pc - R[k] @ mc
    return R, tr


def _omega_from_rotations(R, dR):
    W = dR @ np.swapaxes(R, 1, 2)
    W = (W - np.swapaxes(W, 1, 2)) / 2
    return np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1)


def winter_cutoff(x, rate):
    """Winter's residual analysis: the cutoff (Hz) where the rms residual between the signal and its
    4th-order zero-lag Butterworth low-pass meets the straight line fitted to the residual at high
    cutoffs (the noise's), extrapolated to 0 Hz; the largest over the columns of ``x``."""
    cut = np.arange(1.0, 0.4 * rate, 0.5)
    res = []
    for fc in cut:
        b, a = butter(2, fc / (rate / 2))
        res.append(np.sqrt(np.mean((x - filtfilt(b, a, x, axis=0)) ** 2, axis=0)))
    res = np.array(res)
    tail = cut >= 0.2 * rate
    best = []
    for j in range(res.shape[1]):
        slope, intercept = np.polyfit(cut[tail], res[tail, j], 1)
        below = np.flatnonzero(res[:, j] <= intercept)
        best.append(cut[below[0]] if below.size else cut[-1])
    return float(max(best))


def _butter(x, rate, fc):
    b, a = butter(2, fc / (rate / 2))
    return filtfilt(b, a, x, axis=0)


def _rel(est, ref, inner):
    ok = inner & np.isfinite(est).all(1) & np.isfinite(ref).all(1)
    return 100 * np.sqrt(np.mean(np.sum((est[ok] - ref[ok]) ** 2, 1)) / np.mean(np.sum(ref[ok] ** 2, 1)))


def _raw_error(position, raw_acc, inner, rate):
    """rms (m/s^2) of the second differences of ``position`` against the hidden marker's own (``raw_acc``)."""
    est = np.diff(position, 2, axis=0) * rate ** 2
    ok = inner[1:-1] & np.isfinite(est).all(1) & np.isfinite(raw_acc).all(1)
    return float(np.sqrt(np.mean(np.sum((est[ok] - raw_acc[ok]) ** 2, 1))))


def _continuous(x):
    """The longest run of frames with every marker finite (the Savitzky-Golay filters need no gaps)."""
    ok = np.isfinite(x).all(axis=(1, 2))
    best, start, run = (0, 0), None, 0
    for k, v in enumerate(np.r_[ok, False]):
        if v and start is None:
            start = k
        if not v and start is not None:
            if k - start > best[1] - best[0]:
                best = (start, k)
            start = None
    return slice(*best)


def run_case(name, file, visible, hidden, first, count):
    traj = io3d.read_c3d(DATA / file)
    four = visible + [hidden]
    pts_all = traj.subset(four)[first:first + count]
    span = _continuous(pts_all)
    pts = pts_all[span]
    t = traj.time_s[first:first + count][span]
    rate = 1 / float(np.median(np.diff(t)))
    model4 = pts[0]                                                 # the static frame: the first with all four
    seg = replace(traj, time_s=t, frame=traj.frame[first:first + count][span], names=tuple(visible),
                  points=pts[:, :3])
    static = replace(traj, time_s=t[:1], frame=traj.frame[:1], names=tuple(four), points=model4[None])
    inner = (t >= t[0] + EDGE_S) & (t <= t[-1] - EDGE_S)

    # reference: the measured fourth marker, Savitzky-Golay
    ref_acc = _sg(pts[:, 3], rate, REFERENCE_S, REFERENCE_ORDER, 2)
    P = _sg(pts, rate, REFERENCE_S, REFERENCE_ORDER)
    V = _sg(pts, rate, REFERENCE_S, REFERENCE_ORDER, 1)
    r = P - P.mean(1, keepdims=True)
    dv = V - V.mean(1, keepdims=True)
    ref_omega = np.stack([np.linalg.lstsq(np.concatenate([-_skew(ri) for ri in r[k]]), dv[k].ravel(), rcond=None)[0]
                          for k in range(len(t))])

    # the second reference: the hidden marker's own second differences, no filter (its noise is common to all)
    raw_acc = np.diff(pts[:, 3], 2, axis=0) * rate ** 2
    out = {"case": name, "file": file, "frames": len(t), "rate_hz": rate, "raw": {}}
    for label, smoothing in (("ours", "auto"), ("ours_gcv", "gcv")):
        t0 = time.time()
        res = io3d.kinematics_from_trajectories(seg, static, smoothing=smoothing)
        tr = res["trajectory"]
        out[label] = (_rel(res["hidden_kinematics"].acceleration[:, 0], ref_acc, inner),
                      _rel(tr.omega(t), ref_omega, inner))
        out["raw"][label] = _raw_error(tr.point(t, model4[3]).position, raw_acc, inner, rate)
        if label == "ours":
            ch = tr.smoothing_choice or {}
            out["chosen"] = ch.get("reason", smoothing)
            out["moving_reference"] = tr.moving_reference is not None
        out[label + "_s"] = time.time() - t0

    # the white-noise choice (what "auto" ran before the noise's correlation was measured)
    reg = pose.register_pose(pts[:, :3], model4[:3])
    white = pose.fit_pose_trajectory(t, reg, model4[:3])
    out["ours_white"] = (_rel(white.point(t, model4[3]).acceleration, ref_acc, inner), _rel(white.omega(t), ref_omega, inner))
    out["white_chosen"] = (white.smoothing_choice or {}).get("method", "")

    # leave-one-marker-out over the three visible markers (the hidden one is not used): the plain GCV
    # parameters scaled by the factor that predicts each left-out marker's second differences best
    gcv = pose.fit_pose_trajectory(t, reg, model4[:3], pose.PoseParams(smoothing="gcv", harmonics="none"))
    base = np.array([s.info["lam"] for s in gcv.centre_splines + gcv.rotvec_splines])
    lam, info = pose.marker_cross_validation(t, reg, pts[:, :3], model4[:3], base)
    loo = pose.fit_pose_trajectory(t, reg, model4[:3], pose.PoseParams(smoothing="gcv", harmonics="none"), lam=lam)
    out["ours_loo"] = (_rel(loo.point(t, model4[3]).acceleration, ref_acc, inner), _rel(loo.omega(t), ref_omega, inner))
    out["loo_decades"] = info["cross_validation_decades"]
    out["raw"]["ours_loo"] = _raw_error(loo.point(t, model4[3]).position, raw_acc, inner, rate)

    R, trans = _kabsch(pts[:, :3], model4[:3])
    pred = trans + np.einsum("kij,j->ki", R, model4[3])
    sg_acc = _sg(pred, rate, PEER_SG_S, PEER_SG_ORDER, 2)
    Rs = _sg(R.reshape(-1, 9), rate, PEER_SG_S, PEER_SG_ORDER).reshape(-1, 3, 3)
    dRs = _sg(R.reshape(-1, 9), rate, PEER_SG_S, PEER_SG_ORDER, 1).reshape(-1, 3, 3)
    out["kabsch_sg"] = (_rel(sg_acc, ref_acc, inner), _rel(_omega_from_rotations(Rs, dRs), ref_omega, inner))
    fc = winter_cutoff(np.column_stack([pred, R.reshape(-1, 9)]), rate)
    pb = _butter(pred, rate, fc)
    bw_acc = np.gradient(np.gradient(pb, 1 / rate, axis=0), 1 / rate, axis=0)
    Rb = _butter(R.reshape(-1, 9), rate, fc).reshape(-1, 3, 3)
    out["kabsch_butter"] = (_rel(bw_acc, ref_acc, inner),
                            _rel(_omega_from_rotations(Rb, np.gradient(Rb, 1 / rate, axis=0)), ref_omega, inner))
    out["butter_hz"] = fc
    out["raw"]["kabsch_sg"] = _raw_error(_sg(pred, rate, PEER_SG_S, PEER_SG_ORDER), raw_acc, inner, rate)
    out["raw"]["kabsch_butter"] = _raw_error(pb, raw_acc, inner, rate)
    return out


CRITERIA_HEADER = "Smoothing choices under correlated noise (bench_real_c3d.py --criteria)"


def _discrepancy_lams(t, components, noise):
    """Per component, the smallest ``lam`` (GCV's times 10^g, g on a 0.25 grid) whose fit leaves a residual
    rms at least the component's noise ``noise`` (the discrepancy principle)."""
    lams = []
    for y, sigma in zip(components.T, noise):
        base = splines.smoothing_spline(t, y).info["lam"]
        grid = np.arange(-4, 12.01, 0.25)
        rms = np.array([splines.smoothing_spline(t, y, lam=base * 10 ** g).info["rms_residual"] for g in grid])
        above = np.flatnonzero(rms >= sigma)
        lams.append(base * 10 ** grid[above[0] if above.size else -1])
    return lams


def run_criteria(name, file, visible, hidden, first, count):
    """The hidden point's errors (filtered reference, %; unfiltered, m/s^2) with each criterion's parameters."""
    traj = io3d.read_c3d(DATA / file)
    pts_all = traj.subset(visible + [hidden])[first:first + count]
    span = _continuous(pts_all)
    pts = pts_all[span]
    t = traj.time_s[first:first + count][span]
    rate = 1 / float(np.median(np.diff(t)))
    model4 = pts[0]
    inner = (t >= t[0] + EDGE_S) & (t <= t[-1] - EDGE_S)
    ref_acc = _sg(pts[:, 3], rate, REFERENCE_S, REFERENCE_ORDER, 2)
    P, V = _sg(pts, rate, REFERENCE_S, REFERENCE_ORDER), _sg(pts, rate, REFERENCE_S, REFERENCE_ORDER, 1)
    r, dv = P - P.mean(1, keepdims=True), V - V.mean(1, keepdims=True)
    ref_omega = np.stack([np.linalg.lstsq(np.concatenate([-_skew(ri) for ri in r[k]]), dv[k].ravel(), rcond=None)[0]
                          for k in range(len(t))])
    raw_acc = np.diff(pts[:, 3], 2, axis=0) * rate ** 2
    reg = pose.register_pose(pts[:, :3], model4[:3])
    plain = pose.PoseParams(smoothing="gcv", harmonics="none")
    gcv = pose.fit_pose_trajectory(t, reg, model4[:3], plain)
    components = np.column_stack([reg.centre, gcv.rotvec_data])
    rho = pose.rigidity_residual_correlation(pts[:, :3], reg)
    choices = {"discrepancy": _discrepancy_lams(t, components, pose.pose_noise(reg, None, model4[:3])),
               "reml_ar1": [splines.reml_ar1_smoothing(t, y)["lam"] for y in components.T]}
    if np.isfinite(rho) and rho >= 0:
        choices["reml_rho_resid"] = [splines.reml_ar1_smoothing(t, y, [rho])["lam"] for y in components.T]
    out = {"case": name, "rho": rho}
    for label, lam in choices.items():
        tr = pose.fit_pose_trajectory(t, reg, model4[:3], plain, lam=lam)
        k = tr.point(t, model4[3])
        out[label] = (_rel(k.acceleration, ref_acc, inner), _rel(tr.omega(t), ref_omega, inner),
                      _raw_error(k.position, raw_acc, inner, rate))
    return out


def criteria_main():
    labels = ("discrepancy", "reml_ar1", "reml_rho_resid")
    lines = [CRITERIA_HEADER,
             "Per case: hidden-point acceleration | omega error (% of the filtered reference's rms) | rms against the",
             "hidden marker's unfiltered second differences (m/s^2), the ordinary quintic spline (no harmonics) with",
             "each criterion's six parameters. discrepancy: lam where the fit's residual rms reaches the component's",
             "noise from the registration residual (isotropic, pose.pose_noise without the points); reml_ar1:",
             "splines.reml_ar1_smoothing, the correlation profiled per component; reml_rho_resid: the same with the",
             "correlation the rigidity residual measures (pose.rigidity_residual_correlation; none: not run).", "",
             f"{'case':28s} {'rho':>5s} " + " ".join(f"{c:>26s}" for c in labels)]
    for case in CASES:
        r = run_criteria(*case)
        cells = [("%8.1f %7.1f %9.3f" % r[c]) if c in r else f"{'-':>26s}" for c in labels]
        lines.append(f"{r['case']:28s} {r['rho']:5.2f} " + " ".join(f"{c:>26s}" for c in cells))
        print(lines[-1], flush=True)
    path = HERE / "results" / "real_c3d.txt"
    old = path.read_text() if path.exists() else ""
    old = old.split("\n" + CRITERIA_HEADER)[0].rstrip("\n") + "\n"
    path.write_text(old + "\n" + "\n".join(lines) + "\n")
    return 0


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def main(argv=None):
    if argv and "--criteria" in argv:
        return criteria_main()
    rows = []
    for case in CASES:
        row = run_case(*case)
        rows.append(row)
        print(row, flush=True)
    lines = ["Real C3D benchmark (benchmarks/bench_real_c3d.py): hidden fourth marker of a rigid cluster;",
             "errors in % of the reference's rms (acceleration of the hidden point | angular velocity).",
             "Reference: the measured 4th marker's Savitzky-Golay derivatives (order 4, 0.25 s); omega from",
             "the 4 markers' Savitzky-Golay (same filter). Peers: per-frame Kabsch of the 3 onto the static frame,",
             "then Savitzky-Golay (order 3, 0.15 s), or a 4th-order zero-lag Butterworth at Winter's cutoff.",
             "",
             "Columns: ours = horsemocap.io3d.kinematics_from_trajectories defaults; white = the same without the",
             "noise's correlation (auto as before); gcv = smoothing='gcv'; loo = the GCV parameters times",
             "10^s, s chosen by leaving each visible marker out in turn (pose.marker_cross_validation; the",
             "hidden marker unused); SG, BW = the naive peers.",
             "",
             f"{'case':28s} {'frames':>6s} {'ours acc':>9s} {'ours w':>7s} {'white acc':>9s} {'white w':>7s} "
             f"{'gcv acc':>8s} {'gcv w':>7s} {'loo acc':>8s} {'loo w':>6s} {'loo s':>5s} "
             f"{'SG acc':>7s} {'SG w':>6s} {'BW acc':>7s} {'BW w':>6s} {'BW Hz':>6s}  chosen by ours (auto)"]
    for r in rows:
        lines.append(f"{r['case']:28s} {r['frames']:6d} {r['ours'][0]:9.1f} {r['ours'][1]:7.1f} "
                     f"{r['ours_white'][0]:9.1f} {r['ours_white'][1]:7.1f} "
                     f"{r['ours_gcv'][0]:8.1f} {r['ours_gcv'][1]:7.1f} {r['ours_loo'][0]:8.1f} {r['ours_loo'][1]:6.1f} "
                     f"{r['loo_decades']:5.1f} {r['kabsch_sg'][0]:7.1f} "
                     f"{r['kabsch_sg'][1]:6.1f} {r['kabsch_butter'][0]:7.1f} {r['kabsch_butter'][1]:6.1f} "
                     f"{r['butter_hz']:6.1f}  {r['chosen']}"
                     + ("; moving reference" if r["moving_reference"] else ""))
    raw_cols = ("ours", "ours_gcv", "ours_loo", "kabsch_sg", "kabsch_butter")
    lines += ["", "The same hidden point against its own unfiltered second differences (rms, m/s^2; no filter in the",
              "reference, whose noise adds the same to every method): which smoothing predicts what the hidden marker",
              "measured frame by frame.", "",
              f"{'case':28s} " + " ".join(f"{c:>13s}" for c in raw_cols)]
    for r in rows:
        lines.append(f"{r['case']:28s} " + " ".join(f"{r['raw'][c]:13.3f}" for c in raw_cols))
    text = "\n".join(lines) + "\n"
    (HERE / "results" / "real_c3d.txt").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
