"""Whole command-line runs under faults: a file that cannot be written, --debug, kinematics' folder, export.

Uses the fault corpus' session template of ``test_faults.py`` (the bundled
session with a calibrated rig and known sync offsets).
"""
from __future__ import annotations

import errno
import json
import os

import numpy as np
import pytest

from horsemocap import io3d, pipeline, store, synthetic
from horsemocap.cli import main
from test_faults import (assert_clear_error, calibrated_rig, earlier_results, make_session,  # noqa: F401
                         run_cli, snapshot, template)


def _leftovers(parent, keep=("out", "session")):
    """Names beside ``out`` other than ``keep`` (a temporary folder, a lock)."""
    return sorted(p.name for p in parent.iterdir() if p.name not in keep)


# ---------------------------------------------------------------------------
# 1. a file that cannot be written leaves DIR as it was
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("err_no", [errno.ENOSPC, errno.EROFS])
def test_os_error_inside_a_step_leaves_results_as_before(err_no, tmp_path, template, capsys, monkeypatch):
    """A step whose own writing fails (as the rig step's calibration cache did on a full tmpfs):
    not a step failure with PARTIAL.txt, the earlier run's folder stays byte for byte."""
    session = make_session(tmp_path, template)
    out = tmp_path / "out"
    before = earlier_results(out)
    real = pipeline.STEP_CALLS["detect"]

    def detect_then_full(analysis, progress):
        result = real(analysis, progress)
        raise OSError(err_no, os.strerror(err_no), str(tmp_path / "cache" / "corners.json"))

    monkeypatch.setitem(pipeline.STEP_CALLS, "detect", detect_then_full)
    code, _, err = run_cli(["analyze", session, "--out", out], capsys)
    line = assert_clear_error(code, err, "cannot write", str(tmp_path / "cache" / "corners.json"),
                              os.strerror(err_no), "as it was before the run")
    assert "PARTIAL" not in err and "step 'detect'" not in line
    assert snapshot(out) == before
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("name, err_no", [("markers_2d.csv", errno.EDQUOT), ("rig.toml", errno.EIO),
                                          ("quality.json", errno.EACCES), ("report.html", errno.ENOSPC)])
def test_results_file_not_written_leaves_results_as_before(name, err_no, tmp_path, template, capsys, monkeypatch):
    """The writer fails on one results file (after a step, or after the analysis): the message names
    that file in DIR (not the temporary folder) and the system's error text; DIR is as before."""
    session = make_session(tmp_path, template)
    out = tmp_path / "out"
    before = earlier_results(out)
    real = store._write_whole

    def failing(path, write, *how):
        if path.name == name:
            raise OSError(err_no, os.strerror(err_no), str(path.parent / f".{path.name}.0123.tmp"))
        return real(path, write, *how)

    monkeypatch.setattr(store, "_write_whole", failing)
    code, _, err = run_cli(["analyze", session, "--out", out], capsys)
    line = assert_clear_error(code, err, f"cannot write {out / name}: {os.strerror(err_no)}",
                              f"{out} is as it was before the run")
    assert ".run-" not in line
    assert snapshot(out) == before
    assert _leftovers(tmp_path) == []


def test_lock_note_on_a_full_disk_does_not_stop_the_run(tmp_path, monkeypatch):
    """The lock file's "pid N" note is a courtesy: a full disk there leaves the lock held and the run going
    (its own files then meet the full disk and name themselves)."""
    from horsemocap import runfolder

    real_write = os.write

    def full(fd, data):
        if os.path.basename(os.readlink(f"/proc/self/fd/{fd}")).endswith(".lock"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_write(fd, data)

    monkeypatch.setattr(runfolder.os, "write", full)
    folder = runfolder.RunFolder(tmp_path / "out")
    with folder as tmp:
        (tmp / "a.txt").write_text("x")
        with pytest.raises(runfolder.RunLockedError):      # the lock is held all the same
            runfolder.RunFolder(tmp_path / "out").__enter__()
        folder.commit()
    assert (tmp_path / "out" / "a.txt").read_text() == "x"
    assert _leftovers(tmp_path, keep=("out",)) == []


def test_atomic_write_names_the_file(tmp_path, monkeypatch):
    """store's writers turn any OSError into a WriteError naming the file, not its temporary name."""
    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(store.os, "fdopen", lambda fd, mode: (os.close(fd), _Full())[1])
    with pytest.raises(store.WriteError) as info:
        store.atomic_write_text(tmp_path / "a.csv", "x")
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "a.csv")
    assert str(info.value) == f"cannot write {tmp_path / 'a.csv'}: No space left on device"
    assert os.listdir(tmp_path) == []   # no temporary file left


class _Full:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def write(self, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


# ---------------------------------------------------------------------------
# 2. --debug shows the traceback of a step's error
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("where", ["before", "after"])
def test_debug_shows_the_traceback_of_a_step_error(where, tmp_path, template, capsys, monkeypatch):
    session = make_session(tmp_path, template)

    def broken_sync(*a, **k):
        return {"offsets": 1 / 0}

    monkeypatch.setitem(pipeline.STEP_CALLS, "sync", broken_sync)
    code, _, err = run_cli(["analyze", session, "--out", tmp_path / "plain"], capsys)
    line = assert_clear_error(code, err, "step 'sync'", "ZeroDivisionError", "--debug")
    argv = ["analyze", session, "--out", tmp_path / "debug"]
    argv = ["--debug", *argv] if where == "before" else [*argv, "--debug"]
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and "Traceback" in err and "broken_sync" in err and "1 / 0" in err
    assert line.replace("plain", "debug") in err.splitlines()


# ---------------------------------------------------------------------------
# 4. option syntax and help
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("words", [["0.5,0.8"], ["0.5", "0.8"], ["0.5,", "0.8"], ["0.5, 0.8"]])
def test_times_take_commas_and_spaces(words):
    """One word per occurrence of the option (commas inside a word; the option repeated), in any position:
    a time never swallows the positional argument that follows it."""
    from horsemocap.cli import build_parser, parse_seconds

    assert parse_seconds(words, "--events") == [0.5, 0.8]
    parser = build_parser()
    kin_opts = [x for w in words for x in ("--events", w)]
    ana_opts = [x for w in words for x in ("--pose-events", w)]
    kin = parser.parse_args(["kinematics", *kin_opts, "t.csv", "--static", "s.csv", "--out", "o"])
    ana = parser.parse_args(["analyze", *ana_opts, "S", "--out", "o"])
    assert kin.trajectories == "t.csv" and ana.session == "S"
    assert parse_seconds(kin.events, "--events") == parse_seconds(ana.pose_events, "--pose-events") == [0.5, 0.8]


@pytest.mark.parametrize("words, bad", [(["0.5;0.8"], "'0.5;0.8'"), (["x"], "'x'"), (["nan"], "'nan'"),
                                        ([","], "expected times")])
def test_bad_times_name_the_option_and_the_word(words, bad):
    from horsemocap.cli import parse_seconds
    from horsemocap.params import ParamsError

    with pytest.raises(ParamsError) as info:
        parse_seconds(words, "--pose-events")
    assert str(info.value).startswith("--pose-events: ") and bad in str(info.value)


def test_analyze_pose_events_reach_the_parameters(tmp_path, template):
    """Both spellings give the same parameters (and the same analysis.json)."""
    from horsemocap.cli import _params_from_args, build_parser
    from horsemocap.pipeline import resolve_params
    from horsemocap.session import load_session

    base = resolve_params(load_session(template))
    got = [_params_from_args(build_parser().parse_args(["analyze", "S", "--out", "o",
                                                         *[x for word in w for x in ("--pose-events", word)]]), base)
           for w in (["1.5,2.25"], ["1.5", "2.25"])]
    assert got[0].rigid_body.pose.events == got[1].rigid_body.pose.events == [1.5, 2.25]


def test_kinematics_events_with_commas(tmp_path, capsys):
    """``kinematics --events 0.2,0.4`` (as analyze's --pose-events) runs like ``--events 0.2 0.4``."""
    from test_io3d import _small_record

    traj, static = _small_record(tmp_path / "in")
    outs = []
    for i, words in enumerate((["0.2,0.4"], ["0.2", "0.4"])):
        out = tmp_path / f"o{i}"
        assert main(["kinematics", str(traj), "--static", str(static), "--out", str(out),
                     *[x for word in words for x in ("--events", word)]]) == 0
        outs.append(out)
    assert (outs[0] / "kinematics.csv").read_bytes() == (outs[1] / "kinematics.csv").read_bytes()
    assert json.loads((outs[0] / "kinematics-run.json").read_text())["options"]["events"] == [0.2, 0.4]
    assert main(["kinematics", str(traj), "--static", str(static), "--out", str(tmp_path / "bad"),
                 "--events", "0.2;0.4"]) == 2
    assert "--events: '0.2;0.4' is not a time in seconds" in capsys.readouterr().err


def _help(*command):
    from horsemocap.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command[0]] if command else parser
    return {a.dest: (a.help or "") for a in sub._actions}, sub.format_help()


def test_help_says_what_each_option_does():
    helps, text = _help("kinematics")
    assert "benchmarks/README.md" in helps["events"] and "issue 13" not in text and "18.4" not in text
    assert "2.8,3.35 (or the option repeated" in helps["events"]
    for command in ("kinematics", "calibrate", "export", "analyze", "demo"):
        assert _help(command)[0]["out"], f"{command} --out has no help"
    helps, _ = _help("analyze")
    assert helps["pose_events"].count("e.g.") <= 1 and "2.8,3.35 (or the option repeated" in helps["pose_events"]
    assert "default 0.1" in helps["smoothing_span"] and "default 0" in helps["x_marker"]
    from horsemocap.params import AnalysisParams

    assert AnalysisParams().smooth.span == 0.1 and AnalysisParams().motion_frame.x_marker == 0
    assert "(default auto)" in helps["pose_harmonics"] and "above the noise" in helps["pose_harmonics"]
