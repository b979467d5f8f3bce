"""The stride-harmonics test on a smoothed pose's residual (rigid.stride_harmonics_left) and its use."""
from types import SimpleNamespace

import numpy as np
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
