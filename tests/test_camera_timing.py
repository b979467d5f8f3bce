"""Free-running cameras in the virtual laboratory: timing functions and rendering."""
import numpy as np
import pytest

from horsemocap.virtuallab.session import free_running_offsets, render_session
from horsemocap.virtuallab.timing import (CameraTiming, draw_free_running, field_rows, field_start_times,
                                          flash_fraction, frame_start_times, row_time)
from horsemocap.virtuallab.truth import camera_timings, load_truth, true_offsets_frames


# ---------------------------------------------------------------------------
# timing functions: exact answers
# ---------------------------------------------------------------------------

def test_flash_onset_mid_exposure_lights_the_part_after_it():
    t = CameraTiming(nominal_fps=30.0, exposure_s=1 / 60)
    assert flash_fraction(t, 1.0, onset_s=1.0 + 0.3 / 60) == pytest.approx(0.7, abs=1e-12)
    assert flash_fraction(t, 1.0, onset_s=0.5) == 1.0
    assert flash_fraction(t, 1.0, onset_s=1.0 + 1 / 60) == pytest.approx(0.0, abs=1e-12)
    # on for the first 40 % of the exposure, then off
    assert flash_fraction(t, 1.0, onset_s=0.0, offset_s=1.0 + 0.4 / 60) == pytest.approx(0.4, abs=1e-12)
    # arrays: one value per frame start
    starts = frame_start_times(t, 4, t0=-1 / 30)
    np.testing.assert_allclose(flash_fraction(t, starts, onset_s=0.25 / 60), [0.0, 0.75, 1.0, 1.0], atol=1e-12)


def test_default_exposure_is_half_a_frame():
    assert CameraTiming(nominal_fps=25.0).exposure == pytest.approx(0.02)
    assert CameraTiming(nominal_fps=60.0).exposure == pytest.approx(1 / 120)
    assert CameraTiming(nominal_fps=30.0, exposure_s=0.004).exposure == 0.004


def test_100_ppm_clock_drifts_1_ms_in_10_s():
    fast = CameraTiming(nominal_fps=30.0, rate_offset_ppm=100.0)
    slow = CameraTiming(nominal_fps=30.0, rate_offset_ppm=-100.0)
    exact = CameraTiming(nominal_fps=30.0)
    k = 300                                                     # 10 s at 30 fps
    t_exact = frame_start_times(exact, k + 1)[k]
    assert t_exact == pytest.approx(10.0, abs=1e-12)
    assert t_exact - frame_start_times(fast, k + 1)[k] == pytest.approx(1e-3, abs=1e-6)
    assert frame_start_times(slow, k + 1)[k] - t_exact == pytest.approx(1e-3, abs=1e-6)
    assert fast.fps == pytest.approx(30.003)


def test_rolling_shutter_row_times():
    t = CameraTiming(nominal_fps=30.0, rolling_shutter_s=0.024)
    h = 480
    assert row_time(t, 2.0, 0, h) == 2.0
    assert row_time(t, 2.0, 240, h) == pytest.approx(2.012, abs=1e-12)
    assert row_time(t, 2.0, 120, h) == pytest.approx(2.006, abs=1e-12)
    np.testing.assert_allclose(row_time(t, 0.0, np.array([0, 479]), h), [0.0, 0.024 * 479 / 480], atol=1e-15)
    # a global shutter: every row at the frame's start
    assert row_time(CameraTiming(), 1.5, 400, h) == 1.5


def test_pal_fields_20_ms_apart_bottom_first():
    pal = CameraTiming(nominal_fps=25.0, interlaced="bottom_first")
    first, second = field_start_times(pal, 1.0)
    assert second - first == pytest.approx(0.020, abs=1e-12)
    # bottom field = odd rows, exposed first
    assert row_time(pal, 1.0, 1, 576) == 1.0
    assert row_time(pal, 1.0, 0, 576) == pytest.approx(1.020, abs=1e-12)
    assert row_time(pal, 1.0, 575, 576) == 1.0
    np.testing.assert_array_equal(field_rows(pal, 0, 576)[:3], [1, 3, 5])
    np.testing.assert_array_equal(field_rows(pal, 1, 576)[:3], [0, 2, 4])
    assert len(field_rows(pal, 0, 576)) + len(field_rows(pal, 1, 576)) == 576


def test_timing_rejects_bad_fields_by_name():
    with pytest.raises(ValueError, match="phase_frames"):
        CameraTiming(phase_frames=1.0)
    with pytest.raises(ValueError, match="interlaced"):
        CameraTiming(interlaced="odd")
    with pytest.raises(ValueError, match="exposure_s"):
        CameraTiming(nominal_fps=30.0, exposure_s=0.05)
    with pytest.raises(ValueError, match="unknown fields"):
        CameraTiming.from_dict({"phase": 0.2})


def test_draw_free_running_ranges_and_round_trip():
    draws = [draw_free_running(np.random.default_rng(s), 50.0) for s in range(20)]
    for timings in draws:
        assert timings["left"].phase_frames == 0.0
        for t in timings.values():
            assert 0.0 <= t.phase_frames < 1.0
            assert abs(t.rate_offset_ppm) <= 100.0
            assert 0.0 <= t.rolling_shutter_s <= 0.018
            assert CameraTiming.from_dict(t.to_dict()) == CameraTiming.from_dict(t.to_dict())
    phases = [d["middle"].phase_frames for d in draws]
    assert min(phases) < 0.25 and max(phases) > 0.75
    pal = draw_free_running(np.random.default_rng(0), 25.0, interlaced="bottom_first")
    assert all(t.rolling_shutter_s == 0 and t.interlaced == "bottom_first" for t in pal.values())
    assert draw_free_running(np.random.default_rng(3), 30.0) == draw_free_running(np.random.default_rng(3), 30.0)


def test_true_offsets_are_the_whole_frames_minus_the_phase():
    t = {"left": CameraTiming(phase_frames=0.1), "middle": CameraTiming(phase_frames=0.6),
         "right": CameraTiming(phase_frames=0.05)}
    got = free_running_offsets(t, {"left": 8, "middle": 61, "right": 134})
    assert got == pytest.approx({"left": 0.0, "middle": 52.5, "right": 126.05})


# ---------------------------------------------------------------------------
# rendering
# ---------------------------------------------------------------------------

def _frames(folder, cam):
    import cv2
    files = sorted((folder / "motion" / cam).glob("*.png"), key=lambda p: int(p.stem[len(cam):]))
    return [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in files]


SMALL = dict(horse="Horse 2", gait="sitting_trot", seed=7, compress=False, calibration_views=0,
             left_offset=1, sync_deltas_s=(1 / 30, 1 / 30), n_motion_frames=3)


def test_genlocked_render_is_unchanged_by_the_timing_argument(tmp_path):
    a = render_session(tmp_path / "a", **SMALL)
    b = render_session(tmp_path / "b", timing=None, **SMALL)
    for cam in ("left", "middle", "right"):
        fa, fb = _frames(a, cam), _frames(b, cam)
        assert len(fa) == len(fb) > 0
        for x, y in zip(fa, fb):
            assert np.array_equal(x, y)
    ta = load_truth(a)
    assert not ta.free_running and "camera_timing" not in ta.extras
    assert true_offsets_frames(ta) == {"left": 0.0, "middle": 1.0, "right": 2.0}
    assert set(camera_timings(ta)) == {"left", "middle", "right"}


def test_free_running_truth_times_differ_by_the_phase(tmp_path):
    timing = {"left": CameraTiming(nominal_fps=30.0),
              "middle": CameraTiming(phase_frames=0.4, rate_offset_ppm=80.0, nominal_fps=30.0),
              "right": CameraTiming(phase_frames=0.8, nominal_fps=30.0, rolling_shutter_s=0.02)}
    out = render_session(tmp_path / "free", timing=timing, **SMALL)
    truth = load_truth(out)
    assert truth.free_running
    assert truth.offsets == {"left": 1, "middle": 2, "right": 3}
    t_left = truth.extras["frame_time_s__left"]
    t_mid = truth.extras["frame_time_s__middle"]
    np.testing.assert_allclose(t_left, (np.arange(len(t_left)) - 1) / 30.0, atol=1e-12)
    np.testing.assert_allclose(t_mid, (np.arange(len(t_mid)) - 2 + 0.4) / timing["middle"].fps, atol=1e-12)
    assert true_offsets_frames(truth) == pytest.approx({"left": 0.0, "middle": 0.6, "right": 1.2})
    assert truth.extras["true_rate_ratio"]["middle"] == pytest.approx(1 + 80e-6)
    # global shutters: every marker at its frame's instant; rolling shutter: later, by its row
    np.testing.assert_allclose(truth.extras["marker_time_s__middle"], t_mid[:, None] + np.zeros(4), atol=1e-12)
    late = truth.extras["marker_time_s__right"] - truth.extras["frame_time_s__right"][:, None]
    assert np.all((late >= 0) & (late <= 0.02))
    # the flash switches on in the middle of the left camera's frame 1 (genlocked convention: frame 1 shows t = 0)
    lit = truth.extras["flash_lit__left"]
    assert lit[1] == pytest.approx(0.5) and lit[0] == 0.0
    assert session_timing(out)["middle"]["phase_frames"] == 0.4


def session_timing(folder):
    import json
    return json.loads((folder / "session.json").read_text())["metadata"]["camera_timing"]


def test_rolling_shutter_markers_are_drawn_where_the_truth_says(tmp_path):
    timing = {c: CameraTiming(nominal_fps=30.0, rolling_shutter_s=0.03, phase_frames=p)
              for c, p in (("left", 0.0), ("middle", 0.5), ("right", 0.25))}
    # frame 0 shows about 1.1 s after the flash: the horse in view (no flash in the record)
    out = render_session(tmp_path / "rs", horse="Horse 2", gait="sitting_trot", seed=5, compress=False,
                         calibration_views=0, left_offset=-47, sync_deltas_s=(0.0, 0.0), n_motion_frames=49,
                         timing=timing, noise=False)
    truth = load_truth(out)
    img = _frames(out, "middle")[1].astype(float).mean(axis=2)
    px = truth.marker_px["middle"][1]
    seen = truth.marker_visible["middle"][1]
    assert seen[:3].any()
    frame_instant = truth.extras["frame_time_s__middle"][1]
    for j in np.flatnonzero(seen[:3]):
        u, v = px[j]
        x0, y0 = int(u) - 7, int(v) - 7
        patch = np.clip(img[y0:y0 + 15, x0:x0 + 15] - 120.0, 0, None)
        yy, xx = np.mgrid[0:15, 0:15]
        centroid = np.array([(patch * xx).sum(), (patch * yy).sum()]) / patch.sum() + [x0, y0]
        assert np.linalg.norm(centroid - px[j]) < 0.3
        # the marker's own instant is its row's: a readout of 30 ms puts it well after the frame's instant
        assert truth.extras["marker_time_s__middle"][1, j] - frame_instant == pytest.approx(0.03 * v / 480, abs=2e-4)


def test_fraction_cost_known_answers():
    from horsemocap.virtuallab.timing import fraction_cost
    c = fraction_cost("Horse 2", "canter", 30.0, 0.5)
    assert c.delay_ms == pytest.approx(1000 / 60)
    assert c.travel_mm == pytest.approx(4.888888888888889 * 1000 / 60, rel=1e-9)
    # a small delay: the acceleration read late is off by about 2 pi f delay per harmonic, so it halves
    # with the delay, and is zero without one
    half = fraction_cost("Horse 2", "canter", 60.0, 0.05).acc_y_pct
    quarter = fraction_cost("Horse 2", "canter", 120.0, 0.05).acc_y_pct
    assert half == pytest.approx(2 * quarter, rel=0.02)
    assert fraction_cost("Horse 2", "walk", 30.0, 0.0).acc_y_pct == 0.0


def test_fractional_given_offsets_keep_the_interlaced_fields_timing():
    """Offsets given with a fraction of a frame (``--offsets``) time the centroids like the automatic ones do:
    an interlaced camera's blob a quarter frame after its frame's start, a rolling shutter's row by row."""
    from types import SimpleNamespace
    from horsemocap.steps.detect import observation_times
    timing = {"left": {"interlaced": True}, "right": {"rolling_shutter_s": 0.02}}
    session = SimpleNamespace(fps=25.0, camera_timing=lambda c: timing.get(c, {}))
    rig = {"left": SimpleNamespace(size=(720, 576)), "right": SimpleNamespace(size=(720, 576))}
    px = {c: np.array([[[100.0, 0.0]], [[100.0, 575.0]]]) for c in rig}
    given = observation_times(session, SimpleNamespace(subframe_method="given in parameters"), rig, px)
    assert set(given) == {"left", "right"}
    assert np.all(given["left"][:, 0] - np.arange(2) > 0.2)          # the fields' mean: a quarter frame late
    assert given["right"][1, 0] - 1.0 > given["right"][0, 0]          # the last row read out later
    assert observation_times(session, SimpleNamespace(subframe_method=""), rig, px) == {}
