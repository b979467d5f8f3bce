"""Independent tasks shared with a forked copy of the process, where that is safe.

The report's figures and the passes of a long recording are independent
computations on data already in memory; on two cores a forked copy of the
process can take half of them without pickling the data there (only the
values come back).
"""
from __future__ import annotations

import multiprocessing
import os
import pickle
import threading


def run_beside(tasks) -> list:
    """The values of ``tasks`` (callables without arguments), in order, a forked copy of this process taking
    tasks beside this one where it can.

    Where the system can ``fork``, has two or more cores, and this process
    runs no other Python thread and is not itself a worker of a pool (a
    batch's worker already shares the cores with the others), a forked copy
    of this process takes tasks beside it: the two take the next task not
    yet taken as each becomes free (one byte per task read from a shared
    pipe: reading one byte is atomic), so a slower task does not leave one
    of them waiting, and the copy sends its values back pickled. The copy
    computes with the same code and data, so the values are the same either
    way; those it did not deliver are computed here.

    The copy is made only while this process runs no other Python thread (a
    Jupyter kernel's, an application's): a lock another thread holds at the
    fork would stay held in the copy forever. The native threads left idle
    by OpenCV and the BLAS hold none while they wait, and glibc and OpenBLAS
    reset their own locks at a fork.

    Examples
    --------
    >>> run_beside([lambda: 1, lambda: 2, lambda: 3])
    [1, 2, 3]
    """
    tasks = list(tasks)
    if (len(tasks) < 2 or len(tasks) > 255 or not hasattr(os, "fork") or (os.cpu_count() or 1) < 2
            or threading.active_count() > 1 or multiprocessing.parent_process() is not None):
        return [task() for task in tasks]
    claims_r, claims_w = os.pipe()
    os.write(claims_w, bytes(range(len(tasks))))
    os.close(claims_w)
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:                                     # the copy: compute, send, leave without cleanup
        code = 1
        try:
            os.close(read_end)
            done = _claimed(tasks, claims_r)
            with os.fdopen(write_end, "wb") as sent:
                pickle.dump(done, sent)
            code = 0
        finally:
            os._exit(code)
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


def _claimed(tasks, claims_fd: int) -> dict:
    """The tasks this process takes from the shared pipe of task numbers, computed: {number: value}."""
    done = {}
    while True:
        claim = os.read(claims_fd, 1)
        if not claim:
            return done
        done[claim[0]] = tasks[claim[0]]()
