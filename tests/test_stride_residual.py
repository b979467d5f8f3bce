"""The stride-harmonics test on a smoothed pose's residual (rigid.stride_harmonics_left) and its use."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats
from scipy.signal import lfilter

from horsemocap import rigid


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
        p_all.append(rigid.stride_harmonics_left(_trajectory(t, noise, np.zeros_like(noise)), 1.25))
    p_all = np.concatenate(p_all)
    assert np.all(np.isfinite(p_all))
    # 1200 independent tests at the level: more false alarms than this has a chance below 1e-3 if calibrated
    most = stats.binom.isf(1e-3, p_all.size, rigid.STRIDE_RESIDUAL_LEVEL)
    assert np.sum(p_all < rigid.STRIDE_RESIDUAL_LEVEL) <= most
    assert np.mean(p_all < 0.05) < 0.15                                 # roughly calibrated at a usual level


def test_stride_motion_smoothed_away_is_found_in_the_residual():
    """A second harmonic of the stride (what a heavy smoothing flattens), its rms twice the noise's: found."""
    rng = np.random.default_rng(8)
    t = np.arange(100) / 50.0
    noise = lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3, (6, t.size)), axis=1)
    motion = 2 * np.std(noise) * np.sqrt(2) * np.sin(2 * np.pi * 2 * 1.67 * t + 0.3)
    p = rigid.stride_harmonics_left(_trajectory(t, noise + motion, np.zeros_like(noise)), 1.67)
    assert np.all(p < rigid.STRIDE_RESIDUAL_LEVEL)
    p_followed = rigid.stride_harmonics_left(_trajectory(t, noise + motion, np.tile(motion, (6, 1))), 1.67)
    assert np.all(p_followed > rigid.STRIDE_RESIDUAL_LEVEL)


def test_a_gap_is_never_bridged_by_the_prewhitening():
    """Frames without a pose inside the record: the lag-1 pairs are consecutive frames only (the F test by hand)."""
    rng = np.random.default_rng(9)
    t = np.arange(120) / 50.0
    data = lfilter([1.0], [1.0, -0.8], rng.normal(0, 1e-3, (6, t.size)), axis=1)
    traj = _trajectory(t, data, np.zeros_like(data))
    traj.registration.rotation[50:70] = np.nan                      # 0.4 s without a pose
    p = rigid.stride_harmonics_left(traj, 1.25)
    keep = np.ones(t.size, bool)
    keep[50:70] = False
    pairs = keep[1:] & keep[:-1]
    rate = 1.0 / np.median(np.diff(t))
    orders = np.arange(1, int(rigid.STRIDE_RESIDUAL_MAX_FRACTION * rate // 1.25) + 1)
    phase = 2 * np.pi * 1.25 * np.outer(t, orders)
    X = np.column_stack([np.cos(phase), np.sin(phase)])
    for i in range(6):
        y = np.where(keep, data[i] - data[i][keep].mean(), 0.0)
        rho = np.sum((y[1:] * y[:-1])[pairs]) / np.sum(y * y)
        yw, Xw = (y[1:] - rho * y[:-1])[pairs], (X[1:] - rho * X[:-1])[pairs]
        rss1 = np.sum((yw - Xw @ np.linalg.lstsq(Xw, yw, rcond=None)[0]) ** 2)
        q, dof = Xw.shape[1], yw.size - Xw.shape[1] - 1
        assert p[i] == pytest.approx(stats.f.sf(((np.sum(yw ** 2) - rss1) / q) / (rss1 / dof), q, dof), rel=1e-9)


def _white_if_lost(monkeypatch, p_values, choice={"method": "gcv_ar1", "noise_correlation": 0.6}, period_s=0.8):
    """rigid._white_if_stride_lost on a stand-in trajectory, the test's p-values and the refit given."""
    asked = {}

    def refit(t, registration, model, params, **kw):
        asked.update(params=params, **kw)
        spline = SimpleNamespace(info={"fundamental_hz": 1.25})
        return SimpleNamespace(centre_splines=[spline], rotvec_splines=[SimpleNamespace(info={})])

    monkeypatch.setattr(rigid, "stride_harmonics_left", lambda traj, f0: np.asarray(p_values, float))
    monkeypatch.setattr(rigid, "fit_pose_trajectory", refit)
    traj = SimpleNamespace(smoothing_choice=choice)
    out = rigid._white_if_stride_lost(traj, None, None, None, rigid.RigidBodyParams(), None, period_s)
    return traj, out, asked


def test_white_noise_refit_only_when_the_stride_is_left_in_the_residual(monkeypatch):
    level = rigid.STRIDE_RESIDUAL_LEVEL
    traj, out, asked = _white_if_lost(monkeypatch, [0.5, 0.3, np.nan, 0.2, level / 10, 0.9])
    assert out is not traj and asked["params"].smoothing == "gcv" and asked["expected_fundamental_hz"] == 1.25
    reason = out.rotvec_splines[0].info["smoothing_reason"]
    assert "phiy" in reason and "noise taken as white" in reason and "AR(1) 0.60" in reason
    assert out.centre_splines[0].info["smoothing_method"] == "gcv"
    for p, choice, period in [([0.5, 0.3, 0.2, 0.2, level, 0.9], None, 0.8),          # at the level: kept
                              ([level / 10] * 6, {"method": "gcv"}, 0.8),             # not the correlated GCV
                              ([level / 10] * 6, None, None),                         # no period: no test
                              ([np.nan] * 6, None, 0.8)]:                             # no component testable
        choice = {"method": "gcv_ar1"} if choice is None else choice
        traj, out, asked = _white_if_lost(monkeypatch, p, choice, period)
        assert out is traj and not asked
