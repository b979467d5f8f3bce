"""Whole runs: a results folder is replaced in one step, or left as it was.

``horsemocap analyze SESSION --out DIR`` never writes into ``DIR`` while it
runs. :class:`RunFolder` takes a lock beside ``DIR`` (``.DIR.lock``), writes
into a temporary folder beside it (``.DIR.run-<pid>-<random>``) and, when
the run ends, puts that folder in the place of ``DIR`` in one rename (an
atomic exchange of the two folders on Linux, ``renameat2(RENAME_EXCHANGE)``;
elsewhere two renames a few microseconds apart), then deletes the earlier
run's files. So a reader sees the earlier run's folder whole or the new one
whole, never a mix:

- the run succeeds: ``DIR`` holds the new results only;
- a step fails: ``DIR`` holds the files of the steps that finished, marked
  ``PARTIAL.txt`` and ``"complete": false`` in ``analysis.json`` (the
  earlier run's files are gone: they belonged to another analysis);
- Ctrl-C, SIGTERM, a full disk or any other error: the temporary folder is
  deleted and ``DIR`` is as before the run (SIGKILL leaves the temporary
  folder behind; the next run into ``DIR`` deletes it).

A second run into the same ``DIR`` while one holds the lock stops at once
with :class:`RunLockedError` (it does not wait). The lock is an ``flock``
on the lock file, so a killed run never leaves a stale lock. Folders and
files are created with the user's umask.
"""
from __future__ import annotations

import ctypes
import errno
import os
import secrets
import shutil
from pathlib import Path

from .store import StoreError

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

RESULTS_MARKERS = ("analysis.json", "PARTIAL.txt")


class RunLockedError(StoreError):
    """Another run is writing into the same results folder."""


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2``); False when not supported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    if fn(at_fdcwd, os.fsencode(str(a)), at_fdcwd, os.fsencode(str(b)), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _is_results_folder(path: Path, entries) -> bool:
    """An earlier horsemocap run's folder: its analysis.json says so, or it is marked partial."""
    import json

    if "PARTIAL.txt" in entries:
        return True
    if "analysis.json" not in entries:
        return False
    try:
        record = json.loads((path / "analysis.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(record, dict) and str(record.get("format", "")).startswith("horsemocap-results/")


def check_results_target(out) -> Path:
    """``out`` resolved, if it may be replaced by a run's results.

    It may be absent, an empty folder or an earlier run's results (its
    ``analysis.json`` has ``"format": "horsemocap-results/..."``, or it
    holds ``PARTIAL.txt``); anything else is refused with a
    :class:`StoreError` naming it, so that ``--out ~`` never deletes a home
    folder.
    """
    if "\0" in str(out):
        raise StoreError(f"--out {str(out)!r}: a path cannot hold a NUL byte")
    path = Path(out).expanduser().resolve()
    if path.parent == path:
        raise StoreError(f"--out {out}: the root of a file system cannot be a results folder")
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise StoreError(f"--out {out}: is a file, not a folder; choose a folder for the results")
        entries = [p.name for p in path.iterdir()]
        if entries and not _is_results_folder(path, entries):
            raise StoreError(f"--out {out}: the folder holds files that are not horsemocap results "
                             f"({', '.join(sorted(entries)[:3])}{', ...' if len(entries) > 3 else ''}); "
                             "horsemocap replaces the whole folder, so choose a new or empty folder")
    return path


class RunFolder:
    """Lock, temporary folder and the final swap of one run (a context manager).

    ``with RunFolder(out) as tmp:`` gives the temporary folder to write into;
    leaving the block normally keeps nothing yet: call :meth:`commit` to put
    the folder in place. Leaving without :meth:`commit` (an exception,
    Ctrl-C) deletes the temporary folder, so ``out`` stays as it was.
    """

    def __init__(self, out):
        self.out = check_results_target(out)
        self.given = str(out)
        self.lock_path = self.out.parent / f".{self.out.name}.lock"
        self.tmp: Path | None = None
        self._lock_fd = None
        self.committed = False

    # -- lock ---------------------------------------------------------------
    def _acquire(self) -> None:
        try:
            self.out.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreError(f"--out {self.given}: cannot create its parent folder ({exc.strerror})") from None
        while True:
            try:
                fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o666)
            except OSError as exc:
                raise StoreError(f"--out {self.given}: cannot create the lock file {self.lock_path.name} beside "
                                 f"it ({exc.strerror}); choose a folder you can write to") from None
            if fcntl is None:  # pragma: no cover
                self._lock_fd = fd
                return
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 200).decode("utf-8", "replace").strip()
                os.close(fd)
                raise RunLockedError(
                    f"--out {self.given}: another horsemocap run is writing into this folder"
                    f"{f' ({holder})' if holder else ''}; wait until it ends or choose another --out") from None
            # the file may have been unlinked by the run that held it: lock the one on disk
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.lock_path))
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"pid {os.getpid()}".encode())
                self._lock_fd = fd
                return
            os.close(fd)

    def _release(self) -> None:
        if self._lock_fd is not None:
            try:
                os.unlink(self.lock_path)
            except FileNotFoundError:
                pass
            os.close(self._lock_fd)
            self._lock_fd = None

    # -- context --------------------------------------------------------------
    def __enter__(self) -> Path:
        self._acquire()
        try:
            for stale in self.out.parent.glob(f".{self.out.name}.run-*"):  # left by a killed run
                shutil.rmtree(stale, ignore_errors=True)
            name = f".{self.out.name}.run-{os.getpid()}-{secrets.token_hex(4)}"
            self.tmp = self.out.parent / name
            try:
                os.mkdir(self.tmp, 0o777)  # the umask applies
            except OSError as exc:
                raise StoreError(f"--out {self.given}: cannot create a folder beside it "
                                 f"({exc.strerror})") from None
        except BaseException:
            self._release()
            raise
        return self.tmp

    def commit(self) -> Path:
        """Put the temporary folder in the place of ``out``; the earlier one is deleted."""
        tmp, out = self.tmp, self.out
        if out.is_symlink() or out.exists():
            check_results_target(out)  # still ours to replace
            if _exchange(tmp, out):
                shutil.rmtree(tmp, ignore_errors=True)  # now the earlier run's files
            else:
                old = out.parent / f".{out.name}.run-old-{secrets.token_hex(4)}"
                os.rename(out, old)
                os.rename(tmp, out)
                shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, out)
        self.committed = True
        return out

    def __exit__(self, exc_type, exc, tb):
        try:
            if not self.committed and self.tmp is not None:
                shutil.rmtree(self.tmp, ignore_errors=True)
        finally:
            self._release()
        return False
