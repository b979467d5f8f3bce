"""Fingerprints of a run: the session's input files, the parameters and the package's code.

The results store (:class:`horsemocap.store.ResultsStore`) keeps a step's
result under its key, so a notebook reuses what an earlier one computed for
the same inputs, and a change of any of them recomputes the step and the
steps after it.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .session import Session
from .sources import list_images

FINGERPRINT_EDGE_BYTES = 1 << 20


def session_files(session: Session) -> list[Path]:
    """Every input file of a session: session.json, motion sources, calibration, stills.

    Folders (image sequences, calibration views) give their image files.
    """
    paths = [session.json_path]
    groups = [session.motion, session.calibration_images or {}, session.plumb or {}, session.static or {}]
    for group in groups:
        for cam in sorted(group):
            p = Path(group[cam])
            paths.extend(list_images(p) if p.is_dir() else [p])
    if session.rig_path is not None:
        paths.append(session.rig_path)
    return paths


def file_fingerprint(path: Path, edge: int = FINGERPRINT_EDGE_BYTES) -> str:
    """``path``, size, mtime (ns) and the SHA-256 of its first and last ``edge`` bytes.

    Any change of length, modification time or the bytes at either end
    (a replaced video, re-encoded images, a truncated file) changes it.
    Files up to ``2 * edge`` bytes are hashed whole.

    Examples
    --------
    >>> import tempfile
    >>> p = Path(tempfile.mkdtemp()) / "a.txt"; _ = p.write_text("x")
    >>> file_fingerprint(p) == file_fingerprint(p)
    True
    """
    st = path.stat()
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        if st.st_size <= 2 * edge:
            h.update(fh.read())
        else:
            h.update(fh.read(edge))
            fh.seek(-edge, os.SEEK_END)
            h.update(fh.read(edge))
    return f"{path}|{st.st_size}|{st.st_mtime_ns}|{h.hexdigest()}"


def code_fingerprint() -> str:
    """The SHA-256 of every module of the package (a new version recomputes every step)."""
    h = hashlib.sha256()
    for src in sorted(Path(__file__).parent.rglob("*.py")):
        h.update(src.read_bytes())
    return h.hexdigest()


def run_key(session: Session, params=None) -> str:
    """Fingerprint of a run: every input file of the session, the parameters and the package's code.

    ``params=None``: the files and the code only (:func:`horsemocap.pipeline.step_keys` adds each step's
    parameters).
    Each file of :func:`session_files` enters by :func:`file_fingerprint`.
    """
    h = hashlib.sha256()
    for path in session_files(session):
        h.update(file_fingerprint(path).encode("utf-8", "surrogateescape"))
    if params is not None:
        h.update(json.dumps(params.to_dict(), sort_keys=True, default=str).encode())
    h.update(code_fingerprint().encode())
    return h.hexdigest()
