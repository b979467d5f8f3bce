"""Synchronisation of the cameras with a flashlight (thesis 3.5, eq. 3.11-3.14).

The thesis' cameras had no remote trigger; a flashlight was switched on in
view while all cameras recorded, and the frame where it is on was found by eye
in each camera (Figure 3.9), giving ``Delta F_LM = 53`` and ``Delta F_MR = 73``
(section 8.2). With ``F_L(k)`` the k-th frame of the left camera,

    F_L(k) <-> F_M(k + Delta F_LM)      (3.11)
    F_M(k) <-> F_R(k + Delta F_MR)      (3.12)
    F_L(k) <-> F_R(k + Delta F_LR)      (3.13)

Here the flash is found automatically (:func:`detect_flash`): a region of
pixels that all start to brighten at the same frame and stay bright for a few
frames, in surroundings that were dark. Moving bright things (reflective
markers, bandages, a helmet) also brighten pixels, but only a sliver at their
leading edge, next to their own body that was already bright a frame before;
glints are small and last a frame. The flash frame is then the first frame where the region's
mean brightness is above the middle of its off and on levels, which also
settles a flash that switched on during an exposure.

The result of :func:`flash_offsets` is the session's ``sync.offsets``: the
frame index, in each camera's own source, of the same instant (the flash);
``Delta F_LM = offsets["middle"] - offsets["left"]`` (:func:`frame_differences`).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .sources import FrameSource, SourceError

#: Frames searched from the start of each source when none are given (20 s at 30 fps).
DEFAULT_SEARCH_FRAMES = 600


class SyncError(ValueError):
    """No flash (or an ambiguous one) in a camera's frames."""


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
        before (0 for a flash in the dark; high at a moving object's edge).
    candidates : tuple of dict
        Every region examined up to the flash: ``frame, area_px,
        surround_bright, accepted, reason``.
    start : int
        Index of the first frame searched in the source.
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


def _gray_stack(frames, scale: int) -> np.ndarray:
    out = []
    for f in frames:
        f = np.asarray(f)
        g = f if f.ndim == 2 else cv2.cvtColor(f.astype(np.uint8), cv2.COLOR_RGB2GRAY)
        if scale > 1:
            g = cv2.resize(g, (g.shape[1] // scale, g.shape[0] // scale), interpolation=cv2.INTER_AREA)
        out.append(g.astype(np.int16))
    return np.stack(out)


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


def detect_flash(frames, *, search_frames: int | None = DEFAULT_SEARCH_FRAMES, start: int = 0,
                 min_rise: float = 40.0, min_area_px: int = 20, min_on_frames: int = 3,
                 max_surround_bright: float = 0.2, scale: int = 2, name: str | None = None) -> FlashDetection:
    """Find the flashlight switching on in one camera's frames.

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
        already have been as bright a frame before. A moving bright object
        brightens a sliver at its leading edge, next to its own body; a flash
        lights up in the dark.
    scale : int
        Frames are reduced by this factor for the search (the switch frame is
        then measured at full resolution on the region).
    name : str, optional
        Camera name or file for error messages.

    Returns
    -------
    FlashDetection

    Raises
    ------
    SyncError
        No region brightens coherently and stays on; the message names the
        camera/file and the best candidate seen.
    """
    raw, label = _read(frames, search_frames, start)
    label = name or label
    g = _gray_stack(raw, scale)
    n = g.shape[0]
    m, k = int(min_on_frames), 2
    if n < m + k + 2:
        raise SyncError(f"{label}: only {n} frames searched; need at least {m + k + 2} to find a flash")
    min_area_small = max(1, int(round(min_area_px / scale**2)))
    ring_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    candidates, accepted = [], []
    prev_rise = np.zeros(g.shape[1:], bool)
    for t in range(k, n - m):
        # persistent rise, skipping the transition frame t: min(g[t+1..t+m]) - max(g[t-k..t-1])
        after = g[t + 1:t + 1 + m].min(axis=0)
        before = g[t - k:t].max(axis=0)
        rise = (after - before) >= min_rise
        starts = rise & ~prev_rise            # pixels whose rise starts at t
        prev_rise = rise
        if starts.sum() < min_area_small:
            continue
        nlab, lab, stats, _ = cv2.connectedComponentsWithStats(starts.astype(np.uint8), connectivity=8)
        for i in range(1, nlab):
            area = int(stats[i, cv2.CC_STAT_AREA])
            if area < min_area_small:
                continue
            comp = lab == i
            ring = cv2.dilate(comp.astype(np.uint8), ring_kernel).astype(bool) & ~comp & ~rise
            level = float(np.median(after[comp]))
            frac = float(np.mean(g[t - 1][ring] >= level - min_rise / 2)) if ring.any() else 0.0
            ok = frac < max_surround_bright
            reason = "" if ok else (f"{100 * frac:.0f} % of its surroundings were as bright a frame before "
                                    "(a moving bright object)")
            candidates.append({"frame": t + start, "area_px": area * scale**2, "surround_bright": frac,
                               "accepted": ok, "reason": reason})
            if ok:
                accepted.append((t, area, frac, comp))
        if accepted:
            break
    if not accepted:
        seen = max(candidates, key=lambda c: c["area_px"], default=None)
        extra = (f"; largest brightening region: {seen['area_px']} px at frame {seen['frame']}, "
                 f"{seen['reason']}") if seen else ""
        raise SyncError(f"{label}: no flash found in frames {start}..{start + n - 1} (no region of at least "
                        f"{min_area_px} px that brightens by {min_rise:g} gray levels at once and stays on "
                        f"{m} frames){extra}")
    # the flash: the earliest accepted region (ties: the largest)
    t_med, area, coh, region_small = max(accepted, key=lambda a: a[1])
    full = np.asarray(raw[0]).shape[:2]
    region = cv2.resize(region_small.astype(np.uint8), (full[1], full[0]), interpolation=cv2.INTER_NEAREST) > 0
    signal = np.array([float(np.mean(_gray_stack([f], 1)[0][region])) for f in raw])
    lo = max(0, t_med - k - 3)
    off = float(np.median(signal[lo:t_med])) if t_med > lo else float(signal[t_med - 1])
    on = float(np.median(signal[t_med + 1:t_med + 1 + m]))
    half = 0.5 * (off + on)
    t = lo
    while t < n and signal[t] <= half:
        t += 1
    return FlashDetection(int(t + start), region, signal, off, on, int(region.sum()), coh,
                          tuple(candidates), int(start))


def flash_frame(frames, **kwargs) -> int:
    """The first frame where the flash is on (see :func:`detect_flash` for the options)."""
    return detect_flash(frames, **kwargs).frame


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
    """
    out = {}
    for cam, src in sources.items():
        label = f"camera {cam!r} ({src.path})" if isinstance(src, FrameSource) else f"camera {cam!r}"
        out[cam] = flash_frame(src, search_frames=search_frames, name=label, **kwargs)
    return out


def frame_differences(offsets: dict, order=("left", "middle", "right")) -> dict:
    """``Delta F`` of eq. 3.11-3.13 from offsets: ``{"LM": .., "MR": .., "LR": ..}``.

    Eq. 3.14 (all positive) holds when the cameras were started left, middle,
    right, as in the thesis; a negative value only means another start order.
    """
    a, b, c = order
    letters = [s[0].upper() for s in order]
    return {letters[0] + letters[1]: offsets[b] - offsets[a], letters[1] + letters[2]: offsets[c] - offsets[b],
            letters[0] + letters[2]: offsets[c] - offsets[a]}


def aligned_index(offsets: dict, k: int, reference: str = "left") -> dict:
    """Frame index in every camera of the instant of frame ``k`` of the reference camera."""
    return {c: int(k + o - offsets[reference]) for c, o in offsets.items()}
