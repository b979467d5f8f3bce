"""The partial spline's smoothing choice scores its whole grid at once with the same bits as one point at
a time, so the chosen smoothing is unchanged."""
import numpy as np
import pytest

from horsemocap import splines


@pytest.mark.parametrize("noise", [None, 0.002])
def test_grid_scores_are_the_pointwise_scores_bit_for_bit(monkeypatch, noise):
    rng = np.random.default_rng(7)
    x = np.arange(240) / 60.0
    y = 0.03 * np.sin(2 * np.pi * 1.6 * x) + 0.01 * np.sin(2 * np.pi * 3.2 * x + 0.4) + rng.normal(0, 0.002, x.size)
    w = rng.uniform(0.5, 1.5, x.size)
    checked = []
    choose = splines._choose_lam

    def comparing(score, lo, hi, grid_scores=None):
        grid = np.linspace(lo, hi, 60)
        assert grid_scores is not None
        at_once, one_by_one = grid_scores(grid), [score(g) for g in grid]
        checked.append([float(a).hex() for a in at_once] == [float(b).hex() for b in one_by_one])
        return choose(score, lo, hi, grid_scores)

    monkeypatch.setattr(splines, "_choose_lam", comparing)
    spline, _, info = splines._partial_quintic(x, y, w, None, 1.6, (0, 1, 2, (2,)), noise=noise)
    assert len(checked) == 4 and all(checked)

    monkeypatch.setattr(splines, "_choose_lam", lambda score, lo, hi, grid_scores=None: choose(score, lo, hi))
    spline_pointwise, _, info_pointwise = splines._partial_quintic(x, y, w, None, 1.6, (0, 1, 2, (2,)), noise=noise)
    assert repr(info) == repr(info_pointwise) and spline.c.tobytes() == spline_pointwise.c.tobytes()
