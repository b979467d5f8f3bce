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

FINGERPRINT_DIGEST = "sha256"   # with the processor's SHA instructions, faster than BLAKE2b
# (device, inode, size, mtime, ctime) -> digest of the whole file, for this process: the ctime changes with
# every write to the file and cannot be set back (as the mtime can), so a changed byte is hashed again
_DIGESTS: dict = {}


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


def file_digest(path: Path) -> str:
    """The SHA-256 digest of every byte of ``path`` (read in blocks; kept for the process while unchanged).

    Examples
    --------
    >>> import tempfile
    >>> p = Path(tempfile.mkdtemp()) / "a.bin"; _ = p.write_bytes(b"x" * 10)
    >>> file_digest(p) == hashlib.sha256(b"x" * 10).hexdigest()
    True
    """
    st = os.stat(path)
    known = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    cached = _DIGESTS.get(str(path))
    if cached is not None and cached[0] == known:
        return cached[1]
    with open(path, "rb") as fh:
        digest = hashlib.file_digest(fh, FINGERPRINT_DIGEST).hexdigest()
    _DIGESTS[str(path)] = (known, digest)
    return digest


def file_fingerprint(path: Path) -> str:
    """``path``, size, mtime (ns) and the SHA-256 digest of every byte of it.

    Any change of a byte anywhere in the file (a frame in the middle of a
    video rewritten with its size and modification time kept), of its
    length or of its modification time changes it.

    Examples
    --------
    >>> import tempfile
    >>> p = Path(tempfile.mkdtemp()) / "a.txt"; _ = p.write_text("x")
    >>> file_fingerprint(p) == file_fingerprint(p)
    True
    """
    st = path.stat()
    return f"{path}|{st.st_size}|{st.st_mtime_ns}|{file_digest(path)}"


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
