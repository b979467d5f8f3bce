"""The three-class Otsu search over every pair of levels at once picks the levels a search one dark
level at a time picks."""
import numpy as np
import pytest

from horsemocap.detection.thresholds import _otsu3_centre, otsu3_thresholds


def _one_level_at_a_time(hist):
    p = hist / hist.sum()
    P = np.concatenate([[0.0], np.cumsum(p)])
    S = np.concatenate([[0.0], np.cumsum(p * np.arange(256))])
    best, arg = -1.0, (0, 1)
    t2 = np.arange(1, 255)
    for t1 in range(254):
        j = t2[t2 > t1]
        w0, s0 = P[t1 + 1], S[t1 + 1]
        w1, s1 = P[j + 1] - w0, S[j + 1] - s0
        w2, s2 = 1.0 - P[j + 1], S[-1] - S[j + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where(w1 > 0, s1 ** 2 / w1, 0) + np.where(w2 > 0, s2 ** 2 / w2, 0)
        v = v + (s0 ** 2 / w0 if w0 > 0 else 0.0)
        i = int(np.argmax(v))
        if v[i] > best:
            best, arg = float(v[i]), (t1, int(j[i]))
    return _otsu3_centre(P, S, *arg)


def _histograms(rng):
    yield rng.integers(0, 1000, 256).astype(float)
    for _ in range(20):
        h = np.zeros(256)
        levels = rng.choice(256, rng.integers(1, 6), replace=False)
        h[levels] = rng.integers(1, 5000, levels.size)
        yield h
    for _ in range(10):
        grey = np.r_[rng.normal(30, 10, 20000), rng.normal(rng.uniform(150, 250), 5, 200)]
        yield np.bincount(np.clip(grey, 0, 255).astype(int), minlength=256).astype(float)


def test_otsu3_equals_the_search_one_dark_level_at_a_time():
    rng = np.random.default_rng(11)
    hists = list(_histograms(rng))
    assert len(hists) == 31
    for hist in hists:
        assert otsu3_thresholds(hist) == _one_level_at_a_time(hist)


@pytest.mark.parametrize("level", [0, 17, 255])
def test_otsu3_of_a_single_grey_level(level):
    hist = np.zeros(256)
    hist[level] = 50.0
    assert otsu3_thresholds(hist) == _one_level_at_a_time(hist)
