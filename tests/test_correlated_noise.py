"""The smoothing under correlated marker noise: the rigidity residual's correlation, the correlated-error
GCV and the automatic choice (horsemocap.pose, horsemocap.splines), against exact ground truth."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from horsemocap import pose, splines
from horsemocap.aperture import box_aperture
from horsemocap.params import PoseParams

from test_rotation_continuity import _centre, _cluster, _observe, _wandering_body


def _ar1(rng, shape, rho, sigma):
    """Stationary AR(1) noise along axis 0 with lag-1 correlation ``rho`` and standard deviation ``sigma``."""
    return lfilter([1.0], [1.0, -rho], rng.normal(0, sigma * np.sqrt(1 - rho ** 2), shape), axis=0)


def _cluster_case(seed, rho, sigma=0.001):
    rng, t, R, omega, alpha, _ = _wandering_body(seed)
    markers, hidden = _cluster(rng)
    _, c_acc = _centre(t)
    r = R.apply(hidden - markers.mean(0))
    acc = c_acc + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))
    clean = _observe(rng, t, R, markers, 0.0)
    return t, clean + _ar1(rng, clean.shape, rho, sigma), markers, hidden, acc


def _relative_error(est, true):
    return float(np.sqrt(np.mean(np.sum((est - true) ** 2, 1)) / np.mean(np.sum(true ** 2, 1))))


def test_ar1_correlation_product_matches_the_dense_matrix():
    rng = np.random.default_rng(0)
    Z = rng.normal(size=(50, 4))
    C = 0.7 ** np.abs(np.subtract.outer(np.arange(50), np.arange(50)))
    np.testing.assert_allclose(splines.ar1_correlation_times(Z, 0.7), C @ Z, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8])
def test_rigidity_residual_measures_the_noise_correlation(rho):
    t, pts, markers, _, _ = _cluster_case(1, rho)
    pts = np.concatenate([pts] * 3)          # more frames: a sharper estimate (the motion is not used)
    from horsemocap.pose import register_pose
    est = pose.rigidity_residual_correlation(pts, register_pose(pts, markers))
    assert abs(est - rho) < 0.08


def test_exact_markers_have_no_measurable_correlation():
    t, _, markers, _, _ = _cluster_case(0, 0.8)
    from horsemocap.pose import register_pose
    rng, tt, R, *_ = _wandering_body(0)
    clean = _observe(rng, tt, R, markers, 0.0)
    assert np.isnan(pose.rigidity_residual_correlation(clean, register_pose(clean, markers)))


@pytest.mark.parametrize("seed", range(2))
def test_correlated_noise_choice_beats_plain_gcv_on_the_hidden_point_acceleration(seed):
    t, pts, markers, hidden, acc = _cluster_case(seed, 0.8)
    reg = pose.register_pose(pts, markers)
    auto = pose.fit_pose_trajectory(t, reg, markers, points=pts)
    gcv = pose.fit_pose_trajectory(t, reg, markers, PoseParams(smoothing="gcv"), points=pts)
    choice = auto.smoothing_choice
    assert choice["method"] == "gcv_ar1"
    assert abs(choice["noise_correlation"] - 0.8) < 0.1
    assert "AR(1)" in choice["reason"] and "rigidity residual" in choice["reason"]
    e_auto = _relative_error(auto.point(t, hidden).acceleration, acc)
    e_gcv = _relative_error(gcv.point(t, hidden).acceleration, acc)
    assert e_auto < 0.3 * e_gcv, f"acceleration error {100 * e_auto:.1f} % (AR(1) GCV) vs {100 * e_gcv:.1f} % (GCV)"
    assert e_auto < 0.25


def test_white_noise_keeps_the_white_noise_choice_and_says_so():
    t, pts, markers, _, _ = _cluster_case(0, 0.0, sigma=0.0005)
    reg = pose.register_pose(pts, markers)
    with_points = pose.fit_pose_trajectory(t, reg, markers, points=pts)
    without = pose.fit_pose_trajectory(t, reg, markers)
    assert with_points.smoothing_choice["method"] == without.smoothing_choice["method"]
    assert "noise taken as white" in with_points.smoothing_choice["reason"]
    for a, b in zip(with_points.centre_splines + with_points.rotvec_splines,
                    without.centre_splines + without.rotvec_splines):
        np.testing.assert_array_equal(a.spline.c, b.spline.c)


def test_noise_correlation_is_refused_where_it_does_not_apply():
    t = np.linspace(0, 1, 50)
    with pytest.raises(ValueError, match="noise_correlation"):
        splines.smoothing_spline(t, np.sin(t), noise_correlation=1.0)
    with pytest.raises(ValueError, match="noise_correlation"):
        splines.smoothing_spline(t, np.sin(t), method="adaptive", noise_correlation=0.5)


def _grid_errors(t, reg, markers, hidden, acc, base):
    """The hidden point's acceleration error at every candidate of the cross-validation's grid."""
    params = PoseParams(smoothing="gcv", harmonics="none")
    return np.array([_relative_error(pose.fit_pose_trajectory(t, reg, markers, params, lam=base * 10.0 ** s)
                                     .point(t, hidden).acceleration, acc)
                     for s in pose.CROSS_VALIDATION_DECADES])


@pytest.mark.parametrize("seed, n_markers", [(0, 4), (1, 4), (2, 3)])
def test_leaving_a_marker_out_chooses_near_the_best_smoothing_under_correlated_noise(seed, n_markers):
    """Noise independent between markers but AR(1) 0.8 over frames: the left-out markers choose a smoothing
    whose hidden-point acceleration error is near the best of the grid (the truth is known here), far
    below plain GCV's."""
    t, pts, markers, hidden, acc = _cluster_case(seed, 0.8)
    pts, markers = pts[:, :n_markers], markers[:n_markers]
    reg = pose.register_pose(pts, markers)
    gcv = pose.fit_pose_trajectory(t, reg, markers, PoseParams(smoothing="gcv", harmonics="none"), points=pts)
    base = np.array([s.info["lam"] for s in gcv.centre_splines + gcv.rotvec_splines])
    lam, info = pose.marker_cross_validation(t, reg, pts, markers, base)
    errors = _grid_errors(t, reg, markers, hidden, acc, base)
    chosen = errors[list(pose.CROSS_VALIDATION_DECADES).index(info["cross_validation_decades"])]
    assert info["cross_validation_markers"] == n_markers
    assert chosen < 1.5 * errors.min() + 0.02, f"chosen {chosen:.3f}, best {errors.min():.3f}"
    assert chosen < 0.5 * errors[list(pose.CROSS_VALIDATION_DECADES).index(0.0)]


def test_cross_validation_refuses_too_few_markers():
    t, pts, markers, _, _ = _cluster_case(0, 0.0)
    reg = pose.register_pose(pts, markers)
    with pytest.raises(ValueError, match="m >= 3"):
        pose.marker_cross_validation(t, reg, pts[:, :2], markers[:2], np.ones(6))


@pytest.mark.parametrize("seed", range(4))
def test_short_periodic_record_never_keeps_a_correlated_choice_that_flattens_a_component(monkeypatch, seed):
    """70 frames of a trot-like oscillation with AR(1) 0.8 noise: the correlated-error GCV smooths components
    down to a quadratic (their whole motion taken for noise); without the refit with the stride's harmonics
    (tests/test_correlated_harmonics.py: what runs first) the choice falls back to the white-noise one and says
    why."""
    from scipy.spatial.transform import Rotation
    monkeypatch.setattr(pose, "CORRELATED_HARMONIC_REFIT", False)
    rng = np.random.default_rng(seed)
    model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.05, 0.2, 0.03]])
    t = np.arange(70) / 30.0
    f = 1.4
    R = Rotation.from_rotvec(np.column_stack([0.05 * np.sin(2 * np.pi * f * t), 0.03 * np.sin(4 * np.pi * f * t),
                                              0 * t])).as_matrix()
    c = np.column_stack([0.02 * np.sin(4 * np.pi * f * t), 0.03 * np.sin(4 * np.pi * f * t + 1), 4 * t])
    clean = c[:, None] + np.einsum("kij,mj->kmi", R, model - model.mean(0)) + model.mean(0)
    pts = clean + _ar1(rng, clean.shape, 0.8, 0.004)
    tr = pose.fit_pose_trajectory(t, pose.register_pose(pts, model), model, points=pts)
    edf = [s.info["edf"] for s in tr.centre_splines + tr.rotvec_splines]
    assert tr.smoothing_choice["method"] != "gcv_ar1" or min(edf) > pose.NULL_SPACE_EDF + pose.NULL_SPACE_TOLERANCE
    assert "took a component's whole motion for noise" in tr.smoothing_choice["reason"]
    assert tr.smoothing_choice["method"] == "gcv" and "noise_correlation" not in tr.smoothing_choice


def test_reml_with_ar1_errors_finds_the_correlation_and_beats_plain_gcv():
    # the restricted likelihood, profiled over the AR(1) correlation, on the pose components of a
    # cluster under AR(1) 0.8 marker noise: the correlation found near the truth, and the hidden
    # point's acceleration far nearer the truth than with plain GCV
    t, pts, markers, hidden, acc = _cluster_case(0, 0.8)
    reg = pose.register_pose(pts, markers)
    gcv = pose.fit_pose_trajectory(t, reg, markers, PoseParams(smoothing="gcv", harmonics="none"))
    components = np.column_stack([reg.centre, gcv.rotvec_data])
    found = [splines.reml_ar1_smoothing(t, components[:, i]) for i in range(6)]
    assert abs(np.median([f["noise_correlation"] for f in found]) - 0.8) <= 0.1
    reml = pose.fit_pose_trajectory(t, reg, markers, PoseParams(smoothing="gcv", harmonics="none"),
                                    lam=[f["lam"] for f in found])
    err_reml = _relative_error(reml.point(t, hidden).acceleration, acc)
    err_gcv = _relative_error(gcv.point(t, hidden).acceleration, acc)
    assert err_reml < 0.3 * err_gcv


def test_reml_with_ar1_errors_refuses_bad_input():
    t = np.arange(20) / 10.0
    with pytest.raises(ValueError, match="correlations"):
        splines.reml_ar1_smoothing(t, np.sin(t), correlations=[1.0])
    with pytest.raises(ValueError, match="increasing"):
        splines.reml_ar1_smoothing(t[::-1], np.sin(t))


def test_an_unknown_correlated_noise_criterion_is_refused_where_it_would_run():
    # a misspelt criterion must not silently run the correlated-error GCV
    t, pts, markers, _, _ = _cluster_case(0, 0.8)
    reg = pose.register_pose(pts, markers)
    assert pose.fit_pose_trajectory(t, reg, markers, points=pts).smoothing_choice["method"] == "gcv_ar1"
    with pytest.raises(ValueError, match="correlated_noise_criterion"):
        pose.fit_pose_trajectory(t, reg, markers, PoseParams(correlated_noise_criterion="rml"), points=pts)


@pytest.mark.parametrize("bad", [float("nan"), 0.0, -1.5])
def test_a_stride_frequency_that_is_not_one_is_refused_by_name(bad):
    t, pts, markers, _, _ = _cluster_case(0, 0.8)
    reg = pose.register_pose(pts, markers)
    with pytest.raises(ValueError, match="fundamental_hz"):
        pose.fit_pose_trajectory(t, reg, markers, points=pts, fundamental_hz=bad)


def test_the_white_noise_refit_keeps_the_aperture_in_its_reason(monkeypatch):
    # the correlated choice smoothed again as white (the stride's harmonics found in its residual: the test's
    # p-values in place of the F tests) is still fitted through the frames' aperture, and its reason says so
    t, pts, markers, _, _ = _cluster_case(0, 0.8)
    reg = pose.register_pose(pts, markers)
    monkeypatch.setattr(pose, "_stride_p_values", lambda *args: np.full(6, 1e-9))
    aperture = box_aperture(0.01)
    tr = pose.fit_pose_trajectory(t, reg, markers, points=pts, expected_fundamental_hz=1.5, aperture=aperture)
    reason = tr.smoothing_choice["reason"]
    assert tr.smoothing_choice["method"] == "gcv" and "took periodic motion for noise" in reason
    assert "fitted through the frames' temporal aperture (exposure 10 ms)" in reason
