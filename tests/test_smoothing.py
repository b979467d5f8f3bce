"""Tests of horsemocap.smoothing against MATLAB's documented smooth() rules."""
import numpy as np
import pytest

from horsemocap import smoothing as sm


def tricube(d):
    d = np.abs(d) / np.max(np.abs(d))
    return (1 - d**3) ** 3


def direct_fit(y, i, window, degree):
    """Independent weighted polynomial fit (numpy.polyfit) evaluated at i."""
    x = np.asarray(window, float)
    w = tricube(x - i)
    coef = np.polyfit(x - i, y[window], degree, w=np.sqrt(w))
    return coef[-1]


@pytest.mark.parametrize("n, expected", [(100, 11), (89, 9), (91, 11), (38, 5), (10, 1)])
def test_span_rule(n, expected):
    assert sm.span_points(0.1, n) == expected


def test_span_one_returns_input():
    y = np.random.default_rng(0).normal(size=10)  # ceil(0.1 * 10) = 1
    np.testing.assert_array_equal(sm.rloess(y, 0.1), y)


def test_loess_reproduces_quadratics_everywhere_including_ends():
    t = np.arange(57.0)
    y = 0.3 - 0.02 * t + 0.004 * t**2
    for f in (sm.loess, sm.rloess):
        np.testing.assert_allclose(f(y, 0.1), y, atol=1e-9)
    lin = 1.0 + 0.5 * t
    for f in (sm.lowess, sm.rlowess):
        np.testing.assert_allclose(f(lin, 0.1), lin, atol=1e-9)


@pytest.mark.parametrize("degree, func", [(2, sm.loess), (1, sm.lowess)])
def test_local_fits_match_independent_weighted_polyfit(degree, func):
    rng = np.random.default_rng(3)
    n = 40
    y = np.sin(np.arange(n) / 4) + rng.normal(0, 0.1, n)
    span = 7
    ys = func(y, span)
    h = 3
    for i in range(n):
        lo = min(max(i - h, 0), n - span)  # shifted, never padded, at the ends
        window = np.arange(lo, lo + span)
        assert ys[i] == pytest.approx(direct_fit(y, i, window, degree), abs=1e-10), i


def test_even_span_made_odd():
    y = np.random.default_rng(1).normal(size=30)
    np.testing.assert_allclose(sm.loess(y, 6), sm.loess(y, 7))


def test_rloess_resists_injected_outliers():
    rng = np.random.default_rng(7)
    n = 100
    t = np.arange(n)
    clean = 0.05 * np.sin(2 * np.pi * t / 50) + 0.001 * t  # two periods, as a recording
    noisy = clean + rng.normal(0, 0.001, n)
    spoiled = noisy.copy()
    out_at = [23, 61, 62]
    spoiled[out_at] += [0.08, -0.1, 0.06]
    robust = sm.rloess(spoiled, 0.1)
    plain = sm.loess(spoiled, 0.1)
    near = np.zeros(n, bool)
    for k in out_at:
        near[max(k - 6, 0):k + 7] = True
    err_robust = np.max(np.abs(robust - clean)[near])
    err_plain = np.max(np.abs(plain - clean)[near])
    assert err_robust < 0.003          # within a few noise sigmas of the truth
    assert err_plain > 10 * err_robust  # the non-robust fit is dragged by the outliers
    # and without outliers the robust and plain smoothers nearly agree
    assert np.max(np.abs(sm.rloess(noisy, 0.1) - sm.loess(noisy, 0.1))) < 0.002


def test_span_five_loess_interpolates_the_interior():
    """MATLAB's rule: with 5 points the two farthest get zero tricube weight, so
    the interior quadratic passes through 3 points (38 frames x 0.1 -> 5)."""
    y = np.random.default_rng(4).normal(size=38)
    ys = sm.loess(y, 0.1)
    np.testing.assert_allclose(ys[2:-2], y[2:-2], atol=1e-12)
    assert np.all(np.abs(ys[:2] - y[:2]) > 1e-6)


@pytest.mark.parametrize("n, method, expected", [(38, "rloess", 7), (38, "rlowess", 5), (100, "rloess", 11),
                                                 (38, "moving", 3)])
def test_effective_span_with_auto_minimum(n, method, expected):
    assert sm.effective_span(n, 0.1, method, "auto") == expected


def test_rlowess_resists_outliers_lowess_does_not():
    t = np.arange(60.0)
    clean = 0.01 * t
    y = clean.copy()
    y[30] += 1.0
    assert abs(sm.rlowess(y, 0.2)[30] - clean[30]) < 1e-6
    assert abs(sm.lowess(y, 0.2)[30] - clean[30]) > 0.1


def test_moving_average_ends_shrink():
    y = np.array([1.0, 2, 4, 8, 16, 32, 64])
    ys = sm.moving_average(y, 5)
    assert ys[0] == 1.0
    assert ys[1] == pytest.approx((1 + 2 + 4) / 3)
    assert ys[2] == pytest.approx((1 + 2 + 4 + 8 + 16) / 5)
    assert ys[-1] == 64.0
    assert ys[-2] == pytest.approx((16 + 32 + 64) / 3)
    np.testing.assert_allclose(sm.moving_average(y, 4), sm.moving_average(y, 3))


def test_nan_is_a_clear_error():
    y = np.arange(20.0)
    y[4] = np.nan
    with pytest.raises(ValueError, match=r"sample\(s\) \[4\]"):
        sm.rloess(y)


def test_smooth_positions_columnwise_and_nan_policy():
    rng = np.random.default_rng(2)
    p = rng.normal(size=(50, 2, 3)).cumsum(axis=0)
    out = sm.smooth_positions(p)
    assert out.shape == p.shape
    # 50 frames x 0.1 = 5 points, raised to 7 by default; min_span=None is MATLAB exactly
    np.testing.assert_allclose(out[:, 1, 2], sm.smooth(p[:, 1, 2], 7, "rloess", windows="fixed"))
    exact = sm.smooth_positions(p, min_span=None, windows="matlab")
    np.testing.assert_allclose(exact[:, 1, 2], sm.rloess(p[:, 1, 2], 0.1))
    p[10, 1, 0] = np.nan
    with pytest.raises(ValueError, match="marker 1, axis x"):
        sm.smooth_positions(p)
    omitted = sm.smooth_positions(p, nan="omit")
    assert np.isnan(omitted[10, 1, 0]) and np.isfinite(omitted[11, 1, 0])
    np.testing.assert_allclose(omitted[:, 0], out[:, 0])
    # each run is smoothed on its own: the run after the gap does not see the samples before it
    np.testing.assert_allclose(omitted[11:, 1, 0], sm.smooth(p[11:, 1, 0], 7, "rloess", windows="fixed"))
    np.testing.assert_allclose(omitted[:10, 1, 0], sm.smooth(p[:10, 1, 0], 7, "rloess", windows="fixed"))


def test_unknown_method():
    with pytest.raises(ValueError, match="method"):
        sm.smooth(np.arange(10.0), 0.5, "spline")


def test_short_record_robust_default_resists_outliers():
    """38 frames (the thesis' record): the pipeline default stays near the truth."""
    rng = np.random.default_rng(11)
    n = 38
    t = np.arange(n)
    clean = 0.04 * np.sin(2 * np.pi * t / 18) + 0.005 * t
    y = clean + rng.normal(0, 0.001, n)
    y[[9, 26]] += [0.05, -0.06]
    p = np.stack([y, y, y], axis=1)[:, None, :]
    robust = sm.smooth_positions(p)[:, 0, 0]
    plain = sm.smooth_positions(p, method="loess")[:, 0, 0]
    assert np.max(np.abs(robust - clean)) < 0.4 * np.max(np.abs(plain - clean))
    assert np.sqrt(np.mean((robust - clean) ** 2)) < 0.004


def test_matlab_rules_on_short_records_run_away_at_the_ends():
    """Documents why smooth_positions departs from MATLAB by default (notebook 06)."""
    n = 38
    t = np.arange(n)
    y = 0.04 * np.sin(2 * np.pi * t / 18) + np.random.default_rng(0).normal(0, 0.001, n)
    exact = sm.rloess(y, 0.1)
    assert np.max(np.abs(exact - y)) > 0.05   # the extrapolated ends
    np.testing.assert_allclose(sm.smooth(y, 0.1, "loess")[2:-2], y[2:-2])


@pytest.mark.parametrize("method", ["rloess", "loess", "rlowess", "lowess"])
@pytest.mark.parametrize("windows", ["matlab", "fixed"])
def test_batched_local_fits_equal_the_fits_one_by_one(method, windows):
    """All windows solved at once (issue 16) give smooth.m's loop's values: uniform and irregular x,
    outliers (robust weights of zero move the windows), spans from the thesis' 0.1 to 11 points."""
    rng = np.random.default_rng(7)
    degree, robust = {"rloess": (2, True), "loess": (2, False), "rlowess": (1, True), "lowess": (1, False)}[method]
    for n, span, irregular in [(38, 0.1, False), (97, 0.1, False), (60, 11, False), (45, 7, True), (120, 0.2, True)]:
        x = np.sort(rng.choice(3 * n, n, replace=False)).astype(float) if irregular else np.arange(n, dtype=float)
        y = 40 * np.sin(x / 6) + rng.normal(0, 0.3, n)
        y[rng.choice(n, n // 8, replace=False)] += rng.normal(0, 8, n // 8)
        k = sm.span_points(span, n, uniform=not irregular)
        loop = sm._local_regression_loop(x, y, k, degree, robust, sm.ROBUST_ITERATIONS, windows, not irregular)
        batched = sm.smooth(y, span, method, x=None if not irregular else x, windows=windows)
        np.testing.assert_allclose(batched, loop, rtol=0, atol=1e-12 * np.abs(y).max())


def test_repeated_x_keeps_the_loop():
    x = np.array([0, 1, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10.0])
    y = np.random.default_rng(2).normal(size=x.size)
    out = sm.smooth(y, 5, "rloess", x=x)
    assert out[1] == out[2]  # the same x, the same fit (smooth.m)
