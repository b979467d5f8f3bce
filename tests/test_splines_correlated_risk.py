"""The unbiased risk with a known AR(1) noise covariance (``method="noise"`` with ``noise_correlation``)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from horsemocap import pose, splines


def _hat_matrix(t, lam):
    """The quintic spline's hat matrix at ``lam``: its fit of each unit vector."""
    eye = np.eye(t.size)
    return np.column_stack([splines.smoothing_spline(t, eye[:, j], lam=lam)(t) for j in range(t.size)])


def _closed_form_risk(t, y, lam, noise, rho):
    H = _hat_matrix(t, lam)
    C = rho ** np.abs(np.subtract.outer(np.arange(t.size), np.arange(t.size)))
    r = y - H @ y
    return float(r @ r + 2 * noise ** 2 * np.trace(H @ C))


def test_correlated_risk_choice_minimises_its_closed_form_on_a_tiny_problem():
    t = np.linspace(0.0, 1.0, 14)
    y = np.sin(2 * np.pi * t) + np.random.default_rng(3).normal(0, 0.2, t.size)
    noise, rho = 0.2, 0.6
    s = splines.smoothing_spline(t, y, method="noise", noise=noise, noise_correlation=rho)
    assert s.info["method"] == "noise" and s.info["noise_correlation"] == rho
    chosen = _closed_form_risk(t, y, s.info["lam"], noise, rho)
    grid = [_closed_form_risk(t, y, s.info["lam"] * 10.0 ** k, noise, rho) for k in np.arange(-3, 3.01, 0.25)]
    assert chosen <= min(grid) * (1 + 1e-6)
    # the fit's own residual and freedom are those of the closed form
    H = _hat_matrix(t, s.info["lam"])
    assert s.info["edf"] == pytest.approx(np.trace(H), rel=1e-6)
    assert np.allclose(s(t), H @ y, atol=1e-9)


def test_correlated_risk_without_correlation_is_the_white_noise_risk():
    t = np.linspace(0.0, 2.0, 80)
    y = np.cos(3 * t) + np.random.default_rng(1).normal(0, 0.05, t.size)
    white = splines.smoothing_spline(t, y, method="noise", noise=0.05)
    zero = splines.smoothing_spline(t, y, method="noise", noise=0.05, noise_correlation=0.0)
    assert zero.info["lam"] == white.info["lam"]


def test_correlated_risk_smooths_more_than_the_white_noise_risk_under_correlated_noise():
    t = np.arange(300) / 50.0
    y = np.sin(2 * np.pi * 1.2 * t) + lfilter([1.0], [1.0, -0.8], np.random.default_rng(0).normal(0, 0.06, t.size))
    white = splines.smoothing_spline(t, y, method="noise", noise=0.1)
    correlated = splines.smoothing_spline(t, y, method="noise", noise=0.1, noise_correlation=0.8)
    assert correlated.info["lam"] > white.info["lam"]


@pytest.mark.parametrize("rho, sd", [(0.6, 0.2), (0.8, 0.1), (0.9, 0.2)])
def test_correlated_risk_and_reml_have_lower_expected_error_than_gcv_under_ar1_noise(rho, sd):
    t = np.arange(300) / 50.0
    f = np.sin(2 * np.pi * 1.2 * t) + 0.4 * np.sin(2 * np.pi * 3.6 * t + 1)
    risk = {"gcv": [], "gcv_ar1": [], "risk_ar1": [], "reml_ar1": []}
    for seed in range(12):
        e = lfilter([1.0], [1.0, -rho], np.random.default_rng(seed).normal(0, sd * np.sqrt(1 - rho ** 2), t.size))
        y = f + e
        fits = {"gcv": splines.smoothing_spline(t, y),
                "gcv_ar1": splines.smoothing_spline(t, y, noise_correlation=rho),
                "risk_ar1": splines.smoothing_spline(t, y, method="noise", noise=sd, noise_correlation=rho),
                "reml_ar1": splines.smoothing_spline(t, y, method="reml", noise_correlation=rho)}
        for k, s in fits.items():
            risk[k].append(np.mean((s(t) - f) ** 2))
    mean = {k: float(np.mean(v)) for k, v in risk.items()}
    assert mean["risk_ar1"] < mean["gcv"]
    assert mean["risk_ar1"] < mean["gcv_ar1"]
    # REML, which estimates the level with the signal's, is as good as GCV and far better than the correlated GCV
    assert mean["reml_ar1"] < mean["gcv"]
    assert mean["reml_ar1"] < 0.5 * mean["gcv_ar1"]


def test_correlated_risk_needs_a_noise_level():
    t = np.linspace(0, 2, 60)
    with pytest.raises(ValueError, match="noise"):
        splines.smoothing_spline(t, np.sin(t), method="noise", noise_correlation=0.5)


def _turning_cluster_with_ar1_noise():
    """Four markers turning about z (0.7 Hz) and drifting, 600 frames at 50 Hz, with AR(1) 0.8 noise (0.6 mm):
    the times, the points, the model and their registration."""
    model = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.0, 0.2, 0.05], [0.15, 0.12, 0.1]])
    n = 600
    t = np.arange(n) / 50.0
    rot = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * 0.7 * t), [0, 0, 1]) + [0, 0.05, 0]).as_matrix()
    e = lfilter([1.0], [1.0, -0.8], np.random.default_rng(2).normal(0, 6e-4, (n, 4, 3)), axis=0)
    pts = np.einsum("kij,mj->kmi", rot, model) + 0.1 * t[:, None, None] + e
    return t, pts, model, pose.register_pose(pts, model)


def test_pose_correlated_criterion_risk_reports_its_choice():
    t, pts, model, reg = _turning_cluster_with_ar1_noise()
    params = pose.PoseParams(smoothing="auto", events=None, correlated_noise_criterion="risk")
    tr = pose.fit_pose_trajectory(t, reg, model, params, points=pts)
    choice = tr.smoothing_choice
    assert choice["method"] == "gcv_ar1"
    assert "unbiased risk with the noise's covariance known" in choice["reason"]
    assert all(tr.smoothing[c]["method"] == "noise" for c in ("cx", "phiz"))
    assert tr.smoothing["phiz"]["noise"] == pytest.approx(pose.pose_noise(reg, pts, model)[5])


def test_pose_correlated_risk_with_three_markers_keeps_the_correlated_gcv_and_says_why():
    from scipy.spatial.transform import Rotation
    model = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.0, 0.2, 0.05]])
    n = 600
    t = np.arange(n) / 50.0
    rot = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * 0.7 * t), [0, 0, 1])).as_matrix()
    e = lfilter([1.0], [1.0, -0.8], np.random.default_rng(2).normal(0, 6e-4, (n, 3, 3)), axis=0)
    pts = np.einsum("kij,mj->kmi", rot, model) + 0.1 * t[:, None, None] + e
    reg = pose.register_pose(pts, model)
    tr = pose.fit_pose_trajectory(t, reg, model, pose.PoseParams(smoothing="auto", correlated_noise_criterion="risk"),
                                  points=pts)
    assert "3 markers: their residual does not measure the noise normal" in tr.smoothing_choice["reason"]
    assert tr.smoothing["phiz"]["method"] == "gcv"


def test_reml_method_takes_the_reml_smoothing_with_the_correlation_given():
    t = np.arange(200) / 50.0
    y = np.sin(2 * np.pi * t) + lfilter([1.0], [1.0, -0.7], np.random.default_rng(4).normal(0, 0.02, t.size))
    s = splines.smoothing_spline(t, y, method="reml", noise_correlation=0.7)
    assert s.info["method"] == "reml" and s.info["noise_correlation"] == 0.7
    assert s.info["lam"] == splines.reml_ar1_smoothing(t, y, correlations=[0.7])["lam"]
    with pytest.raises(ValueError, match="reml"):
        splines.smoothing_spline(t, y, method="reml", weights=np.ones(t.size))


def test_pose_correlated_smoothing_by_reml_takes_the_residual_correlation():
    t, pts, model, reg = _turning_cluster_with_ar1_noise()
    tr = pose.fit_pose_trajectory(t, reg, model, pose.PoseParams(smoothing="auto", correlated_noise_criterion="reml"),
                                  points=pts)
    choice = tr.smoothing_choice
    assert choice["method"] == "gcv_ar1" and choice["reason"].startswith("REML with AR(1)")
    assert tr.smoothing["phiz"]["method"] == "reml"
    expected = splines.reml_ar1_smoothing(t, tr.rotvec_data[:, 2], correlations=[choice["noise_correlation"]])
    assert tr.smoothing["phiz"]["lam"] == expected["lam"]
