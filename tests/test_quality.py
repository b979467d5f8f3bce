"""Plausibility checks: known answers of the pure check functions."""
import dataclasses
import math

import numpy as np
import pytest

from horsemocap import quality
from horsemocap.camera import Camera
from horsemocap.steps import CameraSyncCheck


def sync_check(shift=0, current_px=0.2, best_px=0.2, *, moved=None, n_points=0, decided=True, rounds=1,
               settled=True) -> CameraSyncCheck:
    """One camera's check by the markers; by default one round that settled, moved when shifted."""
    return CameraSyncCheck(shift=shift, moved=shift != 0 if moved is None else moved, current_px=current_px,
                           best_px=best_px, n_points=n_points, decided=decided, rounds=rounds, settled=settled)


def test_range_levels_and_verdict():
    ok, warn = (2.0, 71.0), (0.5, 90.0)
    values = (17.7, 2.0, 71.0, 80.0, 1.0, 0.4, 1771.0, float("nan"), float("inf"))
    levels = [quality.range_check("s", x, "km/h", ok, warn, "in", "speed").level for x in values]
    assert levels == ["ok", "ok", "ok", "warning", "warning", "unreliable", "unreliable", "unreliable", "unreliable"]
    assert math.isnan(quality.range_check("s", float("nan"), "", ok, warn, "", "").figure)
    assert quality.range_check("s", float("nan"), "", ok, warn, "", "").level == "unreliable"
    skipped = quality.range_check("s", None, "", ok, warn, "", "x")
    assert skipped.level == "skipped" and quality.verdict([skipped]) == "ok"
    checks = [quality.range_check("a", 10, "", ok, warn, "", ""), quality.range_check("b", 80, "", ok, warn, "", "")]
    assert quality.verdict(checks) == "warning"
    assert quality.verdict(checks + [quality.range_check("c", 1e3, "", ok, warn, "", "")]) == "unreliable"
    rec = quality.quality_record(checks + [quality.range_check("d", float("inf"), "", ok, warn, "", "")])
    assert rec["verdict"] == "unreliable" and rec["checks"][-1]["figure"] == "inf"  # JSON has no inf


def test_fps_against_container():
    src = {"left": "l.avi", "right": "frames/"}
    c = quality.check_fps_against_container(25.0, {"left": 30.0, "right": None}, src)
    assert c.level == "unreliable" and c.figure == pytest.approx(100 / 6) and "l.avi" in c.message
    assert quality.check_fps_against_container(30.0, {"left": 29.97, "right": None}, src).level == "ok"
    assert quality.check_fps_against_container(30.0, {"left": 30.3, "right": None}, src).level == "warning"
    assert quality.check_fps_against_container(30.0, {"left": None, "right": None}, src).level == "skipped"


def test_image_size():
    c = quality.check_image_size({"left": (640, 480)}, {("left", "a.avi"): (640, 480), ("left", "s.png"): (320, 240)})
    assert c.level == "unreliable" and c.figure == 1 and "s.png is 320x240" in c.message
    assert quality.check_image_size({"left": (640, 480)}, {("left", "a.avi"): (640, 480)}).level == "ok"


def test_camera_matrices():
    good = Camera("left", (640, 480), [[730, 0, 320], [0, 730, 240], [0, 0, 1]])
    assert quality.camera_matrix_condition(good.matrix, good.size) < 3
    assert quality.check_camera_matrices([good]).level == "ok"
    singular = Camera("mid", (640, 480), [[0, 0, 320], [0, 730, 240], [0, 0, 1]])
    assert quality.camera_matrix_condition(singular.matrix, singular.size) == math.inf
    assert quality.check_camera_matrices([good, singular]).level == "unreliable"
    nan = Camera("right", (640, 480), [[np.nan, 0, 320], [0, 730, 240], [0, 0, 1]])
    assert quality.check_camera_matrices([nan]).level == "unreliable"
    off = Camera("right", (640, 480), [[730, 0, 2000], [0, 730, 240], [0, 0, 1]])
    c = quality.check_camera_matrices([off])
    assert c.level == "unreliable" and "principal point" in c.message


def test_residuals_against_calibration_and_motion():
    """Thresholds: warning above 3 x the calibration RMS, unreliable above half a frame's motion."""
    motion = {"left": 15.0, "right": 15.0}
    healthy = {"left": np.full(30, 0.01), "right": np.full(30, 0.012)}
    assert quality.check_reprojection_residuals(healthy, motion, 0.105).level == "ok"
    noisy = {"left": np.full(30, 0.5), "right": np.full(30, 0.01)}  # above 3 x 0.105, below 7.5
    c = quality.check_reprojection_residuals(noisy, motion, 0.105)
    assert c.level == "warning" and "'left'" in c.message
    one_frame = {"left": np.full(30, 0.01), "right": np.full(30, 15.0)}
    c = quality.check_reprojection_residuals(one_frame, motion, 0.105)
    assert c.level == "unreliable" and "'right'" in c.message and "sync" in c.message
    assert c.warning == (None, 7.5)
    # a horse that hardly moves: the floor is the calibration's 3 sigma
    still = {"left": np.full(30, 0.2)}
    assert quality.check_reprojection_residuals(still, {"left": 0.1}, 0.105).level == "ok"
    assert quality.check_reprojection_residuals(still, {"left": 0.1}, 0.05).level == "unreliable"
    # without the calibration's RMS only the motion bound is left
    assert quality.check_reprojection_residuals(noisy, motion, None).level == "ok"


def test_physical_ranges():
    assert quality.check_horse_speed(17.7).level == "ok"            # canter
    assert quality.check_horse_speed(1771.0).level == "unreliable"  # a 10 m board square
    assert quality.check_stride_frequency(30 / 18).level == "ok"
    assert quality.check_stride_frequency(0.001 / 18).level == "unreliable"
    assert quality.check_saddle_acceleration(11.7).level == "ok"     # thesis Table 8.7
    assert quality.check_saddle_acceleration(427.0).level == "unreliable"
    assert quality.check_board_square(0.1).level == "ok"
    assert quality.check_board_square(10.0).level == "unreliable"
    assert quality.check_board_square(None).level == "skipped"
    assert quality.check_marker_diameter(0.06).level == "ok"
    assert quality.check_marker_diameter(6.0).level == "unreliable"


def test_marker_motion():
    px = np.zeros((5, 2, 2))
    px[:, :, 0] = np.arange(5)[:, None] * 3.0
    px[2, 1] = np.nan
    assert quality.marker_motion_px({"left": px}) == {"left": 3.0}


def test_sync_by_markers():
    from horsemocap.quality import check_sync_by_markers

    same = {c: sync_check(0, 0.2, 0.2) for c in ("left", "middle", "right")}
    c = check_sync_by_markers(same)
    assert c.level == "ok" and c.figure == 0
    moved = {**same, "right": sync_check(-2, 6.0, 0.3)}
    c = check_sync_by_markers(moved)
    assert c.level == "warning" and c.figure == 2 and "'right' by -2" in c.message
    assert check_sync_by_markers({}).level == "skipped"
    # a camera the markers could not check is not confirmed (it was reported "ok" before)
    unchecked = {c: dataclasses.replace(v, n_points=0, decided=False) for c, v in same.items()}
    c = check_sync_by_markers(unchecked)
    assert c.level == "warning" and "could not check" in c.message and "'left' (0 marker-frames" in c.message
    c = check_sync_by_markers({**moved, "left": unchecked["left"]})
    assert c.level == "warning" and "'right' by -2" in c.message and "could not check the flash offset of camera 'left'" in c.message
    # moved +1 then -1: back at the flash's offset, but the markers did move it
    there_and_back = {**same, "middle": sync_check(0, 3.0, 0.2, moved=True)}
    c = check_sync_by_markers(there_and_back)
    assert c.level == "warning" and "'middle' by +0 frame(s) in all" in c.message
    # the rounds ran out with a correction still to check
    unsettled = {k: dataclasses.replace(v, settled=False, rounds=3) for k, v in moved.items()}
    c = check_sync_by_markers(unsettled)
    assert c.level == "unreliable" and "after 3 rounds" in c.message
    # the residual cap is a marker not found, not a measurement
    capped = {**same, "right": sync_check(-2, 10.0, 0.3)}
    assert "markers not found (>= 10 px) at the flash's offset -> 0.3 px" in check_sync_by_markers(capped).message


def test_sync_check_summary_over_rounds():
    """Two rounds: the flash's own offsets kept, the total shift from them, settled when the last round
    moved nothing; three rounds that all moved: not settled."""
    from horsemocap.steps import SyncResult
    from horsemocap.steps.detect import _check_summary

    def rnd(**shifts):
        return {c: {"shift": shifts.get(c, 0), "current_px": 10.0 if shifts.get(c) else 0.2, "best_px": 0.1,
                    "n_points": 40, "decided": True} for c in ("left", "middle", "right")}

    flash = SyncResult(offsets={"left": 8, "middle": 61, "right": 134}, frame_counts={}, n_frames=0,
                       offsets_from="flashlight")
    sync = flash.replace(offsets={"left": 9, "middle": 64, "right": 134}, flash_offsets=flash.offsets)
    out = _check_summary([rnd(middle=3), rnd(left=1), rnd()], sync, flash)
    assert {c: v.shift for c, v in out.items()} == {"left": 1, "middle": 3, "right": 0}
    assert {c: v.moved for c, v in out.items()} == {"left": True, "middle": True, "right": False}
    assert all(v.settled and v.rounds == 3 for v in out.values())
    assert out["middle"].current_px == 10.0                 # the first round's, at the flash's offset
    out = _check_summary([rnd(middle=3), rnd(middle=-1), rnd(middle=1)], sync, flash)
    assert not any(v.settled for v in out.values())
    from horsemocap.quality import check_sync_by_markers
    assert check_sync_by_markers(out).level == "unreliable"


def test_residual_check_without_any_bound_does_not_crash():
    """No calibration RMS and no marker motion (a camera that lost every marker): the check has no bound;
    it said so with a TypeError before (the run ended with exit 2 and no results)."""
    c = quality.check_reprojection_residuals({"left": np.full(5, np.nan)}, {"left": float("nan")}, None)
    assert c.level == "unreliable" and "any value" in c.threshold


def test_marker_rigidity_is_the_registration_residual_over_the_layout():
    """Figure = median registration RMS over the markers' RMS radius, in %; ok <= 5, warning <= 10."""
    from horsemocap.quality import check_marker_rigidity

    model = np.array([[0.2, 0.0, 0.0], [-0.1, 0.1, 0.0], [-0.1, -0.1, 0.0]])
    radius = np.sqrt(np.mean(np.sum((model - model.mean(0)) ** 2, axis=1)))
    for res_m, level in ((0.001, "ok"), (0.04 * radius, "ok"), (0.07 * radius, "warning"), (0.3 * radius, "unreliable")):
        r = np.full(50, res_m)
        r[:5] = np.nan                                           # frames without a pose are left out
        r[5] = 1.0                                               # one bad frame does not move the median
        c = check_marker_rigidity(r, model)
        assert c.level == level, (res_m, c)
        assert c.figure == pytest.approx(100 * res_m / radius)
    assert "wrong identities" in check_marker_rigidity(np.full(9, 0.3 * radius), model).message
    assert check_marker_rigidity(np.full(9, np.nan), model).level == "skipped"


def test_marker_geometry_check_carries_the_conditioning_warnings():
    """The rigid-body step's conditioning messages reach quality.json: none is ok, any is a warning
    (never unreliable: the results are written and the message says what to distrust)."""
    assert quality.check_marker_geometry([]).level == "ok"
    c = quality.check_marker_geometry(["thin marker triangle: ...", "3 of 40 frames have no pose"])
    assert c.level == "warning" and c.figure == 2.0 and "3 of 40 frames" in c.message
    assert quality.check_marker_geometry(None).level == "skipped"
    assert quality.verdict([c]) == "warning"


def test_post_checks_judge_the_markers_shape():
    """A run whose tracked points are not the static shot's markers (held-out sessions with two flashes
    found in wrong frames: 44 mm residual, exit 0 before) is unreliable by the marker_rigidity check."""
    from types import SimpleNamespace

    from horsemocap.pipeline import Analysis
    from horsemocap.rigid import Conditioning
    from horsemocap.steps import RigidBodyResult

    def unset(cls, **given):      # a result with only the fields the checks read
        return cls(**{**{f.name: None for f in dataclasses.fields(cls)}, **given})

    model = np.array([[0.3, 0.0, 0.0], [-0.15, 0.1, 0.0], [-0.15, -0.1, 0.05]])
    good = unset(RigidBodyResult, model=model,
                 conditioning=unset(Conditioning, registration_rms_m=np.full(40, 0.0008), warnings=[]))
    bad = good.replace(conditioning=dataclasses.replace(good.conditioning, registration_rms_m=np.full(40, 0.044)))
    session = SimpleNamespace(fps=30.0)
    levels = {c.name: c.level for c in quality.post_checks(Analysis(session, None, rigid_body=good))}
    assert levels["marker_rigidity"] == "ok"
    checks = quality.post_checks(Analysis(session, None, rigid_body=bad))
    assert {c.name: c.level for c in checks}["marker_rigidity"] == "unreliable"
    assert quality.verdict(checks) == "unreliable"


def test_an_ambiguous_flash_the_markers_did_not_check_is_a_warning():
    from horsemocap.quality import check_sync_by_markers

    same = {c: sync_check(0, 0.2, 0.2, n_points=40) for c in ("left", "middle", "right")}
    assert check_sync_by_markers(same, ambiguous={"middle": 57}).level == "ok"     # the markers confirm it
    # far beyond the shifts tried: the kept offset is still confirmed by the markers landing on the regions
    assert check_sync_by_markers(same, ambiguous={"middle": 400}).level == "ok"
    # no markers on the regions where the offset was kept: nothing confirmed
    lost = {**same, "middle": dataclasses.replace(same["middle"], current_px=10.0, best_px=10.0)}
    c = check_sync_by_markers(lost, ambiguous={"middle": 57})
    assert c.level == "warning" and "frame 57" in c.message
    unchecked = {**same, "middle": dataclasses.replace(same["middle"], decided=False, n_points=3)}
    c = check_sync_by_markers(unchecked, ambiguous={"middle": 57})
    assert c.level == "warning" and "frame 57 nearly as likely" in c.message
    c = check_sync_by_markers({}, ambiguous={"left": 12})                            # two cameras: no check
    assert c.level == "warning" and "'left'" in c.message and "--offsets" in c.message
    assert check_sync_by_markers({}).level == "skipped"


def test_a_period_searched_again_is_said_by_the_stride_check():
    from horsemocap.quality import check_stride_frequency

    assert check_stride_frequency(1.41).level == "ok"
    c = check_stride_frequency(1.41, faster_hz=2.84)
    assert c.level == "warning" and "also repeats at 2.84 Hz" in c.message
    assert check_stride_frequency(3.0, faster_hz=6.0).level == "warning"      # already outside: as before


def test_marker_rigidity_says_when_the_residual_is_the_triangulations_scatter():
    """The level is the residual's share of the spread either way; the message says whether the markers'
    own covariances predict the residual (rigid markers measured noisily, or views that disagree) or not."""
    from horsemocap.pose import predicted_registration_rms, register_pose
    from horsemocap.quality import RIGIDITY_EXPLAINED_RATIO, check_marker_rigidity

    rng = np.random.default_rng(3)
    model = np.array([[0.2, 0.0, 0.0], [-0.1, 0.17, 0.0], [-0.1, -0.17, 0.0], [0.0, 0.0, 0.19]])
    sd = np.array([0.002, 0.002, 0.025])                     # depth far worse than across the rays
    pts = model[None] + rng.normal(0.0, 1.0, (400, 4, 3)) * sd
    cov = np.tile(np.diag(sd ** 2), (400, 4, 1, 1))
    reg = register_pose(pts, model, covariance=cov)
    pred = predicted_registration_rms(reg)
    ratio = np.nanmedian(reg.rms) / np.nanmedian(pred)
    assert 0.8 < ratio < 1.2                                  # rigid markers: the prediction holds
    noisy = check_marker_rigidity(reg.rms, model, predicted_rms_m=pred)
    assert noisy.level != "ok" and "the triangulation's scatter" in noisy.message
    assert noisy.level == check_marker_rigidity(reg.rms, model).level       # the level is unchanged
    moved = pts.copy()
    moved[:, 1] += [0.08, 0.0, 0.0]                           # one marker 80 mm off the static shot's place
    reg2 = register_pose(moved, model, covariance=cov)
    pred2 = predicted_registration_rms(reg2)
    assert np.nanmedian(reg2.rms) > RIGIDITY_EXPLAINED_RATIO * np.nanmedian(pred2)
    c = check_marker_rigidity(reg2.rms, model, predicted_rms_m=pred2)
    assert c.level == "unreliable" and "wrong identities" in c.message
    assert "scatter" not in check_marker_rigidity(reg.rms, model).message      # no prediction: as before
