"""The saddle vertical acceleration's uncertainty parts (horsemocap.uncertainty)."""
import numpy as np

from horsemocap.splines import smoothing_spline
from horsemocap.uncertainty import (smoothed_acceleration_noise, spline_gain,
                                    unresolved_harmonics_acceleration)


def test_gain_is_half_at_the_half_gain_frequency():
    dt = 0.02
    lam = 1 / (dt * (2 * np.pi * 4.0) ** 6)
    assert np.isclose(spline_gain(4.0, lam, dt), 0.5)
    assert spline_gain(0.0, lam, dt) == 1.0


def test_acceleration_noise_matches_white_noise_through_the_spline():
    """The filter formula against the spline's own second derivative of white noise, away from the ends."""
    rng = np.random.default_rng(1)
    dt, n, sigma = 0.02, 400, 1e-3
    lam = 1 / (dt * (2 * np.pi * 4.0) ** 6)
    t = np.arange(n) * dt
    acc = [smoothing_spline(t, rng.normal(0, sigma, n), lam=lam)(t, 2)[60:-60] for _ in range(20)]
    measured = float(np.sqrt(np.mean(np.square(acc))))
    predicted = smoothed_acceleration_noise(sigma, lam, dt, n)
    assert abs(predicted / measured - 1) < 0.15


def test_unresolved_harmonic_is_covered():
    """A harmonic the smoothing did not keep: the estimate is at least the acceleration it removed."""
    dt, f0 = 0.04, 1.4
    t = np.arange(100) * dt
    y = 2e-3 * np.sin(2 * np.pi * f0 * t) + 3e-4 * np.sin(2 * np.pi * 6 * f0 * t)
    lam = 1 / (dt * (2 * np.pi * 5.0) ** 6)
    missing = (1 - spline_gain(6 * f0, lam, dt)) * (2 * np.pi * 6 * f0) ** 2 * 3e-4 / np.sqrt(2)
    est = unresolved_harmonics_acceleration(t, y, 1e-5, lam, f0, [1, 2, 3, 4, 5])
    assert est >= missing
    assert est < 1.5 * missing
    # every harmonic kept: nothing unresolved
    assert unresolved_harmonics_acceleration(t, y, 1e-5, lam, f0, list(range(1, 11))) == 0.0
