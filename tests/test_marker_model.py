"""The marker model: the static shot's shape kept unless the moving frames' mean shape says it is off;
the share of frames with a marker left out of the pose as a quality check."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import quality
from horsemocap.params import AnalysisParams, ParamsError, PoseParams, RigidBodyParams
from horsemocap.rigid import (analyse_rigid_body, body_coordinates, choose_marker_model, mean_marker_shape,
                              saddle_in_body_versions)

TRUE = np.array([[-0.24, 0.0, 0.0], [0.0, 0.07, 0.01], [0.24, 0.0, 0.0], [-0.1, -0.15, 0.02]])


def _ride(n=300, noise=1e-3, rho=0.0, seed=0):
    rng = np.random.default_rng(seed)
    R = Rotation.from_rotvec(rng.normal(0, 0.2, (n, 3))).as_matrix()
    e = rng.normal(0, noise, (n, len(TRUE), 3))
    for k in range(1, n):                      # AR(1) over frames, same spread
        e[k] = rho * e[k - 1] + np.sqrt(1 - rho * rho) * e[k]
    return np.einsum("kij,mj->kmi", R, TRUE) + np.arange(n)[:, None, None] * [0.01, 0, 0] + e


def test_mean_shape_averages_the_frames_noise_and_keeps_the_static_shots_place():
    pts = _ride(noise=2e-3)
    start = TRUE + np.random.default_rng(5).normal(0, 5e-3, TRUE.shape)
    shape, body = mean_marker_shape(pts, start)
    fitted = body_coordinates(shape[None], TRUE)[0]
    assert np.abs(fitted - TRUE).max() < 1e-3                  # the shape: 2 mm per frame, 300 frames
    assert np.abs(shape.mean(0) - start.mean(0)).max() < 1e-9  # placed where the static shot is
    assert body.shape == pts.shape


def test_static_shot_within_a_frames_noise_is_kept_and_off_is_replaced():
    pts = _ride(noise=1e-3)
    # a static shot that is a frame like the others: kept, bit for bit (most such draws pass a 1 % test)
    kept = [choose_marker_model(pts, TRUE + np.random.default_rng(s).normal(0, 1e-3, TRUE.shape))
            for s in range(20)]
    assert sum(c.source == "static shot" for c in kept) >= 18
    first = next(c for c in kept if c.source == "static shot")
    assert np.isfinite(first.statistic) and np.isfinite(first.p_value)
    # one marker 12 mm off in the static shot: the mean shape is used, and it is right
    off = TRUE.copy()
    off[1, 2] += 0.012
    c = choose_marker_model(pts, off)
    assert c.source == "moving frames" and c.p_value < 0.01
    assert np.abs(body_coordinates(c.model[None], TRUE)[0] - TRUE).max() < 1e-3
    assert c.to_dict()["source"] == "moving frames" and "Hotelling" in c.reason


def test_correlated_noise_counts_fewer_independent_frames():
    white = choose_marker_model(_ride(rho=0.0, seed=3), TRUE)
    red = choose_marker_model(_ride(rho=0.8, seed=3), TRUE)
    assert red.effective_frames < 0.3 * white.effective_frames


def test_too_few_frames_keep_the_static_shot_and_say_why():
    c = choose_marker_model(_ride(n=5), TRUE)
    assert c.source == "static shot" and "too few" in c.reason
    assert c.model is not None and np.array_equal(c.model, TRUE)


def test_the_model_is_the_mean_shape_when_the_static_shot_is_off():
    t = np.arange(200) / 50.0
    pts = _ride(n=200, noise=5e-4, seed=7)
    saddle = np.array([0.05, -0.3, 0.0])
    static = np.vstack([TRUE, saddle])
    static[1, 2] += 0.015                     # the static shot's middle marker 15 mm off in depth
    params = RigidBodyParams(kinematics="pose_spline", pose=PoseParams(smoothing="none"))
    res = analyse_rigid_body(t, pts, static, params)
    assert res.model_choice.source == "moving frames"
    assert np.abs(body_coordinates(res.model[None], TRUE)[0] - TRUE).max() < 1e-3


def _periodic_ride(n=200, rate=50.0, noise=5e-4, seed=7):
    """Three markers turning and bobbing once a second while moving forward, with white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    R = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * t), [0, 1, 0])).as_matrix()
    pts = np.einsum("kij,mj->kmi", R, TRUE[:3]) + np.outer(4 * t, [1, 0, 0])[:, None]
    return t, pts + rng.normal(0, noise, pts.shape)


def test_static_marker_model_keeps_the_static_shot_and_reports_the_test():
    t, pts = _periodic_ride()
    static = np.vstack([TRUE[:3], [0.05, -0.3, 0.0]])
    static[1, 2] += 0.015
    pose = PoseParams(smoothing="none")
    auto = analyse_rigid_body(t, pts, static, RigidBodyParams(pose=pose), period_s=1.0)
    kept = analyse_rigid_body(t, pts, static, RigidBodyParams(marker_model="static", pose=pose), period_s=1.0)
    assert auto.model_choice.source == "moving frames"
    assert kept.model_choice.source == "static shot" and np.array_equal(kept.model, static[:3])
    assert "asked for" in kept.model_choice.reason and kept.model_choice.p_value < 0.01


def test_the_thesis_chain_uses_the_static_shot_whatever_the_pose_model():
    t, pts = _periodic_ride()
    static = np.vstack([TRUE[:3], [0.05, -0.3, 0.0]])
    static[1, 2] += 0.015                     # off: the pose registration takes the moving frames' mean shape
    res = analyse_rigid_body(t, pts, static, RigidBodyParams(kinematics="fits"), period_s=1.0)
    assert res.model_choice.source == "moving frames"
    assert np.allclose(res.saddle_body, saddle_in_body_versions(static[:3], static[3]))
    assert not np.allclose(res.saddle_body, saddle_in_body_versions(res.model, static[3]))


def test_marker_model_is_validated_and_the_thesis_preset_keeps_the_static_shot():
    with pytest.raises(ParamsError, match="marker_model"):
        AnalysisParams.from_dict({"rigid_body": {"marker_model": "mean"}})
    assert AnalysisParams.from_dict({"preset": "thesis"}).rigid_body.marker_model == "static"
    assert AnalysisParams().rigid_body.marker_model == "auto"


def test_left_out_check_levels():
    lo = np.zeros((200, 4), bool)
    assert quality.check_left_out_markers(lo, 50.0).level == "ok"
    lo[50:60, 3] = True                                          # 0.2 s: ok, named (from 1, as the plots)
    c = quality.check_left_out_markers(lo, 50.0)
    assert c.level == "ok" and c.figure == 5.0 and "marker 4: 10 frames" in c.message
    lo[100:140, 2] = True                                        # 0.8 s in one run: longer than the test sees
    c = quality.check_left_out_markers(lo, 50.0)
    assert c.level == "warning" and "marker 3 moved for longer than" in c.message
    lo[:120, 1] = True
    assert quality.check_left_out_markers(lo, 50.0).level == "unreliable"
    assert quality.check_left_out_markers(np.zeros((50, 3), bool), 50.0).level == "skipped"


def test_a_hidden_marker_does_not_move_the_saddle_with_the_mean_shape(monkeypatch):
    """With the static shot's shape off, the pose jumps when the markers seen change; the mean shape's does not."""
    from horsemocap import rigid
    t = np.arange(200) / 50.0
    rng = np.random.default_rng(11)
    R = Rotation.from_rotvec(rng.normal(0, 0.2, (200, 3))).as_matrix()
    move = np.arange(200)[:, None] * [0.01, 0, 0]
    pts = np.einsum("kij,mj->kmi", R, TRUE) + move[:, None] + rng.normal(0, 5e-4, (200, 4, 3))
    pts[60:120, 3] = np.nan                                   # the fourth marker hidden for 1.2 s
    saddle = np.array([0.05, -0.3, 0.0])
    truth = np.einsum("kij,j->ki", R, saddle) + move
    static = np.vstack([TRUE, saddle])
    static[1, 2] += 0.015
    params = RigidBodyParams(kinematics="pose_spline", pose=PoseParams(smoothing="none"))
    refined = analyse_rigid_body(t, pts, static, params)
    monkeypatch.setattr(rigid, "choose_marker_model", lambda p, m: rigid.ModelChoice(model=m, source="static shot",
                                                                                      reason="forced"))
    kept = analyse_rigid_body(t, pts, static, params)

    def jump(r):     # the saddle error's change between the frames with and without the fourth marker (m)
        e = r.saddle_position - truth
        return float(np.linalg.norm(np.median(e[60:120], 0) - np.median(np.r_[e[:60], e[120:]], 0)))
    assert refined.model_choice.source == "moving frames"
    assert jump(kept) > 3e-3 and jump(refined) < 0.2 * jump(kept)
