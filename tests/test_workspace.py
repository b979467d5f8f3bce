"""The session workspace: choices made with the notebooks' widgets carry to every later step."""
import dataclasses
import json
import shutil
from pathlib import Path

import ipywidgets as W
import numpy as np
import pytest

from horsemocap import workspace as wsm
from horsemocap.cli import build_parser, _params_from_args
from horsemocap.data import data_samples_dir, default_session_dir
from horsemocap.params import AnalysisParams, ParamsError, read_params
from horsemocap.pipeline import resolve_params, step_keys
from horsemocap.session import load_session
from horsemocap.workspace import notebook_results_dir, results_for


@pytest.fixture
def store(tmp_path, monkeypatch):
    """A fresh notebooks' results store for one test."""
    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path / "results"))
    return tmp_path / "results"


def test_the_default_session_is_the_bundled_one_until_another_is_chosen(store):
    assert wsm.current_session() == default_session_dir().resolve()
    ball = data_samples_dir() / "ball_drop"
    wsm.set_current_session(ball)
    assert wsm.current_session() == ball.resolve()
    assert json.loads((store / "workspace.json").read_text()) == {"session": str(ball.resolve())}
    with pytest.raises(ParamsError, match="not a session folder"):
        wsm.set_current_session(store)


def test_a_workspace_naming_a_vanished_session_says_so(store):
    store.mkdir(parents=True)
    (store / "workspace.json").write_text(json.dumps({"session": str(store / "gone")}))
    with pytest.raises(ParamsError, match="workspace.json.*not a session folder"):
        wsm.current_session()


def test_nested_choices_are_set_validated_and_taken_back(store):
    s = default_session_dir()
    wsm.set_choice(s, "detection.left.threshold", 150)
    wsm.set_choice(s, "smoothing_method", "rloess")
    assert wsm.read_choices(s) == {"detection": {"left": {"threshold": 150}}, "smoothing_method": "rloess"}
    assert wsm.session_params(s).detect.cameras == {"left": {"threshold": 150}}
    # a bad choice names the file and the parameter and writes nothing
    with pytest.raises(ParamsError, match=r"choices.json: parameter 'detect.cameras' \(given as 'detection'\)"
                                          r".*'top'"):
        wsm.set_choice(s, "detection.top.threshold", 3)
    with pytest.raises(ParamsError, match="smoothing_span"):
        wsm.set_choice(s, "smoothing_span", 3)
    assert wsm.get_choice(s, "detection.left.threshold") == 150
    # taking a nested choice back leaves no empty objects
    wsm.set_choice(s, "detection.left.threshold", None)
    assert wsm.read_choices(s) == {"smoothing_method": "rloess"}
    wsm.clear_choices(s)
    assert wsm.read_choices(s) == {}


def test_a_bound_widget_writes_only_what_differs_from_the_automatic_choice(store):
    ws = wsm.open_workspace()
    mode = ws.bind(W.ToggleButtons(options=["joint", "thesis"], value="joint"), "triangulation")
    assert ws.choices == {}                      # built at the automatic choice: nothing written
    mode.value = "thesis"
    assert ws.choices == {"triangulation": "thesis"}
    assert ws.params.triangulate.mode == "thesis"
    # a widget built later (the next notebook, or the same one run again) shows the choice
    again = ws.bind(W.ToggleButtons(options=["joint", "thesis"], value="joint"), "triangulation")
    assert again.value == "thesis"
    again.value = "joint"                        # back to the automatic choice: taken back
    assert ws.choices == {}
    boxes = [W.Checkbox(value=True) for _ in range(6)]
    ws.bind(boxes, "omega_versions", read=lambda: [b.value for b in boxes])
    boxes[2].value = False
    assert ws.params.rigid_body.fits.omega_versions == [True, True, False, True, True, True]


def test_cli_reads_the_notebooks_choices_over_the_sessions_own_parameters(store, tmp_path):
    s = default_session_dir()
    wsm.set_choice(s, "detection.middle.threshold", 140)
    path = wsm.choices_path(s)
    assert read_params(path) == {"detection": {"middle": {"threshold": 140}}}
    args = build_parser().parse_args(["analyze", str(s), "--out", str(tmp_path / "o"), "--params", str(path),
                                      "--angular", "thesis", "--omega-versions", "1,2,4", "--alpha-versions",
                                      "6", "--first-frame", "3", "--saddle-marker", "1",
                                      "--static-threshold", "200", "--exclude-views", "left=a.png+b.png"])
    base = resolve_params(load_session(s), read_params(path))
    p = _params_from_args(args, base)
    assert p.detect.cameras == {"middle": {"threshold": 140}, "all": {"first_frame": 3}}
    assert p.rigid_body.fits.omega_versions == [True, True, False, True, False, False]
    assert p.rigid_body.fits.alpha_versions == [False] * 5 + [True]
    assert (p.rigid_body.fits.angular_method, p.rigid_body.saddle_marker) == ("thesis", 1)
    assert (p.stills.plumb, p.stills.static) == ({}, {"all": {"threshold": 200}})
    assert p.rig.exclude == {"left": ["a.png", "b.png"]}
    # the other prompts of Appendix A: fit_type_x (9.i), and every value of one camera (4.ii, 7a, 8a, 12a)
    args = build_parser().parse_args(["analyze", str(s), "--out", "o", "--x-degree", "2",
                                      "--set", "detection.left.labels=[3,4,5]", "--set", "detection.left.first_frame=36",
                                      "--set", "detection.right.window=[180,140]",
                                      "--set", "detection.middle.distance_tolerance=0.2",
                                      "--set", "stills.plumb.left.threshold=150"])
    p = _params_from_args(args, base)
    assert p.rigid_body.fits.x_degree == 2
    assert p.detect.cameras == {"middle": {"threshold": 140, "distance_tolerance": 0.2},
                           "left": {"labels": [3, 4, 5], "first_frame": 36}, "right": {"window": [180, 140]}}
    assert (p.stills.plumb, p.stills.static) == ({"left": {"threshold": 150}}, {})
    for wrong, said in (("nope=3", "unknown parameter 'nope'"), ("smoothing_span", "expected NAME=VALUE"),
                        ("smoothing_span=2", "smoothing_span")):
        with pytest.raises(ParamsError, match=said):
            _params_from_args(build_parser().parse_args(["analyze", str(s), "--out", "o", "--set", wrong]), base)
    bad = build_parser().parse_args(["analyze", str(s), "--out", "o", "--omega-versions", "0,7"])
    with pytest.raises(ParamsError, match="--omega-versions: expected version numbers 1-6"):
        _params_from_args(bad, AnalysisParams())


def test_still_and_saddle_choices_are_checked_against_the_session():
    session = load_session(default_session_dir(), open_sources=False)
    with pytest.raises(ParamsError, match="labels given for .*'left'.* but not for"):
        AnalysisParams.from_dict({"stills": {"static": {"left": {"threshold": 150, "labels": [1, 2, 3, 4]}}}}).check_session(session)
    with pytest.raises(ParamsError, match="expected 2 labels for camera 'left'"):
        AnalysisParams.from_dict({"stills": {"plumb": {"all": {"threshold": 150, "labels": [1, 2, 3]}}}}).check_session(session)
    with pytest.raises(ParamsError, match="a threshold with the labels"):
        AnalysisParams.from_dict({"stills": {"plumb": {"all": {"labels": [1, 2]}}}}).validate("x")
    with pytest.raises(ParamsError, match="saddle_marker"):
        AnalysisParams.from_dict({"saddle_marker": 9}).check_session(session)
    with pytest.raises(ParamsError, match="calibration_exclude"):
        AnalysisParams.from_dict({"calibration_exclude": {"top": ["v.png"]}}).check_session(session)


def test_views_left_out_are_named_by_key_or_file_and_checked_before_the_calibration():
    """The bundled session's views are ``middle1.jpg`` ... ``middle45.jpg`` (keys ``1`` ... ``45``): either
    name leaves a view out; a name that is no view is refused at once, with the views the camera has."""
    from horsemocap.calibration.bundle import _usable
    from horsemocap.calibration.board import excluded_view_keys, view_keys, views_from_corners

    session = load_session(default_session_dir(), open_sources=False)
    for given in (["middle5.jpg", "7"], ["middle5"]):
        AnalysisParams.from_dict({"calibration_exclude": {"middle": given}}).check_session(session)
    with pytest.raises(ParamsError, match=r"'rig.exclude'.*camera 'middle': cannot exclude unknown views "
                                          r"\['middle55.jpg'\]; give a view's key or its file name \(its 45 views: "
                                          r"1 \(middle1.jpg\), 2 \(middle2.jpg\), .*45 \(middle45.jpg\)\)"):
        AnalysisParams.from_dict({"calibration_exclude": {"middle": ["middle55.jpg"]}}).check_session(session)
    views = views_from_corners("middle", np.zeros((3, 4, 2)), (640, 480), (2, 2))
    views = dataclasses.replace(views, files=tuple(Path(f"middle{k}.jpg") for k in ("01", "02", "03")))
    used, reasons = _usable(views, ["middle02.jpg"])
    assert used.tolist() == [True, False, True] and reasons[1] == "excluded"
    # a file's stem that is another view's key names that view, not its own file's (keys come first)
    files = ["c/middle5.jpg", "c/middlemiddle5.jpg"]
    assert excluded_view_keys("middle", view_keys(files, "middle"), files, ["middle5"]) == {"middle5"}
    assert excluded_view_keys("middle", view_keys(files, "middle"), files, ["middle5.jpg"]) == {"5"}


def test_step_keys_change_only_from_the_first_step_that_reads_a_parameter():
    session = load_session(default_session_dir(), open_sources=False)
    a = step_keys(session, AnalysisParams())
    b = step_keys(session, AnalysisParams.from_dict({"detection": {"left": {"threshold": 150}}}))
    c = step_keys(session, AnalysisParams.from_dict({"weighting_mode": "thesis"}))
    d = step_keys(session, AnalysisParams.from_dict({"kinematics": "fits"}))
    steps = list(a)
    assert [s for s in steps if a[s] != b[s]] == steps[steps.index("detect"):]
    assert [s for s in steps if a[s] != c[s]] == ["comfort"]          # the comfort section's own
    assert [s for s in steps if a[s] != d[s]] == ["rigid_body", "comfort"]


def test_a_threshold_moved_in_notebook_04_reaches_the_numbers_of_notebooks_12_and_14(tmp_path, monkeypatch):
    """The whole path a teacher takes: 04's threshold widget -> choices.json -> results_for in 12/14.

    The automatic run uses the test session's shared store (the notebooks reuse it); the chosen run a
    copy of it, so no choice ever reaches the notebooks' store and only the steps from detection on
    are recomputed (seconds).
    """
    from horsemocap import accuracy, widgets
    from horsemocap.detection import DetectionParams
    from horsemocap.sources import FrameSource
    from horsemocap.virtuallab import load_truth

    session = default_session_dir()
    auto = results_for(session)
    shared = notebook_results_dir(session)
    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path))
    shutil.copytree(shared, notebook_results_dir(session))
    ws = wsm.open_workspace()
    level = auto.detect.detection["left"]["threshold"]
    frames = FrameSource(auto.session.motion["left"]).read()[:3]
    ui = ws.bind(widgets.ui_threshold(frames, DetectionParams(threshold=level)), "detection.left.threshold")
    ui.slider.value = level + 30                       # what a teacher does in notebook 04
    assert ws.choices == {"detection": {"left": {"threshold": level + 30}}}

    chosen = results_for()                             # what notebooks 05-14 call
    det = chosen.detect.detection
    assert det["left"]["threshold"] == level + 30
    assert det["middle"]["threshold"] == auto.detect.detection["middle"]["threshold"]
    a, c = auto.comfort.indicators, chosen.comfort.indicators
    assert a["acc_y_Wk_rms"] != c["acc_y_Wk_rms"]     # notebook 12's numbers follow
    truth = load_truth(session)
    e_auto = accuracy.errors_2d(auto, truth)["left"]["median"]
    e_chosen = accuracy.errors_2d(chosen, truth)["left"]["median"]
    assert e_auto != e_chosen                          # and notebook 14's
    record = json.loads((notebook_results_dir(session) / "analysis.json").read_text())
    assert record["parameters"]["detect"]["cameras"]["left"]["threshold"] == level + 30

    ui.slider.value = level                            # back to the automatic threshold
    assert ws.choices == {}
    again = results_for()
    assert np.array_equal(again.comfort.indicators["acc_y_Wk_rms"], a["acc_y_Wk_rms"])


def test_still_prompts_are_empty_at_the_automatic_choice_and_name_what_changed(store):
    from horsemocap.steps import still_params, still_points, step_rig  # noqa: F401
    from horsemocap.sources import read_image
    from horsemocap.widgets import ui_still

    session = load_session(default_session_dir(), open_sources=False)
    images = {c: read_image(p) for c, p in session.plumb.items()}
    # the automatic centres: the regions the automatic matching found (here: the two brightest round blobs)
    from horsemocap.detection import detect_still
    px = {c: detect_still(im, 2) for c, im in images.items()}
    ui = ui_still(images, 2, px)
    assert ui.value == {}
    assert all(len(ui.auto[c][1]) == 2 for c in images)
    thr = ui.auto["middle"][0]
    ui.sliders["middle"].value = thr + 10
    assert ui.value == {"middle": {"threshold": thr + 10}}
    ws = wsm.open_workspace()
    ws.bind(ui, "stills.plumb")
    ui.sliders["middle"].value = thr + 20            # a move after binding is written
    assert ws.choices == {"stills": {"plumb": {"middle": {"threshold": thr + 20}}}}
    ui.sliders["middle"].value = thr
    left = ui.pickers["left"]
    left.select.value = left.select.value[:1]          # a label taken away: every camera's labels are given
    v = ui.value
    assert set(v) == set(images) and v["left"]["labels"] == list(left.select.value)
    assert v["right"] == {"threshold": ui.auto["right"][0], "labels": list(ui.auto["right"][1])}
    # one label for a two-marker plumb is refused with the reason, beside the control
    assert "expected 2 labels" in ws.last_error and "not saved" in ui.message.value


def test_detection_controls_have_a_first_frame_and_report_only_changes():
    from horsemocap import detection
    from horsemocap.sources import FrameSource
    from horsemocap.widgets import ui_detection

    frames = FrameSource(default_session_dir() / "motion" / "left.avi").read()
    p = detection.detect_markers(frames, 3).params
    ui = ui_detection(frames, p)
    assert wsm.detection_changes(ui.value, p) == {}
    ui.first_frame.value = (p.first_frame or 0) + 1
    ch = wsm.detection_changes(ui.value, p)
    assert ch == {"first_frame": (p.first_frame or 0) + 1}   # labels of the old first frame are dropped
    AnalysisParams.from_dict({"detection": {"left": ch}}).validate("test")


def test_still_labels_given_for_every_camera_give_the_automatic_markers_back():
    """Appendix A 7a the thesis' way: the labels of the regions the automatic matching chose, at the
    automatic threshold, taken as they are, give the same plumb centres."""
    from horsemocap.detection import auto_threshold, detect_still_views, to_gray
    from horsemocap.steps import still_params, still_points
    from horsemocap.sources import read_image
    from horsemocap.virtuallab import load_truth
    from horsemocap.widgets.stills import automatic_labels

    session = load_session(default_session_dir())
    rig = load_truth(default_session_dir()).rig
    images = {c: read_image(p) for c, p in session.plumb.items()}
    auto = detect_still_views(images, rig, 2)
    given = {}
    for c, im in images.items():
        thr = int(auto_threshold([to_gray(im)], "otsu3"))
        given[c] = {"threshold": thr, "labels": list(automatic_labels(im, thr, auto[c]))}
    params = AnalysisParams.from_dict({"stills": {"plumb": given}})
    params.check_session(session)
    pts, px = still_points(session, rig, session.plumb, 2, "plumb", "joint",
                           still_params(params.stills, "plumb", session.cameras))
    for c in session.cameras:
        np.testing.assert_allclose(px[c], auto[c], atol=1e-9)
    # a threshold alone keeps the matching of the cameras; far too high a level finds nothing, and says so
    from horsemocap.pipeline import AnalysisError
    with pytest.raises(AnalysisError, match="step 'plumb'.*plumb"):
        still_points(session, rig, session.plumb, 2, "plumb", "joint",
                     still_params(AnalysisParams.from_dict({"stills": {"plumb": {"all": {"threshold": 254}}}}).stills,
                                  "plumb", session.cameras))


def test_a_named_saddle_marker_is_never_matched_to_a_ride_marker():
    from horsemocap.rigid import match_static_markers

    rng = np.random.default_rng(1)
    markers = np.array([[0.0, 0, 0], [0.30, 0.02, 0], [0.12, 0.01, 0.25]])
    saddle = np.array([0.15, -0.20, 0.10])
    static = np.vstack([markers[[1]], saddle, markers[[0, 2]]])     # static order: m2, saddle, m1, m3
    ride = markers[None] + rng.normal(0, 1e-4, (20, 3, 3)) + np.linspace(0, 1, 20)[:, None, None] * [1, 0, 0]
    idx, s = match_static_markers(static, ride)
    assert (idx.tolist(), s) == ([2, 0, 3], 1)
    idx, s = match_static_markers(static, ride, saddle=1)
    assert (idx.tolist(), s) == ([2, 0, 3], 1)
    idx, s = match_static_markers(static, ride, saddle=3)              # the user's (wrong) choice is kept
    assert s == 3 and 3 not in idx.tolist()
    with pytest.raises(ValueError, match="saddle marker: expected the index"):
        match_static_markers(static, ride, saddle=7)


def test_views_excluded_in_notebook_03_reach_the_calibration_step(monkeypatch):
    import horsemocap.steps.rig as rig_step
    from horsemocap.steps import step_rig

    session = load_session(default_session_dir(), open_sources=False)
    assert session.calibration_images is not None
    seen = {}

    def fake_calibration(images, inner, square, reference, **kw):
        seen.update(kw)
        raise RuntimeError("stop after the call")

    monkeypatch.setattr(rig_step, "cached_calibration", fake_calibration)
    params = AnalysisParams.from_dict({"recalibrate": True, "calibration_exclude": {"left": ["left3.jpg", "12"]}})
    with pytest.raises(RuntimeError, match="stop after the call"):
        step_rig(session, params.rig, lambda *a: None)
    assert seen["exclude"] == {"left": ["12", "3"]}         # each view by its key, however it was named
    with pytest.raises(RuntimeError):
        step_rig(session, AnalysisParams.from_dict({"recalibrate": True}).rig, lambda *a: None)
    assert seen["exclude"] is None


def test_the_session_picker_switches_the_workspace_and_refuses_a_folder_without_a_session(store, tmp_path):
    from horsemocap.widgets import ui_session

    ws = wsm.open_workspace()
    picker = ui_session(ws)
    names = [n for n, _ in picker.dropdown.options]
    assert "horse2_canter" in names and "ball_drop" in names and picker.value == default_session_dir().resolve()
    picker.dropdown.value = str((data_samples_dir() / "ball_drop").resolve())
    assert wsm.current_session() == (data_samples_dir() / "ball_drop").resolve() == picker.value
    picker.dropdown.value = ""                       # "another folder ...": a path field appears
    assert picker.path.layout.display == ""
    picker.path.value = str(tmp_path)
    picker.use.click()
    assert "not a session folder" in picker.message.value
    assert wsm.current_session() == (data_samples_dir() / "ball_drop").resolve()   # unchanged
    wsm.set_choice(None, "weighting_mode", "thesis")
    picker.reset.click()                             # forget this session's choices
    assert wsm.read_choices() == {}


def test_drawing_the_detection_controls_in_a_browser_writes_no_choice(store):
    """A browser snaps a slider to its grid when it draws it (0.1871 -> 0.185) and, for a slider with
    continuous updates, sends the snapped value back: that must not become a choice (seen in
    JupyterLab: Run All of notebook 04 wrote the middle and right cameras' distance tolerance)."""
    from horsemocap import detection
    from horsemocap.sources import FrameSource
    from horsemocap.widgets import ui_detection
    from horsemocap.widgets.detection import TOLERANCE_STEP

    frames = FrameSource(default_session_dir() / "motion" / "middle.avi").read()
    p = detection.detect_markers(frames, 3).params
    ui = ui_detection(frames, p)
    assert ui.tolerance.continuous_update is False
    ws = wsm.open_workspace()
    ws.bind(ui, "detection.middle", automatic={}, convert=lambda c: wsm.detection_changes(c, p))
    snapped = round(p.distance_tolerance / TOLERANCE_STEP) * TOLERANCE_STEP
    ui.tolerance.value = snapped                     # what the browser sends back
    assert ws.choices == {}
    ui.tolerance.value = snapped + 2 * TOLERANCE_STEP  # a real move is a choice
    assert ws.choices == {"detection": {"middle": {"distance_tolerance": snapped + 2 * TOLERANCE_STEP}}}


def test_the_thesis_preset_chosen_in_a_notebook_holds_for_every_step_and_the_command_line(store):
    from horsemocap.widgets import ui_preset, ui_session

    s = default_session_dir()
    ws = wsm.open_workspace()
    picker = ui_session(ws)
    switch = ui_preset(ws)
    assert switch.value == "default" and ws.choices == {} and "every choice automatic" in picker.message.value
    assert "automatic run" not in picker.message.value
    switch.value = "thesis"
    assert ws.choices == {"preset": "thesis"}
    assert "choices made in the notebooks: preset" in picker.message.value   # the first cell says it at once
    assert "quoted in the notebooks' text are those of the automatic run" in picker.message.value
    p = ws.params                                    # what the notebooks' widgets start from
    assert p.preset == "thesis"
    assert p == AnalysisParams.from_dict({"preset": "thesis"})
    # results_for and `horsemocap analyze --params choices.json` resolve the choices the same way
    session = load_session(s, open_sources=False)
    for q in (resolve_params(session, wsm.read_choices(s)), resolve_params(session, read_params(wsm.choices_path(s)))):
        assert q.to_dict() == p.to_dict()
    # a widget bound under the preset starts from the preset's value; a choice still overrides it,
    # and moving back to the preset's value takes the choice back (the preset holds)
    smooth = ws.bind(W.Dropdown(options=["loess", "rloess"], value=p.smooth.method), "smoothing_method")
    smooth.value = "loess"
    assert ws.choices == {"preset": "thesis", "smoothing_method": "loess"} and ws.params.smooth.method == "loess"
    smooth.value = "rloess"
    assert ws.choices == {"preset": "thesis"}
    assert ui_preset(ws).value == "thesis"           # the next notebook's switch shows it
    switch.value = "default"
    assert ws.choices == {} and ws.params.smooth.method == "loess"


def test_the_period_widget_keeps_the_exact_period_and_shows_it_rounded(store):
    """Seen in notebook 06: the period field showed 17.988538425613434."""
    from horsemocap.widgets import ui_period

    w = ui_period(17.988538425613434, 37)
    assert w.value == 17.988538425613434 and w.readout_format == ".2f" and w.continuous_update is False
    ws = wsm.open_workspace()
    ws.bind(w, "period_frames")
    assert ws.choices == {}
    w.value = 18.0
    assert ws.choices == {"period_frames": 18.0}


def test_two_sessions_with_one_name_keep_apart(store, tmp_path):
    """The store is keyed by the session's folder, not only its name: a copy of the bundled session (the same
    ``name`` in session.json, as the herd's render of Horse 2 canter has) gets its own results folder, and a
    choice made for one is not applied to the other."""
    copy = tmp_path / "elsewhere" / default_session_dir().name
    shutil.copytree(default_session_dir(), copy)
    assert load_session(copy, open_sources=False).name == load_session(default_session_dir(), open_sources=False).name
    a, b = notebook_results_dir(default_session_dir()), notebook_results_dir(copy)
    assert a != b and a.parent == b.parent == store.resolve()
    assert notebook_results_dir(default_session_dir()) == a               # stable
    wsm.set_choice(default_session_dir(), "detection.left.threshold", 140)
    assert wsm.read_choices(default_session_dir()) == {"detection": {"left": {"threshold": 140}}}
    assert wsm.read_choices(copy) == {}


def test_a_checks_message_under_the_downstream_table_is_broken_between_words():
    """JupyterLab's output area breaks a long line mid-word where the pane ends: the messages come pre-wrapped,
    every line within the width, no word cut, nothing lost."""
    from horsemocap.workspace import PROBLEM_WIDTH, problem_lines

    msg = ("the thesis' chain: unreliable: the still's pixel noise (0.0433 px, measured on the moving frames) places "
           "the saddle with standard deviations 2.1, 6.4 and 31.1 mm; carried through the chain that wrote the "
           "acceleration, that is 12.3 % of the written vertical acceleration's rms: 'pose_spline' smoothing")
    lines = problem_lines(msg)
    assert len(lines) > 1 and all(len(line) <= PROBLEM_WIDTH for line in lines)
    assert lines[0].startswith("  the thesis'") and all(line.startswith("    ") for line in lines[1:])
    assert " ".join(line.strip() for line in lines) == msg
