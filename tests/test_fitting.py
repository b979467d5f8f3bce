"""Tests of horsemocap.fitting on synthetic signals with exact truth."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize, stats

from horsemocap import fitting

FPS = 30.0
T = np.arange(38) / FPS          # the thesis' canter record: 38 frames, 2 periods


def fourier_truth(t, a0, ab, w, d=0):
    out = np.full_like(t, a0 if d == 0 else 0.0)
    for i, (a, b) in enumerate(ab, start=1):
        k = i * w
        c, s = np.cos(k * t), np.sin(k * t)
        out += [a * c + b * s, k * (-a * s + b * c), -k * k * (a * c + b * s)][d]
    return out


@pytest.mark.parametrize("seed", range(8))
def test_fourier_recovers_noise_free_signal(seed):
    rng = np.random.default_rng(seed)
    N = int(rng.integers(1, 4))
    # about two periods in the record, as in the thesis (period entered by the
    # user); a dominant fundamental. MATLAB's spectral start point (one FFT
    # bin per period in the record) is what limits this: with 1.7 periods and
    # a strong 2nd harmonic it starts in the basin of a wrong w, as MATLAB would.
    w = 2 * np.pi * rng.uniform(1.85, 2.15) / (T[-1] - T[0])
    ab = rng.normal(0, 0.01, (N, 2))
    ab[0] = rng.choice([-1, 1], 2) * rng.uniform(0.02, 0.05, 2)
    y = fourier_truth(T, 0.4, ab, w)
    f = fitting.fit_fourier(T, y, N)
    assert f.frequency == pytest.approx(w, rel=1e-6)
    np.testing.assert_allclose(f.coefficients[1:-1].reshape(N, 2), ab, atol=1e-7)
    tt = np.linspace(0, T[-1], 200)
    for d in (0, 1, 2):
        truth = fourier_truth(tt, 0.4, ab, w, d)
        np.testing.assert_allclose(f.evaluate(tt, d), truth, atol=1e-5 * np.max(np.abs(truth)))
    assert f.gof.rsquare > 1 - 1e-10
    assert f.names[0] == "a0" and f.names[-1] == "w" and len(f.names) == 2 * N + 2


def test_fourier_gof_and_confint_match_independent_nls():
    """At the optimum, scipy's curve_fit (all coefficients free) agrees, and
    MATLAB's confint formula b +- t sqrt(diag(inv(J'J)) sse/dfe) holds."""
    rng = np.random.default_rng(1)
    w = 2 * np.pi / 0.6
    y = fourier_truth(T, 0.3, [[0.05, 0.02], [0.01, -0.004]], w) + rng.normal(0, 0.002, T.size)
    f = fitting.fit_fourier(T, y, 2)

    def model(t, a0, a1, b1, a2, b2, ww):
        return fourier_truth(t, a0, [[a1, b1], [a2, b2]], ww)

    popt, pcov = optimize.curve_fit(model, T, y, p0=f.coefficients * (1 + 1e-3), xtol=1e-14, ftol=1e-14)
    np.testing.assert_allclose(f.coefficients, popt, rtol=1e-5, atol=1e-8)
    r = y - model(T, *popt)
    sse = np.sum(r ** 2)
    assert f.gof.sse == pytest.approx(sse, rel=1e-6)
    n, m = T.size, 6
    sst = np.sum((y - y.mean()) ** 2)
    assert f.gof.dfe == n - m
    assert f.gof.rsquare == pytest.approx(1 - sse / sst, rel=1e-9)
    assert f.gof.adjrsquare == pytest.approx(1 - sse * (n - 1) / (sst * (n - m)), rel=1e-9)
    assert f.gof.rmse == pytest.approx(np.sqrt(sse / (n - m)), rel=1e-6)
    half = stats.t.ppf(0.975, n - m) * np.sqrt(np.diag(pcov))      # curve_fit's pcov = inv(J'J) sse/dfe
    np.testing.assert_allclose(f.confint[1] - f.coefficients, half, rtol=1e-3)
    np.testing.assert_allclose(f.coefficients - f.confint[0], half, rtol=1e-3)


def test_fourier_start_point_rule():
    """The spectral start point finds w where a naive start would not; with
    N >= 2 it also tries wpeak/j (a signal whose strongest line is its 2nd
    harmonic is fitted at the true fundamental)."""
    w = 2 * np.pi / 0.6
    y = fourier_truth(T, 0.0, [[0.05, 0.0]], w)
    t_span = T[-1] - T[0]
    mag = np.abs(np.fft.fft(y - y.mean()))[: T.size // 2]
    k = int(np.argmax(mag))
    assert fitting.fourier_start_point(T, y, 1) == pytest.approx(2 * np.pi * k / t_span)
    y2 = fourier_truth(T, 0.0, [[0.01, 0.0], [0.05, 0.01]], w)
    f = fitting.fit_fourier(T, y2, 2)
    assert f.frequency == pytest.approx(w, rel=1e-6)
    # from a naive start (w = 1 rad/s) the search lands elsewhere
    naive = fitting.fit_fourier(T, y2, 2, w0=1.0)
    assert naive.gof.sse > 1e3 * max(f.gof.sse, 1e-20)


def test_fourier_ignores_nan_and_validates():
    y = fourier_truth(T, 0.1, [[0.05, 0.01]], 10.0)
    y[[3, 17]] = np.nan
    f = fitting.fit_fourier(T, y, 1)
    assert f.t.size == T.size - 2 and f.frequency == pytest.approx(10.0, rel=1e-6)
    with pytest.raises(ValueError, match="order"):
        fitting.fit_fourier(T, y, 0)
    with pytest.raises(ValueError, match="needs at least"):
        fitting.fit_fourier(T[:5], y[:5], 3)


def test_polynomial_fit_and_derivatives():
    rng = np.random.default_rng(2)
    x = 4.9 * T + 0.7
    f = fitting.fit_polynomial(T, x)
    np.testing.assert_allclose(f.coefficients, [4.9, 0.7], atol=1e-12)
    np.testing.assert_allclose(f.evaluate(T, 1), 4.9, atol=1e-12)
    np.testing.assert_allclose(f.evaluate(T, 2), 0.0, atol=1e-12)
    assert f.names == ("p1", "p2")
    y = 1 - 2 * T + 3 * T ** 2 + rng.normal(0, 0.01, T.size)
    g = fitting.fit_polynomial(T, y, 2)
    ref = np.polyfit(T, y, 2)
    np.testing.assert_allclose(g.coefficients, ref, rtol=1e-9)
    # MATLAB's confint for linear models is the classical OLS interval
    X = np.vander(T, 3)
    s2 = np.sum((y - X @ ref) ** 2) / (T.size - 3)
    half = stats.t.ppf(0.975, T.size - 3) * np.sqrt(np.diag(np.linalg.inv(X.T @ X)) * s2)
    np.testing.assert_allclose(g.confint[1] - g.coefficients, half, rtol=1e-8)
    # coverage: the 95 % interval of the slope covers the truth ~95 % of the time
    hits = 0
    for s in range(200):
        yy = 0.3 + 2.0 * T + np.random.default_rng(100 + s).normal(0, 0.05, T.size)
        lo, hi = fitting.fit_polynomial(T, yy).confint[:, 0]
        hits += lo <= 2.0 <= hi
    assert 0.88 <= hits / 200 <= 0.99


def test_count_extremes():
    t = np.linspace(0, 2, 200)
    assert fitting.count_extremes(np.sin(2 * np.pi * t)) == 4          # 2 periods
    assert fitting.count_extremes(np.sin(2 * np.pi * t + 0.5)) == 4
    assert fitting.count_extremes(t) == 0
    assert fitting.count_extremes(np.cos(np.pi * t)) == 1              # one interior minimum
    rng = np.random.default_rng(0)
    noisy = np.sin(2 * np.pi * t) + rng.normal(0, 0.01, t.size)
    assert fitting.count_extremes(noisy, min_prominence=0.05) == 4
    assert fitting.count_extremes(noisy, min_prominence=0.0) > 4       # every wiggle


def test_proposed_orders():
    assert fitting.proposed_orders(4) == (2, 3)          # thesis y example: Fourier2 / Fourier3
    assert fitting.proposed_orders(2) == (1, 2)          # thesis z example
    assert fitting.proposed_orders(5) == (3, 4)          # odd E: rounded up
    assert fitting.proposed_orders(0) == (1, 2)
    with pytest.raises(ValueError):
        fitting.proposed_orders(-1)


def test_choose_order_rules():
    rng = np.random.default_rng(4)
    w = 2 * np.pi / 0.6
    pure = fourier_truth(T, 0.2, [[0.05, 0.02]], w) + rng.normal(0, 0.001, T.size)
    # E = 2 -> (1, 2): the 2nd harmonic is not significant
    assert fitting.choose_order(T, pure, 2) == 1
    assert fitting.choose_order(T, pure, 2, rule="thesis") == 1
    rich = fourier_truth(T, 0.2, [[0.05, 0.02], [0.015, 0.01]], w) + rng.normal(0, 0.001, T.size)
    assert fitting.choose_order(T, rich, 2) == 2
    assert fitting.choose_order(T, rich, 2, rule="adjrsquare") == 2
    assert fitting.choose_order(T, rich, 2, rule="thesis") == 1
    with pytest.raises(ValueError, match="rule"):
        fitting.choose_order(T, rich, 2, rule="best")


def test_fit_motion_shapes_and_derivatives():
    w = 2 * np.pi / 0.6
    n, m = T.size, 3
    pos = np.zeros((n, m, 3))
    truth_v = np.zeros((n, m, 3))
    truth_a = np.zeros((n, m, 3))
    for j in range(m):
        pos[:, j, 0] = 4.5 * T + j
        truth_v[:, j, 0] = 4.5
        ab_y = [[0.04 + 0.01 * j, 0.01]]
        ab_z = [[0.01, 0.02], [0.005, -0.002]]
        pos[:, j, 1] = fourier_truth(T, 1.2, ab_y, w)
        pos[:, j, 2] = fourier_truth(T, 3.0, ab_z, w)
        truth_v[:, j, 1] = fourier_truth(T, 0, ab_y, w, 1)
        truth_v[:, j, 2] = fourier_truth(T, 0, ab_z, w, 1)
        truth_a[:, j, 1] = fourier_truth(T, 0, ab_y, w, 2)
        truth_a[:, j, 2] = fourier_truth(T, 0, ab_z, w, 2)
    mf = fitting.fit_motion(T, pos, orders=[[1, 2]] * m)
    assert mf.orders.tolist() == [[1, 1, 2]] * m
    np.testing.assert_allclose(mf.position(T), pos, atol=1e-8)
    np.testing.assert_allclose(mf.velocity(T), truth_v, atol=1e-6)
    np.testing.assert_allclose(mf.acceleration(T), truth_a, atol=1e-4)
    auto = fitting.fit_motion(T, pos)
    assert np.all(auto.n_extremes[:, 1:] >= 2)
    np.testing.assert_allclose(auto.acceleration(T), truth_a, atol=1e-4)
    with pytest.raises(ValueError, match="orders"):
        fitting.fit_motion(T, pos, orders=np.ones((2, 2), int))


def test_fourier_start_all_never_worse_than_matlab():
    """start="all" searches from every MATLAB candidate and keeps the best SSE:
    never worse than MATLAB's single start, and on a record of about two
    periods it avoids the sub-multiple basin (fourier3 ending at w/3)."""
    rng = np.random.default_rng(5)
    w = 2 * np.pi / 0.6
    y = fourier_truth(T, 0.1, [[0.09, 0.05], [-0.006, -0.001], [0.001, 0.0005]], w) + rng.normal(0, 0.001, T.size)
    for N in (1, 2, 3, 4):
        fm, fa = fitting.fit_fourier(T, y, N), fitting.fit_fourier(T, y, N, start="all")
        assert fa.gof.sse <= fm.gof.sse * (1 + 1e-9)
    assert fitting.fit_fourier(T, y, 3, start="all").frequency == pytest.approx(w, rel=2e-3)
    with pytest.raises(ValueError, match="start"):
        fitting.fit_fourier(T, y, 2, start="best")


def test_ui_fourier_order_defaults_and_callback():
    from horsemocap import widgets
    w = 2 * np.pi / 0.6
    y = fourier_truth(T, 0.2, [[0.05, 0.02]], w)
    ui = widgets.ui_fourier_order(T, y, "m1 y")
    e = fitting.count_extremes(y)
    assert ui.extremes.value == e
    assert ui.value == fitting.choose_order(T, y, e)
    ui.choice.value = fitting.proposed_orders(e)[1]
    ui.extremes.value = 6                                  # the second choice stays the second
    assert ui.value == fitting.proposed_orders(6)[1]
    assert widgets.ui_x_degree().value == 1


def test_fit_plots_return_figures():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from horsemocap import plots
    y = fourier_truth(T, 0.2, [[0.05, 0.02]], 10.0)
    f1, f2 = fitting.fit_fourier(T, y, 1), fitting.fit_fourier(T, y, 2)
    fig = plots.plot_fit_choice(f1, f2, truth={"t": T, "pos": y})
    assert len(fig.axes) == 8
    pos = np.stack([np.stack([T, y, y], -1)] * 3, 1)
    fig2 = plots.plot_marker_fits(T, pos, fitting.fit_motion(T, pos, orders=1), marker=1)
    assert len(fig2.axes) == 9
    plt.close("all")


def test_fourier_with_trend_recovers_drift():
    """A motion frame tilted by a fraction of a degree adds c*t to y: the trend
    term recovers it exactly and leaves the derivatives exact."""
    w = 2 * np.pi / 0.6
    ab = [[0.075, 0.01], [0.012, -0.004], [0.002, 0.001]]
    y = fourier_truth(T, 0.3, ab, w) + 0.0085 * T
    f = fitting.fit_fourier(T, y, 3, trend=True)
    assert f.names[-2:] == ("w", "c") and f.trend and f.label == "fourier3+trend"
    assert f.frequency == pytest.approx(w, rel=1e-7)
    assert f.coefficients[-1] == pytest.approx(0.0085, abs=1e-8)
    np.testing.assert_allclose(f.evaluate(T, 1), fourier_truth(T, 0, ab, w, 1) + 0.0085, atol=1e-6)
    np.testing.assert_allclose(f.evaluate(T, 2), fourier_truth(T, 0, ab, w, 2), atol=1e-4)
    plain = fitting.fit_fourier(T, y, 3, w0=w)
    assert plain.gof.sse > 1e6 * f.gof.sse
    assert fitting.fit_motion(T, np.stack([T, y, y], -1)[:, None], orders=3, trend=True).fits[0][1].trend


def test_every_significant_lowers_orders_proposed_by_noise():
    # two real harmonics plus noise; E = 10 (as if noise extremes were counted) proposes N1 = 5
    rng = np.random.default_rng(4)
    t = np.arange(80) / 60.0
    w = 2 * np.pi * 1.7
    y = 0.03 * np.cos(w * t) + 0.012 * np.sin(2 * w * t) + rng.normal(0, 0.002, t.size)
    assert fitting.choose_order(t, y, 10, rule="significant", w0=w) >= 5
    n = fitting.choose_order(t, y, 10, rule="every_significant", w0=w)
    assert n == 2
    fit = fitting.fit_fourier(t, y, n, w0=w)
    assert fitting.top_harmonic_significant(fit)
    assert not fitting.top_harmonic_significant(fitting.fit_fourier(t, y, 5, w0=w))
    # an order that stands is still offered N1 + 1 as in "significant"
    assert fitting.choose_order(t, y, 4, rule="every_significant", w0=w) == \
        fitting.choose_order(t, y, 4, rule="significant", w0=w)
    with pytest.raises(ValueError, match="every_significant"):
        fitting.choose_order(t, y, 4, rule="backward")
