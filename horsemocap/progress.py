"""Progress of a run for a person: step lines, and counts inside the long steps.

A progress callback is ``progress(step, message)``. The long steps
(calibration views, detection frames) also report counts through
:func:`counter`, which calls ``progress(step, message, done, total)`` only on
a callback that says it takes counts (``counts = True``, as
:class:`ProgressPrinter`); any other callback (``lambda *a: None``, a
two-argument function) sees the step lines only.

On a terminal (``stream.isatty()``) a count is a bar redrawn in place::

    [horsemocap] rig: detecting the board in camera 'left' [########------------]  12/30

otherwise (a log file, a notebook, CI) it is a plain line at the first
count, at every quarter and at the last, and at least once a minute in
between (with the time left at the rate so far), so a log shows that the step
works without one line per frame.
"""
from __future__ import annotations

import sys
import time

BAR_WIDTH = 24
HEARTBEAT_S = 60.0   # a plain count line at least this often (s) during a long count
ESTIMATE_AFTER_S = 10.0   # a count's time left is said once it has run this long (s)


def progress_bar(done: int, total: int, width: int = BAR_WIDTH) -> str:
    """``[#####-----]  done/total`` with ``round(width * done / total)`` filled cells.

    ``done`` is clipped to ``0..total``; a ``total`` below 1 gives an empty bar.

    Examples
    --------
    >>> progress_bar(3, 10)
    '[#######-----------------]  3/10'
    >>> progress_bar(10, 10, width=5)
    '[#####] 10/10'
    """
    total = int(total)
    done = min(max(int(done), 0), max(total, 0))
    filled = 0 if total < 1 else round(width * done / total)
    digits = len(str(max(total, 0)))
    return f"[{'#' * filled}{'-' * (width - filled)}] {done:>{digits}}/{total}"


def plain_count_due(done: int, total: int) -> bool:
    """Whether a plain (non-terminal) line is printed for count ``done`` of ``total``:
    the first, the last, and the first count at or past each quarter.

    Examples
    --------
    >>> [done for done in range(1, 9) if plain_count_due(done, 8)]
    [1, 2, 4, 6, 8]
    """
    if total <= 0:
        return False
    if done in (1, total):
        return True
    quarter = [int(-(-q * total // 4)) for q in (1, 2, 3)]  # ceil(q * total / 4)
    return done in quarter


class ProgressPrinter:
    """The command's progress callback: ``[horsemocap] step: message`` lines on ``stream``.

    Parameters
    ----------
    stream : file, optional
        Default ``sys.stderr`` (looked up when printing).
    tty : bool, optional
        Draw counts as a bar redrawn in place; default ``stream.isatty()``.
    heartbeat_s : float
        Plain lines: a count line at least this often (s), besides the first,
        the quarters and the last (:func:`plain_count_due`).
    clock : callable
        Seconds (``time.monotonic``), for the heartbeat and the time left.

    Examples
    --------
    >>> import io
    >>> now = iter([0.0, 30.0, 70.0, 75.0])
    >>> buf = io.StringIO()
    >>> p = ProgressPrinter(buf, clock=lambda: next(now))
    >>> for k in (1, 2, 3, 4):
    ...     p("kinematics", "windows", k, 100)
    >>> print(buf.getvalue(), end="")
    [horsemocap] kinematics: windows 1/100
    [horsemocap] kinematics: windows 3/100 (about 57 min left)
    """

    counts = True

    def __init__(self, stream=None, tty: bool | None = None, heartbeat_s: float = HEARTBEAT_S,
                 clock=time.monotonic):
        self._stream = stream
        self._tty = tty
        self._open = False  # a bar is drawn on the current line
        self._heartbeat_s = float(heartbeat_s)
        self._clock = clock
        self._count = None  # (step, message, total, first count's time and value, last plain line's time)

    @property
    def stream(self):
        return self._stream or sys.stderr

    @property
    def tty(self) -> bool:
        if self._tty is not None:
            return self._tty
        try:
            return bool(self.stream.isatty())
        except (AttributeError, ValueError):
            return False

    def __call__(self, step: str, message: str, done: int | None = None, total: int | None = None) -> None:
        out = self.stream
        if done is None or total is None:
            self._close()
            print(f"[horsemocap] {step}: {message}", file=out, flush=True)
            return
        if self.tty:
            out.write(f"\r[horsemocap] {step}: {message} {progress_bar(done, total)}")
            self._open = done < total
            if not self._open:
                out.write("\n")
            out.flush()
        else:
            self._plain_count(step, message, done, total)

    def _plain_count(self, step, message, done, total):
        now = self._clock()
        key = (step, message, total)
        if self._count is None or self._count[0] != key or done < self._count[2]:
            self._count = [key, now, done, now]
        _, first_time, first_done, last_time = self._count
        if not (plain_count_due(done, total) or now - last_time >= self._heartbeat_s):
            return
        self._count[3] = now
        left = ""
        if now - first_time >= ESTIMATE_AFTER_S and first_done < done < total:
            seconds = (now - first_time) / (done - first_done) * (total - done)
            left = f" (about {seconds / 60:.0f} min left)" if seconds >= 90 else f" (about {seconds:.0f} s left)"
        print(f"[horsemocap] {step}: {message} {done}/{total}{left}", file=self.stream, flush=True)

    def _close(self):
        if self._open:
            self.stream.write("\n")
            self._open = False


def counter(progress, step: str, message: str, total: int):
    """A function ``tick(done)`` reporting ``done`` of ``total`` to ``progress``.

    Does nothing when ``progress`` is None or does not take counts
    (no ``counts = True`` attribute).
    """
    if progress is None or not getattr(progress, "counts", False):
        return lambda done: None
    return lambda done: progress(step, message, int(done), int(total))


class CountingFrames:
    """A frame sequence that reports how many distinct frames were read so far.

    Wraps a sequence (``len``, ``[k]``, ``close``) and calls ``tick(count)``
    the first time each index is read, so a step that reads every frame once
    in any order (forward, then backward from an anchor) counts to ``len``.
    Every other attribute is the wrapped sequence's.
    """

    def __init__(self, frames, tick):
        self._frames, self._tick, self._seen = frames, tick, set()

    def __len__(self):
        return len(self._frames)

    def __getitem__(self, k):
        item = self._frames[k]
        if isinstance(k, (int,)) or hasattr(k, "__index__"):
            i = int(k) % max(len(self), 1)
            if i not in self._seen:
                self._seen.add(i)
                self._tick(len(self._seen))
        return item

    def __iter__(self):
        for k in range(len(self)):
            yield self[k]

    def __getattr__(self, name):
        return getattr(self._frames, name)
