"""Known-answer tests of the partial smoothing spline (stride harmonics, horsemocap.splines) and its
use in the pose trajectory (horsemocap.pose, ``harmonics``)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, splines, synthetic
from horsemocap.params import AnalysisParams, ParamsError, PoseParams


def _motion(t, f0):
    """Harmonics 1-3 of f0 plus a quadratic, with its second derivative."""
    w = 2 * np.pi * f0
    y = (0.02 * np.sin(w * t + 0.3) + 0.01 * np.cos(2 * w * t) + 0.004 * np.sin(3 * w * t + 1)
         + 0.1 * t + 0.05 * t ** 2)
    a = (-0.02 * w ** 2 * np.sin(w * t + 0.3) - 0.01 * (2 * w) ** 2 * np.cos(2 * w * t)
         - 0.004 * (3 * w) ** 2 * np.sin(3 * w * t + 1) + 0.1)
    return y, a


def test_harmonic_plus_quadratic_is_recovered_exactly_also_at_the_ends():
    """An exact harmonic + quadratic motion is in the partial spline's unpenalised part: its
    acceleration comes out exact in every frame, the first and last included (the plain
    spline's natural boundary conditions bias those)."""
    t = np.arange(60) / 30.0
    f0 = 1.7
    y, a = _motion(t, f0)
    s = splines.smoothing_spline(t, y, fundamental_hz=f0)
    assert s.info["harmonics"] >= 3
    np.testing.assert_allclose(s(t), y, atol=1e-12)
    np.testing.assert_allclose(s(t, 2), a, atol=1e-8 * np.abs(a).max())
    plain = splines.smoothing_spline(t, y)
    assert abs(plain(t[:1], 2)[0] - a[0]) > 1e3 * abs(s(t[:1], 2)[0] - a[0])


def test_harmonic_terms_derivatives_known_answer():
    h = splines.HarmonicTerms(2.0, np.array([1.0, 0.5]), np.array([0.0, -0.25]), t0=0.1)
    t = np.linspace(0, 1, 7)
    w = 2 * np.pi * 2.0
    u = t - 0.1
    np.testing.assert_allclose(h(t), np.cos(w * u) + 0.5 * np.cos(2 * w * u) - 0.25 * np.sin(2 * w * u))
    np.testing.assert_allclose(h(t, 1), -w * np.sin(w * u) - w * np.sin(2 * w * u) - 0.5 * w * np.cos(2 * w * u))
    np.testing.assert_allclose(h(t, 2), -w ** 2 * np.cos(w * u) - 2 * w ** 2 * np.cos(2 * w * u)
                               + w ** 2 * np.sin(2 * w * u), atol=1e-9)


def test_without_harmonics_the_partial_spline_is_the_plain_spline():
    rng = np.random.default_rng(2)
    t = np.arange(80) / 50.0
    y = np.sin(3 * t) + rng.normal(0, 0.01, t.size)
    plain = splines.smoothing_spline(t, y)
    part, _, info = splines._partial_quintic(t, y, np.ones(t.size), None, 1.0, [0])
    assert info["lam"] == pytest.approx(plain.info["lam"], rel=1e-6)
    np.testing.assert_allclose(part.derivative(2)(t), plain(t, 2), atol=1e-6 * np.abs(plain(t, 2)).max())


def test_noisy_periodic_record_keeps_its_harmonics():
    rng = np.random.default_rng(0)
    t = np.arange(60) / 30.0
    y, a = _motion(t, 1.7)
    yn = y + rng.normal(0, 3e-4, t.size)
    rms = np.sqrt(np.mean(a ** 2))
    part = splines.smoothing_spline(t, yn, fundamental_hz=1.7)
    plain = splines.smoothing_spline(t, yn)
    err = lambda s: np.sqrt(np.mean((s(t, 2) - a) ** 2)) / rms  # noqa: E731
    assert err(part) < 0.05 and err(plain) > 3 * err(part)


def test_cutoff_keeps_only_the_harmonics_the_plain_spline_passes():
    rng = np.random.default_rng(1)
    t = np.arange(90) / 30.0
    y = 0.02 * np.sin(2 * np.pi * 1.5 * t) + 0.0003 * np.sin(2 * np.pi * 9.0 * t) + rng.normal(0, 1e-3, t.size)
    s = splines.smoothing_spline(t, y, fundamental_hz=1.5, harmonic_cutoff=True)
    assert np.isfinite(s.info["cutoff_hz"])
    assert s.info["harmonics"] * 1.5 <= s.info["cutoff_hz"] + 1e-9


def test_fundamental_from_all_components_and_not_its_half():
    rng = np.random.default_rng(3)
    t = np.arange(50) / 30.0
    f0 = 1.62
    Y = np.column_stack([np.sin(2 * np.pi * f0 * t) + 0.3 * np.sin(4 * np.pi * f0 * t + 1),
                         0.5 * np.cos(2 * np.pi * 2 * f0 * t) + 0.2 * np.sin(2 * np.pi * 3 * f0 * t),
                         2 * t + np.sin(2 * np.pi * f0 * t + 2)]) + rng.normal(0, 0.01, (t.size, 3))
    f, gain = splines.estimate_fundamental(t, Y)
    assert f == pytest.approx(f0, rel=0.01) and gain < 0
    with pytest.raises(ValueError, match="too short"):
        splines.estimate_fundamental(t[:5], Y[:5], min_cycles=30)


def test_a_short_record_does_not_take_half_its_stride_frequency():
    """Regression: the pose components (centroid, rotation vector) of the virtual hard session
    sitting640_stirrup_30 (75 frames at 30 fps, stride 1.4 Hz: 3.5 strides), registered with the
    markers' covariances. With 1.5 cycles as the lowest frequency tried the estimate was 0.700 Hz."""
    from pathlib import Path

    data = np.load(Path(__file__).parent / "data" / "pose_components_sitting640_stirrup_30.npz")
    f0, _ = splines.estimate_fundamental(data["t"], data["Y"])
    assert f0 == pytest.approx(1.4, abs=0.02)
    half, _ = splines.estimate_fundamental(data["t"], data["Y"], min_cycles=1.5)
    assert half == pytest.approx(0.7, abs=0.02)      # what the earlier default found


def test_a_record_without_a_period_is_said_to_have_none():
    """The lift of the ringing fixture cut to 2 s: its best 'period' is the lowest frequency tried."""
    d = synthetic.lift_with_ringing(seed=0, duration_s=2.0)
    reg = pose.register_pose(d["markers"], d["model"])
    phi = Rotation.from_matrix(reg.rotation).as_rotvec()
    for cycles in (1.5, 2.0):
        with pytest.raises(ValueError, match="no period resolved"):
            splines.estimate_fundamental(d["t"], np.column_stack([reg.centre, phi]), min_cycles=cycles)


def test_bad_fundamental_and_smoothing_combinations_are_refused():
    t = np.arange(30) / 30.0
    with pytest.raises(ValueError, match="fundamental_hz"):
        splines.smoothing_spline(t, np.sin(t), fundamental_hz=-1.0)
    with pytest.raises(ValueError, match="fundamental_hz"):
        splines.smoothing_spline(t, np.sin(t), fundamental_hz=1.0, order=3)


def _periodic_rigid_motion(n=75, fps=30.0, f0=1.4):
    t = np.arange(n) / fps
    w = 2 * np.pi * f0
    phi = np.column_stack([0.05 * np.sin(w * t + 0.2), 0.03 * np.sin(w * t + 1.0) + 0.01 * np.sin(2 * w * t),
                           0.08 * np.sin(w * t + 2.0)])
    R = Rotation.from_rotvec(phi).as_matrix()
    c = np.column_stack([2.5 * t + 0.04 * np.sin(w * t), 0.02 * np.sin(2 * w * t) + 0.002 * np.sin(4 * w * t + 1),
                         0.015 * np.sin(w * t + 0.5)])
    model = np.array([[0.2, 0.0, 0.05], [-0.2, 0.02, 0.05], [0.0, 0.1, -0.08], [0.05, -0.05, 0.0]])
    model = model - model.mean(0)
    pts = np.einsum("kij,mj->kmi", R, model) + c[:, None]
    return t, pts, model, phi, c


@pytest.mark.parametrize("harmonics", ["auto", "all"])
def test_exact_periodic_rigid_motion_gives_exact_derivatives_at_the_ends(harmonics):
    """Rotation vector and centroid exactly harmonic: the pose trajectory's derivatives are exact in
    every frame, the first and last included (``R_ref`` is the mean rotation, so the fitted rotation
    vector is about it: compare omega and the centroid's acceleration)."""
    t, pts, model, phi, c = _periodic_rigid_motion()
    reg = pose.register_pose(pts, model)
    tr = pose.fit_pose_trajectory(t, reg, model, PoseParams(harmonics=harmonics), fundamental_hz=1.4)
    est = pose.fit_pose_trajectory(t, reg, model, PoseParams(harmonics=harmonics))
    w = 2 * np.pi * 1.4
    c2 = np.column_stack([-0.04 * w ** 2 * np.sin(w * t), -0.02 * (2 * w) ** 2 * np.sin(2 * w * t)
                          - 0.002 * (4 * w) ** 2 * np.sin(4 * w * t + 1), -0.015 * w ** 2 * np.sin(w * t + 0.5)])
    np.testing.assert_allclose(tr.centre(t, 2), c2, atol=1e-6 * np.abs(c2).max())
    # the fundamental estimated from the record: exact to the estimate's precision
    np.testing.assert_allclose(est.centre(t, 2), c2, atol=1e-3 * np.abs(c2).max())
    assert est.smoothing["cx"]["fundamental_hz"] == pytest.approx(1.4, rel=1e-5)
    w_ = 2 * np.pi * 1.4
    dphi = np.column_stack([0.05 * w_ * np.cos(w_ * t + 0.2),
                            0.03 * w_ * np.cos(w_ * t + 1.0) + 0.02 * w_ * np.cos(2 * w_ * t),
                            0.08 * w_ * np.cos(w_ * t + 2.0)])
    omega = pose.angular_velocity_from_rotvec(phi, dphi)      # the same for any reference rotation
    np.testing.assert_allclose(tr.omega(t), omega, atol=1e-4 * np.abs(omega).max())
    np.testing.assert_allclose(est.omega(t), omega, atol=1e-3 * np.abs(omega).max())


def test_non_periodic_ringing_record_keeps_plain_splines_where_harmonics_do_not_help():
    d = synthetic.lift_with_ringing(seed=0, duration_s=2.0)
    reg = pose.register_pose(d["markers"], d["model"])
    plain = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(harmonics="none"))
    auto = pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(harmonics="auto"))
    err = lambda tr: np.sqrt(np.mean(np.sum((tr.omega(d["t"]) - d["omega"]) ** 2, -1)))  # noqa: E731
    assert err(auto) < 1.2 * err(plain)
    with pytest.raises(ValueError, match="harmonics"):
        pose.fit_pose_trajectory(d["t"], reg, d["model"], PoseParams(harmonics="yes"))


def test_pose_harmonics_parameter_is_validated():
    assert AnalysisParams().rigid_body.pose.harmonics == "auto"
    AnalysisParams.from_dict({"pose_harmonics": "none"}).validate("test")
    with pytest.raises(ParamsError, match="pose_harmonics"):
        AnalysisParams.from_dict({"pose_harmonics": "sometimes"}).validate("test")


def test_spline_with_harmonics_is_stored_without_pickle():
    from horsemocap.store import decode_result, encode_result

    t = np.arange(40) / 30.0
    y, _ = _motion(t, 1.7)
    s = splines.smoothing_spline(t, y, fundamental_hz=1.7)
    arrays = {}
    tree = encode_result(s, arrays)
    back = decode_result(tree, arrays)
    np.testing.assert_allclose(back(t, 2), s(t, 2))


def test_long_record_uses_the_gram_route_and_stays_exact(monkeypatch):
    """A record longer than twice the spline basis (knots every few samples) goes through the
    Gram-matrix route of the partial spline, and the fundamental through the periodogram's peaks:
    a harmonic + quadratic motion still comes out exact."""
    t = np.arange(1500) / 30.0
    f0 = 1.3
    y, a = _motion(t, f0)
    s = splines.smoothing_spline(t, y, fundamental_hz=f0)
    np.testing.assert_allclose(s(t, 2), a, atol=1e-6 * np.abs(a).max())
    monkeypatch.setattr(splines, "MAX_GRID", 50)
    rng = np.random.default_rng(4)
    Y = np.column_stack([y, np.cos(2 * np.pi * 2 * f0 * t)]) + rng.normal(0, 1e-3, (t.size, 2))
    f, _ = splines.estimate_fundamental(t, Y)
    assert f == pytest.approx(f0, rel=1e-4)


def test_a_subset_of_harmonics_is_fitted_exactly():
    """Candidate sets may skip harmonics (a trot's pitch: the 2nd and 4th without the 1st); the
    unpenalised part then holds exactly those, the others zero."""
    t = np.arange(50) / 30.0
    w = 2 * np.pi * 1.6
    y = 0.01 * np.sin(2 * w * t + 0.4) + 0.002 * np.cos(4 * w * t) + 0.03 * t
    a = -0.01 * (2 * w) ** 2 * np.sin(2 * w * t + 0.4) - 0.002 * (4 * w) ** 2 * np.cos(4 * w * t)
    spl, harm, info = splines._partial_quintic(t, y, np.ones(t.size), None, 1.6, [(2, 4)])
    assert info["harmonic_indices"] == [2, 4] and info["harmonics"] == 2
    assert harm.cos[[0, 2]].tolist() == [0.0, 0.0] and harm.sin[[0, 2]].tolist() == [0.0, 0.0]
    np.testing.assert_allclose(harm(t, 2) + spl.derivative(2)(t), a, atol=1e-7 * np.abs(a).max())


def test_harmonics_smaller_than_the_noise_are_not_taken_whole():
    """A periodic error (the 3rd harmonic, 0.6 of the noise level given) is left to the penalised
    spline; the motion's 2nd harmonic (20 times the noise) is kept without the absent 1st."""
    rng = np.random.default_rng(5)
    t = np.arange(60) / 30.0
    w = 2 * np.pi * 1.5
    noise = 1e-3
    y = 0.02 * np.sin(2 * w * t) + 0.6 * noise * np.sin(3 * w * t + 0.7) + rng.normal(0, 0.3 * noise, t.size)
    s = splines.smoothing_spline(t, y, fundamental_hz=1.5, harmonic_noise=noise)
    assert s.info["harmonic_indices"] == [2]
    amp = s.info["harmonic_amplitudes"]
    assert amp[1] == pytest.approx(0.02, rel=0.05) and amp[2] == pytest.approx(0.6 * noise, rel=0.3)
    free = splines.smoothing_spline(t, y, fundamental_hz=1.5)
    assert 3 in free.info["harmonic_indices"]          # without the noise level the error is kept
    with pytest.raises(ValueError, match="harmonic_noise"):
        splines.smoothing_spline(t, y, fundamental_hz=1.5, harmonic_noise=-1.0)


def test_pose_noise_isotropic_known_answer():
    """Without the points the marker noise is isotropic (the registration's ``noise_m``): for k markers
    on a circle of radius r in the x-y plane, the rotation noise is sigma / (r sqrt(k)) about z and
    sqrt(2) times that about x and y; the centroid's sigma / sqrt(k)."""
    from dataclasses import replace

    k, r, sigma = 4, 0.1, 2e-3
    ang = np.arange(k) * 2 * np.pi / k
    model = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(k)])
    reg = replace(pose.register_pose(np.repeat(model[None], 5, 0), model), noise_m=sigma)
    got = pose.pose_noise(reg, None, model)
    base = sigma / (r * np.sqrt(k))
    np.testing.assert_allclose(got, [sigma / np.sqrt(k)] * 3 + [np.sqrt(2) * base, np.sqrt(2) * base, base],
                               rtol=1e-9)


def test_thin_triangle_periodic_error_is_not_taken_for_rotation():
    """A thin marker triangle (the herd's Horse 1: smallest height 48 mm) with a marker error that
    repeats with the stride (3rd harmonic, below the rotation noise the registration residual
    predicts): ``harmonics="auto"`` leaves it to the penalised spline; without the noise test it
    is kept whole and omega's error is larger."""
    rng = np.random.default_rng(0)
    fps, f0, n = 30.0, 1.6, 120
    t = np.arange(n) / fps
    w = 2 * np.pi * f0
    phi = np.column_stack([0.03 * np.sin(w * t), 0.02 * np.sin(w * t + 1), 0.08 * np.sin(w * t + 2)
                           + 0.015 * np.sin(2 * w * t)])
    R = Rotation.from_rotvec(phi).as_matrix()
    model = np.array([[0.25, 0.0, 0.0], [-0.25, 0.0, 0.0], [0.05, 0.048, 0.0]])
    c = np.column_stack([3.0 * t, 0.02 * np.sin(2 * w * t), 0.01 * np.sin(w * t)])
    pts = np.einsum("kij,mj->kmi", R, model) + c[:, None]
    pts = pts + rng.normal(0, 1e-3, pts.shape)
    pts[:, 0, 1] += 1.2e-3 * np.sin(3 * w * t + 0.5)       # a periodic detection error on one marker
    reg = pose.register_pose(pts, model)
    auto = pose.fit_pose_trajectory(t, reg, model, fundamental_hz=f0)
    old = pose.fit_pose_trajectory(t, reg, model, fundamental_hz=f0, rotation_noise_test=False)
    assert 3 not in auto.smoothing["phiz"]["harmonic_indices"]
    assert 3 in old.smoothing["phiz"]["harmonic_indices"]
    dphi = np.column_stack([0.03 * w * np.cos(w * t), 0.02 * w * np.cos(w * t + 1),
                            0.08 * w * np.cos(w * t + 2) + 0.03 * w * np.cos(2 * w * t)])
    omega = pose.angular_velocity_from_rotvec(phi, dphi)
    err = lambda tr: np.sqrt(np.mean((tr.omega(t)[:, 2] - omega[:, 2]) ** 2))  # noqa: E731
    assert err(auto) < 0.5 * err(old)           # measured 0.0065 against 0.0435 rad/s


def test_cached_spline_basis_gives_the_same_fit_as_a_fresh_one():
    """The basis of a record's times is cached (the six pose components share it): a fit through the
    cache equals one computed afresh, bit for bit, and the cached arrays cannot be changed."""
    rng = np.random.default_rng(7)
    t = np.arange(70) / 30.0
    y1, _ = _motion(t, 1.7)
    y2 = np.cos(3 * t) + rng.normal(0, 1e-3, t.size)
    splines.smoothing_spline(t, y1, fundamental_hz=1.7)              # fills the cache
    cached = splines.smoothing_spline(t, y2, fundamental_hz=1.7)
    cached_plain = splines.smoothing_spline(t, y2)
    splines._basis_cached.cache_clear()
    splines._gcv_basis_cached.cache_clear()
    fresh = splines.smoothing_spline(t, y2, fundamental_hz=1.7)
    splines._basis_cached.cache_clear()
    splines._gcv_basis_cached.cache_clear()
    fresh_plain = splines.smoothing_spline(t, y2)
    np.testing.assert_array_equal(cached(t, 2), fresh(t, 2))
    np.testing.assert_array_equal(cached_plain(t, 2), fresh_plain(t, 2))
    B = splines._basis(t.tobytes(), 3)[1]
    with pytest.raises(ValueError):
        B[0, 0] = 1.0
