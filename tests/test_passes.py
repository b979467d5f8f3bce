"""Every pass of the horse through the views: found, analysed one by one, combined by duration."""
import csv
import io

import numpy as np
import pytest

from horsemocap.data import default_session_dir
from horsemocap.passes import (PassesResult, PassResult, analyse_passes, combined_comfort, find_runs, pass_segment,
                              passes_check, shortest_pass_frames)
from horsemocap.pipeline import analyze, run_steps
from horsemocap.results import passes_text
from horsemocap.vibration import time_to_a8, time_to_vdv


def test_find_runs_keeps_every_run_long_enough_in_order():
    mask = [False] * 3 + [True] * 10 + [False] * 2 + [True] * 7 + [False] + [True] * 12
    assert find_runs(mask, min_frames=8) == [(3, 13), (23, 35)]
    assert find_runs([True] * 8, min_frames=8) == [(0, 8)]
    assert find_runs([False, False], min_frames=1) == []


def test_pass_segment_is_the_longest_triangulated_run_inside_the_pass():
    points = np.ones((30, 3, 3))
    points[12, 0, 0] = np.nan
    points[25] = np.nan
    assert pass_segment(points, (10, 30)) == (13, 25)
    assert pass_segment(points, (0, 12)) == (0, 12)


def _ind(rms, vdv, speed, tau):
    return {"acc_y_Wb_rms": rms, "VDV_y_Wb": vdv, "vel_x_avg": speed, "acc_y_max": 3 * rms, "duration_s": tau,
            "TA_8_action_Wb": float(time_to_a8(rms, 0.5)), "TVDV_action_Wb": float(time_to_vdv(vdv, tau, 9.1)),
            "Distance_TA_8_action_Wb": speed * float(time_to_a8(rms, 0.5))}


def test_identical_passes_combine_to_the_same_exposure_rates():
    one = _ind(2.0, 3.0, 15.0, 1.5)
    c = combined_comfort([one, one, one], [1.5, 1.5, 1.5])
    assert c["duration_s"] == pytest.approx(4.5)
    assert c["VDV_y_Wb"] == pytest.approx(3.0 * 3 ** 0.25)      # doses add by their fourth powers
    for key in ("acc_y_Wb_rms", "vel_x_avg", "acc_y_max", "TA_8_action_Wb", "TVDV_action_Wb",
                "Distance_TA_8_action_Wb"):
        assert c[key] == pytest.approx(one[key], rel=1e-12), key


def test_passes_are_weighted_by_their_durations():
    short, long_ = _ind(1.0, 1.0, 10.0, 1.0), _ind(3.0, 2.0, 20.0, 3.0)
    c = combined_comfort([short, None, long_], [1.0, 0.0, 3.0])
    assert c["acc_y_Wb_rms"] == pytest.approx(np.sqrt((1 * 1 + 3 * 9) / 4))
    assert c["vel_x_avg"] == pytest.approx((10 + 60) / 4)
    assert c["acc_y_max"] == 9.0
    assert c["TA_8_action_Wb"] == pytest.approx(8 * (0.5 / c["acc_y_Wb_rms"]) ** 2)
    assert c["TVDV_action_Wb"] == pytest.approx(4 * (9.1 / c["VDV_y_Wb"]) ** 4 / 3600)
    assert combined_comfort([None], [0.0]) == {}


@pytest.fixture(scope="module")
def bundled():
    return analyze(default_session_dir(), progress=lambda *a: None)


def test_a_single_pass_session_has_no_passes(bundled):
    assert bundled.passes is None


def _twice(a, gap: int):
    """The record put twice end to end with ``gap`` frames without the horse between (NaN, unseen)."""
    if isinstance(a, dict):
        return {k: _twice(v, gap) for k, v in a.items()}
    if a is None:
        return None
    a = np.asarray(a)
    fill = {"b": False, "U": "", "i": 0, "u": 0}.get(a.dtype.kind, np.nan)
    return np.concatenate([a, np.full((gap,) + a.shape[1:], fill, dtype=a.dtype), a])


def _later(record):
    """``run_later`` of :func:`analyse_passes`: the record's session and parameters."""
    return lambda given, steps, overrides: run_steps(record.session, record.params, given, steps,
                                                     overrides=overrides)


def test_a_second_pass_is_analysed_alone_and_combined(bundled):
    det, tri = bundled.detect, bundled.triangulate
    n, gap = len(det.all_seen), 50
    record = bundled.__class__(bundled.session, bundled.params)
    for name in ("sync", "rig", "plumb", "static", "smooth", "motion_frame", "rigid_body", "comfort"):
        setattr(record, name, getattr(bundled, name))
    record.detect = det.replace(marker_px=_twice(det.marker_px, gap), reason=_twice(det.reason, gap),
                                all_seen=_twice(det.all_seen, gap))
    record.triangulate = tri.replace(points=_twice(tri.points, gap), residual_px=_twice(tri.residual_px, gap),
                                     reason=_twice(tri.reason, gap), n_views=_twice(tri.n_views, gap),
                                     covariance=_twice(tri.covariance, gap))
    messages = []
    result = analyse_passes(record, _later(record),
                            lambda step, message: messages.append(message))
    assert result is not None and len(result.passes) == 2
    first, second = result.passes
    assert first.main and first.analysis is record and not second.main
    a, b = tri.segment
    assert second.segment == (a + n + gap, b + n + gap)
    assert second.verdict == first.verdict
    # the second pass is the first's data smoothed with the first's settled choices: the centroid's fits are
    # the same; the rotation's robust reweighting iterates at the settled (final) parameter, hence not to 1e-9
    for key, value in first.indicators.items():
        assert second.indicators[key] == pytest.approx(value, rel=1e-3, abs=1e-9), key
    smoothing = (first.analysis.rigid_body.body.pose.smoothing, second.analysis.rigid_body.body.pose.smoothing)
    for c in ("cx", "cy", "cz", "phix", "phiy", "phiz"):
        assert smoothing[1][c]["lam"] == smoothing[0][c]["lam"], c
        assert max(smoothing[1][c].get("harmonic_indices") or [0]) <= max(smoothing[0][c].get("harmonic_indices")
                                                                            or [0]), c
        assert smoothing[1][c].get("weights") == smoothing[0][c].get("weights"), c
    # the thesis' chain of fits is the main pass' alone: the other passes' comfort and verdict do without it
    assert first.analysis.rigid_body.body.motion_fit is not None
    assert second.analysis.rigid_body.body.motion_fit is None
    assert "not asked" in second.analysis.rigid_body.body.chain_error
    assert result.combined["duration_s"] == pytest.approx(2 * first.duration_s)
    assert result.combined["acc_y_Wb_rms"] == pytest.approx(first.indicators["acc_y_Wb_rms"], rel=1e-3)
    assert "2 passes" in messages[-1]

    record.passes = result
    rows = list(csv.DictReader(io.StringIO(passes_text(record))))
    assert [r["pass"] for r in rows] == ["1", "2", "all"]
    offset = record.synchronisation.offsets[record.session.reference_camera]
    assert int(rows[1]["first_frame"]) == a + n + gap + offset
    assert float(rows[2]["duration_s"]) == pytest.approx(2 * first.duration_s)
    assert float(rows[2]["acc_y_Wb_rms"]) == pytest.approx(first.indicators["acc_y_Wb_rms"], rel=1e-3)


def _second_pass_too_short(bundled, gap=20):
    """The bundled record twice, ``gap`` frames apart, the second pass' markers never triangulated in 8 frames
    running."""
    det, tri = bundled.detect, bundled.triangulate
    record = bundled.__class__(bundled.session, bundled.params)
    for name in ("sync", "rig", "plumb", "static", "smooth", "motion_frame", "rigid_body", "comfort"):
        setattr(record, name, getattr(bundled, name))
    points = _twice(tri.points, gap)
    points[len(det.all_seen) + gap::3] = np.nan
    record.detect = det.replace(all_seen=_twice(det.all_seen, gap))
    record.triangulate = tri.replace(points=points)
    return record


def test_a_pass_too_short_to_triangulate_is_a_row_with_its_reason(bundled):
    record = _second_pass_too_short(bundled)
    result = analyse_passes(record, _later(record),
                            lambda *a: None)
    second = result.passes[1]
    assert second.analysis is None and second.verdict == "unreliable" and "fewer than 8" in second.error
    assert result.combined["duration_s"] == pytest.approx(result.passes[0].duration_s)


def test_a_pass_under_two_strides_is_not_analysed_and_says_why(bundled):
    """A second pass whose markers are triangulated for one frame less than two strides: its comfort would be the
    stride's harmonics fitted to less than the two periods they are averaged over; left out of the combined comfort."""
    det, tri = bundled.detect, bundled.triangulate
    gap = 20
    shortest = shortest_pass_frames(bundled.motion_frame.period_frames)
    record = bundled.__class__(bundled.session, bundled.params)
    for name in ("sync", "rig", "plumb", "static", "smooth", "motion_frame", "rigid_body", "comfort"):
        setattr(record, name, getattr(bundled, name))
    points = _twice(tri.points, gap)
    start = len(det.all_seen) + gap + tri.segment[0]
    points[start + shortest - 1:] = np.nan
    record.detect = det.replace(all_seen=_twice(det.all_seen, gap))
    record.triangulate = tri.replace(points=points)
    result = analyse_passes(record, _later(record), lambda *a: None)
    second = result.passes[1]
    assert shortest == 2 * round(bundled.motion_frame.period_frames) and shortest - 1 >= 8
    assert second.segment == (start, start + shortest - 1)
    assert second.analysis is None and "under two strides" in second.error
    assert result.combined["duration_s"] == pytest.approx(result.passes[0].duration_s)
    assert passes_check(result).level == result.verdict


def test_a_pass_not_analysed_makes_the_all_row_a_warning_as_the_check_says():
    ok = PassResult(1, (0, 40), (0, 40), object(), "ok")
    short = PassResult(2, (60, 90), (60, 90), None, "unreliable", error="under two strides")
    both = PassesResult((ok, short), {})
    assert both.verdict == passes_check(both).level == "warning"


def _times(a, gap: int, times: int):
    if isinstance(a, dict):
        return {k: _times(v, gap, times) for k, v in a.items()}
    if a is None:
        return None
    a = np.asarray(a)
    fill = np.full((gap,) + a.shape[1:], {"b": False, "U": "", "i": 0, "u": 0}.get(a.dtype.kind, np.nan),
                   dtype=a.dtype)
    return np.concatenate([a] + [np.concatenate([fill, a]) for _ in range(times - 1)])


def test_passes_computed_beside_in_a_forked_copy_are_the_same(bundled, monkeypatch):
    from horsemocap import forking, passes as passes_module

    det, tri = bundled.detect, bundled.triangulate
    record = bundled.__class__(bundled.session, bundled.params)
    for name in ("sync", "rig", "plumb", "static", "smooth", "motion_frame", "rigid_body", "comfort"):
        setattr(record, name, getattr(bundled, name))
    record.detect = det.replace(marker_px=_times(det.marker_px, 30, 3), reason=_times(det.reason, 30, 3),
                                all_seen=_times(det.all_seen, 30, 3))
    record.triangulate = tri.replace(points=_times(tri.points, 30, 3), residual_px=_times(tri.residual_px, 30, 3),
                                     reason=_times(tri.reason, 30, 3), n_views=_times(tri.n_views, 30, 3),
                                     covariance=_times(tri.covariance, 30, 3))
    later = _later(record)
    forks = []
    real_fork = forking.os.fork
    monkeypatch.setattr(forking.os, "fork", lambda: (forks.append(1), real_fork())[1])
    beside = analyse_passes(record, later, lambda *a: None)
    monkeypatch.setattr(passes_module, "run_beside", lambda tasks: [t() for t in tasks])
    alone = analyse_passes(record, later, lambda *a: None)
    import threading
    assert len(forks) == (1 if threading.active_count() == 1 else 0)
    assert [p.segment for p in beside.passes] == [p.segment for p in alone.passes] and len(alone.passes) == 3
    for b, a in zip(beside.passes, alone.passes):
        assert b.indicators == a.indicators and b.verdict == a.verdict
        np.testing.assert_array_equal(b.analysis.rigid_body.saddle_acceleration, a.analysis.rigid_body.saddle_acceleration)
    assert beside.combined == alone.combined


# --- every pass in the overall verdict and the report --------------------------------------------------------

def _analysed(verdict: str, index: int):
    from types import SimpleNamespace

    from horsemocap.passes import PassResult

    return PassResult(index, (40 * index, 40 * index + 30), (40 * index, 40 * index + 30),
                      SimpleNamespace(comfort=None), verdict)


@pytest.mark.parametrize("verdicts, missing, level", [
    (("ok", "ok"), False, "ok"),
    (("ok", "warning"), False, "warning"),
    (("ok", "ok"), True, "warning"),              # a pass left out of the combined comfort
    (("warning", "unreliable"), True, "unreliable"),   # an unreliable pass is in the combined comfort
])
def test_the_passes_check_is_the_worst_analysed_pass_and_a_missing_one_warns(verdicts, missing, level):
    from horsemocap.passes import PassResult, PassesResult, passes_check

    passes = [_analysed(v, i) for i, v in enumerate(verdicts, 1)]
    if missing:
        passes.append(PassResult(9, (400, 409), None, None, "unreliable", error="too short"))
    check = passes_check(PassesResult(tuple(passes), {}))
    assert check.name == "passes" and check.level == level and check.figure == len(verdicts)
    assert ("pass 9 (frames 400..408): not analysed (too short)" in check.message) == missing
    if "unreliable" in verdicts:
        assert "pass 2 (frames 80..109): unreliable" in check.message


def test_the_report_shows_every_pass_and_the_verdict_counts_them(bundled):
    """A record of two passes, the second too short to analyse: the report's table has a row per pass and
    the row 'all'; the overall verdict (the session's checks and the passes check) is at least a warning."""
    from horsemocap import quality, report
    from horsemocap.passes import passes_check

    tri = bundled.triangulate
    record = _second_pass_too_short(bundled)
    record.passes = analyse_passes(record, _later(record), lambda *a: None)
    check = passes_check(record.passes)
    assert check.level != "ok" and "not analysed" in check.message
    checks = quality.post_checks(record) + [check]
    assert quality.LEVELS.index(quality.verdict(checks)) >= quality.LEVELS.index(check.level)

    section = "".join(report.passes_section(record))
    assert "Passes of the horse through the views (2)" in section
    cells = [row.split("</td><td") for row in section.split("<tr>")[2:]]
    assert [c[0].split(">")[-1] for c in cells] == ["1", "2", "all"]
    offset = record.synchronisation.offsets[record.session.reference_camera]
    a, b = tri.segment
    assert f">{a + offset}..{b - 1 + offset}<" in section
    wb = report.format_value(record.passes.passes[0].indicators["acc_y_Wb_rms"], 4)
    assert section.count(f">{wb}<") == 2               # the first pass, and all (the second has none)
    assert "not analysed: fewer than 8" in section and "the result files" in section
    assert report.passes_section(bundled) == []        # one pass: no section
    page = report.report_html(record, quality.quality_record(checks))
    assert section.split("</p>")[-1] in page and ">passes<" in page and page.count("data:image/png") == 6
