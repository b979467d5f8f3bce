"""The NumPy AR(1) recursion and tail probabilities give SciPy's bits, and the analysis loads neither
scipy.signal nor scipy.stats (nor the digital weighting filters, which use scipy.signal)."""
import subprocess
import sys

import numpy as np
import pytest
from scipy import signal, stats

from horsemocap import iir_filters
from horsemocap.probability import f_survival, t_quantile


def _samples_with_gaps(shape, seed):
    """Random samples with a zero, NaNs and infinities of both signs at random places."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=shape)
    flat = x.reshape(-1)
    places = rng.choice(flat.size, size=5, replace=False)
    flat[places] = [0.0, np.nan, np.inf, -np.inf, np.nan]
    return x


@pytest.mark.parametrize("shape, axis", [((500,), 0), ((500,), -1), ((300, 7), 0), ((40, 300), 1),
                                         ((40, 300), -1), ((60, 3, 4), 0), ((3, 60, 4), 1), ((3, 4, 60), -1)])
@pytest.mark.parametrize("rho", [0.0, 0.3, 0.98, -0.5, 1.0])
def test_ar1_filter_is_lfilter_bit_for_bit_also_with_nan_and_inf_samples(shape, axis, rho):
    for seed, x in enumerate([np.random.default_rng(3).normal(size=shape), _samples_with_gaps(shape, 4),
                              _samples_with_gaps(shape, 5)]):
        got = iir_filters.ar1_filter(x, rho, axis=axis)
        want = signal.lfilter([1.0], [1.0, -rho], x, axis=axis)
        assert got.shape == x.shape and got.dtype == want.dtype
        # the same bits, up to a NaN's sign and payload (which of two NaN operands a CPU passes on is not
        # fixed by IEEE 754, and compiled loops may swap the operands of a sum)
        nan = np.isnan(want)
        assert np.array_equal(np.isnan(got), nan), (seed, shape, axis, rho)
        assert got[~nan].tobytes() == want[~nan].tobytes(), (seed, shape, axis, rho)


def test_ar1_filter_spreads_an_inf_sample_as_lfilter_does():
    x = np.array([1.0, np.inf, 0.0, 0.0])
    got = iir_filters.ar1_filter(x, 0.5)
    assert got.tolist()[:2] == [1.0, np.inf] and np.isnan(got[2:]).all()
    assert got.tobytes() == signal.lfilter([1.0], [1.0, -0.5], x).tobytes()


def test_ar1_filter_takes_integers_and_refuses_complex_samples():
    assert iir_filters.ar1_filter([1, 0, 2], 0.5).tolist() == [1.0, 0.5, 2.25]
    with pytest.raises(TypeError, match="must be real, got complex"):
        iir_filters.ar1_filter(np.array([1.0, 1j, 0.0]), 0.5)
    with pytest.raises(TypeError, match="complex"):
        iir_filters.ar1_filter([1.0 + 0j, 2.0], 0.5)


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
            "horsemocap.vibration, horsemocap.splines, horsemocap.uncertainty, horsemocap.io3d, horsemocap.streaming, "
            "horsemocap.errors, horsemocap.workspace\n"
            "print(' '.join(sorted(sys.modules)))")
    loaded = set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                check=True).stdout.split())
    assert "horsemocap.rigid" in loaded and "horsemocap.steps.comfort" in loaded
    assert "horsemocap.weighting_filters" not in loaded
    assert not {m for m in loaded if m.split(".")[:2] in (["scipy", "signal"], ["scipy", "stats"])}
