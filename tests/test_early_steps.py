"""The steps that need nothing of the sync step's result (rig, plumb line, static shot) run in a thread while
the sync step reads the videos: the same results, their progress lines at their step, their own timings, their
errors raised at their step."""
import threading
import time

import pytest

from horsemocap import pipeline
from horsemocap.data import default_session_dir
from horsemocap.session import SessionError


@pytest.fixture(scope="module")
def rig_result():
    """The demo session's rig, computed once: the tests' rig step returns it at once."""
    return pipeline.analyze(default_session_dir(), until="rig", progress=lambda *a: None).rig


@pytest.fixture
def quick_rig(monkeypatch, rig_result):
    monkeypatch.setattr(pipeline, "step_rig", lambda *args, **kwargs: rig_result)


def _recorded(monkeypatch, name, before=None, after=None):
    """pipeline's ``step_<name>`` wrapped: ``before()`` / ``after()`` around it; returns the threads it ran in."""
    original = getattr(pipeline, f"step_{name}")
    threads = []

    def step(*args, **kwargs):
        threads.append(threading.current_thread().name)
        if before is not None:
            before()
        value = original(*args, **kwargs)
        if after is not None:
            after()
        return value
    monkeypatch.setattr(pipeline, f"step_{name}", step)
    return threads


def test_the_plumb_line_and_static_shot_run_beside_the_sync_step_their_lines_at_their_step(monkeypatch, quick_rig):
    plumb = _recorded(monkeypatch, "plumb")
    static = _recorded(monkeypatch, "static")
    _recorded(monkeypatch, "sync", before=lambda: time.sleep(1.0))     # the stills are done before its lines
    lines = []
    analysis = pipeline.analyze(default_session_dir(), until="static", progress=lambda *a: lines.append(a[0]))
    assert plumb == ["horsemocap-early-steps"] and static == ["horsemocap-early-steps"]
    assert lines == sorted(lines, key=pipeline.STEPS.index) and lines[-1] == "plumb"   # the static shot: no line
    assert "sync" in lines
    reference = pipeline.run_steps(analysis.session, analysis.params, analysis, ["plumb", "static"])
    assert analysis.plumb.gravity.tolist() == reference.plumb.gravity.tolist()
    assert analysis.static.static_points.tolist() == reference.static.static_points.tolist()


def test_a_step_run_beside_the_sync_step_is_timed_by_its_own_duration(monkeypatch, quick_rig):
    _recorded(monkeypatch, "plumb", before=lambda: time.sleep(0.3))
    _recorded(monkeypatch, "sync", before=lambda: time.sleep(3.0))
    analysis = pipeline.analyze(default_session_dir(), until="plumb", progress=lambda *a: None)
    assert 0.3 <= analysis.timings["plumb"] < 2.0     # not the wait for it (none: it ended during the sync)


def test_a_step_run_beside_that_fails_is_timed_by_its_own_duration_too(monkeypatch, quick_rig):
    def refused(*args, **kwargs):
        time.sleep(0.3)
        raise SessionError("plumb/left.png: expected 2 plumb-line markers, found 0")
    monkeypatch.setattr(pipeline, "step_plumb", refused)
    _recorded(monkeypatch, "sync", before=lambda: time.sleep(3.0))
    with pytest.raises(SessionError) as caught:
        pipeline.analyze(default_session_dir(), progress=lambda *a: None)
    assert 0.3 <= caught.value.partial.timings["plumb"] < 2.0


def test_an_error_of_a_step_run_beside_is_raised_at_its_step_with_the_steps_before(monkeypatch, quick_rig):
    def refused(*args, **kwargs):
        raise SessionError("plumb/left.png: expected 2 plumb-line markers, found 0")
    monkeypatch.setattr(pipeline, "step_plumb", refused)
    static = _recorded(monkeypatch, "static")
    with pytest.raises(SessionError, match="expected 2 plumb-line markers") as caught:
        pipeline.analyze(default_session_dir(), progress=lambda *a: None)
    partial = caught.value.partial
    assert partial.sync is not None and partial.rig is not None and partial.plumb is None
    assert static == []                               # nothing after the step that failed


def test_a_run_that_stops_at_the_rig_runs_no_still_and_an_error_elsewhere_stops_the_thread(monkeypatch, quick_rig):
    plumb = _recorded(monkeypatch, "plumb")
    pipeline.analyze(default_session_dir(), until="rig", progress=lambda *a: None)
    assert plumb == []
    in_plumb, may_end = threading.Event(), threading.Event()

    def sync_fails(*args, **kwargs):
        in_plumb.wait(10)
        raise SessionError("motion/left.avi: no flash found")
    monkeypatch.setattr(pipeline, "step_sync", sync_fails)
    _recorded(monkeypatch, "plumb", before=lambda: (in_plumb.set(), may_end.wait(0.5)))
    static = _recorded(monkeypatch, "static")
    with pytest.raises(SessionError, match="no flash found"):
        pipeline.analyze(default_session_dir(), progress=lambda *a: None)
    assert in_plumb.is_set() and static == []        # stopped before its next step, and waited for
