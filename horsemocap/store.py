"""Atomic writes and the per-session results store.

Results are written under a results folder chosen by the user (never inside
the input session). Every write goes to a temporary file in the same folder
and is renamed into place, so a reader sees a whole file or none.

A :class:`ResultsStore` keeps each pipeline step's result under the results
folder (``<results>/steps/<step>.json`` + ``.npz``, no pickle), keyed by a fingerprint of the
session, the parameters and the code; notebooks load what an earlier one
computed and compute it with the default parameters when absent.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import io
import json
import mmap
import os
import secrets
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np


class StoreError(RuntimeError):
    """A results folder that cannot be used (e.g. inside the input session)."""


class WriteError(OSError):
    """A file that could not be written (disk full, quota, read-only, permission, I/O error).

    ``filename`` is the file that was being written (not its temporary
    name), ``errno`` and ``strerror`` those of the operating system's error.
    """

    def describe(self, hint: str = "") -> str:
        """``cannot write FILE: text[ (hint)]`` and what became of the results folder (:meth:`_tail`)."""
        head = f"cannot write {self.filename}" if self.filename else "a file could not be written"
        return f"{head}: {self.strerror}" + (f" ({hint})" if hint else "") + self._tail()

    def _tail(self) -> str:
        return ""

    def __str__(self) -> str:
        return self.describe()


class ScratchWriteError(WriteError):
    """A scratch file (a long record's memory-mapped points or registration) that could not be written;
    the message names the file and its folder.

    Examples
    --------
    >>> print(ScratchWriteError(28, "No space left on device", "/tmp/run/points-1.npy"))
    cannot write /tmp/run/points-1.npy: No space left on device; /tmp/run is the scratch folder of a long record's memory-mapped arrays: make room there or choose another
    """

    def _tail(self) -> str:
        return (f"; {Path(self.filename).parent} is the scratch folder of a long record's memory-mapped arrays: "
                "make room there or choose another")


def release_pages(*arrays) -> None:
    """Let the system take back the memory of the pages of memory-mapped ``arrays`` read so far.

    A memory-mapped file's pages stay in the process' memory once read; for
    a file mapped shared (:class:`numpy.memmap`) they are only unmapped (their
    contents stay in the file), so that a record read window by window does
    not accumulate in memory. Arrays not mapped from a file are left alone,
    as is every array where the system offers no ``madvise`` (Windows, some
    builds): there the pages stay until the mapping is closed.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.f8"
    >>> a = np.lib.format.open_memmap(path, mode="w+", dtype=float, shape=(1000,))
    >>> a[:] = 2.0
    >>> release_pages(a, np.zeros(3))
    >>> float(a.sum())
    2000.0
    """
    if not (hasattr(mmap, "MADV_DONTNEED") and hasattr(mmap.mmap, "madvise")):
        return
    for a in arrays:
        mapped = getattr(a, "_mmap", None)
        if mapped is not None:
            mapped.madvise(mmap.MADV_DONTNEED)


def read_text_utf8(path, error=ValueError) -> str:
    """The text of a UTF-8 file; ``error(message)`` naming the file and byte if it is not UTF-8."""
    data = Path(path).read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                    "save the file as UTF-8") from None


MAX_JSON_DEPTH = 64
"""The deepest nesting of objects and arrays a horsemocap JSON file is read with (session.json,
parameter files and choices are a few levels deep)."""


def json_depth(text: str) -> int:
    """The deepest nesting of objects and arrays in a JSON text (brackets inside strings not counted).

    Measured before parsing, so a hostile file is refused by its depth, whatever Python's recursion
    limit is at the time.

    Examples
    --------
    >>> json_depth('{"a": [1, {"b": "[[["}]}')
    3
    """
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def _atomic_write(path: Path, write, by_name: bool = False, suffix: str = "") -> Path:
    """Write ``path`` through a temporary file beside it; any OSError becomes a :class:`WriteError` naming ``path``."""
    path = Path(path)
    try:
        return _write_whole(path, write, by_name, suffix)
    except WriteError:
        raise
    except OSError as exc:
        raise WriteError(exc.errno, exc.strerror or str(exc), str(path)) from exc


def _write_whole(path: Path, write, by_name: bool = False, suffix: str = "") -> Path:
    """``write(fh)`` (or ``write(tmp_path)`` with ``by_name``) into a new temporary file beside ``path``
    whose name ends with ``suffix``, then renamed onto ``path``; removed on failure."""
    path.parent.mkdir(parents=True, exist_ok=True)
    # os.open with mode 0o666 lets the user's umask decide who may read the file
    # (tempfile.mkstemp would make it 0600: colleagues could not read the results)
    while True:
        tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp{suffix}"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
            break
        except FileExistsError:
            continue
    try:
        if by_name:
            os.close(fd)
            write(tmp)
        else:
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


def atomic_write_by_name(path, write, suffix: str = "") -> Path:
    """Write ``path`` atomically with a writer that takes a file *name* (``write(tmp_path)``, e.g. ezc3d's
    ``c3d.write``), the temporary name ending with ``suffix`` (a library that appends its extension to
    other names finds it there); errors as :func:`atomic_write_text`'s."""
    return _atomic_write(Path(path), write, by_name=True, suffix=suffix)


class StreamedTextFiles:
    r"""Text files written a piece at a time and put in place together, whole or not at all.

    Inside the ``with`` block each of ``paths`` is a text file (UTF-8,
    ``newline=""``) with a temporary name beside it; when the block ends
    without an error each is renamed onto its path (through the same atomic
    write as :func:`atomic_write_text`), otherwise they are removed. Any
    OSError is a :class:`WriteError` naming the file, not its temporary name.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with StreamedTextFiles([folder / "a.csv", folder / "b.csv"]) as (a, b):
    ...     _ = a.write("x\n"), b.write("y\n")
    >>> sorted(p.name for p in folder.iterdir()), (folder / "a.csv").read_text()
    (['a.csv', 'b.csv'], 'x\n')
    """

    def __init__(self, paths):
        self.paths = [Path(p) for p in paths]
        self._parts, self._files = [], []

    def __enter__(self):
        for path in self.paths:
            part = path.parent / f".{path.name}.{secrets.token_hex(6)}.part"
            self._parts.append(part)
            try:
                self._files.append(open(part, "x", encoding="utf-8", newline=""))
            except OSError as exc:
                self._discard()
                raise WriteError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        return self._files

    def _discard(self) -> None:
        for fh in self._files:
            fh.close()
        for part in self._parts:
            try:
                os.unlink(part)
            except FileNotFoundError:
                pass

    def __exit__(self, kind, exc, tb):
        if kind is not None:
            self._discard()
            if isinstance(exc, OSError) and not isinstance(exc, WriteError):
                where = next((str(p) for p, part in zip(self.paths, self._parts)
                              if exc.filename in (str(part), part)), str(self.paths[0]))
                raise WriteError(exc.errno, exc.strerror or str(exc), where) from exc
            return False
        try:
            for path, fh, part in zip(self.paths, self._files, self._parts):
                try:
                    fh.close()
                except OSError as err:
                    raise WriteError(err.errno, err.strerror or str(err), str(path)) from err
                _atomic_write(path, lambda tmp, part=part: os.replace(part, tmp), by_name=True)
        finally:
            self._discard()
        return False


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


# ---------------------------------------------------------------------------
# safe encoding of step results: JSON for values, .npz (no pickle) for arrays
# ---------------------------------------------------------------------------

_ARRAY_KINDS = set("biufcUSmM")


def encode_result(obj, arrays: dict):
    """A JSON-able tree for a step's result; arrays go into ``arrays`` by name.

    Values: None, bool, int, float, str, lists, tuples, dicts (any JSON-able
    keys), :class:`pathlib.Path`, NumPy arrays and scalars of numeric, bool,
    string or datetime types, SciPy's :class:`~scipy.interpolate.BSpline`
    (knots, coefficients, degree), and dataclasses defined in the ``horsemocap``
    package (their fields, recursively). Anything else (an object array, a
    callable, another package's class) raises ``TypeError`` naming it: the
    store never falls back to pickle.
    """
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    if isinstance(obj, np.ndarray) or isinstance(obj, np.generic):
        arr = np.asarray(obj)
        if arr.dtype.kind not in _ARRAY_KINDS:
            raise TypeError(f"cannot store an array of dtype {arr.dtype} without pickle")
        name = f"a{len(arrays)}"
        arrays[name] = arr
        return {"$": "array" if isinstance(obj, np.ndarray) else "scalar", "ref": name}
    if isinstance(obj, Path):
        return {"$": "path", "v": str(obj)}
    if isinstance(obj, (list, tuple)):
        return {"$": type(obj).__name__, "items": [encode_result(v, arrays) for v in obj]}
    if isinstance(obj, dict):
        return {"$": "dict", "items": [[encode_result(k, arrays), encode_result(v, arrays)] for k, v in obj.items()]}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        cls = type(obj)
        if not (cls.__module__ == "horsemocap" or cls.__module__.startswith("horsemocap.")):
            raise TypeError(f"cannot store a {cls.__module__}.{cls.__qualname__} (only horsemocap's dataclasses)")
        return {"$": "dataclass", "class": f"{cls.__module__}:{cls.__qualname__}",
                "fields": {f.name: encode_result(getattr(obj, f.name), arrays) for f in dataclasses.fields(obj)}}

    if type(obj) is _loaded_bspline_class():   # the pose trajectory's smoothing splines: knots, coefficients, degree
        return {"$": "bspline", "t": encode_result(np.asarray(obj.t), arrays),
                "c": encode_result(np.asarray(obj.c), arrays), "k": int(obj.k),
                "extrapolate": obj.extrapolate if isinstance(obj.extrapolate, bool) else str(obj.extrapolate),
                "axis": int(obj.axis)}
    raise TypeError(f"cannot store a {type(obj).__module__}.{type(obj).__qualname__} without pickle")


#: Where SciPy's B-spline class lives: looked up when a spline is stored or read, so a store (and every
#: module reading JSON through this one) does not load ``scipy.interpolate``, slow to load, for results
#: that hold none.
_BSPLINE_MODULE = "scipy.interpolate"


def _loaded_bspline_class():
    """SciPy's :class:`~scipy.interpolate.BSpline` if ``scipy.interpolate`` is loaded, else None (then no
    object can be one)."""
    module = sys.modules.get(_BSPLINE_MODULE)
    return None if module is None else module.BSpline


def _bspline_class():
    """SciPy's :class:`~scipy.interpolate.BSpline`, loading ``scipy.interpolate`` if needed."""
    return importlib.import_module(_BSPLINE_MODULE).BSpline


def _dataclass_type(spec: str):
    module, _, qualname = spec.partition(":")
    if not (module == "horsemocap" or module.startswith("horsemocap.")) or not qualname.isidentifier():
        raise ValueError(f"refusing to build {spec!r}: only horsemocap's dataclasses are stored")
    cls = getattr(importlib.import_module(module), qualname)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise ValueError(f"{spec!r} is not a dataclass")
    return cls


def decode_result(tree, arrays):
    """Inverse of :func:`encode_result` (``arrays`` from ``np.load(..., allow_pickle=False)``)."""
    if tree is None or isinstance(tree, (bool, int, float, str)):
        return tree
    tag = tree["$"]
    if tag == "array":
        return np.asarray(arrays[tree["ref"]])
    if tag == "scalar":
        return np.asarray(arrays[tree["ref"]])[()]
    if tag == "path":
        return Path(tree["v"])
    if tag == "list":
        return [decode_result(v, arrays) for v in tree["items"]]
    if tag == "tuple":
        return tuple(decode_result(v, arrays) for v in tree["items"])
    if tag == "dict":
        return {_hashable(decode_result(k, arrays)): decode_result(v, arrays) for k, v in tree["items"]}
    if tag == "bspline":
        return _bspline_class()(decode_result(tree["t"], arrays), decode_result(tree["c"], arrays), int(tree["k"]),
                       extrapolate=tree["extrapolate"], axis=int(tree["axis"]))
    if tag == "dataclass":
        cls = _dataclass_type(tree["class"])
        values = {k: decode_result(v, arrays) for k, v in tree["fields"].items()}
        init = {f.name for f in dataclasses.fields(cls) if f.init}
        obj = cls(**{k: v for k, v in values.items() if k in init})
        for k, v in values.items():
            if k not in init:
                object.__setattr__(obj, k, v)
        return obj
    raise ValueError(f"unknown stored type {tag!r}")


def _hashable(k):
    return tuple(_hashable(v) for v in k) if isinstance(k, list) else k


# the pipeline's steps in order (horsemocap.steps.STEPS) with the result files written from each
# (horsemocap.results.write_available): a step computed anew makes the later steps' stored results and files stale
STEP_RESULT_FILES = (("sync", ()), ("rig", ("rig.toml",)), ("plumb", ()), ("static", ()),
                     ("detect", ("markers_2d.csv",)), ("triangulate", ("markers_3d.csv",)), ("smooth", ()),
                     ("motion_frame", ()), ("rigid_body", ("trajectories.csv", "kinematics.csv", "angular.csv")),
                     ("comfort", ("comfort.csv", "comfort.xlsx")))
# records of a whole analysis: stale as soon as any step is computed anew
WHOLE_ANALYSIS_FILES = ("quality.json", "report.html", "PARTIAL.txt")


def refuse_link(path: Path, what: str) -> None:
    """:class:`StoreError` if ``path`` is a symbolic link (the store never writes through one)."""
    if Path(path).is_symlink():
        raise StoreError(f"{path}: {what} is a symbolic link (to {os.readlink(path)}); the results store does not "
                         "follow links out of itself: delete the link and run again")


def _remove_present(paths) -> list:
    """Remove every file or link of ``paths`` that exists; the paths removed."""
    removed = []
    for path in paths:
        if path.is_symlink() or path.is_file():
            path.unlink()
            removed.append(path)
    return removed


@dataclass(frozen=True)
class ResultsStore:
    """Step results of one session's analysis, so a notebook reuses what an
    earlier one computed.

    Each step's result is kept as ``<root>/steps/<step>.npz`` (its arrays,
    read with ``allow_pickle=False``) and ``<root>/steps/<step>.json`` (the
    other values, the key and the SHA-256 of the ``.npz``), never as a
    pickle: a file planted in the store cannot run code. A result is only
    returned for the same key (a fingerprint of the session's files, the
    parameters and the package's code, :func:`horsemocap.pipeline.run_key`),
    so a change of any of them recomputes it. Files are written atomically
    with the user's umask.

    Saving a step that was computed anew removes the stored results of the
    steps after it and their result files in ``root`` (:data:`STEP_RESULT_FILES`,
    and the records of the whole analysis, :data:`WHOLE_ANALYSIS_FILES`): the
    folder never holds a later step's file of another analysis beside the new
    one. The store never follows a symbolic link: ``root``, ``root/steps`` or
    a step's file planted as a link raises :class:`StoreError`.

    Parameters
    ----------
    root : Path
        The results folder.
    """

    root: Path

    def __post_init__(self):
        object.__setattr__(self, "root", Path(self.root))

    def path(self, step: str) -> Path:
        """The JSON file of a step (its arrays are in the ``.npz`` beside it)."""
        if not step.isidentifier():
            raise ValueError(f"step name {step!r}: expected an identifier")
        return self.root / "steps" / f"{step}.json"

    def _check_links(self, step: str) -> None:
        refuse_link(self.root, "the session's results folder")
        refuse_link(self.root / "steps", "the store's 'steps' folder")
        json_path = self.path(step)
        refuse_link(json_path, f"the stored result of step '{step}'")
        refuse_link(json_path.with_suffix(".npz"), f"the stored arrays of step '{step}'")

    def forget_after(self, step: str) -> list:
        """Remove the stored results and result files of the steps after ``step``; the paths removed."""
        names = [name for name, _ in STEP_RESULT_FILES]
        if step not in names:
            return []
        removed = []
        for later, files in STEP_RESULT_FILES[names.index(step) + 1:]:
            json_path = self.path(later)
            removed += _remove_present((json_path, json_path.with_suffix(".npz"), *(self.root / f for f in files)))
        return removed + _remove_present(self.root / name for name in WHOLE_ANALYSIS_FILES)

    def stored_key(self, step: str) -> str | None:
        """The key ``step``'s stored result was saved under (its marker), or None (none stored, unreadable)."""
        self._check_links(step)
        try:
            payload = json.loads(self.path(step).read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError):
            return None
        return payload.get("key") if isinstance(payload, dict) else None

    def forget_stale(self, keys: dict, until: str) -> list:
        """After a run up to ``until``: remove the later steps' stored results and files of another analysis.

        A later step's result and files stay only where its stored result
        carries the key this run's parameters give it (``keys``, step ->
        key): they are what this run would compute. A later step's file
        without a stored result (a marker) is of unknown origin and removed
        too, and so are the records of a whole analysis
        (:data:`WHOLE_ANALYSIS_FILES`) when any later step was stale.
        Returns the paths removed.
        """
        names = [name for name, _ in STEP_RESULT_FILES]
        if until not in names:
            return []
        removed = []
        for later, files in STEP_RESULT_FILES[names.index(until) + 1:]:
            if later in keys and self.stored_key(later) == keys[later]:
                continue
            json_path = self.path(later)
            removed += _remove_present((json_path, json_path.with_suffix(".npz"), *(self.root / f for f in files)))
        if removed:
            removed += _remove_present(self.root / name for name in WHOLE_ANALYSIS_FILES)
        return removed

    def save(self, step: str, result, key: str) -> Path | None:
        """Store ``result`` of ``step`` under ``key``; None (and a warning) if it holds an unstorable value.

        The later steps' stored results and files are removed first (:meth:`forget_after`).
        """
        self._check_links(step)
        self.forget_after(step)
        arrays: dict = {}
        try:
            tree = encode_result(result, arrays)
        except TypeError as exc:
            warnings.warn(f"results store: step '{step}' not stored ({exc}); it will be recomputed", stacklevel=2)
            return None
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        data = buf.getvalue()
        json_path = self.path(step)
        atomic_write_bytes(json_path.with_suffix(".npz"), data)
        text = json.dumps({"format": "horsemocap-step/1", "key": key, "npz_sha256": hashlib.sha256(data).hexdigest(),
                           "result": tree})
        return atomic_write_text(json_path, text)

    def load(self, step: str, key: str):
        """The stored result of ``step`` for ``key``, or None (absent, other key, unreadable, tampered)."""
        self._check_links(step)
        p = self.path(step)
        try:
            payload = json.loads(p.read_text(encoding="utf-8"))
            if not isinstance(payload, dict) or payload.get("key") != key:
                return None
            data = p.with_suffix(".npz").read_bytes()
            if hashlib.sha256(data).hexdigest() != payload.get("npz_sha256"):
                return None  # the arrays of another save: recompute
            with np.load(io.BytesIO(data), allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
            return decode_result(payload["result"], arrays)
        except Exception:  # noqa: BLE001 - absent, from another version, damaged: recompute
            return None
