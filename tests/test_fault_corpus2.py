"""The second fault corpus: results folders, the notebooks' store, 3D input and export, parameters.

Every case ends in one of three ways, which its test id starts with:
``clear`` (an error that names the file, field, point or frame and what was
expected; nothing written, nothing deleted), ``correct`` (the right result,
nothing said) or ``flagged`` (results written with a warning or an
UNRELIABLE verdict). No case may end in exit 0 with wrong numbers, delete a
file the run did not write, or leave a results folder that mixes two runs.
The cases use small synthetic records, copies of the bundled session's
``session.json`` and the results store's own files: nothing is rendered, and
one case only runs the bundled analysis (the notebooks' folder after an
earlier step changed).
"""
from __future__ import annotations

import csv
import json
import math
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from horsemocap import fingerprint
from horsemocap.cli import _set_param, main
from horsemocap.data import default_session_dir
from horsemocap.params import AnalysisParams, ParamsError, params_fields
from horsemocap.runfolder import RunFolder, check_results_target
from horsemocap.session import SessionError, SessionWarning, load_session
from horsemocap.sources import FrameSource, SourceError
from horsemocap.store import STEP_RESULT_FILES, ResultsStore, StoreError
from horsemocap.steps import STEPS

BUNDLED = default_session_dir()


# ---------------------------------------------------------------------------
# building blocks
# ---------------------------------------------------------------------------

def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (links not followed) -> its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.is_symlink()}


def earlier_results(out: Path, kind: str = "analyze") -> None:
    """A results folder as an earlier run of ``kind`` left it."""
    out.mkdir(parents=True)
    if kind == "analyze":
        (out / "analysis.json").write_text(json.dumps({"format": "horsemocap-results/1", "complete": True}))
        (out / "comfort.csv").write_text("indicator,value,unit\nacc_y_Wk_rms,1.0,m/s^2\n")
        (out / "report.html").write_text("<html>earlier run</html>")
    else:
        (out / "kinematics-run.json").write_text(json.dumps({"format": "horsemocap-kinematics/1"}))
        (out / "kinematics.csv").write_text("frame,time_s\n")


def write_record(path: Path, points: np.ndarray, names, times, frames=None, fmt=repr) -> Path:
    """A trajectories.csv-layout file of (n, k, 3) ``points``."""
    frames = range(len(times)) if frames is None else frames
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s", "point", "x_m", "y_m", "z_m"])
        for k, (fr, t) in enumerate(zip(frames, times)):
            for j, nm in enumerate(names):
                w.writerow([fr, fmt(float(t)), nm, *(fmt(float(v)) for v in points[k, j])])
    return path


TRIANGLE = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.1, 0.25, 0.02]])


def record_files(folder: Path, *, n=40, rate=100.0, scale=1.0, static_scale=None, time_scale=1.0, speed=0.5,
                 edit=None):
    """A rigid triangle moving at ``speed`` m/s and its static shot (+ a hidden point), both as CSV.

    ``scale`` multiplies the record's coordinates (1000: millimetres written as metres), ``static_scale``
    the static shot's (default: ``scale``), ``time_scale`` the times (1000: milliseconds); ``edit(points)``
    changes the record's points before writing.
    """
    t = np.arange(n) / rate
    move = np.stack([speed * t, 0.02 * np.sin(2 * np.pi * 2 * t), 0.01 * np.cos(2 * np.pi * 2 * t)], 1)
    pts = (TRIANGLE[None] + move[:, None, :]) * scale
    if edit is not None:
        edit(pts)
    traj = write_record(folder / "traj.csv", pts, "abc", t * time_scale)
    s = scale if static_scale is None else static_scale
    static_pts = np.vstack([TRIANGLE, [[0.1, 0.1, -0.2]]])[None] * s
    static = write_record(folder / "static.csv", static_pts, "abcs", [0.0])
    return traj, static


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(err: str) -> str:
    """The error line; the test fails on a traceback."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith("horsemocap: error:")]
    assert lines, err
    return lines[0]


@pytest.fixture(scope="module")
def session_json() -> dict:
    return json.loads((BUNDLED / "session.json").read_text())


def light_session(folder: Path, doc: dict) -> Path:
    """A session folder whose files are links to the bundled session's (read only), with ``doc`` as session.json."""
    folder.mkdir(parents=True)
    for entry in BUNDLED.iterdir():
        if entry.name != "session.json":
            (folder / entry.name).symlink_to(entry)
    (folder / "session.json").write_text(json.dumps(doc))
    return folder


# ---------------------------------------------------------------------------
# 1. nothing deleted that a run did not write
# ---------------------------------------------------------------------------

FOREIGN = {
    "user_notes": lambda out: (out / "notes.txt").write_text("my notes"),
    "user_csv": lambda out: (out / "stray.csv").write_text("1,2"),
    "user_docx": lambda out: (out / "thesis.docx").write_bytes(b"PK"),
    "hidden_file": lambda out: (out / ".keep").write_text(""),
    "user_folder": lambda out: (out / "figures").mkdir(),
    "own_name_as_folder": lambda out: (out / "report.html.d").mkdir(),
    "session_at_top": lambda out: (out / "session.json").write_text("{}"),
    "session_in_steps": lambda out: ((out / "steps").mkdir(), (out / "steps" / "session.json").write_text("{}")),
    "session_two_deep": lambda out: ((out / "steps" / "a").mkdir(parents=True),
                                     (out / "steps" / "a" / "session.json").write_text("{}")),
    "link_to_home": lambda out: (out / "home").symlink_to(Path.home()),
    "own_name_linked": lambda out: ((out / "comfort.csv").unlink(), (out / "comfort.csv").symlink_to("/etc/hostname")),
    "video_left": lambda out: (out / "left.avi").write_bytes(b"RIFF"),
}


@pytest.mark.parametrize("plant", FOREIGN.values(), ids=[f"clear-analyze-{k}" for k in FOREIGN])
def test_analyze_target_with_foreign_content_is_refused_and_kept(tmp_path, plant):
    out = tmp_path / "out"
    earlier_results(out)
    plant(out)
    before = snapshot(out)
    with pytest.raises(StoreError, match=r"also holds what no horsemocap run wrote \(.+\).*would delete it"):
        check_results_target(out)
    with pytest.raises(StoreError):
        RunFolder(out)
    assert snapshot(out) == before


@pytest.mark.parametrize("plant", list(FOREIGN.values())[:8], ids=[f"clear-kinematics-{k}" for k in list(FOREIGN)[:8]])
def test_kinematics_target_with_foreign_content_is_refused_and_kept(tmp_path, plant, capsys):
    traj, static = record_files(tmp_path / "in")
    out = tmp_path / "out"
    earlier_results(out, "kinematics")
    plant(out)
    before = snapshot(out)
    code, _, err = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    assert code == 2 and "no horsemocap run wrote" in one_line_error(err)
    assert snapshot(out) == before


OWN = {
    "analysis_only": ["analysis.json"],
    "every_file": ["analysis.json", "quality.json", "report.html", "rig.toml", "calibration.json", "markers_2d.csv",
                   "markers_3d.csv", "trajectories.csv", "kinematics.csv", "angular.csv", "comfort.csv",
                   "comfort.xlsx"],
    "partial": ["PARTIAL.txt", "rig.toml"],
    "notebook_store": ["analysis.json", "choices.json", "steps/detect.json", "steps/detect.npz"],
}


@pytest.mark.parametrize("files", OWN.values(), ids=[f"correct-replaceable-{k}" for k in OWN])
def test_a_folder_of_a_runs_own_files_may_be_replaced(tmp_path, files):
    out = tmp_path / "out"
    out.mkdir()
    for name in files:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(json.dumps({"format": "horsemocap-results/1"}) if name == "analysis.json" else "x")
    assert check_results_target(out) == out.resolve()
    folder = RunFolder(out)
    with folder as tmp:
        (tmp / "analysis.json").write_text(json.dumps({"format": "horsemocap-results/1", "new": True}))
        folder.commit()
    assert sorted(p.name for p in out.iterdir()) == ["analysis.json"]
    assert json.loads((out / "analysis.json").read_text())["new"] is True


@pytest.mark.parametrize("depth", [0, 1, 2], ids=[f"clear-session-inside-out-depth{d}" for d in (0, 1, 2)])
def test_a_session_inside_an_earlier_results_folder_given_as_out_is_kept(tmp_path, depth, session_json, capsys):
    out = tmp_path / "results"
    earlier_results(out)
    where = out.joinpath(*[f"sub{i}" for i in range(depth)]) / "horse"
    session = light_session(where, session_json)
    before = snapshot(out)
    code, _, err = run(["analyze", session, "--out", out], capsys)
    line = one_line_error(err)
    assert code == 2 and "session.json" in line and "would delete it" in line
    assert snapshot(out) == before and (session / "session.json").is_file()


def test_correct_kinematics_replaces_its_own_earlier_output(tmp_path, capsys):
    traj, static = record_files(tmp_path / "in")
    out = tmp_path / "out"
    earlier_results(out, "kinematics")
    code, _, err = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["angular.csv", "kinematics-run.json", "kinematics.csv",
                                                    "trajectories.csv"]


def _sleeper():
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])


STALE = {  # name of a folder beside out -> kept?
    "dead_pid": (lambda pid: ".out.run-999999-deadbeef", False),
    "dead_pid_old_style": (lambda pid: ".out.run-999998-dead", False),
    "old_of_swap": (lambda pid: ".out.run-old-0123abcd", False),
    "live_pid": (lambda pid: f".out.run-{pid}-0123abcd", True),
    "other_folder_out_run_1": (lambda pid: ".out.run-1.run-999999-0123abcd", True),
    "other_folder_prefix": (lambda pid: ".out.run-999999-ab.run-999999-cd", True),
    "unrelated_name": (lambda pid: ".out.runaway", True),
}


@pytest.mark.parametrize("name,kept", STALE.values(), ids=[f"correct-cleanup-{k}" for k in STALE])
def test_the_cleanup_removes_only_dead_runs_temporary_folders(tmp_path, name, kept):
    live = _sleeper()
    try:
        folder = tmp_path / name(live.pid)
        folder.mkdir()
        (folder / "analysis.json").write_text("{}")
        with RunFolder(tmp_path / "out") as tmp:
            (tmp / "analysis.json").write_text(json.dumps({"format": "horsemocap-results/1"}))
        assert folder.exists() == kept
    finally:
        live.kill()
        live.wait()


# ---------------------------------------------------------------------------
# 2. the notebooks' store
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("where", ["first", "middle", "three_quarters", "last"],
                         ids=lambda w: f"correct-key-byte-{w}")
def test_the_key_changes_with_any_byte_with_size_and_mtime_kept(tmp_path, where):
    path = tmp_path / "video.avi"
    data = bytearray(os.urandom(5 << 20))
    path.write_bytes(bytes(data))
    st = path.stat()
    before = fingerprint.file_fingerprint(path)
    at = {"first": 0, "middle": len(data) // 2, "three_quarters": 3 * len(data) // 4, "last": len(data) - 1}[where]
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))     # size and modification time kept
    assert path.stat().st_size == st.st_size and path.stat().st_mtime_ns == st.st_mtime_ns
    assert fingerprint.file_fingerprint(path) != before


def test_correct_the_key_is_stable_for_unchanged_files(tmp_path):
    path = tmp_path / "a.bin"
    path.write_bytes(os.urandom(3 << 20))
    assert fingerprint.file_fingerprint(path) == fingerprint.file_fingerprint(path)
    fingerprint._DIGESTS.clear()
    assert fingerprint.file_fingerprint(path) == fingerprint.file_fingerprint(path)


def test_correct_store_steps_match_the_pipeline():
    assert tuple(name for name, _ in STEP_RESULT_FILES) == STEPS


def _filled_store(root: Path) -> ResultsStore:
    """A store with every step saved and every result file present."""
    store = ResultsStore(root)
    for name, files in STEP_RESULT_FILES:
        store.save(name, {"value": np.arange(3.0)}, f"key-{name}")
    for name, files in STEP_RESULT_FILES:
        for f in files:
            (root / f).write_text("earlier")
    for f in ("analysis.json", "quality.json", "report.html"):
        (root / f).write_text("earlier")
    return store


@pytest.mark.parametrize("step", STEPS, ids=lambda s: f"correct-rerun-{s}-removes-later-files")
def test_a_step_computed_anew_removes_the_later_steps_files(tmp_path, step):
    store = _filled_store(tmp_path / "res")
    names = [n for n, _ in STEP_RESULT_FILES]
    store.save(step, {"value": np.arange(4.0)}, "new-key")
    for name, files in STEP_RESULT_FILES:
        later = names.index(name) > names.index(step)
        assert (store.load(name, f"key-{name}") is None) == (later or name == step)
        for f in files:
            assert (store.root / f).exists() == (not later), f
    assert not (store.root / "quality.json").exists() and not (store.root / "report.html").exists()
    assert store.load(step, "new-key")["value"].tolist() == [0.0, 1.0, 2.0, 3.0]


@pytest.mark.parametrize("until", ["detect", "smooth", "rigid_body"],
                         ids=lambda s: f"correct-reuse-until-{s}-removes-later-files-of-other-parameters")
def test_nothing_recomputed_still_leaves_no_later_file_of_other_parameters(tmp_path, until):
    """A run up to ``until`` that reuses every stored step (another comfort setting, say) keeps a later
    step's files only where its stored result carries the key this run's parameters give it."""
    store = _filled_store(tmp_path / "res")
    names = [n for n, _ in STEP_RESULT_FILES]
    keys = {name: f"key-{name}" for name in names}
    assert store.forget_stale(keys, until) == []          # the same parameters: every later file is this run's
    assert (store.root / "comfort.csv").exists() and (store.root / "report.html").exists()
    keys["comfort"] = "key-comfort-other-weighting"
    removed = {p.name for p in store.forget_stale(keys, until)}
    assert removed == {"comfort.json", "comfort.npz", "comfort.csv", "comfort.xlsx", "quality.json", "report.html"}
    later = names[names.index(until) + 1:]
    for name, files in STEP_RESULT_FILES:
        assert (store.load(name, f"key-{name}") is None) == (name == "comfort"), name
        for f in files:
            assert (store.root / f).exists() == (name != "comfort"), f
    assert "rigid_body" not in later or (store.root / "kinematics.csv").exists()


def test_correct_a_later_file_without_its_stored_result_is_removed(tmp_path):
    store = _filled_store(tmp_path / "res")
    (store.root / "steps" / "triangulate.json").unlink()            # markers_3d.csv now of unknown origin
    keys = {name: f"key-{name}" for name, _ in STEP_RESULT_FILES}
    removed = {p.name for p in store.forget_stale(keys, "detect")}
    assert removed == {"triangulate.npz", "markers_3d.csv", "quality.json", "report.html"}
    assert (store.root / "comfort.csv").exists() and (store.root / "markers_2d.csv").exists()


LINKS = {
    "steps_folder": lambda root, away: (root.mkdir(), (root / "steps").symlink_to(away)),
    "step_json": lambda root, away: ((root / "steps").mkdir(parents=True),
                                     (root / "steps" / "detect.json").symlink_to(away / "x.json")),
    "step_npz": lambda root, away: ((root / "steps").mkdir(parents=True),
                                    (root / "steps" / "detect.npz").symlink_to(away / "x.npz")),
    "results_folder": lambda root, away: root.symlink_to(away),
}


@pytest.mark.parametrize("plant", LINKS.values(), ids=[f"clear-store-link-{k}" for k in LINKS])
@pytest.mark.parametrize("action", ["save", "load"])
def test_the_store_follows_no_link_out_of_itself(tmp_path, plant, action):
    away = tmp_path / "elsewhere"
    away.mkdir()
    root = tmp_path / "res"
    plant(root, away)
    store = ResultsStore(root)
    with pytest.raises(StoreError, match="symbolic link"):
        store.save("detect", {"v": 1}, "k") if action == "save" else store.load("detect", "k")
    assert list(away.iterdir()) == []


def test_clear_a_planted_link_for_the_sessions_results_folder(tmp_path, monkeypatch):
    from horsemocap.workspace import notebook_results_dir

    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path / "store"))
    real = notebook_results_dir(BUNDLED)
    real.parent.mkdir(parents=True)
    (tmp_path / "away").mkdir()
    real.symlink_to(tmp_path / "away")
    with pytest.raises(StoreError, match="symbolic link"):
        notebook_results_dir(BUNDLED)


CHOICES = {"a": [("smooth.span", 0.07), ("rigid_body.fits.x_degree", 2), ("detect.cameras.left.threshold", 140),
                 ("detect.cameras.middle.threshold", 141), ("detect.cameras.right.threshold", 142),
                 ("motion_frame.n_periods", 2)],
           "b": [("detect.cameras.left.area_min", 3.0), ("detect.cameras.middle.area_min", 4.0),
                 ("detect.cameras.right.area_min", 5.0), ("detect.cameras.all.min_circularity", 0.4),
                 ("detect.max_gap_frames", 3), ("motion_frame.x_marker", 1)]}


def _choose_many(store_root: str, who: str, start) -> None:
    os.environ["HORSEMOCAP_RESULTS"] = store_root
    from horsemocap.workspace import set_choice

    start.wait()
    for name, value in CHOICES[who]:
        set_choice(BUNDLED, name, value)


@pytest.mark.parametrize("round_", range(3), ids=lambda r: f"correct-two-kernels-choose-at-once-{r}")
def test_two_processes_choosing_at_once_lose_nothing(tmp_path, round_, monkeypatch):
    ctx = multiprocessing.get_context("fork")
    start = ctx.Event()
    procs = [ctx.Process(target=_choose_many, args=(str(tmp_path), who, start)) for who in CHOICES]
    for p in procs:
        p.start()
    start.set()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path))
    from horsemocap.workspace import get_choice

    for name, value in CHOICES["a"] + CHOICES["b"]:
        assert get_choice(BUNDLED, name) == value, name


# ---------------------------------------------------------------------------
# 3. kinematics and export: units, time step, magnitudes, verdict
# ---------------------------------------------------------------------------

UNIT_CASES = {
    "millimetres": (dict(scale=1000.0), "look like millimetres"),
    "centimetres": (dict(scale=100.0), "not metres"),
    "kilometres": (dict(scale=0.001), "kilometres or other units"),
    "static_in_mm_record_in_m": (dict(static_scale=1000.0), "look like millimetres"),
    "record_in_mm_static_in_m": (dict(scale=1000.0, static_scale=1.0), "look like millimetres"),
    "static_in_cm_record_in_m": (dict(static_scale=3.0), "different units"),
    "time_in_ms": (dict(time_scale=1000.0), "a time column in milliseconds"),
    "time_in_ms_30hz": (dict(rate=30.0, time_scale=1000.0), "a time column in milliseconds"),
    "time_in_us": (dict(time_scale=1e6), "a time column in milliseconds"),
    "time_in_hours": (dict(time_scale=1 / 3600), "a time column in other units"),
}


@pytest.mark.parametrize("kwargs,text", UNIT_CASES.values(), ids=[f"clear-kinematics-{k}" for k in UNIT_CASES])
def test_kinematics_refuses_wrong_units_or_time_column(tmp_path, kwargs, text, capsys):
    traj, static = record_files(tmp_path / "in", **kwargs)
    out = tmp_path / "out"
    code, stdout, err = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    line = one_line_error(err)
    assert code == 2 and text in line and ("traj.csv" in line or "static.csv" in line), line
    assert not out.exists() and "results:" not in stdout


def _set_point(frame, point, axis, value):
    def edit(pts):
        pts[frame, point, axis] = value
    return edit


HUGE = {f"{v}_f{f}_p{p}_{'xyz'[a]}": (v, f, p, a) for v, f, p, a in [
    (1e300, 0, 0, 0), (1e300, 17, 1, 2), (-1e300, 39, 2, 1), (1e7, 5, 0, 1), (-5e6, 20, 2, 0), (1e200, 3, 1, 0)]}


@pytest.mark.parametrize("value,frame,point,axis", HUGE.values(), ids=[f"clear-kinematics-huge-{k}" for k in HUGE])
def test_kinematics_refuses_a_coordinate_beyond_any_body_naming_point_and_frame(tmp_path, value, frame, point, axis,
                                                                                 capsys):
    traj, static = record_files(tmp_path / "in", edit=_set_point(frame, point, axis, value))
    code, _, err = run(["kinematics", traj, "--static", static, "--out", tmp_path / "out"], capsys)
    line = one_line_error(err)
    assert code == 2 and f"point '{'abc'[point]}', frame {frame}" in line and f"'{'xyz'[axis]}_m'" in line, line
    assert "beyond any position of a body" in line and not (tmp_path / "out").exists()


@pytest.mark.parametrize("text", ["1e300", "inf", "-Infinity", "1e309"], ids=lambda t: f"clear-static-shot-{t}")
def test_kinematics_refuses_a_static_shot_coordinate_beyond_any_body(tmp_path, text, capsys):
    traj, static = record_files(tmp_path / "in")
    static.write_text(static.read_text().replace("0.3,0.0,0.0", f"{text},0.0,0.0", 1))
    code, _, err = run(["kinematics", traj, "--static", static, "--out", tmp_path / "out"], capsys)
    line = one_line_error(err)
    assert code == 2 and "static.csv" in line and "x_m" in line, line


@pytest.mark.parametrize("speed", [60.0, 400.0], ids=lambda s: f"flagged-kinematics-speed-{s:g}mps")
def test_kinematics_flags_speeds_no_body_reaches(tmp_path, speed, capsys):
    traj, static = record_files(tmp_path / "in", speed=speed)
    out = tmp_path / "out"
    code, stdout, err = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    assert code == 3, err
    assert "quality: UNRELIABLE" in stdout and "marker_speed" in stdout and "UNRELIABLE (exit status 3)" in err
    quality = json.loads((out / "kinematics-run.json").read_text())["quality"]
    assert quality["verdict"] == "unreliable"
    levels = {c["name"]: c["level"] for c in quality["checks"]}
    assert levels["marker_speed"] == "unreliable" and levels["raw_marker_speed"] == "warning"


def test_flagged_kinematics_an_acceleration_no_body_reaches(tmp_path, capsys):
    t = np.arange(200) / 1000.0

    def edit(pts):      # a 50 Hz shake of 2 cm: 6 m/s, but 2000 m/s² (200 g)
        pts[:, :, 2] += 0.02 * np.sin(2 * np.pi * 50 * t)[:, None]
    traj, static = record_files(tmp_path / "in", rate=1000.0, n=200, edit=edit)
    out = tmp_path / "out"
    code, stdout, _ = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    assert code == 3 and "unreliable: marker_acceleration" in stdout
    levels = {c["name"]: c["level"] for c in json.loads((out / "kinematics-run.json").read_text())["quality"]["checks"]}
    assert levels == {"raw_marker_speed": "ok", "marker_speed": "ok", "marker_acceleration": "unreliable",
                      "time_grid": "ok"}


def test_flagged_kinematics_raw_jitter_the_smoothing_removes(tmp_path, capsys):
    def edit(pts):
        pts[::2] += np.array([0.0, 0.05, 0.0])      # every second frame 5 cm aside at 1000 Hz: 50 m/s raw
    traj, static = record_files(tmp_path / "in", rate=1000.0, n=60, edit=edit)
    out = tmp_path / "out"
    code, stdout, _ = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    assert code == 0 and "quality: WARNING" in stdout and "warning: raw_marker_speed" in stdout
    assert json.loads((out / "kinematics-run.json").read_text())["quality"]["verdict"] == "warning"


def test_flagged_kinematics_times_off_the_rate_grid(tmp_path, capsys):
    traj, static = record_files(tmp_path / "in", n=40)
    rows = traj.read_text().splitlines()
    rows[1 + 3 * 20: 1 + 3 * 21] = [r.replace(",0.2,", ",0.205,", 1) for r in rows[1 + 3 * 20: 1 + 3 * 21]]
    traj.write_text("\n".join(rows) + "\n")
    code, stdout, _ = run(["kinematics", traj, "--static", static, "--out", tmp_path / "out"], capsys)
    assert code == 0 and "warning: time_grid" in stdout and "off the 100 Hz grid by up to 0.5 frame" in stdout


@pytest.mark.parametrize("rate", [50.0, 100.0, 200.0], ids=lambda r: f"correct-kinematics-healthy-{r:g}hz")
def test_kinematics_healthy_records_pass_every_check(tmp_path, rate, capsys):
    traj, static = record_files(tmp_path / "in", rate=rate)
    out = tmp_path / "out"
    code, stdout, err = run(["kinematics", traj, "--static", static, "--out", out], capsys)
    assert code == 0, err
    assert "quality: OK" in stdout
    record = json.loads((out / "kinematics-run.json").read_text())
    assert record["quality"]["verdict"] == "ok" and record["input"]["rate_hz"] == pytest.approx(rate)


EXPORT_RATES = {  # rate given, times' rate, accepted?
    "contradicts_100_on_30": (100.0, 30.0, False),
    "contradicts_30_on_100": (30.0, 100.0, False),
    "contradicts_120_on_100": (120.0, 100.0, False),
    "contradicts_101_on_100": (101.0, 100.0, False),
    "agrees_100": (100.0, 100.0, True),
    "agrees_30": (30.0, 30.0, True),
    "within_a_thousandth": (100.05, 100.0, True),
}


@pytest.mark.parametrize("given,actual,accepted", EXPORT_RATES.values(),
                         ids=[f"{'correct' if v[2] else 'clear'}-export-{k}" for k, v in EXPORT_RATES.items()])
@pytest.mark.parametrize("ext", ["trc", "c3d"])
def test_export_refuses_a_rate_the_times_contradict(tmp_path, given, actual, accepted, ext, capsys):
    traj, _ = record_files(tmp_path / "in", rate=actual, n=12)
    out = tmp_path / f"x.{ext}"
    code, _, err = run(["export", traj, "--out", out, "--rate", given], capsys)
    if accepted:
        assert code == 0 and out.is_file(), err
    else:
        line = one_line_error(err)
        assert code == 2 and f"--rate {given:g} Hz contradicts the times" in line and f"({actual:g} Hz)" in line
        assert not out.exists()


# ---------------------------------------------------------------------------
# 4. parameters: every range checked at the start, naming the field
# ---------------------------------------------------------------------------

NUMERIC = [f for f in params_fields() if f.kind in ("int", "number")]
BAD_NUMBERS = ["NaN", "Infinity", "-Infinity", "1e400", "-1e400", '"x"', "true"]


@pytest.mark.parametrize("field", NUMERIC, ids=lambda f: f.path)
@pytest.mark.parametrize("text", BAD_NUMBERS, ids=lambda t: f"clear-set-{t}")
def test_set_refuses_a_value_outside_the_fields_range(field, text):
    with pytest.raises(ParamsError, match=rf"parameter '{field.path}'.*expected"):
        _set_param(AnalysisParams(), f"{field.path}={text}")


@pytest.mark.parametrize("field", [f for f in NUMERIC if f.range and f.range[0] is not None],
                         ids=lambda f: f"clear-set-below-range-{f.path}")
def test_set_refuses_a_value_below_the_range(field):
    with pytest.raises(ParamsError, match=rf"parameter '{field.path}'"):
        _set_param(AnalysisParams(), f"{field.path}={field.range[0] - 1}")


DETECTOR = {
    "distance_tolerance_1e400": ("distance_tolerance", "1e400"),
    "distance_tolerance_nan": ("distance_tolerance", "NaN"),
    "distance_tolerance_zero": ("distance_tolerance", "0"),
    "distance_tolerance_text": ("distance_tolerance", '"ten"'),
    "first_frame_text": ("first_frame", '"x"'),
    "first_frame_negative": ("first_frame", "-1"),
    "first_frame_fraction": ("first_frame", "1.5"),
    "first_frame_bool": ("first_frame", "true"),
    "threshold_nan": ("threshold", "NaN"),
    "threshold_255": ("threshold", "255"),
    "threshold_bool": ("threshold", "true"),
    "area_min_negative": ("area_min", "-1"),
    "area_min_text": ("area_min", '"x"'),
    "area_max_zero": ("area_max", "0"),
    "area_max_inf": ("area_max", "Infinity"),
    "min_circularity_2": ("min_circularity", "2"),
    "min_circularity_negative": ("min_circularity", "-0.5"),
    "window_predict_number": ("window_predict", "3"),
    "window_zero": ("window", "[0, 10]"),
}


@pytest.mark.parametrize("name,text", DETECTOR.values(), ids=[f"clear-set-detector-{k}" for k in DETECTOR])
@pytest.mark.parametrize("cam", ["all", "left"])
def test_set_refuses_a_detector_value_naming_it(name, text, cam):
    with pytest.raises(ParamsError, match=rf"detect.cameras.{cam}"):
        _set_param(AnalysisParams(), f"detect.cameras.{cam}.{name}={text}")


def test_clear_set_1e400_tolerance_on_the_command_line_ends_before_the_run(tmp_path, capsys):
    code, _, err = run(["analyze", BUNDLED, "--out", tmp_path / "out", "--set",
                        "detection.all.distance_tolerance=1e400"], capsys)
    line = one_line_error(err)
    assert code == 2 and "distance_tolerance" in line and not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------
# 5. session.json: new optional fields, depth; a frames folder of mixed sizes
# ---------------------------------------------------------------------------

NEW_FIELDS = {"operator": "A. Rider", "saddle_model": {"maker": "x"}, "x_vendor": [1, 2], "recorded": "2009-05-01",
              "weather": None, "horse_id": 7}


@pytest.mark.parametrize("key,value", NEW_FIELDS.items(), ids=[f"flagged-session-new-field-{k}" for k in NEW_FIELDS])
def test_a_new_top_level_field_is_read_with_a_warning(tmp_path, session_json, key, value):
    session = light_session(tmp_path / "s", {**session_json, key: value})
    with pytest.warns(SessionWarning, match=rf"field '{key}' is not one this version"):
        loaded = load_session(session, open_sources=False)
    assert loaded.name == session_json["name"]


def test_flagged_session_new_field_is_one_line_on_the_command_line(tmp_path, session_json, capsys):
    session = light_session(tmp_path / "s", {**session_json, "operator": "A. Rider"})
    code, _, err = run(["analyze", session, "--out", tmp_path / "out", "--set", "smooth.span=7"], capsys)
    warned = [ln for ln in err.splitlines() if "field 'operator'" in ln]
    assert code == 2 and len(warned) == 1, err
    assert warned[0].startswith("horsemocap: warning: ") and "SessionWarning" not in err
    assert "warnings.warn(" not in err and "session.py" not in err


@pytest.mark.parametrize("key", ["fsp", "marker", "camera", "calibraton"], ids=lambda k: f"clear-session-typo-{k}")
def test_a_misspelled_top_level_field_is_still_refused(tmp_path, session_json, key):
    session = light_session(tmp_path / "s", {**session_json, key: 1})
    with pytest.raises(SessionError, match=rf"unknown field '{key}'; did you mean"):
        load_session(session, open_sources=False)


@pytest.mark.parametrize("depth", [2000, 100_000], ids=lambda d: f"clear-session-nested-{d}")
@pytest.mark.parametrize("where", ["top", "metadata"])
def test_a_deeply_nested_session_json_gives_a_clear_error(tmp_path, depth, where):
    folder = tmp_path / "s"
    folder.mkdir()
    deep = "[" * depth + "]" * depth
    text = deep if where == "top" else '{"metadata": ' + deep + "}"
    (folder / "session.json").write_text(text)
    with pytest.raises(SessionError, match="session.json: JSON nested too deeply"):
        load_session(folder, open_sources=False)


@pytest.mark.parametrize("odd", [0, 3, 7], ids=lambda i: f"clear-frames-folder-size-at-{i}")
def test_a_frames_folder_image_of_another_size_names_the_file(tmp_path, odd):
    folder = tmp_path / "left"
    folder.mkdir()
    for i in range(8):
        shape = (40, 50) if i == odd and odd else (32, 48)
        cv2.imwrite(str(folder / f"f{i:03d}.png"), np.full(shape, 100, np.uint8))
    if odd == 0:   # the first image is the odd one: the second is named against it
        cv2.imwrite(str(folder / "f000.png"), np.full((40, 50), 100, np.uint8))
        odd = 1
    with pytest.raises(SourceError, match=rf"f{odd:03d}.png: image of .* pixels, but f000.png of the same camera"):
        FrameSource(folder).read()


@pytest.fixture(scope="module")
def bundled_session():
    return load_session(BUNDLED)


@pytest.mark.parametrize("cam,first,accepted", [("all", 100_000, False), ("left", 100_000, False), ("all", 76, False),
                                                ("right", 76, False), ("all", 75, True), ("middle", 0, True)],
                         ids=["clear-first-frame-all-100000", "clear-first-frame-left-100000", "clear-first-frame-all-76",
                              "clear-first-frame-right-76", "correct-first-frame-all-75", "correct-first-frame-middle-0"])
def test_first_frame_within_the_sessions_frames(bundled_session, cam, first, accepted):
    params = AnalysisParams().updated({"detect.cameras": {cam: {"first_frame": first}}})
    if accepted:
        params.check_session(bundled_session)
    else:
        with pytest.raises(ParamsError, match=rf"'detect.cameras.{cam}.first_frame': expected a frame index "
                                              rf"0..75 .*got {first}"):
            params.check_session(bundled_session)


def test_clear_first_frame_beyond_the_frames_on_the_command_line(tmp_path, capsys):
    code, _, err = run(["analyze", BUNDLED, "--out", tmp_path / "out", "--set",
                        "detect.cameras.all.first_frame=100000"], capsys)
    line = one_line_error(err)
    assert code == 2 and "first_frame" in line and "0..75" in line and not (tmp_path / "out").exists()


@pytest.mark.parametrize("depth", [2000, 100_000], ids=lambda d: f"clear-params-file-nested-{d}")
def test_a_deeply_nested_params_file_gives_a_clear_error(tmp_path, depth, capsys):
    params = tmp_path / "choices.json"
    params.write_text('{"parameters": {"smooth": ' + "[" * depth + "]" * depth + "}}")
    code, _, err = run(["analyze", BUNDLED, "--out", tmp_path / "out", "--params", params], capsys)
    line = one_line_error(err)
    assert code == 2 and "choices.json: JSON nested too deeply" in line and not (tmp_path / "out").exists()


def test_correct_notebooks_folder_after_an_earlier_step_changed_holds_no_later_file(tmp_path, monkeypatch):
    """The one case that runs the analysis (the bundled session, about 15 s): the issue's mixed folder."""
    from horsemocap.workspace import notebook_results_dir, results_for

    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path / "store"))
    results_for(BUNDLED, until="comfort")
    folder = notebook_results_dir(BUNDLED)
    assert (folder / "comfort.csv").is_file() and (folder / "trajectories.csv").is_file()
    results_for(BUNDLED, until="detect", params={"detect": {"cameras": {"all": {"min_circularity": 0.3}}}})
    files = sorted(p.name for p in folder.iterdir())
    assert files == ["analysis.json", "calibration.json", "markers_2d.csv", "rig.toml", "steps"]
    assert json.loads((folder / "analysis.json").read_text())["steps_done"][-1] == "detect"
    assert not any(p.name.startswith(("triangulate", "smooth", "rigid_body", "comfort"))
                   for p in (folder / "steps").iterdir())


def test_correct_notebooks_folder_reusing_every_step_holds_no_later_file_of_other_parameters(tmp_path, monkeypatch):
    """A stored detect result reused with another comfort setting: nothing is recomputed, and the
    earlier comfort.csv (of the other setting) is not left beside the new analysis.json."""
    from horsemocap.workspace import notebook_results_dir, results_for

    monkeypatch.setenv("HORSEMOCAP_RESULTS", str(tmp_path / "store"))
    results_for(BUNDLED, until="comfort")
    folder = notebook_results_dir(BUNDLED)
    results_for(BUNDLED, until="detect")                              # the same parameters: the files stay
    assert (folder / "comfort.csv").is_file() and (folder / "trajectories.csv").is_file()
    results_for(BUNDLED, until="detect", params={"comfort": {"weighting_mode": "thesis"}})
    files = sorted(p.name for p in folder.iterdir())
    assert "comfort.csv" not in files and "quality.json" not in files and "report.html" not in files
    assert "trajectories.csv" in files and "markers_2d.csv" in files   # steps whose key did not change
    assert not (folder / "steps" / "comfort.json").exists()


# ---------------------------------------------------------------------------
# exchanged inputs: the identification's failure names the offsets and the videos
# ---------------------------------------------------------------------------

BUNDLED_FLASH = {"left": 8, "middle": 61, "right": 134}       # the flash's frames in the bundled videos

EXCHANGED = {
    "offsets-left-middle": ({"sync": {"offsets": {"left": 61, "middle": 8, "right": 134}}},
                            r"disagree with the flash, found at frames \{'left': 8, 'middle': 61, 'right': 134\}; "
                            r"the offsets of cameras 'left' and 'middle' look exchanged"),
    "videos-left-middle-offsets-given": ({"motion": {"left": "motion/middle.avi", "middle": "motion/left.avi",
                                                     "right": "motion/right.avi"},
                                          "sync": {"offsets": BUNDLED_FLASH}},
                                         r"the offsets of cameras 'left' and 'middle' look exchanged.*"
                                         r"'motion' \(left: middle.avi, middle: left.avi, right: right.avi\)"),
    "videos-left-right-flash": ({"motion": {"left": "motion/right.avi", "middle": "motion/middle.avi",
                                            "right": "motion/left.avi"}},
                                r"'motion' \(left: right.avi, middle: middle.avi, right: left.avi\).*"
                                r"videos or offsets exchanged"),
}


@pytest.mark.parametrize("change,message", EXCHANGED.values(), ids=[f"clear-exchanged-{k}" for k in EXCHANGED])
def test_exchanged_offsets_or_videos_are_named(tmp_path, session_json, change, message):
    from horsemocap.pipeline import analyze
    from horsemocap.steps import AnalysisError

    session = light_session(tmp_path / "s", {**session_json, **change})
    with pytest.raises(AnalysisError, match=message) as err:
        analyze(session, None, until="detect", progress=lambda *a: None)
    assert "detect" in str(err.value)


def test_clear_exchanged_offsets_past_a_video_end_name_the_offset(tmp_path, session_json):
    from horsemocap.pipeline import analyze

    session = light_session(tmp_path / "s", {**session_json, "sync": {"offsets": {"left": 8, "middle": 134,
                                                                                  "right": 61}}})
    with pytest.raises(SessionError, match=r"camera 'middle' has 129 frames, but its sync offset is frame 134.*"
                                           r"'sync.offsets' in .*session.json"):
        analyze(session, None, until="detect", progress=lambda *a: None)
