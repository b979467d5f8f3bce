"""Process-wide thread settings of the libraries, limited while the pipeline runs its own threads.

The analysis parallelises by itself (the board views detected by threads,
the rig calibrated while the sync step reads the videos, the report's
figures drawn by a forked process). The libraries underneath have thread
pools of their own: OpenCV's ``parallel_for`` and the BLAS behind NumPy,
SciPy and OpenCV (OpenBLAS). The calibration's matrices are small (a bundle
adjustment's 306 x 306 normal equations), where a second BLAS thread only
waits for work and slows the calibration down (``benchmarks/README.md``).

Both settings are process-wide: two blocks overlapping in threads would
restore each other's setting. :class:`SingleThreaded` counts the blocks
inside under a lock; the first limits the library, the last restores it.
Only the first block changes the setting, so a caller that enters a block
in the main thread before starting threads that enter their own (as
:func:`horsemocap.pipeline.analyze` does) keeps every change of the BLAS
setting in the main thread, where threadpoolctl expects it.
"""
from __future__ import annotations

import threading
from contextlib import contextmanager

import cv2
from threadpoolctl import threadpool_limits


class SingleThreaded:
    """A context manager limiting one library to one thread, counted across threads.

    Parameters
    ----------
    limit : callable() -> callable()
        Limits the library to one thread and returns the function that
        restores the setting it found.

    Examples
    --------
    A library limited while two blocks overlap, restored once when the last ends:

    >>> calls = []
    >>> def limit():
    ...     calls.append("limit")
    ...     return lambda: calls.append("restore")
    >>> single = SingleThreaded(limit)
    >>> with single():
    ...     with single():
    ...         pass
    >>> calls
    ['limit', 'restore']
    """

    def __init__(self, limit):
        self._limit = limit
        self._lock = threading.Lock()
        self._inside = 0
        self._restore = None

    @contextmanager
    def __call__(self):
        with self._lock:
            if self._inside == 0:
                self._restore = self._limit()
            self._inside += 1
        try:
            yield
        finally:
            with self._lock:
                self._inside -= 1
                if self._inside == 0:
                    restore, self._restore = self._restore, None
                    restore()


def _limit_opencv():
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    return lambda: cv2.setNumThreads(before)


def _limit_blas():
    return threadpool_limits(limits=1, user_api="blas").restore_original_limits


opencv_single_threaded = SingleThreaded(_limit_opencv)
"""OpenCV limited to one thread of its own inside the block (``cv2.setNumThreads``)."""

blas_single_threaded = SingleThreaded(_limit_blas)
"""The BLAS libraries loaded in the process (NumPy's, SciPy's, OpenCV's OpenBLAS) limited to one
thread inside the block (``threadpoolctl.threadpool_limits``)."""
