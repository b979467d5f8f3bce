"""A blend of the fits without and with the stride's harmonics settled once and reused: on a long recording's
other passes (horsemocap.pose.settle_pose_smoothing, fit_pose_trajectory's ``settled``) and on a long record's
windows (horsemocap.streaming), against exact ground truth."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from horsemocap import pose, streaming
from horsemocap.params import PoseParams
from horsemocap.splines import BlendedSpline
from horsemocap.threads import blas_single_threaded

RATE_HZ = 50.0
#: the markers' noise per axis (m), the depth three times the image directions
SIGMA = np.array([1e-3, 1e-3, 3e-3])
HIDDEN = np.array([0.0, -0.15, 0.0])
STRIDE_HZ = 1.5
EDGE = 10


@pytest.fixture(autouse=True)
def one_blas_thread():
    """As the kinematics command runs: the smoothing's small matrices with one BLAS thread."""
    with blas_single_threaded():
        yield


def _pose_path(t):
    """A trot whose stride phase wanders (the stride frequency within 2 % of 1.5 Hz over 14 s) and whose
    amplitude swells by 15 % over 25 s: not exactly periodic, as a ridden horse's."""
    wt = 2 * np.pi * STRIDE_HZ * t + 0.4 * np.sin(2 * np.pi * t / 14.0 + 0.3)
    gain = 1.0 + 0.15 * np.sin(2 * np.pi * t / 25.0 + 1.1)
    c = np.column_stack([3.0 * t + 0.02 * gain * np.sin(wt + 0.4),
                         1.2 + gain * (0.04 * np.sin(2 * wt + 2.0) + 0.01 * np.sin(3 * wt + 5.1)),
                         0.01 * gain * np.sin(wt + 5.1)])
    phi = np.column_stack([a * gain * np.sin((i + 1) * wt + p)
                           for i, (a, p) in enumerate(((0.04, 0.7), (0.02, 3.3), (0.03, 1.9)))])
    return c, phi


MODEL = np.array([[0.22, 0.01, 0.15], [-0.21, -0.02, 0.12], [0.05, 0.03, -0.18], [-0.18, 0.02, -0.12],
                  [0.12, -0.02, 0.03]])
MODEL = MODEL - MODEL.mean(0)


def _hidden(t):
    c, phi = _pose_path(t)
    return c + Rotation.from_rotvec(phi).apply(HIDDEN)


def _trot(frames: int, seed: int, start: int = 0, rho: float = 0.8) -> dict:
    """Frames ``start ..`` of the trot: five markers with AR(1) noise over frames (independent between
    markers) and the hidden point's exact acceleration (a central difference at 0.1 ms of the exact path)."""
    rng = np.random.default_rng(seed)
    t = (start + np.arange(frames)) / RATE_HZ
    c, phi = _pose_path(t)
    clean = c[:, None] + np.einsum("kij,mj->kmi", Rotation.from_rotvec(phi).as_matrix(), MODEL)
    white = rng.normal(0, 1, clean.shape) * np.sqrt(1 - rho ** 2)
    noisy = clean + lfilter([1.0], [1.0, -rho], white, axis=0) * SIGMA
    h = 1e-4
    acc = (_hidden(t + h) - 2 * _hidden(t) + _hidden(t - h)) / h ** 2
    return {"t": t, "markers": noisy, "acc": acc, "reg": pose.register_pose(noisy, MODEL)}


def _error(acc, truth) -> float:
    """rms of the acceleration's error relative to the true acceleration's, without the record's ends."""
    d = (acc - truth)[EDGE:-EDGE]
    return float(np.sqrt(np.mean(np.sum(d ** 2, 1)) / np.mean(np.sum(truth[EDGE:-EDGE] ** 2, 1))))


def _fit(rec, settled=None):
    return pose.fit_pose_trajectory(rec["t"], rec["reg"], MODEL, PoseParams(), points=rec["markers"],
                                    settled=settled)


@pytest.fixture(scope="module")
def longest():
    """The longest pass (400 frames) smoothed by the default choice: a blend of the two routes."""
    rec = _trot(400, seed=3)
    return rec, _fit(rec)


def test_the_longest_pass_is_a_blend(longest):
    _, tr = longest
    weights = [s.weights[1] for s in tr.centre_splines + tr.rotvec_splines]
    assert all(isinstance(s, BlendedSpline) for s in tr.centre_splines + tr.rotvec_splines)
    assert 0.0 < weights[0] < 1.0 and tr.smoothing_choice["method"] == "gcv_ar1"


def test_the_settled_blend_holds_both_routes_and_the_weight(longest):
    _, tr = longest
    settled = pose.settle_pose_smoothing(tr)
    for i, s in enumerate(tr.centre_splines + tr.rotvec_splines):
        plain, harmonic = s.parts
        assert settled.lam[i] == plain.info["lam"] and settled.harmonic_lam[i] == harmonic.info["lam"]
        assert settled.blend_weights[i] == s.weights[1]
        assert settled.harmonics[i] == max(harmonic.info.get("harmonic_indices") or [0])
    assert settled.noise_correlation == pytest.approx(tr.smoothing_choice["noise_correlation"])
    assert settled.fundamental_hz == pytest.approx(tr.smoothing_choice["cross_validation"]["stack_fundamental_hz"])
    assert "both fits made at these parameters and blended" in settled.choice["smoothing_reason"]


def test_the_settled_blend_on_the_same_data_is_the_longest_pass_own_fit(longest):
    """Refitted with its own settled choice, the longest pass gives its own fit: each plain part exactly (same
    parameter, same noise correlation), and the hidden point's acceleration differs from its own fit's by a
    small fraction of that fit's error against the truth (a rotation component's harmonic route may keep the
    first harmonics up to the settled count where the own fit kept those its noise test passed)."""
    rec, own = longest
    again = _fit(rec, pose.settle_pose_smoothing(own))
    for a, b in zip(own.centre_splines + own.rotvec_splines, again.centre_splines + again.rotvec_splines):
        assert isinstance(b, BlendedSpline) and b.weights == a.weights
        assert b.info["blended"]["settled"] is True
        np.testing.assert_allclose(b.parts[0](rec["t"], 2), a.parts[0](rec["t"], 2), rtol=1e-9, atol=1e-9)
    for a, b in zip(own.centre_splines, again.centre_splines):     # the centroid's harmonic routes: the same
        np.testing.assert_allclose(b(rec["t"], 2), a(rec["t"], 2), rtol=1e-7, atol=1e-7)
    acc_own = own.point(rec["t"], HIDDEN).acceleration
    acc_again = again.point(rec["t"], HIDDEN).acceleration
    difference = _error(acc_again, acc_own) * np.sqrt(np.mean(np.sum(acc_own[EDGE:-EDGE] ** 2, 1))
                                                       / np.mean(np.sum(rec["acc"][EDGE:-EDGE] ** 2, 1)))
    assert difference < 0.05 * _error(acc_own, rec["acc"])


def test_another_pass_gets_the_longest_pass_blend_not_white_gcv(longest):
    """A second pass of the same trot (200 frames, 40 s later, another noise draw): each component the blend
    of its two routes at the settled parameters and weight, the reason saying so; its hidden point's
    acceleration error against the truth no worse than 1.5 times the longest pass's own."""
    rec, own = longest
    settled = pose.settle_pose_smoothing(own)
    other = _trot(200, seed=7, start=2000)
    tr = _fit(other, settled)
    for i, s in enumerate(tr.centre_splines + tr.rotvec_splines):
        assert isinstance(s, BlendedSpline) and s.weights[1] == settled.blend_weights[i]
        assert s.parts[0].info["lam"] == settled.lam[i] and s.parts[1].info["lam"] == settled.harmonic_lam[i]
        assert s.parts[1].info["fundamental_hz"] == settled.fundamental_hz
    assert "nothing chosen again" in tr.smoothing_choice["reason"]
    assert "chosen again by white-noise GCV" not in tr.smoothing_choice["reason"]
    assert _error(tr.point(other["t"], HIDDEN).acceleration, other["acc"]) < 1.5 * _error(
        own.point(rec["t"], HIDDEN).acceleration, rec["acc"])


def test_a_choice_without_a_blend_settles_none():
    """Three markers (the correlated-error GCV, no left-out choice): no blend settled, the fields None."""
    rec = _trot(200, seed=3)
    three = pose.register_pose(rec["markers"][:, :3], MODEL[:3])
    tr = pose.fit_pose_trajectory(rec["t"], three, MODEL[:3], PoseParams(), points=rec["markers"][:, :3])
    settled = pose.settle_pose_smoothing(tr)
    assert settled.blend_weights is None and settled.harmonic_lam is None


@pytest.mark.parametrize("fields, match", [
    ({"harmonic_lam": (1e-6,) * 6}, "a blend needs both harmonic_lam and blend_weights"),
    ({"harmonic_lam": (1e-6,) * 6, "blend_weights": (1.5,) * 6}, r"blend_weights: expected 6 weights in \[0, 1\]"),
    ({"harmonic_lam": (1e-6,) * 5 + (None,), "blend_weights": (0.5,) * 6}, "six positive smoothing parameters"),
])
def test_a_half_or_broken_blend_is_refused(fields, match):
    with pytest.raises(ValueError, match=match):
        pose.SettledPoseSmoothing("gcv", 0.8, 1.5, (1e-6,) * 6, (2,) * 6, (False,) * 3, None, **fields)


def test_the_windows_of_a_long_record_carry_the_representative_blend():
    """A 1200-frame record in windows of 300 frames, the smoothing settled on its middle 400: every window
    blends its two routes at the settled parameters and weight (not white-noise GCV per window); over the
    representative frames the windows' hidden-point acceleration is within 1.25 times the error of the fit
    they were settled from, and over the record within 1.25 times that of the whole record fitted at once
    with its own choice."""
    rec = _trot(1200, seed=5)
    t, reg, pts = rec["t"], rec["reg"], rec["markers"]
    settled = streaming.settle_smoothing(t, reg, pts, MODEL, PoseParams(), frames=400, window=300)
    assert settled.blend is not None and 0.0 < settled.blend.blend_weights[0] < 1.0
    assert settled.lam == settled.blend.lam
    assert "every window fits both routes at those smoothing parameters" in settled.choice["reason"]
    assert "white-noise GCV with the stride's harmonics" not in settled.choice["reason"]
    lo, hi, _, _ = streaming.window_plan(t.size, settled.window, settled.margin)[1]
    window, _, why = streaming.window_fit(t, reg, pts, MODEL, settled, lo, hi, 1 / RATE_HZ)
    assert why is None and all(isinstance(s, BlendedSpline) and s.weights[1] == w for s, w in
                               zip(window.centre_splines + window.rotvec_splines, settled.blend.blend_weights))
    blocks = list(streaming.windowed_kinematics(t, reg, pts, MODEL, HIDDEN[None], PoseParams(), settled=settled))
    windows = np.concatenate([b.acceleration[:, 0] for b in blocks])
    a, b = streaming.representative_range(t.size, 400)
    stretch = {"t": t[a:b], "reg": streaming.slice_registration(reg, a, b), "markers": pts[a:b]}
    settled_on = _fit(stretch, settled.blend).point(t[a:b], HIDDEN).acceleration
    assert _error(windows[a:b], rec["acc"][a:b]) < 1.25 * _error(settled_on, rec["acc"][a:b])
    whole = _fit(rec).point(t, HIDDEN).acceleration
    assert _error(windows, rec["acc"]) < 1.25 * _error(whole, rec["acc"])


def test_kinematics_run_json_says_a_windowed_blend_whole():
    """``kinematics-run.json``'s ``windows`` holds a settled blend's harmonic route and weights beside the plain
    route's ``lam``; without a blend it holds neither."""
    from horsemocap.cli import windows_record

    blend = pose.SettledPoseSmoothing("gcv", 0.8, 1.5, (1e-5,) * 6, (2,) * 6, (False,) * 3,
                                      harmonic_lam=(1e-7,) * 6, blend_weights=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6))
    settled = streaming.SettledSmoothing(PoseParams(), blend.lam, 1.5, None, 40, {}, window=500, blend=blend)
    rec = windows_record(settled, np.arange(5000) + 7)
    assert rec["lam"] == [1e-5] * 6 and rec["harmonic_lam"] == [1e-7] * 6
    assert rec["blend_weights"] == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    assert rec["settled_on"] == [507, 4506] and rec["fundamental_hz"] == 1.5
    plain = windows_record(dataclasses.replace(settled, blend=None), np.arange(5000))
    assert "harmonic_lam" not in plain and "blend_weights" not in plain
