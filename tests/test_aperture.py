"""The camera's temporal aperture in the smoothing: known motions observed through a box or two fields."""
from __future__ import annotations

import numpy as np
import pytest

from horsemocap import pose, splines
from horsemocap.aperture import Aperture, box_aperture, camera_aperture, mean_aperture, session_aperture
from horsemocap.params import PoseParams

FPS = 25.0
F0 = 1.4                                  # a trot's stride frequency
AMPLITUDES = {1: 8e-3, 2: 15e-3, 4: 1.6e-3, 6: 0.45e-3}     # harmonics of a saddle's height (m)


def _motion(t, derivative=0):
    """The true height and its derivatives: a sum of stride harmonics."""
    out = np.zeros_like(t)
    for k, a in AMPLITUDES.items():
        w = 2 * np.pi * k * F0
        out += a * w ** derivative * np.sin(w * t + 0.3 * k + derivative * np.pi / 2)
    return out


def _observed(t, aperture):
    """What each frame observes of the motion: exactly, harmonic by harmonic, times the aperture's gain."""
    out = np.zeros_like(t)
    for k, a in AMPLITUDES.items():
        w = 2 * np.pi * k * F0
        out += a * np.abs(aperture.gain(k * F0)) * np.sin(w * t + 0.3 * k + np.angle(aperture.gain(k * F0)))
    return out


def _rel(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def test_box_and_fields_gains_are_the_known_filters():
    """The quadrature's gains against the exact filters (Gauss nodes: within 1e-6 up to 8.4 Hz)."""
    f = np.array([1.4, 8.4])
    np.testing.assert_allclose(box_aperture(0.02).gain(f).real, np.sinc(f * 0.02), atol=1e-6)
    both = camera_aperture(FPS, 0.02, interlaced=True).gain(f)
    np.testing.assert_allclose(both.real, np.cos(np.pi * f * 0.02) * np.sinc(f * 0.02), atol=1e-6)
    np.testing.assert_allclose(both.imag, 0, atol=1e-12)
    fields_only = camera_aperture(FPS, None, interlaced=True)
    np.testing.assert_allclose(fields_only.gain(f).real, np.cos(np.pi * f * 0.02), atol=1e-12)


def test_the_quadrature_is_exact_for_a_quintic_on_each_half_of_the_box():
    """Each box is split at the frame's instant: a polynomial of degree 5 on each side (a quintic spline with
    a knot there) is averaged exactly."""
    a = box_aperture(0.03)

    def piece(u):
        return np.where(u < 0, 1 + 2 * u + 3 * u ** 5, 1 - u ** 4 + 7 * u ** 5)

    h = 0.015
    exact = ((h - h ** 2 - h ** 6 / 2) + (h - h ** 5 / 5 + 7 * h ** 6 / 6)) / (2 * h)
    assert abs(a.average(piece, np.zeros(1))[0] - exact) < 1e-14


@pytest.mark.parametrize("aperture", [box_aperture(0.02), camera_aperture(FPS, 0.02, interlaced=True)],
                         ids=["box 20 ms", "two fields 20 ms apart"])
def test_a_harmonic_motion_seen_through_the_aperture_is_recovered_with_its_second_derivative(aperture):
    t = np.arange(75) / FPS
    y = _observed(t, aperture)
    inner = slice(3, -3)
    fit = splines.smoothing_spline(t, y, fundamental_hz=F0, aperture=aperture)
    assert fit.info["harmonic_indices"][-1] >= 6
    assert _rel(fit(t)[inner], _motion(t)[inner]) < 1e-6
    assert _rel(fit(t, 2)[inner], _motion(t, 2)[inner]) < 1e-6
    np.testing.assert_allclose(fit.observed(t), y, atol=1e-9)
    # the same samples taken for the motion at their instants: the acceleration is the blurred one
    plain = splines.smoothing_spline(t, y, fundamental_hz=F0)
    blur = 1 - np.abs(aperture.gain(6 * F0))
    assert _rel(plain(t, 2)[inner], _motion(t, 2)[inner]) > 0.3 * blur


def test_a_noisy_motion_through_two_fields_loses_less_acceleration_with_the_aperture():
    """With noise (the plain spline's GCV chooses the smoothing) the aperture model removes the fields'
    low-pass: the acceleration's rms error is smaller over ten draws."""
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    t = np.arange(75) / FPS
    rng = np.random.default_rng(3)
    errors = {True: [], False: []}
    for _ in range(10):
        y = _observed(t, aperture) + rng.normal(0, 5e-5, t.size)
        for use in (True, False):
            fit = splines.smoothing_spline(t, y, fundamental_hz=F0, aperture=aperture if use else None)
            errors[use].append(_rel(fit(t, 2)[3:-3], _motion(t, 2)[3:-3]))
    assert np.median(errors[True]) < 0.8 * np.median(errors[False])


def test_without_an_aperture_nothing_changes():
    t = np.arange(60) / FPS
    y = _motion(t) + np.random.default_rng(0).normal(0, 1e-4, t.size)
    a = splines.smoothing_spline(t, y, fundamental_hz=F0)
    b = splines.smoothing_spline(t, y, fundamental_hz=F0, aperture=None)
    np.testing.assert_array_equal(a(t, 2), b(t, 2))
    assert session_aperture(FPS, [{}, {}, {}]) is None
    assert session_aperture(FPS, [{"rolling_shutter_s": 0.02}]) is None


def test_the_pose_trajectory_through_the_aperture_recovers_the_motion():
    """A body moving up and down with the stride harmonics, each frame's markers the mean over the aperture:
    the pose trajectory fitted through it has the true vertical acceleration; taken at the instants, not."""
    aperture = camera_aperture(FPS, 0.02, interlaced=True)
    t = np.arange(75) / FPS
    model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.1, 0.05, 0.2]])
    height = _observed(t, aperture)
    pts = model[None] + np.stack([np.zeros_like(t), height, np.zeros_like(t)], -1)[:, None]
    reg = pose.register_pose(pts, model)
    params = PoseParams(smoothing="gcv", partial_frames=False)
    inner = slice(3, -3)
    fitted = pose.fit_pose_trajectory(t, reg, model, params, fundamental_hz=F0, aperture=aperture)
    acc = fitted.points(t, model).acceleration[:, 0, 1]
    assert _rel(acc[inner], _motion(t, 2)[inner]) < 1e-3
    instants = pose.fit_pose_trajectory(t, reg, model, params, fundamental_hz=F0)
    assert _rel(instants.points(t, model).acceleration[inner, 0, 1], _motion(t, 2)[inner]) > 0.05


def test_bad_apertures_are_refused_by_name():
    with pytest.raises(ValueError, match="exposure_s"):
        camera_aperture(FPS, -0.01)
    with pytest.raises(ValueError, match="weights summing to 1"):
        Aperture((0.0, 0.01), (0.5, 0.6))
    with pytest.raises(ValueError, match="aperture"):
        splines.smoothing_spline(np.arange(20.0), np.arange(20.0), order=3, aperture=box_aperture(0.5))


def test_cameras_with_different_apertures_average_them():
    a = mean_aperture([box_aperture(0.02), camera_aperture(FPS, 0.02, interlaced=True), None])
    f = 8.4
    expected = (np.sinc(f * 0.02) + np.cos(np.pi * f * 0.02) * np.sinc(f * 0.02) + 1) / 3
    assert abs(a.gain(f).real - expected) < 1e-6
