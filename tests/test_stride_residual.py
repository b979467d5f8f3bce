"""The stride-harmonics test on a smoothed pose's residual (rigid.stride_harmonics_left) and its use."""
from types import SimpleNamespace

import numpy as np
import pytest
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
    assert np.mean(p_all < rigid.STRIDE_RESIDUAL_LEVEL) < 0.005        # 1200 tests
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
    from scipy import stats
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
