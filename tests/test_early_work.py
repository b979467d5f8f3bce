"""The work a run starts before it loads the analysis: the figure painter's copy, the flash search, and the
light imports that let them start early."""
from __future__ import annotations

import errno
import gc
import os
import signal
import subprocess
import sys
import threading
import time
import types

import cv2
import numpy as np
import pytest

from horsemocap import cli, report, run, sources, sync
from horsemocap.data import default_session_dir
from horsemocap.forking import EarlyCalls, fork_call
from horsemocap.pipeline import analyze
from horsemocap.plots import figure_painter, report_figures
from horsemocap.session import load_session
from horsemocap.sources import FrameSource
from horsemocap.sync import FlashSearch, SyncError, flash_detections

can_fork_here = pytest.mark.skipif(not hasattr(os, "fork") or (os.cpu_count() or 1) < 2,
                                   reason="the forked copy is made only where fork exists and two cores do")


def _in_a_copy_only(action):
    """A stand-in for ``sync.flash_detections`` that runs ``action`` (ending its process) only in a forked
    copy: a search that fell back to a thread runs it in this process, and it would end the test run; there
    it raises instead, and the test's ``forked`` assertion says why."""
    parent = os.getpid()

    def replaced(*args, **kwargs):
        if os.getpid() == parent:
            raise RuntimeError("the flash search ran in the test's own process, not in a forked copy")
        action()
    return replaced


def _wait_for_other_threads(seconds: float = 30) -> None:
    """Wait until this process runs no other Python thread (an earlier test's helper thread ending), since
    the search forks its copy only then (:func:`horsemocap.forking.can_fork`)."""
    deadline = time.monotonic() + seconds
    while threading.active_count() > 1 and time.monotonic() < deadline:
        time.sleep(0.01)


def _loaded_after(code: str) -> set:
    """The modules loaded by a fresh interpreter after running ``code``."""
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout
    return set(out.split())


def test_the_command_line_and_the_session_load_no_scipy_and_no_analysis_step():
    loaded = _loaded_after("import horsemocap.cli, horsemocap.session, horsemocap.sync, horsemocap.forking, "
                           "horsemocap.plots")
    assert not any(m == "scipy" or m.startswith("scipy.") for m in loaded)
    assert "horsemocap.steps" not in loaded and "matplotlib" not in loaded


def test_the_report_figures_module_loads_no_other_plotting_module():
    loaded = _loaded_after("import horsemocap.plots.report_figures")
    assert "matplotlib.pyplot" in loaded and "horsemocap.plots.summary" in loaded
    assert not {"horsemocap.plots.detection", "horsemocap.plots.herd", "horsemocap.herd"} & loaded


def test_the_plots_package_still_reexports_every_plotting_function():
    code = ("from horsemocap import plots\nfrom horsemocap.plots import plot_marker_tracks\n"
            "assert plots.plot_marker_tracks is plot_marker_tracks\n"
            "import importlib, pkgutil\n"
            "names = []\n"
            "for info in pkgutil.iter_modules(plots.__path__):\n"
            "    mod = importlib.import_module('horsemocap.plots.' + info.name)\n"
            "    names += getattr(mod, '__all__', [n for n in dir(mod) if n.startswith('plot_')])\n"
            "assert plots.__all__ == names, (plots.__all__, names)\n"
            "assert all(callable(getattr(plots, n)) for n in names)\n"
            "assert set(names) <= set(dir(plots))\n"
            "try:\n    plots.no_such_plot\nexcept AttributeError:\n    pass\nelse:\n    raise SystemExit(1)\n")
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("fork", [True, False])
def test_early_calls_give_each_value_in_order_forked_or_not(fork):
    with EarlyCalls("statistics", "median", fork=fork) as calls:
        calls.submit([3.0, 1.0, 2.0, 8.0])
        calls.submit([5.0])
        calls.submit(np.arange(5.0))
        assert calls.results() == [2.5, 5.0, 2.0]
        assert len(calls.given) == 3


@can_fork_here
def test_early_calls_compute_here_what_the_copy_could_not():
    """A copy that dies on its second call leaves every value to this process."""
    parent = os.getpid()
    module = types.ModuleType("fragile_calls")
    module.twice = lambda x: 2 * x if os.getpid() == parent or x < 10 else os._exit(3)
    sys.modules["fragile_calls"] = module
    try:
        with EarlyCalls("fragile_calls", "twice") as calls:
            assert calls.forked
            calls.submit(1)
            calls.submit(21)
            calls.submit(4)
            assert calls.results() == [2, 42, 8]
    finally:
        del sys.modules["fragile_calls"]


@can_fork_here
def test_early_calls_given_nothing_end_their_copy():
    calls = EarlyCalls("statistics", "median")
    pid = calls._pid
    calls.close()
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)         # reaped: no zombie left behind


def test_the_report_draws_the_same_figures_given_step_by_step_or_at_once():
    first = [("reprojection_residuals", ({"left": np.linspace(0, 1, 9)},), {})]
    rest = [("axes_timeseries", (np.arange(4.0), {"p": np.ones((4, 3))}, "m", "Positions"), {"quantity": None})]
    here = report_figures.draw_pngs(first + rest)
    with figure_painter() as painter:
        painter.submit(first)
        assert report._drawn(painter, first + rest) == here
    with figure_painter() as painter:
        painter.submit(rest)
        with pytest.raises(ValueError, match="not the first"):
            report._drawn(painter, first + rest)


def test_the_early_flash_search_finds_what_the_step_would():
    session = load_session(default_session_dir())
    sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
    search = FlashSearch({c: session.motion[c] for c in session.cameras})
    early = search.detections(sources)
    late = flash_detections(sources)
    assert {c: d.frame for c, d in early.items()} == {c: d.frame for c, d in late.items()} \
        == {"left": 8, "middle": 61, "right": 134}
    assert all(np.array_equal(early[c].signal, late[c].signal) for c in late)
    assert list(early) == list(session.cameras)
    one_by_one = flash_detections(sources, readers=1)
    assert {c: (d.frame, d.off_level, d.on_level) for c, d in one_by_one.items()} \
        == {c: (d.frame, d.off_level, d.on_level) for c, d in late.items()}
    # another search (fewer frames, other cameras or another order) is not this one
    assert search.detections(sources, search_frames=100) is None
    assert search.detections(dict(reversed(list(sources.items())))) is None


@pytest.mark.parametrize("fork", [True, False])
def test_the_early_flash_search_raises_its_error_when_asked(tmp_path, fork):
    dark = tmp_path / "dark"
    dark.mkdir()
    for k in range(12):
        cv2.imwrite(str(dark / f"f{k:03d}.png"), np.full((48, 64), 20, np.uint8))
    search = FlashSearch({"left": dark}, fork=fork)
    with pytest.raises(SyncError, match="camera 'left'.*no flash found"):
        search.detections({"left": FrameSource(dark)})


def _flash_video(path, frames=40, flash_at=17):
    """A small MJPEG video: dark, a light switched on at ``flash_at``."""
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (160, 120))
    for k in range(frames):
        image = np.full((120, 160, 3), 20, np.uint8)
        if k >= flash_at:
            image[40:60, 70:90] = 230
        out.write(image)
    out.release()
    return path


@can_fork_here
def test_a_forked_flash_search_shares_its_decoded_frames_as_a_thread_would(tmp_path, monkeypatch):
    """The copy's frames read here in place, pinned in the same order; the detections those of a thread."""
    videos = {"left": _flash_video(tmp_path / "left.avi"), "right": _flash_video(tmp_path / "right.avi", 40, 23)}
    found = {}
    for fork in (True, False):
        shared = sources._SharedGray(sources.SHARED_GRAY_BYTES)
        monkeypatch.setattr(sources, "_SHARED", shared)
        monkeypatch.setattr(sources, "_OPENED", set())
        monkeypatch.setattr(sources, "_COUNTS", {})
        done = []
        search = FlashSearch(videos, when_done=lambda: done.append(os.getpid()), fork=fork)
        assert (search._thread.name, search.forked) == ("horsemocap-flash-search", fork)
        found[fork] = search.detections({c: FrameSource(p) for c, p in videos.items()})
        assert done == [os.getpid()]
        assert len(shared.frames) == len(shared.pinned) == 80
        assert [key[1] for key in shared.frames] == list(range(40)) * 2
        found[fork, "frames"] = [f.copy() for f in shared.frames.values()]
        assert len(sources._OPENED) == 2 and len(sources._COUNTS) == 2
    assert {c: d.frame for c, d in found[True].items()} == {c: d.frame for c, d in found[False].items()} \
        == {"left": 17, "right": 23}
    assert all(np.array_equal(found[True][c].signal, found[False][c].signal) for c in videos)
    assert all(np.array_equal(a, b) for a, b in zip(found[True, "frames"], found[False, "frames"]))


@can_fork_here
def test_a_forked_flash_search_keeps_no_more_frames_than_the_process_shares(tmp_path, monkeypatch):
    video = _flash_video(tmp_path / "left.avi")
    frame_bytes = 160 * 120
    monkeypatch.setattr(sources, "_SHARED", sources._SharedGray(10 * frame_bytes))
    monkeypatch.setattr(sync, "SHARED_GRAY_BYTES", 10 * frame_bytes)
    made = []
    real_mmap = sync.mmap.mmap
    monkeypatch.setattr(sync.mmap, "mmap", lambda *args: made.append(real_mmap(*args)) or made[-1])
    search = FlashSearch({"left": video})
    assert [len(m) for m in made] == [10 * frame_bytes]
    assert search.detections({"left": FrameSource(video)})["left"].frame == 17
    assert [key[1] for key in sources._SHARED.frames] == list(range(30, 40))     # the last ones, as a thread's


@can_fork_here
def test_a_forked_flash_search_cancelled_is_killed_and_one_lost_leaves_the_search_to_the_step(
        tmp_path, monkeypatch):
    video = _flash_video(tmp_path / "left.avi")
    monkeypatch.setattr(sync, "flash_detections", lambda *args, **kwargs: time.sleep(60))
    done = []
    search = FlashSearch({"left": video}, when_done=lambda: done.append(True))
    pid = search._pid
    started = time.perf_counter()
    search.close(wanted=False)
    search._thread.join(10)
    assert time.perf_counter() - started < 10 and done == [True]
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)         # reaped: no zombie left behind
    assert search.detections({"left": FrameSource(video)}) is None
    assert search.lost is None              # cancelled, not lost
    # a copy that dies without a result: no detections and no error (the sync step searches itself)
    monkeypatch.setattr(sync, "flash_detections", _in_a_copy_only(lambda: os._exit(3)))
    _wait_for_other_threads()
    lost = FlashSearch({"left": video})
    assert lost.forked
    assert lost.detections({"left": FrameSource(video)}) is None
    assert lost.lost == "its copy exited with status 3 without a result"


def test_the_command_collects_garbage_less_often_and_exempts_its_objects_at_its_end_and_a_call_does_not(
        tmp_path):
    frozen, threshold = gc.get_freeze_count(), gc.get_threshold()
    assert cli.main(["analyze", str(tmp_path / "no-such-session"), "--out", str(tmp_path / "out")]) == 2
    assert gc.get_freeze_count() == frozen and gc.get_threshold() == threshold
    code = ("import gc, sys\nfrom horsemocap.cli import main\n"
            f"sys.argv = ['horsemocap', 'analyze', {str(tmp_path / 'no-such-session')!r}, '--out', "
            f"{str(tmp_path / 'out')!r}]\n"
            "code = main()\nprint(code, gc.get_freeze_count() > 0, gc.get_threshold()[0])\n")
    got = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert got.stdout.split() == ["2", "True", str(cli.COMMAND_GC_ALLOCATIONS)]
    assert "no-such-session" in got.stderr


# --- early work nobody will use is not waited for --------------------------------------------------------

@pytest.fixture
def slow_module(tmp_path, monkeypatch):
    """A module whose import takes a minute (as matplotlib's takes a while): a copy loading it is busy."""
    (tmp_path / "slow_to_load.py").write_text("import time\ntime.sleep(60)\ndef size(a):\n    return len(a)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return "slow_to_load"


@can_fork_here
def test_early_calls_closed_unwanted_do_not_wait_for_the_copy_loading_its_module(slow_module):
    for submitted in (False, True):
        calls = EarlyCalls(slow_module, "size")
        assert calls.forked
        pid = calls._pid
        if submitted:
            calls.submit(b"x")
        started = time.perf_counter()
        calls.close()
        assert time.perf_counter() - started < 10
        with pytest.raises(ChildProcessError):
            os.waitpid(pid, os.WNOHANG)     # reaped: no zombie left behind


@can_fork_here
def test_early_calls_submit_never_waits_for_the_copy(slow_module):
    """Arguments much larger than a pipe's buffer, given while the copy is still loading its module."""
    calls = EarlyCalls(slow_module, "size")
    assert calls.forked
    started = time.perf_counter()
    for _ in range(3):
        calls.submit(bytes(1 << 20))
    assert time.perf_counter() - started < 10
    calls.close()
    assert threading.active_count() == 1     # the thread writing the rest ended with the copy


@pytest.fixture
def module_that_says_when_loaded(tmp_path, monkeypatch):
    """A module whose import writes the file ``loaded`` (in the process that imports it, a copy too)."""
    flag = tmp_path / "loaded"
    (tmp_path / "says_when_loaded.py").write_text(f"open({str(flag)!r}, 'w').close()\n"
                                                  "def size(a):\n    return len(a)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return "says_when_loaded", flag


def _wait_until_waiting_to_start(calls: EarlyCalls, seconds: float = 30) -> None:
    """Return once the held copy is blocked reading its start pipe (its state read in ``/proc``: the
    system call it waits in and the pipe of that file descriptor); fail if it never is."""
    pid, start_pipe = calls._pid, os.fstat(calls._start_fd).st_ino
    try:
        open(f"/proc/{pid}/syscall").close()
    except OSError:
        pytest.skip("the copy's state cannot be read here (/proc/<pid>/syscall)")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with open(f"/proc/{pid}/syscall") as f:
            fields = f.read().split()
        if fields and fields[0] not in ("running", "-1") and len(fields) > 1:
            fd = int(fields[1], 16)
            try:
                if os.readlink(f"/proc/{pid}/fd/{fd}") == f"pipe:[{start_pipe}]":
                    return
            except OSError:
                pass
        time.sleep(0.01)
    pytest.fail(f"the held copy was not seen waiting on its start pipe within {seconds} s")


@can_fork_here
@pytest.mark.parametrize("how", ["start", "submit", "results"])
def test_a_held_copy_loads_its_module_only_once_started(module_that_says_when_loaded, how):
    module, flag = module_that_says_when_loaded
    with EarlyCalls(module, "size", hold=True) as calls:
        assert calls.forked
        _wait_until_waiting_to_start(calls)
        assert not flag.exists()            # forked, idle: the module is not loaded yet
        if how == "start":
            calls.start()
            calls.start()                   # once is enough; again does nothing
            deadline = time.monotonic() + 30
            while not flag.exists() and time.monotonic() < deadline:
                time.sleep(0.01)
            assert flag.exists()
        if how != "results":
            calls.submit(b"abc")
        assert calls.results() == ([3] if how != "results" else [])
        assert flag.exists()


@can_fork_here
def test_a_held_copy_closed_unstarted_is_ended(module_that_says_when_loaded):
    module, flag = module_that_says_when_loaded
    calls = EarlyCalls(module, "size", hold=True)
    pid = calls._pid
    _wait_until_waiting_to_start(calls)
    calls.close()
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)         # reaped: no zombie left behind
    calls.start()                           # after the end: nothing to do
    assert not flag.exists()


def test_the_flash_search_says_when_it_is_done_found_failed_or_cancelled(tmp_path):
    session = load_session(default_session_dir())
    done = []
    search = FlashSearch({c: session.motion[c] for c in session.cameras}, when_done=lambda: done.append("found"))
    search.close()
    assert done == ["found"]
    dark = tmp_path / "dark"
    dark.mkdir()
    for k in range(12):
        cv2.imwrite(str(dark / f"f{k:03d}.png"), np.full((48, 64), 20, np.uint8))
    failed = FlashSearch({"left": dark}, when_done=lambda: done.append("failed"))
    failed.close()
    assert done == ["found", "failed"]
    cancelled = FlashSearch({c: session.motion[c] for c in session.cameras},
                            when_done=lambda: done.append("cancelled"))
    cancelled.close(wanted=False)
    cancelled._thread.join(30)
    assert done == ["found", "failed", "cancelled"]


@can_fork_here
def test_early_calls_deliver_arguments_larger_than_the_pipe_in_order():
    with EarlyCalls("statistics", "fmean") as calls:
        big = [np.full(300_000, float(k)) for k in range(4)]
        for k, values in enumerate(big):
            calls.submit(values)
            calls.submit([float(k)])
        assert calls.results() == [0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0]
    assert threading.active_count() == 1


def _gated_frames(monkeypatch):
    """FrameSource.iter_frames replaced by one that yields a frame only when the test lets it:
    ``(allow, yielded)``, a semaphore to release per frame and the (folder, frame) yielded."""
    allow, yielded = threading.Semaphore(0), []

    def iter_frames(self, start=0, stop=None, color=True, share=False):
        for k in range(start, stop if stop is not None else 40):
            allow.acquire()
            yielded.append((self.path.name, k))
            yield k, np.full((24, 32), 20, np.uint8)
    monkeypatch.setattr(FrameSource, "iter_frames", iter_frames)
    return allow, yielded


def test_a_flash_search_closed_unwanted_is_not_waited_for_and_stops_between_frames(tmp_path, monkeypatch):
    for camera in ("left", "right"):
        (tmp_path / camera).mkdir()
        cv2.imwrite(str(tmp_path / camera / "f000.png"), np.full((24, 32), 20, np.uint8))
    monkeypatch.setattr(os, "cpu_count", lambda: 2)      # one camera after the other
    allow, yielded = _gated_frames(monkeypatch)
    search = FlashSearch({c: tmp_path / c for c in ("left", "right")}, search_frames=40, fork=False)
    allow.release()
    while not yielded:
        time.sleep(0.01)
    closing = threading.Thread(target=search.close, kwargs={"wanted": False})
    closing.start()
    closing.join(10)
    assert not closing.is_alive()           # returned while the search waits for its next frame
    for _ in range(80):
        allow.release()
    search._thread.join(10)
    assert not search._thread.is_alive()
    # the frame it was reading when cancelled, then it stopped: no further frame, no other camera
    assert yielded in ([("left", 0)], [("left", 0), ("left", 1)])
    assert search.detections({c: FrameSource(tmp_path / c) for c in ("left", "right")}, 40) is None


class _SearchRecorder:
    """In place of FlashSearch: records the searches started and how they were closed."""
    started: list = []

    def __init__(self, videos, search_frames=None, when_done=None):
        self.videos, self.closed, self.when_done = videos, [], when_done
        _SearchRecorder.started.append(self)

    def close(self, wanted=True):
        self.closed.append(wanted)


@pytest.fixture
def early_run(monkeypatch, tmp_path):
    """``horsemocap analyze`` of the bundled session up to the analysis, which raises ``stop`` (the searches
    started are recorded)."""
    monkeypatch.setattr(sync, "FlashSearch", _SearchRecorder)

    def run_until(extra, stop=RuntimeError("the analysis failed")):
        _SearchRecorder.started = []

        def analyse(*args, **kwargs):
            raise stop
        monkeypatch.setattr(cli, "_analyse_session", analyse)
        try:
            cli.main(["analyze", str(default_session_dir()), "--out", str(tmp_path / "out"), "--no-report", *extra])
        except BaseException as exc:    # noqa: BLE001 - main turns some into exit codes
            assert exc is stop
        return _SearchRecorder.started
    return run_until


def test_the_command_line_cancels_the_flash_search_when_the_parameters_give_the_offsets(early_run, tmp_path):
    # started before the parameters are read (they load the detection's modules), cancelled once they give
    # the offsets: closed unwanted, before the analysis, and not again
    given = tmp_path / "choices.json"
    given.write_text('{"sync": {"offsets": {"left": 8, "middle": 61, "right": 134}}}')
    for extra in (["--offsets", "left=8,middle=61,right=134"],
                  ["--set", 'sync.offsets={"left": 8, "middle": 61, "right": 134}'], ["--params", str(given)]):
        started = early_run(extra)
        assert len(started) == 1 and started[0].closed == [False], extra


def test_the_command_line_ends_an_unused_flash_search_without_waiting_on_error_or_ctrl_c(early_run):
    for stop in (RuntimeError("the analysis failed"), KeyboardInterrupt()):
        started = early_run([], stop)
        assert len(started) == 1 and started[0].closed == [False]


class _PainterRecorder:
    """In place of the figure painter: records how it was made, started and closed."""
    made: list = []

    def __init__(self, hold=False):
        self.hold, self.events = hold, []
        _PainterRecorder.made.append(self)

    def start(self):
        self.events.append("start")

    def close(self):
        self.events.append("close")


@pytest.mark.parametrize("extra", [[], ["--offsets", "left=8,middle=61,right=134"]])
def test_the_command_line_holds_the_painter_until_the_flash_search_is_done(monkeypatch, tmp_path, extra):
    # on two cores the search has the second one to itself; matplotlib loads after it (or at once when the
    # parameters give the offsets and the search is cancelled)
    monkeypatch.setattr(sync, "FlashSearch", _SearchRecorder)
    monkeypatch.setattr(cli, "figure_painter", _PainterRecorder)
    _SearchRecorder.started, _PainterRecorder.made = [], []
    seen = []

    def analyse(session, session_dir, out_dir, args, params, board_views, flash_search=None, painter=None):
        seen.append(list(painter.events))
        return 0
    monkeypatch.setattr(cli, "_analyse_session", analyse)
    assert cli.main(["analyze", str(default_session_dir()), "--out", str(tmp_path / "out"), *extra]) == 0
    (painter,), (search,) = _PainterRecorder.made, _SearchRecorder.started
    assert painter.hold
    if extra:
        assert seen == [["start"]] and search.closed[0] is False
    else:
        assert seen == [[]] and search.when_done == painter.start
    assert painter.events[-1] == "close"


def test_the_command_line_starts_no_flash_search_when_the_session_gives_the_offsets(tmp_path, monkeypatch):
    session = load_session(default_session_dir())
    monkeypatch.setattr(sync, "FlashSearch", _SearchRecorder)
    _SearchRecorder.started = []
    params = cli._analysis_params(session, cli.build_parser().parse_args(["demo"]))
    assert not params.sync.offsets and not session.sync_offsets
    assert cli._early_flash_search(session) is not None
    given = types.SimpleNamespace(sync_offsets={"left": 8, "middle": 61, "right": 134}, motion=session.motion,
                                  cameras=session.cameras)
    assert cli._early_flash_search(given) is None
    assert len(_SearchRecorder.started) == 1


# --- figures described as the steps end ------------------------------------------------------------------

def test_an_error_describing_a_steps_figures_mid_analysis_does_not_stop_it(monkeypatch):
    given = []
    painter = types.SimpleNamespace(submit=given.append)
    described = {"detect": [(("marker_tracks", (), {}), "d")], "triangulate": None,
                 "rigid_body": [(("axes_timeseries", (), {}), "r")]}

    def step_figures(analysis, step):
        if described[step] is None:
            raise KeyError("no residuals")
        return described[step]
    monkeypatch.setattr(run, "step_figures", step_figures)
    after_step = run._figures_drawn_after(painter)
    for step in ("detect", "triangulate", "rigid_body"):
        after_step(None, step)              # raises nothing
    assert given == [[("marker_tracks", (), {})]]     # the rest: described and drawn with the report


def test_the_report_leaves_out_figures_it_cannot_describe_and_says_why(monkeypatch):
    def step_figures(analysis, step):
        if step == "triangulate":
            raise KeyError("residual_px")
        return [(("axes_timeseries", (), {}), f"{step} caption")]
    monkeypatch.setattr(report, "step_figures", step_figures)
    figures, left_out = report._described_figures(None)
    assert [caption for _, caption in figures] == ["detect caption", "rigid_body caption"]
    assert len(left_out) == 1 and "'triangulate'" in left_out[0] and "KeyError" in left_out[0]


class _UnmatchedSearch:
    """An early search that is not the step's (its detections are None): records how it was closed."""

    lost = None

    def __init__(self):
        self.closed = []

    def detections(self, sources, search_frames=None):
        return None

    def close(self, wanted=True):
        self.closed.append(wanted)


def test_the_analysis_ends_an_early_flash_search_once_the_sync_step_is_past():
    # the step searched itself (the early search was another one): the early search must not decode beside
    # the later steps until the run's end
    search = _UnmatchedSearch()
    seen = []
    analyze(default_session_dir(), None, None, until="plumb", write_outputs=False, flash_search=search,
            after_step=lambda analysis, name: seen.append((name, list(search.closed))))
    assert dict(seen)["sync"] == [False] and search.closed == [False]


# --- a copy forked later holds none of an earlier copy's pipes ---------------------------------------------

def _results_within(calls, seconds: float):
    """``calls.results()`` computed by a thread: ``(finished within seconds, the values or None)``."""
    got = []
    waiting = threading.Thread(target=lambda: got.append(calls.results()), daemon=True)
    waiting.start()
    waiting.join(seconds)
    return not waiting.is_alive(), (got[0] if got else None), waiting


@can_fork_here
@pytest.mark.parametrize("hold", [False, True])
def test_early_calls_results_do_not_wait_for_a_copy_forked_after_them(hold):
    """A copy forked later (as the flash search's) that lives on does not keep the first copy's arguments
    open: its results come once its own calls are done."""
    calls = EarlyCalls("statistics", "median", hold=hold)
    assert calls.forked
    later = fork_call(lambda: time.sleep(60))
    try:
        calls.submit([3.0, 1.0, 2.0])
        finished, values, waiting = _results_within(calls, 10)
    finally:
        os.kill(later, signal.SIGKILL)
        os.waitpid(later, 0)
    waiting.join(10)
    assert finished and values == [2.0]
    calls.close()


@can_fork_here
def test_the_report_figures_do_not_wait_for_a_flash_search_that_lives_on(tmp_path, monkeypatch):
    video = _flash_video(tmp_path / "left.avi")
    painter = EarlyCalls("statistics", "median", hold=True)      # forked first, held, as the command's
    monkeypatch.setattr(sync, "flash_detections", lambda *args, **kwargs: time.sleep(60))
    search = FlashSearch({"left": video}, when_done=painter.start)
    try:
        painter.submit([5.0])
        finished, values, waiting = _results_within(painter, 10)
    finally:
        search.close(wanted=False)
    waiting.join(30)
    assert finished and values == [5.0]
    painter.close()


# --- a search whose copy is lost says why; one the system cannot fork runs in a thread -------------------

@can_fork_here
def test_a_flash_search_whose_copy_is_killed_or_sends_an_unreadable_result_says_why(tmp_path, monkeypatch):
    video = _flash_video(tmp_path / "left.avi")
    monkeypatch.setattr(sync, "flash_detections", _in_a_copy_only(lambda: os.kill(os.getpid(), signal.SIGKILL)))
    _wait_for_other_threads()
    killed = FlashSearch({"left": video})
    assert killed.forked
    assert killed.detections({"left": FrameSource(video)}) is None
    assert killed.lost == "its copy was killed by signal 9 without a result"
    monkeypatch.undo()

    def import_fails(decoded, buffer):
        raise MemoryError("no room for the frames")
    monkeypatch.setattr(sync, "import_decoded", import_fails)
    _wait_for_other_threads()
    unreadable = FlashSearch({"left": video})
    assert unreadable.forked
    assert unreadable.detections({"left": FrameSource(video)}) is None
    assert unreadable.lost == "its copy's result could not be read (MemoryError: no room for the frames)"


class _LostSearch(_UnmatchedSearch):
    lost = "its copy was killed by signal 9 without a result"


def test_the_sync_step_says_why_it_searches_again_when_the_early_search_was_lost():
    said = []
    analyze(default_session_dir(), None, progress=lambda step, text: said.append((step, text)), until="sync",
            write_outputs=False, flash_search=_LostSearch())
    assert ("sync", "the flash search started early ended without a result: its copy was killed by signal 9 "
                    "without a result; searching again") in said
    said.clear()
    analyze(default_session_dir(), None, progress=lambda step, text: said.append((step, text)), until="sync",
            write_outputs=False, flash_search=_UnmatchedSearch())
    assert not any("early" in text for _, text in said)


@can_fork_here
@pytest.mark.parametrize("refused", ["fork", "mmap"])
def test_a_flash_search_the_system_cannot_fork_runs_in_a_thread(tmp_path, monkeypatch, refused):
    video = _flash_video(tmp_path / "left.avi")

    def no_room(*args):
        raise OSError(errno.EAGAIN if refused == "fork" else errno.ENOMEM, "refused")
    monkeypatch.setattr(*((os, "fork") if refused == "fork" else (sync.mmap, "mmap")), no_room)
    open_fds = len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else None
    search = FlashSearch({"left": video})
    assert not search.forked and search._shared is None
    assert search.detections({"left": FrameSource(video)})["left"].frame == 17
    if open_fds is not None:
        assert len(os.listdir("/proc/self/fd")) == open_fds      # the pipe made for the copy closed


@can_fork_here
def test_a_forked_flash_search_lets_go_of_its_shared_memory_once_collected(tmp_path, monkeypatch):
    video = _flash_video(tmp_path / "left.avi")
    monkeypatch.setattr(sources, "_SHARED", sources._SharedGray(sources.SHARED_GRAY_BYTES))
    search = FlashSearch({"left": video})
    assert search.forked
    assert search.detections({"left": FrameSource(video)})["left"].frame == 17
    assert search._shared is None           # the frames imported hold the memory, not the search
