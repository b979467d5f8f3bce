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
    real = pipeline.STEP_FUNCTIONS["detect"]

    def detect_then_full(session_, params, results, progress):
        result = real(session_, params, results, progress)
        raise OSError(err_no, os.strerror(err_no), str(tmp_path / "cache" / "corners.json"))

    monkeypatch.setitem(pipeline.STEP_FUNCTIONS, "detect", detect_then_full)
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

    def failing(path, write):
        if path.name == name:
            raise OSError(err_no, os.strerror(err_no), str(path.parent / f".{path.name}.0123.tmp"))
        return real(path, write)

    monkeypatch.setattr(store, "_write_whole", failing)
    code, _, err = run_cli(["analyze", session, "--out", out], capsys)
    line = assert_clear_error(code, err, f"cannot write {out / name}: {os.strerror(err_no)}",
                              f"{out} is as it was before the run")
    assert ".run-" not in line
    assert snapshot(out) == before
    assert _leftovers(tmp_path) == []


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

    monkeypatch.setitem(pipeline.STEP_FUNCTIONS, "sync", broken_sync)
    code, _, err = run_cli(["analyze", session, "--out", tmp_path / "plain"], capsys)
    line = assert_clear_error(code, err, "step 'sync'", "ZeroDivisionError", "--debug")
    argv = ["analyze", session, "--out", tmp_path / "debug"]
    argv = ["--debug", *argv] if where == "before" else [*argv, "--debug"]
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and "Traceback" in err and "broken_sync" in err and "1 / 0" in err
    assert line.replace("plain", "debug") in err.splitlines()
