"""The spline's linear algebra: the SVD of the penalised basis survives LAPACK's rare non-convergence."""
import numpy as np

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
