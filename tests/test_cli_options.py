"""The command line's analysis options: generated from the parameter fields, each traceable to one field."""
import argparse

import pytest

from horsemocap.cli import _params_from_args, analysis_options, build_parser
from horsemocap.params import AnalysisParams, ParamsError, params_fields

# the options of `analyze` that are not analysis parameters
NOT_PARAMETERS = {"help", "debug", "session", "out", "params", "no_report", "set"}

# every analysis option before they were generated, with its argparse dest
OLD_OPTIONS = {
    "--preset": "preset", "--offsets": "offsets", "--recalibrate": "recalibrate", "--threshold": "threshold",
    "--first-frame": "first_frame", "--exclude-views": "exclude_views", "--plumb-threshold": "plumb_threshold",
    "--static-threshold": "static_threshold", "--saddle-marker": "saddle_marker", "--detection": "detection_method",
    "--max-gap": "max_gap_frames", "--triangulation": "triangulation", "--span": "smoothing_span",
    "--period": "period_frames", "--x-marker": "x_marker", "--x-degree": "x_degree",
    "--fourier-orders": "fourier_orders", "--smoothing": "smoothing_method", "--angular": "angular_method",
    "--omega-versions": "omega_versions", "--alpha-versions": "alpha_versions", "--saddle": "saddle_method",
    "--kinematics": "kinematics", "--pose-harmonics": "pose_harmonics", "--pose-weights": "pose_weights",
    "--pose-rotation-weights": "pose_rotation_weights", "--pose-events": "pose_events",
    "--motion-frame": "motion_frame", "--weighting": "weighting_mode", "--set": "set",
}

# each old option with a value, and the parameters it gave (by the flat names, as the old code set them)
OLD_MEANINGS = [
    (["--offsets", "left=0,middle=53,right=126"], {"sync_offsets": {"left": 0, "middle": 53, "right": 126}}),
    (["--recalibrate"], {"recalibrate": True}),
    (["--threshold", "150"], {"detection": {"all": {"threshold": 150}}}),
    (["--first-frame", "4"], {"detection": {"all": {"first_frame": 4}}}),
    (["--threshold", "150", "--first-frame", "4"], {"detection": {"all": {"threshold": 150, "first_frame": 4}}}),
    (["--exclude-views", "left=a.png+b.png,right=c.png"],
     {"calibration_exclude": {"left": ["a.png", "b.png"], "right": ["c.png"]}}),
    (["--plumb-threshold", "120"], {"stills": {"plumb": {"all": {"threshold": 120}}}}),
    (["--static-threshold", "200"], {"stills": {"static": {"all": {"threshold": 200}}}}),
    (["--saddle-marker", "1"], {"saddle_marker": 1}),
    (["--detection", "thesis"], {"detection_method": "thesis"}),
    (["--max-gap", "0"], {"max_gap_frames": 0}),
    (["--triangulation", "thesis"], {"triangulation": "thesis"}),
    (["--span", "0.25"], {"smoothing_span": 0.25}),
    (["--period", "18"], {"period_frames": 18.0}),
    (["--x-marker", "2"], {"x_marker": 2}),
    (["--x-degree", "2"], {"x_degree": 2}),
    (["--fourier-orders", "2,1"], {"fourier_orders": {"y": 2, "z": 1}}),
    (["--smoothing", "rloess"], {"smoothing_method": "rloess"}),
    (["--angular", "thesis"], {"angular_method": "thesis"}),
    (["--omega-versions", "1,2,4"], {"omega_versions": [True, True, False, True, False, False]}),
    (["--alpha-versions", "6"], {"alpha_versions": [False] * 5 + [True]}),
    (["--saddle", "direct"], {"saddle_method": "direct"}),
    (["--kinematics", "fits"], {"kinematics": "fits"}),
    (["--pose-harmonics", "none"], {"pose_harmonics": "none"}),
    (["--pose-weights", "equal"], {"pose_weights": "equal"}),
    (["--pose-rotation-weights", "equal"], {"pose_rotation_weights": "equal"}),
    (["--pose-events", "1.5,2.25", "--pose-events", "3"], {"pose_events": [1.5, 2.25, 3.0]}),
    (["--motion-frame", "record"], {"motion_frame": "record"}),
    (["--weighting", "thesis"], {"weighting_mode": "thesis"}),
    (["--preset", "thesis"], {"preset": "thesis"}),
    (["--set", "detection.left.threshold=140"], {"detection": {"left": {"threshold": 140}}}),
]


def _analyze_parser() -> argparse.ArgumentParser:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices["analyze"]


def _params(*words):
    return _params_from_args(build_parser().parse_args(["analyze", "S", "--out", "D", *words]), AnalysisParams())


def test_every_option_maps_to_exactly_one_parameter_field():
    fields = {f.path: f for f in params_fields()}
    options = {o.dest: o for o in analysis_options()}
    assert len(options) == len(analysis_options())                        # one dest per option
    targets = [o.target for o in analysis_options()]
    assert len(targets) == len(set(targets))                               # no two options set one value
    for action in _analyze_parser()._actions:
        if action.dest in NOT_PARAMETERS:
            continue
        opt = options[action.dest]
        assert action.option_strings == [opt.flag]
        assert opt.field is fields[opt.field.path]
        assert opt.target == opt.field.path or opt.target.startswith(opt.field.path + ".")
        if opt.field.choices:
            assert action.choices == list(opt.field.choices)
    parser_dests = {a.dest for a in _analyze_parser()._actions} - NOT_PARAMETERS
    assert parser_dests == set(options)
    # every field with a flag has its option; the demo command has the same ones
    assert {f.path for f in params_fields() if f.cli} <= set(targets)
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert set(options) <= {a.dest for a in sub.choices["demo"]._actions}


def test_every_old_option_still_exists_with_its_dest():
    flags = {s: a.dest for a in _analyze_parser()._actions for s in a.option_strings}
    for flag, dest in OLD_OPTIONS.items():
        assert flags.get(flag) == dest, flag


@pytest.mark.parametrize("words, flat", OLD_MEANINGS, ids=[w[0] for w, _ in OLD_MEANINGS])
def test_every_old_option_gives_the_parameters_it_gave(words, flat):
    assert _params(*words) == AnalysisParams.from_dict(flat)


def test_a_whole_old_command_line_gives_the_same_parameters():
    p = _params("--threshold", "150", "--kinematics", "fits", "--offsets", "left=0,middle=3,right=5",
                "--fourier-orders", "2,1", "--omega-versions", "1,2,4")
    assert p == AnalysisParams.from_dict({"detection": {"all": {"threshold": 150}}, "kinematics": "fits",
                                          "sync_offsets": {"left": 0, "middle": 3, "right": 5},
                                          "fourier_orders": {"y": 2, "z": 1},
                                          "omega_versions": [True, True, False, True, False, False]})
    assert p.detect.cameras == {"all": {"threshold": 150}} and p.rigid_body.kinematics == "fits"


def test_options_apply_over_a_base_and_its_dicts():
    base = AnalysisParams.from_dict({"detection": {"all": {"area_min": 5}, "left": {"threshold": 90}}})
    args = build_parser().parse_args(["analyze", "S", "--out", "D", "--threshold", "150"])
    p = _params_from_args(args, base)
    assert p.detect.cameras == {"all": {"area_min": 5, "threshold": 150}, "left": {"threshold": 90}}
    assert _params_from_args(build_parser().parse_args(["analyze", "S", "--out", "D"]), base) == base


def test_set_takes_new_and_flat_dotted_names():
    assert _params("--set", "smooth.span=0.2") == _params("--set", "smoothing_span=0.2") == _params("--span", "0.2")
    assert _params("--set", "detect.cameras.left.threshold=140") == \
        _params("--set", "detection.left.threshold=140")
    assert _params("--set", "stills.static.left.threshold=150").stills.static == {"left": {"threshold": 150}}
    assert _params("--set", "rigid_body.fits.x_degree=2", "--set", "motion_frame=record") == \
        AnalysisParams.from_dict({"x_degree": 2, "motion_frame": "record"})
    assert _params("--set", "smooth.method=rloess").smooth.method == "rloess"      # a bare word is a string


@pytest.mark.parametrize("words, said", [
    (["--set", "smooth.span=1e400"], r"--set smooth.span=1e400: parameter 'smooth.span'.*got Infinity"),
    (["--set", "smoothing_span=NaN"], r"parameter 'smooth.span' \(given as 'smoothing_span'\).*got NaN"),
    (["--set", "smooth.span=Infinity"], r"parameter 'smooth.span'"),
    (["--set", "motion_frame.period_frames=-Infinity"], r"parameter 'motion_frame.period_frames'"),
    (["--set", "detection.left.threshold=1e400"], r"parameter 'detect.cameras.left.threshold' \(given as "
                                                  r"'detection.left.threshold'\): expected a finite number"),
    (["--set", "detect.cameras.all.distance_tolerance=NaN"], r"'detect.cameras.all.distance_tolerance'"),
    (["--set", "stills.plumb.all.threshold=1e400"], r"'stills.plumb.all.threshold'"),
    (["--set", "pose_events=[1, Infinity]"], r"'rigid_body.pose.events'"),
    (["--set", "x_degree=100000000000000000000"], r"'rigid_body.fits.x_degree'.*0..10"),
    (["--span", "nan"], r"command line: parameter 'smooth.span'"),
    (["--period", "inf"], r"command line: parameter 'motion_frame.period_frames'"),
    (["--set", "nope=3"], r"unknown parameter 'nope'"),
    (["--set", "smoothing_span"], r"expected NAME=VALUE"),
    (["--set", "smooth..span=3"], r"expected NAME=VALUE"),
    (["--omega-versions", "0,7"], r"--omega-versions: expected version numbers 1-6"),
    (["--offsets", "left:0"], r"--offsets: expected CAM=FRAME"),
    (["--fourier-orders", "3"], r"--fourier-orders: expected Y,Z"),
    (["--exclude-views", "left"], r"--exclude-views: expected CAM=VIEW"),
    (["--pose-events", "x"], r"--pose-events: 'x' is not a time"),
    (["--threshold", "999"], r"'detect.cameras.all' \(given as 'detection.all'\).*threshold"),
])
def test_bad_values_are_refused_naming_the_field_or_the_option(words, said):
    with pytest.raises(ParamsError, match=said):
        _params(*words)


def test_help_groups_the_options_by_step():
    text = _analyze_parser().format_help()
    for section in ("sync:", "rig:", "stills:", "detect:", "triangulate:", "smooth:", "motion_frame:",
                    "rigid_body:", "comfort:"):
        assert f"\n{section}\n" in text, section
    assert "--span FRACTION" in text and "(default 0.1)" in text
