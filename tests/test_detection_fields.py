"""Field-by-field centres of an interlaced camera's markers (horsemocap.detection.fields), on combed blobs whose
two fields' true centres are known exactly."""
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from horsemocap import results
from horsemocap.detection.fields import (FIELD_NOT_FOUND, FIELDS_DISAGREE, aliasing_removable, corrected_mean,
                                         field_centroids, field_window, marker_in_fields, remeasure_by_fields,
                                         row_aliasing)
from horsemocap.sources import field_image, fields_blended
from horsemocap.steps import detect as detect_step
from horsemocap.steps.detect import FieldsMeasured, measured_by_fields


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
    per_field, reason = marker_in_fields(frame, mid, 80)
    assert reason == ""
    np.testing.assert_allclose(per_field[1], first, atol=0.03)
    np.testing.assert_allclose(per_field[0], second, atol=0.03)


@pytest.mark.parametrize("first, second", CASES)
def test_mean_of_fields_is_halfway(first, second):
    frame = combed((48, 72), first, second)
    start = 0.5 * (np.array(first) + np.array(second)) + [0.6, -0.4]      # a rough position is enough
    centres, per_field, reason = field_centroids(frame, [start], 80)
    assert reason.tolist() == [""]
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


def test_field_window_keeps_the_fields_rows():
    frame = np.arange(30, dtype=np.uint8).reshape(6, 5) * 7
    for parity in (0, 1):
        np.testing.assert_array_equal(field_window(frame, parity)[parity::2], frame[parity::2])


@pytest.mark.parametrize("rows, cols", [((0, 9), (0, 13)), ((3, 8), (2, 11)), ((4, 5), (0, 13)), ((0, 1), (5, 6)),
                                        ((8, 9), (3, 9)), ((1, 9), (12, 13)), ((-4, 40), (-3, 30))])
def test_field_window_is_the_whole_fields_image_cut(rows, cols):
    """Any window (odd or even first row, at the frame's edges) is exactly the whole field's image, rounded."""
    frame = np.random.default_rng(3).integers(0, 256, (9, 13)).astype(np.uint8)
    r = slice(max(rows[0], 0), min(rows[1], 9))
    c = slice(max(cols[0], 0), min(cols[1], 13))
    for parity in (0, 1):
        whole = np.clip(np.rint(field_image(frame, parity)), 0, 255).astype(np.uint8)
        np.testing.assert_array_equal(field_window(frame, parity, rows, cols), whole[r, c])


@pytest.mark.parametrize("call, match", [
    (lambda: field_window(np.zeros((4, 4, 3), np.uint8), 0), "gray frame"),
    (lambda: field_window(np.zeros((4, 4), np.uint8), 2), "parity"),
    (lambda: field_window(np.zeros((1, 4), np.uint8), 0), "no two fields"),
    (lambda: field_window(np.zeros((4, 4), np.uint8), 0, (5, 7), (0, 4)), "misses the 4x4 frame"),
    (lambda: corrected_mean(np.zeros((1, 2, 1, 2)), (0.3, 0.2)), "not a function of the row"),
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
        fitted = row_aliasing(per_field)
        np.testing.assert_allclose(fitted, (-0.04, 0.09), atol=0.005)
        # with the fitted error removed, the fields' mean is their true mean (the plain mean is not)
        true_mean = 0.5 * (np.stack([y(k - 0.25 + s) + y(k + 0.25 + s) for s in (0.0, 5.3)], axis=1))
        np.testing.assert_allclose(corrected_mean(per_field, fitted)[..., 1], true_mean, atol=0.005)
        np.testing.assert_allclose(corrected_mean(per_field, (-0.04, 0.09))[..., 1], true_mean, atol=1e-9)
        assert np.abs(per_field[..., 1].mean(axis=1) - true_mean).max() > 0.02


def test_row_aliasing_without_enough_frames_is_zero():
    np.testing.assert_array_equal(row_aliasing(np.full((5, 2, 3, 2), np.nan)), (0.0, 0.0))
    with pytest.raises(ValueError, match="frames, 2 fields, markers, 2"):
        row_aliasing(np.zeros((5, 3, 2)))


def write_frames(folder, frames):
    folder.mkdir()
    for k, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"frame_{k:03d}.png"), cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))


def test_detect_step_measures_only_the_interlaced_cameras_by_fields(tmp_path):
    """The detect step's pass: an interlaced camera's centres become the fields' mean (its combed frames written
    as images), a progressive camera's are returned untouched (the same array); what was kept is typed."""
    first, second = (30.3, 20.6), (35.1, 20.9)
    write_frames(tmp_path / "left", [combed((48, 72), first, second) for _ in range(3)])
    timing = {"left": {"interlaced": "bottom_first"}, "right": {}}
    session = SimpleNamespace(cameras=["left", "right"], motion={"left": tmp_path / "left", "right": None},
                              camera_timing=lambda c: timing[c])
    sync = SimpleNamespace(offsets={"left": 1, "right": 0}, n_frames=2)
    given = {"left": np.array([[[32.0, 21.0]], [[np.nan, np.nan]]]), "right": np.array([[[5.0, 6.0]], [[7.0, 8.0]]])}
    messages = []
    out, by_fields = measured_by_fields(session, sync, given, {"left": 80, "right": 80},
                                        lambda *a: messages.append(a))
    assert out["right"] is given["right"]
    np.testing.assert_allclose(out["left"][0, 0], 0.5 * (np.array(first) + np.array(second)), atol=0.03)
    assert np.all(np.isnan(out["left"][1, 0]))
    assert len(messages) == 1 and "'left' (interlaced)" in messages[0][1]
    assert list(by_fields) == ["left"] and by_fields["left"].reason.tolist() == [[""], [""]]
    assert by_fields["left"].kept_blended == 0 and by_fields["left"].aliasing_note == ""


def glint_frame(shape, marker, glint, marker_parity=1):
    """The marker only in the rows of ``marker_parity`` (the other field does not show it), a glint only in
    the other field's rows."""
    rows = np.arange(shape[0])[:, None]
    img = np.where(rows % 2 == marker_parity, blob(shape, *marker), blob(shape, *glint))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("glint_u", [78.0, 76.0, 62.0])
def test_a_marker_missing_from_one_field_keeps_its_blended_centre_near_a_glint(glint_u):
    """The marker is in field 1 only; field 0 shows a glint nearby. The two do not straddle the blended centre
    (the marker's): the centre is kept, with the reason, not moved half-way to the glint."""
    frame = glint_frame((48, 100), (70.0, 20.0), (glint_u, 20.0))
    per_field, reason = marker_in_fields(frame, (70.0, 20.0), 80)
    assert reason == FIELDS_DISAGREE
    assert np.all(np.isnan(per_field))
    frames = [frame] * 3
    got = remeasure_by_fields(frames, np.array([[[70.0, 20.0]]] * 3), 80)
    np.testing.assert_array_equal(got.marker_px[:, 0], [[70.0, 20.0]] * 3)
    assert got.reason.tolist() == [[FIELDS_DISAGREE]] * 3


def test_a_glint_nearer_than_the_markers_own_field_blob_is_not_taken():
    """A fast marker (10 px between the fields) and a small glint in one field nearer the blended centre than the
    marker's own blob there: the pair of blobs that straddles the centre is the marker's."""
    shape = (48, 110)
    rows = np.arange(shape[0])[:, None]
    field1 = blob(shape, 65.0, 20.0, sigma=3.5)
    field0 = blob(shape, 75.0, 20.0, sigma=3.5) + blob(shape, 65.6, 20.0, sigma=1.2) - 20.0
    frame = np.clip(np.rint(np.where(rows % 2 == 1, field1, field0)), 0, 255).astype(np.uint8)
    per_field, reason = marker_in_fields(frame, (70.0, 20.0), 80)
    assert reason == ""
    np.testing.assert_allclose(per_field[1], (65.0, 20.0), atol=0.05)
    np.testing.assert_allclose(per_field[0], (75.0, 20.0), atol=0.05)


@pytest.mark.parametrize("radius", [3.2, 11.0, 18.0])
def test_large_discs_are_measured_in_each_field(radius):
    """The window follows the blob's size and its smear: a disc of radius 11 or 18 px is measured too."""
    shape = (110, 140)
    first, second = (60.3, 50.4), (66.1, 51.7)
    rows = np.arange(shape[0])[:, None]
    img = np.where(rows % 2 == 1, disc_frame(shape, first, radius), disc_frame(shape, second, radius))
    frame = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    mid = 0.5 * (np.array(first) + np.array(second))
    per_field, reason = marker_in_fields(frame, mid + [0.3, -0.2], 100)
    assert reason == ""
    np.testing.assert_allclose(per_field[1, 0], first[0], atol=0.05)        # u: no row sampling along u
    np.testing.assert_allclose(per_field[0, 0], second[0], atol=0.05)
    np.testing.assert_allclose(per_field[:, 1], [second[1], first[1]], atol=0.3)


def test_no_blended_blob_at_the_centre_is_not_found():
    frame = combed((48, 72), (30.0, 20.0), (34.0, 20.0))
    assert marker_in_fields(frame, (60.0, 40.0), 80)[1] == FIELD_NOT_FOUND
    assert marker_in_fields(frame, (-3.0, 20.0), 80)[1] == FIELD_NOT_FOUND


@pytest.mark.parametrize("a, b", [(0.0, -0.13), (0.3, 0.0), (0.2, -0.24), (-0.31, 0.0)])
def test_corrected_mean_inverts_the_sampling_error_exactly(a, b):
    """Rows sampled with a known error, up to amplitudes near the limit pi * amplitude < 1, come back exactly."""
    rows = np.linspace(100.0, 104.0, 401)
    error = lambda v: a * np.cos(np.pi * v) + b * np.sin(np.pi * v)
    per_field = np.zeros((rows.size, 2, 1, 2))
    per_field[:, 0, 0, 1] = rows + error(rows)
    per_field[:, 1, 0, 1] = rows + 0.5 - error(rows + 0.5)
    assert aliasing_removable((a, b))
    np.testing.assert_allclose(corrected_mean(per_field, (a, b))[:, 0, 1], rows + 0.25, atol=1e-9)


def test_row_aliasing_is_not_bent_by_mismeasured_fields():
    """A tenth of the marker-frames measured 2 px off in one field (another light taken): the fit still finds
    the error."""
    y = lambda s: 100.0 + 3.0 * np.sin(2 * np.pi * s / 17.0)
    E = lambda w: -0.04 * np.cos(np.pi * w) + 0.09 * np.sin(np.pi * w)
    k = np.arange(300.0)
    per_field = np.zeros((300, 2, 1, 2))
    per_field[:, 0, 0, 1] = y(k + 0.25) + E(y(k + 0.25))
    per_field[:, 1, 0, 1] = y(k - 0.25) - E(y(k - 0.25))
    clean = row_aliasing(per_field)
    per_field[::10, 0, 0, 1] += 2.0
    np.testing.assert_allclose(row_aliasing(per_field), clean, atol=0.002)
    np.testing.assert_allclose(row_aliasing(per_field), (-0.04, 0.09), atol=0.01)


def test_an_error_too_large_to_remove_is_noted_and_the_plain_mean_used(monkeypatch):
    frames = [combed((48, 72), (30.0, 20.0), (34.0, 20.0))]
    monkeypatch.setattr("horsemocap.detection.fields.row_aliasing", lambda per_field: np.array([0.4, 0.0]))
    got = remeasure_by_fields(frames, np.array([[[32.2, 20.1]]]), 80)
    assert "too large" in got.aliasing_note
    np.testing.assert_allclose(got.marker_px[0, 0], got.per_field[0, :, 0].mean(axis=0))


def test_the_thesis_chain_measures_interlaced_cameras_by_fields_too(monkeypatch):
    """The per-camera chain hands its centroids and its thresholds to the field measurement."""
    n = 12
    track = SimpleNamespace(marker_px=np.full((n, 3, 2), 5.0), reason=np.full((n, 3), ""),
                            params=SimpleNamespace(to_dict=lambda: {"threshold": 77}))
    calls = []

    def fields_pass(session, sync, marker_px, thresholds, progress):
        calls.append(thresholds)
        return {c: px + 1.0 for c, px in marker_px.items()}, {"left": "measured"}

    monkeypatch.setattr(detect_step, "synchronised_frames", lambda *a, **k: SimpleNamespace(close=lambda: None))
    monkeypatch.setattr(detect_step, "detect_markers", lambda *a, **k: track)
    monkeypatch.setattr(detect_step, "measured_by_fields", fields_pass)
    session = SimpleNamespace(cameras=["left", "right"], marker_count=3, fps=25.0)
    sync = SimpleNamespace(n_frames=n)
    section = SimpleNamespace(cameras={}, max_gap_frames=None)
    got = detect_step._detect_per_camera(session, section, sync, lambda *a: None, "")
    assert calls == [{"left": 77, "right": 77}]
    np.testing.assert_array_equal(got.marker_px["left"], 6.0)
    assert got.fields == {"left": "measured"}


def test_analysis_json_records_what_the_fields_kept():
    measured = FieldsMeasured(reason=np.array([["", FIELD_NOT_FOUND], [FIELDS_DISAGREE, FIELD_NOT_FOUND]]),
                              aliasing_px=np.array([0.00123, -0.12345]))
    detect = SimpleNamespace(detection={}, method="multiview", method_note="", identification=None, segment=(0, 2),
                             fields={"left": measured})
    chosen = {}
    results._record_detect(detect, {}, chosen)
    assert chosen["interlaced_fields"] == {"left": {"aliasing_px": [0.0012, -0.1235], "aliasing_removed": True,
                                                    "kept_blended": {FIELD_NOT_FOUND: 2, FIELDS_DISAGREE: 1}}}
    assert measured.kept_blended == 3
    chosen = {}
    results._record_detect(SimpleNamespace(**{**vars(detect), "fields": {}}), {}, chosen)
    assert "interlaced_fields" not in chosen
