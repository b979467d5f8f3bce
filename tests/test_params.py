"""Analysis parameters: defaults, overrides, and clear errors."""
import json

import pytest

from horsemocap.cli import build_parser, _params_from_args
from horsemocap.params import AnalysisParams, ParamsError, load_params


def test_defaults_are_automatic():
    p = AnalysisParams()
    assert p.sync_offsets is None and p.period_frames is None and p.fourier_orders is None
    assert p.smoothing_span == 0.1 and p.omega_versions == [True] * 6
    assert p.smoothing_method == "loess"  # measured over the herd: see AnalysisParams and notebook 06


@pytest.mark.parametrize("data, pattern", [
    ({"perid_frames": 18}, r"unknown parameter 'perid_frames'; did you mean 'period_frames'\?"),
    ({"triangulation": "pairs"}, r"parameter 'triangulation': expected \"joint\" or \"thesis\""),
    ({"smoothing_span": 0}, r"parameter 'smoothing_span'"),
    ({"omega_versions": [False] * 6}, r"parameter 'omega_versions'"),
    ({"weighting_mode": "bs"}, r"parameter 'weighting_mode'"),
    ({"period_frames": 1}, r"parameter 'period_frames'"),
])
def test_bad_parameters(data, pattern):
    with pytest.raises(ParamsError, match=pattern):
        AnalysisParams.from_dict(data, "analysis.json")


def test_load_params_reads_an_analysis_record(tmp_path):
    path = tmp_path / "analysis.json"
    path.write_text(json.dumps({"format": "horsemocap-results/1", "parameters": {"period_frames": 18.0}}))
    assert load_params(path).period_frames == 18.0
    path.write_text("{bad")
    with pytest.raises(ParamsError, match="not valid JSON"):
        load_params(path)
    with pytest.raises(ParamsError, match="parameter file not found"):
        load_params(tmp_path / "none.json")


def test_command_line_choices_override():
    args = build_parser().parse_args(["analyze", "S", "--out", "O", "--threshold", "115", "--period", "18",
                                      "--offsets", "left=0,middle=53,right=126", "--fourier-orders", "3,2",
                                      "--triangulation", "thesis"])
    p = _params_from_args(args, AnalysisParams())
    assert p.detection == {"all": {"threshold": 115}}
    assert p.period_frames == 18 and p.triangulation == "thesis"
    assert p.sync_offsets == {"left": 0, "middle": 53, "right": 126}
    assert p.fourier_orders == {"y": 3, "z": 2}


def test_thesis_preset_sets_the_thesis_chain_and_explicit_values_override():
    from horsemocap.params import PRESETS

    p = AnalysisParams.from_dict({"preset": "thesis"})
    assert p.preset == "thesis"
    for name, value in PRESETS["thesis"].items():
        assert getattr(p, name) == value
    assert (p.calibration_mode, p.detection_method, p.triangulation, p.smoothing_method, p.order_rule,
            p.angular_method, p.saddle_method, p.weighting_mode) == (
        "pairwise", "thesis", "thesis", "rloess", "thesis", "thesis", "thesis", "thesis")
    q = AnalysisParams.from_dict({"preset": "thesis", "smoothing_method": "loess"})
    assert q.smoothing_method == "loess" and q.triangulation == "thesis"
    # a recorded analysis.json (every field written out) reads back unchanged
    assert AnalysisParams.from_dict(q.to_dict()) == q
    assert AnalysisParams.from_dict({"preset": "default"}) == AnalysisParams(preset="default")
    with pytest.raises(ParamsError, match="parameter 'preset'.*got \"thesys\""):
        AnalysisParams.from_dict({"preset": "thesys"}, "analysis.json")


def test_command_line_preset_then_options():
    args = build_parser().parse_args(["analyze", "S", "--out", "O", "--preset", "thesis", "--smoothing", "loess"])
    p = _params_from_args(args, AnalysisParams())
    assert p.preset == "thesis" and p.triangulation == "thesis" and p.smoothing_method == "loess"


def test_resolve_params_keeps_a_preset_given_to_a_notebook():
    from types import SimpleNamespace

    from horsemocap.pipeline import resolve_params

    session = SimpleNamespace(analysis={"period_frames": 18.0}, json_path="session.json")
    p = resolve_params(session, {"preset": "thesis"})
    assert p.preset == "thesis" and p.triangulation == "thesis" and p.period_frames == 18.0
    assert resolve_params(session, {"triangulation": "thesis"}).smoothing_method == "loess"


def test_analysis_json_records_the_preset():
    from types import SimpleNamespace

    from horsemocap.pipeline import Analysis
    from horsemocap.results import analysis_record

    a = Analysis(SimpleNamespace(root="S", name="s"), AnalysisParams.from_dict({"preset": "thesis"}))
    p = analysis_record(a)["parameters"]
    assert p["preset"] == "thesis" and p["calibration_mode"] == "pairwise"
    assert AnalysisParams.from_dict(p) == a.params  # --params analysis.json repeats it


def test_pose_weights_choice_default_and_thesis_preset():
    from horsemocap.params import AnalysisParams, ParamsError

    assert AnalysisParams().pose_weights == "covariance"
    assert AnalysisParams().with_preset("thesis").pose_weights == "equal"    # eq. 5.14-5.21: markers alike
    assert AnalysisParams.from_dict({"pose_weights": "equal"}).pose_weights == "equal"
    with pytest.raises(ParamsError, match="pose_weights"):
        AnalysisParams.from_dict({"pose_weights": "inverse"})
