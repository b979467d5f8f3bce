"""forking.beside: a second computation in a forked copy while this process computes the first; the same
values, errors and warnings as computing both here."""
import os
import warnings

import pytest

from horsemocap import forking


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


def test_an_error_of_the_first_is_raised_without_waiting_for_a_copy_blocked_in_sending(fork):
    def fails():
        raise KeyError("the pose failed")
    with pytest.raises(KeyError, match="the pose failed"):
        forking.beside(fails, lambda: b"x" * (4 * forking.PIPE_CHUNK))   # more than a pipe holds


def test_the_warnings_of_the_second_are_raised_here(fork):
    def warns():
        warnings.warn("omega near the markers' plane", RuntimeWarning)
        return 2
    with pytest.warns(RuntimeWarning, match="omega near the markers' plane"):
        assert forking.beside(lambda: 1, warns) == (1, 2)


def test_a_value_that_cannot_be_sent_back_is_computed_here(fork):
    here, there = forking.beside(lambda: 1, lambda: (lambda: os.getpid()))   # a lambda cannot be pickled
    assert here == 1 and there() == os.getpid()
