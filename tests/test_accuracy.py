"""Accuracy metrics: matching, RMSE, and the rig variants of notebook 14."""
from dataclasses import fields

import numpy as np
import pytest

from horsemocap.accuracy import (match_points, offset_and_motion, rmse_axes, rmse_pct_of_rms, scaled_rig,
                                 wide_baseline_rig)
from horsemocap.camera import Camera, Rig
from horsemocap.pipeline import Analysis
from horsemocap.steps import MotionFrameResult, SyncResult, TriangulateResult


def _rig():
    K = [[700.0, 0, 320], [0, 700.0, 240], [0, 0, 1]]
    return Rig((Camera("left", (640, 480), K),
                Camera("middle", (640, 480), K, translation=[-0.25, 0, 0]),
                Camera("right", (640, 480), K, translation=[-0.45, 0, 0])))


def test_match_points_finds_the_permutation_and_distances():
    true = np.array([[0.0, 0], [10, 0], [0, 10]])
    det = true[[2, 0, 1]] + np.array([[0.1, 0], [0, 0.2], [0, 0]])
    pairs, d = match_points(det, true)
    assert sorted(map(tuple, pairs)) == [(0, 2), (1, 0), (2, 1)]
    np.testing.assert_allclose(sorted(d), [0, 0.1, 0.2], atol=1e-12)


def test_match_points_ignores_missing():
    true = np.array([[0.0, 0], [np.nan, np.nan], [5, 5]])
    det = np.array([[5.0, 5.5], [np.nan, np.nan]])
    pairs, d = match_points(det, true)
    assert pairs.tolist() == [[0, 2]] and d.tolist() == [0.5]


def test_rmse_pct_of_rms_known_answers():
    true = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 5.0]])            # rms of |x|: 5
    assert rmse_pct_of_rms(true, true) == 0.0
    assert rmse_pct_of_rms(true + [0.0, 0.0, 1.0], true) == pytest.approx(20.0)
    est = true.copy()
    est[1] = np.nan                                                  # a frame without a pose: left out
    assert rmse_pct_of_rms(est + [0.5, 0.0, 0.0], true) == pytest.approx(10.0)
    with pytest.raises(ValueError, match="same shape"):
        rmse_pct_of_rms(true[:1], true)


def test_rmse_axes():
    est = np.zeros((4, 2, 3))
    true = np.zeros((4, 2, 3))
    true[..., 2] = 2.0
    true[0, 0] = np.nan  # skipped
    np.testing.assert_allclose(rmse_axes(est, true), [0, 0, 2])


def test_scaled_rig_keeps_the_angles():
    rig = _rig()
    big = scaled_rig(rig, 3.0)
    X = np.array([[0.3, -0.2, 7.5], [1.0, 0.4, 8.0]])
    for c, cb in zip(rig, big):
        np.testing.assert_allclose(c.pixels_to_normalized(c.project(X)), cb.pixels_to_normalized(cb.project(X)), atol=1e-9)
    assert big["left"].size == (1920, 1440)


@pytest.mark.parametrize("baseline", [0.5, 1.5])
def test_wide_baseline_rig_looks_at_the_target(baseline):
    wide = wide_baseline_rig(_rig(), baseline, target_depth_m=7.5)
    target = np.array([0.0, 0.0, 7.5])
    for i, cam in enumerate(wide.cameras):
        np.testing.assert_allclose(cam.center, [i * baseline, 0, 0], atol=1e-12)
        np.testing.assert_allclose(cam.project(target), cam.principal_point, atol=1e-9)


def test_analysed_truth_rows_and_frame():
    from types import SimpleNamespace

    from horsemocap.accuracy import analysed_truth
    from horsemocap.camera import rotation_matrix
    from horsemocap.frames import MotionFrame

    axes = rotation_matrix([0.1, -0.2, 0.3])
    mf = MotionFrame(axes=axes, origin=np.zeros(3), period_frames=18.0, marker=0, n_periods=2,
                     gravity_estimated=axes[1], gravity_correction_deg=0.0)
    n = 10
    rng = np.random.default_rng(0)
    truth = SimpleNamespace(ref_frames=np.arange(30, 40), **{k: rng.normal(size=(n, 3, 3)) for k in
                            ("marker_pos", "marker_vel", "marker_acc")},
                            **{k: rng.normal(size=(n, 3)) for k in
                               ("saddle_pos", "saddle_vel", "saddle_acc", "omega", "alpha")})
    session = SimpleNamespace(reference_camera="left")
    unset = lambda cls, **given: cls(**{**{f.name: None for f in fields(cls)}, **given})  # noqa: E731
    analysis = Analysis(session, None, sync=unset(SyncResult, offsets={"left": 8}),
                        triangulate=unset(TriangulateResult, segment=(24, 34)),
                        motion_frame=unset(MotionFrameResult, frame=mf))
    d = analysed_truth(analysis, truth)
    np.testing.assert_array_equal(d["frames"], np.arange(32, 42))
    assert d["known"].tolist() == [True] * 8 + [False] * 2
    np.testing.assert_allclose(d["saddle_acc"][:8], truth.saddle_acc[2:] @ axes.T)
    np.testing.assert_allclose(d["marker_pos"][:8], truth.marker_pos[2:] @ axes.T)
    assert np.all(np.isnan(d["omega"][8:]))


def test_offset_and_motion_split_the_rmse():
    rng = np.random.default_rng(3)
    true = rng.normal(size=(40, 3, 3))
    shift = np.array([0.004, -0.002, 0.01])
    noise = rng.normal(scale=[0.001, 0.0005, 0.003], size=true.shape)
    est = true + shift + noise
    est[5, 1] = np.nan                                  # a missing sample is left out, not counted
    offset, motion = offset_and_motion(est, true)
    d = (est - true).reshape(-1, 3)
    d = d[np.all(np.isfinite(d), axis=1)]
    np.testing.assert_allclose(offset, d.mean(axis=0))
    np.testing.assert_allclose(offset ** 2 + motion ** 2, rmse_axes(est, true) ** 2)
    np.testing.assert_allclose(offset, shift, atol=4e-4)
    # a pure shift is all offset, no motion error
    off2, mot2 = offset_and_motion(true + shift, true)
    np.testing.assert_allclose(off2, shift, atol=1e-12)
    np.testing.assert_allclose(mot2, 0, atol=1e-12)


def test_calibration_draw_with_few_views():
    """One calibration set of 12 views through calibrate_rig and the exact projections of the truth."""
    from horsemocap.accuracy import calibration_draws
    from horsemocap.data import data_samples_dir
    from horsemocap.virtuallab import load_truth

    truth = load_truth(data_samples_dir() / "horse2_canter")
    (row,) = calibration_draws(truth, [7], n_views=12)
    assert row["seed"] == 7 and row["n_views"] == 12
    assert set(row["intrinsic_error"]) == {"left", "middle", "right"}
    assert set(row["baseline_error_pct"]) == {"middle", "right"}
    np.testing.assert_allclose(row["offset_m"] ** 2 + row["motion_rmse_m"] ** 2, row["rmse_m"] ** 2)
    # the calibration's own 3-sigma bounds hold its intrinsic errors
    for cam, err in row["intrinsic_error"].items():
        assert np.all(np.abs(err) < row["sigma3"][cam]), (cam, err, row["sigma3"][cam])
    # exact projections: what is left after the constant offset is a fraction of a millimetre in x, y
    assert np.all(row["motion_rmse_m"][:2] < 1e-3), row["motion_rmse_m"]
