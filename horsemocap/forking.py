"""Independent tasks shared with a forked copy of the process, where that is safe.

The report's figures and the passes of a long recording are independent
computations on data already in memory; on two cores a forked copy of the
process can take half of them without pickling the data there (only the
values come back) (:func:`run_beside`). A computation whose module is slow
to load (the report's figures: matplotlib) can have a copy forked before
its data exist, which loads the module while this process works
(:class:`EarlyCall`).
"""
from __future__ import annotations

import importlib
import multiprocessing
import os
import pickle
import signal
import threading


def can_fork() -> bool:
    """Whether a forked copy of this process may compute beside it.

    Only where the system can ``fork``, has two or more cores, and this
    process runs no other Python thread and is not itself a worker of a pool
    (a batch's worker already shares the cores with the others). The copy is
    made only while no other Python thread runs (a Jupyter kernel's, an
    application's): a lock another thread holds at the fork would stay held
    in the copy forever. The native threads left idle by OpenCV and the BLAS
    hold none while they wait, and glibc and OpenBLAS reset their own locks
    at a fork.
    """
    return (hasattr(os, "fork") and (os.cpu_count() or 1) >= 2 and threading.active_count() == 1
            and multiprocessing.parent_process() is None)


def run_beside(tasks) -> list:
    """The values of ``tasks`` (callables without arguments), in order, a forked copy of this process taking
    tasks beside this one where it can.

    Where that is safe (:func:`can_fork`), a forked copy of this process
    takes tasks beside it: the two take the next task not yet taken as each
    becomes free (one byte per task read from a shared pipe: reading one
    byte is atomic), so a slower task does not leave one of them waiting,
    and the copy sends its values back pickled. The copy computes with the
    same code and data, so the values are the same either way; those it did
    not deliver are computed here.

    Examples
    --------
    >>> run_beside([lambda: 1, lambda: 2, lambda: 3])
    [1, 2, 3]
    """
    tasks = list(tasks)
    if len(tasks) < 2 or len(tasks) > 255 or not can_fork():
        return [task() for task in tasks]
    claims_r, claims_w = os.pipe()
    os.write(claims_w, bytes(range(len(tasks))))
    os.close(claims_w)
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:                                     # the copy: compute, send, leave without cleanup
        def work():
            os.close(read_end)
            done = _claimed(tasks, claims_r)
            with os.fdopen(write_end, "wb") as sent:
                pickle.dump(done, sent)
        _child(work)
    os.close(write_end)
    got = os.fdopen(read_end, "rb")
    try:
        # an error here closes the read end before the wait: a copy blocked in sending gets a
        # broken pipe and exits, instead of both waiting for each other
        with got:
            out = _claimed(tasks, claims_r)
            data = got.read()
    finally:
        _, status = os.waitpid(pid, 0)
        os.close(claims_r)
    if status == 0 and data:
        out.update(pickle.loads(data))
    return [out[i] if i in out else task() for i, task in enumerate(tasks)]


def _child(work) -> None:
    """A forked copy's whole life: ``work()``, then leave at once without the parent's cleanup (exit status 0
    only when ``work`` finished; an error is seen by the parent as a copy that delivered nothing)."""
    code = 1
    try:
        work()
        code = 0
    finally:
        os._exit(code)


def _claimed(tasks, claims_fd: int) -> dict:
    """The tasks this process takes from the shared pipe of task numbers, computed: {number: value}."""
    done = {}
    while True:
        claim = os.read(claims_fd, 1)
        if not claim:
            return done
        done[claim[0]] = tasks[claim[0]]()


class EarlyCall:
    """``module.function(*args)``, computed by a copy of this process forked before ``args`` exist.

    Made where it is safe (:func:`can_fork`), the copy loads ``module``
    at once, beside this process' own work, then waits for the arguments
    (:meth:`submit`, sent pickled through a pipe), computes, and sends the
    value back (:meth:`result`). Without a copy, or when the copy fails,
    :meth:`result` loads the module and computes here: the value is the same
    either way. :meth:`close` (or leaving the ``with`` block) ends a copy
    that was given nothing: it reads the end of the pipe and exits.

    Examples
    --------
    >>> with EarlyCall("math", "hypot") as call:
    ...     call.submit(3.0, 4.0)
    ...     call.result()
    5.0
    """

    def __init__(self, module: str, function: str, fork: bool = True):
        self.module, self.function = module, function
        self._args = None
        self._pid = self._args_fd = self._value_fd = None
        if fork and can_fork():
            self._fork()

    def _fork(self) -> None:
        args_r, args_w = os.pipe()
        value_r, value_w = os.pipe()
        pid = os.fork()
        if pid == 0:                                 # the copy: load, wait, compute, send, leave
            def work():
                os.close(args_w)
                os.close(value_r)
                target = getattr(importlib.import_module(self.module), self.function)
                with os.fdopen(args_r, "rb") as given:
                    data = given.read()
                if data:
                    value = target(*pickle.loads(data))
                    with os.fdopen(value_w, "wb") as sent:
                        pickle.dump(value, sent)
            _child(work)
        os.close(args_r)
        os.close(value_w)
        self._pid, self._args_fd, self._value_fd = pid, args_w, value_r

    @property
    def forked(self) -> bool:
        """Whether a copy computes the call."""
        return self._pid is not None

    @property
    def submitted(self) -> bool:
        """Whether the call has its arguments."""
        return self._args is not None

    def submit(self, *args) -> None:
        """Give the call its arguments (once)."""
        if self._args is not None:
            raise RuntimeError(f"{self.module}.{self.function}: arguments given twice")
        self._args = args
        if self._args_fd is not None:
            fd, self._args_fd = self._args_fd, None
            try:
                with os.fdopen(fd, "wb") as sent:
                    pickle.dump(args, sent)
            except OSError:          # the copy has gone (its failure is seen in result): computed here
                pass

    def result(self):
        """The call's value: the copy's, or computed here."""
        if self._args is None:
            raise RuntimeError(f"{self.module}.{self.function}: no arguments given (submit)")
        if self._value_fd is not None:
            fd, self._value_fd = self._value_fd, None
            with os.fdopen(fd, "rb") as got:
                data = got.read()
            if self._wait() == 0 and data:
                return pickle.loads(data)
        return getattr(importlib.import_module(self.module), self.function)(*self._args)

    def _wait(self) -> int | None:
        pid, self._pid = self._pid, None
        if pid is None:
            return None
        _, status = os.waitpid(pid, 0)
        return status

    def close(self) -> None:
        """End the copy (if any) without waiting for a value."""
        for name in ("_args_fd", "_value_fd"):
            fd = getattr(self, name)
            if fd is not None:
                setattr(self, name, None)
                os.close(fd)
        if self._pid is not None and self._args is not None:
            os.kill(self._pid, signal.SIGKILL)       # computing a value nobody will read
        self._wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class EarlyCalls:
    """``module.function(*args)`` for every ``args`` given, each computed by a copy of this process as soon
    as it is given; the copy is forked before any of them exists.

    As :class:`EarlyCall`, for work that becomes ready piece by piece: the
    report's figures are described step by step as the analysis runs, and a
    figure drawn while the analysis goes on is not waited for after it. Made
    where it is safe (:func:`can_fork`), the copy loads ``module`` at once,
    then computes each call as its arguments arrive (:meth:`submit`, pickled
    through a pipe, in order) and sends every value back at the end
    (:meth:`results`). A :meth:`submit` waits only when the pipe is full (the
    copy busy with an earlier call and the arguments larger than the pipe's
    buffer). Without a copy, or when the copy fails, :meth:`results` computes
    every call here: the values are the same either way.

    Examples
    --------
    >>> with EarlyCalls("math", "hypot") as calls:
    ...     calls.submit(3.0, 4.0)
    ...     calls.submit(5.0, 12.0)
    ...     calls.results()
    [5.0, 13.0]
    """

    def __init__(self, module: str, function: str, fork: bool = True):
        self.module, self.function = module, function
        self._given: list = []
        self._pid = self._args_file = self._value_fd = None
        self._copy_failed = False
        if fork and can_fork():
            self._fork()

    def _fork(self) -> None:
        args_r, args_w = os.pipe()
        value_r, value_w = os.pipe()
        pid = os.fork()
        if pid == 0:                                 # the copy: load, compute each call as it comes, send
            def work():
                os.close(args_w)
                os.close(value_r)
                target = getattr(importlib.import_module(self.module), self.function)
                values = []
                with os.fdopen(args_r, "rb") as given:
                    while True:
                        try:
                            args = pickle.load(given)
                        except EOFError:
                            break
                        values.append(target(*args))
                with os.fdopen(value_w, "wb") as sent:
                    pickle.dump(values, sent)
            _child(work)
        os.close(args_r)
        os.close(value_w)
        self._pid, self._args_file, self._value_fd = pid, os.fdopen(args_w, "wb"), value_r

    @property
    def forked(self) -> bool:
        """Whether a copy computes the calls."""
        return self._pid is not None

    @property
    def given(self) -> list:
        """The arguments of every call given so far, in order (each a tuple)."""
        return list(self._given)

    def submit(self, *args) -> None:
        """Give one call its arguments (its value is the next of :meth:`results`)."""
        self._given.append(args)
        if self._args_file is not None and not self._copy_failed:
            try:
                pickle.dump(args, self._args_file)
                self._args_file.flush()
            except OSError:          # the copy has gone (seen in results): computed here
                self._copy_failed = True

    def results(self) -> list:
        """The values of every call given, in order: the copy's, or computed here."""
        values = None
        if self._value_fd is not None:
            self._close_args()
            fd, self._value_fd = self._value_fd, None
            with os.fdopen(fd, "rb") as got:
                data = got.read()
            if self._wait() == 0 and data and not self._copy_failed:
                values = pickle.loads(data)
        if values is None or len(values) != len(self._given):
            target = getattr(importlib.import_module(self.module), self.function)
            values = [target(*args) for args in self._given]
        return values

    def _close_args(self) -> None:
        f, self._args_file = self._args_file, None
        if f is not None:
            try:
                f.close()
            except OSError:          # the copy has gone: its end was closed
                self._copy_failed = True

    def _wait(self) -> int | None:
        pid, self._pid = self._pid, None
        if pid is None:
            return None
        _, status = os.waitpid(pid, 0)
        return status

    def close(self) -> None:
        """End the copy (if any) without waiting for its values."""
        busy = self._pid is not None and bool(self._given)
        self._close_args()
        if self._value_fd is not None:
            fd, self._value_fd = self._value_fd, None
            os.close(fd)
        if busy:
            os.kill(self._pid, signal.SIGKILL)       # computing values nobody will read
        self._wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
