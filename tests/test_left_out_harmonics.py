"""The left-out choice with the stride's harmonics (horsemocap.pose.LEFT_OUT_HARMONICS, the ``fundamental_hz`` of
marker_cross_validation_per_component): on by default, and the route of the lower left-out score is
the one fitted, against a trot whose motion is exactly the stride's harmonics."""
from __future__ import annotations

import numpy as np
import pytest

from horsemocap import pose
from test_left_out_smoothing import _error, _fit, _trot


def test_the_harmonic_route_is_on_by_default_and_switched_off_says_nothing_of_it(monkeypatch):
    assert pose.LEFT_OUT_HARMONICS is True
    monkeypatch.setattr(pose, "LEFT_OUT_HARMONICS", False)
    t, pts, x, _, cov = _trot(0)
    choice = _fit("loo", t, pts, x, cov).smoothing_choice
    assert "routes" not in choice["cross_validation"] and "fundamental_hz" not in choice["cross_validation"]
    assert ", no harmonics: smoothing chosen by leaving each of the 5 markers out" in choice["reason"]


def test_candidates_with_the_stride_harmonics_predict_an_exactly_periodic_motion_better():
    """The trot's motion is the stride's first three harmonics plus a constant speed (in the penalty's null
    space): the partial splines predict the left-out markers better than the plain splines can, and their
    penalised part is smoothed more (the harmonics carry the motion)."""
    t, pts, x, _, cov = _trot(2)
    reg = pose.register_pose(pts, x, covariance=cov)
    f0 = pose._record_fundamental(t, reg.centre)[0]
    base = np.full(6, 1e-9)
    decades = pose.LEFT_OUT_DECADES
    _, plain = pose.marker_cross_validation_per_component(t, reg, pts, x, base, decades=decades)
    _, right = pose.marker_cross_validation_per_component(t, reg, pts, x, base, decades=decades, fundamental_hz=f0)
    assert right["cross_validation_score"] < plain["cross_validation_score"]
    assert max(right["cross_validation_component_decades"]) > max(plain["cross_validation_component_decades"])


def test_the_route_of_the_lower_score_is_fitted_and_named(monkeypatch):
    """With the harmonic route on, both routes are scored, the lower is fitted and the reason names it; on the
    exactly periodic trot it is the harmonic route, and its hidden-point acceleration is nearer the truth."""
    monkeypatch.setattr(pose, "LEFT_OUT_HARMONICS", True)
    monkeypatch.setattr(pose, "LEFT_OUT_STACK", False)   # one route, not the blend (test_left_out_stack.py)
    t, pts, x, acc, cov = _trot(2)
    tr = _fit("loo", t, pts, x, cov)
    choice = tr.smoothing_choice
    cv = choice["cross_validation"]
    assert set(cv["routes"]) == {"plain", "harmonics"}
    lower = min(cv["routes"], key=lambda k: cv["routes"][k][0])
    assert cv["cross_validation_score"] == pytest.approx(cv["routes"][lower][0])
    if lower == "harmonics":
        assert cv["fundamental_hz"] > 0 and "harmonics at" in choice["reason"]
        assert all(s.info.get("fundamental_hz") == cv["fundamental_hz"] for s in tr.centre_splines)
    else:
        assert cv["fundamental_hz"] is None and ", no harmonics:" in choice["reason"]
    assert lower == "harmonics"
    monkeypatch.setattr(pose, "LEFT_OUT_HARMONICS", False)
    plain = _fit("loo", t, pts, x, cov)
    assert _error(tr, t, acc) < _error(plain, t, acc)
