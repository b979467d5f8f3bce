"""Partly covered markers: the region's shape against its own track, covers in the virtual lab, the record's ends."""
import numpy as np
import pytest

from horsemocap import quality
from horsemocap.detection.candidates import frame_candidates
from horsemocap.detection.tracker3d import COVER_AREA, COVER_SPREAD, IDENTIFICATION_REASONS, shape_change
from horsemocap.virtuallab.covers import COVER_SESSIONS, Cover, adapt_scene, placed_covers, segment_depth
from horsemocap.virtuallab.hard import plan


def _marker_image(centre, radius=5.0, smear=(0.0, 0.0), cover=None, size=(60, 80)):
    """A bright disc (smeared along ``smear`` px) on a dark ground, sampled 8 x 8 per pixel, blurred a little.

    ``cover``: (unit direction, chord distance in radii): the part of the disc beyond the chord is dark.
    """
    h, w = size
    s = 8
    v, u = np.mgrid[0:h * s, 0:w * s] / s + 0.5 / s - 0.5
    lit = np.zeros(u.shape)
    for a in np.linspace(-0.5, 0.5, 7):
        cu, cv = centre[0] + a * smear[0], centre[1] + a * smear[1]
        inside = (u - cu) ** 2 + (v - cv) ** 2 <= radius ** 2
        if cover is not None:
            (du, dv), d = cover
            inside &= (u - cu) * du + (v - cv) * dv <= d * radius
        lit = np.maximum(lit, inside)
    img = lit.reshape(h, s, w, s).mean(axis=(1, 3))
    return np.clip(30 + 200 * img, 0, 255).astype(np.uint8)


def _region(img):
    c = frame_candidates(img, 120, (3, 400), None, light=True)
    assert len(c) == 1
    return c.area[0], c.moments[0], c.centre[0]


@pytest.mark.parametrize("smear", [(0.0, 0.0), (6.0, 0.0)])
def test_a_third_covered_is_told_from_the_whole_marker(smear):
    ref_area, ref_m, _ = _region(_marker_image((30.3, 25.6), smear=smear))
    # the same marker elsewhere (sub-pixel phase): unchanged shape
    a, s = shape_change(*_region(_marker_image((41.7, 30.2), smear=smear))[:2], ref_area, ref_m)
    assert a > COVER_AREA and s > COVER_SPREAD, (a, s)
    # a third covered from below (a leg), from the front (a hand): shrinks and loses spread
    for direction in ((0.0, 1.0), (1.0, 0.0), (0.6, 0.8)):
        area, mom, centre = _region(_marker_image((30.3, 25.6), smear=smear,
                                                  cover=(direction, segment_depth(1 / 3))))
        a, s = shape_change(area, mom, ref_area, ref_m)
        assert a < COVER_AREA and s < COVER_SPREAD, (direction, a, s)
        # the bias the flag protects from: the centre pulled away from the cover by about 1.4 px
        assert np.dot(centre - (30.3, 25.6), direction) < -0.8


def test_partly_covered_is_a_documented_reason():
    assert "partly_covered" in IDENTIFICATION_REASONS


def test_cover_ramps_in_and_out_and_names_its_truth():
    c = Cover(marker=1, cameras=("left",), start_s=1.0, duration_s=0.4, fraction=0.3, ramp_s=0.1)
    f = c.fraction_at([0.9, 1.0, 1.05, 1.2, 1.35, 1.4, 1.5])
    assert f.tolist() == pytest.approx([0.0, 0.0, 0.15, 0.3, 0.15, 0.0, 0.0])


def test_cover_session_truth_marks_the_covered_marker():
    sc = COVER_SESSIONS["leg_canter"]
    covers = placed_covers(sc)
    p = plan(sc.base, adapt_scene(sc, covers))
    truth, cover = p["truth"], covers[0]
    frac = truth.extras["cover_fraction__leg__left"]
    on = frac > 0
    assert on.sum() >= 10
    assert np.all(truth.marker_reason["left"][on, cover.marker] == "occluded_in_camera")
    assert not np.any(truth.marker_reason["right"][:, cover.marker] == "occluded_in_camera")
    # the cover lies inside the record's fully visible frames
    ref_left = set(truth.ref_frames.tolist())
    assert set(np.flatnonzero(on).tolist()) <= ref_left


def test_record_ends_check_reads_the_written_series():
    t = np.arange(300) / 50.0
    ay = 8.0 * np.sin(2 * np.pi * 1.8 * t)
    assert quality.check_record_ends(ay, 50 / 1.8).level == "ok"
    bad = ay.copy()
    bad[-12:] += np.linspace(0, 30, 12)          # the last frames run away (a biased marker near the end)
    check = quality.check_record_ends(bad, 50 / 1.8)
    assert check.level == "unreliable"
    assert "kinematics.csv" in check.input
    assert quality.check_record_ends(ay[:50], 50 / 1.8).level == "skipped"    # under two strides
    assert quality.check_saddle_acceleration(float(np.max(np.abs(bad)))).input.startswith("kinematics.csv")
