"""The DLT's normal equations summed with Python floats for a few points are the array sums bit for bit,
and the identification's triangulation keeps its results."""
import numpy as np
import pytest

from horsemocap import reconstruction as rc
from horsemocap.detection.candidates import Candidates
from horsemocap.detection.matching import triangulate_rows
from horsemocap.virtuallab.rig import thesis_rig


def _bits(arrays):
    return [np.asarray(a, float).tobytes() for a in arrays]


@pytest.mark.parametrize("n", [1, 2, 4, rc.FEW_POINTS])
def test_few_points_normal_equations_are_the_array_sums_bit_for_bit(n):
    rng = np.random.default_rng(n)
    for _ in range(50):
        cameras = int(rng.integers(1, 5))
        xn = rng.normal(0, 0.3, (cameras, n, 2))
        seen = rng.random((cameras, n)) < 0.7
        xn[~seen] = np.nan if rng.random() < 0.5 else 0.0       # what an unseen view holds does not count
        Ps = rng.normal(size=(cameras, 3, 4))
        h_few, b_few = rc._dlt_normal_equations_few(xn, seen, Ps)
        h, b = rc._dlt_normal_equations(xn, seen, Ps)
        assert _bits(h_few) == _bits(h) and _bits(b_few) == _bits(b)
        assert rc._dlt(xn, seen, Ps).tobytes() == rc._solve3(h, b).tobytes()


def test_triangulate_rows_finds_the_points_and_flags_bad_rows():
    rig = thesis_rig()
    X = np.array([[0.0, 0.0, 7.5], [0.3, -0.1, 7.6], [-0.2, 0.2, 7.4]])
    cands = {c: Candidates(rig[c].project(X), np.full(3, 20.0), np.zeros(3, bool)) for c in rig.names}
    cams = tuple(rig.names)
    rows = np.array([[0, 0, 0], [1, 1, -1], [2, -1, -1], [0, 1, 2]])
    points, worst, ok = triangulate_rows(rig, cams, cands, rows, 2.0)
    np.testing.assert_allclose(points[:2], X[:2], atol=1e-9)
    assert ok.tolist() == [True, True, False, False]          # one view only; views of three markers
    assert np.isnan(points[2]).all() and worst[3] > 2.0
    again, worst_again, _ = triangulate_rows(rig, list(cams), cands, rows, 2.0)   # the kept [R | t] reused
    assert again.tobytes() == points.tobytes() and worst_again.tobytes() == worst.tobytes()
