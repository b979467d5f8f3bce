"""The smoothing's half-gain frequency: what a spline of a given lambda passes, and what the pose reports."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, splines
from horsemocap.params import PoseParams


@pytest.mark.parametrize("dt, lam", [(0.01, 1e-7), (1 / 120, 3e-9), (0.02, 1e-5)])
def test_spline_gain_is_one_half_at_its_half_gain_frequency(dt, lam):
    f = splines.half_gain_frequency(lam, dt)
    t = np.arange(800) * dt
    gains = []
    for freq in (0.5 * f, f, 1.5 * f):
        y = np.sin(2 * np.pi * freq * t)
        s = splines.smoothing_spline(t, y, lam=lam)
        inner = slice(150, -150)
        gains.append(np.std(s(t)[inner]) / np.std(y[inner]))
    assert gains[1] == pytest.approx(0.5, abs=0.01)
    assert gains[0] > 0.95 and gains[2] < 0.1


def _turning_cluster(n=400, rate=100.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    model = np.array([[0.1, 0.0, 0.0], [-0.05, 0.08, 0.0], [-0.05, -0.08, 0.02]])
    R = Rotation.from_rotvec(np.outer(np.sin(2 * np.pi * 0.7 * t), [0.2, 0.5, 0.1])).as_matrix()
    pts = np.einsum("kij,mj->kmi", R, model) + np.c_[0.3 * t, 0.1 * np.sin(3 * t), 0 * t][:, None]
    return t, model, pts + rng.normal(0, 5e-4, pts.shape)


def test_pose_reports_each_components_half_gain_frequency():
    t, model, pts = _turning_cluster()
    reg = pose.register_pose(pts, model)
    tr = pose.fit_pose_trajectory(t, reg, model, PoseParams(smoothing="auto", harmonics="none"), points=pts)
    hz = tr.smoothing_choice["half_gain_hz"]
    assert set(hz) == {"cx", "cy", "cz", "phix", "phiy", "phiz"}
    dt = t[1] - t[0]
    assert any(v is not None for v in hz.values())             # at least one component filtered uniformly
    for name, info in tr.smoothing.items():
        if info.get("method") == "adaptive":
            assert hz[name] is None
        else:
            y = np.sin(2 * np.pi * hz[name] * t)                # the reported frequency, passed at half gain
            s = splines.smoothing_spline(t, y, lam=info["lam"])
            inner = slice(100, -100)
            assert np.std(s(t)[inner]) / np.std(y[inner]) == pytest.approx(0.5, abs=0.03)
    given = pose.fit_pose_trajectory(t, reg, model, PoseParams(smoothing="gcv", harmonics="none"),
                                     lam=[1 / (dt * (2 * np.pi * 5.0) ** 6)] * 6)
    assert all(v == pytest.approx(5.0, rel=1e-3) for v in given.half_gain_hz.values())


def test_common_smoothing_of_one_series_is_its_own_gcv_choice():
    rng = np.random.default_rng(1)
    t = np.arange(300) / 100.0
    y = np.sin(2 * np.pi * 1.3 * t) + rng.normal(0, 0.05, t.size)
    own = splines.smoothing_spline(t, y).info["lam"]
    assert splines.common_smoothing(t, y[:, None])["lam"] == pytest.approx(own, rel=0.02)
    ar1 = splines.smoothing_spline(t, y, noise_correlation=0.5).info["lam"]
    assert splines.common_smoothing(t, y[:, None], noise_correlation=0.5)["lam"] == pytest.approx(ar1, rel=0.02)


def test_common_smoothing_does_not_depend_on_units_and_weighs_columns_by_their_noise():
    rng = np.random.default_rng(2)
    t = np.arange(400) / 100.0
    signal = np.column_stack([np.sin(2 * np.pi * t), np.sin(2 * np.pi * 3 * t)])
    Y = signal + rng.normal(0, 1, signal.shape) * [0.02, 0.02]
    base = splines.common_smoothing(t, Y, scales=[0.02, 0.02])["lam"]
    scaled = splines.common_smoothing(t, Y * [1000.0, 1.0], scales=[20.0, 0.02])["lam"]
    assert scaled == pytest.approx(base, rel=1e-6)
    # a column scaled up a thousandfold without its scale dominates the pooled criterion
    alone = splines.smoothing_spline(t, Y[:, 0] * 1000).info["lam"]
    dominated = splines.common_smoothing(t, Y * [1000.0, 1.0])["lam"]
    assert dominated == pytest.approx(alone, rel=0.05)
    with pytest.raises(ValueError, match="scales"):
        splines.common_smoothing(t, Y, scales=[1.0, -1.0])
