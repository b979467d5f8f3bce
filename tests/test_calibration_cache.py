"""The calibration kept in the results folder (horsemocap.calibration.cache, issue 16)."""
from types import SimpleNamespace

import numpy as np
import pytest

from horsemocap.calibration import cache, rig as rig_module
from horsemocap.calibration.board import views_from_corners
from horsemocap.camera import Camera, Rig

INNER = (3, 2)


@pytest.fixture(autouse=True)
def no_user_board_cache(monkeypatch):
    """These tests count the detections of the results folder's cache alone (the user-level one: test_batch.py)."""
    monkeypatch.setenv(cache.BOARD_CACHE_ENV, "off")


@pytest.fixture
def views_dirs(tmp_path):
    dirs = {}
    for cam in ("left", "right"):
        d = tmp_path / "session" / cam
        d.mkdir(parents=True)
        for k in range(3):
            (d / f"{k:02d}.png").write_bytes(f"{cam} view {k}".encode())
        dirs[cam] = d
    return dirs


@pytest.fixture
def calls(monkeypatch):
    """detect_cameras and calibrate_rig replaced by counting fakes with exact, distinct results."""
    seen = {"detect": [], "calibrate": 0}
    rng = np.random.default_rng(0)

    def detect(image_dirs, inner, window=None, ticks=None, workers=None):
        out = {}
        for camera in image_dirs:
            seen["detect"].append(camera)
            tick = (ticks or {}).get(camera)
            for k in range(3):
                if tick is not None:
                    tick(k + 1, 3)
            corners = rng.uniform(0, 600, (3, inner[0] * inner[1], 2))
            corners[1, 0] = np.nan                            # a view without the board
            out[camera] = views_from_corners(camera, corners, (640, 480), inner, names=["00", "01", "02"])
        return out

    def calibrate(image_dirs, inner, square_m, reference="left", views=None, **kw):
        seen["calibrate"] += 1
        seen["views"] = views
        cams = tuple(Camera(c, (640, 480), np.array([[800.0 + rng.random(), 0, 320], [0, 801, 240], [0, 0, 1]]),
                            rng.normal(0, 0.01, 5), rng.normal(0, 0.1, 3), rng.normal(0, 1, 3)) for c in image_dirs)
        return SimpleNamespace(rig=Rig(cams, {"error": 0.1 + rng.random(), "method": "fake"}))

    monkeypatch.setattr(cache, "detect_cameras", detect)
    monkeypatch.setattr(cache, "calibrate_rig", calibrate)
    return seen


def _same(a: Rig, b: Rig):
    assert a.names == b.names and a.metadata == b.metadata
    for x, y in zip(a.cameras, b.cameras):
        for f in ("matrix", "distortions", "rotation", "translation"):
            assert np.array_equal(getattr(x, f), getattr(y, f))
        assert tuple(x.size) == tuple(y.size)


def test_a_repeated_calibration_is_read_back_exactly(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    out.mkdir()
    rig1, how1 = cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    assert calls["calibrate"] == 1 and calls["detect"] == ["left", "right"]
    assert (out / cache.CACHE_FILE).is_file() and "cached" not in how1
    rig2, how2 = cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    assert calls["calibrate"] == 1 and len(calls["detect"]) == 2 and "cached" in how2
    _same(rig1, rig2)


def test_a_changed_parameter_recalibrates_but_reuses_the_corners(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    first = {c: v.corners.copy() for c, v in calls["views"].items()}
    cache.cached_calibration(views_dirs, INNER, 0.06, "left", write_to=out)          # another square size
    assert calls["calibrate"] == 2 and calls["detect"] == ["left", "right"]
    for c in first:   # the corners (NaN view included) come back exactly
        np.testing.assert_array_equal(calls["views"][c].corners, first[c])
        assert calls["views"][c].reasons == ("", "board not found", "")
    cache.cached_calibration(views_dirs, INNER, 0.06, "right", write_to=out)         # another reference
    assert calls["calibrate"] == 3 and len(calls["detect"]) == 2


def test_a_changed_view_detects_that_camera_again(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    (views_dirs["right"] / "01.png").write_bytes(b"another image, another size")
    _, how = cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    assert calls["calibrate"] == 2 and calls["detect"] == ["left", "right", "right"] and "cached" not in how


def test_recalibrate_ignores_the_cache(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out, recalibrate=True)
    assert calls["calibrate"] == 2 and calls["detect"] == ["left", "right"] * 2


def test_the_earlier_runs_folder_is_read_and_the_cache_carried_over(views_dirs, calls, tmp_path):
    old, new = tmp_path / "old", tmp_path / "new"
    old.mkdir()
    new.mkdir()
    rig1, _ = cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=old)
    rig2, how = cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=new, read_from=[old])
    assert calls["calibrate"] == 1 and "cached" in how
    assert (new / cache.CACHE_FILE).read_bytes() == (old / cache.CACHE_FILE).read_bytes()
    _same(rig1, rig2)


def test_a_damaged_cache_file_is_calibrated_again(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    (out / cache.CACHE_FILE).write_text('{"format": "horsemocap-calibration-cache/1", "key": "x", "rig": 3')
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    assert calls["calibrate"] == 2 and len(calls["detect"]) == 4


def test_excluded_views_and_the_mode_are_part_of_the_key(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out, exclude={"left": ["01"]})
    assert calls["calibrate"] == 2 and len(calls["detect"]) == 2       # calibrated again, corners reused
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out, exclude={"left": ["01"]})
    assert calls["calibrate"] == 2                                       # the same exclusion: reused
    _, how = cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out, mode="pairwise")
    assert calls["calibrate"] == 3 and "pairwise" in how


def test_the_board_views_are_counted_on_the_progress(views_dirs, calls, tmp_path):
    """A long calibration shows progress per view (issue 15): a callback that takes counts gets
    ``done/total`` for every camera's board views; a plain two-argument callback gets lines only."""
    class Counting:
        counts = True

        def __init__(self):
            self.seen = []

        def __call__(self, step, message, done=None, total=None):
            self.seen.append((step, message, done, total))

    progress = Counting()
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", progress=progress)
    counted = [(m, d, t) for s, m, d, t in progress.seen if d is not None]
    for cam in ("left", "right"):
        assert [(d, t) for m, d, t in counted if f"'{cam}'" in m] == [(1, 3), (2, 3), (3, 3)]
    lines = []
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", progress=lambda s, m: lines.append(m),
                             recalibrate=True)
    assert lines and all(isinstance(m, str) for m in lines)


def _copy_views(tmp_path, picks):
    import shutil

    from horsemocap.data import data_samples_dir

    src = data_samples_dir() / "horse2_canter" / "calibration"
    dirs = {}
    for cam, names in picks.items():
        dirs[cam] = tmp_path / "views" / cam
        dirs[cam].mkdir(parents=True)
        for name in names:
            shutil.copy(src / cam / f"{name}.jpg", dirs[cam])
    return dirs


def test_board_detection_started_early_is_used_when_its_views_are_the_sessions(tmp_path):
    """BoardDetectionJob (issue 16): the same corners as detecting in the calibration, taken only for the same files."""
    from horsemocap.calibration.board import detect_cameras

    dirs = _copy_views(tmp_path, {"left": ["left1", "left17"], "middle": ["middle1", "middle2"]})
    job = cache.BoardDetectionJob(dirs, (7, 14), workers=2)
    direct = detect_cameras(dirs, (7, 14), workers=1)
    lines = []

    class Progress:
        counts = True

        def __call__(self, step, message, done=None, total=None):
            lines.append((step, message, done, total))

    for cam in dirs:
        got = job.views(cam, cache.views_key(dirs[cam], (7, 14)), Progress())
        np.testing.assert_array_equal(got.corners, direct[cam].corners)
        assert got.reasons == direct[cam].reasons and got.names == direct[cam].names
    assert job.views("left", "another key") is None and job.views("right", "any") is None
    assert all(step == "rig" for step, *_ in lines)
    job.close()
    # the job's error (a view of another size) comes out where the views are asked for
    (dirs["left"] / "odd.png").write_bytes(__import__("cv2").imencode(".png", np.zeros((10, 10), np.uint8))[1])
    bad = cache.BoardDetectionJob(dirs, (7, 14))
    with pytest.raises(Exception, match="differs from"):
        bad.views("left", cache.views_key(dirs["left"], (7, 14)))
    bad.close()


def test_board_detection_job_stops_when_closed(tmp_path, monkeypatch):
    """Stopped, the job starts no further view and says so where the views are asked for."""
    import threading
    import time

    from horsemocap.calibration import board
    from horsemocap.calibration.board import DetectionStopped

    dirs = _copy_views(tmp_path, {"left": ["left1", "left2", "left3", "left4", "left5", "left6"]})
    started, release = [], threading.Event()
    real = board.detect_board

    def slow(*args, **kwargs):
        started.append(1)
        release.wait(5)                           # the first view is under way when the job is stopped
        return real(*args, **kwargs)

    monkeypatch.setattr(board, "detect_board", slow)
    job = cache.BoardDetectionJob(dirs, (7, 14), workers=1)
    t0 = time.perf_counter()
    while not started and time.perf_counter() - t0 < 5:
        time.sleep(0.01)
    job.stop()
    release.set()
    with pytest.raises(DetectionStopped):
        job.views("left", cache.views_key(dirs["left"], (7, 14)))
    job.close()
    assert len(started) == 1                      # the five other views were never started
    assert not job._thread.is_alive()


def test_views_cached_says_whether_the_corners_are_in_the_folder(views_dirs, calls, tmp_path):
    out = tmp_path / "results"
    assert not cache.views_cached(views_dirs, INNER, [out])
    cache.cached_calibration(views_dirs, INNER, 0.05, "left", write_to=out)
    assert cache.views_cached(views_dirs, INNER, [None, out])
    assert not cache.views_cached(views_dirs, (4, 2), [out])        # another board: detected again


def test_analysis_error_stops_the_board_detection_started_early(tmp_path, monkeypatch):
    """A step failing while the views are detected (here the sync's offset) stops the detection at once.

    The rig step runs in a thread waiting for the early job's views; before
    the fix the error came only after every one of the 135 views.
    """
    import json
    from pathlib import Path

    from horsemocap.calibration import board
    from horsemocap.data import default_session_dir
    from horsemocap.pipeline import analyze
    from horsemocap.session import SessionError, load_session

    bundled = Path(default_session_dir())
    root = tmp_path / "session"
    root.mkdir()
    for sub in ("motion", "plumb", "static", "calibration"):
        (root / sub).symlink_to(bundled / sub, target_is_directory=True)
    doc = json.loads((bundled / "session.json").read_text())
    doc["sync"] = {"offsets": {"left": 100000, "middle": 61, "right": 134}}   # beyond the left video
    (root / "session.json").write_text(json.dumps(doc))
    detected, real = [], board.detect_board

    def counted(*args, **kwargs):
        detected.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(board, "detect_board", counted)
    session = load_session(root)
    job = cache.BoardDetectionJob(session.calibration_images, session.board.inner_corners, workers=1)
    with pytest.raises(SessionError, match="sync offset"):
        analyze(root, tmp_path / "out", board_views=job, progress=lambda *a, **k: None)
    job.close()
    assert len(detected) < 45                     # of 135 views: stopped, not waited for


def test_analyze_sets_the_blas_limit_in_the_main_thread_only(monkeypatch):
    """The calibration's one BLAS thread is set once, by analyze() in the main thread, before the
    rig's thread starts (threadpoolctl expects its changes there); the rig thread's own blocks
    (calibrate_camera, bundle_adjust) only count themselves in, and the setting is back after."""
    import threading

    from horsemocap import pipeline
    from horsemocap.data import default_session_dir
    from horsemocap.threads import blas_single_threaded

    calls = []
    original = blas_single_threaded._limit

    def recording_limit():
        calls.append(threading.current_thread() is threading.main_thread())
        return original()

    monkeypatch.setattr(blas_single_threaded, "_limit", recording_limit)
    analysis = pipeline.analyze(default_session_dir(), None, until="rig", progress=lambda *a: None)
    assert analysis.rig is not None
    assert calls == [True]
    assert blas_single_threaded._inside == 0


def test_the_rig_step_says_a_reused_calibration_once_and_keys_views_left_out_by_file_or_key(views_dirs, calls,
                                                                                             tmp_path):
    """A view left out by its file name (``01.png``) or by its key (``01``) is the same calibration: the second
    run reuses the first's from calibration.json, and says so once (not again as where the rig came from)."""
    from horsemocap.params import RigParams
    from horsemocap.steps.rig import step_rig

    session = SimpleNamespace(rig_path=None, calibration_images=views_dirs, reference_camera="left",
                              cameras=("left", "right"), json_path=tmp_path / "session.json",
                              board=SimpleNamespace(inner_corners=INNER, square_size_m=0.05))
    out = tmp_path / "out"
    out.mkdir()
    runs = []
    for given in ("01.png", "01"):
        lines = []
        step_rig(session, RigParams(exclude={"left": [given]}), lambda step, msg, *a: lines.append(msg),
                 cache_dirs=[out])
        runs.append(lines)
    assert calls["calibrate"] == 1, runs                       # the same key: calibrated once
    assert "views left out: left 01" in runs[0] and "views left out: left 01" in runs[1]
    assert any(m.startswith("calibration reused from calibration.json") for m in runs[1]), runs[1]
    assert not any("(cached in" in m for m in runs[1]), runs[1]
    assert runs[0][-1] == "calibrated from checkerboard views (joint)"
    assert any(m.startswith("camera 'left': the board was found in 2 of 3 views; not in 01") for m in runs[0])
