"""Checkerboard views: automatic corner detection with sub-pixel refinement.

The thesis clicked the four extreme corners of every view by hand in
Bouguet's toolbox (section 3.5, Appendix A step 2), after which the toolbox's
corner finder refined every grid corner to sub-pixel accuracy in a
``(2 wintx + 1) x (2 winty + 1)`` window. Here OpenCV finds the board
(``findChessboardCorners``, falling back to ``findChessboardCornersSB``) and
``cornerSubPix`` refines the corners in a window chosen from the measured size
of a square in pixels (:func:`subpix_window`), the same operation as the
toolbox's corner finder.

Board points follow the toolbox: the board is the plane ``Z = 0`` of its own
frame, corner ``(i, j)`` (column ``i``, row ``j``) at ``(i dX, j dY, 0)``.
"""
from __future__ import annotations

import itertools
import os
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..sources import SourceError, list_images, read_image
from ..threads import opencv_single_threaded


class CalibrationError(ValueError):
    """Calibration input that cannot be used (no views, no board found...)."""


def parse_board(board: str) -> tuple[int, int]:
    """``"COLSxROWS"`` (inner corners) -> ``(cols, rows)``; clear error otherwise.

    Examples
    --------
    >>> parse_board("15x29")
    (15, 29)
    """
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", str(board))
    if not m:
        raise CalibrationError(f"--board {board!r}: expected COLSxROWS inner corners, e.g. 9x6")
    cols, rows = int(m.group(1)), int(m.group(2))
    if cols < 2 or rows < 2:
        raise CalibrationError(f"--board {board!r}: a board needs at least 2x2 inner corners")
    return cols, rows


def board_points(inner_corners: tuple[int, int], square_m: float) -> np.ndarray:
    """Board-frame coordinates ``(cols*rows, 3)`` of the inner corners (metres).

    Row-major, as OpenCV returns the corners: index ``j * cols + i`` is column
    ``i`` and row ``j`` at ``(i * square_m, j * square_m, 0)`` (the toolbox's
    ``X_i`` grid with ``dX = dY = square_m``).

    Examples
    --------
    >>> board_points((3, 2), square_m=0.05).round(3).tolist()
    [[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.05, 0.0], [0.05, 0.05, 0.0], [0.1, 0.05, 0.0]]
    """
    cols, rows = inner_corners
    i, j = np.meshgrid(np.arange(cols), np.arange(rows))
    return np.stack([i.ravel() * square_m, j.ravel() * square_m, np.zeros(cols * rows)], axis=1)


CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH
"""Flags of the classic ``findChessboardCorners``: adaptive thresholding, not
``CALIB_CB_NORMALIZE_IMAGE``: the histogram equalisation makes a failing view
slower and finds no view the fallback does not find
(``benchmarks/bench_board_detection.py`` compares the two)."""

SECTOR_FLAGS = cv2.CALIB_CB_EXHAUSTIVE
"""Flags of the fallback ``findChessboardCornersSB``. Not ``CALIB_CB_ACCURACY``:
its own sub-pixel step is redone by ``cornerSubPix`` (every corner is refined
again, :func:`_refine`): the flag makes the fallback slower for the same refined
corners (``benchmarks/bench_board_detection.py`` compares the two)."""


def subpix_window(square_px: float) -> int:
    """Half-size ``w`` of the sub-pixel window for squares of ``square_px`` pixels.

    ``cornerSubPix`` (and the toolbox's corner finder) solves for the point
    where every image gradient in the window is orthogonal to the vector to
    the corner. Two limits (``benchmarks/README.md`` has the measurements):

    * large squares: the edges far from the corner are curved by the lens and
      foreshortened, so the full window ``2 w + 1`` is kept to about half of
      the smallest square side seen in the view, ``w = round(square_px / 4)``,
      around the toolbox's own ``wintx = winty = 7`` on its stereo example; a
      fixed ``(11, 11)``, as in many tutorials, is too large there.
    * small squares (the virtual laboratory's board at 7.5 m: 5-9 px): the
      detector's first estimate can be 3 px off and the edges are blurred, so
      the window must still reach: ``w >= 4`` (smaller windows leave outliers,
      larger ones reach the neighbouring corners).

    Hence ``w = clip(round(square_px / 4), 4, 15)``.

    Examples
    --------
    >>> subpix_window(30.0), subpix_window(8.0)          # a quarter of the square, at least 4
    (8, 4)
    """
    if not np.isfinite(square_px) or square_px <= 0:
        raise CalibrationError(f"square size in pixels must be positive, got {square_px}")
    return int(np.clip(round(float(square_px) / 4.0), 4, 15))


def square_size_px(corners: np.ndarray, inner_corners: tuple[int, int]) -> float:
    """Smallest spacing (pixels) between neighbouring corners of a view: its smallest square side.

    Examples
    --------
    >>> import numpy as np
    >>> corners = (board_points((3, 2), 0.05)[:, :2] * 400 + 100).astype(np.float32)   # 20 px squares
    >>> square_size_px(corners, (3, 2))
    20.0
    """
    cols, rows = inner_corners
    g = np.asarray(corners, float).reshape(rows, cols, 2)
    along = np.linalg.norm(np.diff(g, axis=1), axis=-1)
    across = np.linalg.norm(np.diff(g, axis=0), axis=-1)
    return float(min(along.min(), across.min()))


def canonical_order(corners: np.ndarray) -> np.ndarray:
    """Resolve the 180-degree ambiguity of a board's corner order.

    A board whose corner order cannot tell its two ends apart (OpenCV returns
    either order) is put in the order whose first corner is nearer the image's
    top-left (smaller ``u + v``) than the last one. Cameras that look at the
    board from roughly the same side (the thesis' parallel rig) then number the
    corners alike, which stereo calibration needs.
    """
    c = np.asarray(corners, float).reshape(-1, 2)
    if c[0].sum() > c[-1].sum():
        c = c[::-1].copy()
    return c


def grid_irregularity(corners: np.ndarray, inner_corners: tuple[int, int]) -> float:
    """Largest departure of a corner from the line through its neighbours, in squares.

    Along every row and column of the grid, ``|c[i-1] - 2 c[i] + c[i+1]|``
    divided by the local spacing ``|c[i+1] - c[i-1]| / 2``. Perspective and
    lens distortion bend a board's rows very little from one corner to the
    next; with corner noise, the 266 boards found in two rendered calibration
    sets of the virtual laboratory (squares 5-10 px) stay below 0.17. A row
    that the sub-pixel refinement pulled onto its neighbour gives 0.96-2.0.

    Parameters
    ----------
    corners : ndarray (cols*rows, 2)
        Corners in row-major order (:func:`canonical_order`).
    inner_corners : (cols, rows)

    Returns
    -------
    float
        0 for a perfectly regular grid (or one with fewer than 3 corners per
        line); ``inf`` if any corner is not finite.
    """
    cols, rows = inner_corners
    g = np.asarray(corners, float).reshape(rows, cols, 2)
    if not np.all(np.isfinite(g)):
        return float("inf")
    worst = 0.0
    for grid in (g, g.transpose(1, 0, 2)):
        if grid.shape[1] < 3:
            continue
        second = np.linalg.norm(grid[:, :-2] - 2 * grid[:, 1:-1] + grid[:, 2:], axis=-1)
        spacing = np.linalg.norm(grid[:, 2:] - grid[:, :-2], axis=-1) / 2
        worst = max(worst, float(np.max(second / np.maximum(spacing, 1e-9))))
    return worst


#: Above this :func:`grid_irregularity` a board's corners are not trusted.
MAX_GRID_IRREGULARITY = 0.25


def _refine(gray: np.ndarray, corners: np.ndarray, inner_corners, window: int):
    """``cornerSubPix`` with half-window ``window``, shrunk while the result is irregular.

    Returns ``(refined or None, half-window used, irregularity)``.
    """
    if int(window) < 2:
        raise CalibrationError(f"sub-pixel half-window must be at least 2 pixels, got {window}")
    irregular = np.inf
    for w in range(int(window), 1, -1):
        refined = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2).astype(np.float32), (w, w), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4))
        refined = refined.reshape(-1, 2).astype(float)
        irregular = grid_irregularity(refined, inner_corners)
        if irregular <= MAX_GRID_IRREGULARITY:
            return refined, w, irregular
    return None, int(window), irregular


def detect_board(image: np.ndarray, inner_corners: tuple[int, int], window: int | None = None,
                 ) -> tuple[np.ndarray | None, int, str]:
    """Find the inner corners of a checkerboard in one image.

    OpenCV's classic detector (``findChessboardCorners``) is tried first;
    when it fails (strongly foreshortened boards, squares of 5-7 px) the
    sector-based ``findChessboardCornersSB`` (:data:`SECTOR_FLAGS`) is
    used. Either way the corners are refined by ``cornerSubPix`` (the
    toolbox's corner finder) with the half-window of :func:`subpix_window`;
    if the refined corners are not a regular grid (:func:`grid_irregularity`
    above :data:`MAX_GRID_IRREGULARITY`: the window reached the neighbouring
    corners and pulled rows onto each other), the window is shrunk by one
    pixel until they are (down to 2); a board that stays irregular is not
    used, with the reason.

    Without the check a window can put whole rows of corners pixels off, and
    the sector detector's corners left unrefined bias the focal length; both
    are measured in ``benchmarks/README.md``.

    Parameters
    ----------
    image : ndarray
        Gray ``(h, w)`` or RGB ``(h, w, 3)`` uint8 image.
    inner_corners : (cols, rows)
        Inner corners per row and per column (the toolbox's ``n_sq_x + 1``,
        ``n_sq_y + 1``).
    window : int, optional
        Largest half-size of the sub-pixel window; default
        :func:`subpix_window` of the measured square size.

    Returns
    -------
    corners : ndarray (cols*rows, 2) or None
        Sub-pixel corners in :func:`canonical_order`, or None if not found.
    window : int
        The ``cornerSubPix`` half-window used (0 when not found).
    reason : str
        ``""`` when found, else why not.
    """
    if window is not None and int(window) < 2:
        raise CalibrationError(f"sub-pixel half-window must be at least 2 pixels, got {window}")
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    pattern = (int(inner_corners[0]), int(inner_corners[1]))
    why = f"board of {pattern[0]}x{pattern[1]} inner corners not found"
    for detector in ("classic", "sector"):
        if detector == "classic":
            ok, corners = cv2.findChessboardCorners(gray, pattern, flags=CLASSIC_FLAGS)
        else:
            ok, corners = cv2.findChessboardCornersSB(gray, pattern, flags=SECTOR_FLAGS)
        if not ok:
            continue
        corners = canonical_order(corners)
        w = int(window) if window else subpix_window(square_size_px(corners, inner_corners))
        refined, w_used, irregular = _refine(gray, corners, inner_corners, w)
        if refined is not None:
            return refined, w_used, ""
        why = (f"the board's corners stay irregular after sub-pixel refinement ({irregular:.2f} "
               "squares off a row, even with a 5x5 window): squares too small or blurred")
    return None, 0, why


@dataclass(frozen=True)
class BoardViews:
    """Detected corners of every view of one camera.

    Attributes
    ----------
    camera : str
        Camera name.
    names : tuple of str
        View keys (what matches the same instant across cameras).
    files : tuple of Path
        Image file of each view.
    corners : ndarray (views, cols*rows, 2)
        Sub-pixel corners (the toolbox's ``x_i``); NaN where not found.
    reasons : tuple of str
        ``""`` for a found board, else why it was not found.
    windows : ndarray (views,)
        Sub-pixel half-window used per view (0 when not found).
    size : (width, height)
        Image size in pixels.
    inner_corners : (cols, rows)
    """

    camera: str
    names: tuple
    files: tuple
    corners: np.ndarray
    reasons: tuple
    windows: np.ndarray
    size: tuple
    inner_corners: tuple

    @property
    def found(self) -> np.ndarray:
        """Boolean mask of views with a board."""
        return np.array([r == "" for r in self.reasons], bool)

    def label(self, k: int) -> str:
        """View ``k`` as a user names it: its key and, where it differs, its file (``"5 (middle5.jpg)"``)."""
        return view_label(self.names[k], self.files[k])

    def missing(self) -> list[str]:
        """``"name (file): reason"`` for every view where the board was not found."""
        return [f"{self.label(k)}: {r}" for k, r in enumerate(self.reasons) if r]


def view_label(key: str, file) -> str:
    """A view's key, with its file's name where that is not the key itself.

    Examples
    --------
    >>> view_label("5", "calib/middle/middle5.jpg"), view_label("view03", "calib/left/view03.png")
    ('5 (middle5.jpg)', 'view03')
    """
    return key if file is None or Path(file).stem == key else f"{key} ({Path(file).name})"


def excluded_view_keys(camera: str, keys, files, given) -> set:
    """The keys of the views ``given`` names: each a view's key (``"5"``) or its file's name, with or without
    its extension (``"middle5.jpg"``, ``"middle5"``), as a user reads it in the camera's folder.

    Raises
    ------
    ValueError
        A name that is no view of the camera, with the views it has.

    Examples
    --------
    >>> files = ["calib/middle/middle4.jpg", "calib/middle/middle5.jpg"]
    >>> sorted(excluded_view_keys("middle", view_keys(files, "middle"), files, ["middle5.jpg", "4"]))
    ['4', '5']
    """
    names = {key: key for key in keys}          # a key first: a file's stem never takes another view's key
    for key, f in zip(keys, files):
        if f is not None:
            names.setdefault(Path(f).name, key)
            names.setdefault(Path(f).stem, key)
    unknown = [g for g in given if g not in names]
    if unknown:
        shown = [view_label(k, f) for k, f in zip(keys, files)]
        listed = ", ".join(shown if len(shown) <= 6 else shown[:5] + ["...", shown[-1]])
        raise ValueError(f"camera {camera!r}: cannot exclude unknown views {sorted(unknown)}; give a view's key or "
                         f"its file name (its {len(shown)} view{'s' if len(shown) != 1 else ''}: {listed})")
    return {names[g] for g in given}


def exclusion_keys(image_dirs: dict, exclude: dict) -> dict:
    """``exclude`` (camera -> views named by key or file, :func:`excluded_view_keys`) as camera -> the views'
    sorted keys, read from each camera's folder of views: one spelling per view, so that the calibration's
    cache key does not depend on how a view was named. A camera whose folder is missing or holds no image keeps
    its names (the calibration names the folder).

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> views = {"middle": default_session_dir() / "calibration" / "middle"}
    >>> exclusion_keys(views, {"middle": ["middle5.jpg", "12", "middle7"]})
    {'middle': ['12', '5', '7']}
    """
    out = {}
    for cam, given in exclude.items():
        given = [given] if isinstance(given, str) else list(given)
        folder = image_dirs.get(cam)
        files = list_images(folder) if folder is not None and Path(folder).is_dir() else []
        if not files:
            out[cam] = sorted(given)
            continue
        try:
            out[cam] = sorted(excluded_view_keys(cam, view_keys(files, cam), files, given))
        except ValueError as exc:
            raise CalibrationError(f"{exc} in {folder}") from None
    return out


def view_keys(files, camera: str | None = None) -> list[str]:
    """Keys that say which views of different cameras are the same instant.

    The file stem (``0007.png`` -> ``"0007"``). When a camera's files carry its
    name (``left07.jpg``), the name is stripped so ``left07`` and ``right07``
    meet on ``"07"``.

    Examples
    --------
    >>> view_keys(["calib/left/view10.png", "calib/left/view2.png"])
    ['view10', 'view2']
    """
    keys = []
    for f in files:
        stem = Path(f).stem
        if camera and stem.lower().startswith(camera.lower()) and len(stem) > len(camera):
            stem = stem[len(camera):].lstrip("_-. ")
        keys.append(stem)
    return keys


def detection_workers(workers: int | None = None) -> int:
    """Threads for board detection: ``workers``, or the processors this process may use.

    OpenCV releases the GIL inside ``imread``, ``findChessboardCorners``,
    ``findChessboardCornersSB`` and ``cornerSubPix``, so views are detected
    in parallel by threads (no process start, no copies of the images).
    """
    if workers is None:
        try:
            workers = len(os.sched_getaffinity(0))
        except (AttributeError, OSError):
            workers = os.cpu_count() or 1
    workers = int(workers)
    if workers < 1:
        raise CalibrationError(f"board detection needs at least 1 worker, got {workers}")
    return workers


def _camera_files(folder, camera: str | None) -> tuple[Path, str, list]:
    """The view files of one camera folder (clear errors for a missing or empty folder)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CalibrationError(f"{folder}: calibration folder not found")
    files = list_images(folder)
    if not files:
        raise CalibrationError(f"{folder}: no image files of checkerboard views")
    return folder, camera or folder.name, files


class DetectionStopped(CalibrationError):
    """Board detection stopped on request (:func:`detect_cameras`' ``stop``)."""


#: The start of the reason of a view whose file cannot be read (truncated, corrupt): skipped like a view without
#: a board, and reported (:func:`horsemocap.calibration.rig.unreadable_views`).
UNREADABLE = "cannot be read"


class BoardSizeError(CalibrationError):
    """The board of the size given is in none of the first views, but a board of another size is."""


#: Views of each camera detected first; when the board is found in none of them, they are searched for a
#: board of any size (:func:`probe_board_size`) before the other views are waited for.
PROBE_VIEWS = 3
#: The pattern size handed to ``findChessboardCornersSB`` with ``CALIB_CB_LARGER``: any board at least this
#: big is found, with the size it has (with ``CALIB_CB_EXHAUSTIVE`` the whole board, without it only parts).
_PROBE_PATTERN = (4, 4)


def probe_board_size(gray: np.ndarray) -> tuple[int, int] | None:
    """The inner corners ``(a, b)`` of the checkerboard in a view, whatever its size; None if none is found.

    ``findChessboardCornersSB`` with ``CALIB_CB_LARGER`` grows a board from
    :data:`_PROBE_PATTERN` to the whole grid it sees; the size is kept only
    when the classic or the sector detector then finds a board of exactly
    that size (in either order: OpenCV finds a ``(a, b)`` board as ``(b, a)``
    too), the grid could not continue beyond the image edge
    (:func:`grid_may_continue`) and no board one row or column larger is found
    (the growth can stop short of a cut edge): a board cut by the image edge
    gives no size (cut views of the bundled 7x14 board gave 7x7, 9x7 or 4x8
    parts before).
    """
    found = cv2.findChessboardCornersSBWithMeta(gray, _PROBE_PATTERN, cv2.CALIB_CB_LARGER | SECTOR_FLAGS)
    ok, corners, meta = found
    if not ok or meta is None or meta.ndim != 2:
        return None
    size = (int(meta.shape[0]), int(meta.shape[1]))
    if grid_may_continue(np.asarray(corners, float).reshape(size + (2,)), gray.shape[:2]):
        return None                         # cut by the image edge: a part of a board, not its size
    if not _board_of_size(gray, size):
        return None
    if _board_of_size(gray, (size[0] + 1, size[1])) or _board_of_size(gray, (size[0], size[1] + 1)):
        return None                         # the grid grew short of the board: a part of it, not its size
    return size


def _board_of_size(gray: np.ndarray, size: tuple[int, int]) -> bool:
    """Whether the classic or the sector detector finds a board of exactly ``size`` inner corners."""
    return bool(cv2.findChessboardCorners(gray, size, flags=CLASSIC_FLAGS)[0]
                or cv2.findChessboardCornersSB(gray, size, flags=SECTOR_FLAGS)[0])


def grid_may_continue(grid: np.ndarray, image_hw, margin: float = 1.0) -> bool:
    """Whether a grid of checkerboard corners may be part of a larger board cut by the image edge.

    Each side of the grid is extended by one square (``2 c_edge - c_next``: the line of corners a
    larger board would have there); if any such corner lies outside the image or within ``margin``
    squares of its edge, a row or column of the board could be hidden there, and the grid's size
    is not the board's.

    Parameters
    ----------
    grid : (a, b, 2) ndarray
        Corner pixel positions ``(u, v)`` in grid order, ``a, b >= 2``.
    image_hw : (int, int)
        The image's height and width.
    margin : float
        The clearance required, in squares (the local corner spacing).

    Returns
    -------
    bool
    """
    h, w = int(image_hw[0]), int(image_hw[1])
    sides = [(grid[0], grid[1]), (grid[-1], grid[-2]), (grid[:, 0], grid[:, 1]), (grid[:, -1], grid[:, -2])]
    for edge, inner in sides:
        out = 2 * edge - inner
        clear = margin * np.linalg.norm(edge - inner, axis=-1)
        u, v = out[:, 0], out[:, 1]
        if np.any((u < clear) | (v < clear) | (u > w - 1 - clear) | (v > h - 1 - clear)):
            return True
    return False


def _check_board_size(probes: dict, inner_corners: tuple[int, int]) -> None:
    """Raise :class:`BoardSizeError` when the first views (``probes``: camera -> [(file, result)]) all miss
    the board of ``inner_corners`` and most of them show a board of one other size."""
    results = [(f, r) for views in probes.values() for f, r in views]
    if not results or any(r[1] is not None or isinstance(r[3], Exception) or not r[3].startswith("board of")
                          for _, r in results):
        return
    sizes, seen = {}, []
    for f, _ in results:
        size = probe_board_size(read_image(f, color=False))
        if size is not None:                # (a, b) and (b, a) are one board (OpenCV finds it either way)
            sizes[tuple(sorted(size))] = sizes.get(tuple(sorted(size)), 0) + 1
            seen.append(size)
    if not sizes:
        return                              # no board of any size either: the views' own reasons will say
    key, count = max(sizes.items(), key=lambda kv: kv[1])
    if key == tuple(sorted(inner_corners)) or 2 * count < len(results):
        return
    size = max(set(s for s in seen if tuple(sorted(s)) == key), key=seen.count)
    tried = f"{inner_corners[0]}x{inner_corners[1]}"
    firsts = "; ".join(f"{cam}: {', '.join(Path(f).name for f, _ in views)}" for cam, views in probes.items())
    raise BoardSizeError(
        f"no board of {tried} inner corners in the first {len(results)} checkerboard views ({firsts}), but "
        f"a board of {size[0]}x{size[1]} inner corners in {count} of them: the board size is wrong; set "
        f"'calibration.board.inner_corners' to [{size[0]}, {size[1]}] in session.json (or --board "
        f"{size[0]}x{size[1]} for horsemocap calibrate)")


def _detect_file(path: Path, inner_corners: tuple[int, int], window: int | None, stop=None):
    """One view: ``((width, height), corners or None, window, reason)``."""
    if stop is not None and stop.is_set():
        raise DetectionStopped("board detection stopped")
    try:
        img = read_image(path, color=False)
    except SourceError as exc:      # a truncated or corrupt view is skipped with its reason, as a view without a board
        problem = str(exc)
        problem = problem[len(str(path)) + 2:] if problem.startswith(f"{path}: ") else problem
        return None, None, 0, f"{UNREADABLE}: {problem}"
    try:
        corners, w, why = detect_board(img, inner_corners, window)
    except Exception as exc:         # raised in file order, after the view's size is checked
        return (img.shape[1], img.shape[0]), None, 0, exc
    return (img.shape[1], img.shape[0]), corners, w, why


def _camera_views(camera: str, files: list, detected, inner_corners, tick=None) -> BoardViews:
    """:class:`BoardViews` of one camera from its views' results in file order (sizes checked)."""
    n = int(inner_corners[0]) * int(inner_corners[1])
    corners = np.full((len(files), n, 2), np.nan)
    reasons, windows, size = [], np.zeros(len(files), int), None
    for k, (f, (view_size, c, w, why)) in enumerate(zip(files, detected)):
        if view_size is None:       # unreadable: no size to compare
            pass
        elif size is None:
            size = view_size
        elif view_size != size:
            raise CalibrationError(f"{f}: image size {view_size[0]}x{view_size[1]} differs from "
                                   f"{size[0]}x{size[1]} of the other views of camera {camera!r}")
        if isinstance(why, Exception):
            raise why
        if c is not None:
            corners[k] = c
        reasons.append(why)
        windows[k] = w
        if tick is not None:
            tick(k + 1, len(files))
    if size is None:
        raise CalibrationError(f"camera {camera!r}: none of its {len(files)} checkerboard views can be read "
                               f"({files[0]}: {reasons[0]})")
    return BoardViews(camera, tuple(view_keys(files, camera)), tuple(files), corners,
                      tuple(reasons), windows, size, (int(inner_corners[0]), int(inner_corners[1])))


def detect_cameras(image_dirs: dict, inner_corners: tuple[int, int], window: int | None = None,
                   ticks: dict | None = None, workers: int | None = None, stop=None) -> dict:
    """Detect the board in every view of several cameras, the views shared among threads.

    Each view is detected exactly as :func:`detect_board` alone would (same
    calls, same arguments: the corners are identical whatever the number of
    threads); the results are gathered in file order.

    Parameters
    ----------
    image_dirs : dict camera -> folder
        One folder of checkerboard views per camera.
    inner_corners : (cols, rows)
    window : int, optional
        Fixed sub-pixel half-window; default chosen per view from its squares.
    ticks : dict camera -> callable(done, total), optional
        Progress of each camera, called in file order as its views are done.
    workers : int, optional
        Threads (:func:`detection_workers`; 1 = one view after the other in
        this thread).
    stop : threading.Event, optional
        Once set, no further view is started and :class:`DetectionStopped`
        is raised.

    Returns
    -------
    dict camera -> BoardViews

    Raises
    ------
    BoardSizeError
        The first :data:`PROBE_VIEWS` views of every camera (detected before
        the others) all miss the board of ``inner_corners`` while at least
        half of them show a board of one other size
        (:func:`probe_board_size`): raised at once, naming the size that
        fits, instead of after every view was searched in vain.
    """
    inner_corners = (int(inner_corners[0]), int(inner_corners[1]))
    listed = [_camera_files(folder, cam) for cam, folder in image_dirs.items()]
    jobs = [f for _, _, files in listed for f in files]
    # the first PROBE_VIEWS views of every camera are detected first: a wrong board size shows in them
    starts = np.cumsum([0] + [len(files) for _, _, files in listed])
    first = [int(a) + k for a, (_, _, files) in zip(starts, listed) for k in range(min(PROBE_VIEWS, len(files)))]
    order = first + sorted(set(range(len(jobs))) - set(first))
    workers = min(detection_workers(workers), max(len(jobs), 1))
    ticks = ticks or {}

    def gather(result_of):
        _check_board_size({cam: [(jobs[j], result_of(j)) for j in first if a <= j < a + len(files)]
                           for cam, a, (_, _, files) in zip(image_dirs, starts, listed)}, inner_corners)
        return {cam: _camera_views(camera, files, (result_of(int(a) + k) for k in range(len(files))), inner_corners,
                                   ticks.get(cam))
                for cam, a, (_, camera, files) in zip(image_dirs, starts, listed)}

    if workers == 1:
        done = {}

        def result_of(j):          # gather asks for the first views first, then every view in file order
            if j not in done:
                done[j] = _detect_file(jobs[j], inner_corners, window, stop)
            return done[j]
        return gather(result_of)
    # the views are the parallel work: OpenCV's own threads inside each call would only compete with them
    with opencv_single_threaded(), ThreadPoolExecutor(max_workers=workers, thread_name_prefix="board") as pool:
        futures = {j: pool.submit(_detect_file, jobs[j], inner_corners, window, stop) for j in order}
        try:
            return gather(lambda j: futures[j].result())
        finally:
            for fut in futures.values():          # an error (or an interrupt): start no further view
                fut.cancel()


def detect_views(folder, inner_corners: tuple[int, int], camera: str | None = None,
                 window: int | None = None, tick=None, workers: int | None = None) -> BoardViews:
    """Detect the board in every image of a folder (natural order).

    Parameters
    ----------
    folder : Path
        One folder of checkerboard views of one camera.
    inner_corners : (cols, rows)
    camera : str, optional
        Camera name (default: the folder name).
    window : int, optional
        Fixed sub-pixel half-window; default chosen per view from its squares.
    tick : callable(done, total), optional
        Called after each view (progress of a long calibration).
    workers : int, optional
        Threads detecting views at once (:func:`detect_cameras`).
    """
    camera = camera or Path(folder).name
    return detect_cameras({camera: folder}, inner_corners, window, {camera: tick}, workers)[camera]


def views_from_corners(camera: str, corners, size, inner_corners, names=None) -> BoardViews:
    """:class:`BoardViews` from corner pixels already known (another detector, a file, a simulation).

    ``corners`` is ``(views, cols*rows, 2)``; a view with any NaN counts as
    "board not found".
    """
    corners = np.asarray(corners, float)
    nv = corners.shape[0]
    if corners.ndim != 3 or corners.shape[1:] != (int(inner_corners[0]) * int(inner_corners[1]), 2):
        raise CalibrationError(f"camera {camera!r}: corners must have shape (views, {inner_corners[0]}*"
                               f"{inner_corners[1]}, 2), got {corners.shape}")
    names = tuple(names) if names is not None else tuple(f"{k + 1:02d}" for k in range(nv))
    reasons = tuple("" if np.all(np.isfinite(c)) else "board not found" for c in corners)
    return BoardViews(camera, names, tuple([None] * nv), corners, reasons, np.zeros(nv, int),
                      (int(size[0]), int(size[1])), (int(inner_corners[0]), int(inner_corners[1])))
