"""Virtual laboratory: rig tables, analytic motion, rendering, truth, sessions."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from horsemocap import virtuallab as vl
from horsemocap.data import default_session_dir, data_samples_dir
from horsemocap.virtuallab import render as R
from horsemocap.virtuallab import session as S
from horsemocap.virtuallab.rig import EXTRINSICS, INTRINSICS


# ---------------------------------------------------------------- rig
def test_rig_reproduces_tables_8_1_to_8_4():
    rig = vl.thesis_rig()
    assert rig.names == ["left", "middle", "right"]
    for cam in rig:
        assert cam.size == (640, 480)
    L, M, Rr = rig["left"], rig["middle"], rig["right"]
    np.testing.assert_allclose(L.focal, INTRINSICS["left"]["left-middle"]["fc"])
    np.testing.assert_allclose(M.principal_point, [314.71229, 232.66709])
    np.testing.assert_allclose(Rr.distortions[:4], [-0.13740, 0.06109, -0.00216, -0.00039])
    np.testing.assert_allclose(L.rotation, 0)
    np.testing.assert_allclose(L.translation, 0)
    np.testing.assert_allclose(M.translation * 1000, [-238.05656, -4.25963, -13.06120])
    np.testing.assert_allclose(Rr.translation * 1000, [-446.97074, -3.85081, 10.56836])
    # rotations: the table's 4-decimal matrices, projected on SO(3)
    np.testing.assert_allclose(M.rotation_matrix, EXTRINSICS["left-middle"]["R"], atol=2e-4)
    np.testing.assert_allclose(Rr.rotation_matrix, EXTRINSICS["left-right"]["R"], atol=6e-4)


def test_pair_disagreement_matches_direct_composition():
    d = vl.pair_disagreement()
    Rml = np.array(EXTRINSICS["left-middle"]["R"])
    Rrl = np.array(EXTRINSICS["left-right"]["R"])
    Rrm = np.array(EXTRINSICS["middle-right"]["R"])
    tml = np.array(EXTRINSICS["left-middle"]["t_mm"])
    trl = np.array(EXTRINSICS["left-right"]["t_mm"])
    trm = np.array(EXTRINSICS["middle-right"]["t_mm"])
    t_comp = trl - Rrl @ Rml.T @ tml          # unprojected tables, mm
    assert abs(np.linalg.norm(t_comp - trm) - d["translation_mm"]) < 0.5
    assert 20 < d["translation_mm"] < 40       # ~30 mm, mostly along z
    assert 0.0 < d["rotation_deg"] < 0.2


# ---------------------------------------------------------------- motion
@pytest.mark.parametrize("horse", vl.HORSES)
@pytest.mark.parametrize("gait", vl.GAITS)
def test_analytic_derivatives_agree_with_finite_differences(horse, gait):
    m = vl.saddle_motion(horse, gait)
    h = 1e-5  # central differences: truncation ~h^2 x(4)/6, round-off ~1e-16 |x|/h
    t = np.linspace(0.0, 2.0, 41)
    pose = m.pose(t)
    pp, pm = m.pose(t + h), m.pose(t - h)
    P, V, A = pose.points(np.vstack([m.horse.marker_body, m.horse.saddle_body]))
    Pp, Vp, _ = pp.points(np.vstack([m.horse.marker_body, m.horse.saddle_body]))
    Pm, Vm, _ = pm.points(np.vstack([m.horse.marker_body, m.horse.saddle_body]))
    np.testing.assert_allclose((Pp - Pm) / (2 * h), V, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose((Vp - Vm) / (2 * h), A, rtol=1e-5, atol=1e-5)
    h2 = 3e-4
    P2p = m.pose(t + h2).points(np.vstack([m.horse.marker_body, m.horse.saddle_body]))[0]
    P2m = m.pose(t - h2).points(np.vstack([m.horse.marker_body, m.horse.saddle_body]))[0]
    np.testing.assert_allclose((P2p - 2 * P + P2m) / h2 ** 2, A, rtol=1e-4, atol=1e-3)
    # omega from dR/dt R^T, alpha from d omega/dt
    W = (pp.rotation - pm.rotation) / (2 * h) @ np.transpose(pose.rotation, (0, 2, 1))
    w = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1)
    np.testing.assert_allclose(w, pose.omega, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose((pp.omega - pm.omega) / (2 * h), pose.alpha, rtol=1e-5, atol=1e-5)
    # rigid: marker distances constant
    d = np.linalg.norm(P[:, 0] - P[:, 1], axis=-1)
    np.testing.assert_allclose(d, d[0], atol=1e-12)


def test_gait_speeds_follow_chapter_2():
    ranges = {"walk": (5, 7), "sitting_trot": (8, 10), "rising_trot": (8, 10), "canter": (16, 20)}
    for horse in vl.HORSES:
        for gait, (lo, hi) in ranges.items():
            v = vl.saddle_motion(horse, gait).gait.speed_mps * 3.6
            assert lo <= v <= hi, (horse, gait, v)


def test_motion_axes_and_net_displacement():
    m = vl.saddle_motion("Horse 2", "canter")
    ax = m.motion_axes
    np.testing.assert_allclose(ax @ ax.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.cross(ax[0], ax[1]), ax[2], atol=1e-12)
    np.testing.assert_allclose(ax[1], m.gravity)
    T = m.period_s
    for t0 in (0.1, 0.37):
        P = m.markers(np.array([t0, t0 + 2 * T]))[0]
        u1 = (P[1] - P[0]) / np.linalg.norm(P[1] - P[0], axis=-1, keepdims=True)   # thesis eq. 5.7
        np.testing.assert_allclose(u1, np.broadcast_to(ax[0], u1.shape), atol=1e-9)


# ---------------------------------------------------------------- rendering
@pytest.fixture(scope="module")
def scene_and_bgs():
    rig = vl.thesis_rig()
    m = vl.saddle_motion("Horse 2", "canter")
    scene = S.Scene(rig, m, 3)
    bgs = {c.name: R.render_arena(c, m.R_wg, m.c_g, seed=3) for c in rig}
    return scene, bgs


def test_noise_free_marker_centroid_within_0_05_px(scene_and_bgs):
    """Intensity-weighted centroid of each rendered (blurred, quantised) marker
    vs the projection of its 3D centre."""
    scene, bgs = scene_and_bgs
    offsets, _ = S.plan_timeline(scene)
    errors = []
    for cam in scene.rig:
        o = offsets[cam.name]
        for k in range(o + 24, o + 66, 6):
            t = (k - o) / 30.0
            a = S.render_motion_frame(scene, cam, k, o, bgs[cam.name], noise=False).astype(float).mean(-1)
            b = S.render_motion_frame(scene, cam, k, o, bgs[cam.name], noise=False, markers=False).astype(float).mean(-1)
            px, vis, _ = S.marker_projection_truth(scene, cam, np.array([t]), ride=True)
            for j in range(3):
                if not vis[0, j]:
                    continue
                u, v = px[0, j]
                x0, y0 = int(round(u)) - 8, int(round(v)) - 8
                if x0 < 0 or y0 < 0 or x0 + 17 > 640 or y0 + 17 > 480:
                    continue
                d = (a - b)[y0:y0 + 17, x0:x0 + 17]
                yy, xx = np.mgrid[y0:y0 + 17, x0:x0 + 17]
                c = np.array([(d * xx).sum(), (d * yy).sum()]) / d.sum()
                errors.append(np.hypot(*(c - px[0, j])))
    errors = np.array(errors)
    assert len(errors) >= 30
    assert errors.max() < 0.05, f"max centroid error {errors.max():.4f} px"


def test_perspective_bias_of_disc_centroid_is_tiny():
    cam = vl.thesis_rig()["left"]
    b = R.perspective_centroid_bias(cam, [2.5, 0.0, 8.0], [0.3, 0.2, -1.0], 0.03)
    assert np.hypot(*b) < 0.01
    # but a large disc close to the camera shows it
    b2 = R.perspective_centroid_bias(cam, [0.5, 0.0, 1.0], [0.7, 0.0, -0.7], 0.2)
    assert np.hypot(*b2) > 0.5


def test_rendering_is_deterministic_and_seeded(scene_and_bgs):
    scene, bgs = scene_and_bgs
    cam = scene.rig["middle"]
    offsets, _ = S.plan_timeline(scene)
    o = offsets["middle"]
    a = S.render_motion_frame(scene, cam, o + 40, o, bgs["middle"], noise=True)
    b = S.render_motion_frame(scene, cam, o + 40, o, bgs["middle"], noise=True)
    assert a.tobytes() == b.tobytes()
    other = S.Scene(scene.rig, scene.motion, 4)
    c = S.render_motion_frame(other, cam, o + 40, o, bgs["middle"], noise=True)
    assert a.tobytes() != c.tobytes()


def _digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.suffix in {".avi", ".png", ".jpg", ".json", ".toml"}}


def test_session_files_are_byte_identical_for_the_same_seed(tmp_path):
    a = vl.render_ball_drop(tmp_path / "a", seed=5, n_frames=3)
    b = vl.render_ball_drop(tmp_path / "b", seed=5, n_frames=3)
    da, db = _digest(a), _digest(b)
    assert any(k.endswith(".avi") for k in da)
    assert da == db


def test_marker_order_is_left_to_right_in_every_camera():
    t = vl.load_truth(default_session_dir())
    for cam in t.cameras:
        vis = t.marker_visible[cam][:, :3].all(axis=1)
        u = t.marker_px[cam][vis, :3, 0]
        assert np.all(np.diff(u, axis=1) > 12), cam   # well separated, same order


# ---------------------------------------------------------------- default session
def test_default_session_follows_the_spec():
    root = default_session_dir()
    sj = json.loads((root / "session.json").read_text())
    assert sj["format"] == "horsemocap-session/1"
    assert sj["cameras"] == ["left", "middle", "right"] and sj["reference_camera"] == "left"
    assert sj["sync"] == {"method": "flash"}
    assert sj["markers"] == {"count": 3, "diameter_m": 0.06}
    assert sj["fps"] == 30.0
    for key in ("motion", "plumb", "static"):
        for cam in sj["cameras"]:
            assert (root / sj[key][cam]).exists(), (key, cam)
    assert "rig" not in sj["calibration"]  # the pipeline calibrates; the true rig is in truth/
    assert (root / "truth" / "rig.toml").is_file()
    for cam in sj["cameras"]:
        assert (root / sj["calibration"]["images"][cam]).is_dir()
    assert len(sj["calibration"]["board"]["inner_corners"]) == 2
    assert sj["metadata"]["horse"] == "Horse 2" and sj["metadata"]["gait"] == "canter"


def test_default_session_truth_is_consistent():
    from horsemocap.sources import FrameSource
    root = default_session_dir()
    t = vl.load_truth(root)
    assert t.offsets["middle"] - t.offsets["left"] == 53
    assert t.offsets["right"] - t.offsets["middle"] == 73
    assert 34 <= len(t.ref_frames) <= 45                       # ~2 canter strides (thesis: 38)
    np.testing.assert_allclose(np.diff(t.time_s), 1 / 30)
    for cam in t.cameras:
        n = len(FrameSource(root / "motion" / f"{cam}.avi"))
        assert t.marker_px[cam].shape == (n, 4, 2)
        # truth pixels = projection of the truth positions
        k = t.ref_frames - t.offsets["left"] + t.offsets[cam]
        np.testing.assert_allclose(t.rig[cam].project(t.marker_pos), t.marker_px[cam][k, :3], atol=1e-9)
        np.testing.assert_allclose(t.rig[cam].project(t.saddle_pos), t.marker_px[cam][k, 3], atol=1e-9)
        assert not t.marker_visible[cam][k, 3].any()          # hidden by the rider (or outside)
        assert (t.marker_reason[cam][k, 3] == "occluded_by_rider").mean() > 0.8
        assert t.marker_visible[cam][k, :3].all()
    # gravity perpendicular to x-motion; static shot and plumb
    assert abs(t.gravity @ t.motion_axes[0]) < 1e-12
    assert t.static_pos.shape == (4, 3) and t.plumb_pos.shape == (2, 3)
    tip, tail = t.plumb_pos
    np.testing.assert_allclose((tip - tail) / np.linalg.norm(tip - tail), t.gravity, atol=1e-12)
    # comfort from the true saddle motion
    assert 16 <= t.comfort["vel_x_avg"] <= 20
    assert t.comfort["acc_y_max"] > 5


def test_ball_drop_sample_has_g():
    t = vl.load_truth(data_samples_dir() / "ball_drop")
    assert t.marker_pos.shape == (21, 1, 3)
    np.testing.assert_allclose(t.marker_acc[:, 0] @ t.gravity, 9.81, atol=1e-12)
    assert t.extras["g"] == 9.81


def test_herd_description():
    d = json.loads((data_samples_dir() / "herd.json").read_text())
    assert d == json.loads(json.dumps(vl.herd_description()))
    assert len(d["sessions"]) == 16
    assert len({s["seed"] for s in d["sessions"]}) == 16
    assert {(s["horse"], s["gait"]) for s in d["sessions"]} == {(h, g) for h in vl.HORSES for g in vl.GAITS}


def test_saddle_marker_is_hidden_by_the_rider_but_not_in_the_static_shot(scene_and_bgs):
    scene, bgs = scene_and_bgs
    offsets, _ = S.plan_timeline(scene)
    cam = scene.rig["left"]
    o = offsets["left"]
    for k in range(o + 25, o + 70, 9):
        t = (k - o) / 30.0
        a = S.render_motion_frame(scene, cam, k, o, bgs["left"], noise=False).astype(float)
        b = S.render_motion_frame(scene, cam, k, o, bgs["left"], noise=False, markers=False).astype(float)
        u, v = S.marker_projection_truth(scene, cam, np.array([t]), ride=True)[0][0, 3]
        if 8 < u < 632 and 8 < v < 472:
            assert np.abs(a - b)[int(v) - 6:int(v) + 7, int(u) - 6:int(u) + 7].max() == 0, k
    static = S.render_static(scene, cam, bgs["left"], noise=False).astype(float).mean(-1)
    u, v = cam.project(scene.marker_geometry(scene.motion.static_pose())[0][0, 3])
    assert static[int(round(v)), int(round(u))] > 200


def test_checkerboard_views_match_the_true_board_poses():
    import cv2
    from horsemocap.virtuallab.calibration import board_corners, detect_board
    root = default_session_dir()
    sj = json.loads((root / "session.json").read_text())
    inner = tuple(sj["calibration"]["board"]["inner_corners"])
    square = sj["calibration"]["board"]["square_size_m"]
    t = vl.load_truth(root)
    obj = board_corners(inner, square)
    for cam in t.cameras:
        folder = root / sj["calibration"]["images"][cam]
        checked = 0
        for i in range(3):                         # the first views (files <cam>1.*, <cam>2.*, ...)
            f = next(folder.glob(f"{cam}{i + 1}.*"))
            corners = detect_board(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), inner)
            if corners is None:
                continue
            proj = t.rig[cam].project(obj @ t.extras["board_R_wb"][i].T + t.extras["board_t_wb"][i])
            err = min(np.median(np.linalg.norm(corners - proj, axis=1)),
                      np.median(np.linalg.norm(corners[::-1] - proj, axis=1)))
            assert err < 0.3, (cam, i, err)
            checked += 1
        assert checked >= 2, cam


def test_herd_session_rejects_unknown_names(tmp_path):
    with pytest.raises(ValueError, match="Horse 9"):
        vl.herd_session("Horse 9", "walk", cache=tmp_path)
    with pytest.raises(ValueError, match="gallop"):
        vl.herd_session("Horse 1", "gallop", cache=tmp_path)


def test_calibration_protocols_differ_only_where_they_should():
    from horsemocap.virtuallab import saddle_motion
    from horsemocap.virtuallab.calibration import PROTOCOLS, board_poses

    motion = saddle_motion("Horse 2", "canter")
    path = board_poses(24, motion, 3, protocol="path")
    depths = board_poses(24, motion, 3, protocol="depths")
    z_path = np.array([np.linalg.norm(t) for _, t in path])
    z_depths = np.array([np.linalg.norm(t) for _, t in depths])
    assert z_depths.min() < 0.75 * z_path.min()          # some boards come nearer the cameras
    assert abs(z_depths[18:].mean() - z_path[18:].mean()) < 0.3   # the last slides stay at the path
    assert set(PROTOCOLS) == {"path", "depths"}
    with pytest.raises(ValueError, match="protocol"):
        board_poses(3, motion, 0, protocol="lab")
