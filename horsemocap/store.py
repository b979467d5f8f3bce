"""Atomic writes and the per-session results store.

Results are written under a results folder chosen by the user (never inside
the input session). Every write goes to a temporary file in the same folder
and is renamed into place, so a reader sees a whole file or none.

A :class:`ResultsStore` keeps one sub-folder per pipeline step
(``<results>/steps/<step>/``) with arrays in ``.npz`` and small facts in
``.json``; notebooks load what an earlier step computed and compute it with
the default parameters when absent.
"""
from __future__ import annotations

import json
import os
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
    """Results of one session's analysis, one sub-folder per step.

    Parameters
    ----------
    root : Path
        The results folder (``--out DIR``).
    """

    root: Path

    def __post_init__(self):
        object.__setattr__(self, "root", Path(self.root))

    def step_dir(self, step: str) -> Path:
        return self.root / "steps" / step

    def has(self, step: str) -> bool:
        """True when ``step`` has been written whole (its ``done.json`` exists)."""
        return (self.step_dir(step) / "done.json").is_file()

    def save(self, step: str, arrays: dict | None = None, info: dict | None = None) -> Path:
        """Save a step's arrays and facts; ``done.json`` is written last."""
        d = self.step_dir(step)
        if arrays:
            atomic_write_npz(d / "arrays.npz", **{k: np.asarray(v) for k, v in arrays.items()})
        atomic_write_json(d / "info.json", info or {})
        atomic_write_json(d / "done.json", {"step": step})
        return d

    def load(self, step: str) -> tuple[dict, dict]:
        """``(arrays, info)`` of a saved step; KeyError if it is absent."""
        if not self.has(step):
            raise KeyError(f"{self.root}: step '{step}' has no saved results")
        d = self.step_dir(step)
        arrays = {}
        if (d / "arrays.npz").is_file():
            with np.load(d / "arrays.npz", allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        info = json.loads((d / "info.json").read_text())
        return arrays, info
