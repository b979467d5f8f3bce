"""An interlaced camera's frame: each field's image blurred on its own, then its rows sampled."""
import hashlib

import numpy as np
import pytest

from horsemocap.virtuallab.horse import saddle_motion
from horsemocap.virtuallab.render import finish, interlaced_readout, render_arena
from horsemocap.virtuallab.rig import thesis_rig
from horsemocap.virtuallab.session import render_free_running_frame, Scene
from horsemocap.virtuallab.timing import CameraTiming, field_rows, field_start_times

#: A frame start (s) at which the sitting trot's markers are in the middle camera's view.
IN_VIEW_S = 2.3


@pytest.fixture(scope="module")
def middle_camera():
    scene = Scene(thesis_rig(), saddle_motion("Horse 2", "sitting_trot"), 5)
    cam = next(c for c in scene.rig if c.name == "middle")
    bg = render_arena(cam, scene.motion.R_wg, scene.motion.c_g, scene.arena, seed=5)
    return scene, cam, bg


@pytest.mark.parametrize("order", ["bottom_first", "top_first"])
def test_interlaced_field_rows_are_a_progressive_render_of_that_fields_instant(middle_camera, order):
    scene, cam, bg = middle_camera
    pal = CameraTiming(nominal_fps=25.0, phase_frames=0.4, rate_offset_ppm=60.0, interlaced=order)
    # the same camera, progressive, with the field's exposure: one frame per field instant
    progressive = CameraTiming(nominal_fps=25.0, phase_frames=0.4, rate_offset_ppm=60.0, exposure_s=pal.exposure)
    frame = render_free_running_frame(scene, cam, 3, IN_VIEW_S, pal, bg, noise=False)
    h = cam.size[1]
    moved = []
    for f, start in enumerate(field_start_times(pal, IN_VIEW_S)):
        alone = render_free_running_frame(scene, cam, 3, start, progressive, bg, noise=False)
        rows = field_rows(pal, f, h)
        np.testing.assert_array_equal(frame[rows], alone[rows])
        moved.append(alone)
    # the horse moves between the fields (else the test would not tell a blend from its fields)
    assert np.abs(moved[0].astype(int) - moved[1].astype(int)).max() > 100


def test_interlaced_readout_keeps_the_other_fields_light_out():
    first = np.zeros((8, 5, 3))
    first[3, 2] = 240.0                      # a bright point in the first field's image (row 3: first field)
    second = np.zeros((8, 5, 3))
    rows = [np.arange(1, 8, 2), np.arange(0, 8, 2)]
    out = interlaced_readout([first, second], rows, noise=False)
    assert out[rows[1]].max() == 0           # the second field's rows got none of it
    assert finish(first, noise=False)[[2, 4], 2, 0].min() > 0   # a blur after interleaving would light them
    with pytest.raises(ValueError, match="each of the 8 rows once"):
        interlaced_readout([first, second], [rows[0], rows[0]], noise=False)


def test_interlaced_noise_is_drawn_once_per_pixel(middle_camera):
    scene, cam, bg = middle_camera
    pal = CameraTiming(nominal_fps=25.0, phase_frames=0.4, interlaced="bottom_first")
    clean = render_free_running_frame(scene, cam, 3, IN_VIEW_S, pal, bg, noise=False).astype(float)
    noisy = render_free_running_frame(scene, cam, 3, IN_VIEW_S, pal, bg, noise=True).astype(float)
    again = render_free_running_frame(scene, cam, 3, IN_VIEW_S, pal, bg, noise=True)
    np.testing.assert_array_equal(noisy, again)                      # deterministic per frame
    # the renderer's sensor model: sd = sqrt(2.2^2 + 0.04 x light); away from the clipped ends, |noise| / sd
    # has mean sqrt(2 / pi) = 0.798 for one normal draw per pixel, 1.13 for two draws, 0 for none (the
    # pixels' rounding to whole levels and a few glints move it by hundredths)
    lit = (clean > 20) & (clean < 235)
    scaled = np.abs(noisy - clean)[lit] / np.sqrt(2.2 ** 2 + 0.04 * clean[lit])
    assert 0.72 < scaled.mean() < 0.88


#: SHA-256 (first 16 hex digits) of progressive free-running frames as rendered before interlaced frames
#: were composed field by field: progressive output must not change (every cached render stays valid).
PROGRESSIVE_DIGESTS = {
    ("rolling", True): "1c8e62b5cc2fa642",
    ("rolling", False): "bac17da161906b22",
    ("global", True): "2d04535b990e1243",
    ("global", False): "db1cabb85bdae4fc",
}


@pytest.mark.parametrize("shutter,noise", list(PROGRESSIVE_DIGESTS))
def test_progressive_frames_are_unchanged(middle_camera, shutter, noise):
    scene, cam, bg = middle_camera
    timing = (CameraTiming(nominal_fps=30.0, phase_frames=0.3, rolling_shutter_s=0.02, rate_offset_ppm=40.0)
              if shutter == "rolling" else CameraTiming(nominal_fps=25.0, phase_frames=0.6))
    img = render_free_running_frame(scene, cam, 3, IN_VIEW_S, timing, bg, noise=noise)
    assert hashlib.sha256(img.tobytes()).hexdigest()[:16] == PROGRESSIVE_DIGESTS[(shutter, noise)]
