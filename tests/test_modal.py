"""The L-spline (notch) smoothing of ringing: :func:`horsemocap.splines.modal_smoothing`,
:func:`horsemocap.splines.estimate_modes` and ``smoothing="modal"`` of the pose trajectory."""
import numpy as np
import pytest

from horsemocap import pose, splines, synthetic
from horsemocap.splines import DampedMode


def _mode(t, f, decay, phase=0.0):
    return np.exp(-t / decay) * np.sin(2 * np.pi * f * t + phase)


def test_filter_annihilates_a_sampled_damped_sinusoid_and_kernel_a_quadratic_plus_mode():
    dt = 0.01
    t = np.arange(200) * dt
    mode = DampedMode(9.0, 0.4)
    a = splines.damped_mode_filter(mode, dt)
    y = 3 * _mode(t, 9.0, 0.4, 0.7)
    assert np.max(np.abs(np.convolve(y, a, "valid"))) < 1e-12
    k = splines.modal_difference_kernel([mode], dt)
    assert k.size == 6
    y2 = y + 0.5 - 2 * t + 4 * t ** 2
    assert np.max(np.abs(np.convolve(y2, k, "valid"))) < 1e-11
    # undamped: r = 1
    assert splines.damped_mode_filter(DampedMode(5.0, np.inf), dt)[2] == 1.0


def test_null_space_reproduced_exactly_with_a_gap():
    dt = 0.01
    t = np.arange(300) * dt
    modes = [DampedMode(10.0, 0.3), DampedMode(23.0, 1.5)]
    y = 1.0 + 0.3 * t - 0.8 * t ** 2 + 0.05 * _mode(t, 10.0, 0.3, 0.4) + 0.02 * _mode(t, 23.0, 1.5, 2.0)
    (s,) = splines.modal_smoothing(t, y[:, None], modes)
    assert np.max(np.abs(s(t) - y)) < 1e-10                   # |y| up to 5: exact to rounding
    keep = np.ones(t.size, bool)
    keep[140:143] = False                                     # a 3-frame gap
    (s,) = splines.modal_smoothing(t[keep], y[keep][:, None], modes)
    assert np.max(np.abs(s(t) - y)) < 1e-7                    # the gap's frames weigh 1e-9: 2e-8 measured
    assert s.info["method"] == "modal" and s.info["n"] == keep.sum()


def test_derivative_bias_of_the_quintic_interpolant_on_a_noise_free_sinusoid():
    # the derivatives of modal_smoothing come from the quintic interpolating spline of the smoothed samples
    for fs, f, tol in ((100.0, 10.0, 1e-3), (100.0, 25.0, 1.5e-2)):
        t = np.arange(400) / fs
        w = 2 * np.pi * f
        y = np.sin(w * t + 0.3)
        (s,) = splines.modal_smoothing(t, y[:, None], [DampedMode(f, np.inf)])
        inner = slice(20, -20)
        acc = -w * w * np.sin(w * t + 0.3)
        err = s(t, 2)[inner] - acc[inner]
        assert np.sqrt(np.mean(err ** 2)) / (w * w / np.sqrt(2)) < tol
        vel = w * np.cos(w * t + 0.3)
        assert np.sqrt(np.mean((s(t, 1) - vel)[inner] ** 2)) / (w / np.sqrt(2)) < tol


def test_white_noise_selects_no_mode_in_most_draws():
    t = np.arange(200) * 0.01
    found = [len(splines.estimate_modes(t, np.random.default_rng(seed).normal(size=(200, 6)))[0])
             for seed in range(5)]
    assert sum(n == 0 for n in found) >= 4, found


def test_known_mode_recovered():
    # six components sharing a 12 Hz mode (decay 0.5 s) from the first sample, white noise of 1
    rng = np.random.default_rng(1)
    t = np.arange(400) * 0.01
    Y = np.column_stack([3 * _mode(t, 12.0, 0.5, p) + 10 * t ** 2 + rng.normal(size=t.size)
                         for p in np.linspace(0, 3, 6)])
    modes, info = splines.estimate_modes(t, Y)
    assert len(modes) >= 1
    assert abs(modes[0].frequency_hz / 12.0 - 1) < 0.03
    assert 0.5 / 1.5 < modes[0].decay_s < 0.5 * 1.5
    assert info["tried"][0]["kept"]


def test_modal_needs_a_uniform_grid():
    t = np.r_[0.0, 0.01, 0.025, 0.03, np.arange(4, 20) * 0.01]
    with pytest.raises(ValueError, match="uniform grid"):
        splines.modal_smoothing(t, np.zeros((t.size, 1)), [])


def test_pose_modal_without_ringing_is_exactly_gcv():
    d = synthetic.lift_with_ringing(seed=0, ring_scale=0.0)
    reg = pose.register_pose(d["markers"], d["model"])
    gcv = pose.fit_pose_trajectory(d["t"], reg, d["model"], smoothing="gcv")
    modal = pose.fit_pose_trajectory(d["t"], reg, d["model"], smoothing="modal")
    assert modal.centre_splines[1].info["method"] != "modal"
    assert not any(tr["kept"] for tr in modal.centre_splines[1].info["mode_search"]["tried"])
    np.testing.assert_array_equal(modal.omega(d["t"]), gcv.omega(d["t"]))
    np.testing.assert_array_equal(modal.centre(d["t"], 2), gcv.centre(d["t"], 2))
    with pytest.raises(ValueError, match="modal"):
        pose.fit_pose_trajectory(d["t"], reg, d["model"], smoothing="modal", events=[2.0])
