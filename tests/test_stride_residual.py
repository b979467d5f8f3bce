"""The stride-harmonics test on a smoothed pose's residual (pose.stride_harmonics_left) and its use: the
correlated-error smoothing taken again as white noise where it took the stride's motion for noise."""
import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats
from scipy.signal import lfilter

from horsemocap import pose, streaming
from horsemocap.cli import main
from horsemocap.params import PoseParams

from test_streaming import HIDDEN, MODEL, _write, trot


def _trajectory(t, data, fitted):
    """A stand-in for a PoseTrajectory: ``data`` (6, n) the per-frame pose, ``fitted`` (6, n) the splines' values."""
    splines = [(lambda tt, v=v: np.interp(tt, t, v)) for v in fitted]
    reg = SimpleNamespace(rotation=np.tile(np.eye(3), (t.size, 1, 1)), centre=data[:3].T)
    return SimpleNamespace(t=t, registration=reg, rotvec_data=data[3:].T,
                           centre_splines=splines[:3], rotvec_splines=splines[3:])


def test_correlated_noise_alone_is_not_taken_for_stride_motion():
    """AR(1) 0.8 noise over 100 frames (two and a half strides) left whole in the residual: false alarms stay rare."""
    rng = np.random.default_rng(7)
    t = np.arange(100) / 50.0
    p_all = []
    for _ in range(200):
        noise = lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3, (6, t.size)), axis=1)
        p_all.append(pose.stride_harmonics_left(_trajectory(t, noise, np.zeros_like(noise)), 1.25))
    p_all = np.concatenate(p_all)
    assert np.all(np.isfinite(p_all))
    # 1200 independent tests at the level: more false alarms than this has a chance below 1e-3 if calibrated
    most = stats.binom.isf(1e-3, p_all.size, pose.STRIDE_RESIDUAL_LEVEL)
    assert np.sum(p_all < pose.STRIDE_RESIDUAL_LEVEL) <= most
    assert np.mean(p_all < 0.05) < 0.15                                 # roughly calibrated at a usual level


def test_stride_motion_smoothed_away_is_found_in_the_residual():
    """A second harmonic of the stride (what a heavy smoothing flattens), its rms twice the noise's: found."""
    rng = np.random.default_rng(8)
    t = np.arange(100) / 50.0
    noise = lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3, (6, t.size)), axis=1)
    motion = 2 * np.std(noise) * np.sqrt(2) * np.sin(2 * np.pi * 2 * 1.67 * t + 0.3)
    p = pose.stride_harmonics_left(_trajectory(t, noise + motion, np.zeros_like(noise)), 1.67)
    assert np.all(p < pose.STRIDE_RESIDUAL_LEVEL)
    p_followed = pose.stride_harmonics_left(_trajectory(t, noise + motion, np.tile(motion, (6, 1))), 1.67)
    assert np.all(p_followed > pose.STRIDE_RESIDUAL_LEVEL)


def test_a_gap_is_never_bridged_by_the_prewhitening():
    """Frames without a pose inside the record: the lag-1 pairs are consecutive frames only (the F test by hand)."""
    rng = np.random.default_rng(9)
    t = np.arange(120) / 50.0
    data = lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3, (6, t.size)), axis=1)
    traj = _trajectory(t, data, np.zeros_like(data))
    traj.registration.rotation[50:70] = np.nan                      # 0.4 s without a pose
    p = pose.stride_harmonics_left(traj, 1.25)
    keep = np.ones(t.size, bool)
    keep[50:70] = False
    pairs = keep[1:] & keep[:-1]
    rate = 1.0 / np.median(np.diff(t))
    orders = np.arange(1, int(pose.STRIDE_RESIDUAL_MAX_FRACTION * rate // 1.25) + 1)
    phase = 2 * np.pi * 1.25 * np.outer(t, orders)
    X = np.column_stack([np.cos(phase), np.sin(phase)])
    for i in range(6):
        y = np.where(keep, data[i] - data[i][keep].mean(), 0.0)
        rho = np.sum((y[1:] * y[:-1])[pairs]) / np.sum(y * y)
        yw, Xw = (y[1:] - rho * y[:-1])[pairs], (X[1:] - rho * X[:-1])[pairs]
        rss1 = np.sum((yw - Xw @ np.linalg.lstsq(Xw, yw, rcond=None)[0]) ** 2)
        q, dof = Xw.shape[1], yw.size - Xw.shape[1] - 1
        assert p[i] == pytest.approx(stats.f.sf(((np.sum(yw ** 2) - rss1) / q) / (rss1 / dof), q, dof), rel=1e-9)


def _correlated_trot(n, rho=0.9, sigma=0.002, seed=1):
    """A trot (:func:`test_streaming.trot`, its third stride harmonic 8 mm in height) under AR(1) marker noise."""
    d = trot(n, noise_m=0.0)
    rng = np.random.default_rng(seed)
    white = rng.normal(0, sigma * np.sqrt(1 - rho ** 2), d["markers"].shape)
    return {**d, "markers": d["markers"] + lfilter([1.0], [1.0, -rho], white, axis=0)}


@pytest.fixture(scope="module")
def trot_fit():
    """The correlated trot, its registration and its fit given the stride frequency as the rigid-body step
    gives it (another estimator's); made once: each takes seconds."""
    d = _correlated_trot(600)
    reg = pose.register_pose(d["markers"], MODEL)
    with pytest.MonkeyPatch.context() as patch:
        # one left-out route, which this trot's test refuses (the blend of both passes it: test_left_out_stack.py)
        patch.setattr(pose, "LEFT_OUT_STACK", False)
        return d, reg, pose.fit_pose_trajectory(d["t"], reg, MODEL, points=d["markers"],
                                                expected_fundamental_hz=1.7)


def _acc_error(tr, d):
    acc = tr.point(d["t"], HIDDEN).acceleration
    return float(np.sqrt(np.mean(np.sum((acc - d["hidden_acc"]) ** 2, 1)) / np.mean(np.sum(d["hidden_acc"] ** 2, 1))))


def test_stride_left_by_the_correlated_choice_is_smoothed_again_as_white(trot_fit):
    """The stride frequency from another estimator (the rigid-body step's motion frame) is tested; the
    correlated-error GCV flattened the trot's harmonics, the white-noise fit keeps them, nearer the truth."""
    d, reg, tr = trot_fit
    rho = pose.significant_noise_correlation(d["markers"], reg)
    assert rho > pose.NOISE_CORRELATION_THRESHOLD
    choice = tr.smoothing_choice
    assert choice["method"] == "gcv" and "noise_correlation" not in choice
    assert "at 1.7 Hz (the stride period of the motion-frame step)" in choice["reason"]
    assert "took periodic motion for noise" in choice["reason"]
    assert tr.smoothing["cx"]["fundamental_hz"] == pytest.approx(1.7, rel=0.01)
    correlated = pose.SettledPoseSmoothing("gcv", min(rho, 0.99), None, (None,) * 6, (0,) * 6, (False,) * 3)
    kept = pose.fit_pose_trajectory(d["t"], reg, MODEL, points=d["markers"], settled=correlated)
    assert np.all(pose.stride_harmonics_left(kept, 1.7)[[1]] < pose.STRIDE_RESIDUAL_LEVEL)
    assert _acc_error(tr, d) < 0.85 * _acc_error(kept, d)


def _choice_with_p_values(monkeypatch, p_values, t, pts, reg, **kw):
    # the test's p-values in place of the F tests on the smoothed components' residuals
    monkeypatch.setattr(pose, "_stride_p_values", lambda *args: np.asarray(p_values, float))
    return pose.fit_pose_trajectory(t, reg, MODEL, points=pts, **kw).smoothing_choice


def test_the_correlated_choice_is_kept_and_says_so_unless_the_test_finds_the_stride(monkeypatch, trot_fit):
    d, reg, _ = trot_fit
    t, pts = d["t"], d["markers"]
    level = pose.STRIDE_RESIDUAL_LEVEL
    kept = _choice_with_p_values(monkeypatch, [0.5, 0.3, np.nan, 0.2, level, 0.9], t, pts, reg,
                                 expected_fundamental_hz=1.7)
    assert kept["method"] == "gcv_ar1" and "no stride harmonics at 1.7 Hz" in kept["reason"]
    assert "smallest p = 0.0001 in phiy" in kept["reason"]
    short = _choice_with_p_values(monkeypatch, [np.nan] * 6, t, pts, reg, expected_fundamental_hz=1.7)
    assert short["method"] == "gcv_ar1" and "too short to test" in short["reason"]
    found = _choice_with_p_values(monkeypatch, [0.5, 0.3, np.nan, level / 10, 0.2, 0.9], t, pts, reg,
                                  fundamental_hz=1.7)
    assert found["method"] == "gcv" and "residual of phix" in found["reason"] and "the given fundamental" in found["reason"]


def test_without_a_stride_frequency_from_another_estimator_nothing_is_tested(monkeypatch, trot_fit):
    """The kinematics command has no stride frequency but the record's own, found in the data tested: the
    correlated choice is kept untested, and the reason says so."""
    d, reg, _ = trot_fit
    monkeypatch.setattr(pose, "stride_harmonics_left", lambda *a: pytest.fail("tested without a stride frequency"))
    choice = pose.fit_pose_trajectory(d["t"], reg, MODEL, points=d["markers"]).smoothing_choice
    assert choice["method"] == "gcv_ar1"
    assert "not tested for the stride's harmonics: no stride frequency given or found by another" in choice["reason"]


def test_settled_passes_and_windows_take_the_choice_made_once(monkeypatch, trot_fit):
    """The choice settled on one record (a ride's longest pass, a long record's middle) is taken by the
    records that reuse it (the other passes, every window) as it is: none is tested again."""
    d, reg, first = trot_fit
    settled = pose.settle_pose_smoothing(first)
    assert settled.method == "gcv" and settled.noise_correlation is None and settled.fundamental_hz is not None
    window = streaming.settle_smoothing(d["t"], reg, d["markers"], MODEL, PoseParams(), window=300)
    assert window.choice["method"] == "gcv_ar1" and "not tested for the stride" in window.choice["reason"]
    calls = []
    monkeypatch.setattr(pose, "stride_harmonics_left", lambda *a: calls.append(a) or np.zeros(6))
    second = _correlated_trot(400, seed=2)
    reg2 = pose.register_pose(second["markers"], MODEL)
    again = pose.fit_pose_trajectory(second["t"], reg2, MODEL, points=second["markers"], settled=settled)
    blocks = list(streaming.windowed_kinematics(d["t"], reg, d["markers"], MODEL, HIDDEN[None], PoseParams(),
                                                settled=window, window=300))
    assert not calls and len(blocks) > 1
    assert again.smoothing_choice["method"] == "gcv"


def test_kinematics_run_record_says_what_was_tested(tmp_path, capsys, trot_fit):
    d = trot_fit[0]
    names = ["m1", "m2", "m3", "m4"]
    _write(tmp_path / "traj.csv", d["t"], names, d["markers"])
    _write(tmp_path / "static.csv", [0.0], names + ["hidden"], np.vstack([MODEL, HIDDEN])[None])
    out = tmp_path / "out"
    assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(out)]) in (0, 3)
    ran = json.loads((out / "kinematics-run.json").read_text())["smoothing_ran"]
    assert ran["method"] == "gcv_ar1" and "not tested for the stride's harmonics" in ran["reason"]
    assert "not tested for the stride's harmonics" in capsys.readouterr().err
