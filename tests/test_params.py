"""Analysis parameters: sections by step, defaults, overrides (nested or flat names), and clear errors."""
import json
import math
from dataclasses import replace
from types import SimpleNamespace

import pytest

from horsemocap.cli import build_parser, _params_from_args
from horsemocap.params import (PRESETS, STEP_SECTIONS, AnalysisParams, ParamsError, legacy_names, load_params,
                               params_fields, read_params)


def test_defaults_are_automatic():
    p = AnalysisParams()
    assert p.sync.offsets is None and p.motion_frame.period_frames is None
    assert p.rigid_body.fits.fourier_orders is None
    assert p.smooth.span == 0.1 and p.rigid_body.fits.omega_versions == [True] * 6
    assert p.smooth.method == "loess"  # measured over the herd: benchmarks/README.md and notebook 06
    assert p.preset is None


def test_every_field_has_help_a_unique_dotted_and_flat_name():
    names = [f.path for f in params_fields()]
    assert len(names) == len(set(names)) == 36
    flat = [f.legacy for f in params_fields() if f.legacy]
    assert len(flat) == len(set(flat)) == 31       # the 33 fields before the sections, less preset and stills
    assert all(f.help for f in params_fields())
    assert legacy_names()["smoothing_span"] == "smooth.span"
    assert legacy_names()["detection"] == "detect.cameras"


def test_order_rules_are_the_fitting_modules():
    from horsemocap.fitting import ORDER_RULES

    field = next(f for f in params_fields() if f.path == "rigid_body.fits.order_rule")
    assert tuple(field.choices) == tuple(ORDER_RULES)


@pytest.mark.parametrize("data, pattern", [
    ({"perid_frames": 18}, r"unknown parameter 'perid_frames'; did you mean 'period_frames'\?"),
    ({"triangulation": "pairs"},
     r"parameter 'triangulate.mode' \(given as 'triangulation'\): expected \"joint\" or \"thesis\", got \"pairs\""),
    ({"triangulate": {"mode": "pairs"}}, r"parameter 'triangulate.mode': expected \"joint\" or \"thesis\""),
    ({"smoothing_span": 0}, r"parameter 'smooth.span' \(given as 'smoothing_span'\): expected a number in \(0, 1\]"),
    ({"smooth": {"span": "wide"}}, r"analysis.json: parameter 'smooth.span': expected a number in \(0, 1\], "
                                   r"got \"wide\""),
    ({"omega_versions": [False] * 6}, r"parameter 'rigid_body.fits.omega_versions' \(given as 'omega_versions'\)"),
    ({"weighting_mode": "bs"}, r"parameter 'comfort.weighting_mode' \(given as 'weighting_mode'\)"),
    ({"period_frames": 1}, r"parameter 'motion_frame.period_frames' \(given as 'period_frames'\): "
                           r"expected a number > 2 or null, got 1"),
    ({"x_degree": 11}, r"'rigid_body.fits.x_degree'.*an integer in 0..10, got 11"),
    ({"max_gap_frames": -1}, r"'detect.max_gap_frames'.*an integer >= 0 or null"),
    ({"smooth": {"spam": 0.2}}, r"unknown parameter 'smooth.spam'; did you mean 'smooth.span'\?"),
    ({"rigid_body": {"fits": {"x_degre": 2}}}, r"unknown parameter 'rigid_body.fits.x_degre'"),
    ({"smooth": 0.2}, r"parameter 'smooth': expected an object of its parameters \(method, span\)"),
    ({"smooth.span": 0.2}, r"unknown parameter 'smooth.span' \(a parameter object nests its sections"),
    ({"motion_frame": "sometimes"}, r"'motion_frame.mode' \(given as 'motion_frame'\)"),
    ({"stills": {"plumb": {"all": {"labels": [1, 2]}}}}, r"'stills.plumb.all'.*a threshold with the labels"),
    ({"stills": {"static": {"left": {"threshold": 255}}}}, r"'stills.static.left.threshold'.*0..254\), got 255"),
    ({"stills": {"top": {}}}, r"unknown parameter 'stills.top'"),
    ({"detection": {"left": {"threshold": 300}}}, r"'detect.cameras.left' \(given as 'detection.left'\).*0..254"),
    ({"detect": {"cameras": {"left": 5}}}, r"'detect.cameras.left': expected an object of detector parameters"),
    ({"sync_offsets": {"left": -1}}, r"'sync.offsets' \(given as 'sync_offsets'\).*camera 'left', got -1"),
    ({"fourier_orders": {"y": 3}}, r"'rigid_body.fits.fourier_orders'"),
    ({"calibration_exclude": {"left": "view03.png"}}, r"'rig.exclude' \(given as 'calibration_exclude'\)"),
    ({"preset": "thesys"}, r"parameter 'preset'.*got \"thesys\""),
])
def test_bad_parameters(data, pattern):
    with pytest.raises(ParamsError, match=pattern):
        AnalysisParams.from_dict(data, "analysis.json")


def test_every_field_refuses_a_wrong_type_naming_it():
    """The one validation path covers every field, whatever its kind."""
    for f in params_fields():
        with pytest.raises(ParamsError, match=rf"^x: parameter '{f.path}'"):
            AnalysisParams().updated({f.path: "?"}, source="x")
        if f.legacy:
            with pytest.raises(ParamsError, match=rf"parameter '{f.path}' \(given as '{f.legacy}'\)"):
                AnalysisParams.from_dict({f.legacy: "?"})


@pytest.mark.parametrize("change, name", [
    ({"smooth.span": math.nan}, "smooth.span"),
    ({"smoothing_span": math.inf}, "smooth.span"),
    ({"smooth.span": 1e300}, "smooth.span"),                         # a huge value beyond the range
    ({"motion_frame.period_frames": math.inf}, "motion_frame.period_frames"),
    ({"rigid_body.fits.x_degree": 10 ** 30}, "rigid_body.fits.x_degree"),
    ({"detection.left.threshold": math.inf}, "detect.cameras.left.threshold"),
    ({"detect.cameras.all.area_min": math.nan}, "detect.cameras.all.area_min"),
    ({"detect.cameras.all.threshold": 10 ** 20}, "detect.cameras.all"),
    ({"stills.static.all.threshold": math.inf}, "stills.static.all.threshold"),
    ({"rigid_body.pose.events": [1.0, math.nan]}, "rigid_body.pose.events"),
    ({"sync.offsets": {"left": math.inf}}, "sync.offsets"),
])
def test_numbers_must_be_finite_and_in_range(change, name):
    with pytest.raises(ParamsError, match=rf"parameter '{name}"):
        AnalysisParams().updated(change)


def test_nested_flat_and_mixed_forms_give_the_same_parameters():
    nested = AnalysisParams.from_dict({"smooth": {"span": 0.2, "method": "rloess"}, "detect": {"cameras": {
        "all": {"threshold": 150}}}, "motion_frame": {"mode": "record"}, "stills": {"static": {"all": {
            "threshold": 200}}}, "rigid_body": {"fits": {"trend": False}, "pose": {"events": [1.5]}}})
    flat = AnalysisParams.from_dict({"smoothing_span": 0.2, "smoothing_method": "rloess",
                                     "detection": {"all": {"threshold": 150}}, "motion_frame": "record",
                                     "stills": {"static": {"all": {"threshold": 200}}}, "fourier_trend": False,
                                     "pose_events": [1.5]})
    mixed = AnalysisParams.from_dict({"smooth": {"span": 0.2}, "smoothing_method": "rloess",
                                      "detection": {"all": {"threshold": 150}}, "motion_frame": "record",
                                      "stills": {"static": {"all": {"threshold": 200}}},
                                      "rigid_body": {"fits": {"trend": False}}, "pose_events": [1.5],
                                      "smoothing_span": 0.2})          # the same value twice is fine
    assert nested == flat == mixed
    assert nested.stills.static == {"all": {"threshold": 200}} and nested.stills.plumb == {}


def test_a_flat_name_and_its_field_with_different_values_are_refused_naming_both():
    with pytest.raises(ParamsError, match="'smooth.span' given twice with different values: as 'smoothing_span' "
                                          r"\(0.2\) and as 'smooth.span' \(0.3\)"):
        AnalysisParams.from_dict({"smoothing_span": 0.2, "smooth": {"span": 0.3}})
    with pytest.raises(ParamsError, match="'detect.cameras' given twice.*'detection'"):
        AnalysisParams.from_dict({"detect": {"cameras": {"all": {"threshold": 1}}}, "detection": {}})


def test_to_dict_is_the_nested_json_form_and_reads_back():
    p = AnalysisParams.from_dict({"preset": "thesis", "sync_offsets": {"left": 0, "middle": 1, "right": 2}})
    d = p.to_dict()
    assert list(d) == ["preset", "sync", "rig", "stills", "detect", "triangulate", "smooth", "motion_frame",
                       "rigid_body", "comfort"]
    assert d["rigid_body"]["fits"]["angular_method"] == "thesis" and d["sync"]["offsets"]["right"] == 2
    assert AnalysisParams.from_dict(json.loads(json.dumps(d))) == p


def test_load_params_reads_an_analysis_record_nested_or_flat(tmp_path):
    path = tmp_path / "analysis.json"
    path.write_text(json.dumps({"format": "horsemocap-results/1", "parameters": {"period_frames": 18.0}}))
    assert load_params(path).motion_frame.period_frames == 18.0
    assert read_params(path) == {"period_frames": 18.0}                     # as given
    nested = {"motion_frame": {"period_frames": 18.0}, "smooth": {"span": 0.2}}
    path.write_text(json.dumps({"format": "horsemocap-results/1", "parameters": nested}))
    assert load_params(path).smooth.span == 0.2 and read_params(path) == nested
    path.write_text("{bad")
    with pytest.raises(ParamsError, match="not valid JSON"):
        load_params(path)
    with pytest.raises(ParamsError, match="parameter file not found"):
        load_params(tmp_path / "none.json")
    path.write_text(json.dumps({"parameters": {"smooth": {"span": 2}}}))
    with pytest.raises(ParamsError, match=r"analysis.json: parameter 'smooth.span'"):
        read_params(path)


def test_command_line_choices_override():
    args = build_parser().parse_args(["analyze", "S", "--out", "O", "--threshold", "115", "--period", "18",
                                      "--offsets", "left=0,middle=53,right=126", "--fourier-orders", "3,2",
                                      "--triangulation", "thesis"])
    p = _params_from_args(args, AnalysisParams())
    assert p.detect.cameras == {"all": {"threshold": 115}}
    assert p.motion_frame.period_frames == 18 and p.triangulate.mode == "thesis"
    assert p.sync.offsets == {"left": 0, "middle": 53, "right": 126}
    assert p.rigid_body.fits.fourier_orders == {"y": 3, "z": 2}


def test_thesis_preset_sets_the_thesis_chain_and_explicit_values_override():
    p = AnalysisParams.from_dict({"preset": "thesis"})
    assert p.preset == "thesis"
    thesis = PRESETS["thesis"]
    assert p.rig.mode == thesis["rig"]["mode"] == "pairwise"
    assert p.rigid_body.fits.alpha_versions == [True] * 6 and p.rigid_body.fits.trend is False
    assert (p.rig.mode, p.detect.method, p.triangulate.mode, p.smooth.method, p.rigid_body.fits.order_rule,
            p.rigid_body.fits.angular_method, p.rigid_body.fits.saddle_method, p.comfort.weighting_mode,
            p.rigid_body.kinematics, p.rigid_body.pose.weights, p.motion_frame.mode) == (
        "pairwise", "thesis", "thesis", "rloess", "thesis", "thesis", "thesis", "thesis", "fits", "equal", "period")
    q = AnalysisParams.from_dict({"preset": "thesis", "smoothing_method": "loess"})
    assert q.smooth.method == "loess" and q.triangulate.mode == "thesis"
    assert AnalysisParams.from_dict({"preset": "thesis", "smooth": {"method": "loess"}}) == q
    # a recorded analysis.json (every field written out) reads back unchanged
    assert AnalysisParams.from_dict(q.to_dict()) == q
    assert AnalysisParams.from_dict({"preset": "default"}) == AnalysisParams(preset="default")
    assert AnalysisParams().with_preset("thesis") == p
    with pytest.raises(ParamsError, match="parameter 'preset'.*got \"thesys\""):
        AnalysisParams.from_dict({"preset": "thesys"}, "analysis.json")


def test_layers_override_field_by_field_and_a_preset_sits_under_all():
    p = AnalysisParams.from_layers({"smoothing_span": 0.2, "period_frames": 18.0},
                                   {"smooth": {"method": "rloess"}, "preset": "thesis"},
                                   {"smoothing_span": 0.3})
    assert (p.smooth.span, p.smooth.method, p.motion_frame.period_frames) == (0.3, "rloess", 18.0)
    assert p.triangulate.mode == "thesis" and p.preset == "thesis"
    # a flat name in one layer and its field in a later one: the later wins, no conflict
    assert AnalysisParams.from_layers({"smoothing_span": 0.2}, {"smooth": {"span": 0.4}}).smooth.span == 0.4
    assert AnalysisParams.from_layers({"preset": "thesis"}, {"preset": None}).triangulate.mode == "joint"


def test_command_line_preset_then_options():
    args = build_parser().parse_args(["analyze", "S", "--out", "O", "--preset", "thesis", "--smoothing", "loess"])
    p = _params_from_args(args, AnalysisParams())
    assert p.preset == "thesis" and p.triangulate.mode == "thesis" and p.smooth.method == "loess"


def test_updated_and_with_path_take_dotted_and_flat_names():
    p = AnalysisParams()
    assert p.updated({"smooth.span": 0.2}) == p.updated(smoothing_span=0.2) == p.updated({"smooth": {"span": 0.2}})
    assert p.updated(smoothing_span=0.2).smooth.method == "loess"
    a = p.with_path("detection.left.threshold", 140).with_path("detect.cameras.left.first_frame", 3)
    assert a.detect.cameras == {"left": {"threshold": 140, "first_frame": 3}}
    assert a == p.with_path("detect.cameras.left.threshold", 140).with_path("detection.left.first_frame", 3)
    assert p.with_path("stills.static.left.threshold", 150).stills.static == {"left": {"threshold": 150}}
    assert p.with_path("motion_frame", "record").motion_frame.mode == "record"
    assert p.with_path("motion_frame.x_marker", 1).motion_frame.x_marker == 1
    assert p.with_path("sync_offsets.left", 3).sync.offsets == {"left": 3}
    assert p.updated({"motion_frame.period_frames": 18.0}).updated({"period_frames": None}) == p
    assert a.value("detection.left.threshold") == a.value("detect.cameras.left.threshold") == 140
    assert a.value("detection.right.threshold") is None and a.value("smoothing_span") == 0.1
    with pytest.raises(ParamsError, match="unknown parameter 'nope'"):
        p.with_path("nope", 3)
    with pytest.raises(ParamsError, match="'rigid_body.fits.omega_versions' is not an object of named values"):
        p.with_path("omega_versions.left", 3)
    with pytest.raises(ParamsError, match=r"x: parameter 'smooth.span' \(given as 'smoothing_span'\)"):
        p.updated(smoothing_span=2, source="x")


def test_each_step_is_given_its_section():
    p = AnalysisParams()
    assert set(STEP_SECTIONS) == {"sync", "rig", "plumb", "static", "detect", "triangulate", "smooth",
                                  "motion_frame", "rigid_body", "comfort"}
    assert p.section("plumb") is p.section("static") is p.stills
    assert p.section("rigid_body") is p.rigid_body and p.section("smooth") is p.smooth
    with pytest.raises(ParamsError, match="no step 'fit'"):
        p.section("fit")


def test_the_flat_names_are_read_from_files_and_map_to_one_field_each():
    """Parameter files written before the sections (flat names) are read: each flat name is one field."""
    p = AnalysisParams.from_dict({"preset": "thesis", "detection": {"all": {"threshold": 90}}})
    assert p.detect.cameras == {"all": {"threshold": 90}} and p.triangulate.mode == "thesis"
    paths = legacy_names()
    assert len(set(paths.values())) == len(paths)
    for flat, path in paths.items():
        node = p
        for key in path.split("."):
            node = getattr(node, key)          # every flat name names a field that exists
    q = p.updated(kinematics="pose_spline", pose_events=[1.0], smoothing_span=0.2)
    assert q.rigid_body.pose.events == [1.0] and q.smooth.span == 0.2 and q.triangulate.mode == "thesis"
    assert AnalysisParams.from_dict({"stills": {"plumb": {"all": {"threshold": 3}}}}).stills.plumb == {"all": {"threshold": 3}}
    with pytest.raises(AttributeError):
        p.smoothing_span                       # in code, the sections only
    with pytest.raises(ParamsError, match=r"test: parameter 'rigid_body.pose.smoothing' \(given as 'pose_smoothing'"):
        AnalysisParams.from_dict({"pose_smoothing": "best"}, "test")


def test_check_session_names_the_parameter():
    session = SimpleNamespace(cameras=["left", "middle", "right"], marker_count=3)
    AnalysisParams().check_session(session)
    for data, pattern in (
            ({"sync_offsets": {"left": 0}}, r"parameter 'sync.offsets' \(given as 'sync_offsets'\).*'middle'"),
            ({"detect": {"cameras": {"top": {}}}}, r"parameter 'detect.cameras': expected 'all' or a camera.*'top'"),
            ({"calibration_exclude": {"top": ["a.png"]}}, r"'rig.exclude' \(given as 'calibration_exclude'\)"),
            ({"x_marker": 3}, r"'motion_frame.x_marker' \(given as 'x_marker'\): expected a marker index 0..2"),
            ({"rigid_body": {"saddle_marker": 4}}, r"'rigid_body.saddle_marker': expected a static-shot point 0..3"),
            ({"fourier_orders": [[3, 2]]}, r"'rigid_body.fits.fourier_orders'.*3 pairs"),
            ({"stills": {"plumb": {"all": {"threshold": 9, "labels": [1, 2, 3]}}}},
             r"'stills.plumb': expected 2 labels for camera 'left'"),
            ({"stills": {"static": {"left": {"threshold": 9, "labels": [1, 2, 3, 4]}}}},
             r"'stills.static': labels given for \['left'\] but not for")):
        with pytest.raises(ParamsError, match=pattern):
            AnalysisParams.from_dict(data).check_session(session, "s.json")


def test_pose_events_need_a_smoothing_that_fits_change_points():
    ok = {"pose_events": [1.0], "pose_smoothing": "gcv", "pose_harmonics": "none"}
    assert AnalysisParams.from_dict(ok).rigid_body.pose.events == [1.0]
    for bad, said in (({"kinematics": "fits"}, "rigid_body.kinematics \"fits\""),
                      ({"pose_harmonics": "auto"}, "rigid_body.pose.harmonics \"auto\""),
                      ({"pose_smoothing": "none"}, "rigid_body.pose.smoothing \"none\"")):
        with pytest.raises(ParamsError, match=rf"'rigid_body.pose.events' \(given as 'pose_events'\).*{said}"):
            AnalysisParams.from_dict({**ok, **bad})


def test_resolve_params_keeps_a_preset_given_to_a_notebook():
    from horsemocap.pipeline import resolve_params

    session = SimpleNamespace(analysis={"period_frames": 18.0}, json_path="session.json")
    p = resolve_params(session, {"preset": "thesis"})
    assert p.preset == "thesis" and p.triangulate.mode == "thesis" and p.motion_frame.period_frames == 18.0
    assert resolve_params(session, {"triangulation": "thesis"}).smooth.method == "loess"
    # an earlier run's analysis.json (nested, every field) over a session's flat values: the record wins
    record = AnalysisParams.from_dict({"period_frames": 20.0}).to_dict()
    assert resolve_params(session, record).motion_frame.period_frames == 20.0


def test_analysis_json_records_the_preset():
    from horsemocap.pipeline import Analysis
    from horsemocap.results import analysis_record

    a = Analysis(SimpleNamespace(root="S", name="s"), AnalysisParams.from_dict({"preset": "thesis"}))
    p = analysis_record(a)["parameters"]
    assert p["preset"] == "thesis" and p["rig"]["mode"] == "pairwise"
    assert AnalysisParams.from_dict(p) == a.params  # --params analysis.json repeats it


def test_pose_weights_choice_default_and_thesis_preset():
    assert AnalysisParams().rigid_body.pose.weights == "covariance"
    assert AnalysisParams().with_preset("thesis").rigid_body.pose.weights == "equal"   # eq. 5.14-5.21
    assert AnalysisParams.from_dict({"pose_weights": "equal"}).rigid_body.pose.weights == "equal"
    with pytest.raises(ParamsError, match="pose_weights"):
        AnalysisParams.from_dict({"pose_weights": "inverse"})
