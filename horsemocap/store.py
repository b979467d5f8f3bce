"""Atomic writes and the per-session results store.

Results are written under a results folder chosen by the user (never inside
the input session). Every write goes to a temporary file in the same folder
and is renamed into place, so a reader sees a whole file or none.

A :class:`ResultsStore` keeps each pipeline step's result under the results
folder (``<results>/steps/<step>.pkl``), keyed by a fingerprint of the
session, the parameters and the code; notebooks load what an earlier one
computed and compute it with the default parameters when absent.
"""
from __future__ import annotations

import json
import os
import pickle
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


class StoreError(RuntimeError):
    """A results folder that cannot be used (e.g. inside the input session)."""


def _atomic_write(path: Path, write) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    """Write text (UTF-8) to ``path`` atomically."""
    return _atomic_write(Path(path), lambda fh: fh.write(text.encode("utf-8")))


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write bytes to ``path`` atomically."""
    return _atomic_write(Path(path), lambda fh: fh.write(data))


def atomic_write_json(path, obj) -> Path:
    """Write ``obj`` as indented JSON atomically (NumPy scalars/arrays allowed)."""
    return atomic_write_text(path, json.dumps(obj, indent=2, default=_json_default) + "\n")


def atomic_write_npz(path, **arrays) -> Path:
    """Write arrays to a compressed ``.npz`` atomically."""
    return _atomic_write(Path(path), lambda fh: np.savez_compressed(fh, **arrays))


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"cannot write {type(o).__name__} as JSON")


def check_outside(results_dir, session_dir) -> None:
    """Raise :class:`StoreError` if ``results_dir`` lies inside ``session_dir``."""
    res = Path(results_dir).resolve()
    ses = Path(session_dir).resolve()
    if res == ses or ses in res.parents:
        raise StoreError(
            f"results folder {results_dir} lies inside the input session {session_dir}; "
            "choose a folder outside it (horsemocap never writes into a session)")


@dataclass(frozen=True)
class ResultsStore:
    """Step results of one session's analysis, so a notebook reuses what an
    earlier one computed.

    Each step's result is pickled to ``<root>/steps/<step>.pkl`` together
    with a key (a fingerprint of the session, the parameters and the
    package's code); a result is only returned for the same key, so a change
    of any of them recomputes it. Files are written atomically.

    Parameters
    ----------
    root : Path
        The results folder.
    """

    root: Path

    def __post_init__(self):
        object.__setattr__(self, "root", Path(self.root))

    def path(self, step: str) -> Path:
        return self.root / "steps" / f"{step}.pkl"

    def save(self, step: str, result, key: str) -> Path:
        """Store ``result`` of ``step`` under ``key``."""
        payload = pickle.dumps({"key": key, "result": result}, protocol=pickle.HIGHEST_PROTOCOL)
        return atomic_write_bytes(self.path(step), payload)

    def load(self, step: str, key: str):
        """The stored result of ``step`` for ``key``, or None (absent, other key, unreadable)."""
        p = self.path(step)
        if not p.is_file():
            return None
        try:
            payload = pickle.loads(p.read_bytes())
        except Exception:  # a file from another version of a class: recompute
            return None
        return payload["result"] if payload.get("key") == key else None
