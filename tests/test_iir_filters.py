"""The NumPy recursive filters and tail probabilities give SciPy's bits, and the analysis loads neither
scipy.signal nor scipy.stats."""
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy import signal, stats

from horsemocap import iir_filters, vibration
from horsemocap.probability import f_survival, t_quantile


@pytest.mark.parametrize("shape, axis", [((500,), 0), ((300, 7), 0), ((40, 300), 1), ((60, 3, 4), 0)])
@pytest.mark.parametrize("rho", [0.0, 0.3, 0.98, -0.5])
def test_ar1_filter_is_lfilter_bit_for_bit(shape, axis, rho):
    x = np.random.default_rng(3).normal(size=shape)
    x.flat[5] = 0.0
    got = iir_filters.ar1_filter(x, rho, axis=axis)
    assert got.shape == x.shape
    assert got.tobytes() == signal.lfilter([1.0], [1.0, -rho], x, axis=axis).tobytes()


def _weighting_sections():
    for name in ("Wb", "Wk", "Wd"):
        for band_limiting in (True, False):
            for b, a, w0 in vibration.analog_sections(name, band_limiting=band_limiting):
                n = max(len(b), len(a))
                yield (np.concatenate([np.zeros(n - len(b)), b]), np.concatenate([np.zeros(n - len(a)), a]), w0)


def test_bilinear_is_scipys_bit_for_bit_on_the_weighting_sections_and_random_ones():
    rng = np.random.default_rng(4)
    cases = [(b, a, w0 / (2 * np.tan(w0 / (2 * fs)))) for b, a, w0 in _weighting_sections()
             for fs in (30.0, 100.0, 200.0, 1000.0) if w0 / (2 * np.pi) < 0.45 * fs]
    cases += [(rng.normal(size=rng.integers(1, 4)), rng.normal(size=rng.integers(1, 4)), rng.uniform(1, 500))
              for _ in range(100)]
    assert len(cases) > 150
    for b, a, fs in cases:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got, want = iir_filters.bilinear(b, a, fs), signal.bilinear(b, a, fs=fs)
        for g, w in zip(got, want):
            assert g.shape == w.shape and g.tobytes() == w.tobytes(), (b, a, fs)


@pytest.mark.parametrize("name", ["Wb", "Wk", "Wd"])
@pytest.mark.parametrize("fs", [60.0, 100.0, 400.0])
def test_sos_response_and_filter_are_scipys_bit_for_bit(name, fs):
    rng = np.random.default_rng(5)
    sos, _ = vibration._design_sos(name, fs)
    f = np.r_[0.0, rng.uniform(0, fs / 2, 200)]
    assert (iir_filters.sos_frequency_response(sos, f, fs).tobytes()
            == signal.freqz_sos(sos, worN=f, fs=fs)[1].tobytes())
    for shape, axis in [((1000,), 0), ((400, 3), 0), ((3, 400), -1)]:
        x = rng.normal(size=shape)
        assert iir_filters.sos_filter(sos, x, axis=axis).tobytes() == signal.sosfilt(sos, x, axis=axis).tobytes()


def test_sos_filter_rejects_sections_that_are_not_normalised():
    with pytest.raises(ValueError, match=r"a0 \(column 3\) must be 1"):
        iir_filters.sos_filter([[1.0, 0, 0, 2.0, 0, 0]], np.ones(4))
    with pytest.raises(ValueError, match=r"shape \(n_sections, 6\)"):
        iir_filters.sos_frequency_response(np.ones((2, 5)), [1.0], 10.0)


def test_t_quantile_and_f_survival_are_scipy_stats_bit_for_bit_with_the_edges():
    rng = np.random.default_rng(6)
    q = np.r_[rng.uniform(0, 1, 500), 0.0, 1.0, -0.1, 1.2, np.nan, 0.975]
    df = np.r_[rng.uniform(-1, 60, 500), 3, 3, 3, 3, 3, 7.5]
    assert t_quantile(q, df).tobytes() == np.asarray(stats.t.ppf(q, df)).tobytes()
    x = np.r_[rng.uniform(-1, 20, 500), 0.0, np.inf, np.nan, -np.inf]
    dfn, dfd = np.r_[rng.uniform(-1, 20, 500), 3, 3, 3, 3], np.r_[rng.uniform(-1, 300, 500), 5, 5, 5, 5]
    assert f_survival(x, dfn, dfd).tobytes() == np.asarray(stats.f.sf(x, dfn, dfd)).tobytes()
    assert f_survival(2.5, 3, 20.7) == stats.f.sf(2.5, 3, 20.7) and np.ndim(f_survival(2.5, 3, 20.7)) == 0
    assert t_quantile(0.975, 7) == stats.t.ppf(0.975, 7)


def test_the_analysis_loads_neither_scipy_signal_nor_scipy_stats():
    code = ("import sys, horsemocap.cli, horsemocap.run, horsemocap.pipeline, horsemocap.steps, "
            "horsemocap.vibration, horsemocap.splines\n"
            "print(' '.join(sorted(sys.modules)))")
    loaded = set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                check=True).stdout.split())
    assert "horsemocap.rigid" in loaded and "horsemocap.steps.comfort" in loaded
    assert not {m for m in loaded if m.split(".")[:2] in (["scipy", "signal"], ["scipy", "stats"])}
