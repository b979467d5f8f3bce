"""Step ``sync``: the frame offsets between the cameras (thesis eq. 3.11-3.14)."""
from __future__ import annotations

from dataclasses import dataclass, field

from .. import sync as flash
from ..params import SyncParams
from ..session import Session, check_frame_counts
from ..sources import FrameSource
from .base import StepResult


@dataclass(frozen=True)
class SyncResult(StepResult):
    """The synchronisation of the cameras' motion sources.

    Attributes
    ----------
    offsets : dict
        Camera -> frame index, in its own motion source, of the same instant
        (the thesis' offsets of eq. 3.11-3.13: F_L(k) <-> F_M(k + offsets.middle - offsets.left)).
    frame_counts : dict
        Camera -> frames in its motion source.
    n_frames : int
        Synchronised frames (every camera has them).
    offsets_from : str
        How the offsets were found ("flashlight", "given in parameters", ...).
    flash_ambiguous : dict
        Camera -> the frame of a second flash candidate nearly as likely as the one taken.
    flash_offsets : dict or None
        The flash's own offsets, when the markers corrected them (then ``offsets`` are the corrected ones).
    """

    offsets: dict
    frame_counts: dict
    n_frames: int
    offsets_from: str
    flash_ambiguous: dict = field(default_factory=dict)
    flash_offsets: dict | None = None


def step_sync(session: Session, section: SyncParams, progress) -> SyncResult:
    """Frame offsets from the parameters, the session or the flashlight (eq. 3.11-3.14).

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> from horsemocap.session import load_session
    >>> r = step_sync(load_session(default_session_dir()), SyncParams(), lambda *a: None)
    >>> r.offsets_from
    'flashlight'
    """
    sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
    ambiguous = {}
    if section.offsets:
        offsets, how = dict(section.offsets), "given in parameters"
    elif session.sync_offsets:
        offsets, how = dict(session.sync_offsets), "given in session.json"
    else:
        found, how = flash.flash_detections(sources), "flashlight"
        offsets = {c: int(d.frame) for c, d in found.items()}
        ambiguous = {c: int(d.runner_up["on_frame"]) for c, d in found.items() if d.ambiguous and d.runner_up}
    counts = {c: len(s) for c, s in sources.items()}
    n = check_frame_counts(session, counts, offsets, offsets_from=how)
    progress("sync", f"offsets {offsets} ({how}); {n} synchronised frames")
    if ambiguous:
        progress("sync", "two flash candidates of similar score in " + ", ".join(
            f"camera '{c}' (frame {offsets[c]} taken, frame {f} nearly as likely)" for c, f in ambiguous.items())
            + "; the markers will check it")
    return SyncResult(offsets=offsets, frame_counts=counts, n_frames=n, offsets_from=how, flash_ambiguous=ambiguous)
