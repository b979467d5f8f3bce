"""Property tests of horsemocap.rigid on random rigid motions with exact truth."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from scipy.spatial.transform import Rotation

from horsemocap import rigid
from horsemocap.camera import axis_rotations
from horsemocap.params import FitsParams, PoseParams, RigidBodyParams


def _rotation_of_quaternion(q):
    """Rotation matrix of a quaternion written scalar first, as the thesis does (eq. 5.15, 5.16)."""
    return Rotation.from_quat(np.roll(q, -1)).as_matrix()


def _params(kinematics="fits", angular_method="thesis", x_degree=1, pose_smoothing="adaptive"):
    """The section with the choices that were ``analyse_rigid_body``'s defaults before it took a section
    (the thesis' chain, its six versions averaged, adaptive pose smoothing without partial frames)."""
    return RigidBodyParams(kinematics=kinematics, fits=FitsParams(x_degree=x_degree, angular_method=angular_method),
                           pose=PoseParams(smoothing=pose_smoothing, partial_frames=False))


# --------------------------------------------------------------------------
# exact random rigid motions
# --------------------------------------------------------------------------
def random_rigid_motion(rng, n=40, markers=4, duration=1.2):
    """A body with ``markers`` points moving with R(t) = Rz(th1) Ry(th2) Rx(th3)
    and translation c(t) (sums of sines), with analytic omega and alpha."""
    t = np.linspace(0, duration, n)
    body = rng.normal(0, 0.15, (markers, 3))
    amp, fr, ph = rng.normal(0, 0.6, 3), rng.uniform(0.5, 3, 3), rng.uniform(0, 2 * np.pi, 3)
    th = amp * np.sin(2 * np.pi * fr * t[:, None] + ph)
    thd = amp * 2 * np.pi * fr * np.cos(2 * np.pi * fr * t[:, None] + ph)
    thdd = -amp * (2 * np.pi * fr) ** 2 * np.sin(2 * np.pi * fr * t[:, None] + ph)
    camp, cfr, cph = rng.normal(0, 0.3, 3), rng.uniform(0.5, 3, 3), rng.uniform(0, 6, 3)
    vx = rng.uniform(2, 5)
    c = camp * np.sin(2 * np.pi * cfr * t[:, None] + cph) + np.outer(t, [vx, 0, 0])
    cd = camp * 2 * np.pi * cfr * np.cos(2 * np.pi * cfr * t[:, None] + cph) + [vx, 0, 0]
    cdd = -camp * (2 * np.pi * cfr) ** 2 * np.sin(2 * np.pi * cfr * t[:, None] + cph)
    Rz, Ry, Rx = axis_rotations("z", th[:, 0]), axis_rotations("y", th[:, 1]), axis_rotations("x", th[:, 2])
    R = Rz @ Ry @ Rx
    ez, ey, ex = np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]
    a1 = np.broadcast_to(ez, (n, 3))
    a2 = Rz @ ey
    a3 = (Rz @ Ry) @ ex
    w12 = thd[:, [0]] * a1 + thd[:, [1]] * a2
    omega = w12 + thd[:, [2]] * a3
    alpha = (thdd[:, [0]] * a1 + thdd[:, [1]] * a2 + thd[:, [1]] * np.cross(thd[:, [0]] * a1, a2)
             + thdd[:, [2]] * a3 + thd[:, [2]] * np.cross(w12, a3))
    rb = np.einsum("kij,mj->kmi", R, body)
    pos = rb + c[:, None]
    w = omega[:, None]
    vel = np.cross(w, rb) + cd[:, None]
    acc = np.cross(alpha[:, None], rb) + np.cross(w, np.cross(w, rb)) + cdd[:, None]
    return dict(t=t, R=R, c=c, body=body, omega=omega, alpha=alpha, pos=pos, vel=vel, acc=acc)


SEEDS = range(12)


def test_generator_is_consistent():
    """The analytic omega/alpha are those of R(t): R' R^T = [omega]x, and v, a
    agree with finite differences of the positions."""
    m = random_rigid_motion(np.random.default_rng(0), n=4001, duration=1.0)
    dt = m["t"][1] - m["t"][0]
    Rd = np.gradient(m["R"], dt, axis=0)
    W = Rd @ np.swapaxes(m["R"], 1, 2)
    w = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1)
    np.testing.assert_allclose(w[5:-5], m["omega"][5:-5], atol=1e-4)
    np.testing.assert_allclose(np.gradient(m["omega"], dt, axis=0)[5:-5], m["alpha"][5:-5], atol=2e-3)
    np.testing.assert_allclose(np.gradient(m["pos"], dt, axis=0)[5:-5], m["vel"][5:-5], atol=1e-4)


@pytest.mark.parametrize("seed", SEEDS)
def test_register_recovers_pose_exactly(seed):
    rng = np.random.default_rng(seed)
    m = random_rigid_motion(rng)
    model = m["body"][:3] + rng.normal(0, 1, 3)          # static shot somewhere else
    # the model's pose: pos = R body + c = R (model - d) + c
    d = model - m["body"][:3]
    reg = rigid.register(m["pos"][:, :3], model)
    np.testing.assert_allclose(reg.rotation, m["R"], atol=1e-12)
    np.testing.assert_allclose(reg.translation, m["c"] - np.einsum("kij,j->ki", m["R"], d[0]), atol=1e-12)
    np.testing.assert_allclose(reg.registered, m["pos"][:, :3], atol=1e-12)
    assert np.all(reg.residual < 1e-12)
    # rotations proper
    np.testing.assert_allclose(np.linalg.det(reg.rotation), 1, atol=1e-12)


def test_register_noisy_is_rigid_and_reduces_error():
    rng = np.random.default_rng(3)
    m = random_rigid_motion(rng, markers=3)
    noisy = m["pos"] + rng.normal(0, 0.01, m["pos"].shape)
    noisy[7, 1] = np.nan
    reg = rigid.register(noisy, m["body"])
    d_model = rigid.pairwise_distances(m["body"])
    ok = np.ones(len(noisy), bool)
    ok[7] = False
    np.testing.assert_allclose(rigid.pairwise_distances(reg.registered[ok]), np.broadcast_to(d_model, (ok.sum(), 3, 3)), atol=1e-12)
    assert np.all(np.isnan(reg.registered[7])) and reg.reason[7] == "marker(s) 2 missing"
    assert np.all(reg.reason[ok] == "")
    err_before = np.sqrt(np.mean((noisy[ok] - m["pos"][ok]) ** 2))
    err_after = np.sqrt(np.mean((reg.registered[ok] - m["pos"][ok]) ** 2))
    assert err_after < err_before
    # registration is the least-squares optimum: perturbing the pose increases f(q)
    k = 3
    f0 = np.mean(np.sum((noisy[k] - reg.registered[k]) ** 2, 1))
    for _ in range(20):
        dR = _rotation_of_quaternion(np.r_[1, rng.normal(0, 1e-3, 3)])
        x = reg.registered[k] @ dR.T + rng.normal(0, 1e-4, 3)
        assert np.mean(np.sum((noisy[k] - x) ** 2, 1)) > f0


def test_register_rejects_bad_shapes():
    with pytest.raises(ValueError, match="model"):
        rigid.register(np.zeros((5, 3, 3)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="points"):
        rigid.register(np.zeros((5, 3)), np.zeros((3, 3)))


@pytest.mark.parametrize("seed", SEEDS)
def test_match_static_markers(seed):
    rng = np.random.default_rng(seed)
    m = random_rigid_motion(rng, markers=4)
    perm = rng.permutation(4)
    static = m["body"][perm] + 1.0           # the static shot, shuffled, elsewhere
    motion = m["pos"][:, :3] + rng.normal(0, 0.002, (len(m["t"]), 3, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        idx, saddle = rigid.match_static_markers(static, motion)
    inv = np.argsort(perm)
    np.testing.assert_array_equal(idx, inv[:3])
    assert saddle == inv[3]


@pytest.mark.parametrize("seed", SEEDS)
def test_angular_velocity_versions_exact(seed):
    m = random_rigid_motion(np.random.default_rng(seed), markers=3)
    vers = rigid.angular_velocity_versions(m["pos"], m["vel"])
    ang = rigid.singularity_angle(m["pos"], m["omega"])
    good = np.abs(ang - 90) > 5              # away from the singularity eq. 6.35
    scale = np.linalg.norm(m["omega"], axis=1, keepdims=True)
    for v in vers:
        np.testing.assert_allclose(v[good] / scale[good], m["omega"][good] / scale[good], atol=1e-9)
    np.testing.assert_allclose(rigid.angular_velocity_lstsq(m["pos"], m["vel"]), m["omega"], atol=1e-10)


@pytest.mark.parametrize("seed", SEEDS)
def test_angular_acceleration_versions_exact(seed):
    m = random_rigid_motion(np.random.default_rng(seed), markers=3)
    vers = rigid.angular_acceleration_versions(m["pos"], m["vel"], m["acc"], m["omega"])
    ang = rigid.singularity_angle(m["pos"], m["omega"])
    # alpha's singularity: alpha . n = 0 (same algebra as eq. 6.31-6.35)
    n = rigid.marker_plane_normal(m["pos"])
    ca = np.abs(np.sum(n * m["alpha"], 1)) / np.linalg.norm(m["alpha"], axis=1)
    good = ca > np.sin(np.radians(5))
    scale = np.linalg.norm(m["alpha"], axis=1, keepdims=True)
    for v in vers:
        np.testing.assert_allclose(v[good] / scale[good], m["alpha"][good] / scale[good], atol=1e-8)
    np.testing.assert_allclose(rigid.angular_acceleration_lstsq(m["pos"], m["acc"], m["omega"]),
                               m["alpha"], atol=1e-9)
    assert np.isfinite(ang).all()


@pytest.mark.parametrize("seed", SEEDS)
def test_compatibility_condition_holds(seed):
    """Eq. 6.19/6.20: r_21.(v_3 - v_1) = -(v_2 - v_1).r_31 for rigid motion,
    and not for a non-rigid one."""
    rng = np.random.default_rng(seed)
    m = random_rigid_motion(rng, markers=3)
    res = rigid.compatibility_residual(m["pos"], m["vel"])
    scale = np.linalg.norm(m["vel"], axis=-1).max() * np.linalg.norm(m["body"], axis=-1).max()
    assert np.max(np.abs(res)) < 1e-12 * scale
    bad = m["vel"].copy()
    bad[:, 1] += rng.normal(0, 0.5, (len(bad), 3))
    assert np.max(np.abs(rigid.compatibility_residual(m["pos"], bad))) > 1e-3


def test_lstsq_has_no_singularity_where_versions_fail():
    """omega in the markers' plane (eq. 6.35): the thesis versions are 0/0,
    the least-squares solution is exact."""
    pos = np.array([[[0, 0, 0], [0.2, 0, 0], [0.05, 0.15, 0]]], float)   # plane z = 0
    omega = np.array([[1.3, -0.4, 0.0]])
    vel = np.cross(omega[:, None], pos) + [3.0, 0.1, 0.0]
    with np.errstate(all="ignore"):
        vers = rigid.angular_velocity_versions(pos, vel)
    assert not np.all(np.isfinite(vers)) or np.max(np.abs(vers - omega)) > 1e-3
    np.testing.assert_allclose(rigid.angular_velocity_lstsq(pos, vel), omega, atol=1e-12)
    np.testing.assert_allclose(rigid.singularity_angle(pos, omega), [90.0], atol=1e-9)
    with pytest.warns(RuntimeWarning, match="unreliable"):
        rep = rigid.singularity_report(rigid.singularity_angle(pos, omega))
    assert rep["fraction"] == 1.0


def test_lstsq_collinear_is_nan_or_raises():
    pos = np.array([[[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]], float)
    vel = np.zeros_like(pos)
    with pytest.raises(np.linalg.LinAlgError):
        rigid.angular_velocity_lstsq(pos, vel)


def test_average_versions():
    v = np.arange(6 * 2 * 3, dtype=float).reshape(6, 2, 3)
    np.testing.assert_allclose(rigid.average_versions(v), v.mean(0))
    use = np.array([1, 1, 0, 1, 0, 1], bool)
    np.testing.assert_allclose(rigid.average_versions(v, use), v[use].mean(0))
    v[0, 0, 0] = np.inf
    assert np.isfinite(rigid.average_versions(v)[0, 0])
    with pytest.raises(ValueError):
        rigid.average_versions(v, np.zeros(6, bool))


@pytest.mark.parametrize("seed", SEEDS)
def test_saddle_kinematics_exact(seed):
    """Body frame from a static shot in another pose (eq. 6.41-6.47), then the
    saddle during the motion (eq. 6.48-6.55) equals the truth for every base."""
    rng = np.random.default_rng(seed)
    m = random_rigid_motion(rng, markers=4)
    Rs = _rotation_of_quaternion(rng.normal(size=4))
    static = m["body"] @ Rs.T + rng.normal(0, 1, 3)
    sb = rigid.saddle_in_body(static[:3], static[3])
    pos, vel, acc = m["pos"][:, :3], m["vel"][:, :3], m["acc"][:, :3]
    for saddle_body in (sb, rigid.saddle_in_body_versions(static[:3], static[3])):
        sk = rigid.saddle_kinematics(pos, vel, acc, m["omega"], m["alpha"], saddle_body)
        np.testing.assert_allclose(sk.position, m["pos"][:, 3], atol=1e-12)
        np.testing.assert_allclose(sk.position_versions, np.broadcast_to(m["pos"][:, 3], (3,) + m["pos"][:, 3].shape), atol=1e-12)
        np.testing.assert_allclose(sk.velocity_versions, np.broadcast_to(m["vel"][:, 3], (3, len(m["t"]), 3)), atol=1e-11)
        np.testing.assert_allclose(sk.acceleration_versions, np.broadcast_to(m["acc"][:, 3], (3, len(m["t"]), 3)), atol=1e-10)
        np.testing.assert_allclose(sk.velocity, m["vel"][:, 3], atol=1e-11)
        np.testing.assert_allclose(sk.acceleration, m["acc"][:, 3], atol=1e-10)


def test_body_frame_is_orthonormal_and_thesis_oriented():
    s = np.array([[1.0, 2, 3], [1.5, 2, 3], [1.2, 2.4, 3.1]])
    R, o = rigid.body_frame(s)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(R), 1)
    np.testing.assert_allclose(o, s[0])
    np.testing.assert_allclose(R[:, 0], [1, 0, 0])                    # marker 2 on +x (eq. 6.41)
    assert (R.T @ (s[2] - s[0]))[1] > 0 and abs((R.T @ (s[2] - s[0]))[2]) < 1e-15


def _periodic_fixed_axis_motion(n=38, fps=30.0, seed=0):
    """Rotation about a fixed axis by a Fourier-series angle, Fourier-series
    translation plus constant speed: every quantity has a closed form."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fps
    w = 2 * np.pi * 30 / 18 / 1.0                  # 18-frame period as in the thesis
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    R0 = _rotation_of_quaternion(rng.normal(size=4))
    th_ab = rng.normal(0, 0.05, (2, 2))
    def series(ab, d):
        out = np.zeros_like(t)
        for i, (a, b) in enumerate(ab, start=1):
            k = i * w
            c, s_ = np.cos(k * t), np.sin(k * t)
            out += [a * c + b * s_, k * (-a * s_ + b * c), -k * k * (a * c + b * s_)][d]
        return out
    th, thd, thdd = (series(th_ab, d) for d in range(3))
    R = R0 @ Rotation.from_rotvec(axis[None] * th[:, None]).as_matrix()
    omega = (R0 @ axis)[None] * thd[:, None]
    alpha = (R0 @ axis)[None] * thdd[:, None]
    c_ab = rng.normal(0, 0.03, (3, 2, 2))
    c = np.stack([series(c_ab[k], 0) for k in range(3)], -1) + np.outer(t, [4.9, 0, 0])
    return dict(t=t, R=R, c=c, omega=omega, alpha=alpha, w=w)


def test_fit_rotations_recovers_omega_alpha():
    m = _periodic_fixed_axis_motion()
    rf = rigid.fit_rotations(m["t"], m["R"], orders=2)
    np.testing.assert_allclose(rf.rotation(m["t"]), m["R"], atol=1e-8)
    np.testing.assert_allclose(rf.omega(m["t"]), m["omega"], atol=1e-6)
    np.testing.assert_allclose(rf.alpha(m["t"]), m["alpha"], atol=1e-4 * np.abs(m["alpha"]).max())


def test_analyse_rigid_body_noise_free():
    """The whole step on an exactly periodic rigid motion: registration exact,
    the saddle position exact, omega/alpha from the rotation fit exact, and the
    saddle acceleration by the direct fit close to the truth."""
    m = _periodic_fixed_axis_motion(seed=1)
    body = np.array([[-0.62, 0.02, -0.31], [-0.38, 0.09, -0.33], [-0.14, 0.03, -0.33], [0.06, -0.16, -0.30]])
    pos = np.einsum("kij,mj->kmi", m["R"], body) + m["c"][:, None]
    static = body[[3, 1, 0, 2]] + [0.3, 1.2, 7.0]              # arbitrary order, another place
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = rigid.analyse_rigid_body(m["t"], pos[:, :3], static, _params(angular_method="rotation"),
                                       fourier_orders=rigid.FourierOrders(markers=2), period_s=2 * np.pi / m["w"])
    assert res.static_index.tolist() == [2, 1, 3] and res.saddle_index == 0
    np.testing.assert_allclose(res.registration.registered, pos[:, :3], atol=1e-12)
    np.testing.assert_allclose(res.saddle.position, pos[:, 3], atol=1e-12)
    np.testing.assert_allclose(res.omega, m["omega"], atol=1e-6)
    np.testing.assert_allclose(res.alpha, m["alpha"], atol=1e-4 * np.abs(m["alpha"]).max())
    assert res.omega_versions.shape == (6, m["t"].size, 3) and res.alpha_versions.shape == (6, m["t"].size, 3)
    assert res.saddle_acceleration.shape == (m["t"].size, 3)


# --------------------------------------------------------------------------
# default virtual session against its truth (runs when the data exist)
# --------------------------------------------------------------------------
def _default_truth():
    try:
        from horsemocap import data, virtuallab
    except Exception as exc:  # pragma: no cover - depends on other steps
        pytest.skip(f"virtual lab not available: {exc}")
    d = Path(data.default_session_dir())
    if not d.exists() or not hasattr(virtuallab, "load_truth"):
        pytest.skip(f"default session not rendered yet: {d}")
    try:
        return d, virtuallab.load_truth(d)
    except FileNotFoundError as exc:
        pytest.skip(f"default session truth not (yet) there: {exc}")


def _motion(truth, x):
    axes = np.asarray(getattr(truth, "motion_axes"), float)      # rows: x, y, z motion axes
    return np.asarray(x, float) @ axes.T


def measured_markers(truth, seed=0, sigma_xyz=(0.0015, 0.0015, 0.005)):
    """Stand-in for the pipeline until it runs: truth markers + Gaussian noise
    along the left camera's axes (depth worse), then the thesis smoothing.
    Returns motion-frame markers (n, 3, 3) and static shot (4, 3)."""
    from horsemocap import smoothing
    rng = np.random.default_rng(seed)
    sig = np.asarray(sigma_xyz)
    pos = np.asarray(truth.marker_pos, float) + rng.normal(0, 1, np.shape(truth.marker_pos)) * sig
    static = np.asarray(truth.static_pos, float) + rng.normal(0, 1, (len(truth.static_pos), 3)) * sig
    return smoothing.smooth_positions(_motion(truth, pos), 0.1), _motion(truth, static)


def _saddle_errors(truth, pts, static, conv):
    t = np.arange(len(pts)) / float(truth.fps)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = rigid.analyse_rigid_body(t, pts, static, _params())
    ay = conv(truth.saddle_acc)[:, 1]
    rmse = np.sqrt(np.mean((res.saddle_acceleration[:, 1] - ay) ** 2))
    rms = np.sqrt(np.mean(ay ** 2))
    pos_rmse = np.sqrt(np.mean((res.saddle.position - conv(truth.saddle_pos)) ** 2, axis=0))
    path_rmse = np.sqrt(np.mean((res.saddle_path - conv(truth.saddle_pos)) ** 2, axis=0))
    print(f"saddle path of the fit ({res.saddle_method}) RMSE x/y/z mm {np.round(1000 * path_rmse, 1)}")
    return rmse, rms, pos_rmse


@pytest.mark.parametrize("kinematics, target", [("fits", 5.0), ("pose_spline", 15.0)])
def test_default_session_saddle_acc(kinematics, target):
    """The pipeline's path on the default session, against its truth.

    ``kinematics="fits"``: ``results_for(until="rigid_body")`` (detection -> triangulation -> motion
    frame -> registration -> fits -> omega/alpha -> saddle, every choice
    automatic) measured by :func:`horsemocap.accuracy.stage_errors` in the
    true motion frame. Target (issue 7): vertical saddle acceleration RMSE
    <= 5 % of its rms (measured 3.0 % on 2026-11-21 with the defaults
    smoothing "loess", angular "rotation", saddle "pose"; 2.1 % with
    smoothing "none", 10.1 % with the thesis' "rloess"; the thesis' own
    chain, eq. 6.55 with the six-version averages, gives about 1560 %:
    notebook 11). This one session is among the easiest: over the 16 virtual
    herd sessions the median is 24.6 % with loess (benchmarks/bench_herd.py).
    ``kinematics="pose_spline"`` (the default since 2026-11-23): issue 13's
    worst-session target, 15 % (measured 10.1 %; herd median 10.4 %, worst
    13.4 %; hard set 3.2 %, worst 9.6 %).
    """
    d, truth = _default_truth()
    from horsemocap import accuracy
    from horsemocap.workspace import results_for
    an = results_for(d, until="rigid_body", params={"rigid_body": {"kinematics": kinematics}})
    rb = an.rigid_body.body
    fits = an.params.rigid_body.fits
    assert (rb.method, rb.saddle_method) == (fits.angular_method, fits.saddle_method)
    st = accuracy.stage_errors(an, truth)
    a, b = an.triangulate.segment
    frames = an.synchronisation.offsets["left"] + np.arange(a, b)
    # compared on every analysed frame the truth covers (the truth lacks frames in which a marker is
    # not whole in every camera; the multi-view identification measures those with two cameras)
    assert st["frames"] == int(np.isin(frames, truth.ref_frames).sum()) >= len(frames) - 2
    pct = st["saddle_acc_y_rmse_pct_of_rms"]
    msg = (f"[kinematics {kinematics}: smoothing {an.params.smooth.method}, omega {rb.method}, saddle "
           f"{rb.saddle_method}] saddle position RMSE x/y/z mm {np.round(1000 * st['saddle_position'], 1)}; "
           f"vertical acc RMSE {st['saddle_acceleration'][1]:.3f} m/s^2 = {pct:.1f} % of rms")
    print(msg)
    assert pct <= target, msg


def test_default_session_saddle_acc_noise_free():
    """Same chain on the exact truth markers (no noise, no smoothing): the
    registration and saddle position are exact and the default fits meet
    the target by far (measured 0.08 %; the smoothing methods are compared
    on the pipeline's data in notebooks 06 and 11)."""
    d, truth = _default_truth()
    conv = lambda x: _motion(truth, x)  # noqa: E731
    rmse, rms, pos_rmse = _saddle_errors(truth, conv(truth.marker_pos), conv(truth.static_pos), conv)
    assert np.all(pos_rmse < 1e-9), pos_rmse
    assert rmse <= 0.01 * rms, f"noise-free: vertical acc RMSE {100 * rmse / rms:.2f} % of rms"


def test_ui_versions_and_methods():
    from horsemocap import widgets
    ui = widgets.ui_versions("omega")
    assert ui.value.tolist() == [True] * 6
    ui.checkboxes[2].value = False
    ui.checkboxes[4].value = False
    assert ui.value.tolist() == [True, True, False, True, False, True]
    from horsemocap.params import AnalysisParams

    assert widgets.ui_angular_method().value == AnalysisParams().rigid_body.fits.angular_method
    assert widgets.ui_saddle_method().value == FitsParams().saddle_method


def test_rigid_plots_return_figures():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from horsemocap import plots
    m = random_rigid_motion(np.random.default_rng(0), markers=4)
    pos, vel = m["pos"][:, :3], m["vel"][:, :3]
    vers = rigid.angular_velocity_versions(pos, vel)
    t = m["t"]
    figs = [plots.plot_registration(pos, pos, 3), plots.plot_marker_distances(t, pos, pos),
            plots.plot_angular_versions(t, vers, vers, 0, truth=m["omega"]),
            plots.plot_angular_average(t, vers, np.ones(6, bool), m["omega"], truth=m["omega"], lstsq=m["omega"]),
            plots.plot_singularity(t, rigid.singularity_angle(pos, m["omega"])),
            plots.plot_saddle_position(t, m["pos"][:, 3], pos, truth=m["pos"][:, 3]),
            plots.plot_saddle_kinematics(t, np.stack([m["vel"][:, 3]] * 3), np.stack([m["acc"][:, 3]] * 3),
                                         m["vel"][:, 3], m["acc"][:, 3], m["vel"][:, 3], m["acc"][:, 3])]
    assert all(hasattr(f, "axes") and len(f.axes) >= 1 for f in figs)
    plt.close("all")


def test_fit_options_reach_every_fit_and_the_pose_path():
    """`orders` (one int) reaches the marker, rotation and saddle-path fits; rotation_orders and
    saddle_orders set those fits alone; kinematics='pose_spline' gives the saddle exactly."""
    m = _periodic_fixed_axis_motion(seed=2)
    body = np.array([[-0.62, 0.02, -0.31], [-0.38, 0.09, -0.33], [-0.14, 0.03, -0.33], [0.06, -0.16, -0.30]])
    pos = np.einsum("kij,mj->kmi", m["R"], body) + m["c"][:, None]
    static = body[[3, 1, 0, 2]] + [0.3, 1.2, 7.0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = rigid.analyse_rigid_body(m["t"], pos[:, :3], static, _params(x_degree=2),
                                       fourier_orders=rigid.FourierOrders(markers=3))
        assert res.rotation_fit.orders.tolist() == [3, 3, 3]
        assert res.saddle_fit.orders.tolist() == [[2, 3, 3]] and res.motion_fit.orders[:, 0].tolist() == [2, 2, 2]
        res = rigid.analyse_rigid_body(m["t"], pos[:, :3], static, _params(),
                                       fourier_orders=rigid.FourierOrders(rotation=[1, 2, 4], saddle=[2, 5]))
        assert res.rotation_fit.orders.tolist() == [1, 2, 4] and res.saddle_fit.orders[0, 1:].tolist() == [2, 5]
        res = rigid.analyse_rigid_body(m["t"], pos[:, :3], static, _params("pose_spline", pose_smoothing="none"))
    assert res.kinematics == "pose_spline" and res.pose is not None
    np.testing.assert_allclose(res.saddle_position, pos[:, 3], atol=1e-9)
    # interpolating quintic splines of 38 samples (about 2 periods): spline precision, not exact
    inner = slice(3, -3)
    for est, true in ((res.omega, m["omega"]), (res.alpha, m["alpha"])):
        rel = np.abs(est[inner] - true[inner]).max() / np.abs(true).max()
        assert rel < 0.02, rel


def test_fourier_orders_of_the_parameter_file_reach_every_fit():
    """``fits.fourier_orders`` in the section (the parameter file's form) is parsed by
    :meth:`rigid.FourierOrders.from_param`; a wrong number of pairs names the parameter."""
    m = _periodic_fixed_axis_motion(seed=2)
    body = np.array([[-0.62, 0.02, -0.31], [-0.38, 0.09, -0.33], [-0.14, 0.03, -0.33], [0.06, -0.16, -0.30]])
    pos = np.einsum("kij,mj->kmi", m["R"], body) + m["c"][:, None]
    static = body[[3, 1, 0, 2]] + [0.3, 1.2, 7.0]
    params = RigidBodyParams(kinematics="fits",
                             fits=FitsParams(fourier_orders={"y": 3, "z": 2, "rotation": [1, 2, 4], "saddle": 2}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = rigid.analyse_rigid_body(m["t"], pos[:, :3], static, params)
    assert res.motion_fit.orders[:, 1:].tolist() == [[3, 2]] * 3
    assert res.rotation_fit.orders.tolist() == [1, 2, 4] and res.saddle_fit.orders[0, 1:].tolist() == [2, 2]
    with pytest.raises(ValueError, match="fourier_orders: expected .* 3 pairs"):
        rigid.analyse_rigid_body(m["t"], pos[:, :3], static,
                                 RigidBodyParams(fits=FitsParams(fourier_orders=[[3, 2]])))
