"""The default pose smoothing ("auto", horsemocap.pose.choose_smoothing): gcv with the stride harmonics on
a periodic record (bit-identical to asking for it), adaptive on a non-periodic one; what ran and why in
each component's info; explicit choices keep their meaning."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, synthetic
from horsemocap.params import AnalysisParams, PoseParams

MODEL = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15], [-0.20, -0.02, -0.15]])


def _periodic_record(f0=1.5, fps=100.0, seconds=4.0, noise=3e-4, seed=0):
    """A box trotting in place: centroid and rotation vector sums of two harmonics of ``f0``."""
    t = np.arange(int(fps * seconds)) / fps
    w = 2 * np.pi * f0
    c = np.stack([0.02 * np.sin(w * t), 1.0 + 0.03 * np.sin(2 * w * t + 0.3), 0.01 * np.cos(w * t)], -1)
    phi = np.stack([0.05 * np.sin(w * t + 1.0), 0.03 * np.sin(2 * w * t), 0.02 * np.cos(w * t + 0.5)], -1)
    R = Rotation.from_rotvec(phi).as_matrix()
    mk = np.einsum("kij,mj->kmi", R, MODEL) + c[:, None]
    return t, mk + np.random.default_rng(seed).normal(0, noise, mk.shape)


def _coefficients(tr):
    return [np.asarray(s.spline.c) for s in tr.centre_splines + tr.rotvec_splines]


def test_choose_smoothing_known_answers():
    assert pose.choose_smoothing(None, None) == ("adaptive", "no fundamental found: a non-periodic record")
    assert pose.choose_smoothing(1.5, None) == ("gcv", "periodic record: fundamental 1.5 Hz")
    assert pose.choose_smoothing(1.5, [2.0])[0] == "adaptive"
    assert pose.choose_smoothing(None, None, order=3)[0] == "gcv"


def test_periodic_record_gets_gcv_with_harmonics_bit_identical():
    t, mk = _periodic_record()
    reg = pose.register_pose(mk, MODEL)
    auto = pose.fit_pose_trajectory(t, reg, MODEL)
    gcv = pose.fit_pose_trajectory(t, reg, MODEL, PoseParams(smoothing="gcv"))
    for a, b in zip(_coefficients(auto), _coefficients(gcv)):
        assert np.array_equal(a, b)
    info = auto.smoothing["cy"]
    assert info["smoothing_method"] == "gcv"
    assert info["fundamental_hz"] == pytest.approx(1.5, rel=0.01)
    assert info["smoothing_reason"].startswith("periodic record: fundamental 1.5")
    assert "smoothing_method" not in gcv.smoothing["cy"]          # an explicit choice is not re-labelled


def test_non_periodic_record_gets_adaptive_and_explicit_gcv_stays_gcv():
    d = synthetic.lift_with_ringing(seed=0)
    reg = pose.register_pose(d["markers"], d["model"])
    auto = pose.fit_pose_trajectory(d["t"], reg, d["model"])
    adaptive = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(smoothing="adaptive"))
    gcv = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(smoothing="gcv"))
    for a, b in zip(_coefficients(auto), _coefficients(adaptive)):
        assert np.array_equal(a, b)
    assert {v["smoothing_method"] for v in auto.smoothing.values()} == {"adaptive"}
    assert auto.smoothing["cx"]["smoothing_reason"] == "no fundamental found: a non-periodic record"
    assert {v["method"] for v in gcv.smoothing.values()} == {"gcv"}
    assert not np.array_equal(_coefficients(auto)[1], _coefficients(gcv)[1])


def test_auto_with_events_is_the_adaptive_spline_with_them():
    d = synthetic.lift_with_ringing(duration_s=2.0, ring_start_s=1.2, seed=0)
    reg = pose.register_pose(d["markers"], d["model"])
    auto = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(events=[1.2]))
    adaptive = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(smoothing="adaptive", events=[1.2]))
    for a, b in zip(_coefficients(auto), _coefficients(adaptive)):
        assert np.array_equal(a, b)
    assert auto.smoothing["cy"]["events"] == [1.2]


def test_params_default_is_auto_and_bad_choices_are_named():
    assert AnalysisParams().rigid_body.pose.smoothing == "auto"
    with pytest.raises(Exception, match="pose_smoothing"):
        AnalysisParams.from_dict({"pose_smoothing": "best"}).validate("test")


def test_auto_keeps_gcv_for_given_smoothing_parameters_and_says_why_with_events():
    from horsemocap.pose import choose_smoothing

    assert choose_smoothing(None, None, 5, lam_given=True)[0] == "gcv"
    method, reason = choose_smoothing(1.5, [2.8], 5)
    assert method == "adaptive" and "1.5 Hz found, not used" in reason
    assert choose_smoothing(None, [2.8], 5)[1] == "1 known change point(s), fitted without harmonics"
