"""Free-running cameras: the flash's rows under a rolling shutter, phases searched by the identification, and the
identification repeated at the phases the markers measured."""
from types import SimpleNamespace

import numpy as np
import pytest

from horsemocap import subframe
from horsemocap.data import default_session_dir
from horsemocap.session import Session
from horsemocap.steps import detect as D
from horsemocap.steps.sync import SyncResult, _flash_fractions

FPS = 30.0


def _session(timing: dict, names=("left", "middle")):
    return Session(root=default_session_dir(), name="s", fps=FPS, cameras=tuple(names), reference_camera=names[0],
                   motion={}, sync_method="flash", sync_offsets=None, rig_path=None, calibration_images=None,
                   board=None, plumb=None, static=None, marker_count=3, marker_diameter_m=0.06,
                   metadata={"camera_timing": timing})


def _flash(first_lit: int, lit_fraction: float, row: int, n: int = 24, height: int = 480):
    signal = np.zeros(n)
    signal[first_lit] = lit_fraction
    signal[first_lit + 1:] = 1.0
    region = np.zeros((height, 640), bool)
    region[row, 300:310] = True
    return SimpleNamespace(signal=signal, off_level=0.0, on_level=1.0, frame=first_lit, start=0, region=region)


def test_the_flash_rows_of_a_rolling_shutter_are_exposed_later_than_row_0():
    """Exact: left reads its rows in 0.4 frame and sees the flash at row 240 (0.2 frame after row 0); its frame 3
    exposes that row over [3.2, 3.7] and is lit 80 %: the onset is 3.3. Middle reads in 0.1 frame, the flash at row
    120 (0.025 frame); its frame 17 lit 25 %: onset 17.4. Phase = (17 - 3) - (17.4 - 3.3) = -0.1 frame; without the
    rows' delay the same brightness gives -0.275."""
    e = 0.5 / FPS
    timing = {"left": {"exposure_s": e, "rolling_shutter_s": 0.4 / FPS},
              "middle": {"exposure_s": e, "rolling_shutter_s": 0.1 / FPS}}
    found = {"left": _flash(3, 0.8, 240), "middle": _flash(17, 0.25, 120)}
    got = _flash_fractions(_session(timing), found, {"left": 3, "middle": 17})
    assert got["subframe_method"] == "flash"
    assert got["phase_frames"]["middle"] == pytest.approx(-0.1, abs=1e-9)
    global_shutters = {c: {"exposure_s": e} for c in timing}
    old = _flash_fractions(_session(global_shutters), found, {"left": 3, "middle": 17})
    assert old["phase_frames"]["middle"] == pytest.approx(-0.275, abs=1e-9)


def test_flash_row_delay_is_the_regions_mean_row_share_of_the_readout():
    region = np.zeros((100, 10), bool)
    region[10, :] = True
    region[30, :5] = True                                    # weighted by pixels: (10 * 10 + 30 * 5) / 15
    assert subframe.flash_row_delay(region, 1.0) == pytest.approx((100 + 150) / 15 / 100)
    assert subframe.flash_row_delay(np.zeros((100, 10), bool), 1.0) == 0.0


def _idn(used: int, inconsistent: int, names=("left", "middle", "right")):
    """An identification whose cameras used ``used`` marker-frames; middle rejected ``inconsistent`` as inconsistent."""
    reason = {c: np.array([""] * used + ["lost"] * 5, dtype=object) for c in names}
    reason["middle"] = np.array([""] * used + ["inconsistent_views"] * inconsistent, dtype=object)
    return SimpleNamespace(reason=reason, marker_px={}, thresholds={})


def _ident(names=("left", "middle", "right"), progress=lambda *x: None):
    """The identifications' shared context of a session of ``names`` (no rig or model: ``_identify`` is replaced)."""
    return D._Identifier(_session({}, names), None, None, {}, progress, 8.0)


def _free_sync(phase: dict, names=("left", "middle", "right")):
    return SyncResult(offsets={c: 0 for c in names}, frame_counts={c: 90 for c in names}, n_frames=90,
                      offsets_from="flashlight", phase_frames=dict(phase), subframe_method="flash")


def _patch_rounds(monkeypatch, identify, refine=lambda session, sync, *a: sync):
    """The identification replaced by ``identify``, the measuring steps by nothing, the markers' refinement by
    ``refine`` (default: the phases it is given)."""
    monkeypatch.setattr(D, "_identify", identify)
    monkeypatch.setattr(D, "measured_by_fields", lambda session, sync, px, thr, progress: (px, {}))
    monkeypatch.setattr(D, "observation_times", lambda *a: {})
    monkeypatch.setattr(D, "_subframe_by_markers", refine)


def test_a_camera_whose_views_the_others_reject_is_identified_at_other_phases(monkeypatch):
    """The middle camera's true phase is 0.55, the flash said 0.30: at 0.30 the identification rejects 40 of its
    views; the trials at 0.30 + (-0.5, -0.25, 0.25, 0.5) use the most views at 0.55, which is kept."""
    names = ("left", "middle", "right")
    true = 0.55

    def identify(session, sync, *args, **kw):
        err = abs(sync.phase_frames["middle"] - true)
        return _idn(used=int(round(100 - 100 * err)), inconsistent=int(round(160 * err)))

    monkeypatch.setattr(D, "_identify", identify)
    flash = _free_sync({"left": 0.0, "middle": 0.30, "right": 0.1})
    first = identify(None, flash)
    said = []
    idn, sync = D._phase_by_identification(_ident(names, lambda *x: said.append(x[-1])), flash, first)
    assert sync.phase_frames["middle"] == pytest.approx(0.55)
    assert sync.phase_frames["right"] == pytest.approx(0.1)              # its views were not rejected: not moved
    assert "middle +0.25 frame" in said[0]


def test_cameras_whose_views_agree_are_not_searched(monkeypatch):
    monkeypatch.setattr(D, "_identify", lambda *a, **k: pytest.fail("searched although no view was rejected"))
    flash = _free_sync({"left": 0.0, "middle": 0.30, "right": 0.1})
    first = _idn(used=100, inconsistent=10)                  # 10 of 110: under INCONSISTENT_SHARE_TO_SEARCH
    idn, sync = D._phase_by_identification(_ident(), flash, first)
    assert idn is first and sync is flash


def test_identified_again_at_the_markers_phases_in_the_current_offsets(monkeypatch):
    """After the markers moved a flash offset by a whole frame (flash_offsets kept), the phases they measured are in
    the current offsets' frames: the identification again must see exactly them, not them moved once more."""
    names = ("left", "middle", "right")
    seen = {}

    def identify(session, sync, *args, **kw):
        seen.update(D.current_phases(sync, "left"))
        return _idn(used=100, inconsistent=0)

    _patch_rounds(monkeypatch, identify)
    refined = SyncResult(offsets={"left": 9, "middle": 61, "right": 134}, frame_counts={c: 90 for c in names},
                         n_frames=90, offsets_from="flashlight, corrected by the markers",
                         flash_offsets={"left": 8, "middle": 61, "right": 134},
                         phase_frames={"left": 0.0, "middle": -0.59, "right": -0.63}, subframe_method="flash and markers")
    identified_at = refined.replace(phase_frames={"left": 0.0, "middle": 0.16, "right": 0.01},
                                    subframe_method="flash")
    rounds = []
    out = D._identified_again(_ident(names, lambda *x: rounds.append(x[-1])), identified_at,
                              _idn(used=50, inconsistent=30), refined)
    assert seen == pytest.approx({"left": 0.0, "middle": -0.59, "right": -0.63})
    assert len(rounds) == 1                      # the phases did not move again: one round
    assert out[-1].flash_offsets == refined.flash_offsets and out[-1].subframe_method == "flash and markers"


def _middle_tried_about(monkeypatch, identified_at: float, markers_phase: float, markers_uncertainty: float):
    """The middle camera identified at ``identified_at``, the markers then giving it ``markers_phase`` +-
    ``markers_uncertainty``; its true phase 0.4 (the identification uses the most marker-frames there). Returns the
    middle phases tried and :func:`_identified_again`'s result."""
    tried = []

    def identify(session, sync, *args, **kw):
        tried.append(round(sync.phase_frames["middle"], 3))
        return _idn(used=int(100 - 100 * abs(sync.phase_frames["middle"] - 0.4)), inconsistent=0)

    _patch_rounds(monkeypatch, identify,
                  lambda session, sync, *a: sync.replace(offset_uncertainty_frames={"middle": 0.02, "right": 0.02}))
    at = _free_sync({"left": 0.0, "middle": identified_at, "right": 0.0})
    markers = at.replace(phase_frames={"left": 0.0, "middle": markers_phase, "right": 0.0},
                         offset_uncertainty_frames={"middle": markers_uncertainty, "right": 0.02})
    out = D._identified_again(_ident(), at, _idn(used=60, inconsistent=0), markers)
    return tried, out


def test_phases_the_markers_cannot_pin_are_tried_about_the_identified_ones(monkeypatch):
    """The markers left the middle's phase uncertain by 1.3 frames (they ran off by a frame): its views are
    identified at the trial phases about the phase they were identified at (0), where 0.5 uses the most."""
    tried, out = _middle_tried_about(monkeypatch, 0.0, 1.01, 1.3)
    assert tried[:4] == [-0.5, -0.25, 0.25, 0.5]
    assert out[-1].phase_frames["middle"] == pytest.approx(0.5)


def test_trial_phases_keep_the_drifting_cameras_rates(monkeypatch):
    """The right camera's clock drifts (the markers measured its rate) while the middle's phase is tried about
    its identified one: every trial identification reads the right camera at its phase and rate, not at its
    phase at frame 0 held over the record."""
    rates = []

    def identify(session, sync, *args, **kw):
        rates.append(dict(sync.rate_ratio))
        return _idn(used=int(100 - 100 * abs(sync.phase_frames["middle"] - 0.4)), inconsistent=0)

    _patch_rounds(monkeypatch, identify,
                  lambda session, sync, *a: sync.replace(offset_uncertainty_frames={"middle": 0.02, "right": 0.02}))
    at = _free_sync({"left": 0.0, "middle": 0.0, "right": 0.2})
    markers = at.replace(phase_frames={"left": 0.0, "middle": 1.01, "right": 0.21}, rate_ratio={"right": 1.0002},
                         offset_uncertainty_frames={"middle": 1.3, "right": 0.02})
    D._identified_again(_ident(), at, _idn(used=60, inconsistent=0), markers)
    assert rates and all(r.get("right") == 1.0002 for r in rates[:4])


def test_phase_moves():
    assert D.phase_moves({"a": 0.1, "b": -0.2}, {"a": 0.1, "b": 0.3}) == {"a": 0.0, "b": 0.5}
    assert D.phase_moves({}, {"a": 0.0, "b": 0.3}) == {"a": 0.0, "b": 0.3}     # a genlocked sync holds no phases


def test_identified_again_after_phases_found_behind_a_genlocked_looking_flash(monkeypatch):
    """Identified as genlocked (no phases held), the markers then found the cameras 0.26 / 0.33 frame apart: the
    views are identified again at those phases."""
    names = ("left", "middle", "right")
    seen = {}

    def identify(session, sync, *args, **kw):
        seen.update(D.current_phases(sync, "left"))
        return _idn(used=100, inconsistent=0)

    _patch_rounds(monkeypatch, identify)
    genlocked = SyncResult(offsets={c: 0 for c in names}, frame_counts={c: 90 for c in names}, n_frames=90,
                           offsets_from="flashlight")
    found = genlocked.replace(phase_frames={"left": 0.0, "middle": -0.26, "right": -0.33}, subframe_method="markers",
                              offset_uncertainty_frames={"middle": 0.05, "right": 0.05})
    out = D._identified_again(_ident(names), genlocked, _idn(used=50, inconsistent=0), found)
    assert out is not None and seen == pytest.approx({"left": 0.0, "middle": -0.26, "right": -0.33})


def test_a_worse_identification_at_the_markers_phases_is_not_kept(monkeypatch):
    """The markers moved the phases, but the identification at them uses fewer marker-frames than the first:
    nothing is replaced (None)."""
    names = ("left", "middle", "right")
    _patch_rounds(monkeypatch, lambda *a, **k: _idn(used=40, inconsistent=0))
    flash = _free_sync({"left": 0.0, "middle": 0.30, "right": 0.1})
    refined = flash.replace(phase_frames={"left": 0.0, "middle": 0.45, "right": 0.1},
                            offset_uncertainty_frames={"middle": 0.02, "right": 0.02})
    assert D._identified_again(_ident(names), flash, _idn(used=90, inconsistent=0), refined) is None


def test_a_phase_run_off_by_frames_is_not_followed(monkeypatch):
    """The markers gave the middle camera -1.73 frames with a small uncertainty (its views identified at the wrong
    instants): whole frames are the offsets', so its views are identified at trial phases about the identified one."""
    tried, out = _middle_tried_about(monkeypatch, 0.1, -1.73, 0.05)
    assert tried[:4] == [-0.4, -0.15, 0.35, 0.6]
    assert out[-1].phase_frames["middle"] == pytest.approx(0.35)


def test_a_drift_that_carries_the_phase_past_a_frame_is_followed(monkeypatch):
    """The right camera runs at 30000/1001 fps labelled 30: its phase is +0.22 frame at frame 0 and, at the measured
    rate, +1.17 by the end of 987 frames. That is the clock's drift, not views identified a frame off: the markers
    are identified again at the markers' phase and rate, not at trial phases with the rate dropped."""
    names = ("left", "middle", "right")
    calls = []

    def identify(session, sync, *args, **kw):
        calls.append((dict(sync.phase_frames), dict(sync.rate_ratio)))
        return _idn(used=100, inconsistent=0)

    _patch_rounds(monkeypatch, identify)
    at = _free_sync({"left": 0.0, "middle": 0.58, "right": 0.21}).replace(
        n_frames=987, frame_counts={c: 1200 for c in names})
    rate = 30.0 / (30000 / 1001)
    markers = at.replace(phase_frames={"left": 0.0, "middle": 0.58, "right": 0.22}, rate_ratio={"right": rate},
                         offset_uncertainty_frames={"middle": 0.006, "right": 0.011})
    assert subframe.largest_phase(0.22, rate, 987) > D.PHASE_MAX_FRAMES
    out = D._identified_again(_ident(names), at, _idn(used=60, inconsistent=0), markers)
    assert len(calls) == 1                                   # one identification, at the markers' phases
    assert calls[0][0]["right"] == pytest.approx(0.22) and calls[0][1]["right"] == pytest.approx(rate)
    assert out is not None and out[-1].rate_ratio["right"] == pytest.approx(rate)


def _long_flash(n=2800, names=("left", "middle", "right")):
    return _free_sync({"left": 0.0, "middle": 0.32, "right": 0.21}).replace(
        n_frames=n, frame_counts={c: n + 200 for c in names}, offsets={"left": 8, "middle": 61, "right": 134},
        offset_uncertainty_frames={"middle": 0.25, "right": 0.25})


def _measuring(sync, *a):
    """The markers' refinement of a part: 1.0009 on the first 1001 frames, 1.001 on longer parts."""
    rate = 1.001 if sync.n_frames >= 2002 else 1.0009
    return sync.replace(phase_frames={"left": 0.0, "middle": 0.58, "right": 0.22}, rate_ratio={"right": rate},
                        offset_uncertainty_frames={"middle": 0.01, "right": 0.01}, subframe_method="flash and markers")


def test_a_long_record_measures_its_clocks_from_the_flash_onward(monkeypatch):
    """2800 frames of cameras running free at rates not yet known: the markers are identified and the clocks
    measured on the first 1001 frames, then on 2002 (at the rate measured on the first; 4004 would be the whole),
    and the whole record's identification starts from the phases and rates of the longest part; its sync keeps
    every other field of the flash's (the whole record, the offsets, the flash's method, so that the whole
    record's own rounds refine it again)."""
    parts = []

    def identify(session, sync, *args, **kw):
        parts.append((sync.n_frames, dict(sync.rate_ratio)))
        return _idn(used=100, inconsistent=0)

    _patch_rounds(monkeypatch, identify, lambda session, sync, *a: _measuring(sync))
    flash = _long_flash()
    out = D._clocks_from_the_flash(_ident(), None, flash)
    assert parts[0][0] == D.CLOCKS_FIRST_FRAMES and {n for n, _ in parts} == {1001, 2002}
    assert next(r for n, r in parts if n == 2002).get("right") == pytest.approx(1.0009)   # the first part's rate
    assert out.rate_ratio["right"] == pytest.approx(1.001) and out.phase_frames["middle"] == pytest.approx(0.58)
    assert out.offset_uncertainty_frames == {"middle": 0.01, "right": 0.01}
    assert out.replace(phase_frames=flash.phase_frames, rate_ratio=flash.rate_ratio,
                       offset_uncertainty_frames=flash.offset_uncertainty_frames) == flash


def test_clocks_not_measured_on_the_first_frames_leave_the_flash_s(monkeypatch):
    """No markers in the first 1001 frames, or a refinement that pins no camera's phase there: the flash's sync
    itself goes on to the whole record (said), and the identification at measured clocks falls back to it
    when it fails."""
    said = []
    ident = _ident(progress=lambda step, msg, *a: said.append(msg))
    flash = _long_flash()

    def no_markers(session, sync, *a, **k):
        raise D.AnalysisError("detect", "no frame")

    _patch_rounds(monkeypatch, no_markers)
    assert D._clocks_from_the_flash(ident, None, flash) is flash
    assert any("no markers identified there" in m for m in said) and "not measured" in said[-1]
    _patch_rounds(monkeypatch, lambda *a, **k: _idn(used=100, inconsistent=0),
                  lambda session, sync, *a: sync.replace(offset_uncertainty_frames={"middle": 0.4, "right": 0.6}))
    assert D._clocks_from_the_flash(ident, None, flash) is flash
    at = []

    def fails_at_measured_clocks(session, sync, *a, **k):
        at.append((sync.n_frames, dict(sync.rate_ratio)))
        if sync.n_frames == 2800 and sync.rate_ratio and len([n for n, _ in at if n == 2800]) == 1:
            raise D.AnalysisError("detect", "no frame")
        return _idn(used=100, inconsistent=0)

    _patch_rounds(monkeypatch, fails_at_measured_clocks, lambda session, sync, *a: _measuring(sync))
    monkeypatch.setattr(D, "_checked_by_markers", lambda ident, section, sync, idn: (idn, sync, {}))
    found, measured = D._identified_at_clocks(ident, None, flash, None)
    whole = [r for n, r in at if n == 2800]
    assert not measured and whole[0]["right"] == pytest.approx(1.001) and whole[1] == {}   # then the flash's


def test_short_genlocked_or_measured_records_go_straight_to_the_whole_identification(monkeypatch):
    """Nothing is identified first: a record of 1001 frames or fewer, cameras exposing together, rates known,
    offsets with their fractions given, or two cameras."""
    names = ("left", "middle", "right")
    _patch_rounds(monkeypatch, lambda *a, **k: pytest.fail("identified a part of the record"))
    free = _long_flash()
    cases = [(free.replace(n_frames=D.CLOCKS_FIRST_FRAMES), names),
             (SyncResult(offsets={c: 0 for c in names}, frame_counts={c: 3000 for c in names}, n_frames=2800,
                         offsets_from="flashlight"), names),
             (free.replace(rate_ratio={"right": 1.001}), names),
             (free.replace(offsets_from="given in parameters", subframe_method="given in parameters"), names),
             (free, names[:2])]
    for sync, cams in cases:
        assert D._clocks_from_the_flash(_ident(cams), None, sync) is sync
