"""Field-by-field centres of an interlaced camera's markers (horsemocap.detection.fields), on combed blobs whose
two fields' true centres are known exactly."""
import numpy as np
import pytest

from horsemocap.detection.fields import (FIELD_NOT_FOUND, corrected_mean, field_centroid, field_centroids,
                                         field_image, remeasure_by_fields, row_aliasing)
from horsemocap.sources import fields_blended


def blob(shape, u, v, sigma=1.6, peak=210.0, background=20.0):
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    return background + peak * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * sigma ** 2))


def combed(shape, first, second, first_parity=1):
    """A frame whose rows of ``first_parity`` show a marker at ``first`` and the other rows one at ``second``."""
    rows = np.arange(shape[0])[:, None]
    img = np.where(rows % 2 == first_parity, blob(shape, *first), blob(shape, *second))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


CASES = [((30.0, 20.0), (35.3, 20.0)), ((30.37, 21.71), (36.02, 22.15)), ((41.8, 17.25), (36.6, 16.9)),
         ((25.5, 24.5), (25.5, 24.5))]


@pytest.mark.parametrize("first, second", CASES)
def test_each_field_gives_its_own_marker(first, second):
    frame = combed((48, 72), first, second)
    mid = 0.5 * (np.array(first) + np.array(second))
    np.testing.assert_allclose(field_centroid(frame, 1, mid, 80), first, atol=0.03)
    np.testing.assert_allclose(field_centroid(frame, 0, mid, 80), second, atol=0.03)


@pytest.mark.parametrize("first, second", CASES)
def test_mean_of_fields_is_halfway(first, second):
    frame = combed((48, 72), first, second)
    start = 0.5 * (np.array(first) + np.array(second)) + [0.6, -0.4]      # a rough position is enough
    centres, per_field, found = field_centroids(frame, [start], 80)
    assert found.tolist() == [True]
    np.testing.assert_allclose(per_field[1, 0], first, atol=0.03)
    np.testing.assert_allclose(per_field[0, 0], second, atol=0.03)
    np.testing.assert_allclose(centres[0], 0.5 * (np.array(first) + np.array(second)), atol=0.02)


def test_blended_frame_gives_the_same_blob_back_for_a_still_marker():
    """A marker that does not move between the fields: blending changes nothing measurable, and both fields agree."""
    frame = combed((48, 72), (30.4, 20.3), (30.4, 20.3))
    centres, _, _ = field_centroids(frame, [[30.0, 20.0]], 80)
    np.testing.assert_allclose(centres[0], (30.4, 20.3), atol=0.02)
    centres_b, _, _ = field_centroids(fields_blended(frame), [[30.0, 20.0]], 80)
    np.testing.assert_allclose(centres_b[0], (30.4, 20.3), atol=0.02)


def test_remeasure_keeps_what_a_field_does_not_show_and_says_so():
    frames = [combed((48, 72), (30.0, 20.0), (34.0, 20.0)) for _ in range(2)]
    px = np.array([[[32.2, 20.1], [60.0, 40.0]], [[np.nan, np.nan], [32.0, 20.0]]])
    got = remeasure_by_fields(frames, px, 80)
    out = got.marker_px
    np.testing.assert_allclose(out[0, 0], (32.0, 20.0), atol=0.02)
    np.testing.assert_array_equal(out[0, 1], (60.0, 40.0))            # no blob there: the value kept
    assert np.all(np.isnan(out[1, 0]))                                  # not seen stays not seen
    np.testing.assert_allclose(out[1, 1], (32.0, 20.0), atol=0.02)
    assert got.reason.tolist() == [["", FIELD_NOT_FOUND], ["", ""]]
    np.testing.assert_array_equal(got.aliasing, (0.0, 0.0))           # too few marker-frames to fit it


def test_field_image_keeps_the_fields_rows():
    frame = np.arange(30, dtype=np.uint8).reshape(6, 5) * 7
    for parity in (0, 1):
        np.testing.assert_array_equal(field_image(frame, parity)[parity::2], frame[parity::2])


@pytest.mark.parametrize("call, match", [
    (lambda: field_image(np.zeros((4, 4, 3), np.uint8), 0), "gray frame"),
    (lambda: field_image(np.zeros((4, 4), np.uint8), 2), "parity"),
    (lambda: field_image(np.zeros((1, 4), np.uint8), 0), "no two fields"),
    (lambda: remeasure_by_fields([], np.zeros((1, 3)), 80), "frames, markers, 2"),
    (lambda: remeasure_by_fields([], np.zeros((1, 3, 2)), 80), "1 frames of centres but 0 frames"),
])
def test_bad_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def disc_frame(shape, centre, radius=3.2, level=210.0, background=20.0, ss=8):
    """A sharp disc (area coverage by ``ss`` x ``ss`` subsamples), the kind of blob whose centre a field's
    two-row pitch samples unevenly."""
    h, w = shape
    off = (np.arange(ss) + 0.5) / ss - 0.5
    yy = (np.arange(h)[:, None] + off[None, :]).ravel()
    xx = (np.arange(w)[:, None] + off[None, :]).ravel()
    inside = ((xx[None, :] - centre[0]) ** 2 + (yy[:, None] - centre[1]) ** 2) <= radius ** 2
    cover = inside.reshape(h, ss, w, ss).mean(axis=(1, 3))
    return background + level * cover


def combed_discs(shape, first, second, first_parity=1):
    rows = np.arange(shape[0])[:, None]
    img = np.where(rows % 2 == first_parity, disc_frame(shape, first), disc_frame(shape, second))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_vertical_sampling_error_of_sharp_discs_is_fitted_and_removed():
    """Sharp discs moving up and down: each field's vertical centre errs with the disc's row (two-row pitch);
    the fitted error removed, the fields' mean is closer to the truth half-way between them."""
    t = np.arange(60.0)
    u = lambda s: 20.0 + 0.6 * s                                          # along the image, px
    v = lambda s: 24.0 + 4.0 * np.sin(2 * np.pi * s / 13.0)             # up and down, px
    frames, truth = [], []
    for k in t:
        first, second = (u(k - 0.25) % 40 + 16, v(k - 0.25)), (u(k + 0.25) % 40 + 16, v(k + 0.25))
        frames.append(combed_discs((48, 72), first, second))
        truth.append([0.5 * (u(k - 0.25) % 40 + 16 + u(k + 0.25) % 40 + 16), 0.5 * (v(k - 0.25) + v(k + 0.25))])
    truth = np.array(truth)[:, None, :]
    got = remeasure_by_fields(frames, truth + 0.3, 100)
    assert not np.any(got.reason != "")
    plain = got.per_field.mean(axis=1)
    err_plain = np.abs(plain[..., 1] - truth[..., 1])
    err_fixed = np.abs(got.marker_px[..., 1] - truth[..., 1])
    per_field_err = got.per_field[:, 1, 0, 1] - (24.0 + 4.0 * np.sin(2 * np.pi * (t - 0.25) / 13.0))
    assert np.abs(per_field_err).max() > 0.02                          # the error exists
    assert np.hypot(*got.aliasing) > 0.02
    assert err_fixed.mean() < 0.5 * err_plain.mean()


def test_row_aliasing_recovers_known_coefficients_either_field_order():
    y = lambda s: 100.0 + 3.0 * np.sin(2 * np.pi * s / 17.0)
    E = lambda w: -0.04 * np.cos(np.pi * w) + 0.09 * np.sin(np.pi * w)
    k = np.arange(300.0)
    for first in (1, 0):
        per_field = np.zeros((300, 2, 2, 2))
        for m, shift in enumerate((0.0, 5.3)):
            t_of = {first: k - 0.25, 1 - first: k + 0.25}
            for parity, sign in ((0, 1.0), (1, -1.0)):
                per_field[:, parity, m, 1] = y(t_of[parity] + shift) + sign * E(y(t_of[parity] + shift))
        np.testing.assert_allclose(row_aliasing(per_field), (-0.04, 0.09), atol=0.005)
        mid = np.stack([y(k + s) for s in (0.0, 5.3)], axis=1)
        # the corrected mean is the fields' true mean (to the curvature over half a frame)
        true_mean = 0.5 * (np.stack([y(k - 0.25 + s) + y(k + 0.25 + s) for s in (0.0, 5.3)], axis=1))
        np.testing.assert_allclose(corrected_mean(per_field, (-0.04, 0.09))[..., 1], true_mean, atol=1e-6)
        assert np.abs(mid - true_mean).max() < 0.02


def test_row_aliasing_without_enough_frames_is_zero():
    np.testing.assert_array_equal(row_aliasing(np.full((5, 2, 3, 2), np.nan)), (0.0, 0.0))
    with pytest.raises(ValueError, match="frames, 2 fields, markers, 2"):
        row_aliasing(np.zeros((5, 3, 2)))


def test_detect_step_measures_only_the_interlaced_cameras_by_fields(tmp_path):
    """The detect step's pass: an interlaced camera's centres become the fields' mean (its combed frames written
    as images), a progressive camera's are returned untouched (the same array)."""
    import cv2
    from types import SimpleNamespace

    from horsemocap.steps.detect import measured_by_fields

    folder = tmp_path / "left"
    folder.mkdir()
    first, second = (30.3, 20.6), (35.1, 20.9)
    for k in range(3):
        image = cv2.cvtColor(combed((48, 72), first, second), cv2.COLOR_GRAY2BGR)
        cv2.imwrite(str(folder / f"frame_{k:03d}.png"), image)
    timing = {"left": {"interlaced": "bottom_first"}, "right": {}}
    session = SimpleNamespace(cameras=["left", "right"], motion={"left": folder, "right": None},
                              camera_timing=lambda c: timing[c])
    sync = SimpleNamespace(offsets={"left": 1, "right": 0}, n_frames=2)
    given = {"left": np.array([[[32.0, 21.0]], [[np.nan, np.nan]]]), "right": np.array([[[5.0, 6.0]], [[7.0, 8.0]]])}
    messages = []
    out = measured_by_fields(session, sync, given, {"left": 80, "right": 80}, lambda *a: messages.append(a))
    assert out["right"] is given["right"]
    np.testing.assert_allclose(out["left"][0, 0], 0.5 * (np.array(first) + np.array(second)), atol=0.03)
    assert np.all(np.isnan(out["left"][1, 0]))
    assert len(messages) == 1 and "'left' (interlaced)" in messages[0][1]
