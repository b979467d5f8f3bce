"""forking.beside: a second computation in a forked copy while this process computes the first; the same
values, errors and warnings as computing both here; the rigid-body step's chain computed so."""
import os
import signal
import time
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from horsemocap import forking, rigid
from horsemocap.params import RigidBodyParams


@pytest.fixture(params=[True, False], ids=["forked", "here"])
def fork(request, monkeypatch):
    if not request.param:
        monkeypatch.setattr(forking, "can_fork", lambda: False)
    elif not forking.can_fork():
        pytest.skip("no fork on this machine")
    return request.param


def test_both_values_come_back_in_order(fork):
    assert forking.beside(lambda: [1, 2], lambda: {"a": 3.5}) == ([1, 2], {"a": 3.5})


def test_the_second_is_computed_by_a_copy_where_it_is_safe(fork):
    here, there = forking.beside(os.getpid, os.getpid)
    assert here == os.getpid()
    assert (there != here) == fork


def test_an_error_of_the_second_is_raised_here(fork):
    def fails():
        raise ValueError("the chain failed")
    with pytest.raises(ValueError, match="the chain failed"):
        forking.beside(lambda: 1, fails)


@pytest.fixture
def alarm():
    """A test that would hang fails after 60 s instead."""
    def timed_out(*args):
        raise TimeoutError("beside hung")
    previous = signal.signal(signal.SIGALRM, timed_out)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def test_an_error_of_the_first_ends_a_copy_blocked_in_sending(fork, alarm):
    def fails():
        raise KeyError("the pose failed")
    with pytest.raises(KeyError, match="the pose failed"):
        forking.beside(fails, lambda: b"x" * (4 * forking.PIPE_CHUNK))   # more than a pipe holds


def test_an_error_of_the_first_does_not_wait_for_the_copy_to_finish(fork, alarm):
    def fails():
        raise KeyError("the pose failed")
    t0 = time.perf_counter()
    with pytest.raises(KeyError, match="the pose failed"):
        forking.beside(fails, lambda: time.sleep(20) if fork else None)
    assert time.perf_counter() - t0 < 10


def test_no_file_descriptor_or_process_is_left_behind(fork, monkeypatch):
    copies = []
    fork_now = os.fork

    def recorded_fork():
        pid = fork_now()
        if pid:
            copies.append(pid)
        return pid
    monkeypatch.setattr(os, "fork", recorded_fork)
    before = len(os.listdir("/proc/self/fd"))
    for there in (lambda: 1, lambda: 1 / 0):
        try:
            forking.beside(lambda: 0, there)
        except ZeroDivisionError:
            pass
    assert len(os.listdir("/proc/self/fd")) == before
    assert len(copies) == (2 if fork else 0)
    for pid in copies:
        with pytest.raises(ChildProcessError):
            os.waitpid(pid, os.WNOHANG)              # reaped


def test_a_copy_the_system_refuses_leaves_both_computed_here(monkeypatch):
    def refused():
        raise OSError(12, "Cannot allocate memory")
    monkeypatch.setattr(forking, "can_fork", lambda: True)
    monkeypatch.setattr(os, "fork", refused)
    assert forking.beside(os.getpid, os.getpid) == (os.getpid(), os.getpid())


def test_the_warnings_of_the_second_are_shown_here_as_its_filters_say(fork):
    def warns():
        warnings.warn("omega near the markers' plane", RuntimeWarning)
        return 2
    with pytest.warns(RuntimeWarning, match="omega near the markers' plane"):
        assert forking.beside(lambda: 1, warns) == (1, 2)


def test_a_value_that_cannot_be_sent_back_is_computed_here(fork):
    here, there = forking.beside(lambda: 1, lambda: (lambda: os.getpid()))   # a lambda cannot be pickled
    assert here == 1 and there() == os.getpid()


def test_a_warning_the_filters_make_an_error_is_raised_here(fork):
    def warns():
        warnings.warn("omega near the markers' plane", RuntimeWarning)
        return 2
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(RuntimeWarning, match="omega near the markers' plane"):
            forking.beside(lambda: 1, warns)


def _rigid_ride():
    """Three markers and the saddle (the static shot's fourth point) on a body trotting forward."""
    rng = np.random.default_rng(3)
    t = np.arange(60) / 25.0
    body = np.array([[-0.3, 0.0, 0.0], [0.0, 0.05, 0.1], [0.3, 0.0, 0.0], [0.0, -0.2, 0.0]])
    turn = Rotation.from_rotvec(np.outer(0.1 * np.sin(2 * np.pi * 1.5 * t), [0, 1, 0.2])).as_matrix()
    moved = np.einsum("kij,mj->kmi", turn, body) + np.outer(4 * t, [1, 0, 0])[:, None]
    return t, moved[:, :3] + rng.normal(0, 5e-4, (t.size, 3, 3)), body


def test_the_rigid_body_step_gives_the_same_numbers_with_its_chain_forked_or_not(fork):
    t, points, body = _rigid_ride()
    res = rigid.analyse_rigid_body(t, points, body, RigidBodyParams(), period_s=1 / 1.5)
    assert res.chain_error == "" and np.isfinite(res.acc).any()
    forking.can_fork, was = (lambda: False), forking.can_fork
    try:
        serial = rigid.analyse_rigid_body(t, points, body, RigidBodyParams(), period_s=1 / 1.5)
    finally:
        forking.can_fork = was
    for name in ("acc", "omega", "alpha", "saddle_acceleration", "saddle_position"):
        np.testing.assert_array_equal(getattr(res, name), getattr(serial, name))


def test_a_chain_that_fails_in_the_copy_leaves_the_pose_trajectory_and_says_why(fork, monkeypatch):
    def singular(*args):
        raise np.linalg.LinAlgError("Singular matrix")
    monkeypatch.setattr(rigid, "_thesis_chain", singular)
    t, points, body = _rigid_ride()
    res = rigid.analyse_rigid_body(t, points, body, RigidBodyParams(), period_s=1 / 1.5)
    assert res.chain_error == "LinAlgError: Singular matrix" and res.pose is not None
