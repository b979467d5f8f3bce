"""The harder virtual laboratory (issue 17): rigs, extras and their exact truth.

Fast: a tiny scenario is planned (truth only) and a few clean frames are
rendered at reduced size; no session is rendered.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from horsemocap.virtuallab import session as S
from horsemocap.virtuallab import hard as H
from horsemocap.virtuallab.horse import HERD, SaddleMotion, marker_height
from horsemocap.virtuallab.render import render_arena
from horsemocap.virtuallab.truth import load_truth, save_truth

TINY = H.HardScenario("tiny", "Horse 2", "sitting_trot", 77, 30.0,
                      H.RigSpec((640, 360), "toed_in", 0.6), speed_change=(-0.6, 2.5), stirrup=True,
                      reflector=True, occlusion=("middle", 1, 0.5, 6), sync_deltas_s=(0.2, 0.1))


@pytest.fixture(scope="module")
def tiny():
    return H.plan(TINY)


def _gray(img):
    return img.astype(float).mean(-1)


def test_occlusion_truth_matches_the_image(tiny):
    scene, truth, off = tiny["scene"], tiny["truth"], tiny["offsets"]
    cam = scene.rig["middle"]
    hidden = truth.marker_reason["middle"] == "occluded_in_camera"
    frames = np.flatnonzero(hidden.any(axis=1))
    # exactly the chosen marker, for exactly the chosen number of consecutive frames, in that camera only
    assert len(frames) == 6 and np.all(np.diff(frames) == 1)
    assert hidden[:, 1].sum() == 6 and hidden[:, [0, 2, 3]].sum() == 0
    for other in ("left", "right"):
        assert not (truth.marker_reason[other] == "occluded_in_camera").any()
    assert truth.extras["occluder_description"]["frames"] == frames.tolist()
    # the hidden frames stay in the analysed run (the other cameras see the marker)
    assert set(frames - off["middle"] + off["left"]) <= set(truth.ref_frames.tolist())
    bg = render_arena(cam, scene.motion.R_wg, scene.motion.c_g, scene.arena, seed=TINY.seed)
    exp = H.exposure_for(TINY.fps)
    for k in (frames[0] - 1, frames[0], frames[-1], frames[-1] + 1):
        img = _gray(S.render_motion_frame(scene, cam, int(k), off["middle"], bg, noise=False, fps=TINY.fps,
                                          exposure_s=exp))
        u, v = truth.marker_px["middle"][k, 1]
        win = img[int(round(v)) - 2:int(round(v)) + 3, int(round(u)) - 2:int(round(u)) + 3]
        if hidden[k, 1]:
            assert win.max() < 60, (k, win.max())          # not one bright pixel of the marker
        else:
            assert truth.marker_visible["middle"][k, 1]
            assert win.max() > 150, (k, win.max())
        # the other markers are untouched
        for j in (0, 2):
            u, v = truth.marker_px["middle"][k, j]
            assert img[int(round(v)) - 1:int(round(v)) + 2, int(round(u)) - 1:int(round(u)) + 2].max() > 150


def _segments_cross(a, b) -> bool:
    """Whether polylines ``a`` (n, 2) and ``b`` (m, 2) intersect (proper crossings)."""
    p, r = a[:-1, None], (a[1:] - a[:-1])[:, None]
    q, s = b[None, :-1], (b[1:] - b[:-1])[None]
    den = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
    qp = q - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / den
        u = (qp[..., 0] * r[..., 1] - qp[..., 1] * r[..., 0]) / den
    return bool(np.any((t >= 0) & (t <= 1) & (u >= 0) & (u <= 1) & (den != 0)))


def test_reflector_path_crosses_the_markers_paths_without_covering_them(tiny):
    truth = tiny["truth"]
    crossed = []
    for cam in truth.cameras:
        path = truth.extras[f"reflector_px__{cam}"]
        inside = truth.extras[f"reflector_inside__{cam}"]
        assert path.shape == (len(truth.marker_px[cam]), 2) and inside.any()
        for j in range(3):
            vis = truth.marker_visible[cam][:, j]
            if _segments_cross(path[inside], truth.marker_px[cam][vis, j]):
                crossed.append((cam, j))
        # at the same instant the reflector never sits on a marker (>= 2 marker diameters apart)
        d = np.hypot(*(truth.marker_px[cam][:, :3] - path[:, None]).transpose(2, 0, 1))
        diameter_px = truth.rig[cam].focal.mean() * S.MARKER_DIAMETER / 7.5
        assert np.nanmin(d[inside]) > 2 * diameter_px
    assert crossed, "the reflector's image path crosses no marker path"


def test_stirrup_hangs_below_the_markers_and_shines(tiny):
    truth, scene = tiny["truth"], tiny["scene"]
    st = next(e for e in scene.extras if isinstance(e, H.Stirrup))
    for cam in truth.cameras:
        path = truth.extras[f"stirrup_px__{cam}"]
        vis = truth.marker_visible[cam][:, :3].all(axis=1)
        # image v grows downwards: the stirrup is below every skin marker in every frame
        assert np.all(path[vis, 1] > truth.marker_px[cam][vis, :3, 1].max(axis=1) + 20)
        b = truth.extras[f"stirrup_brightness__{cam}"]
        assert b.max() > 0.95 and b.min() < 0.5                       # marker-bright at times, dull at others
    # its swing is its own: relative to the body it moves
    x = st.body_position(np.linspace(0, 1, 50))
    assert np.ptp(x[:, 0]) > 0.05


def test_speed_change_kinematics_are_exact():
    h = HERD["Horse 2"]
    g = h.gait("canter")
    w = 2 * math.pi / 3.0
    base = SaddleMotion(h, g, -3.0, marker_height(h))
    m = SaddleMotion(h, g, -3.0, marker_height(h),
                     speed_change=H.Harmonics((1,), (-1.0 / w,), (0.4,)), speed_change_hz=1 / 3.0)
    t = np.linspace(0.2, 2.8, 41)
    dt = 1e-5
    p0, v0, a0 = m.markers(t)
    pm, vm, _ = m.markers(t - dt)
    pp, vp, _ = m.markers(t + dt)
    np.testing.assert_allclose(v0, (pp - pm) / (2 * dt), atol=1e-6)
    np.testing.assert_allclose(a0, (vp - vm) / (2 * dt), atol=1e-4)
    # the speed really changes (by 2 m/s peak to peak, beyond the surge) ...
    speed = m.forward_speed(t) - base.forward_speed(t)
    assert np.ptp(speed) > 1.9
    # ... along the path only: the saddle's vertical motion (comfort) is untouched
    axes = m.motion_axes
    np.testing.assert_allclose(m.saddle(t)[2] @ axes[1], base.saddle(t)[2] @ axes[1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("size", [(1280, 720), (1920, 1080)])
@pytest.mark.parametrize("kind", ["toed_in", "wide"])
def test_rig_builder_sees_the_horse(size, kind):
    spec = H.RigSpec(size, kind, 0.8)
    rig, R_wg, c_g = H.hard_rig(spec, seed=3)
    assert rig.names == ["left", "middle", "right"]
    np.testing.assert_allclose(rig["left"].rotation, 0, atol=1e-12)
    np.testing.assert_allclose(rig["left"].translation, 0, atol=1e-12)
    h = HERD["Horse 2"]
    m = SaddleMotion(h, h.gait("canter"), 0.0, marker_height(h), R_wg=R_wg, c_g=c_g)
    static = m.static_pose().points(np.vstack([h.marker_body, h.saddle_body[None]]))[0][0]
    centres = []
    for cam in rig:
        assert cam.size == size
        px = cam.project(static)
        assert np.all(cam.in_image(px, margin=50)), (cam.name, px)
        # the horse is as large as in the thesis (or larger): marker spacing in px per image width
        spread = np.ptp(px[:3, 0]) / size[0]
        assert spread > 0.8 * 0.48 * 730 / (7.7 * 640)     # thesis: 0.48 m of markers at 7.7 m, f = 730 px
        centres.append(cam.center)
    base = np.linalg.norm(centres[2] - centres[0])
    assert 1.5 < base < 1.7
    # toed-in: the optical axes converge on the path; wide: nearly parallel
    z = [cam.rotation_matrix[2] for cam in rig]
    ang = math.degrees(math.acos(np.clip(z[0] @ z[2], -1, 1)))
    assert (ang > 8) if kind == "toed_in" else (ang < 3)


def test_border_aim_and_timeline_scaled_in_seconds():
    sc = H.HARD_SESSIONS["rising720_toedin_100_border"]
    scene, info = H.build_scene(sc)
    cam = scene.rig["middle"]
    offsets, _ = S.plan_timeline(scene, sc.fps, left_offset=10, sync_deltas_s=sc.sync_deltas_s)
    assert offsets["middle"] - offsets["left"] == round(sc.sync_deltas_s[0] * 100)
    assert S.flash_frames(100.0) == 13 and S.flash_frames(30.0) == S.FLASH_FRAMES
    # the thesis' offsets at 30 fps, the same seconds at 60 fps
    o30, _ = S.plan_timeline(scene, 30.0, left_offset=0)
    o60, _ = S.plan_timeline(scene, 60.0, left_offset=0)
    assert o30["middle"] == S.DELTA_F_LM and o60["middle"] == 2 * S.DELTA_F_LM
    ts = np.arange(0.3, 3.0, 0.01)
    px = cam.project(scene.motion.markers(ts)[0])
    horiz = np.all((px[..., 0] > 15) & (px[..., 0] < cam.size[0] - 15), axis=1)
    gap = cam.size[1] - 1 - px[horiz][..., 1].max()
    assert 8 < gap < 20
    # the plumb and the flash stay in every view (raised when needed)
    for c in scene.rig:
        assert np.all(c.in_image(c.project(S.plumb_world(scene)), margin=20))


def test_truth_carries_what_accuracy_needs_and_round_trips(tiny, tmp_path):
    truth = tiny["truth"]
    assert truth.fps == TINY.fps and set(truth.cameras) == {"left", "middle", "right"}
    assert truth.static_pos.shape == (4, 3) and truth.plumb_pos.shape == (2, 3)
    for key in ("acc_y_Wb_rms", "acc_y_Wk_rms", "VDV_y_Wb", "VDV_y_Wk", "vel_x_avg", "amplitude_y"):
        assert np.isfinite(truth.comfort[key])
    # vel_x_avg with a speed change: the mean over the analysed frames, exactly
    t = truth.motion_time_s
    p = tiny["scene"].motion.saddle(np.array([t[0], t[-1]]))[0]
    assert truth.comfort["vel_x_avg"] == pytest.approx((p[1] - p[0]) @ truth.motion_axes[0] / (t[-1] - t[0]) * 3.6)
    assert len(truth.ref_frames) / TINY.fps * tiny["scene"].motion.gait.stride_hz > 2.9
    save_truth(truth, tmp_path)
    back = load_truth(tmp_path)
    for cam in truth.cameras:
        np.testing.assert_array_equal(back.extras[f"stirrup_px__{cam}"], truth.extras[f"stirrup_px__{cam}"])
        np.testing.assert_array_equal(back.marker_reason[cam], truth.marker_reason[cam])
    assert back.extras["occluder_description"]["camera"] == "middle"


def test_hard_set_covers_the_issue():
    scs = list(H.HARD_SESSIONS.values())
    assert len(scs) >= 8
    sizes = {sc.rig.size for sc in scs}
    assert {(1280, 720), (1920, 1080)} <= sizes
    assert {50.0, 60.0, 100.0} <= {sc.fps for sc in scs}
    assert {"toed_in", "wide"} <= {sc.rig.kind for sc in scs}
    assert {"sitting_trot", "rising_trot", "canter"} <= {sc.gait for sc in scs}
    assert any(sc.stirrup for sc in scs) and any(sc.reflector for sc in scs)
    assert any(sc.rig.border for sc in scs) and any(sc.speed_change for sc in scs)
    assert all(5 <= sc.occlusion[3] <= 20 for sc in scs if sc.occlusion) and any(sc.occlusion for sc in scs)


def test_hard_session_renders_once_into_the_cache(tmp_path, monkeypatch):
    calls = []

    def fake_render(out, sc, **kw):
        calls.append(sc.name)
        (out / "session.json").parent.mkdir(parents=True, exist_ok=True)
        (out / "session.json").write_text("{}")
        return out

    monkeypatch.setattr(H, "render_hard", fake_render)
    name = "canter720_toedin_60"
    a = H.hard_session(name, cache=tmp_path)
    b = H.hard_session(name, cache=tmp_path)
    assert a == b and calls == [name]
    assert a.name == f"hard-{name}-{H.hard_key(H.HARD_SESSIONS[name])}" and a.parent == tmp_path / "virtuallab"
    assert (a / ".complete").is_file() and not a.with_name(a.name + ".partial").exists()
    with pytest.raises(ValueError, match="unknown hard session"):
        H.hard_session("nope", cache=tmp_path)


def test_speed_change_extreme_when_passing_the_rig_centre():
    sc = H.HARD_SESSIONS["canter720_wide_50_everything"]
    m = H.build_scene(sc)[0].motion
    ts = np.arange(0.0, 6.0, 0.001)
    X = H._ground_points(m, m.pose(ts).position)[:, 0]
    t_c = ts[np.argmin(np.abs(X - sc.rig.centre_x_m))]
    # the speed change alone (no surge): dv at t_c, as documented (slowest there for dv < 0)
    d1 = m.speed_change.value(np.array([t_c]), m.speed_change_hz, 1)[0]
    assert d1 == pytest.approx(sc.speed_change[0], abs=0.02)


def test_plumb_and_flash_seen_by_every_camera_of_a_top_border_session():
    scene, info = H.build_scene(H.HARD_SESSIONS["sitting720_toedin_100_occluded_border"])
    flash = scene.ground_to_world(np.asarray(scene.flash_g)[None])
    for cam in scene.rig:
        assert np.all(cam.in_image(cam.project(S.plumb_world(scene)), margin=20)), cam.name
        assert np.all(cam.in_image(cam.project(flash), margin=20)), cam.name
    bad = H.HardScenario("bad", "Horse 2", "sitting_trot", 1, 30.0, H.RigSpec(border=("right", "top", 12.0)),
                         plumb=(0.2, 3.0))
    with pytest.raises(ValueError, match="plumb"):
        H.build_scene(bad)
