"""The report as a person reads it, and the progress lines: known input -> expected text."""
from __future__ import annotations

import io
import subprocess
import sys

import numpy as np
import pytest

from horsemocap import readable, report
from horsemocap.params import AnalysisParams
from horsemocap.plots import figure_painter
from horsemocap.progress import CountingFrames, ProgressPrinter, counter, plain_count_due, progress_bar
from horsemocap.vibration import COMFORT_KEYS, COMFORT_UNITS


@pytest.mark.parametrize("unit, expected", [
    ("m/s^2", "m/s<sup>2</sup>"), ("m/s^1.75", "m/s<sup>1.75</sup>"), ("km/h", "km/h"), ("1", ""),
    ("rad/s^2", "rad/s<sup>2</sup>"), ("a<b", "a&lt;b")])
def test_unit_html_writes_powers_as_superscripts(unit, expected):
    assert report.unit_html(unit) == expected


def test_unit_text_uses_unicode_powers_where_they_exist():
    assert report.unit_text("m/s^2") == "m/s²"
    assert report.unit_text("m/s^1.75") == "m/s^1.75"  # no superscript decimal point
    assert report.unit_text("1") == ""


@pytest.mark.parametrize("value, expected", [
    (17.98881515983109, "17.99"), (0.1, "0.1"), (3, "3"), (None, "automatic"), (True, "yes"),
    ("joint", "joint (all cameras at once)"), ("thesis", "thesis"), ([True] * 6, "all six"),
    ([True, False, True, False, False, True], "versions 1, 3, 6"), ([[3, 2], [4, 2]], "(3, 2); (4, 2)"),
    ({"y": 3, "z": 2}, "y: 3; z: 2"), ([21, 60], "21, 60"), (float("nan"), "not a number"),
    ({}, "none"), ([], "none")])
def test_format_value_rounds_and_spells_out(value, expected):
    assert report.format_value(value) == expected


def test_choice_rows_have_names_and_no_json():
    record = {"parameters": {"triangulate": {"mode": "joint"},
                             "motion_frame": {"period_frames": 17.98881515983109, "x_marker": 0},
                             "preset": None,
                             "detect": {"cameras": {"left": {"threshold": 128, "centroid": "weighted"}}}},
              "chosen": {"rig": "calibrated from checkerboard views (joint)", "analysed_frames": [21, 60]}}
    rows = report.choice_rows(record)
    assert rows == [("triangulation", "joint (all cameras at once)"), ("stride period (frames)", "17.99"),
                    ("marker defining the direction of motion", "marker 1"),
                    ("preset", "none (the automatic choices)"),
                    ("detector settings (left)", "threshold: 128; centroid: weighted"),
                    ("rig", "calibrated from checkerboard views (joint)"),
                    ("analysed frames (first, last + 1)", "21, 60")]
    assert not any('"' in v for _, v in rows)


@pytest.mark.parametrize("text, expected", [
    ("ok <= 0.314271 px; unreliable outside <= 7.71295 px", "ok <= 0.3143 px; unreliable above 7.713 px"),
    ("ok 0..0 images; unreliable outside 0..0 images", "ok 0 images; unreliable otherwise"),
    ("ok <= 20 ; unreliable outside <= 1000", "ok <= 20; unreliable above 1000"),
    ("ok 0..0.5 %; unreliable outside 0..2.5 %", "ok 0\u00a0–\u00a00.5 %; unreliable outside 0\u00a0–\u00a02.5 %"),
    ("0 frames: ok; any correction: warning", "0 frames: ok; any correction: warning")])
def test_thresholds_read_as_a_person_writes_them(text, expected):
    """Seen in the report in a browser: unrounded bounds, '0..0 images', 'outside <= 1000', ' ;'."""
    assert report.threshold_text(text) == expected


def test_every_parameter_and_indicator_has_a_name():
    from horsemocap.params import params_fields

    assert {f.path for f in params_fields()} - {"stills.plumb", "stills.static"} <= set(report.PARAMETER_NAMES)
    assert set(COMFORT_KEYS) <= set(report.INDICATORS)
    assert all(meaning for _, meaning in report.INDICATORS.values())
    # two indicators of different keys that differ only by their weighting say how the weightings differ
    assert report.INDICATORS["acc_y_Wb_rms"][1] != report.INDICATORS["acc_y_Wk_rms"][1]


def test_comfort_rows_name_meaning_value_unit():
    ind = {k: 1.0 for k in COMFORT_KEYS}
    ind["acc_y_Wk_rms"] = 4.27654321
    ind["VDV_y_Wk"] = 5.5129
    rows = {r[0]: r for r in report.comfort_rows(ind)}
    name = "vertical acceleration, Wk-weighted rms [acc_y_Wk_rms]"
    assert rows[name][2:] == ("4.277", "m/s<sup>2</sup>")
    assert rows["vibration dose value, Wk [VDV_y_Wk]"][2:] == ("5.513", "m/s<sup>1.75</sup>")
    assert "action value" in rows["time to the action value by VDV, Wk [TVDV_action_Wk]"][1]
    assert len(rows) == len(COMFORT_KEYS)
    assert COMFORT_UNITS["crest_factor_y"] == "1" and rows["crest factor [crest_factor_y]"][3] == ""


def test_x_acceleration_note_only_when_zero_by_construction():
    assert "zero by construction" in report.x_acceleration_note(AnalysisParams.from_dict({"x_degree": 1, "kinematics": "fits"}))
    assert report.x_acceleration_note(AnalysisParams.from_dict({"x_degree": 2, "kinematics": "fits"})) is None
    assert report.x_acceleration_note(AnalysisParams.from_dict({"kinematics": "pose_spline"})) is None


def test_quality_section_rounds_figures():
    rec = {"verdict": "warning", "checks": [
        {"name": "sync_flash", "figure": 0.123456789, "unit": "frames", "threshold": 0.5, "level": "warning",
         "message": "late"},
        {"name": "saddle_acceleration", "figure": 12.15, "unit": "m/s^2", "threshold": "ok 0.5..40 m/s^2",
         "level": "ok", "message": "peak <12.15 m/s^2>"}]}
    text = "".join(report.quality_section(rec))
    assert "WARNING" in text and "0.1235" in text and "0.123456789" not in text and "sync flash" in text
    assert "<td>m/s<sup>2</sup></td>" in text and "ok 0.5\u00a0–\u00a040 m/s<sup>2</sup>" in text
    assert "peak &lt;12.15 m/s<sup>2</sup>&gt;" in text and "m/s^2" not in text


@pytest.mark.parametrize("hours, expected", [
    (0.106, "0 h 06 min"), (0.5596, "0 h 34 min"), (2.5, "2 h 30 min"), (0.9999, "1 h 00 min"),
    (12.0, "12 h 00 min"), (0.002329, "0 h 00 min (8 s)"), (float("inf"), "never"),
    (float("nan"), "not computed")])
def test_times_read_in_hours_and_minutes(hours, expected):
    assert readable.hours_minutes(hours) == expected


def _indicators():
    from horsemocap.vibration import THESIS_TABLE_8_7
    ind = dict(THESIS_TABLE_8_7)
    ind.update({"TA_8_action_directive": 0.0759, "TA_8_limit_directive": 0.4018,
                "Distance_TA_8_action_directive": 1.3369, "Distance_TA_8_limit_directive": 7.072})
    return ind


def test_summary_line_has_verdict_rms_vdv_and_times_in_h_min_and_km():
    from types import SimpleNamespace
    ind = _indicators()
    text = report.summary_html(SimpleNamespace(indicators=ind, reason=""), {"verdict": "warning"})
    assert text.startswith('<p class="summary">')
    assert "WARNING" in text
    assert "Wb rms</b>: 3.19 m/s²" in text and "Wk rms</b>: 3.7 m/s²" in text
    assert "Wb 3.79 m/s<sup>1.75</sup>, Wk 4.4 m/s<sup>1.75</sup>" in text
    # Table 8.7: 0.1460 h = 8.76 min, 0.7725 h = 46.35 min
    assert f"EU action value (A(8), vertical Wk)</b>: 0 h 09 min, 2.58 km" in text
    assert "EU limit value (A(8), vertical Wk)</b>: 0 h 46 min, 13.6 km" in text
    assert "action 0 h 05 min, 1.34 km; limit 0 h 24 min, 7.07 km" in text
    assert not any(f"{ind[k]}" in text for k in ("TA_8_action_Wk", "TA_8_limit_Wk"))   # no decimal hours
    stopped = report.summary_html(SimpleNamespace(indicators=None, reason="no saddle"), None)
    assert "NOT JUDGED" in stopped and "comfort: not computed (no saddle)" in stopped and "rms" not in stopped


THIN = ("thin marker triangle: smallest height 32 mm; a marker noise of 0.90 mm gives about 1.6 deg of rotation "
        "noise per frame (above 1 deg); a point 0.56 m away moves by about 15.6 mm per frame; the smoothing removes "
        "part of it, but angular results and far points are unreliable")


@pytest.mark.parametrize("rigid, levels, box", [
    ([], ["ok", "ok"], False), ([THIN], ["ok", "ok"], True), ([], ["ok", "warning"], True),
    ([], ["unreliable", "ok"], True), ([], [], False)])
def test_warnings_are_highlighted_exactly_when_there_is_one(rigid, levels, box):
    quality = {"verdict": "ok", "checks": [{"name": f"check_{i}", "level": lv, "message": f"message {i}"}
                                           for i, lv in enumerate(levels)]}
    parts = report.warnings_box(rigid, quality)
    assert bool(parts) == box
    if box:
        assert parts[0].startswith('<div class="alert')
        assert ('class="alert unreliable"' in parts[0]) == ("unreliable" in levels)


def test_a_thin_triangle_warning_says_what_it_means_for_the_comfort_figures():
    text = "".join(report.warnings_box([THIN], {"verdict": "warning", "checks": [
        {"name": "marker_geometry", "level": "warning", "message": THIN}]}))
    assert text.count("thin marker triangle") == 1           # the quality check repeating it is not listed twice
    meaning = report.warning_meaning(THIN)
    assert "For the numbers:" in text and "comfort figures" in meaning and "saddle" in meaning
    assert "overstated" in meaning and "upper" in meaning


def test_report_has_summary_first_then_the_box_and_angular_panels_by_what_they_show():
    import matplotlib
    matplotlib.use("Agg")
    import numpy as np
    from horsemocap.plots import plot_axes_timeseries
    fig = plot_axes_timeseries(np.arange(3.0), {"omega": np.zeros((3, 3))}, "rad/s", "Angular velocity",
                               quantity="angular velocity about")
    assert [ax.get_title() for ax in fig.axes] == [f"angular velocity about {a} (rad/s)" for a in "xyz"]
    fig = plot_axes_timeseries(np.arange(3.0), {"p": np.zeros((3, 3))}, "m", "Positions")
    assert fig.axes[0].get_title() == "x-motion (m)"


# --- progress ---------------------------------------------------------------

def test_progress_bar_text():
    assert progress_bar(0, 4, width=8) == "[--------] 0/4"
    assert progress_bar(3, 12, width=8) == "[##------]  3/12"
    assert progress_bar(12, 12, width=8) == "[########] 12/12"
    assert progress_bar(20, 12, width=8) == "[########] 12/12"  # clipped


def test_plain_lines_at_first_quarters_and_last():
    assert [d for d in range(1, 46) if plain_count_due(d, 45)] == [1, 12, 23, 34, 45]
    assert [d for d in range(1, 3) if plain_count_due(d, 2)] == [1, 2]
    assert not plain_count_due(0, 0)


def test_printer_on_a_file_prints_plain_lines():
    buf = io.StringIO()
    p = ProgressPrinter(buf)
    p("rig", "calibrating ...")
    tick = counter(p, "rig", "views", 8)
    for k in range(1, 9):
        tick(k)
    assert buf.getvalue().splitlines() == ["[horsemocap] rig: calibrating ...", "[horsemocap] rig: views 1/8",
                                           "[horsemocap] rig: views 2/8", "[horsemocap] rig: views 4/8",
                                           "[horsemocap] rig: views 6/8", "[horsemocap] rig: views 8/8"]


def test_printer_on_a_terminal_redraws_one_bar():
    buf = io.StringIO()
    p = ProgressPrinter(buf, tty=True)
    tick = counter(p, "detect", "frames", 2)
    tick(1)
    p("detect", "half way")  # a step line ends the open bar first
    tick(2)
    text = buf.getvalue()
    assert text == ("\r[horsemocap] detect: frames " + progress_bar(1, 2) + "\n[horsemocap] detect: half way\n"
                    "\r[horsemocap] detect: frames " + progress_bar(2, 2) + "\n")


def test_counter_ignores_callbacks_without_counts():
    calls = []
    tick = counter(lambda *a: calls.append(a), "detect", "frames", 3)
    tick(1)
    assert calls == []


def test_counting_frames_counts_each_frame_once_in_any_order():
    seen = []
    frames = CountingFrames(list("abcd"), seen.append)
    assert [frames[k] for k in (2, 3, 2, 1, 0)] == ["c", "d", "c", "b", "a"]
    assert seen == [1, 2, 3, 4] and len(frames) == 4


@pytest.fixture
def report_figures():
    """The module that draws the report's figures (loads matplotlib: imported by the tests that draw)."""
    import importlib

    return importlib.import_module("horsemocap.plots.report_figures")


def _line_figure(k):
    import matplotlib.pyplot as plt

    def make():
        fig, ax = plt.subplots(figsize=(2, 1.5))
        ax.plot([0, 1, 2], [0, k, 2 * k])
        ax.set_title(f"figure {k}")
        return fig
    return make


def test_render_pngs_gives_the_sequential_pngs_in_order(report_figures):
    makers = [_line_figure(k) for k in range(5)]
    alone = [report_figures.png(make()) for make in makers]
    assert report_figures.render_pngs(makers) == alone
    assert len(set(alone)) == 5          # five different figures: the order is checked


def test_render_pngs_draws_here_what_the_forked_copy_failed_to_draw(report_figures):
    import os

    parent = os.getpid()

    def fails_in_a_copy():
        if os.getpid() != parent:
            raise RuntimeError("only in the forked copy")
        return _line_figure(7)()

    makers = [fails_in_a_copy, _line_figure(1), fails_in_a_copy]
    expected = [report_figures.png(_line_figure(7)()), report_figures.png(_line_figure(1)()), report_figures.png(_line_figure(7)())]
    assert report_figures.render_pngs(makers) == expected


def _pid_recording_figure(log):
    def make():
        import os

        with open(log, "a") as f:
            f.write(f"{os.getpid()}\n")
        return _line_figure(3)()
    return make


@pytest.mark.skipif(not hasattr(__import__("os"), "fork") or (__import__("os").cpu_count() or 1) < 2,
                    reason="the forked copy is made only where fork exists and two cores do")
def test_render_pngs_forks_only_without_other_python_threads(report_figures, tmp_path):
    """Alone, the process shares the figures with a forked copy; while another Python thread runs
    (a Jupyter kernel's, an application's), it draws them all itself: a lock that thread holds at the
    fork would stay held in the copy."""
    import os
    import threading

    def pids(log):
        return {int(line) for line in log.read_text().split()}

    log = tmp_path / "alone.txt"
    slow = [_pid_recording_figure(log)] * 6
    assert threading.active_count() == 1, "the test needs a process without other Python threads"
    report_figures.render_pngs(slow)
    assert len(pids(log)) == 2 and os.getpid() in pids(log)

    stop = threading.Event()
    worker = threading.Thread(target=stop.wait)
    worker.start()
    try:
        log = tmp_path / "threaded.txt"
        report_figures.render_pngs([_pid_recording_figure(log)] * 6)
        assert pids(log) == {os.getpid()}
    finally:
        stop.set()
        worker.join()


def test_render_pngs_error_here_neither_hangs_nor_is_swallowed(report_figures):
    """A figure failing in this process ends the call with its error, even while the forked copy is
    sending more than a pipe holds (before, both waited for each other: the copy blocked in sending,
    this process in waiting for it)."""
    import os
    import signal

    import numpy as np

    parent = os.getpid()

    def large_noise_figure():
        import matplotlib.pyplot as plt

        if os.getpid() == parent:
            raise RuntimeError("drawing failed here")
        fig, ax = plt.subplots(figsize=(6, 6))
        ax.imshow(np.random.default_rng(0).random((300, 300)))     # a PNG of about 200 kB
        return fig

    signal.signal(signal.SIGALRM, lambda *a: (_ for _ in ()).throw(TimeoutError("render_pngs hung")))
    signal.alarm(120)
    try:
        with pytest.raises(RuntimeError, match="drawing failed here"):
            report_figures.render_pngs([large_noise_figure] * 4)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, signal.SIG_DFL)


# --- the figures drawn by a copy forked before the analysis -------------------------------------------------

def test_the_analysis_never_loads_matplotlib_and_the_report_draws_the_same_figures(report_figures):
    """``horsemocap.run`` (the analysis and the report's text) loads no matplotlib: the figures are drawn
    from their descriptions by :mod:`horsemocap.plots.report_figures`, in a forked copy or here, alike."""
    code = "import sys, horsemocap.run, horsemocap.report; print('matplotlib' in sys.modules)"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "False"
    descriptions = [("reprojection_residuals", ({"left": np.linspace(0, 1, 9)},), {}),
                    ("axes_timeseries", (np.arange(4.0), {"p": np.ones((4, 3))}, "m", "Positions"), {"quantity": None})]
    here = report_figures.draw_pngs(descriptions)
    painter = figure_painter()
    with painter:
        assert report._drawn(painter, descriptions) == here
    assert len(set(here)) == 2


def test_plain_lines_at_least_once_a_minute_with_the_time_left():
    """A long count in a log: a line at least once a minute between the quarters, saying the time left at
    the rate so far (once the count has run 10 s); quick counts print exactly the quarters."""
    now = iter([0.0, 59.0, 61.0, 100.0, 121.5, 1000.0])
    buf = io.StringIO()
    p = ProgressPrinter(buf, clock=lambda: next(now))
    for k in (1, 2, 3, 4, 5, 400):
        p("kinematics", "windows", k, 400)
    lines = buf.getvalue().splitlines()
    assert lines == ["[horsemocap] kinematics: windows 1/400",
                     "[horsemocap] kinematics: windows 3/400 (about 202 min left)",
                     "[horsemocap] kinematics: windows 5/400 (about 200 min left)",
                     "[horsemocap] kinematics: windows 400/400"]
