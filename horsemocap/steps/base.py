"""What every step shares: the error a step raises, the base of the typed results, small helpers."""
from __future__ import annotations

import dataclasses

import numpy as np


class AnalysisError(RuntimeError):
    """A step that cannot go on; the message names the input to look at.

    Examples
    --------
    >>> str(AnalysisError("detect", "no markers"))
    "step 'detect': no markers"
    """

    def __init__(self, step: str, message: str):
        super().__init__(f"step '{step}': {message}")
        self.step = step


class StepResult:
    """Base of the typed, frozen results the steps hand each other.

    A step's result is produced once and never rewritten: a later step that
    corrects an earlier one's output (the markers' check of the flash
    offsets) carries the correction in its own result.
    """

    def replace(self, **changes):
        """A copy with ``changes`` (the result itself stays as it was)."""
        return dataclasses.replace(self, **changes)


def longest_run(mask) -> tuple[int, int] | None:
    """``(start, stop)`` of the longest run of True in ``mask``, or None.

    Examples
    --------
    >>> longest_run([False, True, True, False, True])
    (1, 3)
    """
    best, start = None, None
    for i, v in enumerate(list(np.asarray(mask, bool)) + [False]):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if best is None or i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return best


def frames_text(reference_camera: str, offsets: dict, first: int, last: int) -> str:
    """Synchronised frames ``first..last`` as the results files number them: the reference camera's own
    frames (``frame`` of trajectories.csv), with the synchronised index beside them.

    Examples
    --------
    >>> frames_text("left", {"left": 10}, 0, 4)
    "left camera's frames 10..14 (synchronised frames 0..4)"
    """
    off = int(offsets[reference_camera])
    return (f"{reference_camera} camera's frames {first + off}..{last + off} "
            f"(synchronised frames {first}..{last})")
