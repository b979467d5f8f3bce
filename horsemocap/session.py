"""Read and validate a riding session (``session.json``, spec ``sessions.md``).

A session folder holds the recordings of one ride: one motion video (or image
folder) per camera, calibration views or a rig, a plumb still and a static
still (or a short static clip) per camera (thesis Appendix A, steps 1-12). :func:`load_session` checks
every field and every path and raises :class:`SessionError` naming the file,
the field and what was expected.
"""
from __future__ import annotations

import difflib
import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from .sources import check_image_file, FrameSource, is_still_image, list_images, SourceError, still_frame_counts
from .store import MAX_JSON_DEPTH, json_depth, read_text_utf8

FORMAT = "horsemocap-session/1"
KNOWN_FIELDS = ("format", "name", "fps", "cameras", "reference_camera", "motion", "sync",
                "calibration", "plumb", "static", "markers", "analysis", "metadata")
#: Most skin markers a session may name: the static shot is matched to the ride by trying every assignment
#: of its points to the markers ((m + 1)! of them: 7 markers 1.4 s, 8 about 13 s, 9 minutes).
MAX_MARKERS = 8
#: ``metadata.camera_timing.<camera>.interlaced``: which field an interlaced camera exposes first.
INTERLACE_ORDERS = ("bottom_first", "top_first")
REQUIRED_FIELDS = ("format", "name", "fps", "cameras", "motion", "sync", "calibration", "markers")


class SessionError(ValueError):
    """A session that breaks the contract; the message names file and field."""


@dataclass(frozen=True)
class Board:
    """Checkerboard: ``inner_corners`` (cols, rows) and square size in metres."""

    inner_corners: tuple[int, int]
    square_size_m: float


@dataclass(frozen=True)
class Session:
    """A validated riding session. Paths are absolute.

    Attributes mirror ``session.json``; ``sync_offsets`` is None for
    ``{"method": "flash"}`` (found by :mod:`horsemocap.sync`).
    """

    root: Path
    name: str
    fps: float
    cameras: tuple[str, ...]
    reference_camera: str
    motion: dict
    sync_method: str
    sync_offsets: dict | None
    rig_path: Path | None
    calibration_images: dict | None
    board: Board | None
    plumb: dict | None
    static: dict | None
    marker_count: int
    marker_diameter_m: float
    analysis: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)

    @property
    def json_path(self) -> Path:
        return self.root / "session.json"

    def camera_timing(self, camera: str) -> dict:
        """What ``metadata.camera_timing.<camera>`` gives of a camera that runs free (``exposure_s``,
        ``rolling_shutter_s``, ``interlaced``; docs/sessions.md), checked, or ``{}``.

        Examples
        --------
        >>> s = Session(root=Path("."), name="s", fps=25.0, cameras=("left",), reference_camera="left", motion={},
        ...             sync_method="flash", sync_offsets=None, rig_path=None, calibration_images=None, board=None,
        ...             plumb=None, static=None, marker_count=3, marker_diameter_m=0.06,
        ...             metadata={"camera_timing": {"left": {"interlaced": "bottom_first"}}})
        >>> s.camera_timing("left"), s.camera_timing("right")
        ({'interlaced': 'bottom_first'}, {})

        A value the camera cannot have is an error naming its field: ``interlaced`` other than
        ``"bottom_first"``, ``"top_first"`` or null/false; ``exposure_s`` longer than a frame (a field,
        interlaced) or ``rolling_shutter_s`` longer than a frame.
        """
        timing = self.metadata.get("camera_timing", {}) if isinstance(self.metadata, dict) else {}
        given = timing.get(camera) if isinstance(timing, dict) else None
        if not isinstance(given, dict):
            return {}
        name = f"metadata.camera_timing.{camera}"
        if given.get("interlaced") not in (None, False, *INTERLACE_ORDERS):
            _fail(self.json_path, f"{name}.interlaced",
                  f"one of {list(INTERLACE_ORDERS)}, or null/false for a progressive camera", given["interlaced"])
        longest = {"exposure_s": ("one field", 0.5) if given.get("interlaced") else ("one frame", 1.0),
                   "rolling_shutter_s": ("one frame", 1.0)}
        for key, (span, frames) in longest.items():
            value = given.get(key)
            if value is not None and not (isinstance(value, (int, float)) and not isinstance(value, bool)
                                          and 0 <= value <= frames / self.fps * (1 + 1e-9)):
                _fail(self.json_path, f"{name}.{key}", f"a time in seconds from 0 to {span} "
                      f"({frames / self.fps:.6g} s at {self.fps:g} fps)", value)
        return given

    def calibrates_from_views(self, recalibrate: bool = False) -> bool:
        """Whether the rig comes from the checkerboard views: no ``rig.toml``, or ``recalibrate``."""
        return self.calibration_images is not None and (self.rig_path is None or recalibrate)

    def source(self, camera: str) -> FrameSource:
        """The motion frame source of a camera."""
        return FrameSource(self.motion[camera])


def _fail(path, field_name, expected, got=None):
    msg = f"{path}: field '{field_name}': expected {expected}"
    if got is not None:
        msg += f", got {json.dumps(got) if not isinstance(got, str) else repr(got)}"
    raise SessionError(msg)


def _require_dict(path, name, value):
    if not isinstance(value, dict):
        _fail(path, name, "an object", value)
    return value


def _camera_paths(path, root, name, value, cameras, *, must_exist=True, kind="file or folder"):
    value = _require_dict(path, name, value)
    unknown = [c for c in value if c not in cameras]
    if unknown:
        _fail(path, f"{name}.{unknown[0]}", f"a camera listed in 'cameras' {list(cameras)}", unknown[0])
    missing = [c for c in cameras if c not in value]
    if missing:
        _fail(path, name, f"an entry for every camera; '{missing[0]}' is missing")
    out = {}
    for cam in cameras:
        rel = value[cam]
        if not isinstance(rel, str) or not rel or "\0" in rel:
            _fail(path, f"{name}.{cam}", "a path relative to the session folder (no NUL byte)", rel)
        p = (root / rel).resolve()
        if must_exist and not p.exists():
            _fail(path, f"{name}.{cam}", f"an existing {kind} ({p} not found)")
        out[cam] = p
    return out


class SessionWarning(UserWarning):
    """A session.json field this version does not know (a newer optional field): read, not used."""


def _check_unknown_top(path, data) -> None:
    """Top-level fields: a misspelling of a known one is refused, any other new field warned about.

    The contract grows by optional top-level fields, so a session written
    for a newer version is read; a name close to a known field (``"fsp"``)
    is a typo and is refused naming the field it resembles.
    """
    for key in data:
        if key in KNOWN_FIELDS:
            continue
        close = difflib.get_close_matches(key, KNOWN_FIELDS, n=1)
        if close:
            raise SessionError(f"{path}: unknown field '{key}'; did you mean '{close[0]}'? "
                               f"(known fields: {', '.join(KNOWN_FIELDS)})")
        warnings.warn(f"{path}: field '{key}' is not one this version of horsemocap knows "
                      f"(known: {', '.join(KNOWN_FIELDS)}); it is ignored", SessionWarning, stacklevel=3)


def _check_unknown(path, data, known, where=""):
    for key in data:
        if key not in known:
            close = difflib.get_close_matches(key, known, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise SessionError(f"{path}: unknown field '{where}{key}'{hint} (known fields: {', '.join(known)})")


def _number(path, name, value, *, positive=True):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or (positive and value <= 0):
        _fail(path, name, "a positive number" if positive else "a number", value)
    return float(value)


def _check_still(path, field_name, image) -> None:
    """A still image file that is whole (:func:`horsemocap.sources.check_image_file`), else SessionError."""
    if image.is_dir():
        _fail(path, field_name, f"an image file ({image} is a folder)")
    try:
        check_image_file(image)
    except SourceError as exc:
        raise SessionError(f"{path}: field '{field_name}': {exc}") from None


def _check_clip(path, field_name: str, clips: dict) -> None:
    """A plumb or static clip (a video or a folder of frames per camera) whose cameras all hold the same number
    of readable frames (:func:`horsemocap.sources.still_frame_counts`), the image files whole; else SessionError."""
    try:
        still_frame_counts(clips)
        for p in clips.values():
            if Path(p).is_dir():
                for image in list_images(p):
                    check_image_file(image)
    except SourceError as exc:
        raise SessionError(f"{path}: field '{field_name}': {exc}") from None


def load_session(folder, *, open_sources: bool = True) -> Session:
    """Read and validate ``<folder>/session.json``.

    Parameters
    ----------
    folder : path
        The session folder (or the ``session.json`` file itself).
    open_sources : bool
        Also open every motion source (a video must yield a frame; a folder
        must hold images) and check that every plumb and static still is a
        whole image file (a truncated JPEG or PNG is refused naming its
        field), or, a plumb or static clip, that every camera's clip holds the same
        number of frames (:func:`horsemocap.sources.still_frame_counts`). Frame counts against sync offsets are checked by
        :func:`check_frame_counts` once the offsets are known.

    Returns
    -------
    Session

    Raises
    ------
    SessionError
        Naming the file, the field and what was expected.

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> session = load_session(default_session_dir(), open_sources=False)
    >>> session.name, session.fps, session.cameras, session.reference_camera
    ('horse2_canter', 30.0, ('left', 'middle', 'right'), 'left')
    """
    if "\0" in str(folder):
        raise SessionError(f"{str(folder)!r}: a session folder path cannot hold a NUL byte")
    folder = Path(folder)
    path = folder if folder.name == "session.json" else folder / "session.json"
    root = path.parent.resolve()
    if not path.is_file():
        raise SessionError(f"{path}: session file not found (a session folder holds session.json)")

    text = read_text_utf8(path, SessionError)
    if json_depth(text) > MAX_JSON_DEPTH:
        raise SessionError(f"{path}: JSON nested too deeply to read (a session.json is a few levels deep: "
                           "objects of fields, cameras and values)")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SessionError(f"{path}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    except RecursionError:
        raise SessionError(f"{path}: JSON nested too deeply to read (a session.json is a few levels deep: "
                           "objects of fields, cameras and values)") from None
    if not isinstance(data, dict):
        raise SessionError(f"{path}: expected a JSON object at the top level")
    _check_unknown_top(path, data)
    for key in REQUIRED_FIELDS:
        if key not in data:
            raise SessionError(f"{path}: required field '{key}' is missing")
    if data["format"] != FORMAT:
        _fail(path, "format", f'"{FORMAT}"', data["format"])
    name = data["name"]
    if not isinstance(name, str) or not name:
        _fail(path, "name", "a non-empty string", name)
    fps = _number(path, "fps", data["fps"])
    if fps > 10000:
        _fail(path, "fps", "frames per second (at most 10000)", data["fps"])

    cams = data["cameras"]
    if not isinstance(cams, list) or not cams or not all(isinstance(c, str) and c for c in cams):
        _fail(path, "cameras", "a non-empty list of camera names", cams)
    if len(set(cams)) != len(cams):
        _fail(path, "cameras", "unique camera names", cams)
    cameras = tuple(cams)
    ref = data.get("reference_camera", cameras[0])
    if ref not in cameras:
        _fail(path, "reference_camera", f"one of {list(cameras)}", ref)

    motion = _camera_paths(path, root, "motion", data["motion"], cameras, kind="video file or image folder")
    if open_sources:
        for cam, p in motion.items():
            try:
                FrameSource(p).check_whole()
            except SourceError as exc:
                raise SessionError(f"{path}: field 'motion.{cam}': {exc}") from None

    sync = _require_dict(path, "sync", data["sync"])
    _check_unknown(path, sync, ("method", "offsets"), "sync.")
    offsets = None
    if "offsets" in sync:
        raw = _require_dict(path, "sync.offsets", sync["offsets"])
        _check_unknown(path, raw, cameras, "sync.offsets.")
        offsets = {}
        for cam in cameras:
            v = raw.get(cam)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                _fail(path, f"sync.offsets.{cam}", "a frame index (integer >= 0)", v)
            offsets[cam] = v
        method = "offsets"
    elif sync.get("method") == "flash":
        method = "flash"
    else:
        _fail(path, "sync", '{"method": "flash"} or {"offsets": {camera: frame}}', sync)

    cal = _require_dict(path, "calibration", data["calibration"])
    _check_unknown(path, cal, ("rig", "images", "board"), "calibration.")
    rig_path = None
    if "rig" in cal:
        if not isinstance(cal["rig"], str) or not cal["rig"] or "\0" in cal["rig"]:
            _fail(path, "calibration.rig", "a path to rig.toml", cal["rig"])
        rig_path = (root / cal["rig"]).resolve()
        if not rig_path.is_file():
            _fail(path, "calibration.rig", f"an existing rig file ({rig_path} not found)")
    images = board = None
    if "images" in cal:
        images = _camera_paths(path, root, "calibration.images", cal["images"], cameras, kind="folder")
        if "board" not in cal:
            raise SessionError(f"{path}: field 'calibration.board' is required with 'calibration.images'")
        b = _require_dict(path, "calibration.board", cal["board"])
        _check_unknown(path, b, ("inner_corners", "square_size_m"), "calibration.board.")
        ic = b.get("inner_corners")
        if not (isinstance(ic, list) and len(ic) == 2 and all(isinstance(v, int) and not isinstance(v, bool) and v >= 2 for v in ic)):
            _fail(path, "calibration.board.inner_corners", "[columns, rows] of inner corners (integers >= 2)", ic)
        board = Board((ic[0], ic[1]), _number(path, "calibration.board.square_size_m", b.get("square_size_m")))
    if rig_path is None and images is None:
        _fail(path, "calibration", "a 'rig' file or 'images' + 'board'", cal)

    stills = {key: _camera_paths(path, root, key, data[key], cameras, kind="image, video or folder of frames")
              for key in ("plumb", "static") if key in data}
    plumb, static = stills.get("plumb"), stills.get("static")
    if open_sources:
        for key, paths in stills.items():     # not `name`: the session's name
            if all(is_still_image(p) for p in paths.values()):
                for cam, p in paths.items():
                    _check_still(path, f"{key}.{cam}", p)
            else:
                _check_clip(path, key, paths)

    markers = _require_dict(path, "markers", data["markers"])
    _check_unknown(path, markers, ("count", "diameter_m"), "markers.")
    count = markers.get("count")
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_MARKERS:
        _fail(path, "markers.count", f"the number of markers on the horse, the saddle marker not counted (an "
                                     f"integer 1..{MAX_MARKERS}; 3 or more for the rigid body: the "
                                     "static shot is matched by trying every assignment of its points)",
              count)
    diameter = _number(path, "markers.diameter_m", markers.get("diameter_m", 0.06))

    analysis = _require_dict(path, "analysis", data.get("analysis", {}))
    metadata = _require_dict(path, "metadata", data.get("metadata", {}))
    return Session(root=root, name=name, fps=fps, cameras=cameras, reference_camera=ref,
                   motion=motion, sync_method=method, sync_offsets=offsets, rig_path=rig_path,
                   calibration_images=images, board=board, plumb=plumb, static=static,
                   marker_count=count, marker_diameter_m=diameter, analysis=dict(analysis),
                   metadata=dict(metadata))


def synced_frame_count(frame_counts: dict, offsets: dict) -> int:
    """Number of synchronised frames all cameras share (thesis eq. 3.11-3.14).

    Frame ``k`` of the synchronised sequence is frame ``offsets[c] + k`` of
    camera ``c``; the shared length is ``min_c(count_c - offsets_c)``.

    Examples
    --------
    The thesis' offsets: the right camera started 126 frames after the left one.

    >>> synced_frame_count({"left": 300, "middle": 350, "right": 420}, {"left": 12, "middle": 65, "right": 138})
    282
    """
    return min(frame_counts[c] - offsets[c] for c in offsets)


def _offsets_origin(session: Session, offsets: dict, offsets_from: str | None) -> str:
    """Where the sync offsets came from, for an error message."""
    if offsets_from is None:
        if session.sync_offsets is not None and dict(offsets) == dict(session.sync_offsets):
            offsets_from = "given in session.json"
        elif session.sync_method == "flash":
            return ("the offsets given by --offsets (the sync_offsets parameter) or found by the flashlight; "
                    "not session.json's")
        else:
            offsets_from = "given in parameters"
    if offsets_from == "given in session.json":
        return f"'sync.offsets' in {session.json_path}"
    if offsets_from == "given in parameters":
        return "the offsets given by --offsets (the analysis parameter sync_offsets), not session.json"
    if offsets_from.startswith("flashlight"):
        return f"the offsets found by the flashlight ({offsets_from}); give them with --offsets if it is wrong"
    return f"the offsets {offsets_from}"


def check_frame_counts(session: Session, frame_counts: dict, offsets: dict, offsets_from: str | None = None) -> int:
    """Check that every camera has frames at and after its sync offset.

    ``offsets_from`` says where the offsets came from (the sync step's
    ``"given in parameters"``, ``"given in session.json"``, ``"flashlight"``),
    named in the message; None: told from the session (``sync.offsets`` of
    session.json when they are those, else --offsets or the flashlight).

    Returns the synchronised frame count; raises :class:`SessionError` naming
    the camera's file when a source is too short (e.g. a truncated video).
    """
    for cam in session.cameras:
        if frame_counts[cam] <= offsets[cam]:
            raise SessionError(
                f"{session.motion[cam]} ('motion.{cam}'): camera '{cam}' has {frame_counts[cam]} frames, but "
                f"its sync offset is frame {offsets[cam]}: the source is truncated or the offset is wrong "
                f"(see {_offsets_origin(session, offsets, offsets_from)})")
    n = synced_frame_count(frame_counts, offsets)
    return n
