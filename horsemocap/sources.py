"""Frame sources: a video file or a folder of images, in natural order.

Thesis Appendix A spends pages renaming files so that MATLAB reads
``left2.png`` before ``left10.png``; :func:`natural_key` does it here.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm"}


class SourceError(ValueError):
    """A camera source that cannot be opened or read."""


def natural_key(name: str):
    """Sort key that orders embedded numbers by value (``a2`` < ``a10``)."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", str(name))]


def natural_sorted(paths) -> list[Path]:
    """Paths sorted by :func:`natural_key` of their file names."""
    return sorted((Path(p) for p in paths), key=lambda p: natural_key(p.name))


def list_images(folder) -> list[Path]:
    """Image files of a folder in natural order (hidden files skipped)."""
    folder = Path(folder)
    return natural_sorted(p for p in folder.iterdir()
                          if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith("."))


def read_image(path, color: bool = True) -> np.ndarray:
    """Read one image as RGB ``(h, w, 3)`` uint8 (or gray ``(h, w)``)."""
    path = Path(path)
    img = cv2.imread(str(path), cv2.IMREAD_COLOR if color else cv2.IMREAD_GRAYSCALE)
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
        else:
            cap = cv2.VideoCapture(str(path))
            ok = cap.isOpened() and cap.read()[0]
            cap.release()
            if not ok:
                raise SourceError(f"{path}: cannot be opened as a video (OpenCV read no frame)")

    @property
    def is_video(self) -> bool:
        return not self.path.is_dir()

    def __len__(self) -> int:
        """Number of frames actually readable (videos are decoded to count)."""
        if not self.is_video:
            return len(list_images(self.path))
        return sum(1 for _ in self.iter_frames())

    def iter_frames(self, start: int = 0, stop: int | None = None, color: bool = True):
        """Yield ``(index, frame)`` for frames ``start <= index < stop``."""
        if not self.is_video:
            files = list_images(self.path)[start:stop]
            for i, f in enumerate(files, start):
                yield i, read_image(f, color)
            return
        cap = cv2.VideoCapture(str(self.path))
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
                yield i, (cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) if color else cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
                i += 1
        finally:
            cap.release()

    def read(self, start: int = 0, stop: int | None = None, color: bool = True) -> np.ndarray:
        """Frames ``start..stop-1`` stacked ``(n, h, w[, 3])``.

        Raises :class:`SourceError` naming the file if fewer frames exist than
        asked for.
        """
        frames = [f for _, f in self.iter_frames(start, stop, color)]
        if stop is not None and len(frames) < stop - start:
            raise SourceError(
                f"{self.path}: expected frames {start}..{stop - 1}, but the source ends after "
                f"{start + len(frames)} frames (truncated video or missing images?)")
        if not frames:
            raise SourceError(f"{self.path}: no frame from index {start}")
        return np.stack(frames)

    def frame(self, index: int, color: bool = True) -> np.ndarray:
        """One frame by index."""
        return self.read(index, index + 1, color)[0]
