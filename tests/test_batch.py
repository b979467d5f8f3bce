"""horsemocap batch: sessions side by side, one table, resumable after SIGKILL; the user-level board cache."""
import io
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from horsemocap import batch
from horsemocap.calibration import cache
from horsemocap.calibration.board import views_from_corners
from horsemocap.camera import Camera, Rig
from horsemocap.data import default_session_dir
from horsemocap.run import run_analysis

REPO = Path(__file__).resolve().parents[1]


def _fake_session(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "session.json").write_text("{}")
    return folder


def test_sessions_are_found_in_folders_folders_of_sessions_and_list_files(tmp_path):
    a = _fake_session(tmp_path / "herd" / "walk")
    b = _fake_session(tmp_path / "herd" / "canter")
    c = _fake_session(tmp_path / "other" / "walk")
    (tmp_path / "list.txt").write_text("# the season\nother/walk\n\nherd/walk  # again\n")
    found = batch.find_sessions([tmp_path / "herd", tmp_path / "list.txt"])
    assert found == [b, a, tmp_path / "other" / "walk"]            # each once, in order
    assert batch.result_names(found) == ["canter", "walk", "walk-2"]
    assert batch.result_names([c, Path("x/sessions.csv"), Path("y/a b")]) == ["walk", "sessions.csv-2", "a_b"]
    with pytest.raises(batch.BatchError, match="line 1"):
        (tmp_path / "bad.txt").write_text("nowhere\n")
        batch.find_sessions([tmp_path / "bad.txt"])
    with pytest.raises(batch.BatchError, match="not found"):
        batch.find_sessions([tmp_path / "missing"])


def test_the_progress_line_counts_and_estimates_the_time_left():
    out = io.StringIO()
    p = batch.BatchProgress(5, 2, stream=out)
    p.finished({"exit_status": 0, "seconds": 10.0, "reused": False})
    p.finished({"exit_status": 2, "seconds": 0.1, "reused": False})
    assert p.line() == "batch: 2/5 done, 2 running, 1 failed, about 20 s left"   # 3 left on 2 workers: 2 rounds
    p.finished({"exit_status": 0, "seconds": float("nan"), "reused": True})
    assert p.line().startswith("batch: 3/5 done (1 reused), 2 running, 1 failed")


def test_scheduler_without_dask_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    session = _fake_session(tmp_path / "s")
    with pytest.raises(batch.BatchError, match=r"pip install horsemocap\[cluster\]"):
        batch.run_batch([session], tmp_path / "out", scheduler="tcp://127.0.0.1:8786")


def test_the_table_is_written_whole_and_read_back(tmp_path):
    rows = [{**batch._empty_row(batch.BatchTask(Path("s/a"), tmp_path / "a", "a")), "exit_status": 0,
             "seconds": 1.5, "verdict": "ok", "VDV_y_Wb": 4.599090786415252},
            {**batch._empty_row(batch.BatchTask(Path("s/b"), tmp_path / "b", "b")), "error": "bad, \"quoted\""}]
    path, _ = batch.write_table(tmp_path, rows)
    back = batch.read_table(path)
    assert back[0]["VDV_y_Wb"] == 4.599090786415252 and back[0]["exit_status"] == 0
    assert back[1]["error"] == 'bad, "quoted"' and np.isnan(back[1]["VDV_y_Wb"]) and back[1]["exit_status"] == 2


# ---------------------------------------------------------------------------
# the user-level board cache
# ---------------------------------------------------------------------------

def test_a_rig_calibrated_once_serves_copies_of_its_views(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.BOARD_CACHE_ENV, str(tmp_path / "boards"))
    seen = {"detect": 0, "calibrate": 0}
    rng = np.random.default_rng(1)

    def detect(image_dirs, inner, ticks=None, **kw):
        seen["detect"] += len(image_dirs)
        return {c: views_from_corners(c, rng.uniform(0, 600, (2, inner[0] * inner[1], 2)), (640, 480), inner,
                                      names=["00", "01"]) for c in image_dirs}

    def calibrate(image_dirs, inner, square_m, reference="left", views=None, **kw):
        seen["calibrate"] += 1
        cams = tuple(Camera(c, (640, 480), np.diag([800.0 + rng.random(), 800.0, 1.0]), np.zeros(5),
                            rng.normal(0, 0.1, 3), rng.normal(0, 1, 3)) for c in image_dirs)
        return SimpleNamespace(rig=Rig(cams, {"method": "fake"}))

    monkeypatch.setattr(cache, "detect_cameras", detect)
    monkeypatch.setattr(cache, "calibrate_rig", calibrate)
    sessions = []
    for name in ("one", "two"):
        dirs = {}
        for cam in ("left", "right"):
            d = tmp_path / name / cam
            d.mkdir(parents=True)
            for k in range(2):
                (d / f"{k:02d}.png").write_bytes(f"{cam} view {k}".encode())
            dirs[cam] = d
        sessions.append(dirs)
    rig1, _ = cache.cached_calibration(sessions[0], (3, 2), 0.05, "left", write_to=tmp_path / "r1")
    rig2, how = cache.cached_calibration(sessions[1], (3, 2), 0.05, "left", write_to=tmp_path / "r2")
    assert seen == {"detect": 2, "calibrate": 1} and "user-level" in how
    assert all(np.array_equal(a.matrix, b.matrix) for a, b in zip(rig1.cameras, rig2.cameras))
    assert cache.views_cached(sessions[1], (3, 2), [])                 # analyze starts no early detection
    cache.cached_calibration(sessions[1], (3, 2), 0.06, "left")         # another square: the corners reused
    assert seen == {"detect": 2, "calibrate": 2}
    (sessions[1]["right"] / "01.png").write_bytes(b"another view")     # another view: that camera detected
    cache.cached_calibration(sessions[1], (3, 2), 0.05, "left")
    assert seen == {"detect": 3, "calibrate": 3}
    monkeypatch.setenv(cache.BOARD_CACHE_ENV, "off")
    cache.cached_calibration(sessions[0], (3, 2), 0.05, "left")
    assert seen == {"detect": 5, "calibrate": 4}


# ---------------------------------------------------------------------------
# a real batch killed with SIGKILL, then run again
# ---------------------------------------------------------------------------

def _table_names(path: Path) -> list:
    return [r["name"] for r in batch.read_table(path)] if path.is_file() else []


def test_a_session_analysed_again_replaces_its_batch_results_folder(tmp_path):
    """A batch's results folder (its record batch.json, a long recording's passes.csv) is a run's own:
    when the session or the parameters change, the batch analyses it again into the same folder."""
    from horsemocap.runfolder import check_results_target
    from horsemocap.store import StoreError

    folder = tmp_path / "horse1_walk"
    folder.mkdir()
    (folder / "analysis.json").write_text('{"format": "horsemocap-results/1"}')
    for name in (batch.BATCH_FILE, "passes.csv", "comfort.csv"):
        (folder / name).write_text("written by a run")
    assert check_results_target(folder) == folder.resolve()
    (folder / "notes.txt").write_text("a user's file")
    with pytest.raises(StoreError, match="notes.txt"):
        check_results_target(folder)


def test_a_batch_killed_with_sigkill_finishes_only_the_rest(tmp_path, monkeypatch):
    sessions = tmp_path / "sessions"
    for k in (1, 2, 3):
        shutil.copytree(default_session_dir(), sessions / f"canter {k}")
    broken = sessions / "broken"
    broken.mkdir()
    (broken / "session.json").write_text('{"format": "horsemocap-session/1"}')
    out = tmp_path / "out"
    monkeypatch.setenv(cache.BOARD_CACHE_ENV, str(tmp_path / "boards"))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "horsemocap.cli", "batch", str(sessions), "--out", str(out), "--workers", "2"]
    proc = subprocess.Popen(command, env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    deadline = time.monotonic() + 600
    while not any(n.startswith("canter") for n in _table_names(out / batch.TABLE_CSV)):
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read().decode()
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)                  # the batch and its workers, mid-run
    proc.wait()
    proc.stdout.close(), proc.stderr.close()
    killed_table = _table_names(out / batch.TABLE_CSV)   # a valid table of the sessions finished
    finished = {p.parent.name for p in out.glob(f"*/{batch.BATCH_FILE}")}
    assert set(killed_table) - {"broken"} <= finished and finished < {"canter_1", "canter_2", "canter_3"}

    rerun = subprocess.run(command, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert rerun.returncode == 2, rerun.stderr                # a session failed (the broken one)
    rows = {r["name"]: r for r in batch.read_table(out / batch.TABLE_CSV)}
    assert list(rows) == ["broken", "canter_1", "canter_2", "canter_3"]
    assert {n for n, r in rows.items() if r["reused"]} == finished      # only the rest analysed again
    assert "required field 'name'" in rows["broken"]["error"] and rows["broken"]["exit_status"] == 2
    for name in ("canter_1", "canter_2", "canter_3"):
        r = rows[name]
        assert r["exit_status"] == 0 and r["error"] == "" and r["horse"] == "Horse 2" and r["gait"] == "canter"
        assert r["rider"] == "A" and r["direction"] == "CCW" and r["verdict"] in ("ok", "warning")
    assert "batch: 4/4 done" in rerun.stderr and f"{len(finished)} reused" in rerun.stderr

    alone = run_analysis(sessions / "canter 3", tmp_path / "alone", progress=lambda *a: None)   # as analyze
    expected = (alone.out / "comfort.csv").read_bytes()
    for name in ("canter_1", "canter_2", "canter_3"):
        assert (out / name / "comfort.csv").read_bytes() == expected
    assert rows["canter_3"]["VDV_y_Wb"] == alone.analysis.comfort.indicators["VDV_y_Wb"]


def test_the_herd_study_reads_a_batch_table(tmp_path):
    from horsemocap import herd

    rows = []
    for k, h in enumerate(herd.HORSES):
        task = batch.BatchTask(Path(f"s/{k}"), tmp_path / f"h{k}", f"h{k}")
        rows.append({**batch._empty_row(task), "horse": h, "gait": "canter", "exit_status": 0,
                     **{ind: float(k + 1) * (1 if ind != "TA_8_limit_Wb" else -1) for ind in herd.THESIS_INDICATORS}})
    rows.append({**batch._empty_row(batch.BatchTask(Path("s/x"), tmp_path / "x", "x")), "horse": "Horse 1",
                 "gait": "walk", "error": "failed"})
    path, _ = batch.write_table(tmp_path, rows)
    table = herd.table_indicators(path)
    assert set(table) == {(h, "canter") for h in herd.HORSES}           # the failed session left out
    assert table[("Horse 3", "canter")]["VDV_y_Wb"] == 3.0
    direct = {(r["horse"], r["gait"]): {i: r[i] for i in herd.THESIS_INDICATORS} for r in rows[:4]}
    assert [repr(c) for c in herd.compare(table)] == [repr(c) for c in herd.compare(direct)]   # (NaN: by repr)
    with pytest.raises(ValueError, match="both Horse 1, canter"):
        herd.table_indicators(rows[:4] + [{**rows[0], "name": "again"}])
