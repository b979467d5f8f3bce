"""A long pass through analyze's rigid-body step keeps its accelerations: its pose trajectory in windows
(horsemocap.pose_windows), exact truth."""
from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import pose, pose_windows, streaming
from horsemocap.params import AnalysisParams, PoseParams, RigidBodyParams
from horsemocap.passes import pass_smoothing
from horsemocap.results import _record_rigid_body
from horsemocap.rigid import PoseInput, analyse_rigid_body, conditioning, saddle_angles
from horsemocap.steps.rigid_body import _report
from horsemocap.threads import blas_single_threaded

FPS = 100.0
MODEL = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15]])
SADDLE = np.array([0.20, -0.10, -0.15])
STRIDE_HZ = 1.7


@pytest.fixture(autouse=True)
def one_blas_thread():
    with blas_single_threaded():
        yield


def _s(t, a, f, p=0.0):
    return a * np.sin(2 * np.pi * f * t + p)


def _path(t):
    """A trot at 1.7 Hz whose stride frequency wanders by 2 % over 14 s (benchmarks/bench_long_pass.py)."""
    u = t + 0.02 * 14 / (2 * np.pi) * np.sin(2 * np.pi * t / 14)
    c = np.stack([1.5 * t + _s(u, 0.01, 1.7), _s(u, 0.03, 3.4) + _s(u, 0.008, 6.8, 0.7) + 1.2,
                  _s(u, 0.01, 1.7, 0.3)], -1)
    rot = Rotation.from_rotvec(np.stack([_s(u, 0.03, 1.7, 1.0), _s(u, 0.05, 3.4, 0.2), _s(u, 0.04, 1.7, 2.0)], -1))
    return c, rot


def _pass(n: int, seed: int = 0) -> SimpleNamespace:
    """Three markers with 0.5 mm white noise; the hidden saddle's exact acceleration and the body's omega."""
    t = np.arange(n) / FPS
    c, rot = _path(t)
    markers = np.einsum("kij,mj->kmi", rot.as_matrix(), MODEL) + c[:, None]
    markers = markers + np.random.default_rng(seed).normal(0, 5e-4, markers.shape)
    h = 1e-3

    def saddle(u):
        cu, ru = _path(u)
        return cu + ru.apply(SADDLE)

    acc = (saddle(t + h) - 2 * saddle(t) + saddle(t - h)) / h ** 2
    omega = (_path(t + h)[1] * _path(t - h)[1].inv()).as_rotvec() / (2 * h)
    return SimpleNamespace(t=t, markers=markers, acc=acc, omega=omega)


def _analyse(d, **kwargs):
    return analyse_rigid_body(d.t, d.markers, np.vstack([MODEL, SADDLE]), RigidBodyParams(saddle_marker=3),
                              period_s=1.0 / STRIDE_HZ, static_index=np.arange(3), thesis_chain=False, **kwargs)


def _error(estimate, truth) -> float:
    """Rms error as a fraction of the truth's rms, 20 frames left out at each end."""
    e = slice(20, len(truth) - 20)
    return float(np.sqrt(np.mean(np.sum((estimate[e] - truth[e]) ** 2, 1)) / np.mean(np.sum(truth[e] ** 2, 1))))


@pytest.fixture(scope="module")
def long_pass():
    d = _pass(3000)
    with blas_single_threaded():
        return d, _analyse(d)


def test_a_long_pass_keeps_its_saddle_acceleration(long_pass):
    """30 s at 100 Hz fitted whole had a knot every 8 frames: the saddle's acceleration 61.1 % off
    (measured on main); in windows 3.3 %. Omega, the markers' kinematics, the conditioning and the saddle's
    angles come from the same windows."""
    d, rb = long_pass
    assert _error(rb.saddle_acceleration, d.acc) < 0.08               # measured 0.033 (0.611 fitted whole)
    assert rb.pose.windows is not None and len(rb.pose.windows.plan) == 3
    assert _error(rb.omega, d.omega) < 0.05                            # measured 0.018
    pos, vel, acc = rb.marker_kinematics
    assert pos.shape == (3000, 3, 3) and np.isfinite(acc).all()
    cond = conditioning(rb)
    assert np.isfinite(cond.singularity_deg).all() and cond.warnings == []
    truth = pose.saddle_angles_deg(_path(d.t)[1].as_matrix(), pose.static_body_axes(np.vstack([MODEL, SADDLE])))
    assert np.abs(saddle_angles(rb) - truth).max() < 0.5               # deg; measured 0.14


def test_a_long_pass_says_it_was_smoothed_in_windows(long_pass):
    d, rb = long_pass
    lines = []
    cond = conditioning(rb)
    _report(RigidBodyParams(), rb, cond, None, lambda step, msg: lines.append(msg))
    said = [m for m in lines if "pose trajectory of a long pass" in m]
    assert len(said) == 1 and "3000 frames smoothed in 3 windows" in said[0]
    chosen = {}
    _record_rigid_body(SimpleNamespace(static_order=[0, 1, 2, 3], saddle_index=3, body=rb, orders=None,
                                       warnings=[]), {}, chosen)
    record = chosen["pose_windows"]
    assert record["frames"] == 3000 and record["count"] == 3
    assert record["settled_on_s"] == [0.0, 29.99]                      # 3000 frames: settled on them all


def test_a_long_passs_smoothing_serves_the_recordings_other_passes(long_pass):
    """The choices a long pass hands to the recording's other passes (passes.pass_smoothing) are its middle
    window's: a 12 s pass of the same trot smoothed with them misses the saddle's acceleration by 3.5 %
    (its own choice: 3.2 %); with the choices of the 30 s pass fitted whole (main) by 36.7 %."""
    d, rb = long_pass
    given = pass_smoothing(SimpleNamespace(rigid_body=SimpleNamespace(body=rb), params=AnalysisParams()))
    other = _pass(1200, seed=7)
    reused = _analyse(other, pose_input=PoseInput(settled=given))
    assert _error(reused.saddle_acceleration, other.acc) < 0.08


def test_a_pass_is_fitted_whole_up_to_the_threshold_and_in_windows_beyond(monkeypatch):
    """Up to WHOLE_RECORD_FRAMES (here lowered to 800) the pose trajectory is the whole record's fit, bit
    for bit; one frame more and it is made of windows."""
    monkeypatch.setattr(streaming, "WHOLE_RECORD_FRAMES", 800)
    d = _pass(800, seed=1)
    rb = _analyse(d)
    whole = pose.fit_pose_trajectory(d.t, rb.pose_registration, rb.model, RigidBodyParams().pose,
                                     points=d.markers, expected_fundamental_hz=STRIDE_HZ)
    assert whole.point(d.t, SADDLE).acceleration.tobytes() == rb.saddle_acceleration.tobytes()
    assert getattr(rb.pose, "windows", None) is None
    longer = _analyse(_pass(801, seed=1))
    assert getattr(longer.pose, "windows", None) is not None and longer.pose.windows.frames == 801


def test_the_windowed_trajectory_is_the_kinematics_commands_windows():
    """At the frames, the windowed trajectory's point kinematics, omega and alpha are those of
    streaming.windowed_kinematics with the same settled smoothing (the blend over the cuts included);
    between frames it is continuous."""
    d = _pass(1200, seed=2)
    reg = pose.register_pose(d.markers, MODEL)
    params = PoseParams(smoothing="gcv", partial_frames=False)      # as windowed_kinematics smooths
    settled = streaming.settle_smoothing(d.t, reg, d.markers, MODEL, params, frames=400, window=300)
    blocks = list(streaming.windowed_kinematics(d.t, reg, d.markers, MODEL, np.vstack([MODEL, SADDLE]), params,
                                                settled=settled))
    tr = pose_windows.windowed_pose_trajectory(d.t, reg, MODEL, params, points=d.markers, frames=400, window=300)
    assert tr.settled.lam == settled.lam and len(tr.windows.plan) == 4
    k = tr.points(d.t, np.vstack([MODEL, SADDLE]))
    for name, mine in (("position", k.position), ("velocity", k.velocity), ("acceleration", k.acceleration),
                       ("omega", tr.omega(d.t)), ("alpha", tr.alpha(d.t))):
        theirs = np.concatenate([getattr(b, name) for b in blocks])
        np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-9 * np.abs(theirs).max(), err_msg=name)
    assert tr.reason.tolist() == np.concatenate([b.reason for b in blocks]).tolist()
    half = d.t[:-1] + 0.5 / FPS                                        # between the frames, across the cuts
    mid = tr.point(half, SADDLE).acceleration
    a = k.acceleration[:, -1]
    assert np.all(np.linalg.norm(mid - 0.5 * (a[1:] + a[:-1]), axis=1) < 0.05 * np.abs(a).max())
    R = tr.rotation(half)
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-12)
    assert np.isnan(tr.omega(np.array([-0.01, d.t[-1] + 0.01]))).all()    # outside the record, as a whole fit


def test_a_long_pass_fits_a_smoothing_settled_on_another_pass():
    """A long recording's other pass, given the longest pass's settled smoothing, fits it in every window
    (nothing chosen again) and keeps its accelerations (measured: 3.1 %; fitted whole with the same choice,
    on main, 38.1 %)."""
    d = _pass(2400, seed=3)
    first = pose.fit_pose_trajectory(d.t[:800], pose.register_pose(d.markers[:800], MODEL), MODEL,
                                     RigidBodyParams().pose, points=d.markers[:800], expected_fundamental_hz=1.7)
    given = pose.settle_pose_smoothing(first, RigidBodyParams().pose)
    rb = _analyse(d, pose_input=PoseInput(settled=given))
    assert _error(rb.saddle_acceleration, d.acc) < 0.08
    assert rb.pose.windows is not None and rb.pose.settled.given is given
    for piece in rb.pose.pieces:
        assert [piece.trajectory.smoothing[c]["lam"] for c in pose.POSE_COMPONENTS] == list(given.lam)


def test_a_window_without_poses_is_nan_with_its_reason():
    d = _pass(1200, seed=4)
    pts = d.markers.copy()
    pts[500:900, :2] = np.nan                              # two markers hidden for 4 s
    reg = pose.register_pose(pts, MODEL)
    tr = pose_windows.windowed_pose_trajectory(d.t, reg, MODEL, PoseParams(smoothing="gcv"), points=pts,
                                               frames=400, window=300)
    acc = tr.point(d.t, SADDLE).acceleration
    assert np.isnan(acc[510:890]).all() and all(tr.reason[510:890] != "") and not tr.valid[510:890].any()
    assert np.isfinite(acc[:490]).all() and np.isfinite(acc[910:]).all()


def test_a_long_pass_without_harmonics_takes_lambdas_chosen_on_a_fine_basis():
    """The plain route (``harmonics: none``: every window reuses the lambdas settled once) on the 30 s pass: the
    lambdas are chosen again on the representative stretch's middle with a knot at every frame. Settled on the
    4000-frame stretch fitted whole (a knot every 11 frames) the vertical's lambda was about 80 times larger and
    the saddle's acceleration 32.5 % off; now within 5 %."""
    d = _pass(3000)
    params = RigidBodyParams(saddle_marker=3, pose=PoseParams(smoothing="gcv", harmonics="none"))
    rb = analyse_rigid_body(d.t, d.markers, np.vstack([MODEL, SADDLE]), params, period_s=1.0 / STRIDE_HZ,
                            static_index=np.arange(3), thesis_chain=False)
    assert rb.pose.windows is not None and rb.pose.settled.lam[1] < 1e-9
    assert _error(rb.saddle_acceleration, d.acc) < 0.05
