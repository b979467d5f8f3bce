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
  folder behind; the next run into ``DIR`` deletes it). A file that could not
  be written (disk full, quota, read-only, permission, I/O error), also inside
  a step, ends the run with :class:`RunWriteError` naming the file in ``DIR``
  and the system's error text: a step's result cut short by the disk is not a
  partial result.

``horsemocap kinematics TRAJECTORIES --out DIR`` uses the same folder
(``kind="kinematics"``): ``DIR`` may be new, empty or an earlier
``kinematics`` run's output, which holds ``kinematics-run.json``
(:data:`KINEMATICS_FORMAT`).

A second run into the same ``DIR`` while one holds the lock stops at once
with :class:`RunLockedError` (it does not wait). The lock is an ``flock``
on the lock file, so a killed run never leaves a stale lock. Folders and
files are created with the user's umask.
"""
from __future__ import annotations

import ctypes
import errno
import glob
import json
import os
import re
import secrets
import shutil
from pathlib import Path

from .store import StoreError, WriteError

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

RESULTS_MARKERS = ("analysis.json", "PARTIAL.txt")
# every file and folder an ``analyze`` run writes into its results folder (the notebooks' store adds ``steps``,
# a batch its record ``batch.json``)
ANALYZE_OUTPUTS = frozenset({
    "analysis.json", "PARTIAL.txt", "quality.json", "report.html", "rig.toml", "calibration.json",
    "markers_2d.csv", "markers_3d.csv", "trajectories.csv", "kinematics.csv", "angular.csv",
    "comfort.csv", "comfort.xlsx", "passes.csv", "steps", "choices.json", ".choices.json.lock",
    "batch.json"})
KINEMATICS_OUTPUTS = frozenset({"kinematics-run.json", "trajectories.csv", "kinematics.csv", "angular.csv"})
# a temporary folder of a run: .NAME.run-<pid>-<hex> (or .NAME.run-old-<hex> of the two-rename swap)
_TMP_PATTERN = r"\.{name}\.run-(?:(?P<pid>\d+)|old)-[0-9A-Za-z]+"
KINEMATICS_RECORD = "kinematics-run.json"
KINEMATICS_FORMAT = "horsemocap-kinematics/1"
# errors of the operating system that only writing gives (any other errno counts when the file is ours)
_WRITE_ERRNOS = {errno.ENOSPC, errno.EROFS, getattr(errno, "EDQUOT", -1), errno.EFBIG}


class RunLockedError(StoreError):
    """Another run is writing into the same results folder."""


class RunWriteError(WriteError):
    """A run's file that could not be written; the results folder ``out`` was left as it was."""

    def __init__(self, errno_, strerror, filename, out):
        super().__init__(errno_, strerror, filename)
        self.out = out

    def _tail(self) -> str:
        return f"; {self.out} is as it was before the run"


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


def _json_record(path: Path) -> dict:
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return record if isinstance(record, dict) else {}


def _foreign_entries(path: Path, entries, own: frozenset) -> list:
    """What in ``path`` a run of this kind did not write: unknown names, a session, a link, a nested folder."""
    foreign = []
    for name in sorted(entries):
        entry = path / name
        if name not in own:
            foreign.append(name)
        elif entry.is_symlink():
            foreign.append(f"{name} (a symbolic link)")
        elif entry.is_dir() and name != "steps":
            foreign.append(f"{name}/ (a folder)")
    sessions = _sessions_inside(path)
    tops = {s.split("/")[0] for s in sessions}
    return [f"{s} (a session)" for s in sessions] + [f for f in foreign if f.split(" ")[0].rstrip("/") not in tops]


def _sessions_inside(path: Path, limit: int = 3) -> list:
    """Relative paths of up to ``limit`` ``session.json`` files anywhere under ``path`` (links not followed)."""
    found = []
    for root, dirs, files in os.walk(path, followlinks=False):
        if "session.json" in files:
            found.append(str(Path(root, "session.json").relative_to(path)))
            if len(found) >= limit:
                break
    return found


def _is_results_folder(path: Path, entries) -> bool:
    """An earlier horsemocap run's folder: its analysis.json says so, or it is marked partial."""
    if "PARTIAL.txt" in entries:
        return True
    if "analysis.json" not in entries:
        return False
    return str(_json_record(path / "analysis.json").get("format", "")).startswith("horsemocap-results/")


def _is_kinematics_folder(path: Path, entries) -> bool:
    """An earlier ``horsemocap kinematics`` run's output: its kinematics-run.json says so."""
    if KINEMATICS_RECORD not in entries:
        return False
    return _json_record(path / KINEMATICS_RECORD).get("format") == KINEMATICS_FORMAT


# kind of run -> (test of an earlier run's folder, what the refusal calls it)
_KINDS = {"analyze": (_is_results_folder, "horsemocap results", ANALYZE_OUTPUTS),
          "kinematics": (_is_kinematics_folder, "an earlier 'horsemocap kinematics' output", KINEMATICS_OUTPUTS)}


def check_results_target(out, kind: str = "analyze") -> Path:
    """``out`` resolved, if it may be replaced by a run's results.

    It may be absent, an empty folder or an earlier run's results of the
    same ``kind``: for ``"analyze"`` its ``analysis.json`` has ``"format":
    "horsemocap-results/..."``, or it holds ``PARTIAL.txt``; for
    ``"kinematics"`` its ``kinematics-run.json`` has ``"format":
    "horsemocap-kinematics/1"``. Such a folder must hold nothing else than
    the files a run of that kind writes (:data:`ANALYZE_OUTPUTS`,
    :data:`KINEMATICS_OUTPUTS`): a file a user left there, a link, a
    folder or a ``session.json`` anywhere inside (a session kept in an
    earlier results folder) is named in the refusal, so the swap never
    deletes what a run did not write, and ``--out ~`` never deletes a home
    folder.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> check_results_target(folder / "results") == (folder / "results").resolve()     # a new folder: fine
    True
    >>> (folder / "thesis").mkdir()
    >>> _ = (folder / "thesis" / "chapter1.docx").write_text("not results")
    >>> try:
    ...     check_results_target(folder / "thesis")
    ... except StoreError as error:
    ...     print(type(error).__name__)
    StoreError
    """
    is_earlier_run, what, own = _KINDS[kind]
    if "\0" in str(out):
        raise StoreError(f"--out {str(out)!r}: a path cannot hold a NUL byte")
    path = Path(out).expanduser().resolve()
    if path.parent == path:
        raise StoreError(f"--out {out}: the root of a file system cannot be a results folder")
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise StoreError(f"--out {out}: is a file, not a folder; choose a folder for the results")
        entries = [p.name for p in path.iterdir()]
        if entries and not is_earlier_run(path, entries):
            raise StoreError(f"--out {out}: the folder holds files that are not {what} "
                             f"({', '.join(sorted(entries)[:3])}{', ...' if len(entries) > 3 else ''}); "
                             "horsemocap replaces the whole folder, so choose a new or empty folder")
        foreign = _foreign_entries(path, entries, own) if entries else []
        if foreign:
            raise StoreError(f"--out {out}: the earlier results folder also holds what no horsemocap run wrote "
                             f"({', '.join(foreign[:4])}{', ...' if len(foreign) > 4 else ''}); horsemocap "
                             "replaces the whole folder and would delete it: move it out or choose another --out")
    return path


def _stale_run_folders(parent: Path, name: str) -> list:
    """Temporary folders of runs into ``parent/name`` whose process has ended (never a live run's)."""
    pattern = re.compile(_TMP_PATTERN.format(name=re.escape(name)))
    stale = []
    for entry in parent.glob(f".{glob.escape(name)}.run-*"):
        match = pattern.fullmatch(entry.name)
        if match is None or entry.is_symlink() or not entry.is_dir():
            continue   # another folder's temporary folder (".x.run-1" of --out x.run-1), or not ours
        pid = match.group("pid")
        if pid is not None and _alive(int(pid)):
            continue
        stale.append(entry)
    return stale


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` runs (ours, or another user's)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return pid < 2 ** 31
    return True


def _chain(exc: BaseException):
    """``exc`` and the exceptions it was raised from or while handling, once each."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        yield exc
        exc = exc.__cause__ if exc.__cause__ is not None else exc.__context__


class RunFolder:
    """Lock, temporary folder and the final swap of one run (a context manager).

    ``with RunFolder(out) as tmp:`` gives the temporary folder to write into;
    leaving the block normally keeps nothing yet: call :meth:`commit` to put
    the folder in place. Leaving without :meth:`commit` (an exception,
    Ctrl-C) deletes the temporary folder, so ``out`` stays as it was.
    """

    def __init__(self, out, kind: str = "analyze"):
        self.kind = kind
        self.out = check_results_target(out, kind)
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
                self._lock_fd = fd
                try:   # who holds the lock, for a second run's message: a courtesy, the flock is the lock
                    os.ftruncate(fd, 0)
                    os.write(fd, f"pid {os.getpid()}".encode())
                except OSError:   # a full disk: the run's own writes meet it and say so with the file's name
                    pass
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
            for stale in _stale_run_folders(self.out.parent, self.out.name):  # left by a killed run
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
            check_results_target(out, self.kind)  # still ours to replace
            if _exchange(tmp, out):
                shutil.rmtree(tmp, ignore_errors=True)  # now the earlier run's files
            else:
                old = out.parent / f".{out.name}.run-old-{secrets.token_hex(4)}"
                os.rename(out, old)
                try:
                    os.rename(tmp, out)
                except BaseException:
                    os.rename(old, out)   # the earlier run's folder back in place
                    raise
                shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, out)
        self.committed = True
        return out

    def write_failure(self, exc: BaseException) -> OSError | None:
        """The error of writing a file of this run in ``exc``'s chain, or None.

        A :class:`~horsemocap.store.WriteError`, an error only writing gives
        (ENOSPC, EDQUOT, EROFS, EFBIG), or any OSError on a file inside the
        temporary folder; an error reading an input is not one.
        """
        for e in _chain(exc):
            if not isinstance(e, OSError):
                continue
            if isinstance(e, WriteError) or e.errno in _WRITE_ERRNOS or self._inside_tmp(e.filename):
                return e
        return None

    def _inside_tmp(self, filename) -> bool:
        if self.tmp is None or not isinstance(filename, (str, os.PathLike)):
            return False
        path = Path(os.fsdecode(filename))
        return path == self.tmp or self.tmp in path.parents

    def final_path(self, filename) -> str:
        """``filename`` as it would have been in ``out`` (the temporary folder's name replaced)."""
        if not self._inside_tmp(filename):
            return str(filename)
        return str(self.out / Path(os.fsdecode(filename)).relative_to(self.tmp))

    def __exit__(self, exc_type, exc, tb):
        try:
            if not self.committed and self.tmp is not None:
                shutil.rmtree(self.tmp, ignore_errors=True)
        finally:
            self._release()
        failed = self.write_failure(exc) if isinstance(exc, Exception) and not self.committed else None
        if failed is not None and not isinstance(failed, RunWriteError):
            raise RunWriteError(failed.errno, failed.strerror or str(failed), self.final_path(failed.filename),
                                self.given) from exc
        return False
