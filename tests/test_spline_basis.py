"""The spline_basis check: a pose record too long for a knot at every frame is asked whether its basis holds
the saddle's motion (horsemocap.basis_check), against exact truth."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import quality
from horsemocap.cli import main
from horsemocap.basis_check import FULL_BASIS_FRAMES, BasisResolution, basis_resolution
from horsemocap.params import PoseParams, RigidBodyParams
from horsemocap.rigid import PoseInput, analyse_rigid_body
from horsemocap.splines import knot_step
from horsemocap.threads import blas_single_threaded

from test_io3d import _write_csv

MODEL = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15]])
SADDLE = np.array([0.20, -0.10, -0.15])


@pytest.fixture(autouse=True)
def one_blas_thread():
    with blas_single_threaded():
        yield


def _path(t):
    """A trot at 1.7 Hz (harmonics up to 6.8 Hz) whose stride wanders by 2 % over 14 s."""
    u = t + 0.02 * 14 / (2 * np.pi) * np.sin(2 * np.pi * t / 14)
    s = lambda a, f, p=0.0: a * np.sin(2 * np.pi * f * u + p)      # noqa: E731
    c = np.stack([1.5 * t + s(0.01, 1.7), s(0.03, 3.4) + s(0.008, 6.8, 0.7) + 1.2, s(0.01, 1.7, 0.3)], -1)
    return c, Rotation.from_rotvec(np.stack([s(0.03, 1.7, 1.0), s(0.05, 3.4, 0.2), s(0.04, 1.7, 2.0)], -1))


def _analysed(n: int, fps: float):
    """The rigid-body analysis of an n-frame pass (0.5 mm white noise) and its saddle acceleration's error (%)."""
    t = np.arange(n) / fps
    c, rot = _path(t)
    markers = np.einsum("kij,mj->kmi", rot.as_matrix(), MODEL) + c[:, None]
    markers = markers + np.random.default_rng(0).normal(0, 5e-4, markers.shape)

    def saddle(u):
        cu, ru = _path(u)
        return cu + ru.apply(SADDLE)
    h = 1e-3
    truth = (saddle(t + h) - 2 * saddle(t) + saddle(t - h)) / h ** 2
    rb = analyse_rigid_body(t, markers, np.vstack([MODEL, SADDLE]), RigidBodyParams(saddle_marker=3),
                            period_s=1 / 1.7, static_index=np.arange(3), thesis_chain=False)
    e = slice(20, n - 20)
    err = np.sqrt(np.mean(np.sum((rb.saddle_acceleration[e] - truth[e]) ** 2, 1)) / np.mean(np.sum(truth[e] ** 2, 1)))
    return rb, 100 * float(err)


def test_a_long_record_at_50_fps_whose_knots_lose_the_trot_is_unreliable():
    """1200 frames at 50 fps (24 s) fitted whole: a knot every 4 frames (80 ms) loses the trot's fast part
    (the saddle's acceleration tens of per cent off); the record's middle fitted with a knot at every frame
    differs by as much, and the check says unreliable."""
    rb, err = _analysed(1200, 50.0)
    r = rb.basis_resolution
    assert err > 30
    assert r.knot_step == 4 and r.knot_spacing_s == pytest.approx(0.08)
    assert r.stretch_s == (8.04, 15.94) and r.compared_s == (10.02, 13.96)      # the middle 396 frames, on time_s
    assert r.difference_pct > 2 * quality.SPLINE_BASIS_PCT[1]
    check = quality.check_spline_basis(r)
    assert check.level == "unreliable" and "a knot every 4 frames (80 ms)" in check.message


def test_a_long_record_at_100_hz_whose_knots_hold_the_trot_is_ok():
    """The same trot, 1200 frames at 100 Hz (a knot every 4 frames, 40 ms): the fit holds the motion (a few per
    cent from the truth), the fine refit agrees within the ok bound."""
    rb, err = _analysed(1200, 100.0)
    assert err < 5
    assert quality.check_spline_basis(rb.basis_resolution).level == "ok"


def test_a_record_with_a_knot_at_every_frame_is_not_checked():
    rb, _ = _analysed(FULL_BASIS_FRAMES, 50.0)
    assert knot_step(FULL_BASIS_FRAMES) == 1 and rb.basis_resolution is None
    reg = SimpleNamespace(rotation=np.repeat(np.eye(3)[None], FULL_BASIS_FRAMES + 4, 0))
    reg.rotation[::2] = np.nan                              # 400 frames, 200 with a pose: a knot at every sample
    assert basis_resolution(SimpleNamespace(t=np.arange(FULL_BASIS_FRAMES + 4) / 50.0), reg, MODEL, SADDLE) is None


def test_a_check_without_a_figure_is_skipped_with_its_reason():
    r = BasisResolution(3, 0.06, (8.04, 15.94), (10.02, 13.96), float("nan"), "no frame of the stretch's middle has a pose")
    check = quality.check_spline_basis(r)
    assert check.level == "skipped" and "no frame of the stretch's middle has a pose" in check.message


def test_the_kinematics_command_says_when_its_knots_lose_the_hidden_points_motion(tmp_path, capsys):
    """``horsemocap kinematics`` on the trot at 50 fps, 1000 frames (smoothed whole, a knot every 3 frames):
    kinematics-run.json holds an unreliable spline_basis check naming the hidden point, and the command exits 3;
    at 100 Hz (a knot every 3 frames, 30 ms) the check is ok."""
    for fps, level, status in ((50.0, "unreliable", 3), (100.0, "ok", 0)):
        _kinematics_basis_check(tmp_path, 1000, fps, level, status)


def test_the_kinematics_command_checks_a_long_records_windows(tmp_path):
    """A 2000-frame record at 50 fps (40 s) is smoothed in windows of up to 1300 frames (a knot every 4 frames):
    its middle window is checked, unreliable (the windows lose the trot's fast part)."""
    _kinematics_basis_check(tmp_path, 2000, 50.0, "unreliable", 3)


def _kinematics_basis_check(tmp_path, n, fps, level, status, extra=()):
    """``horsemocap kinematics`` on the trot (n frames at fps, the saddle a hidden point): its exit status and the
    spline_basis check in kinematics-run.json."""
    t = np.arange(n) / fps
    c, rot = _path(t)
    pts = np.einsum("kij,mj->kmi", rot.as_matrix(), MODEL) + c[:, None]
    pts = pts + np.random.default_rng(1).normal(0, 5e-4, pts.shape)
    _write_csv(tmp_path / "traj.csv", t, ["m1", "m2", "m3"], pts)
    _write_csv(tmp_path / "static.csv", [0.0], ["m1", "m2", "m3", "saddle"], np.vstack([MODEL, SADDLE])[None])
    out = tmp_path / f"kin{fps:g}"
    assert main(["kinematics", str(tmp_path / "traj.csv"), "--static", str(tmp_path / "static.csv"),
                 "--out", str(out), *extra]) == status
    checks = {c["name"]: c for c in json.loads((out / "kinematics-run.json").read_text())["quality"]["checks"]}
    assert checks["spline_basis"]["level"] == level, checks["spline_basis"]["message"]
    assert "the hidden point saddle's acceleration" in checks["spline_basis"]["message"]


def test_known_events_outside_the_refitted_stretch_are_left_to_the_record(tmp_path):
    """``--events`` at 1.0 s on a 600-frame record at 50 fps (the stretch refitted is 2.04-9.94 s): the refit takes
    only the events inside it, so the check has its figure (it crashed the command, a "skipped" level unknown to the
    verdict, when the refit was given the record's events)."""
    _kinematics_basis_check(tmp_path, 600, 50.0, "ok", 0, ("--events", "1.0"))


def test_the_check_reads_the_analysed_frames_of_a_wider_pose_record():
    """300 analysed frames at 50 fps and 600 frames after them in which the pose record goes on (the partial
    frames' stretch): the refitted stretch is centred on the analysed frames and only they are compared."""
    n, extra = 300, 600
    t_all = np.arange(n + extra) / 50.0
    c, rot = _path(t_all)
    pts = np.einsum("kij,mj->kmi", rot.as_matrix(), MODEL) + c[:, None]
    pts = pts + np.random.default_rng(0).normal(0, 5e-4, pts.shape)
    rb = analyse_rigid_body(t_all[:n], pts[:n], np.vstack([MODEL, SADDLE]), RigidBodyParams(saddle_marker=3),
                            period_s=1 / 1.7, static_index=np.arange(3), thesis_chain=False,
                            pose_input=PoseInput(points=pts, t=t_all))
    r = rb.basis_resolution
    assert r.stretch_s[0] == 0.0 and r.stretch_s[1] == pytest.approx(395 / 50.0)
    assert r.compared_s[0] >= 99 / 50.0 - 1e-9 and r.compared_s[1] <= (n - 1) / 50.0 + 1e-9


def test_an_uncapped_smoothing_is_not_checked():
    """``smoothing: none`` (interpolation) and ``gcv_cubic`` (SciPy's, a knot at every sample) have no capped basis."""
    t = np.arange(800) / 50.0
    reg = SimpleNamespace(rotation=np.repeat(np.eye(3)[None], t.size, 0))
    for method in ("none", "gcv_cubic"):
        assert basis_resolution(SimpleNamespace(t=t), reg, MODEL, SADDLE, PoseParams(smoothing=method)) is None
