"""Exchanged inputs behind a failed identification: offsets or videos given to the wrong cameras.

When the markers cannot be identified across the cameras, two common
mistakes in ``session.json`` give the same symptom: the sync offsets of two
cameras exchanged, or their motion videos exchanged. :func:`identification_hint`
looks for the first (the flash found in each video, compared with the given
offsets) and names the offsets and the videos so that the message says what
to check.
"""
from __future__ import annotations

from itertools import combinations

from .sources import FrameSource, SourceError
from .sync import flash_detections

__all__ = ["relative_offsets", "exchanged_offsets", "identification_hint"]

AGREEMENT_FRAMES = 1
"""Relative offsets within this many frames agree (the flash may light a frame partly)."""


def relative_offsets(offsets: dict, reference: str) -> dict:
    """Camera -> its offset minus the reference camera's (frames).

    Examples
    --------
    >>> relative_offsets({"left": 12, "middle": 15, "right": 9}, "left")
    {'left': 0, 'middle': 3, 'right': -3}
    """
    return {c: offsets[c] - offsets[reference] for c in offsets}


def _agree(a: dict, b: dict, reference: str) -> bool:
    ra, rb = relative_offsets(a, reference), relative_offsets(b, reference)
    return set(ra) == set(rb) and all(abs(ra[c] - rb[c]) <= AGREEMENT_FRAMES for c in ra)


def exchanged_offsets(given: dict, found: dict, reference: str) -> list:
    """Camera pairs whose given offsets, exchanged, agree with the found ones.

    Examples
    --------
    >>> exchanged_offsets({"left": 12, "middle": 9, "right": 15}, {"left": 40, "middle": 43, "right": 37}, "left")
    [('middle', 'right')]
    """
    pairs = []
    for a, b in combinations(sorted(given), 2):
        swapped = dict(given)
        swapped[a], swapped[b] = given[b], given[a]
        if _agree(swapped, found, reference):
            pairs.append((a, b))
    return pairs


def _flash_offsets(session) -> dict | None:
    """Camera -> the frame of the flash in its motion video, or None (no flash found, unreadable)."""
    sources = {}
    try:
        sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
        return {c: int(d.frame) for c, d in flash_detections(sources).items()}
    except (SourceError, ValueError, RuntimeError, OSError):
        return None


def identification_hint(session, sync) -> str:
    """``"; ..."``: what to check in ``session.json`` when the markers cannot be identified.

    With offsets given (in ``session.json`` or the parameters), the flash is
    searched in each video: offsets that disagree with it are named, and a
    pair of cameras whose offsets exchanged would agree is named as likely
    exchanged. The videos of the cameras are always named (two exchanged
    videos give the same failure).
    """
    parts = []
    if sync.offsets_from != "flashlight":
        found = _flash_offsets(session)
        if found is not None and not _agree(sync.offsets, found, session.reference_camera):
            pairs = exchanged_offsets(sync.offsets, found, session.reference_camera)
            text = (f"the offsets {sync.offsets} ({sync.offsets_from}) disagree with the flash, found at frames "
                    f"{found}")
            if pairs:
                text += "; the offsets of cameras " + " or ".join(f"'{a}' and '{b}'" for a, b in pairs) + \
                        " look exchanged"
            parts.append(text)
    videos = ", ".join(f"{c}: {session.motion[c].name}" for c in session.cameras)
    parts.append(f"check that each camera's video in session.json's 'motion' ({videos}) and its sync offset are "
                 "that camera's (two cameras' videos or offsets exchanged give this failure)")
    return "; " + "; ".join(parts)
