"""Known-answer and property tests of the pose-trajectory estimator (horsemocap.pose, splines)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import frames, pose, splines, synthetic
from horsemocap.camera import axis_rotations
from horsemocap.params import PoseParams

from test_rigid import random_rigid_motion


def _rel(est, true):
    return np.sqrt(np.nanmean(np.sum((est - true) ** 2, -1))) / np.sqrt(np.mean(np.sum(true ** 2, -1)))


@pytest.mark.parametrize("seed", range(4))
def test_exact_rigid_motion_gives_exact_derivatives(seed):
    """Noise-free rigid motion: interpolating quintic pose splines recover omega, alpha and a hidden
    point's velocity and acceleration to spline precision."""
    m = random_rigid_motion(np.random.default_rng(seed), n=301, markers=4, duration=1.2)
    model = m["body"]
    reg = pose.register_pose(m["pos"], model)
    assert np.nanmax(reg.residual) < 1e-12
    tr = pose.fit_pose_trajectory(m["t"], reg, model, PoseParams(smoothing="none"))
    t = m["t"]
    assert _rel(tr.omega(t), m["omega"]) < 1e-4
    assert _rel(tr.alpha(t)[5:-5], m["alpha"][5:-5]) < 1e-3
    k = tr.points(t, model)
    np.testing.assert_allclose(k.position, m["pos"], atol=1e-9)
    assert _rel(k.velocity, m["vel"]) < 1e-4
    assert _rel(k.acceleration[5:-5], m["acc"][5:-5]) < 1e-3


def test_gcv_on_exact_motion_stays_exact():
    """With no noise, cross-validation chooses (almost) no smoothing."""
    m = random_rigid_motion(np.random.default_rng(7), n=200, markers=3, duration=1.0)
    reg = pose.register_pose(m["pos"], m["body"])
    tr = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="gcv"))
    assert _rel(tr.omega(m["t"]), m["omega"]) < 1e-3


def test_jacobian_formulas_match_finite_differences():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 2001)
    a, f, p = rng.normal(0, 1.2, 3), rng.uniform(0.5, 2, 3), rng.uniform(0, 6, 3)
    phi = a * np.sin(2 * np.pi * f * t[:, None] + p)
    dphi = a * 2 * np.pi * f * np.cos(2 * np.pi * f * t[:, None] + p)
    ddphi = -a * (2 * np.pi * f) ** 2 * np.sin(2 * np.pi * f * t[:, None] + p)
    R = Rotation.from_rotvec(phi).as_matrix()
    dt = t[1] - t[0]
    W = np.gradient(R, dt, axis=0) @ np.swapaxes(R, 1, 2)
    w_fd = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1)
    w = pose.angular_velocity_from_rotvec(phi, dphi)
    np.testing.assert_allclose(w[3:-3], w_fd[3:-3], atol=1e-3 * np.abs(w).max())
    al = pose.angular_acceleration_from_rotvec(phi, dphi, ddphi)
    np.testing.assert_allclose(al[3:-3], np.gradient(w, dt, axis=0)[3:-3], atol=1e-3 * np.abs(al).max())
    # near zero rotation the series branch agrees with the closed form
    small = np.array([[1e-3, -2e-3, 5e-4]])
    J = pose.left_jacobian(small)
    assert np.allclose(J[0], np.eye(3) + 0.5 * np.array(
        [[0, -small[0, 2], small[0, 1]], [small[0, 2], 0, -small[0, 0]], [-small[0, 1], small[0, 0], 0]]), atol=1e-6)


def test_missing_marker_still_gives_a_pose_and_gaps_are_reasoned():
    m = random_rigid_motion(np.random.default_rng(1), n=120, markers=4, duration=1.0)
    pts = m["pos"].copy()
    pts[10:20, 2] = np.nan                 # one marker hidden: 3 remain
    pts[40:42, :2] = np.nan                # two hidden: no pose, short gap (bridged)
    pts[70:90, 1:] = np.nan                # long gap: NaN
    reg = pose.register_pose(pts, m["body"])
    assert np.all(np.isfinite(reg.rotation[10:20]))
    np.testing.assert_allclose(reg.registered[10:20], m["pos"][10:20], atol=1e-9)
    assert np.all(reg.n_markers[10:20] == 3)
    assert reg.reason[40].startswith("only 2 marker(s) visible")
    tr = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="none"))
    assert tr.valid[40] and "bridged gap of 2" in tr.reason[40]
    assert not tr.valid[75] and "gap of 20 frames" in tr.reason[75]
    assert np.all(np.isnan(tr.omega(m["t"])[75]))
    assert np.all(np.isfinite(tr.omega(m["t"])[40]))


def test_weights_zero_is_the_same_as_a_missing_marker():
    m = random_rigid_motion(np.random.default_rng(2), n=30, markers=4)
    noisy = m["pos"] + np.random.default_rng(0).normal(0, 1e-3, m["pos"].shape)
    w = np.array([1.0, 2.0, 0.5, 0.0])
    a = pose.register_pose(noisy, m["body"], weights=w)
    pts = noisy.copy()
    pts[:, 3] = np.nan
    b = pose.register_pose(pts, m["body"], weights=w)
    np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-12)


def test_collinear_markers_are_refused_and_never_give_numbers():
    line = np.array([[0.0, 0, 0], [0.2, 0, 0], [0.5, 0, 0]])
    with pytest.raises(pose.CollinearMarkersError, match="collinear"):
        pose.register_pose(np.broadcast_to(line, (5, 3, 3)), line)
    nearly = line + [[0, 0, 0], [0, 0, 0], [0, 1e-4, 0]]
    with pytest.raises(pose.CollinearMarkersError):
        pose.check_model_conditioning(nearly)
    thin = line + [[0, 0, 0], [0, 0, 0], [0, 0.004, 0]]
    with pytest.raises(pose.CollinearMarkersError, match="3 times the marker noise"):
        pose.check_model_conditioning(thin, noise_m=0.002)
    # 4 markers, of which the 3 left visible in a frame are collinear: that frame has no pose
    model = np.vstack([line, [[0.1, 0.1, 0.0]]])
    pts = np.broadcast_to(model, (4, 4, 3)).copy()
    pts[2, 3] = np.nan
    reg = pose.register_pose(pts, model)
    assert np.all(np.isnan(reg.rotation[2])) and "collinear" in reg.reason[2]
    assert np.all(np.isfinite(reg.rotation[[0, 1, 3]]))


def test_smallest_height_known_answer():
    tri = np.array([[0.0, 0, 0], [0.4, 0, 0], [0.1, 0.05, 0]])
    assert pose.smallest_height(tri) == pytest.approx(0.05)


def test_thin_triangle_is_warned():
    m = synthetic.lift_with_ringing(noise_m=1e-3, duration_s=1.0)
    model = m["model"][:3].copy()
    model[2] = [0.0, 0.1, 0.151]        # 1 mm from the line through markers 1, 2
    pts = np.einsum("kij,mj->kmi", m["R"], model) + m["markers_true"][:, :1] - (m["R"] @ m["model"][0])[:, None]
    pts += np.random.default_rng(0).normal(0, 1e-4, pts.shape)
    reg = pose.register_pose(pts, model)
    assert any("thin marker triangle" in w for w in pose.conditioning_warnings(reg, 0.5))


def test_noise_of_the_ringing_fixture_is_measured_from_the_residuals():
    d = synthetic.lift_with_ringing(seed=1)
    reg = pose.register_pose(d["markers"], d["model"])
    assert reg.noise_m == pytest.approx(d["noise_m"], rel=0.05)


@pytest.mark.parametrize("extra", [{}, {"ring_hz": 6.0, "second_ring_hz": 14.0, "ring_decay_s": 0.5,
                                       "ring_rise_s": 0.03, "ring_start_s": 2.9}])
def test_synthetic_truth_is_consistent(extra):
    """The exact kinematics of the fixture (and of the second one, bench_kinematics.py --fixture
    second) agree with finite differences of its positions."""
    d = synthetic.lift_with_ringing(fps=2000.0, duration_s=4.0, noise_m=0.0, **extra)
    dt = 1 / 2000.0
    onset = extra.get("ring_start_s", 2.8)
    # away from the ringing's onset, where the jerk jumps (finite differences are poor there)
    keep = (np.abs(d["t"] - onset) > 0.005) & (d["t"] > 0.002) & (d["t"] < 3.998)
    v = np.gradient(d["hidden_pos"], dt, axis=0)
    np.testing.assert_allclose(v[keep], d["hidden_vel"][keep], atol=2e-3)
    a = np.gradient(d["hidden_vel"], dt, axis=0)
    np.testing.assert_allclose(a[keep], d["hidden_acc"][keep], atol=0.05)


def test_smoothing_spline_recovers_a_noisy_polynomial():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 2, 200)
    y = 0.5 * t ** 3 - t + 0.2
    s = splines.smoothing_spline(t, y + rng.normal(0, 1e-3, t.size))
    assert np.max(np.abs(s(t, 2) - 3 * t)[10:-10]) < 0.1 * 6.0     # 10 % of the largest |y''|
    with pytest.raises(ValueError, match="finite"):
        splines.smoothing_spline(t, np.where(t > 1, np.nan, y))


def test_motion_frame_from_record_needs_no_period():
    rng = np.random.default_rng(0)
    n = 57
    t = np.arange(n) / 30
    heading = np.array([0.8, 0.0, 0.6])
    travel = 4.0 * t[:, None] * heading
    sway = 0.02 * np.sin(2 * np.pi * 1.3 * t)[:, None] * np.array([-0.6, 0, 0.8])   # not whole periods
    body = rng.normal(0, 0.1, (3, 3))
    pts = travel[:, None] + sway[:, None] + body[None]
    g = np.array([0.0, 1.0, 0.0])
    mf = frames.motion_frame_from_record(pts, g)
    assert frames.angle_deg(mf.axes[0], heading) < 0.6
    assert np.allclose(mf.axes[1], g) and np.isnan(mf.period_frames)
    np.testing.assert_allclose(mf.axes @ mf.axes.T, np.eye(3), atol=1e-12)
    with pytest.raises(ValueError, match="no horizontal part"):
        frames.motion_frame_from_record(np.broadcast_to(body, (5, 3, 3)) + np.arange(5)[:, None, None] * g, g)


def test_saddle_angles_known_answer():
    axes0 = pose.static_body_axes(np.array([[0.0, 0, 0], [0.5, 0.01, 0], [0.25, 0, 0.05]]))
    np.testing.assert_allclose(axes0[:, 1], [0, 1, 0])
    assert axes0[0, 0] > 0.99
    R = axis_rotations("x", np.radians([10.0]))          # roll 10 deg about x-motion
    ang = pose.saddle_angles_deg(R, np.eye(3))
    np.testing.assert_allclose(ang[0], [10, 0, 0], atol=1e-9)
    R = axis_rotations("z", np.radians([-4.0]))
    np.testing.assert_allclose(pose.saddle_angles_deg(R, np.eye(3))[0], [0, -4, 0], atol=1e-9)


def test_partial_pose_fits_the_two_markers_and_keeps_only_the_roll_about_their_line():
    """Two visible markers: the pose matches them exactly; of the predicted rotation only the turn
    about their line survives (a prediction that is the truth gives the truth)."""
    m = random_rigid_motion(np.random.default_rng(11), n=20, markers=3)
    pts = m["pos"].copy()
    pts[:, 2] = np.nan
    d = m["body"] - m["body"].mean(0)
    c_true = m["c"] + np.einsum("kij,j->ki", m["R"], m["body"].mean(0))
    R, c = pose.partial_pose(pts, m["body"], m["R"], c_true)
    np.testing.assert_allclose(R, m["R"], atol=1e-9)
    np.testing.assert_allclose(c, c_true, atol=1e-9)
    # a wrong prediction: the two markers still match, and R differs from the truth by a rotation
    # about the line through them
    rng = np.random.default_rng(5)
    Rp = Rotation.from_rotvec(rng.normal(0, 0.2, (20, 3))).as_matrix() @ m["R"]
    R, c = pose.partial_pose(pts, m["body"], Rp, c_true + rng.normal(0, 0.05, (20, 3)))
    moved = np.einsum("kij,mj->kmi", R, d) + c[:, None]
    np.testing.assert_allclose(moved[:, :2], m["pos"][:, :2], atol=1e-9)
    diff = Rotation.from_matrix(R @ np.swapaxes(m["R"], 1, 2)).as_rotvec()
    line = np.einsum("kij,j->ki", m["R"], d[1] - d[0])
    line /= np.linalg.norm(line, axis=1, keepdims=True)
    np.testing.assert_allclose(np.linalg.norm(np.cross(diff, line), axis=1), 0, atol=1e-9)
    with pytest.raises(ValueError, match="exactly two visible markers"):
        pose.partial_pose(m["pos"], m["body"], m["R"], c_true)


def test_frames_with_two_markers_beyond_the_ends_reduce_the_end_error():
    """A noisy rigid motion whose first and last 4 frames show two markers only: smoothing over them
    (partial=True) gives a smaller acceleration error in the frames with three markers than
    smoothing those frames alone, and the partial frames are reasoned."""
    errs = {True: [], False: []}
    for seed in range(3):
        rng = np.random.default_rng(20 + seed)
        m = random_rigid_motion(rng, n=60, markers=3, duration=1.0)
        pts = m["pos"] + rng.normal(0, 5e-4, m["pos"].shape)
        pts[:4, 2] = np.nan
        pts[-4:, 0] = np.nan
        reg = pose.register_pose(pts, m["body"])
        inner = slice(4, -4)
        for partial in (True, False):
            tr = pose.fit_pose_trajectory(m["t"], reg, m["body"], PoseParams(smoothing="gcv", partial_frames=partial),
                                          points=pts)
            k = tr.points(m["t"], m["body"])
            errs[partial].append(_rel(k.acceleration[inner], m["acc"][inner]))
            if partial:
                assert tr.valid.all() and tr.reason[0].startswith("partial pose: 2 markers")
            else:
                assert not tr.valid[0] and "outside the frames with a pose" in tr.reason[0]
    assert np.median(errs[True]) < np.median(errs[False])


def test_pose_margin_widens_the_segment_over_frames_with_two_markers():
    from horsemocap.steps import pose_margin

    pts = np.full((12, 3, 3), np.nan)
    counts = [0, 1, 2, 2, 3, 3, 3, 3, 2, 1, 2, 3]
    for k, c in enumerate(counts):
        pts[k, :c] = 1.0
    assert pose_margin(pts, (4, 8)) == (2, 9)
    assert pose_margin(pts, (4, 8), min_markers=1) == (1, 12)
    assert pose_margin(pts, (4, 8), min_markers=3) == (4, 8)


def test_frames_without_a_pose_name_the_missing_markers():
    model = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    pts = np.tile(model, (3, 1, 1))
    pts[1, [1, 2]] = np.nan
    assert "missing: marker2, marker3" in pose.register_pose(pts, model).reason[1]
    reg = pose.register_pose(pts, model, names=["LASI", "RASI", "LPSI", "RPSI"])
    assert "missing: RASI, LPSI" in reg.reason[1] and reg.reason[0] == ""


def test_a_fundamental_under_two_cycles_is_taken_when_another_estimator_agrees():
    """1.97 cycles of a 1.41 Hz motion: the record's own search (2 cycles at least) finds none; searched
    down to 1.5 cycles it finds 1.41 Hz, kept only when another estimate (the motion frame's) agrees."""
    t = np.arange(36) / 25.0
    w = 2 * np.pi * 1.4065
    Y = np.column_stack([0.02 * np.sin(w * t) + 0.03 * np.sin(2 * w * t + 1), 0.01 * np.cos(w * t),
                         0.004 * np.sin(3 * w * t)]) + 1e-5 * np.random.default_rng(0).normal(size=(36, 3))
    with pytest.raises(ValueError, match="no period resolved"):
        splines.estimate_fundamental(t, Y)
    f, note = pose._record_fundamental(t, Y, None)
    assert f is None and note == ""
    f, note = pose._record_fundamental(t, Y, 1.405)
    assert f == pytest.approx(1.4065, rel=1e-3) and "confirmed by the stride period" in note
    f, _ = pose._record_fundamental(t, Y, 2.81)                 # the other estimate disagrees: none
    assert f is None
