"""Which path finds the candidate regions: the compiled core or pure Python (issue 16).

The compiled core ``horsemocap.detection._regions`` (``_regions.c``, built by
``pip install -e .`` as an optional extension) does in one call per crop (or
per frame's list of crops) what :func:`~horsemocap.detection.frame_candidates`
and the whole-frame search of the identification do in Python: threshold
(eq. 4.5), 8-connected labels in OpenCV's order, area, box, border flags,
the crop-edge drop, the area range, circularity, the ``max_count`` largest,
the weighted centres with the symmetric border and the light terms. The
Python path stays the reference and the fallback: it runs when the core is
not built, when ``HORSEMOCAP_PURE_PYTHON`` is set (to anything but ``""`` or
``"0"``), for inputs the core does not take (not a C-contiguous 2-D uint8
image, a negative ``max_count``), and for a call with a region whose light
terms need a least-squares solve. Equivalence (same regions, order, areas and
flags; centres within 1e-9 px) is tested in ``tests/test_regions_core.py``.

:data:`ACTIVE_PATH` is ``"compiled"`` or ``"python"``, :data:`ACTIVE_REASON`
says why.
"""
from __future__ import annotations

import hashlib
import importlib
import math
import os
from pathlib import Path

import numpy as np

__all__ = ["PURE_PYTHON_ENV", "ACTIVE_PATH", "ACTIVE_REASON", "CORE", "core_candidates", "core_label",
           "core_bright_boxes"]

#: Environment variable that forces the pure-Python path.
PURE_PYTHON_ENV = "HORSEMOCAP_PURE_PYTHON"
#: The most pixels the core labels in one image (its labels and sums are 32-bit).
MAX_PIXELS = 2 ** 28


def _load_core():
    """``(module or None, reason)``: the compiled core unless forced off or not built."""
    if os.environ.get(PURE_PYTHON_ENV, "").strip() not in ("", "0"):
        return None, f"pure Python ({PURE_PYTHON_ENV} is set)"
    try:
        _regions = importlib.import_module(f"{__package__}._regions")
    except ImportError as exc:
        return None, f"pure Python (the compiled core is not built: {exc})"
    source = Path(__file__).with_name("_regions.c")
    if source.is_file():                      # an editable install: the module sits beside its source
        built, now = getattr(_regions, "CORE_SOURCE_HASH", ""), source_hash(source)
        if built != now:
            return None, (f"pure Python (the compiled core was built from another _regions.c, {built or 'unknown'}"
                          f", not {now}: rebuild it with pip install -e .)")
    return _regions, "compiled core (horsemocap.detection._regions)"


def source_hash(path) -> str:
    """The first 16 hex digits of the SHA-256 of the core's C source (as ``setup.py`` gives it to the build)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


#: The compiled module, or None (chosen once, at import; read at each call, so that a test or a
#: benchmark can run the Python path in the same process by setting it to None for a while).
CORE, ACTIVE_REASON = _load_core()
#: ``"compiled"`` or ``"python"``.
ACTIVE_PATH = "compiled" if CORE is not None else "python"


def core_candidates(gray, threshold, crops: list, area_range, min_circularity, whole: bool, max_count,
                    centroid: str, light: bool):
    """Candidate arrays ``(centre, area, cut, slope, moments)`` by the compiled core, or None.

    None: the core is not active (:data:`CORE` None), does not take this input,
    or a region needs the Python path; the caller then runs the Python path.
    ``crops``: ``[(u0, v0, u1, v1), ...]`` inside the image; ``whole``: the
    whole-frame search's crops (labelling order of the whole image), else
    one crop of :func:`~horsemocap.detection.frame_candidates`.
    """
    if CORE is None:
        return None
    args = _arguments(gray, area_range, min_circularity, max_count)
    if args is None:
        return None
    out = CORE.candidates(gray, _level(threshold), crops, *args[:3], bool(whole), args[3], centroid != "binary",
                          bool(light))
    if out is None:
        return None
    n, centre, area, cut, slope, moments = out
    return (np.frombuffer(centre, float).reshape(n, 2), np.frombuffer(area, float),
            np.frombuffer(cut, bool), None if slope is None else np.frombuffer(slope, float).reshape(n, 2),
            None if moments is None else np.frombuffer(moments, float).reshape(n, 2, 2))


def core_label(gray, threshold):
    """``(n, labels, stats, centroids)`` of ``gray > threshold`` by the compiled core, or None.

    OpenCV's output (``thresholds.connected_components`` of the thresholded
    image: 8-connected, int32 labels, the same numbering, stats and centres)
    for every region; the background's row holds its area only. None when
    the core is not active or ``gray`` is not a 2-D uint8 array with
    contiguous rows (a crop of a C-contiguous image is fine).
    """
    if CORE is None or not (isinstance(gray, np.ndarray) and gray.dtype == np.uint8 and gray.ndim == 2
                            and gray.strides[1] == 1 and gray.strides[0] >= gray.shape[1]
                            and 0 < gray.size < MAX_PIXELS):
        return None
    n, labels, stats, cents = CORE.label(gray, _level(threshold))
    return (n, np.frombuffer(labels, np.int32).reshape(gray.shape), np.frombuffer(stats, np.int32).reshape(n, 5),
            np.frombuffer(cents, float).reshape(n, 2))


def core_bright_boxes(gray, threshold):
    """:func:`~horsemocap.detection.thresholds.bright_crops`' crops (the same, in the same order) by the
    compiled core without the binary image, or None (core not active, or not a C-contiguous 2-D uint8 image)."""
    if CORE is None or not (isinstance(gray, np.ndarray) and gray.dtype == np.uint8 and gray.ndim == 2
                            and gray.flags.c_contiguous and gray.size < MAX_PIXELS):
        return None
    from .thresholds import BRIGHT_BLOCK, BRIGHT_MAX_FRACTION, BRIGHT_PAD
    return CORE.bright_boxes(gray, _level(threshold), BRIGHT_BLOCK, BRIGHT_PAD, BRIGHT_MAX_FRACTION)


def _level(threshold) -> int:
    """``int(threshold)`` kept within -1..255: the same white pixels in a uint8 image, in the core's int."""
    return min(max(int(threshold), -1), 255)


def _arguments(gray, area_range, min_circularity, max_count):
    """``(area_min, area_max, min_circularity, max_count)`` as the core takes them, or None where it does
    not take these arguments (the Python path then runs, and raises where it raises)."""
    if not (isinstance(gray, np.ndarray) and gray.dtype == np.uint8 and gray.ndim == 2
            and gray.flags.c_contiguous and gray.size < MAX_PIXELS):
        return None
    try:
        lo, hi, count = float(area_range[0]), float(area_range[1]), int(max_count)
        circ = None if min_circularity is None else float(min_circularity)
    except (TypeError, ValueError, OverflowError):
        return None
    if count < 0 or math.isnan(lo) or math.isnan(hi):
        return None
    return lo, hi, circ, min(count, 2 ** 31 - 1)     # more than the core's int holds: every region anyway
