"""The work a run starts before it loads the analysis: the figure painter's copy, the flash search, and the
light imports that let them start early."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from horsemocap.data import default_session_dir
from horsemocap.forking import EarlyCalls
from horsemocap.session import load_session
from horsemocap.sources import FrameSource
from horsemocap.sync import FlashSearch, SyncError, flash_detections

can_fork_here = pytest.mark.skipif(not hasattr(os, "fork") or (os.cpu_count() or 1) < 2,
                                   reason="the forked copy is made only where fork exists and two cores do")


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
    import types

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
    from horsemocap import report
    from horsemocap.plots import report_figures

    first = [("reprojection_residuals", ({"left": np.linspace(0, 1, 9)},), {})]
    rest = [("axes_timeseries", (np.arange(4.0), {"p": np.ones((4, 3))}, "m", "Positions"), {"quantity": None})]
    here = report_figures.draw_pngs(first + rest)
    with report.figure_painter() as painter:
        painter.submit(first)
        assert report._drawn(painter, first + rest) == here
    with report.figure_painter() as painter:
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


def test_the_early_flash_search_raises_its_error_when_asked(tmp_path):
    dark = tmp_path / "dark"
    dark.mkdir()
    import cv2

    for k in range(12):
        cv2.imwrite(str(dark / f"f{k:03d}.png"), np.full((48, 64), 20, np.uint8))
    search = FlashSearch({"left": dark})
    with pytest.raises(SyncError, match="camera 'left'.*no flash found"):
        search.detections({"left": FrameSource(dark)})


def test_the_command_exempts_its_objects_from_the_collector_at_its_end_and_a_call_does_not(tmp_path):
    import gc

    from horsemocap.cli import main

    frozen = gc.get_freeze_count()
    assert main(["analyze", str(tmp_path / "no-such-session"), "--out", str(tmp_path / "out")]) == 2
    assert gc.get_freeze_count() == frozen
    code = ("import gc, sys\nfrom horsemocap.cli import main\n"
            f"sys.argv = ['horsemocap', 'analyze', {str(tmp_path / 'no-such-session')!r}, '--out', "
            f"{str(tmp_path / 'out')!r}]\n"
            "code = main()\nprint(code, gc.get_freeze_count() > 0)\n")
    got = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert got.stdout.split() == ["2", "True"]
    assert "no-such-session" in got.stderr
