"""Rotation smoothing weighted by each frame's predicted variance (horsemocap.splines
robust_weighted_spline and residual_log_likelihood; horsemocap.pose frame_variances and
fit_pose_trajectory's ``rotation_weights``).

Known answers: the weighted fit's scale invariance; equal variances without reweighting give the
plain spline; heteroscedastic noise is fitted better with the weights and the likelihood says so; a
sample whose variance the prediction underestimates is downweighted by Huber's weights; the
likelihood criterion by hand; the per-frame variances are the inverse information's diagonal and
their RMS is pose_noise's.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, splines
from horsemocap.params import PoseParams

F0 = 1.67
T = np.arange(42) / 30.0     # the bundled session's length: 42 frames at 30 Hz, 2.3 strides


def _signal(t):
    w = 2 * np.pi * F0
    y = 0.07 * np.sin(w * t + 0.4) + 0.014 * np.cos(2 * w * t + 1.0)
    a = -0.07 * w ** 2 * np.sin(w * t + 0.4) - 0.014 * (2 * w) ** 2 * np.cos(2 * w * t + 1.0)
    return y, a


def _heteroscedastic_sd(rng, n):
    """Mostly 5 mrad, one frame in six 30-60 mrad (the pitch's pattern at 0.25 px of detection noise)."""
    sd = np.full(n, 5e-3)
    bad = rng.choice(n, n // 6, replace=False)
    sd[bad] = rng.uniform(30e-3, 60e-3, bad.size)
    return sd


def _rms(x):
    return float(np.sqrt(np.mean(x ** 2)))


def test_weighted_fit_is_invariant_to_the_variances_scale():
    rng = np.random.default_rng(0)
    y, _ = _signal(T)
    sd = _heteroscedastic_sd(rng, T.size)
    yn = y + rng.normal(0, sd)
    a = splines.robust_weighted_spline(T, yn, sd ** 2, fundamental_hz=F0)
    b = splines.robust_weighted_spline(T, yn, 1e4 * sd ** 2, fundamental_hz=F0)
    np.testing.assert_allclose(a(T, 2), b(T, 2), rtol=1e-7, atol=1e-9)


def test_equal_variances_without_reweighting_give_the_plain_spline():
    rng = np.random.default_rng(1)
    y, _ = _signal(T)
    yn = y + rng.normal(0, 5e-3, T.size)
    a = splines.robust_weighted_spline(T, yn, np.full(T.size, 3.0), iterations=0, fundamental_hz=F0)
    b = splines.smoothing_spline(T, yn, fundamental_hz=F0)
    np.testing.assert_allclose(a(T, 2), b(T, 2), rtol=1e-9, atol=1e-9)
    assert a.info["downweighted"] == 0 and a.info["weights"] == "inverse variance, Huber"


def test_weights_beat_equal_weights_under_heteroscedastic_noise_and_the_likelihood_says_so():
    """200 draws of the 42-frame record: the acceleration error of the weighted fit against the
    equal-weight fit (median ratio measured 0.31), and the likelihood picks the weights (199 of the
    200 draws measured) when the variances are right, the equal weights (186 of 200) when they are
    shuffled (a prediction that says nothing)."""
    rng = np.random.default_rng(2)
    y, acc = _signal(T)
    ratio, pick_right, pick_equal_when_shuffled = [], 0, 0
    for _ in range(200):
        sd = _heteroscedastic_sd(rng, T.size)
        yn = y + rng.normal(0, sd)
        w = splines.robust_weighted_spline(T, yn, sd ** 2, fundamental_hz=F0)
        e = splines.smoothing_spline(T, yn, fundamental_hz=F0)
        ratio.append(_rms(w(T, 2) - acc) / _rms(e(T, 2) - acc))
        le = splines.residual_log_likelihood(e, T, yn)
        pick_right += splines.residual_log_likelihood(w, T, yn, sd ** 2) > le
        wrong = rng.permutation(sd) ** 2
        ws = splines.robust_weighted_spline(T, yn, wrong, fundamental_hz=F0)
        pick_equal_when_shuffled += splines.residual_log_likelihood(ws, T, yn, wrong) < le
    assert np.median(ratio) < 0.6
    assert pick_right >= 190 and pick_equal_when_shuffled >= 175


def test_huber_weights_take_out_a_frame_whose_variance_is_underestimated():
    """One frame 80 mrad off while its predicted sd is 5 mrad: the reweighting downweights it and the
    acceleration error comes within 1.5 times that of the record without the outlier (measured 1.03;
    without reweighting 3.09)."""
    rng = np.random.default_rng(3)
    y, acc = _signal(T)
    sd = np.full(T.size, 5e-3)
    noise = rng.normal(0, sd)
    clean = splines.robust_weighted_spline(T, y + noise, sd ** 2, fundamental_hz=F0)
    yo = y + noise
    yo[20] += 0.08
    robust = splines.robust_weighted_spline(T, yo, sd ** 2, fundamental_hz=F0)
    plain = splines.robust_weighted_spline(T, yo, sd ** 2, fundamental_hz=F0, iterations=0)
    e_clean, e_robust, e_plain = (_rms(s(T, 2) - acc) for s in (clean, robust, plain))
    assert robust.info["downweighted"] >= 1
    assert e_robust < 1.5 * e_clean and e_plain > 2.5 * e_clean


def test_residual_log_likelihood_by_hand():
    y = np.array([0.0, 1.0, 0.0, -1.0, 0.5, 0.2])
    t = np.arange(6.0)
    v = np.array([1.0, 2.0, 1.0, 4.0, 1.0, 0.5])

    class Fit:
        info = {"edf": 2.5}

        def __call__(self, t):
            return np.zeros_like(t)

    s2 = np.sum(y ** 2 / v) / 6
    expect = -0.5 * (np.sum(np.log(v)) + 6 * np.log(s2)) - 2.5
    assert splines.residual_log_likelihood(Fit(), t, y, v) == pytest.approx(expect, rel=1e-12)
    assert splines.residual_log_likelihood(Fit(), t, y) == pytest.approx(-3 * np.log(np.mean(y ** 2)) - 2.5)


def test_robust_weighted_spline_input_errors():
    y, _ = _signal(T)
    with pytest.raises(ValueError, match="variance"):
        splines.robust_weighted_spline(T, y, np.ones(T.size - 1))
    with pytest.raises(ValueError, match="variance"):
        splines.robust_weighted_spline(T, y, np.r_[0.0, np.ones(T.size - 1)])
    with pytest.raises(ValueError, match="weights"):
        splines.robust_weighted_spline(T, y, np.ones(T.size), weights=np.ones(T.size))
    with pytest.raises(ValueError, match="harmonic_noise"):
        splines.robust_weighted_spline(T, y, np.ones(T.size), fundamental_hz=F0, harmonic_noise="rms")


MODEL = np.array([[0.0, 0.0, 0.0], [0.32, 0.02, 0.01], [0.15, -0.03, 0.12], [0.24, 0.05, -0.09]])


def _registration(rng, n, sd_frames):
    """A pitching rigid body (the signal about z) with isotropic marker noise of sd_frames (m) per frame."""
    y, _ = _signal(np.arange(n) / 30.0)
    R = Rotation.from_rotvec(np.column_stack([0.01 * y, 0.02 * y, y])).as_matrix()
    pts = np.einsum("kij,mj->kmi", R, MODEL) + rng.normal(0, 1, (n, 4, 3)) * sd_frames[:, None, None]
    cov = np.broadcast_to(np.eye(3), (n, 4, 3, 3)) * (sd_frames ** 2)[:, None, None, None]
    return pose.register_pose(pts, MODEL, covariance=cov, extra_noise=0.0), R


def test_frame_variances_are_the_inverse_information_diagonal():
    rng = np.random.default_rng(4)
    sd = np.r_[np.full(20, 1e-3), np.full(22, 4e-3)]
    reg, _ = _registration(rng, 42, sd)
    var = pose.frame_variances(reg)
    np.testing.assert_allclose(var[5], np.diag(np.linalg.inv(reg.information[5])), rtol=1e-12)
    np.testing.assert_allclose(var[30, :3] / var[5, :3], 16.0, rtol=1e-9)     # variance ~ sd^2 (centroid)
    np.testing.assert_allclose(var[30, 3:] / var[5, 3:], 16.0, rtol=0.15)     # (rotation: the pose differs)
    np.testing.assert_allclose(np.sqrt(var.mean(0)), pose.pose_noise(reg, None, MODEL), rtol=1e-12)
    reg.information[7] = np.nan                                                # a frame without information
    assert np.all(pose.frame_variances(reg)[7] == np.nanmax(np.delete(pose.frame_variances(reg), 7, 0), axis=0))
    horn = pose.register_pose(reg.registered, MODEL)
    assert np.all(np.isnan(pose.frame_variances(horn)))


def test_fit_pose_trajectory_weights_the_rotation_by_the_predicted_variance():
    """Heteroscedastic marker noise (one frame in six 8 times noisier): with ``rotation_weights="auto"``
    the pitch's acceleration error is below 0.6 of the equal-weight fit's (measured 0.15), and the
    rotation components say which weights they kept; ``"equal"`` is the fit before."""
    rng = np.random.default_rng(5)
    n = 42
    sd = np.full(n, 1e-3)
    sd[rng.choice(n, 7, replace=False)] = 8e-3
    reg, R = _registration(rng, n, sd)
    t = np.arange(n) / 30.0
    _, acc = _signal(t)
    auto = pose.fit_pose_trajectory(t, reg, MODEL, fundamental_hz=F0)
    equal = pose.fit_pose_trajectory(t, reg, MODEL, PoseParams(rotation_weights="equal"), fundamental_hz=F0)
    e_auto = _rms(auto.rotvec(t, 2)[:, 2] - acc)
    e_equal = _rms(equal.rotvec(t, 2)[:, 2] - acc)
    assert e_auto < 0.6 * e_equal
    assert auto.smoothing["phiz"]["weights"] == "inverse variance, Huber"
    assert "weights" not in equal.smoothing["phiz"]
    with pytest.raises(ValueError, match="rotation_weights"):
        pose.fit_pose_trajectory(t, reg, MODEL, PoseParams(rotation_weights="variance"))


def test_calibrated_harmonic_noise_is_the_noise_the_residuals_show():
    """Predicted variances 100 times too small (sd 0.5 mrad, true 5 mrad): "unit weight" tests the harmonics
    against 0.5 mrad, "calibrated" against the predicted noise times the robust scale of the residuals,
    within 20 % of the true 5 mrad (median of 20 draws; measured 4.6 over 50)."""
    rng = np.random.default_rng(7)
    y, _ = _signal(T)
    var = np.full(T.size, 0.5e-3 ** 2)
    levels = []
    for _ in range(20):
        yn = y + rng.normal(0, 5e-3, T.size)
        unit = splines.robust_weighted_spline(T, yn, var, fundamental_hz=F0, harmonic_noise="unit weight")
        assert unit.info["harmonic_noise"] == pytest.approx(0.5e-3, rel=1e-9)
        cal = splines.robust_weighted_spline(T, yn, var, fundamental_hz=F0, harmonic_cutoff=True,
                                             harmonic_noise="calibrated")
        levels.append(cal.info["harmonic_noise"])
    assert 4e-3 < np.median(levels) < 6e-3
    zero = splines.robust_weighted_spline(T, yn, var, fundamental_hz=F0, harmonic_noise="calibrated", iterations=0)
    assert zero.info["harmonic_noise"] == pytest.approx(0.5e-3, rel=1e-9)     # no residuals yet: "unit weight"


def test_calibrated_harmonics_are_not_limited_by_the_plain_splines_cutoff():
    """A smoothing (lam given) whose plain-spline cutoff, 2.5 Hz, lies between the 1st (1.67 Hz) and the 2nd
    stride harmonic: with the cutoff rule ("unit weight") the 2nd harmonic (14 mrad, noise 2 mrad) is never
    offered and its acceleration is lost; "calibrated" keeps harmonics 1 and 2."""
    rng = np.random.default_rng(8)
    y, acc = _signal(T)
    dt = T[1] - T[0]
    lam = 1.0 / (dt * (2 * np.pi * 2.5) ** 6)        # cutoff (1 / (dt lam))^(1/6) / (2 pi) = 2.5 Hz
    sd = np.full(T.size, 2e-3)
    yn = y + rng.normal(0, sd)
    kw = dict(fundamental_hz=F0, harmonic_cutoff=True, lam=lam)
    unit = splines.robust_weighted_spline(T, yn, sd ** 2, harmonic_noise="unit weight", **kw)
    cal = splines.robust_weighted_spline(T, yn, sd ** 2, harmonic_noise="calibrated", **kw)
    assert unit.info["cutoff_hz"] == pytest.approx(2.5, rel=1e-6)
    assert 2 not in unit.info["harmonic_indices"]
    assert cal.info["harmonic_indices"][:2] == [1, 2]
    assert _rms(cal(T, 2) - acc) < 0.5 * _rms(unit(T, 2) - acc)


def test_robust_scale_is_corrected_for_the_smoothers_degrees_of_freedom():
    """A stride-like record as the rotation components (42 samples at 30 Hz, 1.67 Hz and its 2nd
    harmonic) with noise of known sd, the variances given right: the robust scale of the standardised
    residuals, corrected by sqrt(1 - edf / n), is about 1 (measured 1.03 over 40 draws; uncorrected
    0.80: the smoother's residuals are smaller than the noise)."""
    from horsemocap.splines import robust_weighted_spline

    rng = np.random.default_rng(3)
    t = np.arange(42) / 30.0
    scales = []
    for _ in range(40):
        y = np.sin(2 * np.pi * 1.67 * t) + 0.3 * np.sin(2 * np.pi * 3.33 * t) + rng.normal(0, 0.05, t.size)
        s = robust_weighted_spline(t, y, np.full(t.size, 0.05 ** 2), iterations=1)
        scales.append(s.info["robust_scale"])
    assert abs(np.median(scales) - 1.0) < 0.1


# --- under correlated noise, a marker of four covered for a stretch: the left-out route weighs its frames ---

#: Three markers almost on a line (a thin triangle, 2 cm high) and a fourth well off it: with the fourth covered the
#: roll about the line rests on the 2 cm, and those frames' rotation variances are many times the others'.
THIN_AND_SPREAD = np.array([[0.0, 0.0, 0.0], [0.40, 0.01, 0.0], [0.20, -0.005, 0.02], [0.20, 0.10, 0.15]])
SADDLE_POINT = np.array([0.55, -0.25, 0.05])


def _swaying_body(tt):
    w = 2 * np.pi * F0
    R = Rotation.from_rotvec(np.column_stack([0.05 * np.sin(w * tt + 0.3), 0.03 * np.sin(w * tt + 1.1),
                                              0.08 * np.sin(w * tt)]))
    return np.column_stack([2.0 * tt, 0.04 * np.sin(2 * w * tt), 0 * tt]), R


def _covered_fourth_marker(seed, n=180, rho=0.8, sd=1e-3):
    """Six seconds at 30 Hz, marker noise AR(1) ``rho`` per coordinate, the fourth marker missing in frames
    70-119; returns ``t, points, registration (with the markers' covariances), the hidden point's true
    acceleration`` (second differences of the exact motion at 0.1 ms)."""
    from scipy.signal import lfilter
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 30.0
    c, R = _swaying_body(t)
    pts = c[:, None] + np.einsum("kij,mj->kmi", R.as_matrix(), THIN_AND_SPREAD)
    pts = pts + lfilter([1.0], [1.0, -rho], rng.normal(0, sd * np.sqrt(1 - rho ** 2), pts.shape), axis=0)
    pts[70:120, 3] = np.nan
    cov = np.broadcast_to(sd ** 2 * np.eye(3), pts.shape + (3,)).copy()
    reg = pose.register_pose(pts, THIN_AND_SPREAD, covariance=cov, extra_noise=0.0)

    def point(tt):
        c, R = _swaying_body(tt)
        return c + R.apply(SADDLE_POINT)
    h = 1e-4
    return t, pts, reg, (point(t + h) - 2 * point(t) + point(t - h)) / h ** 2


def _relative(est, true):
    return float(np.sqrt(np.mean(np.sum((est - true) ** 2, 1)) / np.mean(np.sum(true ** 2, 1))))


def test_left_out_route_under_correlated_noise_weights_the_frames_a_covered_marker_leaves_thin():
    """Four markers, AR(1) 0.8 noise, the spread marker covered for 50 of 180 frames: ``auto`` takes the
    correlated-noise route chosen by leaving markers out, weights the roll and pitch by each frame's predicted
    variance, and the hidden point's acceleration error falls below 0.75 of the equal-weight fit's (measured
    1.6 against 3.5 %; over seeds 0-3: 1.6-3.8 against 2.8-4.3 %). Its settled choices replay the same fit."""
    t, pts, reg, acc = _covered_fourth_marker(0)
    auto = pose.fit_pose_trajectory(t, reg, THIN_AND_SPREAD, points=pts)
    equal = pose.fit_pose_trajectory(t, reg, THIN_AND_SPREAD, PoseParams(rotation_weights="equal"), points=pts)
    assert auto.smoothing_choice["method"] == "gcv_ar1"
    assert "cross_validation" in auto.smoothing_choice
    assert auto.smoothing["phix"].get("weights") == "inverse variance, Huber"
    assert "weights" not in equal.smoothing["phix"]
    e_auto = _relative(auto.point(t, SADDLE_POINT).acceleration, acc)
    e_equal = _relative(equal.point(t, SADDLE_POINT).acceleration, acc)
    assert e_auto < 0.75 * e_equal, f"{100 * e_auto:.1f} % weighted against {100 * e_equal:.1f} % equal"
    settled = pose.settle_pose_smoothing(auto)
    assert settled.rotation_weighted[0]
    again = pose.fit_pose_trajectory(t, reg, THIN_AND_SPREAD, points=pts, settled=settled)
    np.testing.assert_allclose(again.point(t, SADDLE_POINT).acceleration, auto.point(t, SADDLE_POINT).acceleration,
                               rtol=1e-6, atol=1e-6)


def test_a_blend_whose_routes_chose_different_weights_is_replayed_route_by_route(monkeypatch):
    """The plain route weighted, the harmonic route kept at equal weights (forced: the harmonic fits are not offered
    the variances): the blend says "in one route", the settled choices hold each route's weighting, and the replay
    reproduces the fit (weighting both routes had moved the acceleration by up to 1.4 m/s^2)."""
    t, pts, reg, _ = _covered_fourth_marker(0)
    first = pose._rotation_component

    def harmonic_route_equal(t, y, variance, *, compare=True, **kwargs):
        return first(t, y, None if compare and kwargs.get("fundamental_hz") is not None else variance,
                     compare=compare, **kwargs)
    monkeypatch.setattr(pose, "_rotation_component", harmonic_route_equal)
    auto = pose.fit_pose_trajectory(t, reg, THIN_AND_SPREAD, points=pts)
    monkeypatch.undo()
    assert auto.smoothing["phix"].get("weights") == "inverse variance in one route"
    settled = pose.settle_pose_smoothing(auto)
    assert settled.rotation_weighted[0] and not settled.harmonic_rotation_weighted[0]
    again = pose.fit_pose_trajectory(t, reg, THIN_AND_SPREAD, points=pts, settled=settled)
    np.testing.assert_allclose(again.point(t, SADDLE_POINT).acceleration, auto.point(t, SADDLE_POINT).acceleration,
                               rtol=1e-6, atol=1e-6)


def test_three_markers_under_correlated_noise_keep_equal_weights():
    """With three markers the criterion "loo" runs the correlated-error GCV, not the left-out route: its rotation
    is smoothed with equal weights, as before the left-out route was weighted, even where 40 frames' covariances
    are 9 times the others' (weighted, the likelihood took the weights there)."""
    from scipy.signal import lfilter
    rng = np.random.default_rng(0)
    t = np.arange(180) / 30.0
    three = THIN_AND_SPREAD[:3]
    c, R = _swaying_body(t)
    pts = c[:, None] + np.einsum("kij,mj->kmi", R.as_matrix(), three)
    pts = pts + lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3 * np.sqrt(1 - 0.8 ** 2), pts.shape), axis=0)
    cov = np.broadcast_to(1e-6 * np.eye(3), pts.shape + (3,)).copy()
    cov[60:100] *= 9
    reg3 = pose.register_pose(pts, three, covariance=cov, extra_noise=0.0)
    fit = pose.fit_pose_trajectory(t, reg3, three, points=pts)
    assert fit.smoothing_choice["method"] == "gcv_ar1" and "cross_validation" not in fit.smoothing_choice
    assert all(fit.smoothing[c].get("weights", "equal") == "equal" for c in ("phix", "phiy", "phiz"))
