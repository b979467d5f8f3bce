"""Errors as a person reads them: one line naming what to look at."""
from __future__ import annotations

import errno

from .calibration.board import CalibrationError
from .camera import RigError
from .params import ParamsError
from .session import SessionError
from .sources import SourceError
from .steps import AnalysisError
from .store import StoreError, WriteError


def one_line(exc: BaseException) -> str:
    """A one-line description of an error for a person (what the command line prints).

    The package's own errors say what to look at and are shown as they are;
    an operating-system error gets a hint (disk full, permission, ...); any
    other error is named as unexpected.

    Examples
    --------
    >>> one_line(ParamsError("analysis.json: parameter 'smooth.span': expected a number in (0, 1], got 2"))
    "analysis.json: parameter 'smooth.span': expected a number in (0, 1], got 2"
    >>> one_line(ZeroDivisionError("division by zero"))
    'ZeroDivisionError: division by zero (an unexpected error; --debug shows where, please report it)'
    """
    if isinstance(exc, OSError) and exc.strerror:
        hint = {errno.ENOSPC: "the disk is full: free some space or choose another --out",
                errno.EDQUOT: "the disk quota is used up: free some space or choose another --out",
                errno.EACCES: "permission denied: choose a folder you can write to",
                errno.EPERM: "not permitted: choose a folder you can write to",
                errno.EROFS: "read-only file system: choose a folder you can write to",
                errno.ENAMETOOLONG: "the path is too long: choose a shorter --out"}.get(exc.errno, "")
        if isinstance(exc, WriteError):   # "cannot write FILE: text (hint)[; DIR is as it was before the run]"
            text = exc.describe(hint)
        else:
            where = f"{exc.filename}: " if exc.filename else ""
            text = f"{where}{exc.strerror}" + (f" ({hint})" if hint else "")
    else:
        known = (SessionError, ParamsError, AnalysisError, StoreError, RigError, SourceError, CalibrationError)
        text = str(exc) if isinstance(exc, known) else \
            f"{type(exc).__name__}: {exc} (an unexpected error; --debug shows where, please report it)"
        if isinstance(exc, AnalysisError) and exc.__cause__ is not None:   # a step's unexpected error
            text += " (--debug shows where)"
    return " ".join(text.split())
