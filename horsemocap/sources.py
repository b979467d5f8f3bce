"""Frame sources: a video file or a folder of images, in natural order.

Thesis Appendix A spends pages renaming files so that MATLAB reads
``left2.png`` before ``left10.png``; :func:`natural_key` does it here.
"""
from __future__ import annotations

import re
import threading
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm"}
#: A video read ahead by fewer frames than this is decoded through, not sought (OpenCV's seek in an
#: MJPEG AVI costs 6-8 ms, about 15 frames' decoding at 640 x 480).
_DECODE_THROUGH = 16
#: Frames a :class:`FrameSequence` read forwards keeps decoded ahead of the one being read, by a second
#: thread, in blocks of :data:`READ_BLOCK` (the next block starts as soon as the last is collected);
#: at most half and a quarter of the sequence's cache.
READ_AHEAD = 48
READ_BLOCK = 16
#: Bytes of decoded gray video frames shared by the readers of a video in one process: the flash
#: search decodes the first frames of each video, the detection and its check read them again.
SHARED_GRAY_BYTES = 160 * 2 ** 20

#: The backend that reads the videos: FFmpeg where OpenCV has it. The default order would try OpenCV's own
#: MJPEG reader after FFmpeg fails on a broken file, and that reader prints its complaints to the terminal.
VIDEO_BACKEND = cv2.CAP_FFMPEG if cv2.videoio_registry.hasBackend(cv2.CAP_FFMPEG) else cv2.CAP_ANY
_OPEN_LOCK = threading.Lock()


def open_video(path) -> cv2.VideoCapture:
    """A ``cv2.VideoCapture`` of ``path`` through :data:`VIDEO_BACKEND` (check ``isOpened()``).

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> cap = open_video(default_session_dir() / "motion" / "left.avi")
    >>> cap.isOpened(), cap.read()[0]
    (True, True)
    >>> cap.release()
    """
    # OpenCV's own warning of a file its backend cannot open would come before our error too. The level is the
    # process's: other threads' OpenCV warnings are held back while a video opens (the lock serialises the opens)
    with _OPEN_LOCK:
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(min(level, cv2.utils.logging.LOG_LEVEL_ERROR))   # never louder
        try:
            return cv2.VideoCapture(str(path), VIDEO_BACKEND)
        finally:
            cv2.utils.logging.setLogLevel(level)



class _SharedGray:
    """Decoded gray frames of videos, at most ``limit`` bytes.

    Frames put ``pinned`` (the flash search's, which the detection reads again from the start of the
    record) leave only when no other frame is left to make room; the others least recently used first.
    """

    def __init__(self, limit: int):
        self.limit, self.size, self.frames = int(limit), 0, OrderedDict()
        self.pinned: set = set()
        self.unpinned: OrderedDict = OrderedDict()     # the frames not pinned, in the order of ``frames``
        self.lock = threading.Lock()        # the reading threads of several sequences share it

    @staticmethod
    def video_key(path: Path):
        st = path.stat()
        return str(path.resolve()), st.st_mtime_ns, st.st_size

    def get(self, video, index: int):
        with self.lock:
            f = self.frames.get((video, index))
            if f is not None:
                self.frames.move_to_end((video, index))
                if (video, index) in self.unpinned:
                    self.unpinned.move_to_end((video, index))
            return f

    def put(self, video, index: int, frame: np.ndarray, pinned: bool = False) -> None:
        with self.lock:
            self._put((video, index), frame, pinned)

    def _put(self, key, frame: np.ndarray, pinned: bool) -> None:
        if frame.nbytes > self.limit or key in self.frames:
            return
        if not pinned and self.size + frame.nbytes > self.limit and len(self.pinned) == len(self.frames):
            return                      # room only by dropping a pinned frame: keep those instead
        self.frames[key] = frame
        self.size += frame.nbytes
        if pinned:
            self.pinned.add(key)
        else:
            self.unpinned[key] = None
        while self.size > self.limit:
            if self.unpinned:           # the least recently used frame not pinned (no scan past the pinned)
                old_key = next(iter(self.unpinned))
                del self.unpinned[old_key]
            else:                       # only pinned frames left: the oldest of them
                old_key = next(iter(self.frames))
                self.pinned.discard(old_key)
            self.size -= self.frames.pop(old_key).nbytes


_SHARED = _SharedGray(SHARED_GRAY_BYTES)
#: Frame counts of the videos read in this process (FrameSource._video_counts), by video_key.
_COUNTS: dict = {}
_COUNTS_LOCK = threading.Lock()
#: Videos found to open and decode a first frame in this process (FrameSource), by video_key.
_OPENED: set = set()


@dataclass(frozen=True)
class DecodedFrames:
    """The gray video frames a process decoded and shares, copied into one buffer for another process.

    Made by :func:`export_decoded` in the process that decoded them (a forked
    copy searching the flash), given to :func:`import_decoded` in the one
    that reads them next: the frames are not decoded again there, and what
    each process knows of its videos (frame counts, files checked) goes with
    them.

    Attributes
    ----------
    frames : tuple
        ``(video, index, shape, offset)`` per frame, in the order they were
        kept (``video``: the file's key, path, modification time and size).
    counts : dict
        Video key -> its frame counts (declared, decodable).
    opened : frozenset
        Video keys of the files found to open and decode.

    Examples
    --------
    One 2 x 3 gray frame (frame 0 of a video), copied at the start of a buffer:

    >>> import mmap
    >>> buffer = mmap.mmap(-1, mmap.PAGESIZE)
    >>> buffer[:6] = bytes([10, 20, 30, 40, 50, 60])
    >>> video = ("/videos/left.avi", 1_700_000_000_000_000_000, 123_456)    # path, modification time, size
    >>> decoded = DecodedFrames(frames=((video, 0, (2, 3), 0),), counts={video: (250, 250)},
    ...                         opened=frozenset({video}))
    >>> [(index, shape, offset) for _, index, shape, offset in decoded.frames]
    [(0, (2, 3), 0)]
    """

    frames: tuple
    counts: dict
    opened: frozenset


def export_decoded(buffer) -> DecodedFrames:
    """The pinned gray frames this process shares (see :class:`_SharedGray`), copied into ``buffer`` (a
    writable buffer, e.g. a shared ``mmap`` made before a fork) in the order they were kept, as many as fit.

    Examples
    --------
    >>> import mmap
    >>> export_decoded(mmap.mmap(-1, 4096)).frames        # nothing decoded in this process yet
    ()
    """
    view = np.frombuffer(buffer, np.uint8)
    with _SHARED.lock:
        pinned = [(key, f) for key, f in _SHARED.frames.items() if key in _SHARED.pinned]
    entries, offset = [], 0
    for (video, index), frame in pinned:
        if offset + frame.nbytes > len(view):
            break
        view[offset:offset + frame.nbytes] = frame.reshape(-1)
        entries.append((video, index, frame.shape, offset))
        offset += frame.nbytes
    with _COUNTS_LOCK:
        return DecodedFrames(tuple(entries), dict(_COUNTS), frozenset(_OPENED))


def import_decoded(decoded: DecodedFrames, buffer) -> None:
    """Share in this process the frames :func:`export_decoded` copied into ``buffer`` (read in place, kept
    pinned as if decoded here, in the same order) and what the other process knew of the videos.

    Examples
    --------
    A forked copy decodes the first frames of a video and copies them into
    memory made before the fork; this process reads them from there:

    >>> import mmap, os, pickle, tempfile
    >>> from horsemocap.forking import fork_call
    >>> path = os.path.join(tempfile.mkdtemp(), "clip.avi")
    >>> out = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (64, 48))
    >>> for k in range(3):
    ...     _ = out.write(np.full((48, 64, 3), 60 * k, np.uint8))
    >>> out.release()
    >>> buffer = mmap.mmap(-1, SHARED_GRAY_BYTES)          # seen by both processes
    >>> read_end, write_end = os.pipe()
    >>> def decode_and_send():
    ...     list(FrameSource(path).iter_frames(0, 3, color=False, share=True))
    ...     with os.fdopen(write_end, "wb") as sent:
    ...         pickle.dump(export_decoded(buffer), sent)
    >>> pid = fork_call(decode_and_send)
    >>> os.close(write_end)
    >>> with os.fdopen(read_end, "rb") as got:
    ...     decoded = pickle.load(got)
    >>> os.waitpid(pid, 0)[1]
    0
    >>> import_decoded(decoded, buffer)
    >>> [(index, shape) for video, index, shape, _ in decoded.frames if video[0] == str(Path(path).resolve())]
    [(0, (48, 64)), (1, (48, 64)), (2, (48, 64))]
    >>> frame = FrameSource(path).sequence(0, 3, color=False)[2]
    >>> frame.shape, np.shares_memory(frame, np.frombuffer(buffer, np.uint8))   # read in place, not decoded
    ((48, 64), True)
    """
    view = np.frombuffer(buffer, np.uint8)
    for video, index, shape, offset in decoded.frames:
        frame = view[offset:offset + int(np.prod(shape))].reshape(shape)
        _SHARED.put(video, index, frame, pinned=True)
    with _COUNTS_LOCK:
        for key, counts in decoded.counts.items():
            _COUNTS.setdefault(key, counts)
        _OPENED.update(decoded.opened)


class SourceError(ValueError):
    """A camera source that cannot be opened or read."""


def natural_key(name: str):
    """Sort key that orders embedded numbers by value (``a2`` < ``a10``).

    Examples
    --------
    >>> sorted(["f10.png", "f2.png", "F1.png"], key=natural_key)
    ['F1.png', 'f2.png', 'f10.png']
    """
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", str(name))]


def natural_sorted(paths) -> list[Path]:
    """Paths sorted by :func:`natural_key` of their file names.

    Examples
    --------
    >>> [p.name for p in natural_sorted(["left/f10.png", "left/f2.png", "left/f1.png"])]
    ['f1.png', 'f2.png', 'f10.png']
    """
    return sorted((Path(p) for p in paths), key=lambda p: natural_key(p.name))


def list_images(folder) -> list[Path]:
    """Image files of a folder in natural order (hidden files skipped)."""
    folder = Path(folder)
    return natural_sorted(p for p in folder.iterdir()
                          if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith("."))


def _jpeg_complete(data: bytes) -> bool:
    """Whether a JPEG's marker segments lead to a scan that ends with the end-of-image marker.

    The segments before the first start-of-scan (``FF DA``) are stepped over by their lengths (an
    EXIF thumbnail inside APP1 is not mistaken for the image), then the entropy-coded data, in which
    ``FF`` is always followed by ``00`` or a restart marker, must reach ``FF D9``. Data after it
    (phone cameras append trailers) is allowed.
    """
    i = 2
    while i + 4 <= len(data):
        if data[i] != 0xFF:
            return False
        marker = data[i + 1]
        if marker == 0xFF:                          # fill byte
            i += 1
        elif marker == 0xDA:                        # start of scan: the image data follows
            return data.find(b"\xff\xd9", i) >= 0
        elif 0xD0 <= marker <= 0xD7 or marker == 0x01:
            i += 2
        else:
            i += 2 + int.from_bytes(data[i + 2:i + 4], "big")
    return False


def _png_complete(data: bytes) -> bool:
    """Whether a PNG's chunks, stepped over by their lengths, reach ``IEND`` inside the file."""
    i = 8
    while i + 8 <= len(data):
        length = int.from_bytes(data[i:i + 4], "big")
        if data[i + 4:i + 8] == b"IEND":
            return True
        i += 12 + length
    return False


def image_file_problem(path) -> str | None:
    """Why an image file is truncated or corrupt, or None when it is whole.

    The decoders of OpenCV read a truncated JPEG as an image filled with gray
    after the cut (printing only "Premature end of JPEG file") and a PNG
    without its last chunks as far as it goes, so the file's own structure is
    checked: a JPEG's segments must lead to a scan that reaches the end-of-image
    marker ``FF D9`` (:func:`_jpeg_complete`; data after it allowed); a PNG's
    chunks must reach ``IEND`` (:func:`_png_complete`); a BMP is at least as
    long as its header says. Other formats: None (their decoder decides).
    """
    return image_bytes_problem(Path(path).read_bytes())


def image_bytes_problem(data: bytes) -> str | None:
    """:func:`image_file_problem` of a file's bytes (read once by :func:`read_image` for the check and
    the decoder)."""
    if not data:
        return "the file is empty"
    if data.startswith(b"\xff\xd8"):
        if not _jpeg_complete(data):
            return f"JPEG whose image data does not reach its end-of-image marker (FF D9): truncated or corrupt " \
                   f"({len(data)} bytes)"
    elif data.startswith(b"\x89PNG\r\n\x1a\n"):
        if not _png_complete(data):
            return f"PNG whose chunks do not reach IEND: truncated or corrupt ({len(data)} bytes)"
    elif data.startswith(b"BM") and len(data) >= 6:
        declared = int.from_bytes(data[2:6], "little")
        if len(data) < declared:
            return f"BMP of {len(data)} bytes, but its header says {declared}: truncated"
    return None


def check_image_file(path) -> None:
    """Raise :class:`SourceError` naming the file when :func:`image_file_problem` finds one."""
    problem = image_file_problem(path)
    if problem is not None:
        raise SourceError(f"{path}: {problem}")


#: Share of a numbered series' steps that must equal its smallest step for gaps to be reported.
REGULAR_SHARE = 0.9


def numbering_gaps(names, shown: int = 10) -> tuple[int, list[str]]:
    """Images missing from a regularly numbered series: their count and the first ``shown`` names
    (``a0.png .. a19.png`` without ``a3.png``: ``(1, ["a3.png"])``).

    The last number in each name is its place in the series; the names must all share the text
    before and after it. The series' step is its smallest difference (1 for ``a0, a1, ..``, 2 for
    frames kept every second one); gaps are reported only when every difference is a multiple of the
    step and at least :data:`REGULAR_SHARE` of them equal it (a series numbered by timestamps, whose
    differences vary, is not checked). Zero padding (``a007.png``) is kept in the names returned;
    the count is computed, not listed, so large numbers cost nothing.

    Examples
    --------
    >>> numbering_gaps([f"a{i}.png" for i in range(20) if i != 3])
    (1, ['a3.png'])
    >>> numbering_gaps(["a0.png", "a10.png", "a25.png"])     # not a regular series: not checked
    (0, [])
    """
    parsed = []
    for name in names:
        m = re.match(r"^(.*?)(\d+)(\D*)$", name)
        if m is None:
            return 0, []
        parsed.append((m.group(1), m.group(3), m.group(2)))
    if len({(pre, post) for pre, post, _ in parsed}) != 1 or len(parsed) < 3:
        return 0, []
    pre, post = parsed[0][0], parsed[0][1]
    digits = [d for _, _, d in parsed]
    numbers = sorted(int(d) for d in digits)
    diffs = [b - a for a, b in zip(numbers, numbers[1:])]
    step = min(diffs)
    if step <= 0 or any(d % step for d in diffs) or sum(d == step for d in diffs) < REGULAR_SHARE * len(diffs):
        return 0, []
    width = len(digits[0]) if len({len(d) for d in digits}) == 1 and any(d.startswith("0") and len(d) > 1
                                                                           for d in digits) else 0
    count = sum(d // step - 1 for d in diffs)
    names_out = []
    for a, d in zip(numbers, diffs):
        for k in range(a + step, a + d, step):
            if len(names_out) == shown:
                return count, names_out
            names_out.append(f"{pre}{k:0{width}d}{post}")
    return count, names_out


def read_image(path, color: bool = True) -> np.ndarray:
    """Read one image as RGB ``(h, w, 3)`` uint8 (or gray ``(h, w)``).

    A truncated or corrupt file (:func:`image_file_problem`) is refused with
    :class:`SourceError` naming it, as is one OpenCV cannot decode.
    """
    path = Path(path)
    data = path.read_bytes()              # read once: checked, then decoded from memory
    problem = image_bytes_problem(data)
    if problem is not None:
        raise SourceError(f"{path}: {problem}")
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR if color else cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise SourceError(f"{path}: cannot be read as an image")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB) if color else img


@dataclass(frozen=True)
class FrameSource:
    """Frames of one camera: a video file or a folder of images.

    Frames are RGB ``(height, width, 3)`` uint8 arrays, indexed from 0 in the
    camera's own numbering.
    """

    path: Path

    def __post_init__(self):
        path = Path(self.path)
        object.__setattr__(self, "path", path)
        if not path.exists():
            raise SourceError(f"{path}: camera source not found (expected a video file or a folder of images)")
        if path.is_dir():
            if not list_images(path):
                raise SourceError(f"{path}: folder holds no image files ({', '.join(sorted(IMAGE_SUFFIXES))})")
        elif _SharedGray.video_key(path) not in _OPENED:     # each file as it is checked once per process
            cap = open_video(path)
            ok = cap.isOpened() and cap.read()[0]
            cap.release()
            if not ok:
                raise SourceError(f"{path}: cannot be opened as a video (OpenCV read no frame)")
            with _COUNTS_LOCK:
                _OPENED.add(_SharedGray.video_key(path))

    @property
    def is_video(self) -> bool:
        return not self.path.is_dir()

    @property
    def container_fps(self) -> float | None:
        """The frame rate the video container declares; None for an image folder or when it says none."""
        if not self.is_video:
            return None
        cap = open_video(self.path)
        try:
            fps = float(cap.get(cv2.CAP_PROP_FPS))
        finally:
            cap.release()
        return fps if np.isfinite(fps) and fps > 0 else None

    def __len__(self) -> int:
        """Number of frames actually readable (videos are decoded to count)."""
        if not self.is_video:
            return len(list_images(self.path))
        return self._video_counts()[1]

    def gray_bytes(self, frames: int | None = None) -> int:
        """Bytes of the first ``frames`` frames (None: all) decoded gray, from the size of a frame and the
        count the container declares (a folder: its images), without decoding the video. A container that
        declares no count is taken to hold at least ``frames`` (None: :meth:`__len__`, which decodes to count)."""
        if self.is_video:
            cap = open_video(self.path)
            try:
                size = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) * int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
                count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            finally:
                cap.release()
        else:
            files = list_images(self.path)
            size, count = read_image(files[0], color=False).size, len(files)
        if count <= 0:      # the container does not say: never assume fewer frames than may be held
            count = len(self) if frames is None else int(frames)
        return max(size, 0) * max(count if frames is None else min(count, int(frames)), 0)

    def _video_counts(self) -> tuple[int | None, int]:
        """The frame count the video container declares (None: none) and the count that decodes (kept
        for the file as it is: its path, size and modification time)."""
        key = _SharedGray.video_key(self.path)
        with _COUNTS_LOCK:
            known = _COUNTS.get(key)
        if known is None:
            known = self._count_frames()
            with _COUNTS_LOCK:
                _COUNTS[key] = known
        return known

    def _count_frames(self) -> tuple[int | None, int]:
        cap = open_video(self.path)
        try:
            # the count the container declares, if its last frame is read and nothing after it
            # (no decoding of the whole video: a ten-minute session would be decoded twice)
            n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            if n > 0:
                cap.set(cv2.CAP_PROP_POS_FRAMES, n - 1)
                if int(cap.get(cv2.CAP_PROP_POS_FRAMES)) == n - 1 and cap.grab() and not cap.grab():
                    return n, n
            # otherwise (no count, a truncated or an inexact one): count every frame
            cap.release()
            cap = open_video(self.path)
            count = 0
            while cap.grab():
                count += 1
            return (n if n > 0 else None), count
        finally:
            cap.release()

    def truncation(self) -> tuple[int, int] | None:
        """``(declared, decodable)`` frame counts of a video of which fewer frames decode than its
        container declares (a file cut short while copying or recording); None otherwise (also for
        an image folder: its gaps are :meth:`missing_images`). Containers often declare a frame or
        two more than they hold, so a shortfall counts beyond 2 frames and 2 % of the declared."""
        if not self.is_video:
            return None
        declared, count = self._video_counts()
        short = None if declared is None else declared - count
        return (declared, count) if short is not None and short > max(2, 0.02 * declared) else None

    def missing_images(self) -> tuple[int, list[str]]:
        """Names of the images missing from a numbered frames folder (``left0.png .. left128.png``
        without ``left80.png``: ``["left80.png"]``); empty for a video.

        The number in the names (the last one, zero padding kept) is the frame's
        place in time: a gap would shift every later frame by one. Only gaps
        between the first and the last number are seen, and only when every
        image shares one pattern (same text around the number, same suffix).
        """
        if self.is_video:
            return 0, []
        return numbering_gaps([p.name for p in list_images(self.path)])

    def check_whole(self) -> None:
        """Raise :class:`SourceError` naming the file when a video is truncated (:meth:`truncation`)
        or a numbered frames folder has a gap (:meth:`missing_images`)."""
        n_missing, gaps = self.missing_images()
        if n_missing:
            shown = ", ".join(gaps) + (f" and {n_missing - len(gaps)} more" if n_missing > len(gaps) else "")
            raise SourceError(f"{self.path}: {n_missing} image(s) missing from the frame numbering: {shown} "
                              "(each image is one frame in time; restore them, or renumber the folder "
                              "if the gap is not in the recording)")
        cut = self.truncation()
        if cut is not None:
            raise SourceError(f"{self.path}: truncated video: its container declares {cut[0]} frames, "
                              f"but only {cut[1]} decode (frames {cut[1]}..{cut[0] - 1} are missing)")

    def iter_frames(self, start: int = 0, stop: int | None = None, color: bool = True, share: bool = False):
        """Yield ``(index, frame)`` for frames ``start <= index < stop``.

        ``share`` (gray frames of a video): keep them for the other readers of
        the video in this process (:data:`SHARED_GRAY_BYTES`; what the flash
        search decodes, the detection reads again).
        """
        if not self.is_video:
            files = list_images(self.path)[start:stop]
            size = None
            for i, f in enumerate(files, start):
                image = read_image(f, color)
                if size is None:
                    size = (image.shape[:2], f)
                elif image.shape[:2] != size[0]:
                    (h, w), (h0, w0) = image.shape[:2], size[0]
                    raise SourceError(f"{f}: image of {w}x{h} pixels, but {size[1].name} of the same camera "
                                      f"folder is {w0}x{h0}; every frame of a camera must have one size")
                yield i, image
            return
        video = _SharedGray.video_key(self.path) if share and not color else None
        cap = open_video(self.path)
        try:
            if start:
                cap.set(cv2.CAP_PROP_POS_FRAMES, start)
                if int(cap.get(cv2.CAP_PROP_POS_FRAMES)) != start:  # codec cannot seek: read through
                    cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
                    for _ in range(start):
                        if not cap.grab():
                            return
            i = start
            while stop is None or i < stop:
                ok, bgr = cap.read()
                if not ok:
                    return
                if color:
                    yield i, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                else:
                    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
                    if video is not None:
                        _SHARED.put(video, i, gray, pinned=True)
                    yield i, gray
                i += 1
        finally:
            cap.release()

    def read(self, start: int = 0, stop: int | None = None, color: bool = True) -> np.ndarray:
        """Frames ``start..stop-1`` stacked ``(n, h, w[, 3])``.

        Raises :class:`SourceError` naming the file if fewer frames exist than
        asked for.
        """
        if stop is None:
            frames = [f for _, f in self.iter_frames(start, stop, color)]
            if not frames:
                raise SourceError(f"{self.path}: no frame from index {start}")
            return np.stack(frames)
        # known length: fill one array (a list of frames and its stacked copy would need twice the memory)
        out, count = None, 0
        for _, f in self.iter_frames(start, stop, color):
            if out is None:
                out = np.empty((stop - start,) + f.shape, f.dtype)
            out[count] = f
            count += 1
        if out is None and stop <= start:
            raise SourceError(f"{self.path}: no frame from index {start}")
        if count < stop - start:
            raise SourceError(
                f"{self.path}: expected frames {start}..{stop - 1}, but the source ends after "
                f"{start + count} frames (truncated video or missing images?)")
        return out

    def frame(self, index: int, color: bool = True) -> np.ndarray:
        """One frame by index."""
        return self.read(index, index + 1, color)[0]

    def sequence(self, start: int, stop: int, color: bool = True, cache_frames: int = 128) -> "FrameSequence":
        """Frames ``start..stop-1`` decoded on demand: :class:`FrameSequence`."""
        return FrameSequence(self, int(start), int(stop), color, cache_frames)


class _Shared(list):
    """Frames of a block taken from the shared frames: the capture did not move."""


class FrameSequence:
    """Frames ``start..stop-1`` of a :class:`FrameSource`, decoded when indexed.

    Indexable like the array :meth:`FrameSource.read` returns (``seq[k]`` is
    frame ``start + k``; ``len``, ``shape``, ``ndim``, ``dtype``), but only
    the last ``cache_frames`` decoded frames are kept, so a long session
    needs the memory of a few dozen frames, not of all of them. Reading
    backwards decodes blocks of frames forwards (videos seek to a frame,
    then decode on). The whole range is checked on creation: a source that
    ends early raises :class:`SourceError` as :meth:`FrameSource.read` does.
    """

    def __init__(self, source: FrameSource, start: int, stop: int, color: bool = True, cache_frames: int = 128):
        if stop <= start or start < 0:
            raise SourceError(f"{source.path}: no frame from index {start} (asked for {start}..{stop - 1})")
        self.source, self.start, self.stop, self.color = source, start, stop, color
        self.cache_frames = max(8, int(cache_frames))
        self._cache: dict[int, np.ndarray] = {}
        self._files = None if source.is_video else list_images(source.path)
        self._cap, self._next = None, None
        self._last, self._job, self._pool, self._low = None, None, None, None
        self._video = None if (self._files is not None or color) else _SharedGray.video_key(source.path)
        first = self[0]
        self.shape = (stop - start,) + first.shape
        self.dtype = first.dtype
        self.ndim = len(self.shape)
        try:
            self[len(self) - 1]
        except SourceError:
            count = len(self.source) - start
            raise SourceError(
                f"{source.path}: expected frames {start}..{stop - 1}, but the source ends after "
                f"{start + max(count, 0)} frames (truncated video or missing images?)") from None

    def __len__(self) -> int:
        return self.stop - self.start

    def __getitem__(self, k):
        if not isinstance(k, (int, np.integer)):
            raise TypeError(f"{self.source.path}: a FrameSequence is indexed by one frame number, got {k!r}")
        k = int(k) + (len(self) if k < 0 else 0)
        if not 0 <= k < len(self):
            raise IndexError(f"frame {k} outside 0..{len(self) - 1}")
        if self._job is not None and self._job.done():
            self._collect()
        frame = self._cache.get(k)
        if frame is None:
            frame = self._load(k)
        if self._files is None and self._last is not None and k == self._last + 1:
            self._read_ahead(k)
        elif self._files is None and self._last is not None and k == self._last - 1:
            self._read_behind(k)
        self._last = k
        return frame

    # reading ahead: while the caller works on frame k, a second thread decodes the next frames
    # (OpenCV releases the interpreter while it decodes); only when reading forwards, frame by frame
    def _read_ahead(self, k: int) -> None:
        ahead, block = min(READ_AHEAD, self.cache_frames // 2), min(READ_BLOCK, self.cache_frames // 4)
        if (self._job is None and self._cap is not None and self._next is not None
                and k < self._next <= k + ahead and self._next < len(self)):
            count = min(block, len(self) - self._next)
            self._submit(self._decode, self._cap, count, count=count)

    # reading backwards: while the caller works down the block decoded last (frames low.. upwards), a second
    # thread seeks to the block before it and decodes that (the first half of the cache holds the one, the
    # second half the other)
    def _read_behind(self, k: int) -> None:
        low, block = self._low, self.cache_frames // 2
        if (self._job is None and self._cap is not None and low is not None and 0 < low <= k < low + block
                and (low - 1) not in self._cache):
            first = max(0, low - block)
            self._submit(self._decode_block, self._cap, first, low - first, count=low - first, first=first)

    def _submit(self, fn, *args, **attrs) -> None:
        """``fn(*args)`` decoded by the reading thread (started on first use) as ``self._job``, with ``attrs`` set on it."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="horsemocap-read-ahead")
        self._job = self._pool.submit(fn, *args)
        for name, value in attrs.items():
            setattr(self._job, name, value)

    def _decode_block(self, cap, first: int, count: int):
        """Frames ``first..first+count-1`` (seek, then decode); None when the codec cannot seek.

        The block's first frames that another reader of the video decoded already (the flash search's)
        are taken as they are; only the rest is decoded."""
        shared = []
        while self._video is not None and len(shared) < count:
            f = _SHARED.get(self._video, self.start + first + len(shared))
            if f is None:
                break
            shared.append(f)
        if len(shared) == count:
            return _Shared(shared)
        index = self.start + first + len(shared)
        cap.set(cv2.CAP_PROP_POS_FRAMES, index)
        if int(cap.get(cv2.CAP_PROP_POS_FRAMES)) != index:
            return None
        return shared + self._decode(cap, count - len(shared))

    def _decode(self, cap, count: int) -> list:
        frames = []
        for _ in range(count):
            ok, bgr = cap.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB if self.color else cv2.COLOR_BGR2GRAY))
        return frames

    def _collect(self) -> None:
        """Wait for the frames being read ahead and keep them (the capture is free again)."""
        job, self._job = self._job, None
        frames = job.result()
        first = getattr(job, "first", None)
        if first is not None:                  # a block before the one read last (reading backwards)
            if frames is None:                 # the codec cannot seek: _load reads through instead
                self._next = self._low = None
                return
            self._next = self._low = first
        for f in frames:
            self._keep(self._next, f)
            if self._video is not None:
                _SHARED.put(self._video, self.start + self._next, f)
            self._next += 1
        if len(frames) < job.count or isinstance(frames, _Shared):
            self._next = None          # the source ended early (_load seeks and reports it), or the capture
                                       # did not move (every frame was shared): the next decode seeks

    def _keep(self, k: int, frame: np.ndarray) -> None:
        self._cache[k] = frame
        while len(self._cache) > self.cache_frames:
            self._cache.pop(next(iter(self._cache)))

    def _load(self, k: int) -> np.ndarray:
        if self._job is not None:
            self._collect()
            if k in self._cache:
                return self._cache[k]
        if self._video is not None:                 # decoded already by another reader of the video
            frame = _SHARED.get(self._video, self.start + k)
            if frame is not None:
                self._keep(k, frame)
                return frame
        if self._files is not None:
            if self.start + k >= len(self._files):
                raise SourceError(f"{self.source.path}: no image for frame {self.start + k}")
            frame = read_image(self._files[self.start + k], self.color)
            self._keep(k, frame)
            return frame
        # a video: decode forwards from where the capture is (a seek costs about as much as decoding
        # 15 frames), or, reading backwards (the frame after k was read), from a block of half the
        # cache before k; a jump elsewhere seeks to k itself
        ahead = _DECODE_THROUGH
        first = k if self._next is not None and k >= self._next and k - self._next < ahead else None
        self._low = None
        if first is None:
            backwards = self._next is not None and k < self._next and (k + 1) in self._cache
            first = max(0, k - self.cache_frames // 2 + 1) if backwards else k
            if backwards:
                self._low = first              # the block read backwards starts here (see _read_behind)
        if self._cap is None or self._next is None or first < self._next or first - self._next >= ahead:
            self._seek(first)
        frame = None
        while self._next <= k:
            ok, bgr = self._cap.read()
            if not ok:
                raise SourceError(f"{self.source.path}: no frame {self.start + self._next}")
            f = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB if self.color else cv2.COLOR_BGR2GRAY)
            self._keep(self._next, f)
            if self._video is not None:
                _SHARED.put(self._video, self.start + self._next, f)
            if self._next == k:
                frame = f
            self._next += 1
        return frame

    def _seek(self, k: int) -> None:
        if self._cap is None:
            self._cap = open_video(self.source.path)
        index = self.start + k
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, index)
        if int(self._cap.get(cv2.CAP_PROP_POS_FRAMES)) != index:   # codec cannot seek: read through
            self._cap.release()
            self._cap = open_video(self.source.path)
            for _ in range(index):
                if not self._cap.grab():
                    break
        self._next = k

    def close(self) -> None:
        """Release the video (also done when the sequence is garbage-collected)."""
        if self._job is not None:
            self._job.result()
            self._job = None
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        self._next = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


def is_still_image(path) -> bool:
    """Whether a still source (``static`` / ``plumb`` of a session) is one image file, not a clip.

    An image file is a file whose suffix is an image's (:data:`IMAGE_SUFFIXES`), or
    any other file OpenCV's image readers recognise by its first bytes (a
    ``.webp``, a ``.jp2``); a folder (of frames) or any other file (a video)
    is a clip.

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> _ = (folder / "left.png").write_bytes(b"")
    >>> is_still_image(folder / "left.png"), is_still_image(folder)
    (True, False)
    """
    p = Path(path)
    if p.is_dir():
        return False
    return p.suffix.lower() in IMAGE_SUFFIXES or (p.is_file() and bool(cv2.haveImageReader(str(p))))


def still_frame_counts(paths: dict) -> dict:
    """Camera -> frames of a still source per camera (1 for an image file, :class:`FrameSource`'s count for a
    clip), checked: every camera's source must be the same kind, with the same number of frames.

    Raises :class:`SourceError` naming every camera's file and its count when they differ, or the file that
    is not a readable image, video or folder of images.

    Examples
    --------
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> for cam, n in (("left", 3), ("right", 2)):
    ...     (root / cam).mkdir()
    ...     for k in range(n):
    ...         _ = cv2.imwrite(str(root / cam / f"{cam}{k}.png"), np.zeros((4, 4), np.uint8))
    >>> still_frame_counts({"left": root / "left"})
    {'left': 3}
    >>> try:
    ...     still_frame_counts({"left": root / "left", "right": root / "right"})
    ... except SourceError as exc:
    ...     print(str(exc).replace(str(root), "ROOT"))
    a clip has one frame count in every camera (the cameras record the same instants), and a still is an image in every camera: 'left' ROOT/left 3 frames, 'right' ROOT/right 2 frames
    """
    image = {cam: is_still_image(p) for cam, p in paths.items()}
    counts = {}
    for cam, path in paths.items():
        path = Path(path)
        if image[cam]:
            counts[cam] = 1
            continue
        source = FrameSource(path)
        source.check_whole()
        counts[cam] = len(source)
        if counts[cam] == 0:
            raise SourceError(f"{path}: a clip with no frame (expected the horse standing, every marker in view)")
    if len(set(image.values())) > 1 or len(set(counts.values())) > 1:
        listed = ", ".join(f"'{c}' {paths[c]} {'an image' if image[c] else f'{counts[c]} frames'}" for c in paths)
        raise SourceError(f"a clip has one frame count in every camera (the cameras record the same instants), "
                          f"and a still is an image in every camera: {listed}")
    return counts


def read_still(path, color: bool = True) -> np.ndarray:
    """A still source's image: the image file, or a clip's first frame (its size is the camera's)."""
    if is_still_image(path):
        return read_image(path, color)
    return FrameSource(Path(path)).frame(0, color)


def still_frames(path, color: bool = True):
    """Yield ``(index, frame)`` of a still source: ``(0, image)`` for an image file, every frame of a clip."""
    if is_still_image(path):
        yield 0, read_image(path, color)
        return
    yield from FrameSource(Path(path)).iter_frames(0, None, color)


def field_image(frame: np.ndarray, parity: int) -> np.ndarray:
    """One field of an interlaced frame at the frame's size: its rows where they are, the other field's
    rows filled in between them.

    The field with rows ``r % 2 == parity`` keeps its rows in place, so a
    pixel ``(u, v)`` is still the camera model's pixel ``(u, v)``; each row
    of the other field becomes the mean of the field's rows above and below
    it (at the top or bottom edge, the one next to it).

    Parameters
    ----------
    frame : ndarray (H, W) or (H, W, 3)
    parity : int
        ``1``: the bottom field (rows 1, 3, ...); ``0``: the top field.

    Returns
    -------
    ndarray (H, W[, 3]) float32

    Examples
    --------
    >>> f = np.array([[0], [10], [200], [30], [0]], np.uint8)
    >>> field_image(f, 1)[:, 0].tolist()
    [10.0, 10.0, 20.0, 30.0, 30.0]
    >>> field_image(f, 0)[:, 0].tolist()
    [0.0, 100.0, 200.0, 100.0, 0.0]
    """
    frame = np.asarray(frame)
    if parity not in (0, 1):
        raise ValueError(f"field_image: parity must be 0 or 1, got {parity!r}")
    height = frame.shape[0]
    if height < 2:
        raise ValueError(f"field_image: a frame of {height} row(s) has no two fields")
    out = frame.astype(np.float32)
    other = np.arange(1 - parity, height, 2)
    above = np.where(other - 1 >= 0, other - 1, other + 1)
    below = np.where(other + 1 < height, other + 1, other - 1)
    out[other] = 0.5 * (out[above] + out[below])
    return out


def fields_blended(frame: np.ndarray) -> np.ndarray:
    """An interlaced frame with its two fields blended: the mean of their :func:`field_image` images.

    An interlaced frame holds two fields exposed half a frame apart (PAL:
    20 ms); a marker moving between them is a combed blob, its rows
    alternately from two positions, which a threshold breaks into slivers
    of no marker's shape. Each field filled in to the whole height and the
    two averaged (a vertical ``[1/4, 1/2, 1/4]`` filter of the frame) is one
    blob again. The filter keeps the light's total and its centre, so the
    blob's centre is still the mean of the two fields' positions, seen a
    quarter of a frame after the first field's start
    (:func:`horsemocap.subframe.observation_instants`); pixels are the
    camera model's pixels.

    Parameters
    ----------
    frame : ndarray (H, W) or (H, W, 3), integer or float

    Returns
    -------
    ndarray, same shape and dtype (integers rounded)

    Examples
    --------
    >>> f = np.array([[0, 0], [200, 0], [0, 200], [200, 0], [0, 0]], np.uint8)   # combed: rows alternate
    >>> fields_blended(f).tolist()
    [[100, 0], [100, 50], [100, 100], [100, 50], [100, 0]]
    """
    frame = np.asarray(frame)
    out = 0.5 * (field_image(frame, 0) + field_image(frame, 1))
    if np.issubdtype(frame.dtype, np.integer):
        out = np.clip(np.rint(out), np.iinfo(frame.dtype).min, np.iinfo(frame.dtype).max)
    return out.astype(frame.dtype)


class BlendedFields:
    """A frame sequence of an interlaced camera whose frames have their fields blended (:func:`fields_blended`).

    Wraps a sequence (``len``, ``[k]``, ``close``), e.g. a
    :class:`FrameSequence`; ``seq[k]`` is frame ``k`` with its fields
    blended. Every other attribute is the wrapped sequence's.
    """

    def __init__(self, frames):
        self._frames = frames

    def __len__(self):
        return len(self._frames)

    def __getitem__(self, k):
        return fields_blended(self._frames[k])

    def __iter__(self):
        for k in range(len(self)):
            yield self[k]

    def close(self):
        close = getattr(self._frames, "close", None)
        if close is not None:
            close()

    def __getattr__(self, name):
        if name == "_frames":
            raise AttributeError(name)
        return getattr(self._frames, name)
