"""Step ``sync``: the frame offsets between the cameras (thesis eq. 3.11-3.14)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from .. import subframe
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
    phase_frames : dict
        Camera -> the fraction of a frame by which its synchronised frame ``k`` is exposed after the
        reference camera's frame ``k`` (``k + phase`` in reference frames; see :mod:`horsemocap.subframe`).
        Empty (every camera at 0) for genlocked cameras: the offsets alone synchronise them.
    rate_ratio : dict
        Camera -> reference frames per frame of its own (its frame period over the reference's: above 1
        its clock is slower); ``phase_frames`` are then the phases at frame 0 and camera ``c``'s frame
        ``k`` is at the reference instant ``phase_frames[c] + rate_ratio[c] k``
        (:func:`horsemocap.subframe.camera_frames`). Empty or 1: the phase holds over the record.
    offset_uncertainty_frames : dict
        Camera -> standard error of its offset with the fraction (frames).
    subframe_method : str
        How the fractions were found ("" none, "flash", "flash and markers", "markers", "given in parameters").
    genlocked_check : dict
        Cameras the flash found genlocked (every first lit frame fully lit) and the markers confirmed:
        camera -> ``(phase, standard error)`` frames the markers measured (empty when not measured).
    genlocked_check_method : str
        How ``genlocked_check`` was measured: ``"linearised"`` (one least-squares step at zero phase,
        :func:`horsemocap.subframe.linearised_phases`, put the phases so near zero that the search was not run),
        ``"search"`` (:func:`horsemocap.subframe.refine_phases`), ``""`` when not measured.
    """

    offsets: dict
    frame_counts: dict
    n_frames: int
    offsets_from: str
    flash_ambiguous: dict = field(default_factory=dict)
    flash_offsets: dict | None = None
    phase_frames: dict = field(default_factory=dict)
    rate_ratio: dict = field(default_factory=dict)
    offset_uncertainty_frames: dict = field(default_factory=dict)
    subframe_method: str = ""
    genlocked_check: dict = field(default_factory=dict)
    genlocked_check_method: str = ""

    @property
    def free_running(self) -> bool:
        """True when a camera's frames fall a fraction of a frame (or a rate) apart from the reference's."""
        return any(v != 0.0 for v in self.phase_frames.values()) or any(v != 1.0 for v in self.rate_ratio.values())

    def offsets_with_fraction(self, reference: str) -> dict:
        """Camera -> frames after the reference camera's, with the fraction: ``offsets[c] - offsets[ref] - phase[c]``."""
        ref = self.offsets[reference]
        return {c: float(o - ref - self.phase_frames.get(c, 0.0)) for c, o in self.offsets.items()}


def step_sync(session: Session, section: SyncParams, progress, flash_search=None) -> SyncResult:
    """Frame offsets from the parameters, the session or the flashlight (eq. 3.11-3.14).

    ``flash_search`` (a :class:`horsemocap.sync.FlashSearch` started earlier
    on the session's videos) gives the flash detections when the flashlight
    is used; they are the same as those searched here.

    Examples
    --------
    >>> from horsemocap.data import default_session_dir
    >>> from horsemocap.session import load_session
    >>> r = step_sync(load_session(default_session_dir()), SyncParams(), lambda *a: None)
    >>> r.offsets_from
    'flashlight'
    """
    sources = {c: FrameSource(session.motion[c]) for c in session.cameras}
    ambiguous, sub = {}, {}
    if section.offsets:
        offsets, how = {c: int(round(float(v))) for c, v in section.offsets.items()}, "given in parameters"
        ref = session.reference_camera
        phase = {c: float((offsets[c] - offsets[ref]) - (float(v) - float(section.offsets[ref])))
                 for c, v in section.offsets.items()}
        if any(v != 0.0 for v in phase.values()):
            sub = dict(phase_frames=phase, subframe_method="given in parameters")
    elif session.sync_offsets:
        offsets, how = dict(session.sync_offsets), "given in session.json"
    else:
        found = flash_search.detections(sources) if flash_search is not None else None
        if found is None and flash_search is not None and flash_search.lost:
            progress("sync", f"the flash search started early ended without a result: {flash_search.lost}; "
                     "searching again")
        found, how = (found if found is not None else flash.flash_detections(sources)), "flashlight"
        offsets = {c: int(d.frame) for c, d in found.items()}
        ambiguous = {c: int(d.runner_up["on_frame"]) for c, d in found.items() if d.ambiguous and d.runner_up}
        sub = _flash_fractions(session, found, offsets)
        offsets = sub.pop("offsets", offsets)
    counts = {c: len(s) for c, s in sources.items()}
    n = check_frame_counts(session, counts, offsets, offsets_from=how)
    progress("sync", f"offsets {offsets} ({how}); {n} synchronised frames")
    if ambiguous:
        progress("sync", "two flash candidates of similar score in " + ", ".join(
            f"camera '{c}' (frame {offsets[c]} taken, frame {f} nearly as likely)" for c, f in ambiguous.items())
            + "; the markers will check it")
    if sub:
        progress("sync", "the flash lit a first frame partly: the cameras run free; fractions of a frame "
                 + ", ".join(f"{c} {v:+.2f}" for c, v in sub["phase_frames"].items()) + " (the markers will refine them)")
    return SyncResult(offsets=offsets, frame_counts=counts, n_frames=n, offsets_from=how, flash_ambiguous=ambiguous,
                      **sub)


def exposure_fractions(session: Session) -> dict:
    """Camera -> the part of the frame period its frame collects light, from the optional
    ``metadata.camera_timing.<camera>.exposure_s`` (:func:`horsemocap.subframe.exposure_fraction`: half a
    frame when not given, 0 an instant) and ``.interlaced``.

    An interlaced frame's two fields are exposed half a frame apart, each for the exposure: the frame
    collects light from its first field's start to its second field's end, half a frame more (with the
    usual field exposure of half a frame, the whole frame period; the flash's onset inside the frame then
    follows from the first lit frame's brightness as for a progressive frame of that exposure).
    """
    out = {}
    for c in session.cameras:
        given = session.camera_timing(c)
        fraction = subframe.exposure_fraction(given, session.fps)
        if given.get("interlaced"):
            fraction += subframe.INTERLACED_FIELD_FRAMES
        out[c] = min(1.0, fraction)
    return out


def _flash_fractions(session: Session, found: dict, offsets: dict) -> dict:
    """The flash's sub-frame phases as SyncResult fields, or {} when every first lit frame was fully lit.

    The whole-frame offsets are those of the frames nearest in time (:func:`subframe.nearest_frames`: phases
    within half a frame), under key ``offsets``; the markers identify and check the cameras on them.
    """
    exposure = exposure_fractions(session)
    onsets = {c: subframe.flash_onset(d.signal, d.off_level, d.on_level, d.frame - d.start, exposure[c])
              for c, d in found.items()}
    # a rolling shutter exposes the flash's rows later than row 0, by which the markers' instants are timed
    # (an interlaced frame's rows are timed by their field: no delay)
    readout = {c: 0.0 if session.camera_timing(c).get("interlaced")
               else subframe.readout_frames(session.camera_timing(c), session.fps) for c in onsets}
    onsets = {c: replace(o, onset_frames=o.onset_frames + subframe.flash_row_delay(found[c].region, readout[c]))
              for c, o in onsets.items()}
    if not any(o.partial for o in onsets.values()):
        return {}
    phase, unc = subframe.flash_phases(onsets, offsets, session.reference_camera)
    offsets, phase = subframe.nearest_frames(offsets, phase)
    return dict(offsets=offsets, phase_frames=phase, offset_uncertainty_frames=unc, subframe_method="flash")
