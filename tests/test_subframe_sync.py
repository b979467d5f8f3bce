"""Sub-frame synchronisation: the flash's fraction, the markers' refinement, tracks at common instants."""
from types import SimpleNamespace

import numpy as np
import pytest

from horsemocap import aperture, quality, subframe
from horsemocap.cli import _parse_offsets
from horsemocap.data import default_session_dir
from horsemocap.params import AnalysisParams, ParamsError
from horsemocap.pipeline import analyze
from horsemocap.session import Session
from horsemocap.steps.detect import CameraSyncCheck
from horsemocap.steps.sync import SyncResult, exposure_fractions
from horsemocap.sync import detect_flash


@pytest.fixture(scope="module")
def rig():
    return analyze(default_session_dir(), None, {}, until="rig", progress=lambda *a: None).rig.rig


def _trajectory(n, m=3):
    """A trotting marker set 4 m in front of the rig: forward 3 m/s and a 2 Hz bounce, at 30 fps."""
    t = np.arange(n, dtype=float)[:, None] / 30.0
    base = np.array([[-0.2, 0.0, 4.0], [0.0, -0.1, 4.1], [0.2, 0.05, 3.9]])[:m]
    return lambda k: (base[None] + np.stack([-1.2 + 3.0 * (np.asarray(k, float)[:, None] / 30.0),
                                             0.06 * np.sin(2 * np.pi * 2.0 * np.asarray(k, float)[:, None] / 30.0),
                                             0.0 * np.asarray(k, float)[:, None]], axis=-1))


def test_flash_onset_partial_and_full_frames():
    partial = subframe.flash_onset([0, 0, 0.25, 1, 1], 0.0, 1.0, 3, exposure_fraction=0.4)
    assert partial.partial and partial.onset_frames == pytest.approx(2 + 0.4 * 0.75)
    full = subframe.flash_onset([0, 0, 1, 1], 0.0, 1.0, 2, exposure_fraction=0.5)
    assert not full.partial and full.onset_frames == pytest.approx(1.75)
    with pytest.raises(ValueError, match="exposure_fraction"):
        subframe.flash_onset([0, 1], 0.0, 1.0, 1, exposure_fraction=-0.1)


def test_an_instant_exposure_is_never_partly_lit():
    """With ``exposure_s`` 0 a frame is dark or lit: a half-bright first frame is a lit frame's noise, and
    the onset is anywhere in the period before it (middle taken, uniform spread)."""
    instant = subframe.flash_onset([0, 0, 0.6, 1, 1], 0.0, 1.0, 3, exposure_fraction=0.0)
    assert not instant.partial
    assert instant.onset_frames == pytest.approx(1.5)
    assert instant.uncertainty_frames == pytest.approx(1 / np.sqrt(12))


def test_sync_and_aperture_read_exposure_s_the_same_way():
    """One default, applied in one place: no ``exposure_s`` is half a frame for both the flash's timing and
    the pose's aperture, and ``exposure_s`` 0 is an instant for both."""
    meta = {"camera_timing": {"left": {"exposure_s": 0}, "middle": {"interlaced": None}, "right": {}}}
    s = SimpleNamespace(metadata=meta, fps=25.0, cameras=("left", "middle", "right"))
    s.camera_timing = lambda camera: Session.camera_timing(s, camera)
    assert exposure_fractions(s) == {"left": 0.0, "middle": 0.5, "right": 0.5}
    assert aperture.session_aperture(25.0, {"left": {"exposure_s": 0}}) is None
    assert aperture.session_aperture(25.0, {"middle": {"interlaced": None}}).description == "exposure 20 ms"


def test_tracks_at_reference_instants_cubic_and_outside():
    k = np.arange(20, dtype=float)
    px = np.stack([k ** 2, k], axis=-1)[:, None, :].copy()
    px[10] = np.nan
    out, outside = subframe.tracks_at_reference_instants({"a": px}, {"a": 0.3})
    assert out["a"][5, 0, 0] == pytest.approx((5 - 0.3) ** 2, rel=1e-6)
    same, none_out = subframe.tracks_at_reference_instants({"a": px}, {"a": 0.0})
    assert same["a"] is px and not none_out["a"].any()


def test_markers_recover_the_phases(rig):
    n, true_phase = 90, {"middle": 0.37, "right": -0.22}
    where = _trajectory(n)
    names = list(rig.names)
    ref = names[0]
    px = {}
    for c in names:
        k = np.arange(n) + true_phase.get(c, 0.0)       # camera c's frame k is at reference instant k + phase
        px[c] = rig[c].project(where(k))
    start = {c: 0.0 for c in names}
    fits = subframe.refine_phases(rig, px, start, ref)
    for c, p in true_phase.items():
        assert fits[c].phase == pytest.approx(p, abs=0.03)
        assert fits[c].rate_ratio == 1.0 or abs(fits[c].rate_ratio - 1) < 1e-3


def _ride_of_passes(rig, phase0: dict, ratio: dict, noise_px: float = 0.0, rho: float = 0.0, seed: int = 0,
                    n: int = 1500, lap: int = 700, seen: int = 90) -> dict:
    """Three passes of ``seen`` frames across ``n`` (one every ``lap``): camera c's frame j at the reference
    instant ``phase0[c] + ratio[c] j``; centroid noise AR(1) (``noise_px`` standard deviation, correlation
    ``rho`` from frame to frame, every camera its own)."""
    where = _trajectory(seen)
    rng = np.random.default_rng(seed)
    px = {}
    for c in rig.names:
        instant = phase0.get(c, 0.0) + ratio.get(c, 1.0) * np.arange(n)
        px[c] = rig[c].project(where(np.mod(instant, lap)))
        e = np.zeros((n, 3, 2))
        e[0] = noise_px * rng.standard_normal((3, 2))
        for k in range(1, n):
            e[k] = rho * e[k - 1] + noise_px * np.sqrt(1 - rho ** 2) * rng.standard_normal((3, 2))
        px[c] = px[c] + e
        px[c][np.mod(instant, lap) > seen] = np.nan
    return px


def test_a_drifting_clock_over_passes_gives_its_phase_at_frame_0_and_its_rate(rig):
    """Three passes of 90 frames across 1500, the middle camera's clock 300 ppm slow (0.45 frame of drift
    over the record), the right camera's exact: the middle camera's phase at frame 0 and its rate are
    found (a constant phase would be the drift's average, 0.22 frame off at the ends), the right camera's
    rate stays 1, and every camera's tracks then meet at the reference instants."""
    names = list(rig.names)
    phase0, ratio = {names[1]: 0.2, names[2]: -0.15}, {names[1]: 1.0003, names[2]: 1.0}
    px = _ride_of_passes(rig, phase0, ratio)
    fits = subframe.refine_phases(rig, px, {c: 0.0 for c in names}, names[0])
    assert fits[names[1]].phase == pytest.approx(0.2, abs=0.01)
    assert fits[names[1]].rate_ratio == pytest.approx(1.0003, abs=1e-5)
    assert fits[names[2]].phase == pytest.approx(-0.15, abs=0.01)
    assert fits[names[2]].rate_ratio == 1.0
    at_ref, _ = subframe.tracks_at_reference_instants(px, {c: f.phase for c, f in fits.items()},
                                                      {c: f.rate_ratio for c, f in fits.items()})
    late = slice(2 * 700 + 10, 2 * 700 + 80)
    truth = rig[names[1]].project(_trajectory(90)(np.arange(1500)[late] % 700))
    assert np.nanmax(np.abs(at_ref[names[1]][late] - truth)) < 0.05


def test_a_drift_measured_through_noisy_markers_is_not_pulled_toward_a_constant_phase(rig):
    """The same ride with 0.5 px of white centroid noise: each chunk's simplex, started from the record's
    constant phase, stopped short of the drift; on a grid about each camera's line first, then together, the
    rate is within 10 % of the drift and the phase at frame 0 within 0.03 frame (two seeds on which it was
    232 and 242 ppm against 300)."""
    names = list(rig.names)
    for seed in (1, 2):
        px = _ride_of_passes(rig, {names[1]: 0.2}, {names[1]: 1.0003}, noise_px=0.5, seed=seed)
        fit = subframe.refine_phases(rig, px, {c: 0.0 for c in names}, names[0])[names[1]]
        assert fit.rate_ratio - 1 == pytest.approx(3e-4, rel=0.1)
        assert fit.phase == pytest.approx(0.2, abs=0.03)


@pytest.mark.parametrize("seed", [0, 1])
def test_marker_noise_correlated_over_frames_is_not_taken_for_a_drifting_clock(rig, seed):
    """Three passes across 1500 frames, no camera drifting, every camera's centroids with AR(1) noise
    (0.15 px, correlation 0.8 from frame to frame): the chunks' phases trend with the noise's slow part,
    which a 2-standard-error test took for a drift; every rate stays 1 and the phases near the truth."""
    true_phase = {"middle": 0.37, "right": -0.22}
    px = _ride_of_passes(rig, true_phase, {}, noise_px=0.15, rho=0.8, seed=seed)
    fits = subframe.refine_phases(rig, px, {c: 0.0 for c in rig.names}, rig.names[0])
    for c, p in true_phase.items():
        assert fits[c].rate_ratio == 1.0
        assert fits[c].phase == pytest.approx(p, abs=0.1)


def test_seen_chunks_skip_the_empty_arena():
    px = np.full((100, 2, 2), np.nan)
    px[10:20] = px[60:70] = 5.0
    parts = subframe.seen_chunks({"a": px, "b": px, "c": np.full((100, 2, 2), np.nan)}, chunks=4)
    assert [p.tolist() for p in parts] == [list(range(10, 15)), list(range(15, 20)), list(range(60, 65)),
                                           list(range(65, 70))]
    across = subframe.seen_chunks({"a": px, "b": px}, chunks=3)      # the middle chunk spans both passes: cut,
    assert [p.tolist() for p in across] == [list(range(10, 17)), list(range(60, 64)),  # its 3-frame piece left out
                                            list(range(64, 70))]
    only_one = subframe.seen_chunks({"a": px, "b": np.full((100, 2, 2), np.nan)})
    assert only_one == []


def test_shifted_instants_follow_a_drifting_clock():
    p = np.arange(100.0).reshape(100, 1, 1) * 2.0
    out = subframe.points_at_shifted_instants(p, 0.5, 1.001)
    k = np.arange(100.0)
    inside = 0.5 + 1.001 * k < 99
    assert np.allclose(out[inside, 0, 0], 2.0 * (0.5 + 1.001 * k[inside]))
    assert np.isnan(out[~inside]).all()


def test_coupled_phases_are_refined_until_they_settle(rig):
    """Two cameras' phases off the search grid: each camera's best phase moves with the other's error, so both
    are moved together (a Nelder-Mead simplex) to the joint minimum (noise-free: a few thousandths of a frame)."""
    n, true_phase = 90, {rig.names[1]: 0.337, rig.names[2]: -0.263}
    px = _free_running_views(rig, n, true_phase)
    fits = subframe.refine_phases(rig, px, {c: 0.0 for c in rig.names}, rig.names[0])
    for c, p in true_phase.items():
        assert fits[c].phase == pytest.approx(p, abs=0.005)


def test_genlocked_sync_result_is_not_free_running():
    r = SyncResult(offsets={"left": 3, "middle": 17}, frame_counts={"left": 50, "middle": 60}, n_frames=40,
                   offsets_from="flashlight")
    assert not r.free_running
    assert r.offsets_with_fraction("left") == {"left": 0.0, "middle": 14.0}
    f = r.replace(phase_frames={"left": 0.0, "middle": 0.25})
    assert f.free_running and f.offsets_with_fraction("left")["middle"] == pytest.approx(13.75)


def test_offsets_take_fractions():
    assert _parse_offsets("left=0,middle=53.4,right=126", "--offsets") == {"left": 0, "middle": 53.4, "right": 126}
    params = AnalysisParams().updated({"sync.offsets": {"left": 0, "middle": 53.4, "right": 126}})
    assert params.sync.offsets["middle"] == 53.4
    with pytest.raises(ParamsError):
        AnalysisParams().updated({"sync.offsets": {"left": 0, "middle": -1.5, "right": 126}})


def _free_running_views(rig, n, true_phase):
    where = _trajectory(n)
    return {c: rig[c].project(where(np.arange(n) + true_phase.get(c, 0.0))) for c in rig.names}


def test_sync_residual_is_the_timing_error_times_the_motion(rig):
    n, true_phase = 90, {rig.names[1]: 0.37, rig.names[2]: -0.22}
    px = _free_running_views(rig, n, true_phase)
    motion = quality.marker_motion_px(px)
    right, _ = subframe.tracks_at_reference_instants(px, true_phase)
    resid = subframe.others_residual(rig, right)
    assert max(float(np.nanmedian(r[2:-2])) for r in resid.values()) < 0.05
    off = {**true_phase, rig.names[1]: true_phase[rig.names[1]] + 0.2}     # a fraction 0.2 frame wrong
    wrong, _ = subframe.tracks_at_reference_instants(px, off)
    bad = {c: float(np.nanmedian(r[2:-2])) for c, r in subframe.others_residual(rig, wrong).items()}
    assert bad[rig.names[1]] == pytest.approx(0.2 * motion[rig.names[1]], rel=0.5)
    checks = {lvl: quality.check_sync_residual(r, motion).level
              for lvl, r in (("right", subframe.others_residual(rig, right)),
                             ("wrong", subframe.others_residual(rig, wrong)))}
    assert checks == {"right": "ok", "wrong": "unreliable"}


def test_subframe_sync_check_judges_the_fraction_not_the_whole_frames():
    unsettled = {c: CameraSyncCheck(shift=1, moved=True, current_px=10.0, best_px=2.0, n_points=100, decided=True,
                                    rounds=3, settled=False) for c in ("left", "right")}
    flash = {"left": 0.0, "middle": 26.25, "right": 44.73}
    refined = {"left": 0.0, "middle": 26.06, "right": 44.73}
    ok = quality.check_subframe_sync_by_markers(unsettled, flash, refined, {"left": 0.1, "middle": 0.04, "right": 0.1})
    assert ok.level == "ok" and ok.figure == pytest.approx(0.19)
    lost = quality.check_subframe_sync_by_markers(unsettled, flash, refined, {"left": 0.1, "middle": 4.0, "right": 0.1})
    assert lost.level == "unreliable" and "middle" in lost.message
    moved = quality.check_subframe_sync_by_markers({}, {**flash, "middle": 27.25}, refined,
                                                   {"left": 0.1, "middle": 0.04, "right": 0.1})
    assert moved.level == "warning" and "27.250" in moved.message


def test_interpolation_spans_short_gaps_but_reads_only_near_an_observation():
    k = np.arange(12, dtype=float)
    px = np.stack([k ** 2, k], axis=-1)[:, None, :].copy()
    px[[4, 5, 7]] = np.nan                              # frame 6 seen alone between gaps of 2 and 1 frames
    alone, outside = subframe.tracks_at_reference_instants({"a": px}, {"a": 0.2})
    joined, gone = subframe.tracks_at_reference_instants({"a": px}, {"a": 0.2}, max_gap=2)
    assert np.isnan(alone["a"][5:8, 0, 0]).all() and outside["a"][6, 0]
    assert joined["a"][7, 0, 0] == pytest.approx(6.8 ** 2, rel=1e-2) and not gone["a"][6, 0]
    assert np.isnan(joined["a"][5, 0, 0])              # instant 4.8: no observation within one frame
    assert joined["a"][6, 0, 0] == pytest.approx(5.8 ** 2, rel=1e-2)


def _flash_next_to_a_rail(n=40, on_at=2, lit=(0.7, 1.0, 1.0, 0.3), seed=1):
    """Dark noisy frames, a static bright rail's posts either side of the flashlight, and a flash switched on at frame
    ``on_at`` (the record starts just before it) for a few frames, the first and last lit in part."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:96, :128]
    frames = np.clip(rng.normal(30, 2, (n, 96, 128)), 0, 255)
    frames[:, 8:32, 67:100] = 200                                 # the rail's posts either side, bright in
    frames[:, 8:32, 20:53] = 200                                  # every frame
    lamp = (xx - 60) ** 2 + (yy - 20) ** 2 <= 36
    for i, share in enumerate(lit):
        frames[on_at + i][lamp] = 30 + share * 220
    return frames.astype(np.uint8)


def test_flash_at_the_start_of_a_record_beside_a_static_bright_thing():
    # no frame lies two frames before the switch-on: the frames after the flash tell the rail is static
    det = detect_flash(_flash_next_to_a_rail())
    assert det.frame == 2 and not det.ambiguous


def test_short_flash_with_a_mostly_lit_first_frame_keeps_still():
    # lit 70 % in its first frame (an interlaced frame whose first field caught it), 2 full frames, then off
    det = detect_flash(_flash_next_to_a_rail(on_at=12), min_on_frames=3)
    assert det.frame == 12
    best = max(det.candidates, key=lambda c: c["score"])
    assert best["stays"] == pytest.approx(1.0, abs=0.05)


def test_observation_instants_rolling_shutter_and_interlaced_fields():
    px = np.array([[[5.0, 0.0], [5.0, 480.0]], [[5.0, 240.0], [np.nan, np.nan]]])
    rs = subframe.observation_instants(px, 480, readout_frames=0.6)
    np.testing.assert_allclose(rs[0], [0.0, 0.6])
    assert rs[1, 0] == pytest.approx(1.3)
    il = subframe.observation_instants(px, 480, interlaced=True)
    np.testing.assert_allclose(il[0], [0.25, 0.25])         # half-way between the fields, 0 and 0.5 frame


def test_interlaced_frame_collects_light_over_both_fields(tmp_path):
    meta = {"camera_timing": {"left": {"exposure_s": 0.02, "interlaced": "bottom_first"},
                              "middle": {"exposure_s": 0.01}}}
    s = SimpleNamespace(metadata=meta, fps=25.0, cameras=("left", "middle", "right"))
    s.camera_timing = lambda camera: Session.camera_timing(s, camera)
    e = exposure_fractions(s)
    assert e == {"left": pytest.approx(1.0), "middle": pytest.approx(0.25), "right": subframe.DEFAULT_EXPOSURE_FRACTION}


def test_timing_floor_is_the_residual_in_frames(rig):
    n, true_phase = 90, {rig.names[1]: 0.37, rig.names[2]: -0.22}
    px = _free_running_views(rig, n, true_phase)
    motion = quality.marker_motion_px(px)
    exact = subframe.timing_floor(rig, px, true_phase)
    assert max(exact.values()) < 0.01
    wrong = {**true_phase, rig.names[1]: true_phase[rig.names[1]] + 0.2}
    floor = subframe.timing_floor(rig, px, wrong)
    # a camera read 0.2 frame off lies about 0.2 x its motion from the others' markers
    assert floor[rig.names[1]] == pytest.approx(0.2, rel=0.5)
    assert motion[rig.names[1]] > 1.0



def test_residual_curve_is_least_at_the_true_phase(rig):
    n, true_phase = 90, {rig.names[1]: 0.37, rig.names[2]: -0.22}
    px = _free_running_views(rig, n, true_phase)
    trials = true_phase[rig.names[1]] + np.array([-0.4, -0.2, 0.0, 0.2, 0.4])
    curve = subframe.residual_curve(rig, px, {rig.names[0]: 0.0, **true_phase}, rig.names[1], trials)
    assert int(np.argmin(curve)) == 2 and curve[2] < 0.05 and curve[0] > 5 * curve[2]


def test_nearest_frames_moves_whole_frames_into_the_offsets():
    offsets, phase = subframe.nearest_frames({"left": 6, "middle": 27, "right": 45},
                                             {"left": 0.0, "middle": 0.919, "right": 0.222})
    assert offsets == {"left": 6, "middle": 26, "right": 45}
    assert phase["middle"] == pytest.approx(-0.081) and phase["right"] == pytest.approx(0.222)
    # the same instants: offset minus phase is kept
    assert 26 - phase["middle"] == pytest.approx(27 - 0.919)


def test_phase_widget_defaults_to_the_estimate():
    from horsemocap.widgets import ui_phase
    s = ui_phase("right", 0.123, 0.01)
    assert s.value == pytest.approx(0.123) and s.min == pytest.approx(-0.377) and s.max == pytest.approx(0.623)


def test_a_thing_brightening_over_its_on_frames_weighs_less_than_a_light():
    # a larger bright thing comes into place at frame 10, brightening over four frames, then leaves; the
    # flashlight switches on at frame 25 and holds its level: the flash is chosen
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:96, :128]
    frames = np.clip(rng.normal(30, 2, (60, 96, 128)), 0, 255)
    thing = (xx - 30) ** 2 + (yy - 60) ** 2 <= 64
    for i, level in enumerate((130, 150, 175, 200)):
        frames[10 + i][thing] = level
    frames[25:, (xx - 100) ** 2 + (yy - 20) ** 2 <= 25] = 230
    det = detect_flash(frames.astype(np.uint8))
    assert det.frame == 25
    steady = {c["frame"]: c["steady"] for c in det.candidates if c["accepted"]}
    assert steady[24] == pytest.approx(1.0, abs=0.02) and steady[9] < 0.85


def test_candidates_at_instant_follows_regions_moving_more_than_half_their_spacing():
    """Three markers 20 px apart moving 12 px a frame (the nearest region in the next frame is the
    neighbour's) and a still lamp: each is moved along its own path."""
    from horsemocap.detection.candidates import Candidates
    from horsemocap.detection.matching import candidates_at_instant

    def frame(k):
        xy = np.array([[100.0 + 12.0 * k, 50.0], [120.0 + 12.0 * k, 52.0], [140.0 + 12.0 * k, 49.0], [300.0, 200.0]])
        return Candidates(xy, np.full(4, 20.0), np.zeros(4, bool))

    moved = candidates_at_instant(frame(-1), frame(0), frame(1), -0.4)
    assert moved.centre[:3, 0] == pytest.approx([100.0 - 4.8, 120.0 - 4.8, 140.0 - 4.8])
    assert moved.centre[3].tolist() == [300.0, 200.0]
    ends = candidates_at_instant(None, frame(0), frame(1), np.array([-0.4, -0.4, -0.4, -0.4]))
    assert np.all(np.isfinite(ends.centre))
    assert candidates_at_instant(frame(-1), frame(0), frame(1), 0.0).centre.tolist() == frame(0).centre.tolist()


def test_views_moved_to_the_reference_instant_keep_the_marker_distances(rig):
    """Cameras a third of a frame apart at trot: the raw views' 3D distances are centimetres off, the
    views moved to the reference instant (:func:`candidates_at_instant`) agree with the rigid set."""
    from horsemocap.detection.candidates import Candidates
    from horsemocap.detection.matching import candidates_at_instant, triangulate_rows

    n, k, true_phase = 40, 20, {"middle": 0.34, "right": -0.41}
    where = _trajectory(n)
    names = list(rig.names)
    model = np.linalg.norm(np.diff(where(np.array([k]))[0], axis=0), axis=1)

    def cands(c, j):
        xy = rig[c].project(where(np.array([j + true_phase.get(c, 0.0)]))[0])
        return Candidates(xy, np.full(3, 20.0), np.zeros(3, bool))

    raw = {c: cands(c, k) for c in names}
    moved = {c: candidates_at_instant(cands(c, k - 1), raw[c], cands(c, k + 1), -true_phase.get(c, 0.0))
             for c in names}
    rows = np.tile(np.arange(3)[:, None], (1, len(names)))
    errors = {}
    for label, cc in (("raw", raw), ("moved", moved)):
        X, _, ok = triangulate_rows(rig, tuple(names), cc, rows, 50.0)
        assert ok.all()
        errors[label] = np.abs(np.linalg.norm(np.diff(X, axis=0), axis=1) - model).max()
    assert errors["moved"] < 0.002 < 0.01 < errors["raw"]


def test_blended_fields_make_a_combed_marker_one_blob_at_the_mean_of_its_fields():
    """A marker (14 px across) 10 px further right in the second field: the interlaced frame's comb is no
    marker-shaped region; blended, it is one region centred half-way between the fields' positions."""
    from horsemocap.detection.candidates import frame_candidates
    from horsemocap.sources import fields_blended

    v, u = np.mgrid[0:480, 0:640].astype(float)
    disc = lambda cu, cv: 255.0 * np.clip(7.0 - np.hypot(u - cu, v - cv), 0.0, 1.0)
    first, second = disc(70.0, 60.0), disc(80.0, 60.0)
    frame = np.where((np.arange(480) % 2 == 1)[:, None], first, second).astype(np.uint8)   # bottom field first
    assert len(frame_candidates(frame, 100)) == 0
    blended = frame_candidates(fields_blended(frame), 100)
    assert len(blended) == 1
    assert blended.centre[0] == pytest.approx([75.0, 60.0], abs=0.3)


def _full_flash_sync(names):
    """A flash lit fully in every camera's first lit frame: whole-frame offsets, no fraction, no sub-frame method."""
    return SyncResult(offsets={c: 0 for c in names}, frame_counts={c: 90 for c in names}, n_frames=90,
                      offsets_from="flashlight")


def _session_of(names):
    return Session(root=default_session_dir(), name="s", fps=30.0, cameras=tuple(names), reference_camera=names[0],
                   motion={}, sync_method="flash", sync_offsets=None, rig_path=None, calibration_images=None,
                   board=None, plumb=None, static=None, marker_count=3, marker_diameter_m=0.06, metadata={})


def test_cameras_running_free_behind_a_fully_lit_flash_are_found(rig):
    """The flash gave whole frames only; the cameras ran 0.3 and 0.55 of a frame apart: the markers find it."""
    from horsemocap.steps.detect import _phases_behind_a_full_flash

    names, true_phase = rig.names, {rig.names[1]: 0.3, rig.names[2]: 0.55}
    said = []
    sync = _phases_behind_a_full_flash(_session_of(names), _full_flash_sync(names), rig,
                                       _free_running_views(rig, 90, true_phase), lambda *x: said.append(x[-1]))
    assert sync.free_running and sync.subframe_method == "markers"
    for c, p in true_phase.items():
        assert sync.phase_frames[c] == pytest.approx(p, abs=0.01)
    assert "running free" in said[0]


def test_genlocked_cameras_behind_a_fully_lit_flash_stay_genlocked(rig):
    """The same views exposed together: offsets, phases and method unchanged, the phases measured kept, and said."""
    from horsemocap.steps.detect import _phases_behind_a_full_flash

    names, said = rig.names, []
    full = _full_flash_sync(names)
    sync = _phases_behind_a_full_flash(_session_of(names), full, rig, _free_running_views(rig, 90, {}),
                                       lambda *x: said.append(x[-1]))
    assert not sync.free_running and sync.subframe_method == "" and sync.offsets == full.offsets
    assert sorted(sync.genlocked_check) == sorted(names[1:])
    assert all(abs(p) < 0.01 for p, _ in sync.genlocked_check.values())
    assert "genlocked" in said[0]


def test_hidden_phases_are_found_after_the_markers_corrected_a_flash_by_a_frame(rig):
    """The markers moved one camera's flash offset by a whole frame (offsets_from says so, flash_offsets kept): the
    phases are still searched from zero, found, and the flash's own offsets kept beside them."""
    from horsemocap.steps.detect import _phases_behind_a_full_flash

    names, true_phase = rig.names, {rig.names[1]: 0.3, rig.names[2]: 0.55}
    corrected = _full_flash_sync(names).replace(offsets_from="flashlight, corrected by the markers",
                                                flash_offsets={names[0]: 0, names[1]: 1, names[2]: 0})
    sync = _phases_behind_a_full_flash(_session_of(names), corrected, rig,
                                       _free_running_views(rig, 90, true_phase), lambda *x: None)
    for c, p in true_phase.items():
        assert sync.phase_frames[c] == pytest.approx(p, abs=0.01)
    assert sync.flash_offsets == corrected.flash_offsets and sync.offsets == corrected.offsets


def test_a_phase_below_a_twentieth_of_a_frame_keeps_the_cameras_genlocked(rig):
    """Cameras 0.02 frame apart, noise-free (so the phase is measured far beyond 4 of its uncertainties): below
    HIDDEN_PHASE_MIN_FRAMES they stay genlocked, the phases measured recorded."""
    from horsemocap.steps.detect import HIDDEN_PHASE_MIN_FRAMES, _phases_behind_a_full_flash

    names = rig.names
    sync = _phases_behind_a_full_flash(_session_of(names), _full_flash_sync(names), rig,
                                       _free_running_views(rig, 90, {names[1]: 0.02, names[2]: -0.02}),
                                       lambda *x: None)
    assert not sync.free_running
    assert all(abs(p) < HIDDEN_PHASE_MIN_FRAMES for p, _ in sync.genlocked_check.values())
    assert sync.genlocked_check[names[1]][0] == pytest.approx(0.02, abs=0.01)


def test_linearised_phases_recover_small_phases_and_genlocked_zero(rig):
    """One linearised least-squares step at zero measures phases of a few hundredths of a frame to a thousandth
    (noise-free views), and genlocked views at zero."""
    names = rig.names
    free = subframe.linearised_phases(rig, _free_running_views(rig, 90, {names[1]: 0.07, names[2]: -0.04}),
                                      {c: 0.0 for c in names}, names[0])
    assert free[names[1]].phase == pytest.approx(0.07, abs=0.002)
    assert free[names[2]].phase == pytest.approx(-0.04, abs=0.002)
    still = subframe.linearised_phases(rig, _free_running_views(rig, 90, {}), {c: 0.0 for c in names}, names[0])
    assert sorted(still) == sorted(names[1:])
    assert all(abs(f.phase) < 1e-3 and 0 < f.uncertainty < 0.01 for f in still.values())


def test_genlocked_cameras_behind_a_fully_lit_flash_need_no_search(rig, monkeypatch):
    """Genlocked views: the linearised phases keep the cameras genlocked without the search (refine_phases is
    not called), and say so: the phases measured and the method are recorded."""
    from horsemocap.steps.detect import _phases_behind_a_full_flash

    def no_search(*args, **kwargs):
        raise AssertionError("the search ran")

    monkeypatch.setattr(subframe, "refine_phases", no_search)
    names, said = rig.names, []
    full = _full_flash_sync(names)
    sync = _phases_behind_a_full_flash(_session_of(names), full, rig, _free_running_views(rig, 90, {}),
                                       lambda *x: said.append(x[-1]))
    assert not sync.free_running and sync.offsets == full.offsets and sync.genlocked_check_method == "linearised"
    assert sorted(sync.genlocked_check) == sorted(names[1:])
    assert all(abs(p) < 0.002 for p, _ in sync.genlocked_check.values())
    assert "genlocked" in said[0] and "no search" in said[0]


def test_phases_a_timing_floor_at_zero_would_miss_are_searched_and_found(rig):
    """Cameras 0.05 and 0.10 frame after the reference (phase in proportion to the camera's place in the row,
    the motion along the row): the others' markers absorb most of it, the timing floor at zero phase is only
    0.015 frame (a gate on it below 0.025 would skip the search), but the linearised phases see them: the
    search runs and finds both."""
    from horsemocap.steps.detect import _phases_behind_a_full_flash

    names, true_phase = rig.names, {rig.names[1]: 0.05, rig.names[2]: 0.10}
    views = _free_running_views(rig, 90, true_phase)
    floor = subframe.timing_floor(rig, views, {c: 0.0 for c in names})
    assert max(floor.values()) < 0.025
    sync = _phases_behind_a_full_flash(_session_of(names), _full_flash_sync(names), rig, views, lambda *x: None)
    assert sync.free_running and sync.subframe_method == "markers"
    for c, p in true_phase.items():
        assert sync.phase_frames[c] == pytest.approx(p, abs=0.01)


def test_a_phase_between_the_gate_and_a_twentieth_is_searched_and_kept_genlocked(rig):
    """One camera 0.04 frame off (noise-free): beyond the linearised gate's 0.025, so the search runs; below
    HIDDEN_PHASE_MIN_FRAMES it keeps the cameras genlocked, the search's phases recorded as such."""
    from horsemocap.steps.detect import HIDDEN_PHASE_GATE_FRAMES, HIDDEN_PHASE_MIN_FRAMES, _phases_behind_a_full_flash

    names = rig.names
    assert HIDDEN_PHASE_GATE_FRAMES < 0.04 < HIDDEN_PHASE_MIN_FRAMES
    sync = _phases_behind_a_full_flash(_session_of(names), _full_flash_sync(names), rig,
                                       _free_running_views(rig, 90, {names[1]: 0.04}), lambda *x: None)
    assert not sync.free_running and sync.genlocked_check_method == "search"
    assert sync.genlocked_check[names[1]][0] == pytest.approx(0.04, abs=0.005)


def test_a_rate_measured_before_starts_the_chunks_on_its_line(rig):
    """Four passes across 3600 frames, the right camera's clock 1000 ppm slow (3.6 frames of drift: a camera at
    30000/1001 fps labelled 30), 0.3 px of centroid noise. Searched from the record's constant phase, the chunks
    at either end start more than a frame from theirs: 872 ppm and a phase at frame 0 0.12 frame off (residual
    0.47 px). Given the rate measured on the record's first frames (960 ppm, as the detect step measures it
    there), each chunk starts on that line: the rate within 3 % and the phase within 0.05 frame, the tracks
    meeting twice as well."""
    names = list(rig.names)
    px = _ride_of_passes(rig, {names[1]: 0.58, names[2]: 0.22}, {names[2]: 1.001}, noise_px=0.3, seed=2,
                         n=3600, lap=900)
    start = {names[0]: 0.0, names[1]: 0.56, names[2]: 0.23}
    alone = subframe.refine_phases(rig, px, start, names[0])[names[2]]
    given = subframe.refine_phases(rig, px, start, names[0], rate_ratio={names[2]: 1.00096})[names[2]]
    assert given.rate_ratio - 1 == pytest.approx(1e-3, rel=0.03)
    assert given.phase == pytest.approx(0.22, abs=0.06)
    assert given.residual_px < 0.6 * alone.residual_px


def test_a_given_rate_the_chunks_do_not_confirm_leaves_the_others_alone(rig):
    """The same ride, with a wrong earlier rate for the middle camera (500 ppm; its clock is the reference's) beside
    the right camera's: the chunks do not confirm it, and the second measurement starts from the constant phase
    for it, so it pulls neither camera: kept along with the right one's, it gave the right camera 1135 ppm and a
    phase 0.18 frame off (residual 0.49 px), and the middle camera an uncertainty of 0.30 frame."""
    names = list(rig.names)
    px = _ride_of_passes(rig, {names[1]: 0.58, names[2]: 0.22}, {names[2]: 1.001}, noise_px=0.3, seed=2,
                         n=3600, lap=900)
    start = {names[0]: 0.0, names[1]: 0.56, names[2]: 0.23}
    fits = subframe.refine_phases(rig, px, start, names[0], rate_ratio={names[1]: 1.0005, names[2]: 1.00096})
    assert fits[names[2]].rate_ratio - 1 == pytest.approx(1e-3, rel=0.03)
    assert fits[names[2]].phase == pytest.approx(0.22, abs=0.06)
    assert fits[names[1]].rate_ratio == 1.0 and fits[names[1]].uncertainty < 0.1
    assert fits[names[1]].phase == pytest.approx(0.58, abs=0.03)
