"""The static shot's uncertainty carried to the saddle's acceleration (horsemocap.uncertainty, quality)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import quality
from horsemocap.camera import Camera, Rig
from horsemocap.reconstruction import triangulate
from horsemocap.uncertainty import (StaticShotUncertainty, saddle_acceleration_sensitivity, saddle_offset_map,
                                    static_shot_uncertainty, still_point_covariance, weighted_rms_sd_pct)

K = [[1000.0, 0.0, 640.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]]
MARKERS = np.array([[-0.35, 0.0, 4.0], [0.35, 0.02, 4.05], [0.0, -0.06, 4.02]])   # a thin triangle
SADDLE = np.array([0.05, 0.35, 4.0])


def _rig():
    turn = np.radians([-12.0, 0.0, 12.0])           # toed in, about the vertical axis
    return Rig(tuple(Camera(name, (1280, 720), K, rotation=[0.0, y, 0.0], translation=[x, 0.0, 0.0])
                     for name, y, x in zip(("left", "middle", "right"), turn, (0.6, 0.0, -0.6))))


def _body_offset(markers, saddle):
    """The saddle's offset from the true body frame, nonlinearly: the measured markers fitted to the true ones
    (Kabsch), the measured saddle carried by that fit, against the true saddle."""
    a, b = markers - markers.mean(0), MARKERS - MARKERS.mean(0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(u @ vt))
    R = (u @ np.diag([1, 1, d]) @ vt).T
    return R @ (saddle - markers.mean(0)) + MARKERS.mean(0) - SADDLE


def test_offset_map_is_blind_to_a_rigid_motion_of_the_whole_still():
    L = saddle_offset_map(MARKERS, SADDLE)
    small = Rotation.from_rotvec([1e-3, -2e-3, 1.5e-3]).as_matrix()
    still = np.vstack([MARKERS, SADDLE])
    centre = still.mean(0)
    d = ((still - centre) @ small.T + centre + [3e-4, -2e-4, 4e-4] - still).reshape(-1)
    assert np.abs(L @ d).max() < 1e-2 * np.abs(d).max()                # second order only
    d = np.zeros(12)
    d[9:] = [1e-3, -2e-3, 3e-3]                                        # the saddle point alone
    assert np.allclose(L @ d, [1e-3, -2e-3, 3e-3])


def test_offset_covariance_matches_monte_carlo_over_the_still_pixels():
    """Pixels -> triangulated still -> saddle offset: the linear covariance against 2000 noisy stills (noise
    small enough for the triangle's tilt to stay linear: a few degrees)."""
    rig, noise = _rig(), 0.1
    still = np.vstack([MARKERS, SADDLE])
    px = rig.project(still[None])
    rng = np.random.default_rng(7)
    draws = 2000
    noisy = {c: px[c] + rng.normal(0, noise, (draws,) + px[c].shape[1:]) for c in rig.names}
    pts = triangulate(rig, noisy, max_residual_px=None).points
    offsets = np.array([_body_offset(p[:3], p[3]) for p in pts])
    cov = still_point_covariance(rig, still, noise)
    L = saddle_offset_map(MARKERS, SADDLE)
    block = np.zeros((12, 12))
    for i in range(4):
        block[3 * i:3 * i + 3, 3 * i:3 * i + 3] = cov[i]
    predicted = np.sqrt(np.diag(L @ block @ L.T))
    measured = offsets.std(0)
    assert predicted.max() > 1e-2                                      # the thin triangle: centimetres
    assert np.allclose(measured, predicted, rtol=0.1)


def test_sensitivity_is_the_rigid_body_acceleration_of_the_offset():
    rng = np.random.default_rng(3)
    w, al = rng.normal(0, 2, (20, 3)), rng.normal(0, 20, (20, 3))
    R = Rotation.from_rotvec(rng.normal(0, 0.5, (20, 3))).as_matrix()
    dr = np.array([0.01, -0.02, 0.005])
    r = R @ dr
    expected = np.cross(al, r) + np.cross(w, np.cross(w, r))
    assert np.allclose(saddle_acceleration_sensitivity(w, al, R) @ dr, expected)


def test_static_shot_uncertainty_predicts_the_error_of_noisy_stills():
    """The whole chain: the estimate against the rms acceleration error of many noisy stills."""
    rig, noise = _rig(), 0.1
    n = 100
    t = np.arange(n) / 50.0
    w = np.zeros((n, 3)); w[:, 0] = 0.8 * np.cos(2 * np.pi * 2 * t)              # pitching and rolling
    al = np.zeros((n, 3)); al[:, 0] = -0.8 * 2 * np.pi * 2 * np.sin(2 * np.pi * 2 * t)
    al[:, 2] = 15 * np.sin(2 * np.pi * 4 * t)
    R = np.repeat(np.eye(3)[None], n, 0)
    G = saddle_acceleration_sensitivity(w, al, R)
    ay = 6 * np.sin(2 * np.pi * 2 * t)
    u = static_shot_uncertainty(rig, np.vstack([MARKERS, SADDLE]), [0, 1, 2], 3, np.eye(3), noise, G, ay, fs=50.0)
    still = np.vstack([MARKERS, SADDLE])
    px = rig.project(still[None])
    rng = np.random.default_rng(11)
    noisy = {c: px[c] + rng.normal(0, noise, (1000,) + px[c].shape[1:]) for c in rig.names}
    pts = triangulate(rig, noisy, max_residual_px=None).points
    errors = [np.mean((G[:, 1, :] @ _body_offset(p[:3], p[3])) ** 2) for p in pts]
    assert u.sd == pytest.approx(np.sqrt(np.mean(errors)), rel=0.1)
    assert set(u.weighted_pct) == {"Wb", "Wk"} and all(np.isfinite(v) for v in u.weighted_pct.values())


def test_weighted_share_is_first_order_exact():
    t = np.arange(250) / 50
    wave = np.sin(2 * np.pi * 2 * t)
    g = np.zeros((250, 3)); g[:, 1] = 30 * wave; g[:, 2] = 30 * np.cos(2 * np.pi * 2 * t)   # in and out of phase
    pct = weighted_rms_sd_pct(g, np.diag([0, 1e-4, 1e-4]), 4 * wave, 50.0, "Wb")
    assert pct == pytest.approx(100 * 30 * 1e-2 / 4, rel=1e-6)          # only the in-phase part changes the rms


def test_still_covariance_uses_only_the_cameras_that_saw_each_point():
    rig, still = _rig(), np.vstack([MARKERS, SADDLE])
    every = still_point_covariance(rig, still, 0.1)
    seen = {c: np.ones(4, bool) for c in rig.names}
    seen["middle"] = np.array([True, True, True, False])             # the saddle missed by the middle camera
    fewer = still_point_covariance(rig, still, 0.1, seen)
    assert np.allclose(fewer[:3], every[:3])
    assert fewer[3][0, 0] > 1.2 * every[3][0, 0]                      # across the rays: two cameras, not three
    pair = Rig((rig["left"], rig["right"]))
    assert np.allclose(fewer[3], still_point_covariance(pair, still[3:], 0.1)[0])
    seen["left"] = np.array([True, True, True, False])               # now only one camera saw it
    with pytest.raises(ValueError, match="fewer than two cameras"):
        static_shot_uncertainty(rig, still, [0, 1, 2], 3, np.eye(3), 0.1, np.ones((5, 3, 3)), np.ones(5), seen=seen)


def test_bad_input_is_refused_naming_it():
    with pytest.raises(ValueError, match="noise_px"):
        still_point_covariance(_rig(), MARKERS, float("nan"))
    with pytest.raises(ValueError, match="seen"):
        still_point_covariance(_rig(), MARKERS, 0.1, {"left": np.ones(2, bool)})
    with pytest.raises(ValueError, match="collinear"):
        saddle_offset_map([[0, 0, 0], [1, 0, 0], [2, 0, 0]], SADDLE)
    with pytest.raises(ValueError, match="rotation"):
        saddle_acceleration_sensitivity(np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((3, 3, 3)))


def _uncertainty(pct):
    return StaticShotUncertainty(noise_px=0.1, offset_covariance=np.eye(3) * 1e-6, offset_sd_m=np.full(3, 1e-3),
                                 acceleration_sd=np.full(10, pct / 100), sd=pct / 100, rms=1.0, pct_of_rms=pct,
                                 weighted_pct={"Wb": pct / 3})


@pytest.mark.parametrize("pct,level", [(1.0, "ok"), (2.5, "ok"), (4.0, "warning"), (5.0, "warning"),
                                       (5.1, "unreliable"), (40.0, "unreliable")])
def test_static_shot_check_levels(pct, level):
    c = quality.check_static_shot(_uncertainty(pct))
    assert (c.name, c.level, c.figure) == ("static_shot", level, pct)
    assert "Wb rms" in c.message and c.threshold == "ok <= 2.5 %; warning <= 5 %; unreliable above"
    if level == "unreliable":
        assert "10 %" in c.message


def test_static_shot_check_skipped_with_its_reason():
    c = quality.check_static_shot(quality.StaticShotSkipped("no pixel noise measured"))
    assert c.level == "skipped" and "no pixel noise measured" in c.message
    assert quality.verdict([c]) == "ok"


def test_static_shot_check_unreliable_names_a_clip_as_a_clip_also_when_worth_one_frame():
    """A static clip whose average is worth a single independent frame (strongly correlated noise) is still a
    clip: the message must not call it "one still" nor ask for a clip to be recorded."""
    still = quality.check_static_shot(_uncertainty(40.0))
    clip = quality.check_static_shot(_uncertainty(40.0), clip_frames=12)
    assert "one still cannot place the saddle" in still.message
    assert "record the static shot as a clip" in still.message
    assert "this static clip cannot place the saddle" in clip.message
    assert "record a longer static clip" in clip.message and "one still" not in clip.message
