"""The spline's linear algebra: the SVD of the penalised basis survives LAPACK's rare non-convergence, and is kept
for fits of the same times, weights and harmonics at other smoothing parameters (the same bits)."""
import numpy as np
import pytest

from horsemocap import splines


def test_svd_falls_back_to_qr_iteration_when_divide_and_conquer_fails(monkeypatch):
    """LAPACK's gesdd (NumPy's SVD) rarely fails to converge on an ill-conditioned basis; the spline's fit then
    takes gesvd's SVD instead of stopping, with the same fit."""
    rng = np.random.default_rng(0)
    x = np.linspace(0.0, 2.0, 120)
    y = np.sin(2 * np.pi * 1.5 * x) + rng.normal(0.0, 0.05, x.size)
    expected = splines.smoothing_spline(x, y, fundamental_hz=1.5)
    calls = []

    def not_converging(*args, **kwargs):
        calls.append(1)
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(np.linalg, "svd", not_converging)
    monkeypatch.setattr(splines, "_svd_cache", type(splines._svd_cache)())     # nothing kept: computed again
    a = np.array([[3.0, 0.0], [4.0, 5.0], [0.0, 0.0]])
    u, s, vt = splines.robust_svd(a)
    np.testing.assert_allclose(u * s @ vt, a, atol=1e-12)
    assert u.shape == (3, 2)
    fallback = splines.smoothing_spline(x, y, fundamental_hz=1.5)
    assert len(calls) > 1
    np.testing.assert_allclose(fallback(x), expected(x), rtol=0, atol=1e-9)


def test_svd_of_a_matrix_with_nan_still_raises_numpys_error():
    """Not a convergence failure: NaN in the matrix raises NumPy's LinAlgError, not a fallback's ValueError."""
    import pytest

    a = np.array([[1.0, np.nan], [0.0, 1.0]])
    with pytest.raises(np.linalg.LinAlgError):
        splines.robust_svd(a)


def _case(seed=0, n=120):
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 2.0, n)
    return x, np.sin(2 * np.pi * 1.5 * x) + rng.normal(0.0, 0.05, x.size), rng.uniform(0.5, 2.0, n)


@pytest.fixture
def fresh_cache(monkeypatch):
    monkeypatch.setattr(splines, "_svd_cache", type(splines._svd_cache)())
    calls = []
    svd = splines.robust_svd
    monkeypatch.setattr(splines, "robust_svd", lambda a: calls.append(a.shape) or svd(a))
    return calls


def test_the_svd_is_computed_once_for_fits_at_many_smoothing_parameters_with_the_same_bits(fresh_cache):
    x, y, w = _case()
    lams = [1e-9, 1e-7, 1e-5]
    kept = [splines.smoothing_spline(x, y, weights=w, lam=lam, fundamental_hz=1.5)(x) for lam in lams]
    once = len(fresh_cache)
    assert once >= 1
    for lam, value in zip(lams, kept):
        splines._svd_cache.clear()
        again = splines.smoothing_spline(x, y, weights=w, lam=lam, fundamental_hz=1.5)(x)
        np.testing.assert_array_equal(again, value)           # the same bits computed afresh
    assert len(fresh_cache) == once * (1 + len(lams))


def test_other_weights_times_or_harmonics_never_reuse_an_svd(fresh_cache):
    x, y, w = _case()
    splines.smoothing_spline(x, y, weights=w, lam=1e-7, fundamental_hz=1.5)
    for kwargs in ({"weights": w[::-1].copy()}, {"weights": w, "fundamental_hz": 1.7}):
        reused = splines.smoothing_spline(x, y, lam=1e-7, **{"fundamental_hz": 1.5, **kwargs})(x)
        splines._svd_cache.clear()
        fresh = splines.smoothing_spline(x, y, lam=1e-7, **{"fundamental_hz": 1.5, **kwargs})(x)
        np.testing.assert_array_equal(reused, fresh)
    other_x = x * 1.01
    reused = splines.smoothing_spline(other_x, y, weights=w, lam=1e-7, fundamental_hz=1.5)(other_x)
    splines._svd_cache.clear()
    np.testing.assert_array_equal(reused, splines.smoothing_spline(other_x, y, weights=w, lam=1e-7, fundamental_hz=1.5)(other_x))


def test_the_kept_svds_stay_within_their_bytes(fresh_cache, monkeypatch):
    x, y, w = _case()
    splines.smoothing_spline(x, y, weights=w, lam=1e-7, fundamental_hz=1.5)
    one = sum(a.nbytes for v in splines._svd_cache.values() for a in v) / len(splines._svd_cache)
    monkeypatch.setattr(splines, "SVD_CACHE_BYTES", int(2.5 * one))
    for seed in range(1, 6):
        splines.smoothing_spline(x, y, weights=_case(seed)[2], lam=1e-7, fundamental_hz=1.5)
        assert sum(a.nbytes for v in splines._svd_cache.values() for a in v) <= splines.SVD_CACHE_BYTES
    monkeypatch.setattr(splines, "SVD_CACHE_BYTES", int(0.5 * one))
    splines._svd_cache.clear()
    splines.smoothing_spline(x, y, weights=w, lam=1e-7, fundamental_hz=1.5)
    assert not splines._svd_cache                                 # larger than the bound alone: not kept


def test_partial_spline_on_a_long_record_follows_its_smoothing_parameter():
    """With more samples than twice the basis (knots every few samples) the partial spline without harmonics is
    the plain quintic spline at every lam, also at a small one: its projected basis is decomposed itself, not
    through its Gram matrix (whose eigenvalues square the condition number and lost a third of the degrees of
    freedom at lam 1e-9 on 1300 samples)."""
    for n in (400, 1050, 1300):
        x = np.arange(n) / 50.0
        y = np.random.default_rng(0).normal(size=n)
        w = np.ones(n)
        for lam in (1e-9, 1e-5):
            partial = splines._partial_quintic(x, y, w, lam, 1.5, [0])[2]["edf"]
            plain = splines._quintic_gcv(x, y, w, lam)[1]["edf"]
            assert abs(partial - plain) < 1e-6 * plain, (n, lam, partial, plain)
