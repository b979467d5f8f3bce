"""The pose smoothing settled on one record and reused on another (a long recording's passes)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap.params import PoseParams
from horsemocap.pose import SettledPoseSmoothing, fit_pose_trajectory, register_pose, settle_pose_smoothing

MODEL = np.array([[0.3, 0.0, 0.0], [0.0, 0.06, 0.0], [-0.2, -0.03, 0.02]])     # a thin triangle
COMPONENTS = ("cx", "cy", "cz", "phix", "phiy", "phiz")


def _record(n, seed, f0=1.6, fps=50.0):
    """A body swaying at the stride frequency ``f0`` with 2 mm marker noise, registered with covariances."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fps
    w = 2 * np.pi * f0 * t
    rot = np.column_stack([0.05 * np.sin(w), 0.03 * np.sin(2 * w + 0.4), 0.08 * np.sin(w + 1.0)])
    R = Rotation.from_rotvec(rot).as_matrix()
    centre = np.column_stack([3.0 * t, 0.04 * np.sin(2 * w), 0.02 * np.cos(w)])
    pts = np.einsum("kij,mj->kmi", R, MODEL) + centre[:, None] + rng.normal(0, 2e-3, (n, 3, 3))
    cov = np.broadcast_to(4e-6 * np.eye(3), (n, 3, 3, 3)).copy()
    cov[:, :, 2, 2] *= 6.0                                                    # depth less precise
    return t, pts, register_pose(pts, MODEL, covariance=cov)


def test_the_same_record_refitted_with_its_own_settled_choices_keeps_them():
    t, pts, reg = _record(120, 0)
    first = fit_pose_trajectory(t, reg, MODEL, points=pts)
    settled = settle_pose_smoothing(first)
    assert settled.method == "gcv" and settled.fundamental_hz == pytest.approx(1.6, rel=0.02)
    again = fit_pose_trajectory(t, reg, MODEL, points=pts, settled=settled)
    for c in COMPONENTS:
        a, b = first.smoothing[c], again.smoothing[c]
        assert b["lam"] == a["lam"] and b.get("weights", "equal") == a.get("weights", "equal"), c
        assert max(b.get("harmonic_indices") or [0]) <= max(a.get("harmonic_indices") or [0]), c
    assert again.smoothing_choice["reason"] == first.smoothing_choice["reason"]
    for c in ("cx", "cy", "cz"):         # no reweighting there: the very same fit
        assert again.smoothing[c]["edf"] == first.smoothing[c]["edf"], c
        assert again.smoothing[c].get("harmonic_indices") == first.smoothing[c].get("harmonic_indices"), c
    scale = np.nanmax(np.abs(first.omega(t)))
    assert np.nanmax(np.abs(again.omega(t) - first.omega(t))) < 0.05 * scale


def test_another_record_is_fitted_with_the_settled_choices_and_no_search():
    t, pts, reg = _record(120, 1)
    settled = settle_pose_smoothing(fit_pose_trajectory(t, reg, MODEL, points=pts))
    t2, pts2, reg2 = _record(60, 2)
    own = fit_pose_trajectory(t2, reg2, MODEL, points=pts2)
    reused = fit_pose_trajectory(t2, reg2, MODEL, points=pts2, settled=settled)
    for i, c in enumerate(COMPONENTS):
        info = reused.smoothing[c]
        assert info["lam"] == settled.lam[i], c
        assert max(info.get("harmonic_indices") or [0]) <= settled.harmonics[i], c
        assert "log_likelihood_equal" not in info, c           # one weighting fitted, not both compared
    assert reused.smoothing["phix"].get("weights", "equal") != "equal" or not settled.rotation_weighted[0]
    # the same body and motion: the saddle-like far point's acceleration stays close to the record's own choice
    far = np.array([0.0, -0.4, 0.1])
    a_own, a_reused = own.point(t2, far).acceleration, reused.point(t2, far).acceleration
    inner = slice(10, -10)
    rms = lambda a: float(np.sqrt(np.nanmean(a[inner] ** 2)))   # noqa: E731
    assert rms(a_reused) == pytest.approx(rms(a_own), rel=0.15)


def test_settled_adaptive_smoothing_chooses_its_parameters_again():
    t, pts, reg = _record(120, 3)
    tr = fit_pose_trajectory(t, reg, MODEL, PoseParams(smoothing="adaptive"), points=pts)
    settled = settle_pose_smoothing(tr, PoseParams(smoothing="adaptive"))
    assert settled.method == "adaptive" and settled.lam == (None,) * 6 and settled.fundamental_hz is None
    assert settled.choice is None and settled.harmonics == (0,) * 6
    again = fit_pose_trajectory(t, reg, MODEL, PoseParams(smoothing="adaptive"), points=pts, settled=settled)
    assert again.smoothing["cx"]["method"] == "adaptive"


def test_a_given_lam_takes_precedence_over_the_settled_one():
    t, pts, reg = _record(80, 4)
    settled = SettledPoseSmoothing("gcv", None, None, (1e-5,) * 6, (0,) * 6, (False,) * 3)
    tr = fit_pose_trajectory(t, reg, MODEL, points=pts, settled=settled, lam=[2e-5] + [None] * 5)
    assert tr.smoothing["cx"]["lam"] == 2e-5 and tr.smoothing["cy"]["lam"] == 1e-5
    assert "harmonics" not in tr.smoothing["phiz"] or tr.smoothing["phiz"]["harmonics"] == 0
