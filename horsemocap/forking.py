"""Independent tasks shared with a forked copy of the process, where that is safe.

The report's figures and the passes of a long recording are independent
computations on data already in memory; on two cores a forked copy of the
process can take half of them without pickling the data there (only the
values come back) (:func:`run_beside`). A computation whose module is slow
to load (the report's figures: matplotlib) can have a copy forked before
its data exist, which loads the module while this process works
(:class:`EarlyCalls`).
"""
from __future__ import annotations

import importlib
import multiprocessing
import os
import pickle
import signal
import threading
import warnings

#: Bytes of arguments the writer thread offers the pipe at once (a pipe's buffer on Linux): the unsent
#: arguments are copied a chunk at a time, not whole.
PIPE_CHUNK = 64 * 1024

#: File descriptors only this process may hold (the ends of an :class:`EarlyCalls` copy's pipes kept
#: here): a copy forked later closes them first (:func:`_child`), or the first copy would never see the
#: end of its arguments while the later one lives.
_PARENT_ONLY_FDS: set = set()


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


def beside(here, there) -> tuple:
    """``(here(), there())``, ``there`` computed by a forked copy of this process while this one computes
    ``here``, where that is safe (:func:`can_fork`).

    The copy computes with the same code, data and warning filters, so the
    values are the same either way; only ``there``'s value comes back
    (pickled), with the warnings it showed, which are shown again here
    (:func:`warnings.showwarning`). Elsewhere, or when the copy delivers
    nothing (an error in ``there``, a value that cannot be sent back, no
    fork to be had), ``there`` is computed here after ``here``, as without
    a copy: its error is then raised here. An error in ``here`` (Ctrl-C
    too) kills the copy.

    Examples
    --------
    >>> beside(lambda: 1 + 1, lambda: 2 * 3)
    (2, 6)
    """
    if not can_fork():
        return here(), there()
    try:
        read_end, write_end = os.pipe()
    except OSError:                                  # no file descriptor left: the copy is only a speed-up
        return here(), there()
    try:
        pid = os.fork()
    except OSError:                                  # the system refuses the copy (its memory, its processes)
        os.close(read_end)
        os.close(write_end)
        return here(), there()
    if pid == 0:                                     # the copy: compute, send, leave without cleanup
        def work():
            os.close(read_end)
            with warnings.catch_warnings(record=True) as caught:
                value = there()
            shown = [(w.message, w.category, w.filename, w.lineno) for w in caught]
            with os.fdopen(write_end, "wb") as sent:
                pickle.dump((value, shown), sent)
        _child(work)
    os.close(write_end)
    try:
        with os.fdopen(read_end, "rb") as got:
            mine = here()
            data = got.read()
    except BaseException:
        os.kill(pid, signal.SIGKILL)                 # its value is not wanted any more
        raise
    finally:
        _, status = os.waitpid(pid, 0)
    try:
        value, shown = pickle.loads(data) if status == 0 and data else (None, None)
    except Exception:       # noqa: BLE001 - a value that cannot be read back is computed here
        shown = None
    if shown is None:
        return mine, there()
    for message, category, filename, lineno in shown:
        warnings.showwarning(message, category, filename, lineno)
    return mine, value


def fork_call(work) -> int:
    """Fork a copy of this process that runs ``work()`` and leaves at once (no cleanup of this process';
    exit status 0 only when ``work`` finished); returns the copy's process id. Call it only where
    :func:`can_fork` says a copy is safe.

    Examples
    --------
    >>> pid = fork_call(lambda: None)
    >>> os.waitpid(pid, 0)[1]
    0
    """
    pid = os.fork()
    if pid == 0:
        _child(work)
    return pid


def _child(work) -> None:
    """A forked copy's whole life: the pipe ends only the parent may hold closed, ``work()``, then leave at
    once without the parent's cleanup (exit status 0 only when ``work`` finished; an error is seen by the
    parent as a copy that delivered nothing)."""
    code = 1
    try:
        for fd in tuple(_PARENT_ONLY_FDS):
            os.close(fd)
        _PARENT_ONLY_FDS.clear()
        work()
        code = 0
    finally:
        os._exit(code)


def _close_own(fd: int) -> None:
    """Close a pipe end only this process held (no longer closed by later copies: its number may be reused)."""
    _PARENT_ONLY_FDS.discard(fd)
    os.close(fd)


def _claimed(tasks, claims_fd: int) -> dict:
    """The tasks this process takes from the shared pipe of task numbers, computed: {number: value}."""
    done = {}
    while True:
        claim = os.read(claims_fd, 1)
        if not claim:
            return done
        done[claim[0]] = tasks[claim[0]]()


class EarlyCalls:
    """``module.function(*args)`` for every ``args`` given, each computed by a copy of this process as soon
    as it is given; the copy is forked before any of them exists.

    For a computation whose module is slow to load and whose work becomes
    ready piece by piece: the report's figures (matplotlib) are described
    step by step as the analysis runs, and a figure drawn while the analysis
    goes on is not waited for after it. Made where it is safe
    (:func:`can_fork`), the copy loads ``module`` at once, beside this
    process' own work, then computes each call as its arguments arrive
    (:meth:`submit`, pickled through a pipe, in order) and sends every value
    back at the end (:meth:`results`). :meth:`submit` never waits for the
    copy: arguments the pipe cannot take at once (the copy still loading its
    module or busy with an earlier call) are written by a thread of this
    process that ends when they are all written. Without a copy, or when the
    copy fails, :meth:`results` computes every call here: the values are the
    same either way. :meth:`close` (or leaving the ``with`` block) ends a
    copy whose values nobody will read at once (it is killed, not waited
    for).

    With ``hold=True`` the copy waits, forked but idle, until :meth:`start`
    (or the first :meth:`submit`, or :meth:`results`) before it loads
    ``module``: on two cores, work this process started beside it (a
    search decoding videos) then has the other core to itself, and the
    module loads after it.

    Examples
    --------
    >>> with EarlyCalls("math", "hypot") as calls:
    ...     calls.submit(3.0, 4.0)
    ...     calls.submit(5.0, 12.0)
    ...     calls.results()
    [5.0, 13.0]
    >>> with EarlyCalls("math", "hypot", hold=True) as calls:
    ...     calls.start()                         # the copy loads math now
    ...     calls.submit(8.0, 15.0)
    ...     calls.results()
    [17.0]
    """

    def __init__(self, module: str, function: str, fork: bool = True, hold: bool = False):
        self.module, self.function = module, function
        self._given: list = []
        self._pid = self._args_fd = self._value_fd = self._start_fd = None
        self._copy_failed = False
        self._unsent = bytearray()              # pickled arguments the pipe has not taken yet
        self._unsent_lock = threading.Lock()
        self._writer: threading.Thread | None = None
        if fork and can_fork():
            self._fork(hold)

    def _fork(self, hold: bool) -> None:
        args_r, args_w = os.pipe()
        value_r, value_w = os.pipe()
        start_r, start_w = os.pipe() if hold else (None, None)
        pid = os.fork()
        if pid == 0:                                 # the copy: load, compute each call as it comes, send
            def work():
                os.close(args_w)
                os.close(value_r)
                if start_r is not None:              # held: one byte (or the parent's end closed) starts it
                    os.close(start_w)
                    os.read(start_r, 1)
                    os.close(start_r)
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
        if start_r is not None:
            os.close(start_r)
        os.set_blocking(args_w, False)              # submit writes what the pipe takes; the writer the rest
        self._pid, self._args_fd, self._value_fd, self._start_fd = pid, args_w, value_r, start_w
        _PARENT_ONLY_FDS.update(fd for fd in (args_w, value_r, start_w) if fd is not None)

    def start(self) -> None:
        """Let a held copy load its module now (nothing to do when it was not held, or was started);
        safe from any thread."""
        with self._unsent_lock:
            fd, self._start_fd = self._start_fd, None
        if fd is not None:
            try:
                os.write(fd, b"s")
            except OSError:          # the copy has gone (seen in results): computed here
                pass
            _close_own(fd)

    @property
    def forked(self) -> bool:
        """Whether a copy computes the calls."""
        return self._pid is not None

    @property
    def given(self) -> list:
        """The arguments of every call given so far, in order (each a tuple)."""
        return list(self._given)

    def submit(self, *args) -> None:
        """Give one call its arguments (its value is the next of :meth:`results`); returns at once."""
        self._given.append(args)
        if self._args_fd is None or self._copy_failed:
            return
        self.start()
        data = pickle.dumps(args, protocol=pickle.HIGHEST_PROTOCOL)
        with self._unsent_lock:
            writing = bool(self._unsent)             # the writer is sending earlier arguments: after them
            self._unsent += data
        if not writing:
            self._send_what_fits()

    def _send_what_fits(self) -> None:
        """Write to the pipe what it takes now; a writer thread sends the rest as the copy reads."""
        with self._unsent_lock:
            try:
                sent = os.write(self._args_fd, self._unsent)
            except BlockingIOError:
                sent = 0
            except OSError:          # the copy has gone (seen in results): computed here
                self._copy_failed = True
                self._unsent.clear()
                return
            del self._unsent[:sent]
            if self._unsent:
                self._writer = threading.Thread(target=self._write_rest, name="horsemocap-early-calls",
                                                daemon=True)
                self._writer.start()

    def _write_rest(self) -> None:
        """The writer thread: the unsent arguments, as the copy takes them (blocking writes: submit does not
        write while the thread runs); ends, the pipe's end non-blocking again, when none is left."""
        fd = self._args_fd
        os.set_blocking(fd, True)
        while True:
            with self._unsent_lock:
                if not self._unsent or self._copy_failed:
                    self._unsent.clear()
                    os.set_blocking(fd, False)
                    return
                chunk = bytes(self._unsent[:PIPE_CHUNK])
            try:
                sent = os.write(fd, chunk)
            except OSError:          # the copy has gone (seen in results): computed here
                self._copy_failed = True
                continue
            with self._unsent_lock:
                del self._unsent[:sent]

    def results(self) -> list:
        """The values of every call given, in order: the copy's, or computed here."""
        values = None
        if self._value_fd is not None:
            self.start()
            self._close_args()
            fd, self._value_fd = self._value_fd, None
            _PARENT_ONLY_FDS.discard(fd)            # before its number can be reused
            with os.fdopen(fd, "rb") as got:
                data = got.read()
            if self._wait() == 0 and data and not self._copy_failed:
                values = pickle.loads(data)
        if values is None or len(values) != len(self._given):
            target = getattr(importlib.import_module(self.module), self.function)
            values = [target(*args) for args in self._given]
        return values

    def _close_args(self) -> None:
        """Every argument sent, then the pipe's end closed (the copy sees the end of the calls)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.join()
        fd, self._args_fd = self._args_fd, None
        if fd is not None:
            _close_own(fd)

    def _wait(self) -> int | None:
        pid, self._pid = self._pid, None
        if pid is None:
            return None
        _, status = os.waitpid(pid, 0)
        return status

    def close(self) -> None:
        """End the copy (if any) without waiting for it: its values are not wanted (after :meth:`results`,
        there is nothing left to end)."""
        if self._pid is not None:
            os.kill(self._pid, signal.SIGKILL)       # loading its module or computing values nobody will read
        with self._unsent_lock:
            fd, self._start_fd = self._start_fd, None
        if fd is not None:
            _close_own(fd)
        if self._value_fd is not None:
            fd, self._value_fd = self._value_fd, None
            _close_own(fd)
        self._close_args()                           # the writer, if any, ends: the copy's end is closed
        self._wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
