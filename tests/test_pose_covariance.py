"""Pose registration weighted by the markers' 3 x 3 covariances (horsemocap.pose, reconstruction).

Known answers: an exact rigid motion gives the exact pose; equal isotropic covariances give Horn's
answer; with anisotropic noise the weighted registration beats Horn's in expectation, and the pose
noise it predicts is the one measured; the triangulation's covariance is the one its points show
under pixel noise.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, reconstruction
from horsemocap.virtuallab.rig import thesis_rig

MODEL = np.array([[0.0, 0.0, 0.0], [0.32, 0.02, 0.01], [0.15, -0.03, 0.12], [0.24, 0.05, -0.09]])


def _poses(rng, n):
    R = Rotation.random(n, random_state=rng.integers(1 << 31)).as_matrix()
    t = rng.normal(0, 1.0, (n, 3))
    return R, t


def _moved(model, R, t):
    return np.einsum("kij,mj->kmi", R, model) + t[:, None]


def _random_spd(rng, shape, scale):
    A = rng.normal(size=shape + (3, 3))
    return scale ** 2 * (A @ np.swapaxes(A, -1, -2) + 0.05 * np.eye(3))


def _rotation_error(R_est, R_true):
    """Per-frame rotation error vectors (rad), R_est = Exp(e) R_true."""
    return Rotation.from_matrix(R_est @ np.swapaxes(R_true, 1, 2)).as_rotvec()


def test_exact_rigid_motion_gives_exact_pose():
    rng = np.random.default_rng(0)
    R, t = _poses(rng, 300)
    pts = _moved(MODEL, R, t)
    cov = _random_spd(rng, (300, 4), 1e-3)
    reg = pose.register_pose(pts, MODEL, covariance=cov)
    np.testing.assert_allclose(reg.rotation, R, atol=1e-12)
    np.testing.assert_allclose(reg.translation, t, atol=1e-12)
    assert np.nanmax(reg.residual) < 1e-12
    assert reg.extra_noise_m == 0.0 and reg.covariance_scale < 1e-8
    assert reg.information.shape == (300, 6, 6) and np.all(np.isfinite(reg.information))


def test_missing_marker_exact_pose_and_nan_frames():
    """A frame with one of four markers missing still has its exact pose; one with two missing is NaN."""
    rng = np.random.default_rng(1)
    R, t = _poses(rng, 20)
    pts = _moved(MODEL, R, t)
    pts[3, 1] = np.nan
    pts[7, [0, 2]] = np.nan
    cov = _random_spd(rng, (20, 4), 1e-3)
    cov[3, 1] = np.nan                           # a missing marker's covariance is not used
    reg = pose.register_pose(pts, MODEL, covariance=cov)
    np.testing.assert_allclose(reg.rotation[3], R[3], atol=1e-12)
    assert np.all(np.isnan(reg.rotation[7])) and "only 2 marker(s)" in reg.reason[7]
    assert np.all(np.isnan(reg.information[7]))


def test_equal_isotropic_covariances_give_horns_answer():
    rng = np.random.default_rng(2)
    R, t = _poses(rng, 200)
    noisy = _moved(MODEL, R, t) + rng.normal(0, 2e-3, (200, 4, 3))
    horn = pose.register_pose(noisy, MODEL)
    for s0 in ("estimate", 0.0, 1e-3):
        cov = np.broadcast_to(3e-6 * np.eye(3), (200, 4, 3, 3))
        reg = pose.register_pose(noisy, MODEL, covariance=cov, extra_noise=s0)
        np.testing.assert_allclose(reg.rotation, horn.rotation, atol=1e-11)
        np.testing.assert_allclose(reg.translation, horn.translation, atol=1e-12)


def _anisotropic_draws(rng, n, depth_sd, across_sd):
    """Each marker's noise long along its own direction (a camera's depth), short across it."""
    dirs = Rotation.random(4, random_state=rng.integers(1 << 31)).as_matrix()       # (4, 3, 3) columns
    sd = np.array([across_sd, across_sd, depth_sd])
    cov = np.einsum("mij,j,mkj->mik", dirs, sd ** 2, dirs)
    z = rng.normal(size=(n, 4, 3)) * sd
    noise = np.einsum("mij,kmj->kmi", dirs, z)
    return np.broadcast_to(cov, (n, 4, 3, 3)), noise


@pytest.mark.parametrize("extra_noise", ["estimate", 0.0])
def test_anisotropic_noise_weighted_beats_horn(extra_noise):
    """Depth noise 10 times the noise across (different directions per marker), 4000 frames: the
    weighted registration's mean squared rotation error is a fraction of Horn's. Linearised, the
    ratio is the generalised least squares' against ordinary least squares' variance (about 0.1
    here); the assertion (below 0.5) leaves a margin of many standard errors (relative standard
    error of a mean square over 4000 frames: about 2 %)."""
    rng = np.random.default_rng(3)
    n = 4000
    R, t = _poses(rng, n)
    cov, noise = _anisotropic_draws(rng, n, depth_sd=5e-3, across_sd=5e-4)
    noisy = _moved(MODEL, R, t) + noise
    horn = pose.register_pose(noisy, MODEL)
    reg = pose.register_pose(noisy, MODEL, covariance=cov, extra_noise=extra_noise)
    e_h = _rotation_error(horn.rotation, R)
    e_w = _rotation_error(reg.rotation, R)
    ratio_rot = np.mean(np.sum(e_w ** 2, 1)) / np.mean(np.sum(e_h ** 2, 1))
    ratio_pos = np.mean(np.sum((reg.centre - _moved(MODEL.mean(0)[None], R, t)[:, 0]) ** 2, 1)) / np.mean(
        np.sum((horn.centre - _moved(MODEL.mean(0)[None], R, t)[:, 0]) ** 2, 1))
    assert ratio_rot < 0.5 and ratio_pos < 0.5
    assert reg.covariance_scale == pytest.approx(1.0, abs=0.05)
    if extra_noise == "estimate":                 # the covariances explain the residuals: s0 about 0
        assert reg.extra_noise_m < 2e-4


def test_predicted_pose_noise_is_the_measured_one():
    """pose_noise from the information matrices (no points) against the spread of the rotation and
    centroid errors of a fixed pose over 4000 draws (expressed in the moved frame: R = Exp(e) R_true)."""
    rng = np.random.default_rng(4)
    n = 4000
    R0 = Rotation.from_rotvec([0.2, -0.4, 0.1]).as_matrix()
    R = np.broadcast_to(R0, (n, 3, 3))
    t = np.zeros((n, 3))
    cov, noise = _anisotropic_draws(rng, n, depth_sd=4e-3, across_sd=1e-3)
    reg = pose.register_pose(_moved(MODEL, R, t) + noise, MODEL, covariance=cov, extra_noise=0.0)
    got = pose.pose_noise(reg, None, MODEL)
    measured = np.r_[np.std(reg.centre - R0 @ MODEL.mean(0), axis=0),
                     np.std(_rotation_error(reg.rotation, R), axis=0)]
    np.testing.assert_allclose(got, measured, rtol=0.06)       # standard error of a std over 4000: 1.1 %


def test_extra_noise_is_recovered():
    """Markers with the given covariances plus an isotropic 1.5 mm the covariances do not hold."""
    rng = np.random.default_rng(5)
    n = 3000
    R, t = _poses(rng, n)
    cov, noise = _anisotropic_draws(rng, n, depth_sd=3e-3, across_sd=5e-4)
    noisy = _moved(MODEL, R, t) + noise + rng.normal(0, 1.5e-3, (n, 4, 3))
    reg = pose.register_pose(noisy, MODEL, covariance=cov)
    assert reg.extra_noise_m == pytest.approx(1.5e-3, rel=0.05)
    assert reg.covariance_scale > 1.5


def test_extra_marker_noise_known_answer():
    """Isotropic covariances lam I and residuals of squared norm S over dof: s0^2 = S / dof - lam."""
    rng = np.random.default_rng(6)
    e = rng.normal(0, 1e-3, (600, 3))
    lam = 2e-7
    cov = np.broadcast_to(lam * np.eye(3), (600, 3, 3))
    dof = 1500.0
    got = pose.extra_marker_noise(e, cov, dof)
    assert got == pytest.approx(np.sqrt(np.sum(e ** 2) / dof - lam), rel=1e-8)
    assert pose.extra_marker_noise(1e-4 * e, cov, dof) == 0.0


def test_covariance_input_errors():
    pts = _moved(MODEL, *_poses(np.random.default_rng(7), 5))
    cov = np.broadcast_to(1e-6 * np.eye(3), (5, 4, 3, 3)).copy()
    with pytest.raises(ValueError, match="expected .*frames, markers, 3, 3"):
        pose.register_pose(pts, MODEL, covariance=cov[:, :3])
    with pytest.raises(ValueError, match="weights and covariance"):
        pose.register_pose(pts, MODEL, weights=np.ones(4), covariance=cov)
    bad = cov.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="not finite for visible marker 2 in frame 2"):
        pose.register_pose(pts, MODEL, covariance=bad)
    bad = cov.copy()
    bad[4, 3] = np.diag([1e-6, 1e-6, -1e-6])
    with pytest.raises(ValueError, match="not positive definite for visible marker 4 in frame 4"):
        pose.register_pose(pts, MODEL, covariance=bad)
    with pytest.raises(ValueError, match="extra_noise"):
        pose.register_pose(pts, MODEL, covariance=cov, extra_noise=-1.0)


# --------------------------------------------------------------------------
# the triangulation's covariance
# --------------------------------------------------------------------------
def _rig_draws(rng, sigma_px, n_draws, points):
    rig = thesis_rig()
    px0 = {c.name: c.project(points) for c in rig.cameras}
    draws = {c: px0[c][None] + rng.normal(0, sigma_px, (n_draws,) + px0[c].shape) for c in px0}
    return rig, draws


def test_point_covariance_matches_the_spread_of_triangulated_points():
    """Three points 7.5 m in front of the thesis rig, 0.3 px of white noise, 3000 draws: the
    covariance (noise estimated from the residuals) is the sample covariance of the points."""
    rng = np.random.default_rng(8)
    points = np.array([[0.5, 0.2, 7.5], [-0.4, 0.1, 7.2], [0.1, -0.3, 7.8]])
    rig, draws = _rig_draws(rng, 0.3, 3000, points)
    tri = reconstruction.triangulate(rig, draws, covariance=True)
    assert tri.noise_px == pytest.approx(0.3, rel=0.03)
    for j in range(3):
        sample = np.cov(tri.points[:, j].T)
        predicted = np.median(tri.covariance[:, j], axis=0)
        # compare along the principal axes (depth variance is ~100 times the others)
        lam, U = np.linalg.eigh(predicted)
        np.testing.assert_allclose(np.diag(U.T @ sample @ U), lam, rtol=0.1)
        assert lam[-1] / lam[0] > 20                   # depth far less certain than across the rays


def test_covariance_off_by_default_and_nan_where_no_point():
    rng = np.random.default_rng(9)
    points = np.array([[0.5, 0.2, 7.5], [-0.4, 0.1, 7.2]])
    rig, draws = _rig_draws(rng, 0.2, 5, points)
    assert reconstruction.triangulate(rig, draws).covariance is None
    draws["middle"][2, 0] = np.nan
    draws["right"][2, 0] = np.nan                      # seen by the left camera only
    tri = reconstruction.triangulate(rig, draws, covariance=True)
    assert np.all(np.isnan(tri.covariance[2, 0])) and np.all(np.isfinite(tri.covariance[2, 1]))


def test_pixel_noise_known_answer():
    """Residual distances r with k cameras: sigma^2 = sum r^2 / sum (2k - 3); rejected ones left out."""
    r = {"a": np.array([[1.0, 2.0]]), "b": np.array([[1.0, 2.0]]), "c": np.array([[1.0, 50.0]])}
    used = {"a": np.array([[True, True]]), "b": np.array([[True, True]]), "c": np.array([[True, False]])}
    # point 1: 3 cameras, 3 dof, sum 3; point 2: 2 cameras, 1 dof, sum 8
    assert reconstruction.pixel_noise(r, used) == pytest.approx(np.sqrt(11 / 4))


def test_nearest_covariance_fills_interpolated_positions():
    cov = np.full((6, 1, 3, 3), np.nan)
    cov[0], cov[4] = np.eye(3), 4 * np.eye(3)
    fill = np.zeros((6, 1), bool)
    fill[[1, 2, 3, 5], 0] = True
    got = reconstruction.nearest_covariance(cov, fill)[:, 0, 0, 0]
    np.testing.assert_array_equal(got, [1, 1, 1, 4, 4, 4])


def test_weighted_cost_never_above_horns_with_huge_noise():
    """Errors far beyond the linearisation (noise of half the marker spacing, depth 20 times the rest):
    every frame's weighted cost at the result is at most that of Horn's pose it starts from."""
    rng = np.random.default_rng(10)
    n = 500
    R, t = _poses(rng, n)
    cov, noise = _anisotropic_draws(rng, n, depth_sd=0.15, across_sd=0.0075)
    noisy = _moved(MODEL, R, t) + noise
    W = np.linalg.inv(cov)
    horn = pose.register_pose(noisy, MODEL)
    reg = pose.register_pose(noisy, MODEL, covariance=cov, extra_noise=0.0)

    def cost(r):
        e = noisy - r.registered
        return np.einsum("kmi,kmij,kmj->k", e, W, e)

    assert np.all(cost(reg) <= cost(horn) * (1 + 1e-9))
    assert np.median(cost(reg) / cost(horn)) < 0.9                # and usually well below


def test_pose_weights_parameter_reaches_the_registration():
    """``pose_weights``: "covariance" (default) weights the markers by their triangulation covariance in
    the bundled session's rigid-body step; "equal" gives Horn's registration, as the thesis preset."""
    from horsemocap.data import default_session_dir
    from horsemocap.pipeline import analyze, run_steps

    base = analyze(default_session_dir(), None, {}, until="motion_frame", progress=lambda *a: None)
    assert base.triangulate.covariance is not None
    out = {w: run_steps(base.session, base.params.updated({"rigid_body.pose.weights": w}), base, ["rigid_body"])
           for w in ("covariance", "equal")}
    cov, equal = (out[w].rigid_body for w in ("covariance", "equal"))
    # the residual of the weighted fit is larger (depth keeps its residual) and the saddle moves
    rms = {w: np.nanmedian(r.conditioning.registration_rms_m) for w, r in (("covariance", cov), ("equal", equal))}
    assert rms["covariance"] > rms["equal"]
    assert not np.allclose(cov.saddle_acceleration, equal.saddle_acceleration)


def test_pose_rotation_weights_parameter_reaches_the_rotation_smoothing():
    """``pose_rotation_weights``: "auto" (default) lets the rotation components be smoothed with each frame
    weighted by its predicted variance (on the bundled session at least one component takes it and the
    saddle moves); "equal" smooths every frame alike; an unknown value is refused."""
    from horsemocap.data import default_session_dir
    from horsemocap.params import AnalysisParams, ParamsError
    from horsemocap.pipeline import analyze, run_steps

    assert AnalysisParams().rigid_body.pose.rotation_weights == "auto"
    with pytest.raises(ParamsError, match="pose_rotation_weights"):
        AnalysisParams.from_dict({"pose_rotation_weights": "inverse"})
    base = analyze(default_session_dir(), None, {}, until="motion_frame", progress=lambda *a: None)
    out = {w: run_steps(base.session, base.params.updated({"rigid_body.pose.rotation_weights": w}), base,
                     ["rigid_body"]).rigid_body for w in ("auto", "equal")}
    chosen = {w: [out[w].body.pose.smoothing[c].get("weights", "equal") for c in ("phix", "phiy", "phiz")]
              for w in out}
    assert "inverse variance, Huber" in chosen["auto"]
    assert chosen["equal"] == ["equal"] * 3
    assert not np.allclose(out["auto"].saddle_acceleration, out["equal"].saddle_acceleration)
