"""The partial spline (the stride's harmonics unpenalised) under AR(1) noise: its correlated-error criterion
(horsemocap.splines) and the pose smoothing's refit with it where the correlated choice took the stride's motion
for noise (horsemocap.pose), against exact ground truth."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, splines

from test_correlated_noise import _ar1

F = 1.5
T = np.arange(150) / 50.0


def _stride(t):
    """A stride's two harmonics (m) and their exact second derivative."""
    y = 0.02 * np.sin(2 * np.pi * F * t) + 0.005 * np.sin(4 * np.pi * F * t + 1)
    acc = (-(2 * np.pi * F) ** 2 * 0.02 * np.sin(2 * np.pi * F * t)
           - (4 * np.pi * F) ** 2 * 0.005 * np.sin(4 * np.pi * F * t + 1))
    return y, acc


def _error(s, acc) -> float:
    return float(np.sqrt(np.mean((s(T, 2) - acc) ** 2) / np.mean(acc ** 2)))


def _dense_traces(x, w, lam, f, K, rho, aperture=None, m=3):
    """``tr(H)`` and ``tr(H C)`` of the partial spline's hat matrix on the weighted samples, built densely: the
    penalised least squares of ``sqrt(w) y`` on the basis and the harmonics (through ``aperture``)."""
    _, B, P, _, _ = splines._basis(np.ascontiguousarray(x, float).tobytes(), m, aperture)
    A = np.sqrt(w)[:, None] * np.hstack([B, splines._harmonic_subset(x, f, K, float(x[0]), aperture)])
    penalty = np.zeros((A.shape[1],) * 2)
    penalty[:B.shape[1], :B.shape[1]] = (P + P.T) / 2
    H = A @ np.linalg.solve(A.T @ A + lam * penalty, A.T)
    C = rho ** np.abs(np.subtract.outer(np.arange(x.size), np.arange(x.size)))
    return np.trace(H), float(np.sum(H * C))


@pytest.mark.parametrize("weighted, aperture", [(False, None), (True, None), (True, 0.01)])
def test_the_correlated_trace_is_the_dense_hat_matrix_times_the_ar1_correlation(weighted, aperture):
    """tr(H C), computed from the projected basis' singular vectors, against the dense hat matrix of the same
    smoothing parameter and harmonics (the weighted samples' hat, as the white-noise criterion's tr(H)), with
    unequal weights and through a camera's exposure."""
    from horsemocap.aperture import box_aperture

    rng = np.random.default_rng(1)
    x = np.arange(300) / 50.0
    w = rng.uniform(0.3, 3.0, x.size) if weighted else np.ones(x.size)
    ap = None if aperture is None else box_aperture(aperture)
    y = np.sin(2 * np.pi * 1.3 * x) + 0.01 * rng.normal(size=x.size)
    rho = 0.7
    for lam in (1e-7, 1e-5):
        _, _, info = splines._partial_quintic(x, y, w, lam, 1.3, [(1, 2)], correlation=rho, aperture=ap)
        edf, edf_correlated = _dense_traces(x, w, lam, 1.3, (1, 2), rho, ap)
        assert info["edf_correlated"] == pytest.approx(edf_correlated, rel=1e-8)
        assert info["edf"] == pytest.approx(edf, rel=1e-8)
        assert info["noise_correlation"] == rho


def test_a_vanishing_correlation_is_the_white_noise_partial_spline():
    y, _ = _stride(T)
    noisy = y + _ar1(np.random.default_rng(0), T.size, 0.8, 0.002)
    white = splines.smoothing_spline(T, noisy, fundamental_hz=F)
    almost = splines.smoothing_spline(T, noisy, fundamental_hz=F, noise_correlation=1e-12)
    assert almost.info["lam"] == pytest.approx(white.info["lam"], rel=1e-6)
    assert almost.info["harmonic_indices"] == white.info["harmonic_indices"]
    assert np.allclose(almost(T, 2), white(T, 2), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_correlated_partial_spline_keeps_the_stride_that_both_other_criteria_lose(seed):
    """A stride under AR(1) 0.8 noise: the white-noise partial spline follows the slow noise (GCV takes it for
    motion), the correlated-error plain spline flattens the stride (it takes the motion for noise); the partial
    spline under the correlated criterion keeps the harmonics and smooths the rest."""
    y, acc = _stride(T)
    noisy = y + _ar1(np.random.default_rng(seed), T.size, 0.8, 0.0012)
    white = splines.smoothing_spline(T, noisy, fundamental_hz=F)
    plain = splines.smoothing_spline(T, noisy, noise_correlation=0.8)
    both = splines.smoothing_spline(T, noisy, fundamental_hz=F, noise_correlation=0.8)
    assert both.info["harmonics"] >= 1
    assert _error(both, acc) < 0.6 * _error(white, acc)
    assert _error(both, acc) < 0.5 * _error(plain, acc)


def test_the_correlated_unbiased_risk_takes_harmonics_too_and_reml_does_not():
    y, _ = _stride(T)
    s = splines.smoothing_spline(T, y + 1e-3 * np.sin(40 * T), method="noise", noise=1e-3, noise_correlation=0.5,
                                 fundamental_hz=F)
    assert s.info["noise_correlation"] == 0.5 and s.info["harmonics"] >= 1
    with pytest.raises(ValueError, match="'reml' is the quintic spline without harmonics"):
        splines.smoothing_spline(T, y, method="reml", noise_correlation=0.5, fundamental_hz=F)


def _short_trot(seed, n=70):
    """``n`` frames (30 fps; 70 by default) of a trot-like oscillation of a three-marker body with AR(1) 0.8 marker noise (4 mm):
    the times, the points, the model, a hidden point and its exact acceleration. Only cx, cy, phix and phiy
    move with the stride; cz is a steady walk forward and phiz still (both a quadratic: the penalty's null
    space)."""
    rng = np.random.default_rng(seed)
    model = np.array([[0.0, 0, 0], [0.25, 0, 0], [0.05, 0.2, 0.03]])
    hidden = np.array([0.1, 0.1, -0.3])
    f = 1.4

    def motion(t):
        R = Rotation.from_rotvec(np.column_stack([0.05 * np.sin(2 * np.pi * f * t), 0.03 * np.sin(4 * np.pi * f * t),
                                                  0 * t])).as_matrix()
        c = np.column_stack([0.02 * np.sin(4 * np.pi * f * t), 0.03 * np.sin(4 * np.pi * f * t + 1), 4 * t])
        return R, c

    t = np.arange(n) / 30.0
    R, c = motion(t)
    clean = c[:, None] + np.einsum("kij,mj->kmi", R, model - model.mean(0)) + model.mean(0)
    fine = np.linspace(t[0], t[-1], 100 * (n - 1) + 1)
    Rf, cf = motion(fine)
    path = cf + np.einsum("kij,j->ki", Rf, hidden - model.mean(0))
    h = fine[1] - fine[0]
    acc = np.gradient(np.gradient(path, h, axis=0), h, axis=0)[::100]
    return t, clean + _ar1(rng, clean.shape, 0.8, 0.004), model, hidden, acc


@pytest.mark.parametrize("seed", range(4))
def test_a_correlated_choice_that_flattens_the_stride_is_fitted_again_with_its_harmonics(monkeypatch, seed):
    """The correlated-error GCV smooths the short trot's components down to a quadratic (their whole motion
    taken for noise). The pose is fitted again under the same AR(1) noise with the stride's harmonics
    unpenalised: the reason says so, the components left flat are the two without stride motion, and the hidden
    point's acceleration is nearer the truth than the white-noise fit that used to replace the choice."""
    t, pts, model, hidden, acc = _short_trot(seed)
    reg = pose.register_pose(pts, model)
    tr = pose.fit_pose_trajectory(t, reg, model, points=pts)
    choice = tr.smoothing_choice
    assert choice["method"] == "gcv_ar1" and choice["correlated_harmonics"]
    assert "took a component's whole motion for noise" in choice["reason"]
    assert "with the stride's harmonics unpenalised (correlated-error GCV of the partial spline)" in choice["reason"]
    flat = [c for c, info in tr.smoothing.items()
            if not info.get("harmonics") and info["edf"] < pose.NULL_SPACE_EDF + pose.NULL_SPACE_TOLERANCE]
    assert set(flat) <= {"cz", "phiz"}
    monkeypatch.setattr(pose, "CORRELATED_HARMONIC_REFIT", False)
    white = pose.fit_pose_trajectory(t, reg, model, points=pts)
    assert white.smoothing_choice["method"] == "gcv" and "noise taken as white" in white.smoothing_choice["reason"]

    def error(trajectory):
        a = trajectory.point(t, hidden).acceleration[3:-3]
        return float(np.sqrt(np.mean(np.sum((a - acc[3:-3]) ** 2, 1)) / np.mean(np.sum(acc[3:-3] ** 2, 1))))
    assert error(tr) < 0.75 * error(white)


def test_the_refit_keeps_its_correlation_when_settled_for_other_records():
    """A long recording's other passes (or a long record's windows) reuse the refit's choice: the stride's
    harmonics with the same AR(1) correlation, nothing chosen again."""
    t, pts, model, _, _ = _short_trot(0)
    tr = pose.fit_pose_trajectory(t, pose.register_pose(pts, model), model, points=pts)
    settled = pose.settle_pose_smoothing(tr)
    assert settled.method == "gcv" and settled.fundamental_hz is not None
    assert settled.noise_correlation == pytest.approx(tr.smoothing_choice["noise_correlation"])
    again = pose.fit_pose_trajectory(t, pose.register_pose(pts, model), model, points=pts, settled=settled)
    for c, info in again.smoothing.items():
        assert info["lam"] == tr.smoothing[c]["lam"]
        assert info["fundamental_hz"] == pytest.approx(settled.fundamental_hz)
        # the spline's own record of the criterion it ran (not the choice copied onto every component)
        assert "edf_correlated" in info or (info["harmonics"] == 0 and "edf_correlated" not in tr.smoothing[c])


def test_a_long_record_in_windows_fits_every_window_under_the_refits_correlation():
    """A record smoothed in windows whose choice is the correlated refit: each window chooses its own smoothing
    parameters under the same AR(1) correlation with the stride's harmonics, and says so."""
    from horsemocap import pose_windows

    t, pts, model, _, _ = _short_trot(0, n=420)
    windowed = pose_windows.windowed_pose_trajectory(t, pose.register_pose(pts, model), model, points=pts,
                                                     window=140, frames=70)
    choice = windowed.smoothing_choice
    assert choice["method"] == "gcv_ar1" and choice.get("correlated_harmonics")
    assert "each window chose its own smoothing parameters under that correlation" in choice["reason"]
    rho = [piece.trajectory.centre_splines[0].info.get("noise_correlation") for piece in windowed.pieces]
    assert rho == [choice["noise_correlation"]] * len(windowed.pieces)
