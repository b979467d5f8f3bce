"""Synchronisation of the cameras with a flashlight (thesis 3.5, eq. 3.11-3.14).

The thesis' cameras had no remote trigger; a flashlight was switched on in
view while all cameras recorded, and the frame where it is on was found by eye
in each camera (Figure 3.9), giving ``Delta F_LM = 53`` and ``Delta F_MR = 73``
(section 8.2). With ``F_L(k)`` the k-th frame of the left camera,

    F_L(k) <-> F_M(k + Delta F_LM)      (3.11)
    F_M(k) <-> F_R(k + Delta F_MR)      (3.12)
    F_L(k) <-> F_R(k + Delta F_LR)      (3.13)

Here the flash is found automatically (:func:`detect_flash`): every region
of pixels that all start to brighten at the same frame and stay bright for a
few frames is a candidate, and the flash is the candidate that looks most
like a light switched on in place, not the earliest one. Moving bright things
(the horse's head and a bright coat, bandages, a helmet, markers) also
brighten pixels at once; they are told apart by what a light cannot do: come
in through the image edge, brighten next to their own body that was bright a
frame before, grow or move over their on-frames, leave a place that goes
dark, or be a bright thing that was there before and is only uncovered again.
When another candidate at another frame scores nearly as well, the detection
says so (``FlashDetection.ambiguous``). The flash frame is then the first
frame where the region's mean brightness is above the middle of its off and
on levels, which also settles a flash that switched on during an exposure.

The result of :func:`flash_offsets` is the session's ``sync.offsets``: the
frame index, in each camera's own source, of the same instant (the flash);
``Delta F_LM = offsets["middle"] - offsets["left"]`` (:func:`frame_differences`).
"""
from __future__ import annotations

import mmap
import os
import pickle
import signal
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .forking import can_fork, fork_call
from .sources import SHARED_GRAY_BYTES, FrameSource, SourceError, export_decoded, import_decoded

#: Frames searched from the start of each source when none are given (20 s at 30 fps).
DEFAULT_SEARCH_FRAMES = 600
#: An on-frame at least this share of the way from the off level to the brightest on-frame counts as fully lit.
FULLY_LIT_SHARE = 0.9


class SyncError(ValueError):
    """No flash (or an ambiguous one) in a camera's frames.

    Examples
    --------
    >>> import numpy as np
    >>> try:
    ...     detect_flash(np.full((30, 120, 160), 20, np.uint8))
    ... except SyncError as error:
    ...     print(str(error)[:38])
    frames: no flash found in frames 0..29
    """


@dataclass(frozen=True)
class FlashDetection:
    """Where and when the flash switches on in one camera.

    Attributes
    ----------
    frame : int
        First frame with the flash on (index in the frames searched + ``start``).
    region : ndarray of bool (h, w)
        Pixels of the flash (full resolution).
    signal : ndarray (n,)
        Mean gray level of the region in every frame searched.
    off_level, on_level : float
        Region brightness before and after the switch.
    area_px : int
        Region area, full-resolution pixels.
    surround_bright : float
        Fraction of the region's surroundings already as bright a frame
        before, static bright things aside (0 for a flash in the dark; high
        at a moving object's edge).
    candidates : tuple of dict
        Every region that started to brighten in the frames searched:
        ``frame, x, y, area_px, touches_edge, lit_before, surround_bright,
        stays, vacated, score, reason, accepted`` (see :func:`detect_flash`;
        a measure not taken because an earlier test rejected the region is
        NaN).
    start : int
        Index of the first frame searched in the source.
    score : float
        The chosen region's flash score (near 1: a large region that lit up
        in place, nothing bright beside it before, nothing darkening beside
        it).
    ambiguous : bool
        True when another accepted region, switching on at another frame,
        scored nearly as well (at least ``ambiguity_ratio`` of ``score``):
        the frames cannot tell which one is the flash, and the offset
        should be checked (by eye or by the markers).
    runner_up : dict or None
        The best accepted candidate at another frame (an entry of
        ``candidates``, with ``on_frame``: its first frame on, measured as
        ``frame`` is), None if there is none.

    Examples
    --------
    See :func:`detect_flash`.
    """

    frame: int
    region: np.ndarray
    signal: np.ndarray
    off_level: float
    on_level: float
    area_px: int
    surround_bright: float
    candidates: tuple
    start: int = 0
    score: float = 1.0
    ambiguous: bool = False
    runner_up: dict | None = None


def _gray_stack(frames, scale: int) -> np.ndarray:
    """Gray uint8 frames reduced ``scale`` times (INTER_AREA), as one (n, h, w) array."""
    out = None
    for i, f in enumerate(frames):
        f = np.asarray(f)
        g = f if f.ndim == 2 else cv2.cvtColor(f.astype(np.uint8, copy=False), cv2.COLOR_RGB2GRAY)
        g = np.ascontiguousarray(g, dtype=np.uint8)
        if out is None:
            size = (g.shape[0] // scale, g.shape[1] // scale)
            out = np.empty((len(frames),) + size, np.uint8)
        if scale > 1:
            cv2.resize(g, (size[1], size[0]), dst=out[i], interpolation=cv2.INTER_AREA)
        else:
            out[i] = g
    return out


def _read(source, search_frames, start):
    if isinstance(source, FrameSource):
        stop = None if search_frames is None else start + int(search_frames)
        frames = [f for _, f in source.iter_frames(start, stop, color=False, share=True)]
        if stop is None or len(frames) < stop - start:
            try:        # the source ended before the search did: a truncated video is said so, not searched
                source.check_whole()
            except SourceError as exc:
                raise SyncError(f"{exc}; the flash cannot be searched in the frames that decode") from None
        if not frames:
            raise SyncError(f"{source.path}: no frames from index {start} to search for the flash")
        return frames, str(source.path)
    arr = np.asarray(source)
    if arr.ndim not in (3, 4):
        raise SyncError(f"frames must be (n, h, w) gray or (n, h, w, 3) RGB, got shape {arr.shape}")
    if search_frames is not None:
        arr = arr[: int(search_frames)]
    return arr, "frames"


def _min_max(stack) -> tuple:
    """Pixel-wise minimum and maximum of a few uint8 frames."""
    lo, hi = stack[0].copy(), stack[0].copy()
    for f in stack[1:]:
        cv2.min(lo, f, dst=lo)
        cv2.max(hi, f, dst=hi)
    return lo, hi


def _switch_ons(g, min_rise, min_area, m, k):
    """Regions whose pixels start, at frame ``t``, to be ``min_rise`` brighter for ``m`` frames.

    Yields ``(t, labels, origin, stats, rise, before, after, earlier,
    always)``: ``labels`` of the regions inside the bounding box of the
    starting pixels, whose corner is ``origin = (x0, y0)`` (``stats`` are in
    whole-frame coordinates); ``rise`` is every pixel risen at ``t`` (also
    those that started earlier), ``before`` the maximum of the (up to) ``k``
    frames before ``t``, ``after`` the minimum of the ``m`` after it (frame
    ``t`` itself, maybe lit during part of its exposure, is skipped),
    ``earlier`` and ``always`` the maximum and the minimum of all frames
    before those ``k`` (while there are none, as at the very start of a
    record, ``always`` is the median of the frames after the first ``k + m
    + 1``: a static thing is as bright there, a moving object has left).
    """
    shape = g.shape[1:]
    prev_rise = np.zeros(shape, bool)
    earlier = np.zeros(shape, np.uint8)
    # before any frame lies k frames back, the frames after the first on-frames tell the static things
    later = g[min(k + m + 2, g.shape[0] - 1):]
    always = np.median(later[np.linspace(0, len(later) - 1, min(len(later), 51)).astype(int)], axis=0).astype(np.uint8)
    for t in range(1, g.shape[0] - m):
        if t - k - 1 == 0:
            always = g[0].copy()
        if t - k - 1 >= 0:
            cv2.max(earlier, g[t - k - 1], dst=earlier)
            cv2.min(always, g[t - k - 1], dst=always)
        after = _min_max(g[t + 1:t + 1 + m])[0]
        before = _min_max(g[max(0, t - k):t])[1]
        rise = cv2.subtract(after, before) >= min_rise
        starts = rise & ~prev_rise
        prev_rise = rise
        if np.count_nonzero(starts) < min_area:
            continue
        x0, y0, w, h = cv2.boundingRect(starts.view(np.uint8))
        crop = np.ascontiguousarray(starts[y0:y0 + h, x0:x0 + w]).view(np.uint8)
        nlab, labels, stats, _ = cv2.connectedComponentsWithStats(crop, connectivity=8)
        if np.any(stats[1:, cv2.CC_STAT_AREA] >= min_area):
            stats[:, 0] += x0
            stats[:, 1] += y0
            yield t, labels, (x0, y0), stats, rise, before, after, earlier, always


def _touching(mask, seed) -> np.ndarray:
    """The parts of ``mask`` (8-connected) that overlap ``seed``."""
    nlab, lab = cv2.connectedComponents(mask.view(np.uint8), connectivity=8)
    keep = np.zeros(nlab, bool)
    keep[lab[seed & mask]] = True
    keep[0] = False
    return keep[lab]


def _judge(g, t, comp, win, touches_edge, maps, m, min_rise, max_surround_bright, ring_kernel) -> dict:
    """The evidence that tells a light switched on from a moving bright object, for one region.

    ``comp`` is the region (bool, inside the window ``win`` of the reduced
    frames) whose rise starts at ``t``; ``maps`` holds the ``rise, before,
    after, earlier, always`` images of :func:`_switch_ons`. The tests, in
    this order (cheapest first; the first failed one rejects the region and
    the later ones are not measured: NaN):

    * ``touches_edge``: an object entering the view (its body, outside the
      image, cannot be seen);
    * ``lit_before``: fraction of its pixels already half-way as bright in an
      earlier frame: a static bright thing uncovered again by a passing
      occluder (0 for a light switched on for the first time; 0.5 or more
      rejects);
    * ``surround_bright``: fraction of the pixels around it already about as
      bright a frame before, not counting those as bright in every earlier
      frame (a static bright thing, such as a rail behind the flashlight): a
      moving object's own body (``max_surround_bright`` or more rejects);
    * ``stays``: the area newly bright (``min_rise`` above the frames before
      ``t``) around it in its first fully lit on-frame, over the area newly
      bright in any of its on-frames from that one on: 1 when the bright area
      keeps still, ``2 / (m + 1)`` at the leading edge of an object moving at
      any steady speed (the first fully lit frame shows the pixels first
      covered in frames ``t`` and ``t + 1``, the on-frames those of ``t ..
      t + m``); below half-way between the two rejects. An on-frame lit
      only during part of its exposure (below :data:`FULLY_LIT_SHARE` of the
      way to the brightest on-frame) is passed over, so that a flash
      switched on mid-exposure, or mid-frame between two interlaced fields,
      keeps 1;
    * ``vacated``: pixels beside it that were as bright a frame before and are
      dark in all its on-frames, over its area: a moving object leaving its
      former place (0 for a light; about 1 for an object that moved by its
      own size or more; 0.5 or more rejects).

    * ``steady`` (not a test, a weight): the region's lowest level over its
      highest in its on-frames after the first (above the off level): 1 for
      a light, whose first on-frame alone may be lit in part; below 1 for a
      bright thing that keeps brightening as it comes into place.

    ``score = (1 - surround_bright) * stays * (1 - vacated) * steady`` for a region
    that passed them all (1: a region lit up in place, with nothing bright
    beside it before and nothing darkening beside it), 0 for a rejected one.
    """
    rise, before, after, earlier, always = (a[win] for a in maps)
    ev = dict.fromkeys(("lit_before", "surround_bright", "stays", "vacated", "steady"), float("nan"))
    ev.update(score=0.0, reason="")
    if touches_edge:
        ev["reason"] = "it touches the image edge (a moving bright object entering the view)"
        return ev
    off = float(np.median(before[comp]))
    level = float(np.median(after[comp]))
    half_way = (before[comp].astype(np.int16) + after[comp]) // 2
    ev["lit_before"] = float(np.mean(earlier[comp] >= half_way))
    if ev["lit_before"] >= 0.5:
        ev["reason"] = (f"{100 * ev['lit_before']:.0f} % of it was as bright in an earlier frame "
                        "(a bright thing uncovered again, not switched on)")
        return ev
    prev = g[t - 1][win]
    ring = cv2.dilate(comp.view(np.uint8), ring_kernel).astype(bool) & ~comp & ~rise
    as_bright = level - min_rise / 2
    body = (prev[ring] >= as_bright) & (always[ring] < as_bright)
    ev["surround_bright"] = float(np.mean(body)) if ring.any() else 0.0
    if ev["surround_bright"] >= max_surround_bright:
        ev["reason"] = (f"{100 * ev['surround_bright']:.0f} % of its surroundings were as bright a frame before "
                        "(a moving bright object)")
        return ev
    on_frames = [g[j][win] for j in range(t + 1, t + 1 + m)]
    on_levels = [float(np.median(f[comp])) for f in on_frames]
    lit = off + FULLY_LIT_SHARE * (max(on_levels) - off)
    first = next(i for i, v in enumerate(on_levels) if v >= lit)
    newly = [cv2.subtract(f, before) >= min_rise for f in on_frames[first:]]
    region = _touching(newly[0] | comp, comp)
    swept = _touching(np.logical_or.reduce(newly) | comp, comp)
    area = float(np.count_nonzero(region))
    ev["stays"] = area / float(np.count_nonzero(swept))
    if ev["stays"] < 0.5 * (1.0 + 2.0 / (m + 1)):
        ev["reason"] = f"its bright area grew {1 / ev['stays']:.1f}-fold in its on-frames (a moving bright object)"
        return ev
    on_max = _min_max(on_frames)[1]
    vacated = (cv2.subtract(prev, on_max) >= max(min_rise, (level - off) / 2)) & ~swept
    ev["vacated"] = float(np.count_nonzero(vacated)) / area
    if ev["vacated"] >= 0.5:
        ev["reason"] = (f"an area {ev['vacated']:.1f} times its own went dark beside it at the same frame "
                        "(a moving bright object leaving its place)")
        return ev
    later = on_levels[1:]
    ev["steady"] = float(np.clip((min(later) - off) / (max(later) - off), 0.0, 1.0)) if max(later) > off else 0.0
    ev["score"] = (1.0 - ev["surround_bright"]) * ev["stays"] * (1.0 - ev["vacated"]) * ev["steady"]
    return ev


def _region_signal(raw, region) -> np.ndarray:
    """Mean gray level of ``region`` (full resolution) in every frame."""
    x, y, w, h = cv2.boundingRect(region.view(np.uint8))
    mask = np.ascontiguousarray(region[y:y + h, x:x + w]).view(np.uint8)
    out = []
    for f in raw:
        crop = np.ascontiguousarray(np.asarray(f)[y:y + h, x:x + w], dtype=np.uint8)
        if crop.ndim == 3:
            crop = cv2.cvtColor(crop, cv2.COLOR_RGB2GRAY)
        out.append(cv2.mean(crop, mask)[0])
    return np.array(out)


def _window(stats_row, shape, pad) -> tuple:
    x, y, w, h = (int(v) for v in stats_row[:4])
    return (slice(max(0, y - pad), min(shape[0], y + h + pad)), slice(max(0, x - pad), min(shape[1], x + w + pad)))


def _candidates(g, scale, start, min_rise, min_area_small, m, k, max_surround_bright) -> list:
    """Every region that starts to brighten, with its evidence, score and verdict."""
    ring_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    shape = g.shape[1:]
    out = []
    for t, labels, (x0, y0), stats, *maps in _switch_ons(g, min_rise, min_area_small, m, k):
        for i in np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= min_area_small):
            if i == 0:
                continue
            x, y, w, h, area = (int(v) for v in stats[i])
            # the window reaches as far as a moving object of the region's size could have been a frame before
            pad = int(np.ceil(2 * np.sqrt(area))) + 3
            win = _window(stats[i], shape, pad)
            comp = np.zeros((win[0].stop - win[0].start, win[1].stop - win[1].start), bool)
            comp[y - win[0].start:y - win[0].start + h, x - win[1].start:x - win[1].start + w] = \
                labels[y - y0:y - y0 + h, x - x0:x - x0 + w] == i
            edge = x == 0 or y == 0 or x + w == shape[1] or y + h == shape[0]
            ev = _judge(g, t, comp, win, edge, maps, m, min_rise, max_surround_bright, ring_kernel)
            ev["score"] *= area / (area + min_area_small)     # a region of the smallest size counts half
            out.append({"frame": t + start, "x": scale * (x + w / 2), "y": scale * (y + h / 2),
                        "area_px": area * scale**2, "touches_edge": edge, **ev, "accepted": not ev["reason"],
                        "_t": t, "_mask": (win, comp)})
    return out


def detect_flash(frames, *, search_frames: int | None = DEFAULT_SEARCH_FRAMES, start: int = 0,
                 min_rise: float = 40.0, min_area_px: int = 20, min_on_frames: int = 3,
                 max_surround_bright: float = 0.2, ambiguity_ratio: float = 0.8, scale: int = 2,
                 name: str | None = None) -> FlashDetection:
    """Find the flashlight switching on in one camera's frames.

    A light switched on is a compact region that brightens at once by a large
    step and then stays where it is; a moving bright object (the horse's
    head, a bandage, a helmet) also brightens pixels at once, but its bright
    area moves and grows frame to frame, leaves a place that goes dark, is
    next to its own body that was bright a frame before, or comes in through
    the image edge. Every region that starts to brighten in the frames
    searched is scored by these, and the best accepted one is the flash
    (not the earliest).

    Parameters
    ----------
    frames : FrameSource or ndarray (n, h, w[, 3])
        The camera's motion frames (gray or RGB uint8).
    search_frames : int or None
        How many frames to search from ``start`` (None: all).
    start : int
        First frame searched (source index).
    min_rise : float
        Gray levels a flash pixel brightens by, at least.
    min_area_px : int
        Smallest flash region, full-resolution pixels.
    min_on_frames : int
        Frames the flash stays on, at least.
    max_surround_bright : float
        Largest fraction of the pixels around a newly bright region that may
        already have been as bright a frame before (those as bright in every
        earlier frame, static things, not counted). A moving bright object
        brightens a sliver at its leading edge, next to its own body; a flash
        lights up in the dark.
    ambiguity_ratio : float
        Another accepted region at another frame scoring at least this part
        of the chosen one's score makes the detection ``ambiguous``.
    scale : int
        Frames are reduced by this factor for the search (the switch frame is
        then measured at full resolution on the region).
    name : str, optional
        Camera name or file for error messages.

    Returns
    -------
    FlashDetection
        ``candidates`` holds every region examined with its evidence and
        verdict (see :func:`_judge`: ``touches_edge``, ``lit_before``,
        ``surround_bright``, ``stays``, ``vacated``, ``score``, ``reason``);
        the score of an accepted region is ``(1 - surround_bright) * stays *
        (1 - vacated)`` weighted by ``area / (area + min_area_px)`` (a region
        of the smallest size counts half: a few pixels are weak evidence).
        The limits are half-way between what a light and a moving object
        give (see :func:`_judge`), not fitted to sessions.

    Raises
    ------
    SyncError
        No region brightens coherently, stays on and keeps still; the message
        names the camera/file and the largest candidate seen and why it was
        rejected.

    Examples
    --------
    A dark scene where a 20 x 20 px light switches on at frame 12:

    >>> import numpy as np
    >>> frames = np.full((30, 120, 160), 20, np.uint8)
    >>> frames[12:, 40:60, 70:90] = 230
    >>> flash = detect_flash(frames)
    >>> flash.frame, flash.area_px, flash.off_level, flash.on_level, flash.ambiguous
    (12, 400, 20.0, 230.0, False)
    """
    raw, label = _read(frames, search_frames, start)
    label = name or label
    if len(raw) == 0:
        raise SyncError(f"{label}: no frames to search for the flash (from frame {start})")
    g = _gray_stack(raw, scale)
    n = g.shape[0]
    m, k = int(min_on_frames), 2
    if n < m + k + 2:
        raise SyncError(f"{label}: only {n} frames searched; need at least {m + k + 2} to find a flash")
    min_area_small = max(1, int(round(min_area_px / scale**2)))
    candidates = _candidates(g, scale, start, min_rise, min_area_small, m, k, max_surround_bright)
    accepted = [c for c in candidates if c["accepted"]]
    if not accepted:
        seen = max(candidates, key=lambda c: c["area_px"], default=None)
        extra = (f"; largest brightening region: {seen['area_px']} px at frame {seen['frame']}, "
                 f"{seen['reason']}") if seen else ""
        raise SyncError(f"{label}: no flash found in frames {start}..{start + n - 1} (no region of at least "
                        f"{min_area_px} px that brightens by {min_rise:g} gray levels at once, stays on "
                        f"{m} frames and keeps still){extra}")
    # the flash: the best score (ties: the largest, then the earliest)
    best = max(accepted, key=lambda c: (round(c["score"], 6), c["area_px"], -c["frame"]))
    others = [c for c in accepted if abs(c["frame"] - best["frame"]) > 1]
    runner = max(others, key=lambda c: c["score"], default=None)
    ambiguous = runner is not None and runner["score"] >= ambiguity_ratio * best["score"]
    t, region, signal, off, on = _on_frame(raw, best, g.shape[1:], k, m, n)
    public = tuple({key: v for key, v in c.items() if not key.startswith("_")} for c in candidates)
    pub_runner = None
    if runner is not None:      # its own first frame on, measured as the flash's (not the onset of its rise)
        pub_runner = {key: v for key, v in runner.items() if not key.startswith("_")}
        pub_runner["on_frame"] = int(_on_frame(raw, runner, g.shape[1:], k, m, n)[0] + start)
    return FlashDetection(int(t + start), region, signal, off, on, int(region.sum()), best["surround_bright"],
                          public, int(start), float(best["score"]), bool(ambiguous), pub_runner)


def _on_frame(raw, cand: dict, small_shape, k: int, m: int, n: int):
    """``(t, region, signal, off, on)`` of a candidate: its region at full size, its mean brightness per
    frame, the levels before and after its rise, and ``t`` the first frame (in the window) above half-way."""
    t_med, (win, comp) = cand["_t"], cand["_mask"]
    region_small = np.zeros(small_shape, np.uint8)
    region_small[win] = comp
    full = np.asarray(raw[0]).shape[:2]
    region = cv2.resize(region_small, (full[1], full[0]), interpolation=cv2.INTER_NEAREST) > 0
    signal = _region_signal(raw, region)
    lo = max(0, t_med - k - 3)
    off = float(np.median(signal[lo:t_med])) if t_med > lo else float(signal[t_med - 1])
    on = float(np.median(signal[t_med + 1:t_med + 1 + m]))
    half = 0.5 * (off + on)
    t = lo
    while t < n and signal[t] <= half:
        t += 1
    return t, region, signal, off, on


def flash_frame(frames, **kwargs) -> int:
    """The first frame where the flash is on (see :func:`detect_flash` for the options).

    Examples
    --------
    A dark scene where a 20 x 20 px light switches on at frame 12:

    >>> import numpy as np
    >>> frames = np.full((30, 120, 160), 20, np.uint8)
    >>> frames[12:, 40:60, 70:90] = 230
    >>> flash_frame(frames)
    12
    """
    return detect_flash(frames, **kwargs).frame


def flash_detections(sources: dict, search_frames: int | None = DEFAULT_SEARCH_FRAMES, *,
                     readers: int | None = None, **kwargs) -> dict:
    """:func:`detect_flash` in every camera: ``{camera: FlashDetection}`` (errors name the camera).

    The cameras are searched side by side, as many at once as ``readers``
    (default: as many as the decoded frames' memory allows, on two or more
    cores; never more); the detections are the same however many.

    A detection with ``ambiguous`` set is a camera whose flash offset should
    be checked (two candidates of similar score at different frames).

    Examples
    --------
    A dark scene where a 20 x 20 px light switches on at frame 12:

    >>> import numpy as np
    >>> frames = np.full((30, 120, 160), 20, np.uint8)
    >>> frames[12:, 40:60, 70:90] = 230
    >>> {camera: flash.frame for camera, flash in flash_detections({"left": frames}).items()}
    {'left': 12}
    """
    # the cameras searched side by side (OpenCV decodes without holding the GIL), as many at once as
    # FLASH_SEARCH_BYTES of decoded frames allow; an error is the first camera's in session order
    at_once = _flash_readers(sources, search_frames)
    with ThreadPoolExecutor(max_workers=at_once if readers is None else max(1, min(at_once, int(readers))),
                            thread_name_prefix="horsemocap-flash") as pool:
        found = {cam: pool.submit(detect_flash, src, search_frames=search_frames, name=label, **kwargs)
                 for cam, src, label in ((cam, src, f"camera {cam!r} ({src.path})" if isinstance(src, FrameSource)
                                          else f"camera {cam!r}") for cam, src in sources.items())}
        return {cam: future.result() for cam, future in found.items()}


class FlashSearchCancelled(Exception):
    """The flash search was ended by :meth:`FlashSearch.close` before it finished (its result is not wanted)."""


@dataclass(frozen=True)
class _CancellableSource(FrameSource):
    """A :class:`~horsemocap.sources.FrameSource` whose frames stop coming once ``cancel`` is set: the
    search reading it ends between two frames (:class:`FlashSearchCancelled`)."""

    cancel: threading.Event | None = None

    def iter_frames(self, start: int = 0, stop: int | None = None, color: bool = True, share: bool = False):
        self._check()
        for item in super().iter_frames(start, stop, color=color, share=share):
            yield item
            self._check()

    def _check(self) -> None:
        if self.cancel is not None and self.cancel.is_set():
            raise FlashSearchCancelled(f"{self.path}: the flash search was cancelled")


class FlashSearch:
    """:func:`flash_detections` of a session's motion videos, started before the analysis needs it.

    ``horsemocap analyze`` starts it as soon as the session is read, so the
    videos are decoded while the interpreter loads the analysis' modules;
    the sync step takes the detections from it (:meth:`detections`) when it
    searches the same videos the same way, and the frames it decoded are
    shared with the detection as those of a search made in the step.

    Where a forked copy of the process is safe (:func:`horsemocap.forking.can_fork`)
    the search runs in one: its work in Python (comparing the frames) then
    never waits for the interpreter lock the loading of modules holds, nor
    holds it back. The copy decodes the frames and
    copies those the process shares (:data:`horsemocap.sources.SHARED_GRAY_BYTES`)
    into memory both see, so this process reads them as if it had decoded
    them (:func:`horsemocap.sources.import_decoded`); a copy that ends
    without a result leaves the search to the sync step, saying why
    (:attr:`lost`). Elsewhere, or where the system refuses the copy (its
    memory or process), the search runs in a thread.

    The cameras are searched one after another on a machine of two cores
    (one reader per core beyond the one left to the interpreter loading the
    analysis: side by side, the readers would take half of its core).

    A search whose result nobody will read (the run ended early, or the
    offsets turned out to be given) is ended by ``close(wanted=False)``:
    it stops (the copy is killed; the thread before its next frame),
    without being waited for.

    Parameters
    ----------
    videos : dict
        Camera -> its motion video or image folder, in the session's order.
    search_frames : int or None
        As :func:`flash_detections`.
    when_done : callable, optional
        Called without arguments by a thread of the search when the search
        ends (found, failed or cancelled): e.g. to start work that was held
        back so as not to share the second core with the search.
    fork : bool
        Search in a forked copy where that is safe (else in a thread).

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> from horsemocap.session import load_session
    >>> session = load_session(default_session_dir())
    >>> search = FlashSearch(session.motion)
    >>> sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
    >>> {c: d.frame for c, d in search.detections(sources).items()}
    {'left': 8, 'middle': 61, 'right': 134}
    >>> unwanted = FlashSearch(session.motion)
    >>> unwanted.close(wanted=False)
    >>> unwanted.detections(sources) is None         # cancelled: the step searches itself
    True
    """

    def __init__(self, videos: dict, search_frames: int | None = DEFAULT_SEARCH_FRAMES, when_done=None,
                 fork: bool = True):
        self.videos = [(cam, Path(path)) for cam, path in videos.items()]
        self.search_frames = search_frames
        self._when_done = when_done
        self._found, self._error, self._lost = None, None, None
        self._cancel = threading.Event()
        self._pid, self._pid_lock = None, threading.Lock()
        self._shared = None
        self.forked = fork and can_fork() and self._forked()
        target = self._collect if self.forked else self._run
        self._thread = threading.Thread(target=target, name="horsemocap-flash-search", daemon=True)
        self._thread.start()

    def _search(self, cancel=None) -> dict:
        sources = {cam: _CancellableSource(path, cancel=cancel) for cam, path in self.videos}
        return flash_detections(sources, self.search_frames, readers=(os.cpu_count() or 1) - 1)

    def _run(self) -> None:
        try:
            self._found = self._search(self._cancel)
        except FlashSearchCancelled:
            self._found = None
        except BaseException as exc:  # given to the caller by detections()
            self._error = exc
        finally:
            if self._when_done is not None:
                self._when_done()

    def _forked(self) -> bool:
        """Whether the copy that searches was forked (:meth:`_fork`); False when the system refused the
        memory, the pipe or the process (the search then runs in a thread: the copy is only a speed-up)."""
        try:
            self._fork()
            return True
        except OSError:
            self._shared = None
            return False

    def _fork(self) -> None:
        """The copy that searches: it sends ``(outcome, decoded)`` pickled through a pipe, the frames in
        ``self._shared`` (memory both processes see, made before the fork)."""
        self._shared = mmap.mmap(-1, max(_shared_bytes(self.videos, self.search_frames), mmap.PAGESIZE))
        read_end, write_end = os.pipe()
        try:
            self._pid = fork_call(self._copy_work(read_end, write_end))
        except OSError:
            os.close(read_end)
            os.close(write_end)
            raise
        os.close(write_end)
        self._result_fd = read_end

    def _copy_work(self, read_end: int, write_end: int):
        """What the forked copy does: search, then send its outcome and the frames it shares."""

        def work():
            os.close(read_end)
            try:
                outcome = ("found", self._search())
            except BaseException as exc:  # raised by detections() in the parent
                outcome = ("error", _picklable(exc))
            decoded = export_decoded(self._shared)
            with os.fdopen(write_end, "wb") as sent:
                pickle.dump((outcome, decoded), sent, protocol=pickle.HIGHEST_PROTOCOL)
        return work

    def _collect(self) -> None:
        """The thread waiting for the copy: its detections or error, and its decoded frames shared here."""
        try:
            with os.fdopen(self._result_fd, "rb") as got:
                data = got.read()
            with self._pid_lock:
                pid, self._pid = self._pid, None
            status = os.waitpid(pid, 0)[1] if pid is not None else None
            if self.cancelled:
                return                   # killed: no detections, nobody reads them
            if not data or status != 0:
                self._lost = f"its copy {_ended_how(status)} without a result"
                return
            (kind, value), decoded = pickle.loads(data)
            import_decoded(decoded, self._shared)
            if kind == "found":
                self._found = value
            else:
                self._error = value
        except BaseException as exc:  # noqa: BLE001 - a result that cannot be read: the step searches itself
            self._found = self._error = None
            self._lost = f"its copy's result could not be read ({type(exc).__name__}: {exc})"
        finally:
            self._shared = None          # the frames imported keep the memory they are in; the rest is freed
            if self._when_done is not None:
                self._when_done()

    @property
    def lost(self) -> str | None:
        """Why the search ended without a result although it was not cancelled (its copy exited with an
        error, was killed, or sent a result that could not be read; the sync step then searches itself),
        else None (also while it runs)."""
        return self._lost

    @property
    def cancelled(self) -> bool:
        """Whether :meth:`close` ended the search unwanted (it then gives no detections)."""
        return self._cancel.is_set()

    def detections(self, sources: dict, search_frames: int | None = DEFAULT_SEARCH_FRAMES) -> dict | None:
        """``flash_detections(sources, search_frames)`` if this search is that one (waits for it), else None
        (also when the search was cancelled, or its copy ended without a result).

        Its error (a video that cannot be decoded, no flash in a camera) is
        raised here, as the search in the step would raise it.
        """
        searched = [(cam, Path(src.path)) if isinstance(src, FrameSource) else (cam, None)
                    for cam, src in sources.items()]
        if searched != self.videos or search_frames != self.search_frames or self.cancelled:
            return None
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._found

    def close(self, wanted: bool = True) -> None:
        """End the search: ``wanted``, wait for it (its result is kept for :meth:`detections`); else
        cancel it (the copy is killed, the thread stops before its next frame) and return at once."""
        if wanted and not self.cancelled:
            self._thread.join()
            return
        self._cancel.set()
        with self._pid_lock:
            if self._pid is not None:       # not yet reaped by the collecting thread, which reaps it
                os.kill(self._pid, signal.SIGKILL)


def _shared_bytes(videos, search_frames) -> int:
    """Bytes of the decoded gray frames a search of ``videos`` shares with this process (at most
    :data:`horsemocap.sources.SHARED_GRAY_BYTES`; image folders share none)."""
    total = 0
    for _, path in videos:
        try:
            source = FrameSource(path)
            total += source.gray_bytes(search_frames) if source.is_video else 0
        except (SourceError, OSError):        # the search reports it
            pass
    return min(total, SHARED_GRAY_BYTES)


def _ended_how(status: int | None) -> str:
    """How a process ended, from its wait status, in words ("exited with status 3", "was killed by signal 9")."""
    if status is None:
        return "ended unseen"
    if os.WIFSIGNALED(status):
        return f"was killed by signal {os.WTERMSIG(status)}"
    return f"exited with status {os.waitstatus_to_exitcode(status)}"


def _picklable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a :class:`RuntimeError` with its type and message."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(exc).__name__}: {exc}")


#: Decoded gray frames the flash searches of several cameras may hold at once (bytes): about what one
#: 1080p camera's whole search holds (600 frames, 1.2 GB) halved, so two 640x480 searches (2 x 184 MB)
#: run side by side while 1080p cameras search one at a time, within the memory a single search needs.
FLASH_SEARCH_BYTES = 512 * 2 ** 20


def _flash_readers(sources: dict, search_frames: int | None) -> int:
    """How many cameras' flash searches run at once: each holds its searched frames decoded."""
    held = [src.gray_bytes(search_frames) if isinstance(src, FrameSource) else np.asarray(src).nbytes
            for src in sources.values()]
    if (os.cpu_count() or 1) < 2 or not held:
        return 1
    return int(np.clip(FLASH_SEARCH_BYTES // max(max(held), 1), 1, len(held)))


def flash_offsets(sources: dict, search_frames: int | None = DEFAULT_SEARCH_FRAMES, **kwargs) -> dict:
    """Flash frame in every camera: the session's ``sync.offsets``.

    Parameters
    ----------
    sources : dict[str, FrameSource or ndarray]
        Motion frames per camera (session order).
    search_frames : int or None
        Frames searched from the start of each source.

    Returns
    -------
    dict[str, int]
        Frame index, in each camera's own source, of the same instant; thesis
        eq. 3.11: ``F_L(k) <-> F_M(k + offsets["middle"] - offsets["left"])``.

    Examples
    --------
    A dark scene where a 20 x 20 px light switches on at frame 12:

    >>> import numpy as np
    >>> frames = np.full((30, 120, 160), 20, np.uint8)
    >>> frames[12:, 40:60, 70:90] = 230
    >>> later = np.full((30, 120, 160), 20, np.uint8)
    >>> later[17:, 40:60, 70:90] = 230              # the middle camera started 5 frames earlier
    >>> flash_offsets({"left": frames, "middle": later})
    {'left': 12, 'middle': 17}
    """
    return {cam: det.frame for cam, det in flash_detections(sources, search_frames, **kwargs).items()}


def frame_differences(offsets: dict, order=("left", "middle", "right")) -> dict:
    """``Delta F`` of eq. 3.11-3.13 from offsets: ``{"LM": .., "MR": .., "LR": ..}``.

    Eq. 3.14 (all positive) holds when the cameras were started left, middle,
    right, as in the thesis; a negative value only means another start order.

    Examples
    --------
    The thesis' offsets (section 8.2: ``Delta F_LM = 53``, ``Delta F_MR = 73``):

    >>> frame_differences({"left": 12, "middle": 65, "right": 138})
    {'LM': 53, 'MR': 73, 'LR': 126}
    """
    a, b, c = order
    letters = [s[0].upper() for s in order]
    return {letters[0] + letters[1]: offsets[b] - offsets[a], letters[1] + letters[2]: offsets[c] - offsets[b],
            letters[0] + letters[2]: offsets[c] - offsets[a]}


def aligned_index(offsets: dict, k: int, reference: str = "left") -> dict:
    """Frame index in every camera of the instant of frame ``k`` of the reference camera.

    Examples
    --------
    >>> aligned_index({"left": 12, "middle": 65, "right": 138}, k=0)
    {'left': 0, 'middle': 53, 'right': 126}
    """
    return {c: int(k + o - offsets[reference]) for c, o in offsets.items()}
