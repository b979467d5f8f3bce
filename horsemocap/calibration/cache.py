"""The session's calibration kept in its results folder.

Calibrating the rig from its checkerboard views is most of the time of a
bundled analysis (board detection in every view, then each camera, the pairs
and the joint bundle adjustment). :func:`cached_calibration` keeps the result
in ``calibration.json`` in the results folder, so a repeated ``analyze`` of
the same views does not calibrate again:

- ``key``: SHA-256 of everything that changes the result: every view
  (:func:`horsemocap.fingerprint.file_fingerprint`: path, size, mtime and the
  bytes at both ends), the board (inner corners, square size), the cameras
  and the reference camera, and the source code of :mod:`horsemocap.calibration`
  and :mod:`horsemocap.camera`. The rig is reused only when the key matches.
- ``views``: the detected corners per camera, each under its own key (that
  camera's view files, the board's inner corners and the detector's code), so
  that when the key changes for another reason (the square size, the
  reference camera, another camera's views) board detection still runs once
  per view.

A second, user-level cache (:func:`board_cache_dir`, by default
``horsemocap.data.cache_dir() / "boards"``) keeps the same records under keys
of the views' *contents* (:func:`content_views_key`: each view's file name,
size and bytes; not its folder or modification time), so a rig calibrated
once serves every results folder and every session whose calibration views
are the same files, copied or not. Its files are written whole or not at
all by any number of processes at once; a cache that cannot be written
(a read-only home) is skipped, never an error of the analysis.

``recalibrate`` (:class:`~horsemocap.params.AnalysisParams`) ignores both
caches and calibrates from scratch. The file is written whole or not at all
(:func:`horsemocap.store.atomic_write_text`), into the run's own folder (with
``horsemocap analyze`` the temporary folder that replaces the results folder
whole, :mod:`horsemocap.runfolder`); it is read from there and from the
earlier run's folder.
"""
from __future__ import annotations

import hashlib
import json
import os
import threading
from pathlib import Path

import numpy as np

from .. import camera
from ..camera import Camera, Rig
from ..data import cache_dir
from ..fingerprint import file_digest, file_fingerprint
from ..sources import list_images
from ..store import atomic_write_text
from .board import UNREADABLE, BoardViews, detect_cameras
from .rig import board_view_counter, calibrate_rig

CACHE_FILE = "calibration.json"
CACHE_FORMAT = "horsemocap-calibration-cache/1"

BOARD_CACHE_ENV = "HORSEMOCAP_BOARD_CACHE"

__all__ = ["CACHE_FILE", "CACHE_FORMAT", "BOARD_CACHE_ENV", "calibration_key", "views_key", "content_views_key",
           "board_cache_dir", "cached_calibration", "BoardDetectionJob", "views_cached"]


def _code_hash(names) -> bytes:
    here = Path(__file__).parent
    h = hashlib.sha256()
    for name in names:
        h.update((here / name).read_bytes() if (here / name).is_file() else name.encode())
    return h.digest()


def views_key(folder, inner_corners) -> str:
    """Key of one camera's board detection: its view files, the inner corners and the detector's code."""
    h = hashlib.sha256()
    for f in list_images(Path(folder)):
        h.update(file_fingerprint(f).encode("utf-8", "surrogateescape"))
    h.update(json.dumps([int(inner_corners[0]), int(inner_corners[1])]).encode())
    h.update(_code_hash(["board.py"]))
    return h.hexdigest()


def _content_fingerprint(path: Path) -> str:
    """A view's file name, size and the SHA-256 of all its bytes (:func:`horsemocap.fingerprint.file_digest`)."""
    return f"{path.name}|{path.stat().st_size}|{file_digest(path)}"


def content_views_key(folder, inner_corners) -> str:
    """Key of one camera's board detection by the views' contents: names, sizes, bytes, the board, the detector.

    Unlike :func:`views_key` it leaves out the folder and the modification
    times, so the same views copied elsewhere have the same key.

    Examples
    --------
    >>> import tempfile
    >>> a, b = Path(tempfile.mkdtemp()), Path(tempfile.mkdtemp())
    >>> for d in (a, b):
    ...     _ = (d / "1.png").write_bytes(b"view")
    >>> content_views_key(a, (7, 14)) == content_views_key(b, (7, 14)) != content_views_key(a, (9, 6))
    True
    """
    h = hashlib.sha256(b"content")
    for f in list_images(Path(folder)):
        h.update(_content_fingerprint(f).encode("utf-8", "surrogateescape"))
    h.update(json.dumps([int(inner_corners[0]), int(inner_corners[1])]).encode())
    h.update(_code_hash(["board.py"]))
    return h.hexdigest()


def board_cache_dir() -> Path | None:
    """The user-level cache of board detections and calibrated rigs, or None when switched off.

    ``$HORSEMOCAP_BOARD_CACHE``: a folder, or ``off`` for no user-level
    cache; unset: ``horsemocap.data.cache_dir() / "boards"``.
    """
    given = os.environ.get(BOARD_CACHE_ENV, "").strip()
    if given.lower() == "off":
        return None
    return Path(given) if given else cache_dir() / "boards"


def _user_read(name: str) -> dict | None:
    """A record of the user-level cache (None if absent, damaged, another format or the cache is off)."""
    folder = board_cache_dir()
    if folder is None:
        return None
    try:
        d = json.loads((folder / name).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return d if isinstance(d, dict) and d.get("format") == CACHE_FORMAT else None


def _user_write(name: str, record: dict) -> None:
    """A record written whole into the user-level cache; skipped when it cannot be written."""
    folder = board_cache_dir()
    if folder is None:
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(folder / name, json.dumps(record, separators=(",", ":")) + "\n")
    except OSError:
        pass


def _user_views(cam: str, folder, content_key: str) -> BoardViews | None:
    """``cam``'s views from the user-level cache, their files those of ``folder`` (None if not there)."""
    d = _user_read(f"views-{content_key}.json")
    if d is None or not isinstance(d.get("views"), dict):
        return None
    try:
        v = _views_from_json(cam, d["views"])
    except (KeyError, TypeError, ValueError):
        return None
    files = tuple(list_images(Path(folder)))
    if len(files) != len(v.names):
        return None
    return BoardViews(cam, v.names, files, v.corners, v.reasons, v.windows, v.size, v.inner_corners)


def calibration_key(image_dirs: dict, inner_corners, square_m: float, reference: str, exclude=None,
                    mode: str = "joint", view_keys: dict | None = None) -> str:
    """Key of a rig calibration: every view, the board, the cameras, the reference, the views left out and the code.

    ``view_keys``: each camera's :func:`views_key`, when the caller has them (else computed here).
    """
    view_keys = view_keys or {cam: views_key(folder, inner_corners) for cam, folder in image_dirs.items()}
    h = hashlib.sha256()
    for cam in image_dirs:
        h.update(cam.encode())
        h.update(view_keys[cam].encode())
    h.update(json.dumps({"inner_corners": [int(x) for x in inner_corners], "square_m": float(square_m),
                         "reference": reference}, sort_keys=True).encode())
    if mode != "joint":                 # (no key change for the default joint calibration)
        h.update(f"mode={mode}".encode())
    if exclude:                         # (no key change for calibrations without exclusions)
        h.update(json.dumps({c: sorted(str(v) for v in exclude[c]) for c in sorted(exclude)}).encode())
    h.update(_code_hash(sorted(p.name for p in Path(__file__).parent.glob("*.py"))))
    h.update(Path(camera.__file__).read_bytes())
    return h.hexdigest()


def _rig_to_json(rig: Rig) -> dict:
    """Every number of the rig (JSON keeps floats exactly)."""
    return {"cameras": [{"name": c.name, "size": [int(x) for x in c.size], "matrix": np.asarray(c.matrix).tolist(),
                         "distortions": np.asarray(c.distortions).tolist(), "rotation": np.asarray(c.rotation).tolist(),
                         "translation": np.asarray(c.translation).tolist()} for c in rig.cameras],
            "metadata": json.loads(json.dumps(rig.metadata, default=float))}


def _rig_from_json(d: dict) -> Rig:
    cams = tuple(Camera(name=c["name"], size=tuple(c["size"]), matrix=np.asarray(c["matrix"], float),
                        distortions=np.asarray(c["distortions"], float), rotation=np.asarray(c["rotation"], float),
                        translation=np.asarray(c["translation"], float)) for c in d["cameras"])
    return Rig(cams, dict(d.get("metadata", {})))


def _views_to_json(v: BoardViews, key: str) -> dict:
    return {"key": key, "names": list(v.names), "files": [str(f) for f in v.files],
            "reasons": list(v.reasons), "windows": [int(w) for w in v.windows], "size": [int(s) for s in v.size],
            "inner_corners": [int(x) for x in v.inner_corners],
            "corners": [_corners_json(c) for c in v.corners]}


def _corners_json(c: np.ndarray):
    """One view's corners: null where the board was not found, else the pixels (null for a NaN value)."""
    ok = np.isfinite(c)
    if not ok.any():
        return None
    if ok.all():
        return c.tolist()
    return [[float(x) if np.isfinite(x) else None for x in pt] for pt in c]


def _views_from_json(camera: str, d: dict) -> BoardViews:
    n = int(d["inner_corners"][0]) * int(d["inner_corners"][1])
    corners = np.full((len(d["names"]), n, 2), np.nan)
    for k, c in enumerate(d["corners"]):
        if c is not None:
            corners[k] = np.array(c, dtype=float)     # null -> NaN
    return BoardViews(camera, tuple(d["names"]), tuple(Path(f) for f in d["files"]), corners,
                      tuple(d["reasons"]), np.asarray(d["windows"], int), tuple(d["size"]),
                      tuple(d["inner_corners"]))


def _write(folder: Path, record: dict) -> None:
    """``calibration.json`` written whole or not at all (compact: the corners are most of it)."""
    atomic_write_text(folder / CACHE_FILE, json.dumps(record, separators=(",", ":")) + "\n")


def _read(folder) -> dict | None:
    if folder is None:
        return None
    path = Path(folder) / CACHE_FILE
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return d if isinstance(d, dict) and d.get("format") == CACHE_FORMAT else None


class BoardDetectionJob:
    """The board detection of a session's views, started in a thread before the analysis needs it.

    ``horsemocap analyze`` starts it as soon as the session is read, so the
    views are detected while the interpreter imports the analysis' modules
    and checks the parameters; :func:`cached_calibration` takes the views
    from it (``detected``) when their key (:func:`views_key`: the same files,
    board and detector code) is the one it would detect.

    Parameters
    ----------
    image_dirs : dict camera -> folder
    inner_corners : (cols, rows)
    workers : int, optional
        As :func:`~.board.detect_cameras`.
    """

    def __init__(self, image_dirs: dict, inner_corners, workers: int | None = None):
        self.keys = {cam: views_key(folder, inner_corners) for cam, folder in image_dirs.items()}
        self.done = {cam: 0 for cam in image_dirs}
        self.totals = {cam: 0 for cam in image_dirs}
        self._views, self._error = None, None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(dict(image_dirs), inner_corners, workers),
                                        name="horsemocap-board", daemon=True)
        self._thread.start()

    def _count(self, cam):
        def tick(done, total):
            self.done[cam], self.totals[cam] = done, total
        return tick

    def _run(self, image_dirs, inner_corners, workers):
        try:
            self._views = detect_cameras(image_dirs, inner_corners, workers=workers, stop=self._stop,
                                         ticks={cam: self._count(cam) for cam in image_dirs})
        except BaseException as exc:  # given to the caller by views()
            self._error = exc

    def views(self, cam: str, key: str, progress=None) -> BoardViews | None:
        """The views of ``cam`` if this job detects the files of ``key`` (waits for it), else None.

        ``progress`` (as :func:`cached_calibration`'s) is told the views
        counted while it waits. The job's error (a view of another size...)
        is raised here.
        """
        if self.keys.get(cam) != key:
            return None
        told = {}
        while self._thread.is_alive():
            self._thread.join(0.25)
            for c in self.done:
                if progress is not None and self.totals[c] and told.get(c) != self.done[c]:
                    told[c] = self.done[c]
                    board_view_counter(progress, c)(self.done[c], self.totals[c])
        if self._error is not None:
            raise self._error
        return self._views[cam]

    def stop(self) -> None:
        """Start no further view (without waiting): :meth:`views` then raises ``DetectionStopped``."""
        self._stop.set()

    def close(self) -> None:
        """Start no further view and wait for those under way (at the end of a run, or after its error)."""
        self.stop()
        self._thread.join()


def views_cached(image_dirs: dict, inner_corners, folders) -> bool:
    """Whether ``calibration.json`` in one of ``folders`` or the user-level cache holds every camera's corners."""
    found = [d for d in (_read(f) for f in folders if f is not None) if d is not None]
    return all(_cached_views(found, cam, views_key(folder, inner_corners)) is not None
               or _user_read(f"views-{content_views_key(folder, inner_corners)}.json") is not None
               for cam, folder in image_dirs.items())


def _cached_views(records: list, cam: str, key: str) -> dict | None:
    """The first of the ``calibration.json`` records holding ``cam``'s views under ``key`` (its JSON), else None."""
    return next((d["views"][cam] for d in records if isinstance(d.get("views"), dict)
                 and isinstance(d["views"].get(cam), dict) and d["views"][cam].get("key") == key), None)


def cached_calibration(image_dirs: dict, inner_corners, square_m: float, reference: str, *,
                       write_to=None, read_from=(), recalibrate: bool = False, progress=None, exclude=None,
                       mode: str = "joint", detected: BoardDetectionJob | None = None):
    """The rig calibrated from ``image_dirs`` (as :func:`~.rig.calibrate_rig`), reusing a cached one.

    Parameters
    ----------
    image_dirs : dict camera -> folder of checkerboard views
    inner_corners, square_m, reference
        As :func:`~.rig.calibrate_rig` (joint mode).
    write_to : path, optional
        Results folder to write ``calibration.json`` into (none: not written).
    read_from : iterable of paths
        Results folders whose ``calibration.json`` may be reused (``write_to``
        is looked at first).
    recalibrate : bool
        Ignore every cached result.
    progress : callable(step, message[, done, total]), optional
        The pipeline's progress (messages under ``"rig"``; board views counted).
    mode : {"joint", "pairwise"}
        As :func:`~.rig.calibrate_rig` (part of the key).
    exclude : dict camera -> list of view names, optional
        Views left out of the calibration (as :func:`~.rig.calibrate_rig`;
        part of the key; the board corners of every view are still kept).
    detected : BoardDetectionJob, optional
        Board detection already under way: the views it detects (same key)
        are taken from it instead of detected again.

    Returns
    -------
    rig : Rig
    how : str
        ``"calibrated from checkerboard views"``, ``"... (cached in calibration.json)"`` or ``"... (cached in
        the user-level board cache)"`` (:func:`board_cache_dir`).
    """
    say = (lambda msg: progress("rig", msg)) if progress else (lambda msg: None)
    vkeys = {cam: views_key(folder, inner_corners) for cam, folder in image_dirs.items()}   # (hashes every view)
    key = calibration_key(image_dirs, inner_corners, square_m, reference, exclude, mode, vkeys)
    ckeys = {} if recalibrate else {cam: content_views_key(folder, inner_corners) for cam, folder in image_dirs.items()}
    user_key = None if recalibrate else calibration_key(image_dirs, inner_corners, square_m, reference, exclude,
                                                        mode, ckeys)
    folders = [f for f in ([write_to] + list(read_from)) if f is not None]
    found = [] if recalibrate else [(f, d) for f, d in ((f, _read(f)) for f in folders) if d is not None]
    for folder, d in found:
        if d.get("key") != key or not isinstance(d.get("rig"), dict):
            continue
        try:
            rig = _rig_from_json(d["rig"])
        except (KeyError, TypeError, ValueError):
            continue                                    # damaged: calibrate again
        if write_to is not None and Path(write_to).resolve() != Path(folder).resolve():
            _write(Path(write_to), d)                   # carried into the new results folder
        say(f"calibration reused from {CACHE_FILE} (same views, board, cameras and code)")
        return rig, "calibrated from checkerboard views (cached in calibration.json)"
    found = [d for _, d in found]
    if user_key is not None:
        rig, views = _user_calibration(user_key, image_dirs, inner_corners)
        if rig is not None:
            if write_to is not None:
                _write(Path(write_to), _record(key, reference, inner_corners, square_m, rig, views, vkeys))
            say(f"calibration reused from the user-level cache {board_cache_dir()} (same views, board, cameras "
                "and code)")
            return rig, "calibrated from checkerboard views (cached in the user-level board cache)"
    views, reused = {}, []
    for cam in image_dirs:
        hit = _cached_views(found, cam, vkeys[cam])
        try:
            views[cam] = _views_from_json(cam, hit) if hit is not None else None
        except (KeyError, TypeError, ValueError):
            views[cam] = None                           # damaged: detect again
        if views[cam] is None and ckeys:
            views[cam] = _user_views(cam, image_dirs[cam], ckeys[cam])
        if views[cam] is not None:
            reused.append(cam)
    if detected is not None:
        early = [cam for cam in image_dirs if views[cam] is None]
        for cam in early:
            views[cam] = detected.views(cam, vkeys[cam], progress)
        early = [cam for cam in early if views[cam] is not None]
        if early:
            say(f"board corners of camera(s) {', '.join(early)} detected while the analysis started")
    missing = {cam: image_dirs[cam] for cam in image_dirs if views[cam] is None}
    if missing:                                         # every camera's views in one pool of threads
        views.update(detect_cameras(missing, inner_corners,
                                    ticks={cam: board_view_counter(progress, cam) for cam in missing}))
    if reused:
        say(f"board corners of camera(s) {', '.join(reused)} reused from {CACHE_FILE} or the user-level cache")
    for cam in ckeys:                                   # (the user-level cache: by the views' contents)
        if cam not in reused:
            _user_write(f"views-{ckeys[cam]}.json", {"format": CACHE_FORMAT, "views": _views_to_json(views[cam],
                                                                                                   ckeys[cam])})
    for line in boards_not_found(views):
        say(line)
    say("calibrating from checkerboard views ...")
    # the pairs' stereo calibrations (Table 8.4) are not part of a joint rig: not computed here
    # (``horsemocap calibrate`` reports them); the pairwise rig computes the pairs it needs
    cal = calibrate_rig(image_dirs, inner_corners, square_m, reference=reference, views=dict(views), exclude=exclude,
                        mode=mode, progress=progress, pairs=False)
    if user_key is not None:
        _user_write(f"rig-{user_key}.json", _record(user_key, reference, inner_corners, square_m, cal.rig, None, {}))
    if write_to is not None:
        _write(Path(write_to), _record(key, reference, inner_corners, square_m, cal.rig, views, vkeys))
    return cal.rig, f"calibrated from checkerboard views ({mode})"


def boards_not_found(views: dict, shown: int = 3) -> list[str]:
    """One line per camera whose board was not found in every view: how many views have it, and the first
    ``shown`` of those without, each with its reason (such a view is left out of the calibration). A view
    whose file cannot be read is said by :func:`~.rig.unreadable_views`, not here.

    Examples
    --------
    >>> from horsemocap.calibration.board import views_from_corners
    >>> corners = np.zeros((3, 4, 2)); corners[1] = np.nan
    >>> boards_not_found({"left": views_from_corners("left", corners, (640, 480), (2, 2))})
    ["camera 'left': the board was found in 2 of 3 views; not in 02: board not found"]
    """
    lines = []
    for cam, v in views.items():
        lost = [f"{v.label(k)}: {r}" for k, r in enumerate(v.reasons) if r and not r.startswith(UNREADABLE)]
        if lost:
            more = f" and {len(lost) - shown} more" if len(lost) > shown else ""
            lines.append(f"camera {cam!r}: the board was found in {int(v.found.sum())} of {len(v.names)} "
                         f"views; not in {'; '.join(lost[:shown])}{more}")
    return lines


def _record(key: str, reference: str, inner_corners, square_m: float, rig: Rig, views, vkeys: dict) -> dict:
    """A ``calibration.json`` record (``views`` None: the rig only, as the user-level cache keeps it)."""
    record = {"format": CACHE_FORMAT, "key": key, "reference": reference,
              "board": {"inner_corners": [int(x) for x in inner_corners], "square_size_m": float(square_m)},
              "rig": _rig_to_json(rig)}
    if views is not None:
        record["views"] = {cam: _views_to_json(views[cam], vkeys[cam]) for cam in vkeys}
    return record


def _user_calibration(user_key: str, image_dirs: dict, inner_corners):
    """The rig of the user-level cache under ``user_key`` and every camera's views, or (None, None)."""
    d = _user_read(f"rig-{user_key}.json")
    if d is None or d.get("key") != user_key or not isinstance(d.get("rig"), dict):
        return None, None
    try:
        rig = _rig_from_json(d["rig"])
    except (KeyError, TypeError, ValueError):
        return None, None
    views = {}
    for cam, folder in image_dirs.items():
        views[cam] = _user_views(cam, folder, content_views_key(folder, inner_corners))
        if views[cam] is None:
            return None, None                           # the rig without its corners: calibrate again
    return rig, views
