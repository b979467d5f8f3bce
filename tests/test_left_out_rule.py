"""How the left-out choice picks among its candidates: the minimum (the default) or the most smoothing within
one standard error, and the standard error of a left-out score difference."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from horsemocap import pose


def _cluster(seed, markers=5, frames=200, rho=0.8, sigma=1e-3):
    """Markers on a body bobbing and pitching at a trot's stride, with AR(1) noise over frames."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 50.0
    w = 2 * np.pi * 1.5
    x = rng.uniform(-0.2, 0.2, (markers, 3)) * [1.0, 0.15, 1.0]
    x -= x.mean(0)
    c = np.column_stack([3.0 * t, 1.2 + 0.04 * np.sin(2 * w * t), 0.01 * np.sin(w * t)])
    phi = np.column_stack([0.04 * np.sin(w * t), 0.02 * np.sin(2 * w * t + 1), 0.03 * np.sin(3 * w * t + 2)])
    clean = c[:, None] + np.einsum("kij,mj->kmi", Rotation.from_rotvec(phi).as_matrix(), x)
    noise = lfilter([1.0], [1.0, -rho], rng.normal(0, sigma * np.sqrt(1 - rho ** 2), clean.shape), axis=0)
    return t, clean + noise, x


def _choose(rule, seed=0):
    t, pts, x = _cluster(seed)
    reg = pose.register_pose(pts, x)
    white = pose.fit_pose_trajectory(t, reg, x, pose.PoseParams(smoothing="gcv", harmonics="none",
                                                                rotation_weights="equal", partial_frames=False),
                                     iterations=0)
    base = np.array([s.info["lam"] for s in white.centre_splines + white.rotvec_splines])
    return pose.marker_cross_validation_per_component(t, reg, pts, x, base, decades=pose.LEFT_OUT_DECADES,
                                                      rule=rule)


def test_the_difference_of_identical_losses_plus_a_constant_is_that_constant_without_error():
    losses = np.random.default_rng(0).gamma(2.0, 1.0, 300)
    diff, se = pose.left_out_score_difference(losses + 0.25, losses)
    assert diff == pytest.approx(0.25) and se == pytest.approx(0.0, abs=1e-12)


def test_the_standard_error_counts_the_frames_correlation():
    """Differences correlated over frames (AR(1) 0.9): the block means' standard error is close to the true
    standard error of the mean over many records, and far above the one that takes the frames as independent."""
    rng = np.random.default_rng(3)
    n, means, ses, naive = 1000, [], [], []
    for _ in range(200):
        d = lfilter([1.0], [1.0, -0.9], rng.normal(0, 1, n))
        diff, se = pose.left_out_score_difference(d, np.zeros(n))
        means.append(diff)
        ses.append(se)
        naive.append(d.std(ddof=1) / np.sqrt(n))
    true_se = np.std(means)
    assert 0.7 * true_se < np.mean(ses) < 1.3 * true_se
    assert np.mean(naive) < 0.5 * true_se


def test_the_frames_not_scored_are_left_out_and_too_few_are_refused():
    a = np.arange(100.0)
    a[::2] = np.nan
    diff, _ = pose.left_out_score_difference(a + 1.0, a)
    assert diff == pytest.approx(1.0)
    with pytest.raises(ValueError, match="at least 20 scored frames, got 10"):
        pose.left_out_score_difference(np.ones(10), np.zeros(10))


def test_the_one_standard_error_rule_smooths_at_least_as_much_as_the_minimum():
    lam_min, info_min = _choose("min")
    lam_se, info_se = _choose("one_se")
    assert info_min["cross_validation_component_decades"] == info_min["cross_validation_minimum_decades"]
    assert info_se["cross_validation_minimum_decades"] == info_min["cross_validation_component_decades"]
    assert np.all(np.array(info_se["cross_validation_component_decades"])
                  >= np.array(info_min["cross_validation_component_decades"]))
    assert np.any(np.array(info_se["cross_validation_component_decades"])
                  > np.array(info_min["cross_validation_component_decades"]))
    assert np.all(lam_se >= lam_min)
    assert info_se["cross_validation_score"] >= info_min["cross_validation_score"]


def test_the_default_rule_is_the_minimum_and_an_unknown_rule_is_refused():
    assert pose.LEFT_OUT_RULE == "min"
    t, pts, x = _cluster(1, markers=4, frames=80)
    with pytest.raises(ValueError, match="rule: expected one of min, one_se, got 'median'"):
        pose.marker_cross_validation_per_component(t, pose.register_pose(pts, x), pts, x, np.ones(6), rule="median")
