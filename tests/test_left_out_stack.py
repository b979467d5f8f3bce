"""Stacking the left-out choice's two routes (horsemocap.pose.LEFT_OUT_STACK): the blend of two splines
(horsemocap.splines.blend_splines), the weights' exact box minimum (horsemocap.pose.stacking_weights) and the
blend in fit_pose_trajectory, against known answers."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from horsemocap import pose
from horsemocap.aperture import box_aperture
from horsemocap.params import PoseParams
from horsemocap.splines import BlendedSpline, blend_splines, smoothing_spline
from test_left_out_smoothing import _fit, _trot


def _two_fits():
    rng = np.random.default_rng(3)
    t = np.arange(120) / 50.0
    y = np.sin(2 * np.pi * 1.3 * t) + 0.3 * np.sin(2 * np.pi * 2.6 * t) + rng.normal(0, 0.02, t.size)
    return t, smoothing_spline(t, y, lam=1e-6), smoothing_spline(t, y, lam=1e-7, fundamental_hz=1.3)


def test_the_blend_of_two_splines_is_their_weighted_sum_with_its_derivatives():
    t, plain, harmonic = _two_fits()
    assert harmonic.info["harmonics"] >= 1
    b = blend_splines(plain, harmonic, 0.3)
    u = np.linspace(t[0], t[-1], 301)
    for d in range(4):
        np.testing.assert_allclose(b(u, d), 0.7 * plain(u, d) + 0.3 * harmonic(u, d), rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.observed(t), 0.7 * plain.observed(t) + 0.3 * harmonic.observed(t), atol=1e-12)
    assert b.info["edf"] == pytest.approx(0.7 * plain.info["edf"] + 0.3 * harmonic.info["edf"], rel=1e-12)
    assert b.info["lam"] is None and b.info["method"] == "blend" and b.info["blend_weights"] == [0.7, 0.3]
    assert b.info["n"] == t.size and b.info["order"] == 5
    # the ends of the weight: either spline itself
    np.testing.assert_array_equal(blend_splines(plain, harmonic, 0.0)(u, 2), plain(u, 2))
    np.testing.assert_array_equal(blend_splines(plain, harmonic, 1.0)(u, 2), harmonic(u, 2))


@pytest.mark.parametrize("weight", [-0.1, 1.5, np.nan])
def test_a_blend_weight_outside_zero_one_is_refused(weight):
    _, plain, harmonic = _two_fits()
    with pytest.raises(ValueError, match=r"weight: expected the second fit's weight in \[0, 1\]"):
        blend_splines(plain, harmonic, weight)


def _loss(r, D, w):
    return float(np.sum((r + D @ w) ** 2))


@pytest.mark.parametrize("seed", range(6))
def test_the_weights_closed_form_equals_the_brute_force_grid_minimum(seed):
    """Two weights, correlated directions: the exact box minimum is no worse than the best point of a 0.002
    grid, and within the grid's resolution of it."""
    rng = np.random.default_rng(seed)
    D = rng.normal(size=(200, 2))
    D[:, 1] += 0.8 * D[:, 0]
    r = -D @ rng.uniform(-0.5, 1.5, 2) + rng.normal(0, 0.5, 200)
    w = pose.stacking_weights(r, D)
    grid = np.linspace(0.0, 1.0, 501)
    losses = np.array([[_loss(r, D, np.array([a, b])) for b in grid] for a in grid])
    i, j = np.unravel_index(np.argmin(losses), losses.shape)
    assert np.all((w >= 0) & (w <= 1))
    assert _loss(r, D, w) <= losses[i, j] + 1e-9
    np.testing.assert_allclose(w, [grid[i], grid[j]], atol=0.004)


def test_six_weights_against_every_corner_and_the_unconstrained_minimum():
    """Six weights whose unconstrained minimum lies inside the box: the closed form finds it exactly; no corner
    of the box is lower."""
    rng = np.random.default_rng(7)
    D = rng.normal(size=(500, 6))
    inside = rng.uniform(0.1, 0.9, 6)
    r = -D @ inside
    np.testing.assert_allclose(pose.stacking_weights(r, D), inside, atol=1e-10)
    w = pose.stacking_weights(r + rng.normal(0, 3.0, 500), D)
    corners = [_loss(r, D, np.array(c)) for c in itertools.product((0.0, 1.0), repeat=6)]
    assert _loss(r, D, w) <= min(corners)


def test_the_weights_are_clipped_into_zero_one():
    """Unconstrained, the first weight would be 2 and the second -1: each stops at its bound, exactly."""
    D = np.eye(2)
    r = np.array([-2.0, 1.0])
    np.testing.assert_array_equal(pose.stacking_weights(r, D), [1.0, 0.0])
    # a direction of zeros (the two predictors agree) takes no weight
    np.testing.assert_array_equal(pose.stacking_weights(np.array([1.0, -1.0]), np.zeros((2, 1))), [0.0])


def test_the_weights_refuse_shapes_that_do_not_match():
    with pytest.raises(ValueError, match="residual, directions"):
        pose.stacking_weights(np.zeros(3), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="k <= 8"):
        pose.stacking_weights(np.zeros(3), np.zeros((3, 9)))


def test_the_switch_off_fits_one_route_and_says_nothing_of_a_blend(monkeypatch):
    """``LEFT_OUT_STACK`` False: no blended spline, no stack in the record; each component's spline is the
    chosen route's at ``base * 10^s``."""
    monkeypatch.setattr(pose, "LEFT_OUT_STACK", False)
    t, pts, x, _, cov = _trot(2)
    tr = _fit("loo", t, pts, x, cov)
    cv = tr.smoothing_choice["cross_validation"]
    assert set(cv["routes"]) == {"plain", "harmonics"} and "stack_fundamental_hz" not in cv
    assert not any(isinstance(s, BlendedSpline) for s in tr.centre_splines + tr.rotvec_splines)
    assert "blended" not in tr.smoothing_choice["reason"]


def test_the_default_blends_the_routes_with_one_weight_for_the_pose():
    assert pose.LEFT_OUT_STACK == "pose" and pose.LEFT_OUT_HARMONICS is True


@pytest.mark.parametrize("mode", ["pose", True])
def test_the_stacked_fit_is_the_weighted_sum_of_the_two_routes_fits(monkeypatch, mode):
    """``LEFT_OUT_STACK`` on the five-marker trot: each component is the blend of the plain route's fit
    (the harmonic route switched off) and the harmonic route's (``LEFT_OUT_HARMONICS = "always"``) at the
    recorded weights (one for the pose, or one per component); the blend's left-out score is no higher than
    either route's."""
    t, pts, x, acc, cov = _trot(2)
    # the default also through a 10 ms exposure: both parts fitted through it
    aperture = box_aperture(0.01) if mode == "pose" else None
    reg = pose.register_pose(pts, x, covariance=cov)

    def fit():
        return pose.fit_pose_trajectory(t, reg, x, PoseParams(), points=pts, aperture=aperture)

    monkeypatch.setattr(pose, "LEFT_OUT_STACK", mode)
    stacked = fit()
    monkeypatch.setattr(pose, "LEFT_OUT_STACK", False)
    monkeypatch.setattr(pose, "LEFT_OUT_HARMONICS", False)
    plain = fit()
    monkeypatch.setattr(pose, "LEFT_OUT_HARMONICS", "always")
    harmonic = fit()
    cv = stacked.smoothing_choice["cross_validation"]
    score, weights = cv["routes"]["stack"]
    assert 0 < min(weights) < 1 or 0 < max(weights) < 1          # a blend, not one route
    assert score <= min(cv["routes"]["plain"][0], cv["routes"]["harmonics"][0]) * (1 + 1e-9)
    assert cv["cross_validation_score"] == score and cv["stack_fundamental_hz"] > 0
    assert len(weights) == 6
    assert (len(set(weights)) == 1) == (mode == "pose")
    assert ("for the whole pose (minimising the left-out score" if mode == "pose" else
            "the harmonic fit's weight per component cx") in stacked.smoothing_choice["reason"]
    for s, p, h, w in zip(stacked.centre_splines + stacked.rotvec_splines, plain.centre_splines
                          + plain.rotvec_splines, harmonic.centre_splines + harmonic.rotvec_splines, weights):
        assert isinstance(s, BlendedSpline) and s.weights[1] == pytest.approx(w, abs=1e-4)
        assert s.parts[0].aperture is aperture and s.parts[1].aperture is aperture
        np.testing.assert_allclose(s.observed(t), (1 - s.weights[1]) * p.observed(t) + s.weights[1] * h.observed(t),
                                   rtol=1e-9, atol=1e-12)
        for d in range(3):
            np.testing.assert_allclose(s(t, d), (1 - s.weights[1]) * p(t, d) + s.weights[1] * h(t, d),
                                       rtol=1e-9, atol=1e-12)
    assert np.all(np.isfinite(stacked.point(t, np.zeros(3)).acceleration))


def test_the_weights_on_left_out_predictions_reach_the_brute_force_minimum_of_the_blends_own_score():
    """On the five-marker trot's left-out predictions of both routes: one weight for the pose minimises the
    blend's own (not linearised) left-out score as a fine grid of weights does; the per-component weights score
    no higher than either route."""
    t, pts, x, _, cov = _trot(2)
    reg = pose.register_pose(pts, x, covariance=cov)
    f0 = pose._record_fundamental(t, reg.centre)[0]
    base = np.full(6, 1e-9)
    routes = [pose._left_out_choice(t, reg, pts, x, base, pose.LEFT_OUT_DECADES, 3, None, "min", f)
              for f in (None, f0)]
    (_, _, plain, i_plain), (_, _, harmonic, i_harmonic) = routes
    firsts, seconds = plain.chosen(i_plain), harmonic.chosen(i_harmonic)
    w, score = pose.left_out_stacking_weights(plain, i_plain, harmonic, i_harmonic, common=True)
    assert np.all(w == w[0])
    grid = np.linspace(0.0, 1.0, 201)
    scores = [pose._stacked_score(plain, firsts, seconds, np.full(6, g)) for g in grid]
    assert score <= min(scores) * (1 + 1e-9)
    assert abs(w[0] - grid[int(np.argmin(scores))]) <= 0.01
    per_component, best = pose.left_out_stacking_weights(plain, i_plain, harmonic, i_harmonic)
    assert best <= min(plain.score(i_plain), harmonic.score(i_harmonic), score) * (1 + 1e-9)
    assert np.all((per_component >= 0) & (per_component <= 1))


def test_on_a_trot_whose_single_route_the_stride_test_refuses_the_blend_passes_and_is_nearer_the_truth():
    """Four markers on a trot under AR(1) 0.9 noise (test_stride_residual's): the lower-scoring route alone
    leaves the stride's harmonics in its residual and falls back to white-noise GCV, which takes the slow noise
    for motion; the blend (the default) passes the stride test, and its hidden point's acceleration is far
    nearer the truth."""
    from test_stride_residual import MODEL, _acc_error, _correlated_trot
    d = _correlated_trot(600)
    reg = pose.register_pose(d["markers"], MODEL)
    blend = pose.fit_pose_trajectory(d["t"], reg, MODEL, points=d["markers"], expected_fundamental_hz=1.7)
    choice = blend.smoothing_choice
    assert choice["method"] == "gcv_ar1" and "no stride harmonics at 1.7 Hz" in choice["reason"]
    assert "for the whole pose (minimising the left-out score" in choice["reason"]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(pose, "LEFT_OUT_STACK", False)
        single = pose.fit_pose_trajectory(d["t"], reg, MODEL, points=d["markers"], expected_fundamental_hz=1.7)
    assert single.smoothing_choice["method"] == "gcv" and "noise taken as white" in single.smoothing_choice["reason"]
    assert _acc_error(blend, d) < 0.25 * _acc_error(single, d)


@pytest.mark.parametrize("stack", ["pose", False])
def test_a_stacked_or_harmonic_choice_settled_on_one_pass_smooths_another(monkeypatch, stack):
    """A long record's other passes reuse the longest pass's settled choice: after the harmonic route alone the
    settled smoothing fits a second record of the same trot as white-noise fits with the stride's harmonics (the
    correlated-error GCV takes none); after a blend, the blend of both routes at their settled parameters."""
    monkeypatch.setattr(pose, "LEFT_OUT_STACK", stack)
    if stack is False:
        monkeypatch.setattr(pose, "LEFT_OUT_HARMONICS", "always")
    t, pts, x, _, cov = _trot(2)
    first = pose.fit_pose_trajectory(t, pose.register_pose(pts, x, covariance=cov), x, PoseParams(), points=pts)
    settled = pose.settle_pose_smoothing(first)
    assert settled.fundamental_hz is not None
    assert (settled.noise_correlation is None) == (settled.blend_weights is None) == (stack is False)
    t2, pts2, x2, _, cov2 = _trot(3)
    again = pose.fit_pose_trajectory(t2, pose.register_pose(pts2, x2, covariance=cov2), x2, PoseParams(),
                                     points=pts2, settled=settled)
    assert np.all(np.isfinite(again.point(t2, np.zeros(3)).acceleration))
    if stack:
        assert "blended with the harmonic fit's weight" in again.smoothing_choice["reason"]
        assert [s.weights[1] for s in again.centre_splines + again.rotvec_splines] == list(settled.blend_weights)
    else:
        assert [s.info["lam"] for s in again.centre_splines + again.rotvec_splines] == pytest.approx(
            list(settled.lam), rel=1e-12)
