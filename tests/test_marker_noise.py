"""The virtual laboratory's correlated marker noise (horsemocap.virtuallab.noise): known answers."""
from dataclasses import replace

import numpy as np
import pytest

from horsemocap.virtuallab.horse import saddle_motion
from horsemocap.virtuallab.noise import MarkerNoise
from horsemocap.virtuallab.rig import thesis_rig
from horsemocap.virtuallab.session import Scene, render_motion_frame, _scene_and_backgrounds


def _ar1_part(mn, seed, camera, frames, markers=4):
    t = np.arange(frames) / mn.frame_rate_hz
    return mn.offsets(seed, camera, t, markers) - mn.bias(seed, camera, markers)[None]


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.9])
def test_lag1_correlation_and_std_as_specified(rho):
    mn = MarkerNoise(sigma_px=0.4, rho=rho, bias_px=0.0)
    e = _ar1_part(mn, 3, "middle", 40000)
    for j in range(4):
        for axis in range(2):
            x = e[:, j, axis]
            r1 = np.corrcoef(x[1:], x[:-1])[0, 1]
            # standard error of a lag-1 correlation over 40000 frames: about 0.005 (more for large rho)
            assert abs(r1 - rho) < 0.02, (j, axis, r1)
            assert abs(x.std() / 0.4 - 1) < (0.03 if rho < 0.8 else 0.06)


def test_bias_is_constant_per_camera_and_marker_with_the_given_spread():
    mn = MarkerNoise(sigma_px=0.3, rho=0.8, bias_px=0.25)
    b = mn.bias(5, "left", 4)
    e = mn.offsets(5, "left", np.arange(30000) / 30.0, 4)
    # the mean offset over a long record is the bias (AR(1) 0.8: the mean's error ~0.3 * 3 / sqrt(30000))
    assert np.allclose(e.mean(0), b, atol=0.02)
    # the biases' spread over many cameras and markers is bias_px
    many = np.concatenate([mn.bias(s, c, 50) for s in range(40) for c in ("left", "middle", "right")])
    assert abs(many.std() / 0.25 - 1) < 0.03
    # other camera, other biases and noise; same inputs, same values
    assert not np.allclose(mn.bias(5, "right", 4), b)
    assert np.array_equal(mn.offsets(5, "left", [1.0, 2.0], 4), mn.offsets(5, "left", [1.0, 2.0], 4))


def test_noise_does_not_depend_on_the_query():
    mn = MarkerNoise(sigma_px=0.3, rho=0.9, bias_px=0.0)
    long = mn.offsets(1, "left", np.arange(3000) / 30.0, 2)
    short = mn.offsets(1, "left", np.arange(10) / 30.0, 2)
    assert np.array_equal(long[:10], short)


def test_displaced_marker_projects_by_the_offset():
    cam = thesis_rig()["left"]
    mn = MarkerNoise(sigma_px=0.5, rho=0.7, bias_px=0.2, frame_rate_hz=30.0)
    centres = np.array([[[0.3, -1.2, 8.0], [0.5, -1.1, 8.1], [0.2, -1.0, 7.9], [0.4, -1.3, 8.2]]])
    moved = mn.displace(centres, cam, 0.5, 11)
    shift = cam.project(moved) - cam.project(centres)
    assert np.allclose(shift[0], mn.offsets(11, "left", [0.5], 4)[0], atol=1e-6)
    # moved within its depth from the camera
    assert np.allclose(np.linalg.norm(moved - cam.center, axis=-1), np.linalg.norm(centres - cam.center, axis=-1))


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="rho"):
        MarkerNoise(rho=1.0)
    with pytest.raises(ValueError, match="sigma_px"):
        MarkerNoise(sigma_px=-1)


def test_default_scene_has_no_marker_noise_and_the_option_moves_the_markers():
    scene, bgs = _scene_and_backgrounds("Horse 2", "canter", 0)
    assert scene.marker_noise is None
    cam = scene.rig["left"]
    plain = render_motion_frame(scene, cam, 40, 8, bgs["left"], noise=False)
    zero = render_motion_frame(replace(scene, marker_noise=MarkerNoise(0.0, 0.0, 0.0)), cam, 40, 8, bgs["left"],
                               noise=False)
    noisy = render_motion_frame(replace(scene, marker_noise=MarkerNoise(1.5, 0.8, 1.0)), cam, 40, 8, bgs["left"],
                                noise=False)
    assert np.abs(zero.astype(int) - plain.astype(int)).max() <= 1
    assert np.abs(noisy.astype(int) - plain.astype(int)).max() > 20
