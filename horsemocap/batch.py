"""Many sessions analysed side by side into one table: ``horsemocap batch``.

Each session is analysed exactly as ``horsemocap analyze`` analyses it
(:func:`horsemocap.run.run_analysis`, with its parameters resolved the same
way) into ``DIR/<name>/``; the sessions run in worker processes on the local
cores (:class:`concurrent.futures.ProcessPoolExecutor`, one BLAS and one
OpenCV thread per worker) or on an existing Dask cluster
(``dask.distributed``, the optional extra ``horsemocap[cluster]``).

After each session ends, ``DIR/sessions.csv`` (and ``DIR/sessions.parquet``
where pyarrow is importable) is written whole with one row per finished
session (:data:`BASE_COLUMNS`, then the indicators of ``comfort.csv``), so a
batch killed at any moment leaves a valid table. A session that fails is a
row with its error, never the end of the batch.

A batch is resumable: each results folder gets ``batch.json`` holding the
run key (:func:`horsemocap.fingerprint.run_key` of the session's files, the
parameters and the package's code) and the session's row. A session whose
folder holds a complete analysis under the same run key is not analysed
again; its row is read back (``reused`` true).
"""
from __future__ import annotations

import csv
import io
import json
import math
import multiprocessing
import os
import re
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

from .batch_table import BASE_COLUMNS, METADATA_COLUMNS, TABLE_CSV, TABLE_PARQUET, _json_row, read_table, write_table
from .errors import one_line
from .fingerprint import run_key
from .herd import GAITS, HORSES
from .params import read_params
from .pipeline import resolve_params
from .run import EXIT_ERROR, run_analysis
from .session import load_session
from .store import atomic_write_json, atomic_write_text
from .virtuallab import herd_session
from .data import cache_dir
from .virtuallab.herd import _key as _herd_key, session_slug

BATCH_FILE = "batch.json"
BATCH_FORMAT = "horsemocap-batch/1"
CLUSTER_HINT = "pip install horsemocap[cluster]"

__all__ = ["BATCH_FILE", "TABLE_CSV", "TABLE_PARQUET", "BASE_COLUMNS", "BatchError", "BatchTask", "BatchSummary",
           "find_sessions", "safe_name", "result_names", "plan_batch", "analyse_task", "reusable_row",
           "write_table", "read_table", "run_batch", "BatchProgress"]


class BatchError(ValueError):
    """A batch that cannot start: no session found, a list file that cannot be read, no Dask."""


@dataclass(frozen=True)
class BatchTask:
    """One session of a batch.

    Attributes
    ----------
    session : Path
        The session folder (holding ``session.json``).
    out : Path
        Its results folder, ``DIR/<name>``.
    name : str
        The results folder's name (unique in the batch, safe as a file name).
    params_file : str or None
        The ``--params`` file (an earlier ``analysis.json`` or a ``choices.json``).
    """

    session: Path
    out: Path
    name: str
    params_file: str | None = None


@dataclass
class BatchSummary:
    """What a batch did: the rows of the table (input order) and where the table is."""

    rows: list
    table: Path
    parquet: Path | None
    seconds: float

    @property
    def failed(self) -> int:
        return sum(1 for r in self.rows if r["exit_status"] == EXIT_ERROR)

    @property
    def exit_code(self) -> int:
        """The worst exit status of the sessions (0 ok, 3 an unreliable verdict, 2 a failure)."""
        codes = {r["exit_status"] for r in self.rows}
        return EXIT_ERROR if EXIT_ERROR in codes else max(codes, default=0)


# ---------------------------------------------------------------------------
# The sessions of a batch and their results folders
# ---------------------------------------------------------------------------

def find_sessions(paths) -> list[Path]:
    """The session folders named by ``paths``, in order, each once.

    Each path is a session folder (it holds ``session.json``), a folder of
    sessions (every subfolder holding ``session.json``, in name order) or a
    list file (one session folder per line, relative to the list file's
    folder; blank lines and ``#`` comments skipped).

    Raises
    ------
    BatchError
        Naming a path that is none of these, or a list line that is not a session.

    Examples
    --------
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> for name in ("b", "a"):
    ...     (root / name).mkdir(); _ = (root / name / "session.json").write_text("{}")
    >>> [p.name for p in find_sessions([root])]
    ['a', 'b']
    """
    found = []
    for given in paths:
        path = Path(given).expanduser()
        if (path / "session.json").is_file():
            found.append(path)
        elif path.is_dir():
            inside = sorted(p for p in path.iterdir() if (p / "session.json").is_file())
            if not inside:
                raise BatchError(f"{path}: neither a session (no session.json) nor a folder of sessions "
                                 "(no subfolder holds session.json)")
            found.extend(inside)
        elif path.is_file():
            found.extend(_listed_sessions(path))
        else:
            raise BatchError(f"{path}: not found (expected a session folder, a folder of sessions or a list file)")
    unique, seen = [], set()
    for p in found:
        if p.resolve() not in seen:
            seen.add(p.resolve())
            unique.append(p)
    return unique


def _listed_sessions(list_file: Path) -> list[Path]:
    try:
        lines = list_file.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise BatchError(f"{list_file}: cannot read the list of sessions ({exc})") from None
    out = []
    for number, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        path = Path(text).expanduser()
        path = path if path.is_absolute() else list_file.parent / path
        if not (path / "session.json").is_file():
            raise BatchError(f"{list_file}: line {number}: {text!r} is not a session folder (no session.json)")
        out.append(path)
    return out


def safe_name(text: str) -> str:
    """``text`` as a folder name: letters, digits, ``.``, ``_`` and ``-`` kept, every other run of characters ``_``.

    Examples
    --------
    >>> safe_name("Horse 2 / canter")
    'Horse_2_canter'
    >>> safe_name("..")
    'session'
    """
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._")
    return name or "session"


def result_names(sessions) -> list[str]:
    """A results folder name per session: its folder's :func:`safe_name`, made unique (``-2``, ``-3`` ...).

    Names are unique without regard to case (a case-insensitive file
    system), and never those of the batch's table files.

    Examples
    --------
    >>> result_names([Path("a/walk"), Path("b/walk"), Path("c/Walk")])
    ['walk', 'walk-2', 'Walk-3']
    """
    taken = {TABLE_CSV.lower(), TABLE_PARQUET.lower()}
    names = []
    for session in sessions:
        base = safe_name(Path(session).name)
        name, k = base, 1
        while name.lower() in taken:
            k += 1
            name = f"{base}-{k}"
        taken.add(name.lower())
        names.append(name)
    return names


def plan_batch(paths, out_dir, params_file=None) -> list[BatchTask]:
    """The tasks of a batch: :func:`find_sessions` of ``paths``, each into ``out_dir/<name>``."""
    sessions = find_sessions(paths)
    out_dir = Path(out_dir)
    return [BatchTask(s, out_dir / n, n, None if params_file is None else str(params_file))
            for s, n in zip(sessions, result_names(sessions))]


# ---------------------------------------------------------------------------
# One session
# ---------------------------------------------------------------------------

def _params(session, params_file):
    """The parameters ``horsemocap analyze --params FILE`` would use (the session's own without a file)."""
    base = resolve_params(session, read_params(params_file)) if params_file else resolve_params(session)
    base.check_session(session, f"{params_file}" if params_file else "parameters")
    return base


def _empty_row(task: BatchTask) -> dict:
    return {"name": task.name, "folder": str(task.session), "results": str(task.out), "session_name": "",
            **{k: "" for k in METADATA_COLUMNS}, "verdict": "", "exit_status": EXIT_ERROR, "reused": False,
            "seconds": float("nan"), "error": ""}


def _comfort(folder: Path) -> dict:
    """``comfort.csv``'s indicator column -> its value (empty if the file is absent)."""
    path = folder / "comfort.csv"
    if not path.is_file():
        return {}
    with open(path, newline="", encoding="utf-8") as fh:
        return {r["indicator"]: float(r["value"]) if r["value"] not in ("", None) else float("nan")
                for r in csv.DictReader(fh)}


PASSES_PREFIX = "passes"
"""Optional columns of a recording with several passes (``passes.csv``): ``passes`` (how many),
``passes_verdict`` (the worst pass') and ``passes_<indicator>``, the comfort over every pass weighted by
their durations (its row ``all``); the indicators of ``comfort.csv`` are the longest pass'."""


def _passes(folder: Path) -> dict:
    """The optional ``passes*`` columns from ``passes.csv`` (none when the file is absent)."""
    path = folder / "passes.csv"
    if not path.is_file():
        return {}
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    combined = next((r for r in rows if r["pass"] == "all"), None)
    if combined is None:
        return {}
    skip = {"pass", "main", "first_frame", "last_frame", "start_s", "error", "verdict"}
    out = {PASSES_PREFIX: len(rows) - 1, f"{PASSES_PREFIX}_verdict": combined["verdict"]}
    out.update({f"{PASSES_PREFIX}_{k}": float(v) if v not in ("", None) else float("nan")
                for k, v in combined.items() if k not in skip})
    return out


def reusable_row(task: BatchTask) -> dict | None:
    """The row of an earlier complete run of ``task`` under the same run key, else None.

    Complete: ``batch.json`` holds the run key of the session's files, the
    parameters and the code as they are now, and ``analysis.json`` says
    ``"complete": true``.
    """
    try:
        record = json.loads((task.out / BATCH_FILE).read_text(encoding="utf-8"))
        analysis = json.loads((task.out / "analysis.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(record, dict) and record.get("format") == BATCH_FORMAT and isinstance(analysis, dict)
            and analysis.get("complete") is True and isinstance(record.get("row"), dict)):
        return None
    try:
        session = load_session(task.session)
        key = run_key(session, _params(session, task.params_file))
    except Exception:   # noqa: BLE001 - a session that no longer loads is analysed again (and fails there)
        return None
    if record.get("run_key") != key:
        return None
    row = dict(record["row"])
    row.update(name=task.name, folder=str(task.session), results=str(task.out), reused=True)
    return row


def _single_threaded_libraries() -> None:
    """One BLAS and one OpenCV thread in this process (a worker of a batch shares the cores with the others)."""
    import cv2
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    cv2.setNumThreads(1)


def analyse_task(task: BatchTask, single_threaded: bool = True) -> dict:
    """Analyse one session as ``horsemocap analyze`` would and return its row of the table.

    Every error becomes the row's ``error`` (exit status 2), never an
    exception: the batch goes on. ``batch.json`` (the run key and the row)
    is written into the results folder after the analysis.
    """
    if single_threaded:
        _single_threaded_libraries()
    row = _empty_row(task)
    start = time.perf_counter()
    try:
        session = load_session(task.session)
        row["session_name"] = session.name
        row.update({k: str(session.metadata.get(k, "")) for k in METADATA_COLUMNS})
        params = _params(session, task.params_file)
        key = run_key(session, params)
        outcome = run_analysis(task.session, task.out, params, progress=lambda *a, **k: None)
    except Exception as exc:  # noqa: BLE001 - a failing session is a row
        row["error"] = _error_text(exc)
        row["seconds"] = time.perf_counter() - start
        return row
    row["verdict"] = outcome.verdict
    row["exit_status"] = outcome.exit_code
    row["error"] = "" if outcome.error is None else _error_text(outcome.error)
    row.update(_comfort(outcome.out))
    row.update(_passes(outcome.out))
    row["seconds"] = time.perf_counter() - start
    try:
        atomic_write_json(outcome.out / BATCH_FILE, {"format": BATCH_FORMAT, "run_key": key,
                                                     "session": str(task.session), "row": _json_row(row)})
    except OSError as exc:   # the analysis is written; only its resumption is lost
        row["error"] = f"{BATCH_FILE} not written ({exc}): this session will be analysed again on a rerun"
    return row


def _error_text(exc: BaseException) -> str:
    """The error in one line, worded as ``horsemocap analyze`` prints it."""
    return one_line(exc)


class BatchProgress:
    """One line: sessions done / running / failed of the total and the time left.

    The time left is the mean time of the sessions analysed so far (those
    that failed left out: they often fail at once) times the rounds of
    sessions left on the workers.
    """

    def __init__(self, total: int, workers: int, stream=None):
        self.total, self.workers = total, max(1, workers)
        self.stream = stream if stream is not None else sys.stderr
        self.done = self.failed = self.reused = 0
        self.times = []
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._width = 0

    def finished(self, row: dict) -> None:
        self.done += 1
        self.failed += row["exit_status"] == EXIT_ERROR
        if row.get("reused"):
            self.reused += 1
        elif row["exit_status"] != EXIT_ERROR and math.isfinite(row.get("seconds", float("nan"))):
            self.times.append(row["seconds"])
        self.show()

    def line(self) -> str:
        left = self.total - self.done
        running = min(self.workers, left)
        text = f"batch: {self.done}/{self.total} done"
        if self.reused:
            text += f" ({self.reused} reused)"
        text += f", {running} running, {self.failed} failed"
        if left and self.times:
            text += f", about {_duration(sum(self.times) / len(self.times) * math.ceil(left / self.workers))} left"
        elif not left:
            text += ", finished"
        return text

    def show(self) -> None:
        text = self.line()
        if self._tty:
            self.stream.write("\r" + text.ljust(self._width))
            self._width = len(text)
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(text + "\n")
        self.stream.flush()


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


def _pool_context():
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def run_batch(paths, out_dir, *, workers: int | None = None, scheduler: str | None = None, params_file=None,
              progress: BatchProgress | None = None) -> BatchSummary:
    """Analyse every session of ``paths`` into ``out_dir`` (see the module's description).

    Parameters
    ----------
    paths : iterable of path
        Session folders, folders of sessions or list files (:func:`find_sessions`).
    out_dir : path
        The batch's folder: ``<name>/`` per session and the table.
    workers : int, optional
        Local worker processes (default: every core); 1 analyses in this process.
    scheduler : str, optional
        The address of a running Dask scheduler (``tcp://host:8786``): the
        sessions run on its workers instead.
    params_file : path, optional
        As ``horsemocap analyze --params``.
    progress : BatchProgress, optional

    Returns
    -------
    BatchSummary
    """
    start = time.perf_counter()
    tasks = plan_batch(paths, out_dir, params_file)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    workers = max(1, workers or default_workers())
    rows: dict = {}
    todo = []
    for task in tasks:
        row = reusable_row(task)
        if row is None:
            todo.append(task)
        else:
            rows[task.name] = row
    progress = progress or BatchProgress(len(tasks), workers)
    for row in rows.values():
        progress.finished(row)
    order = [t.name for t in tasks]

    def finished(row):
        rows[row["name"]] = row
        write_table(out_dir, [rows[n] for n in order if n in rows])
        progress.finished(row)

    if rows or not todo:
        write_table(out_dir, [rows[n] for n in order if n in rows])
    if scheduler:
        _run_on_dask(todo, scheduler, finished, progress)
    elif workers == 1 or len(todo) <= 1:
        for task in todo:
            finished(analyse_task(task, single_threaded=False))
    else:
        _run_on_processes(todo, min(workers, len(todo)), finished)
    csv_path, parquet = write_table(out_dir, [rows[n] for n in order if n in rows])
    return BatchSummary([rows[n] for n in order], csv_path, parquet, time.perf_counter() - start)


def _run_on_processes(tasks, workers: int, finished) -> None:
    """The tasks on ``workers`` local processes; a worker that dies makes its sessions rows with the error."""
    from concurrent.futures.process import BrokenProcessPool

    with ProcessPoolExecutor(max_workers=workers, mp_context=_pool_context()) as pool:
        pending = {pool.submit(analyse_task, task): task for task in tasks}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                task = pending.pop(future)
                try:
                    row = future.result()
                except BrokenProcessPool as exc:
                    row = _empty_row(task)
                    row["error"] = f"the worker process ended abruptly ({exc}); run the batch again to retry"
                finished(row)


def _run_on_dask(tasks, address: str, finished, progress: BatchProgress) -> None:
    """The tasks on the workers of the Dask scheduler at ``address``."""
    try:  # optional dependency: imported only for --scheduler
        from dask.distributed import as_completed, Client
    except ImportError:
        raise BatchError(f"--scheduler {address}: needs dask.distributed, which is not installed; "
                         f"{CLUSTER_HINT} (or pip install 'dask[distributed]')") from None
    with Client(address) as client:
        progress.workers = max(1, sum(client.nthreads().values()))
        futures = [client.submit(analyse_task, task, pure=False) for task in tasks]
        tasks_of = dict(zip(futures, tasks))
        for future in as_completed(futures):
            try:
                row = future.result()
            except Exception as exc:  # noqa: BLE001 - a worker lost: the session is a row with the error
                row = _empty_row(tasks_of[future])
                row["error"] = f"the Dask worker failed ({type(exc).__name__}: {exc}); run the batch again to retry"
            finished(row)


def herd_batch(out_dir, *, horses=HORSES, gaits=GAITS, workers: int | None = None, scheduler: str | None = None,
               params_file=None, progress=None):
    """The herd study as one batch: every (horse, gait) session analysed into ``out_dir``, one table.

    The sessions are rendered into the cache first (once each,
    :func:`render_herd`, a progress line per session rendered), then analysed as ``horsemocap batch``
    analyses them (:func:`horsemocap.batch.run_batch`: ``workers`` local
    processes, or the Dask cluster at ``scheduler``); run again, only the
    sessions not finished are analysed.

    Returns
    -------
    horsemocap.batch.BatchSummary
        ``.table`` is ``out_dir/sessions.csv``; :func:`horsemocap.herd.table_indicators` reads it.
    """
    sessions = render_herd([(h, g) for h in horses for g in gaits], progress)
    return run_batch(sessions, out_dir, workers=workers, scheduler=scheduler, params_file=params_file,
                     progress=progress)


def herd_session_cached(horse: str, gait: str) -> bool:
    """Whether ``virtuallab.herd_session`` finds the session complete in the cache (nothing to render)."""
    folder = cache_dir() / "virtuallab" / f"{session_slug(horse, gait)}-{_herd_key(horse, gait)}"
    return (folder / ".complete").is_file()


def render_herd(pairs, progress=None, stream=None) -> list[Path]:
    """The herd sessions of ``pairs`` ((horse, gait), ...), rendered into the cache where absent.

    A line per session rendered: how many are ready and the rendering
    time left (the mean of the renders so far times those left to
    render; sessions already in the cache cost nothing). ``progress``
    (a :class:`BatchProgress`): its stream is used for the lines.
    """
    stream = stream or getattr(progress, "stream", None) or sys.stderr
    missing = [p for p in pairs if not herd_session_cached(*p)]
    paths, times = [], []
    for h, g in pairs:
        t0 = time.perf_counter()
        paths.append(herd_session(h, g))
        if (h, g) in missing:
            times.append(time.perf_counter() - t0)
            left = len(missing) - len(times)
            text = f"herd: {len(times)}/{len(missing)} sessions rendered"
            text += f", about {_duration(sum(times) / len(times) * left)} of rendering left" if left else ", done"
            stream.write(text + "\n")
            stream.flush()
    return paths
