"""The pose smoothing chosen by leaving each marker out in turn (four or more markers, noise correlated over
frames): horsemocap.pose.marker_cross_validation_per_component and its place in fit_pose_trajectory's
``"auto"``, against exact ground truth."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from horsemocap import pose
from horsemocap.params import AnalysisParams, ParamsError, PoseParams

RATE_HZ = 50.0
#: the markers' noise per axis (m): the depth (z) three times the image directions, as a camera rig measures
SIGMA = np.array([1e-3, 1e-3, 3e-3])
HIDDEN = np.array([0.0, -0.15, 0.0])


def _pose_path(t, f, ph):
    """A trotting back: the centroid (m) and the rotation vector (rad) at times ``t``, stride frequency ``f``."""
    w = 2 * np.pi * f
    c = np.column_stack([3.0 * t + 0.02 * np.sin(w * t + ph[0]),
                         1.2 + 0.04 * np.sin(2 * w * t + ph[1]) + 0.01 * np.sin(3 * w * t + ph[2]),
                         0.01 * np.sin(w * t + ph[2])])
    phi = np.column_stack([a * np.sin((i + 1) * w * t + ph[3 + i]) for i, a in enumerate((0.04, 0.02, 0.03))])
    return c, phi


def _point(t, f, ph, body_point):
    c, phi = _pose_path(t, f, ph)
    return c + Rotation.from_rotvec(phi).apply(body_point)


def _trot(seed, markers=5, rho=0.8, frames=200):
    """Markers on a trotting back with AR(1) noise over frames (independent between markers), the hidden
    point's exact acceleration, and each marker's noise covariance."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / RATE_HZ
    f, ph = rng.uniform(1.2, 1.8), rng.uniform(0, 6, 6)
    x = np.column_stack([rng.uniform(-0.25, 0.25, markers), rng.uniform(-0.03, 0.03, markers),
                         rng.uniform(-0.2, 0.2, markers)])
    x -= x.mean(0)
    c, phi = _pose_path(t, f, ph)
    clean = c[:, None] + np.einsum("kij,mj->kmi", Rotation.from_rotvec(phi).as_matrix(), x)
    white = rng.normal(0, 1, clean.shape) * np.sqrt(1 - rho ** 2)
    noisy = clean + lfilter([1.0], [1.0, -rho], white, axis=0) * SIGMA
    h = 1e-4                    # the exact path's second derivative, by a central difference at 0.1 ms
    acc = (_point(t + h, f, ph, HIDDEN) - 2 * _point(t, f, ph, HIDDEN) + _point(t - h, f, ph, HIDDEN)) / h ** 2
    cov = np.broadcast_to(np.diag(SIGMA ** 2), (frames, markers, 3, 3))
    return t, noisy, x, acc, cov


def _error(tr, t, acc, edge=10):
    """The hidden point's acceleration error, rms relative to the true acceleration's, inside the record."""
    d = (tr.point(t, HIDDEN).acceleration - acc)[edge:-edge]
    return float(np.sqrt(np.mean(np.sum(d ** 2, 1)) / np.mean(np.sum(acc[edge:-edge] ** 2, 1))))


def test_the_default_criterion_leaves_markers_out():
    assert PoseParams().correlated_noise_criterion == "loo"
    assert AnalysisParams().rigid_body.pose.correlated_noise_criterion == "loo"


def _fit(criterion, t, pts, x, cov=None, params=PoseParams()):
    params = replace(params, correlated_noise_criterion=criterion)
    return pose.fit_pose_trajectory(t, pose.register_pose(pts, x, covariance=cov), x, params, points=pts)


def test_the_criterion_parameter_reaches_the_choice():
    """Five markers under AR(1) 0.8 noise: ``"loo"`` leaves each marker out, ``"gcv"`` runs the correlated-error
    GCV, each saying so in its reason; the section's value (``rigid_body.pose.correlated_noise_criterion``) is
    the one the fit reads."""
    t, pts, x, _, cov = _trot(0)
    chosen = AnalysisParams().updated({"rigid_body.pose.correlated_noise_criterion": "gcv"}).rigid_body.pose
    assert chosen.correlated_noise_criterion == "gcv"
    gcv = _fit("gcv", t, pts, x, cov, chosen).smoothing_choice
    loo = _fit("loo", t, pts, x, cov).smoothing_choice
    assert gcv["method"] == loo["method"] == "gcv_ar1"
    assert "correlated-error GCV" in gcv["reason"] and "markers out" not in gcv["reason"]
    assert "cross_validation" not in gcv
    assert "leaving each of the 5 markers out" in loo["reason"] and "cross_validation" in loo


def test_an_unknown_criterion_is_refused_by_name():
    with pytest.raises(ParamsError, match=r"rigid_body\.pose\.correlated_noise_criterion.*loo.*gcv.*reml.*risk"):
        AnalysisParams.from_dict({"rigid_body": {"pose": {"correlated_noise_criterion": "rml"}}})
    t, pts, x, _, _ = _trot(1, rho=0.0)     # white noise: refused before the correlated path would run
    with pytest.raises(ValueError, match=r"correlated_noise_criterion: expected one of loo, gcv, reml, risk, "
                                         r"got 'rml'"):
        _fit("rml", t, pts, x)


def test_leaving_markers_out_smooths_more_than_gcv_and_beats_both_gcv_choices():
    """AR(1) 0.8 noise, five markers: the choice is heavier than white-noise GCV's in every case, says what it
    ran, and its hidden-point acceleration error is below both plain GCV's and the correlated-error GCV's on
    average over the seeds (the truth is exact here)."""
    left_out, correlated, plain = [], [], []
    for seed in range(3):
        t, pts, x, acc, cov = _trot(seed)
        tr = _fit("loo", t, pts, x, cov)
        choice = tr.smoothing_choice
        cv = choice["cross_validation"]
        assert choice["method"] == "gcv_ar1" and "leaving each of the 5 markers out" in choice["reason"]
        assert choice["noise_correlation"] > 0.5
        assert len(cv["cross_validation_scores"]) == len(cv["decades"]) == len(pose.LEFT_OUT_DECADES)
        assert np.mean(cv["cross_validation_component_decades"]) > 0.5
        assert cv["cross_validation_score"] <= min(cv["cross_validation_scores"])
        left_out.append(_error(tr, t, acc))
        correlated.append(_error(_fit("gcv", t, pts, x, cov), t, acc))
        plain.append(_error(_fit("loo", t, pts, x, cov, PoseParams(smoothing="gcv", harmonics="none")),
                            t, acc))
    assert np.mean(left_out) < np.mean(plain), f"left out {left_out}, plain GCV {plain}"
    assert np.mean(left_out) < np.mean(correlated), f"left out {left_out}, correlated GCV {correlated}"


def test_three_markers_keep_the_correlated_gcv_unchanged():
    t, pts, x, _, _ = _trot(0, markers=3)
    a = _fit("loo", t, pts, x)
    b = _fit("gcv", t, pts, x)
    assert a.smoothing_choice["method"] == "gcv_ar1"
    assert a.smoothing_choice["reason"] == b.smoothing_choice["reason"]
    assert "correlated-error GCV" in a.smoothing_choice["reason"]
    assert "cross_validation" not in a.smoothing_choice
    for sa, sb in zip(a.centre_splines + a.rotvec_splines, b.centre_splines + b.rotvec_splines):
        np.testing.assert_array_equal(sa.spline.c, sb.spline.c)


def test_white_noise_never_runs_the_cross_validation():
    t, pts, x, _, _ = _trot(1, rho=0.0)
    tr = _fit("loo", t, pts, x)
    assert tr.smoothing_choice["method"] != "gcv_ar1"
    assert "cross_validation" not in tr.smoothing_choice


def test_per_component_cross_validation_refuses_three_markers():
    t, pts, x, _, _ = _trot(0, markers=3)
    with pytest.raises(ValueError, match="m >= 4"):
        pose.marker_cross_validation_per_component(t, pose.register_pose(pts, x), pts, x, np.ones(6))


def test_left_out_registration_keeps_the_markers_covariances():
    t, pts, x, _, cov = _trot(2, markers=4)
    reg = pose.register_pose(pts, x, covariance=cov)
    np.testing.assert_array_equal(reg.marker_covariance, cov)
    left, model = pose._left_out_registration(reg, pts, x, 1)
    assert left.information is not None and model.shape == (3, 3)
    np.testing.assert_array_equal(left.marker_covariance, cov[:, [0, 2, 3]])


def test_noise_ratios_of_a_symmetric_cluster():
    """A regular tetrahedron: leaving any marker out leaves three, the centroid's variance 4/3 larger, and the
    rotation's larger in every direction."""
    x = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) * 0.1
    reg = pose.register_pose(np.repeat(x[None], 4, axis=0), x)
    ratios = pose.left_out_noise_ratios(reg, x)
    np.testing.assert_allclose(ratios[:, :3], 4 / 3)
    assert np.all(ratios[:, 3:] > 1)
    with pytest.raises(ValueError, match="four or more"):
        pose.left_out_noise_ratios(reg, x[:3])
