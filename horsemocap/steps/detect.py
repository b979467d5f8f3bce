"""Step ``detect``: the markers' centroids in every camera's synchronised frames (thesis chapter 4).

By default the markers are identified by all cameras together and followed
in 3D (:func:`horsemocap.detection.identify_markers`); the thesis' chain
detects them in each camera alone (:func:`horsemocap.detection.detect_markers`).
With a flashlight and three cameras, each camera's flash offset is then
checked against the instants of the other cameras' markers; a correction is
part of this step's result (:attr:`DetectResult.sync`), the sync step's own
result stays as it was.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..camera import Rig
from ..detection import (DetectionError, DetectionParams, best_frame_shift, bridge_gaps, candidate_area_range,
                         candidate_min_circularity, default_max_gap, detect_markers, frame_shift_residuals,
                         identify_markers, reason_counts, remeasure_by_fields)
from ..detection.candidates import WholeFrameSearches
from ..params import DetectParams
from ..progress import CountingFrames, counter
from .. import subframe
from ..reconstruction import DEFAULT_MAX_RESIDUAL_PX, triangulate
from ..session import Session, check_frame_counts
from ..sources import BlendedFields, FrameSource
from ..swaps import identification_hint
from .base import AnalysisError, StepResult, frames_text, longest_run
from .sync import SyncResult

#: Rounds of the markers' check of the flash offsets: a camera corrected in one round moves the markers the
#: next round projects into the others (two cameras' flashes found in wrong frames need two rounds).
SYNC_CHECK_ROUNDS = 3

MIN_SEGMENT_FRAMES = 8
"""The fewest consecutive frames an analysis needs."""

#: Free-running cameras: the identification accepts views this share of the image width apart on top of the
#: genlocked tolerance (a horse crossing the view in 50 frames moves 2 % of the width a frame; the views of
#: cameras half a frame apart then disagree by 1 % of the width).
FREE_RUNNING_TOLERANCE_OF_WIDTH = 0.01
#: A flash lit fully in every camera's first lit frame says nothing of a fraction of a frame: cameras that run
#: free look genlocked to it. The markers then measure the phases; a camera's phase is taken when it is more than
#: this many times its uncertainty (:class:`horsemocap.subframe.PhaseFit`: the chunks' spread with the timing
#: floor) and more than :data:`HIDDEN_PHASE_MIN_FRAMES` from zero (:func:`_phases_behind_a_full_flash`), else the
#: cameras stay genlocked.
HIDDEN_PHASE_Z = 4.0
#: The smallest phase (frames) taken as cameras running free behind a fully lit flash: a twentieth of a frame moves
#: a marker by a twentieth of its motion per frame, below what interpolating the tracks to common instants costs.
HIDDEN_PHASE_MIN_FRAMES = 0.05
#: Before that search (hundreds of triangulations of the record), one linearised least-squares step at zero phase
#: (:func:`horsemocap.subframe.linearised_phases`, a few triangulations) measures the phases: when every camera's is
#: within this many of its uncertainties or :data:`HIDDEN_PHASE_GATE_FRAMES` of zero, the cameras stay genlocked
#: without the search (:func:`phases_may_be_hidden`). Half of :data:`HIDDEN_PHASE_Z`: a phase the search takes lies
#: beyond 4 of its uncertainties, and the two estimates differ by about one (on 44 genlocked sessions at most 1.3).
HIDDEN_PHASE_GATE_Z = HIDDEN_PHASE_Z / 2
#: Half of :data:`HIDDEN_PHASE_MIN_FRAMES`, for the same margin: a phase the search takes is beyond 0.05 frame.
HIDDEN_PHASE_GATE_FRAMES = HIDDEN_PHASE_MIN_FRAMES / 2
#: Free-running cameras: a camera whose views the identification found inconsistent with the others' in more than
#: this share of its marker-frames (the views it used or rejected so) is identified again at other phases
#: (:func:`_phase_by_identification`): a flash lit fully in a camera's first lit frame leaves its phase a quarter of
#: a frame either way, and a fast marker's views a quarter of a frame apart disagree by more than the tolerance.
INCONSISTENT_SHARE_TO_SEARCH = 0.2
#: Free-running cameras: when the markers move a camera's phase by more than this (frames) from the phase its
#: views were identified at, the markers are identified again at the markers' phases and the phases refined
#: once more (:func:`_identified_again`): views a fraction of a frame apart were judged at the wrong instants,
#: and the ones rejected or lost then are not recovered otherwise. A twentieth of a frame, as
#: :data:`HIDDEN_PHASE_MIN_FRAMES`.
REIDENTIFY_MOVE_FRAMES = 0.05
#: At most this many identifications at the markers' phases (each refines the phases the next is made at).
REIDENTIFY_ROUNDS = 3
#: A phase the markers measured with an uncertainty above this (frames) is not followed: the markers are identified
#: at trial phases about the one they were identified at instead (:func:`_identified_again`).
PHASE_UNPINNED_FRAMES = 0.25
#: Nor is a phase at frame 0 of more than a frame either way: whole frames are the offsets' (the flash's, checked by
#: the markers' whole-frame check, :func:`_checked_by_markers`); a fraction that runs off by frames has followed
#: views identified at the wrong instants. A clock's drift may carry the phase past a frame over a long record (a
#: camera at 30000/1001 fps labelled 30 gains a frame in 1000): that part is the rate's, kept only when the drift
#: is measured (:func:`horsemocap.subframe.drift_is_measured`, within its largest rate).
PHASE_MAX_FRAMES = 1.0
#: The phases tried for such a camera, in frames from the flash's (the flash's uncertainty either way, and twice it).
PHASE_TRIALS_FRAMES = (-0.5, -0.25, 0.25, 0.5)
#: Free-running cameras whose rates are not known: a record longer than this many frames has its clocks measured
#: first on its first this-many frames from the flash, then on twice as many while that is shorter than three
#: quarters of the record, before the whole record (:func:`_clocks_from_the_flash`). The first identification labels the markers from the record's middle at the
#: flash's phases with every clock at the reference's rate; a camera at 30000/1001 fps labelled 30 is half a frame
#: off those phases at the middle of 1001 frames, past which its views disagree with the others'.
CLOCKS_FIRST_FRAMES = subframe.NTSC_FRAMES_PER_GAINED_FRAME


@dataclass(frozen=True)
class CameraSyncCheck(StepResult):
    """One camera's flash offset checked by the other cameras' markers.

    Attributes
    ----------
    shift : int
        Whole frames by which the markers moved the flash's offset (0 = confirmed).
    moved : bool
        A round moved the camera (even if the moves cancel).
    current_px, best_px : float
        Median distance of the others' projected markers from this camera's
        marker regions at the flash's offset (first round) and at the best shift (last round).
    n_points : int
        Marker-frames compared.
    decided : bool
        The residuals single out one shift.
    rounds : int
        Rounds run.
    settled : bool
        The last round moved no camera: the offsets the results use were checked.
    """

    shift: int
    moved: bool
    current_px: float
    best_px: float
    n_points: int
    decided: bool
    rounds: int
    settled: bool


@dataclass(frozen=True)
class IdentificationSummary(StepResult):
    """What the multi-view identification chose: the anchor frame and the static shot's markers.

    Attributes
    ----------
    anchor_frame : int
        Synchronised frame in which the markers were labelled.
    anchor_margin : float
        How clearly that labelling won over the next one.
    model_index : list of int
        Static-shot point of each marker.
    rigid_rms_m : float
        RMS distance of the identified markers from the static shot's rigid shape.
    """

    anchor_frame: int
    anchor_margin: float
    model_index: list
    rigid_rms_m: float


@dataclass(frozen=True)
class FieldsMeasured(StepResult):
    """An interlaced camera's markers measured field by field (:func:`measured_by_fields`): what was kept.

    Attributes
    ----------
    reason : (n, m) str
        Why a centroid kept the blended frame's value
        (:data:`~horsemocap.detection.fields.FIELD_NOT_FOUND`,
        :data:`~horsemocap.detection.fields.FIELDS_DISAGREE`); ``""`` where the
        fields measured it (or the marker was not seen).
    aliasing_px : (2,) ndarray
        The camera's vertical sampling error ``(a, b)`` fitted
        (:func:`~horsemocap.detection.row_aliasing`), px.
    aliasing_note : str
        Why that error was not removed (``""``: removed).
    """

    reason: np.ndarray
    aliasing_px: np.ndarray
    aliasing_note: str = ""

    @property
    def kept_blended(self) -> int:
        """Marker-frames that kept the blended frame's centroid."""
        return int(np.count_nonzero(self.reason != ""))


@dataclass(frozen=True)
class DetectResult(StepResult):
    """Marker centroids per camera, in the synchronised numbering.

    Attributes
    ----------
    marker_px : dict
        Camera -> (n, m, 2) centroids (px), NaN where not found (thesis ``PM_L``, ``PM_M``, ``PM_R``); an
        interlaced camera's measured field by field (:func:`measured_by_fields`).
    reason : dict
        Camera -> (n, m) why a centroid is missing ("" where found).
    segment : (int, int)
        The analysed frames ``[start, stop)``: the longest run in which every marker is seen.
    detection : dict
        Camera -> the detector parameters used (automatic choices filled in).
    all_seen : (n,) bool
        Frames in which every marker is seen (by two or more cameras, or bridged).
    method : str
        ``"multiview"`` or ``"thesis"``.
    method_note : str
        Why the thesis' chain ran although multiview was asked ("" otherwise).
    max_gap_frames : int
        Longest gap of a marker's 3D position bridged by interpolation.
    sync : SyncResult
        The synchronisation these frames are in: the sync step's, or its
        correction by the markers (then ``sync.flash_offsets`` holds the flash's).
    sync_check : dict
        Camera -> :class:`CameraSyncCheck` (empty when not checked).
    identification : IdentificationSummary or None
        The multi-view identification's choices.
    observation_frames : dict
        Camera -> (n, m) instant of each centroid in its synchronised frames (frame index plus the rolling
        shutter's row time, when the readout is known); empty: the frame instants.
    fields : dict
        Interlaced camera -> :class:`FieldsMeasured` (empty when no camera is interlaced).
    """

    marker_px: dict
    reason: dict
    segment: tuple
    detection: dict
    all_seen: np.ndarray
    method: str
    method_note: str
    max_gap_frames: int
    sync: SyncResult
    sync_check: dict = field(default_factory=dict)
    identification: IdentificationSummary | None = None
    observation_frames: dict = field(default_factory=dict)
    fields: dict = field(default_factory=dict)

    @property
    def sync_corrected(self) -> bool:
        """True when the markers corrected the flash offsets."""
        return self.sync.flash_offsets is not None


def max_gap_frames(session: Session, section: DetectParams) -> int:
    """The longest 3D gap bridged: ``section.max_gap_frames`` or 0.1 s of frames (at least 2)."""
    return default_max_gap(session.fps) if section.max_gap_frames is None else int(section.max_gap_frames)


def camera_detection_params(section: DetectParams, camera: str) -> DetectionParams | None:
    """The detector parameters given for ``camera`` ("all" first, then the camera's own), or None."""
    given = dict(section.cameras.get("all", {}))
    given.update(section.cameras.get(camera, {}))
    return DetectionParams.from_dict(given) if given else None


def synchronised_frames(session: Session, sync: SyncResult, cam: str, progress=None, message: str = ""):
    """The synchronised gray frames of ``cam``; with ``progress``, each first read of a frame is counted.
    An interlaced camera (``metadata.camera_timing.<cam>.interlaced``): its frames with the two fields
    blended (:class:`~horsemocap.sources.BlendedFields`: a moving marker's combed blob made whole); the
    identified markers are then measured in each field (:func:`measured_by_fields`)."""
    offsets, n = sync.offsets, sync.n_frames
    seq = FrameSource(session.motion[cam]).sequence(offsets[cam], offsets[cam] + n, color=False)
    if _interlaced(session, cam):
        seq = BlendedFields(seq)
    if progress is None or not getattr(progress, "counts", False):
        return seq
    return CountingFrames(seq, counter(progress, "detect", message or f"camera '{cam}' frames", n))


def step_detect(session: Session, section: DetectParams, sync: SyncResult, rig: Rig,
                static_points: np.ndarray | None, progress) -> DetectResult:
    """Marker centroids per camera in the synchronised numbering (chapter 4).

    ``section.method="multiview"`` (default): the markers are identified by
    all cameras together and followed in 3D, which needs the static shot's
    markers (``static_points``) as the rigid model; ``"thesis"``: each camera
    alone with the filters of chapter 4, and the analysed segment is the
    longest run in which every camera sees every marker.
    """
    method, why = section.method, ""
    if method == "multiview":
        if static_points is None:
            method, why = "thesis", "no static shot to take the markers' rigid shape from"
        elif session.marker_count < 3:
            method, why = "thesis", f"{session.marker_count} marker(s): a rigid shape needs 3"
        if why:
            progress("detect", f"multi-view identification not possible ({why}); the thesis' per-camera chain")
    if method == "multiview":
        return _detect_multiview(session, section, sync, rig, static_points, progress)
    if session.marker_count > 3:
        raise AnalysisError("detect", f"the thesis' per-camera chain (chapter 4) follows three markers, "
                                      f"{session.json_path} 'markers.count' says {session.marker_count}"
                                      + (f" and {why}" if why else "")
                                      + ": use detection method 'multiview' with a static shot of every marker")
    return _detect_per_camera(session, section, sync, progress, why)


@dataclass(frozen=True)
class _Identified:
    """The markers identified in every camera and the sync they were identified in (see :func:`_identified`)."""

    idn: object
    sync: SyncResult
    check: dict
    marker_px: dict
    by_fields: dict
    times: dict


def _silent(*_args) -> None:
    """A progress report that says nothing (the trial identifications')."""


@dataclass(frozen=True)
class _Identifier:
    """What every identification of one detect step shares (:func:`_identify`).

    Attributes
    ----------
    session, rig : Session, Rig
    static_points : (S, 3) array
        The static shot's markers, the rigid model.
    given : dict camera -> DetectionParams
        Each camera's detection parameters as the session gives them.
    progress : callable
        The step's progress report.
    tolerance : float
        Largest reprojection error (px) of a consistent point: the genlocked default, or wider for
        free-running cameras (:func:`free_running_tolerance`).
    searches : WholeFrameSearches or None
        The whole-frame searches kept for the identifications of the same recording that follow.

    Examples
    --------
    >>> ident = _Identifier(None, None, None, {}, print)
    >>> ident.at_tolerance(8.0).tolerance, ident.quiet().progress is _silent
    (8.0, True)
    """

    session: Session
    rig: Rig
    static_points: np.ndarray | None
    given: dict
    progress: object
    tolerance: float = DEFAULT_MAX_RESIDUAL_PX
    searches: WholeFrameSearches | None = None

    def at_tolerance(self, tolerance: float) -> "_Identifier":
        """The same identifications with views ``tolerance`` px apart taken as consistent."""
        return replace(self, tolerance=tolerance)

    def quiet(self) -> "_Identifier":
        """The same identifications without progress reports (the trials)."""
        return replace(self, progress=_silent)


def _identified(ident: _Identifier, section, sync, frames, *, check_offsets: bool = True) -> _Identified:
    """Identify the markers in ``sync`` and settle the sync on them: free-running cameras' phases searched by
    the identification (:func:`_phase_by_identification`), the flash's whole frames checked by the markers
    (:func:`_checked_by_markers`; not with ``check_offsets`` False), the fractions refined by the markers or found
    behind a fully lit flash, and the markers identified again at the phases the markers measured
    (:func:`_identified_again`)."""
    session, rig, progress = ident.session, ident.rig, ident.progress
    idn = _identify(ident, sync, frames)
    if sync.free_running and len(session.cameras) >= 3:
        idn, sync = _phase_by_identification(ident, sync, idn)
    check = {}
    if check_offsets and sync.offsets_from == "flashlight" and len(session.cameras) >= 3:
        idn, sync, check = _checked_by_markers(ident, section, sync, idn)
    marker_px, by_fields = measured_by_fields(session, sync, idn.marker_px, idn.thresholds, progress)
    times = observation_times(session, sync, rig, marker_px)
    if sync.subframe_method in ("flash", "markers") and len(session.cameras) >= 3:
        refined = _subframe_by_markers(session, sync, rig, marker_px, times, progress)
        again = _identified_again(ident, sync, idn, refined)
        if again is not None:
            idn, marker_px, by_fields, times, refined = again
        sync = refined
    elif sync.offsets_from.startswith("flashlight") and not sync.subframe_method and len(session.cameras) >= 3:
        genlocked = sync
        sync = _phases_behind_a_full_flash(session, sync, rig, marker_px, progress)
        times = observation_times(session, sync, rig, marker_px)      # the rows' instants, when running free
        if sync.free_running:          # identified as genlocked: again at the phases found, as free-running
            again = _identified_again(ident.at_tolerance(free_running_tolerance(rig)), genlocked, idn, sync)
            if again is not None:
                idn, marker_px, by_fields, times, sync = again
    return _Identified(idn, sync, check, marker_px, by_fields, times)


def _clocks_from_the_flash(ident: _Identifier, section, sync: SyncResult) -> SyncResult:
    """``sync`` with the free-running cameras' phases at frame 0 and rates measured on the record's first frames.

    A long record (more than :data:`CLOCKS_FIRST_FRAMES`) of cameras running free at rates not yet measured
    (the flash's fractions, or phases to be found behind a fully lit flash) is identified first on its first
    :data:`CLOCKS_FIRST_FRAMES` frames from the flash, where the flash's phases hold best, and the markers
    measure the phases and rates there (:func:`_measured_part`); then on twice as many frames at those, while
    the next part is shorter than three quarters of the record (the whole record's own rounds go on from
    there). Returns the phases and rates of the longest part measured, in ``sync``'s other fields, for the
    whole record's identification; ``sync`` itself when the record is short, the cameras expose together,
    the rates are known, or the first part measured nothing.
    """
    session, n = ident.session, sync.n_frames
    rates_known = any(float(v) != 1.0 for v in sync.rate_ratio.values())
    if (rates_known or n <= CLOCKS_FIRST_FRAMES or len(session.cameras) < 3
            or sync.subframe_method not in ("flash", "markers")):
        return sync
    current, length, measured_on = sync, CLOCKS_FIRST_FRAMES, 0
    while length < n:
        got = _measured_part(ident, section, current, length)
        if got is None:
            break
        current, measured_on = got, length
        if 2 * length >= 0.75 * n:
            break
        length *= 2
    if current is sync:
        ident.progress("detect", f"the clocks not measured on the first {CLOCKS_FIRST_FRAMES} synchronised frames: "
                                 "the whole record identified at the flash's phases")
        return sync
    ident.progress("detect", f"the cameras' clocks measured on synchronised frames 0..{measured_on - 1}: " + ", ".join(
        f"{c} {current.phase_frames.get(c, 0.0):+.3f}" + subframe.drift_text(current.rate_ratio.get(c, 1.0), n)
        for c in session.cameras if c != session.reference_camera) + "; the whole record identified at them")
    return current


def _measured_part(ident: _Identifier, section, sync: SyncResult, length: int) -> SyncResult | None:
    """``sync`` with the phases and rates the markers measure on the record's first ``length`` frames
    (:func:`_identified` on them, without the offsets' check: the whole record's identification makes it), for
    the cameras they pin (uncertainty within :data:`PHASE_UNPINNED_FRAMES`); None when nothing is identified
    there or no camera is pinned. Its progress reports say which frames they are about."""
    said = f"synchronised frames 0..{length - 1} first"
    within = replace(ident, progress=lambda step, msg, *a: ident.progress(step, f"{said}: {msg}", *a))
    try:
        found = _identified(within, section, sync.replace(n_frames=length), None, check_offsets=False).sync
    except AnalysisError:
        ident.progress("detect", f"{said}: no markers identified there")
        return None
    ref = ident.session.reference_camera
    pinned = [c for c in ident.session.cameras if c != ref
              and found.offset_uncertainty_frames.get(c, np.inf) <= PHASE_UNPINNED_FRAMES]
    if not pinned:
        return None
    return sync.replace(phase_frames={**sync.phase_frames, **{c: found.phase_frames[c] for c in pinned}},
                        rate_ratio={**sync.rate_ratio, **{c: found.rate_ratio.get(c, 1.0) for c in pinned}},
                        offset_uncertainty_frames={**sync.offset_uncertainty_frames,
                                                   **{c: found.offset_uncertainty_frames[c] for c in pinned}})


def _identified_at_clocks(ident: _Identifier, section, sync: SyncResult, frames) -> tuple:
    """``(found, measured)``: :func:`_identified` at the clocks measured from the flash onward
    (:func:`_clocks_from_the_flash`), or at ``sync``'s when they were not measured or the identification at
    them fails; ``measured`` says whether they were."""
    clocks = _clocks_from_the_flash(ident, section, sync)
    if clocks is sync:
        return _identified(ident, section, sync, frames), False
    try:
        return _identified(ident, section, clocks, frames), True
    except AnalysisError as exc:
        ident.progress("detect", f"at the clocks measured from the flash onward: {exc}; identifying at the "
                                 "flash's phases")
        return _identified(ident, section, sync, None), False


def clocks_not_measured_hint(n_frames: int) -> str:
    """``"; ..."``: why cameras running free may not be identified in a record of ``n_frames`` whose clocks were
    not measured before its identification (:func:`_clocks_from_the_flash`), or ``""`` for a short one.

    The whole record is then identified from its middle outward at the flash's phases, every clock at the
    reference's rate; a camera at 30000/1001 fps labelled 30 is ``n_frames / 2 / 1001`` frames off there, and
    from half a frame on its views disagree with the others'.

    Examples
    --------
    >>> clocks_not_measured_hint(1000)
    ''
    >>> "1.4 frames" in clocks_not_measured_hint(2787)
    True
    """
    gained = subframe.NTSC_FRAMES_PER_GAINED_FRAME
    off = 0.5 * int(n_frames) / gained
    if off < 0.5:
        return ""
    return (f"; the cameras run free and no markers in the first {CLOCKS_FIRST_FRAMES} frames after the flash "
            f"measured their clocks: a camera at another rate than the reference's (one at 30000/1001 fps labelled "
            f"30 gains a frame every {gained}) is {off:.1f} frames off the flash's phase by the middle of these "
            f"{int(n_frames)} frames, where the markers are then first labelled; if the cameras may differ in rate, "
            "fire the flash shortly before the horse's first pass")


def _as_free_running(session, sync: SyncResult) -> SyncResult:
    """The flash's sync with the cameras taken as free-running from phase zero (the markers find the phases)."""
    return sync.replace(phase_frames={c: 0.0 for c in session.cameras}, subframe_method="markers")


def _tracked(idn, gap: int) -> tuple:
    """The frames with a pose (every marker of three, any three or more of four or more: the others define the
    pose while one is hidden), gaps of at most ``gap`` frames bridged, and their longest run (or None)."""
    have, _ = bridge_gaps(idn.points, gap)
    located = np.all(np.isfinite(have), axis=2).sum(axis=1)
    tracked = located >= min(3, have.shape[1])
    return tracked, longest_run(tracked), have.shape[1]


def _run_length(segment) -> int:
    return 0 if segment is None else segment[1] - segment[0]


def _detect_multiview(session, section, sync, rig, static_points, progress) -> DetectResult:
    first = session.cameras[0]
    frames = {c: synchronised_frames(session, sync, c, progress if c == first else None, "frames identified")
              for c in session.cameras}
    given = {c: camera_detection_params(section, c) or DetectionParams() for c in session.cameras}
    progress("detect", f"{sync.n_frames} frames of cameras {', '.join(session.cameras)}: "
                       "markers identified by all cameras together ...")
    tolerance = free_running_tolerance(rig) if sync.free_running else DEFAULT_MAX_RESIDUAL_PX
    # every identification below searches the same frames whole
    ident = _Identifier(session, rig, static_points, given, progress, tolerance, WholeFrameSearches())
    as_free = ident.at_tolerance(free_running_tolerance(rig))
    tried_free, retry_error = sync.free_running, ""
    try:
        found, measured = _identified_at_clocks(ident, section, sync, frames)
    except AnalysisError:
        if sync.free_running or sync.offsets_from != "flashlight":
            raise
        progress("detect", "no consistent views at the genlocked tolerance: trying the cameras as free-running")
        tried_free = True
        found, measured = _identified_at_clocks(as_free, section, _as_free_running(session, sync), None)
    gap = max_gap_frames(session, section)
    tracked, segment, n_markers = _tracked(found.idn, gap)
    if (_run_length(segment) < MIN_SEGMENT_FRAMES and not tried_free and not found.sync.free_running
            and sync.offsets_from == "flashlight" and len(session.cameras) >= 3):
        # a fully lit flash hides cameras that run free; identified as genlocked, their views disagree
        progress("detect", f"only {_run_length(segment)} consecutive frames tracked with the cameras genlocked: "
                           "trying them as free-running")
        try:
            alt, alt_measured = _identified_at_clocks(as_free, section, _as_free_running(session, sync), None)
        except AnalysisError as exc:
            retry_error = f"; as free-running: {exc}"
            progress("detect", f"as free-running: {exc}")
        else:
            alt_tracked, alt_segment, _ = _tracked(alt.idn, gap)
            if _run_length(alt_segment) > _run_length(segment):
                found, tracked, segment, measured = alt, alt_tracked, alt_segment, alt_measured
            else:
                retry_error = f"; as free-running {_run_length(alt_segment)} consecutive frames"
    idn, sync, check = found.idn, found.sync, found.check
    if segment is None or segment[1] - segment[0] < MIN_SEGMENT_FRAMES:
        moved = [c for c, v in check.items() if v.moved or not v.decided]
        hint = (f"; the markers moved or could not check the flash offsets of {', '.join(moved)} (offsets now "
                f"{sync.offsets}, the flash's {sync.flash_offsets or sync.offsets}): "
                "if the flash was found in the wrong frame in two cameras, give the offsets (--offsets)"
                if moved else "") + retry_error \
            + (clocks_not_measured_hint(sync.n_frames) if sync.free_running and not measured else "") \
            + identification_hint(session, sync)
        raise AnalysisError("detect", "fewer than 8 consecutive frames in which every marker (three of four or more) "
                            "is seen by two or "
                            f"more cameras (marker-frames per camera: {reason_counts(idn.reason)}); check the "
                            "motion videos, the threshold, the rig and 'markers.count' in session.json" + hint)
    progress("detect", f"{frames_text(session.reference_camera, sync.offsets, segment[0], segment[1] - 1)}: every "
                       f"marker{'' if n_markers <= 3 else ' (three or more of them)'} seen by two or more cameras "
                       f"(or bridged); labelled in synchronised frame "
                       f"{idn.anchor_frame}")
    chosen = {c: {**given[c].to_dict(), "threshold": int(idn.thresholds[c])} for c in session.cameras}
    summary = IdentificationSummary(anchor_frame=idn.anchor_frame, anchor_margin=idn.anchor_margin,
                                    model_index=[int(i) for i in idn.model_index], rigid_rms_m=idn.rigid_rms_m)
    return DetectResult(marker_px=found.marker_px, reason=idn.reason, segment=segment, detection=chosen,
                        all_seen=tracked, method="multiview", method_note="", max_gap_frames=gap, sync=sync,
                        sync_check=check, identification=summary, observation_frames=found.times,
                        fields=found.by_fields)


def measured_by_fields(session: Session, sync: SyncResult, marker_px: dict, thresholds: dict,
                       progress) -> tuple[dict, dict]:
    """The interlaced cameras' centroids measured again in each field of their frames as recorded
    (:func:`horsemocap.detection.remeasure_by_fields`: each field's centre, the fields' vertical sampling
    error removed, the two averaged, half-way between the fields' instants); other cameras' as they are.

    The identification follows the markers in frames whose fields are blended; a blended combed blob's
    centre errs more than the mean of its two fields' centres. A marker the fields do not show as a pair
    of blobs straddling its blended centre keeps that centre, with the reason recorded.

    Returns
    -------
    marker_px : dict
        Camera -> (n, m, 2) centroids (a progressive camera's array unchanged, the same object).
    fields : dict
        Interlaced camera -> :class:`FieldsMeasured`.

    Examples
    --------
    One interlaced camera whose two frames show a marker combed between its fields, 4.8 px apart:

    >>> import tempfile, pathlib, cv2
    >>> from types import SimpleNamespace
    >>> yy, xx = np.mgrid[0:48, 0:72]
    >>> disc = lambda u, v: 20 + 210 * np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 1.6 ** 2))
    >>> combed = np.where(yy % 2 == 1, disc(30.3, 20.6), disc(35.1, 20.9)).round().astype(np.uint8)
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for k in range(2):
    ...     _ = cv2.imwrite(str(folder / f"frame_{k:03d}.png"), combed)
    >>> session = SimpleNamespace(cameras=["left"], motion={"left": folder},
    ...                           camera_timing=lambda c: {"interlaced": "bottom_first"})
    >>> sync = SimpleNamespace(offsets={"left": 0}, n_frames=2)
    >>> px, fields = measured_by_fields(session, sync, {"left": np.array([[[32.7, 20.8]], [[50.0, 40.0]]])},
    ...                                 {"left": 80}, lambda *message: None)
    >>> np.round(px["left"], 2).tolist(), fields["left"].reason.tolist()
    ([[[32.7, 20.75]], [[50.0, 40.0]]], [[''], ['field_not_found']])
    """
    measured, by_fields = dict(marker_px), {}
    for c in session.cameras:
        if not _interlaced(session, c):
            continue
        seq = FrameSource(session.motion[c]).sequence(sync.offsets[c], sync.offsets[c] + sync.n_frames, color=False)
        try:
            remeasured = remeasure_by_fields(seq, marker_px[c], int(thresholds[c]))
        finally:
            seq.close()
        measured[c] = remeasured.marker_px
        by_fields[c] = FieldsMeasured(reason=remeasured.reason, aliasing_px=np.asarray(remeasured.aliasing),
                                      aliasing_note=remeasured.aliasing_note)
        progress("detect", f"camera '{c}' (interlaced): {_fields_summary(by_fields[c])}")
    return measured, by_fields


def _fields_summary(measured: FieldsMeasured) -> str:
    """One line for the progress output: the error removed and the marker-frames that kept the blended centre."""
    a, b = measured.aliasing_px
    text = ("centroids measured in each field (" + (measured.aliasing_note or
            f"vertical sampling error {a:+.3f} cos, {b:+.3f} sin px removed") + ")")
    if measured.kept_blended:
        counts = ", ".join(f"{r} {n}" for r, n in zip(*np.unique(measured.reason[measured.reason != ""],
                                                                    return_counts=True)))
        text += f"; {measured.kept_blended} marker-frame(s) keep the blended frame's centroid ({counts})"
    return text


def free_running_tolerance(rig: Rig) -> float:
    """The identification's residual limit (px) for free-running cameras (:data:`FREE_RUNNING_TOLERANCE_OF_WIDTH`)."""
    width = max(rig[c].size[0] for c in rig.names)
    return DEFAULT_MAX_RESIDUAL_PX + FREE_RUNNING_TOLERANCE_OF_WIDTH * width


def observation_times(session: Session, sync: SyncResult, rig: Rig, marker_px: dict) -> dict:
    """The centroids' own instants (:func:`observation_frames`) whenever the cameras' offsets have a fraction of
    a frame (found from the flash and the markers, or given as fractional ``--offsets``); none for genlocked
    cameras, whose rows and fields are exposed at the same instants in every camera.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> observation_times(None, SimpleNamespace(subframe_method=""), None, {})
    {}
    """
    return observation_frames(session, rig, marker_px) if sync.subframe_method else {}


def observation_frames(session: Session, rig: Rig, marker_px: dict) -> dict:
    """Camera -> (n, m) instants of its centroids in its frames (:func:`subframe.observation_instants`), for the
    cameras whose rolling-shutter readout ``metadata.camera_timing.<camera>.rolling_shutter_s`` (s) or interlaced
    fields (``.interlaced``) session.json gives; others are absent."""
    out = {}
    for c, px in marker_px.items():
        given = session.camera_timing(c)
        readout, interlaced = subframe.readout_frames(given, session.fps), bool(given.get("interlaced"))
        if readout or interlaced:
            out[c] = subframe.observation_instants(px, rig[c].size[1], readout, interlaced)
    return out


def _interlaced(session: Session, cam: str) -> bool:
    """Does session.json's ``metadata.camera_timing.<cam>.interlaced`` say the camera records interlaced fields?"""
    return bool(session.camera_timing(cam).get("interlaced"))


def row_timing(session: Session) -> dict:
    """Camera -> ``(start, readout)`` frames of its rows' instants (:func:`subframe.observation_instants`:
    a quarter of a frame for interlaced fields, the rolling-shutter readout), for the cameras session.json's
    ``metadata.camera_timing`` describes."""
    out = {}
    for c in session.cameras:
        given = session.camera_timing(c)
        if given.get("rolling_shutter_s") or given.get("interlaced"):
            start = subframe.INTERLACED_FIELD_FRAMES / 2.0 if given.get("interlaced") else 0.0
            out[c] = (start, subframe.readout_frames(given, session.fps))
    return out


def current_phases(sync: SyncResult, reference: str) -> dict:
    """Each camera's phase in the current offsets (its synchronised frame ``k`` shows reference instant
    ``k + phase``; none for genlocked cameras), the reference camera's 0.

    A whole frame the markers moved a camera by (``sync.flash_offsets`` kept) corrects the flash's frame: its
    phase stays (the markers' whole-frame check reads free-running cameras at their own instants, so a move it
    makes is the flash found in a wrong frame, not the nearest frame taken on the other side of half a frame).

    Examples
    --------
    >>> s = SyncResult(offsets={"a": 9, "b": 61}, frame_counts={"a": 90, "b": 90}, n_frames=80,
    ...                offsets_from="flashlight, corrected by the markers", flash_offsets={"a": 8, "b": 61},
    ...                phase_frames={"a": 0.0, "b": 0.3})
    >>> current_phases(s, "a")
    {'a': 0.0, 'b': 0.3}
    """
    return {**dict(sync.phase_frames), reference: 0.0} if sync.phase_frames else {}


def _subframe_by_markers(session, sync, rig, marker_px, times, progress):
    """The sync with every camera's phase (and rate ratio) refined by the markers (:func:`subframe.refine_phases`)."""
    ref = session.reference_camera
    start = current_phases(sync, ref)
    fits = subframe.refine_phases(rig, marker_px, start, ref, times=times, rate_ratio=dict(sync.rate_ratio))
    if not fits:
        progress("detect", "the markers could not refine the fractions of a frame (too few marker-frames); "
                           "the flash's are kept")
        return sync
    phase = {c: (fits[c].phase if c in fits else start.get(c, 0.0)) for c in session.cameras}
    phase[ref] = 0.0
    unc = {c: (fits[c].uncertainty if c in fits else sync.offset_uncertainty_frames.get(c, 0.0))
           for c in session.cameras}
    rate = {c: (fits[c].rate_ratio if c in fits else sync.rate_ratio.get(c, 1.0)) for c in session.cameras}
    progress("detect", "fractions of a frame refined by the markers: " + ", ".join(
        f"{c} {phase[c]:+.3f} +- {unc[c]:.3f}" + subframe.drift_text(rate[c], sync.n_frames) for c in fits) + f" (residual {min(f.residual_px for f in fits.values()):.2f} px"
        + (f"; readout times of {', '.join(times)} used" if times else "; no rolling-shutter readout given") + ")")
    how = "flash and markers" if sync.subframe_method == "flash" else "markers"
    return sync.replace(phase_frames=phase, offset_uncertainty_frames=unc, rate_ratio=rate, subframe_method=how)


def phases_may_be_hidden(fits: dict, cameras) -> bool:
    """Could the search find cameras running free behind a fully lit flash, given the linearised phases?

    True unless every camera of ``cameras`` has a fit (:class:`horsemocap.subframe.PhaseFit`, from
    :func:`horsemocap.subframe.linearised_phases` at zero phase) within :data:`HIDDEN_PHASE_GATE_Z` times its
    uncertainty or :data:`HIDDEN_PHASE_GATE_FRAMES` of zero: half the margins by which
    :func:`_phases_behind_a_full_flash` takes a phase the search found.

    Examples
    --------
    >>> from horsemocap.subframe import PhaseFit
    >>> fit = lambda phase, unc: PhaseFit(phase=phase, uncertainty=unc, rate_ratio=1.0, residual_px=0.1, n_points=90)
    >>> phases_may_be_hidden({"middle": fit(0.02, 0.003), "right": fit(-0.03, 0.02)}, ["middle", "right"])
    False
    >>> phases_may_be_hidden({"middle": fit(0.03, 0.003), "right": fit(-0.03, 0.02)}, ["middle", "right"])
    True
    >>> phases_may_be_hidden({"middle": fit(0.02, 0.003)}, ["middle", "right"])     # right's phase not measured
    True
    """
    return any(c not in fits or abs(fits[c].phase) > max(HIDDEN_PHASE_GATE_Z * fits[c].uncertainty,
                                                         HIDDEN_PHASE_GATE_FRAMES)
               for c in cameras)


def _phases_behind_a_full_flash(session, sync, rig, marker_px, progress):
    """The sync of cameras the flash found genlocked, with the phases the markers measure when they differ.

    A flash that lights every camera's first lit frame fully gives whole-frame offsets only
    (:func:`horsemocap.steps.sync._flash_fractions`): cameras that run free then look genlocked. The markers
    first measure the phases by one linearised step at zero (:func:`horsemocap.subframe.linearised_phases`);
    when :func:`phases_may_be_hidden` says they are near enough zero, the cameras stay genlocked without
    the search. Otherwise the search measures each camera's phase (:func:`_subframe_by_markers` from zero);
    when one is more than :data:`HIDDEN_PHASE_Z` times its uncertainty and :data:`HIDDEN_PHASE_MIN_FRAMES`
    from zero (at frame 0 or, for a drifting clock, at the last: :func:`horsemocap.subframe.largest_phase`)
    the cameras run free and every phase found is kept,
    else the cameras stay genlocked (offsets and phases unchanged) with what was measured in
    ``genlocked_check`` and how in ``genlocked_check_method``.
    """
    others = [c for c in session.cameras if c != session.reference_camera]
    times = observation_frames(session, rig, marker_px)
    quick = subframe.linearised_phases(rig, marker_px, {c: 0.0 for c in session.cameras}, session.reference_camera,
                                       times=times)
    if not phases_may_be_hidden(quick, others):
        text = ", ".join(f"{c} {quick[c].phase:+.3f} +- {quick[c].uncertainty:.3f}" for c in others)
        progress("detect", f"the markers find the cameras genlocked, as the flash said ({text} frames, linearised "
                           "at zero phase: no search needed)")
        return sync.replace(genlocked_check={c: (float(quick[c].phase), float(quick[c].uncertainty)) for c in others},
                            genlocked_check_method="linearised")
    probe = sync.replace(phase_frames={c: 0.0 for c in session.cameras}, subframe_method="markers")
    found = _subframe_by_markers(session, probe, rig, marker_px, times, lambda *x: None)
    if found is probe:
        return sync
    phase, unc = found.phase_frames, found.offset_uncertainty_frames
    text = ", ".join(f"{c} {phase[c]:+.3f} +- {unc[c]:.3f}" for c in others)
    reach = {c: subframe.largest_phase(phase[c], found.rate_ratio.get(c, 1.0), found.n_frames) for c in others}
    if any(reach[c] > max(HIDDEN_PHASE_Z * unc.get(c, 0.0), HIDDEN_PHASE_MIN_FRAMES) for c in others):
        progress("detect", f"the flash lit every camera's first frame fully, but the markers find the cameras "
                           f"running free: {text} frames; those are used")
        return found
    progress("detect", f"the markers find the cameras genlocked, as the flash said ({text} frames)")
    return sync.replace(genlocked_check={c: (float(phase[c]), float(unc[c])) for c in others},
                        genlocked_check_method="search")


def inconsistent_shares(reason: dict) -> dict:
    """Camera -> the share of its marker-frames (views used or rejected as inconsistent) whose view was
    rejected as inconsistent with the other cameras' (0 when it has none).

    Examples
    --------
    >>> import numpy as np
    >>> r = {"left": np.array([["", ""], ["", "occluded"]]),
    ...      "middle": np.array([["inconsistent_views", ""], ["inconsistent_views", "lost"]])}
    >>> {c: round(v, 3) for c, v in inconsistent_shares(r).items()}
    {'left': 0.0, 'middle': 0.667}
    """
    out = {}
    for c, r in reason.items():
        r = np.asarray(r)
        bad = int(np.count_nonzero(r == "inconsistent_views"))
        seen = bad + int(np.count_nonzero(r == ""))
        out[c] = bad / seen if seen else 0.0
    return out


def phase_moves(before: dict, after: dict, *, rates: tuple = ({}, {}), n_frames: int = 0) -> dict:
    """Camera -> how far (frames, absolute) its phase moved from ``before`` to ``after`` (a camera absent
    from one of them at phase 0 there: a genlocked sync holds no phases).

    With ``rates`` (the rate ratios before and after; 1 where absent) a phase
    drifts over the record (:func:`horsemocap.subframe.camera_frames`): the
    move is the larger at its first frame and its last (``n_frames - 1``).

    Examples
    --------
    >>> phase_moves({"left": 0.0, "middle": 0.32}, {"left": 0.0, "middle": 0.58})
    {'left': 0.0, 'middle': 0.26}
    >>> phase_moves({}, {"left": 0.0, "middle": -0.26})
    {'left': 0.0, 'middle': 0.26}
    >>> phase_moves({"middle": 0.3}, {"middle": 0.3}, rates=({}, {"middle": 1.0001}), n_frames=1001)
    {'middle': 0.1}
    """
    cameras = list(before) + [c for c in after if c not in before]
    return {c: round(subframe.largest_phase(float(after.get(c, 0.0)) - float(before.get(c, 0.0)),
                                            1.0 + float(rates[1].get(c, 1.0)) - float(rates[0].get(c, 1.0)),
                                            n_frames), 9)
            for c in cameras}


def _identified_again(ident: _Identifier, identified_at, idn, refined):
    """The markers identified again until the phases the markers measure settle, or None when nothing better
    was found.

    ``idn`` was identified in ``identified_at``; ``refined`` holds the phases the markers measured on it (in the
    current offsets' frames). Each round identifies the markers at the markers' phases, measures them and
    refines the phases again; a camera whose phase the markers left uncertain by more than
    :data:`PHASE_UNPINNED_FRAMES`, or found more than :data:`PHASE_MAX_FRAMES` either way at frame 0, is instead
    identified at the trial phases :data:`PHASE_TRIALS_FRAMES` about
    the phase its views were identified at (:func:`_phase_trials`; the other cameras at the markers' phases).
    The rounds go on while a phase moves by more than :data:`REIDENTIFY_MOVE_FRAMES` or stays uncertain, at
    most :data:`REIDENTIFY_ROUNDS`. Returns ``(idn, marker_px, by_fields, times, sync)`` of the round whose
    identification used the most marker-frames, when it used more than ``idn``.
    """
    session, rig, progress = ident.session, ident.rig, ident.progress
    ref = session.reference_camera
    prev = identified_at.replace(phase_frames=current_phases(identified_at, ref))
    best, best_used = None, _used_marker_frames(idn)
    for _ in range(REIDENTIFY_ROUNDS):
        moved = phase_moves(prev.phase_frames, refined.phase_frames, rates=(prev.rate_ratio, refined.rate_ratio),
                            n_frames=refined.n_frames)
        loose = {c: u for c, u in refined.offset_uncertainty_frames.items()
                 if c != ref and (u > PHASE_UNPINNED_FRAMES
                                  or abs(refined.phase_frames.get(c, 0.0)) > PHASE_MAX_FRAMES)}
        if not loose and max(moved.values(), default=0.0) <= REIDENTIFY_MOVE_FRAMES:
            break
        if loose:
            progress("detect", "the markers could not pin the phases of " + ", ".join(
                f"{c} ({refined.phase_frames.get(c, 0.0):+.2f} +- {u:.2f} frame)" for c, u in loose.items())
                + ": identifying at other phases")
            about = prev.replace(phase_frames={**refined.phase_frames,
                                               **{c: prev.phase_frames.get(c, 0.0) for c in loose}},
                                 rate_ratio={**refined.rate_ratio, **{c: prev.rate_ratio.get(c, 1.0) for c in loose}})
            idn, at = _phase_trials(ident, about, idn, list(loose))
            if at is about and about.phase_frames == prev.phase_frames and about.rate_ratio == prev.rate_ratio:
                break                               # no trial used more: the same identification again
        else:
            progress("detect", "the markers moved the phases by " + ", ".join(
                f"{c} {d:.3f}" for c, d in moved.items() if d) + " frame from those the views were identified "
                "at: identifying again at the markers' phases")
            at = refined
            try:
                idn = _identify(ident, at)
            except AnalysisError as exc:
                progress("detect", f"identifying again failed ({exc}); the best identification so far is kept")
                break
        marker_px, by_fields = measured_by_fields(session, at, idn.marker_px, idn.thresholds, progress)
        times = observation_times(session, at, rig, marker_px)
        found = _subframe_by_markers(session, at, rig, marker_px, times, progress)
        prev, refined = at, found.replace(subframe_method=refined.subframe_method)
        used = _used_marker_frames(idn)
        if used > best_used:
            best, best_used = (idn, marker_px, by_fields, times, refined), used
    return best


def _phase_trials(ident: _Identifier, sync, idn, cameras):
    """The identification using the most marker-frames, and its sync, with each of ``cameras`` (in turn, the
    others at their best so far) at its phase in ``sync`` moved by each of :data:`PHASE_TRIALS_FRAMES`
    (``idn``: the identification at ``sync``'s phases, kept when no trial uses more). A camera moved gets at
    least the move as its phase's uncertainty; trials whose identification fails are said."""
    best_used, failed = _used_marker_frames(idn), []
    for c in cameras:
        base = dict(sync.phase_frames)
        for step in PHASE_TRIALS_FRAMES:
            trial = sync.replace(phase_frames={**base, c: base.get(c, 0.0) + step})
            try:
                found = _identify(ident.quiet(), trial)
            except AnalysisError:
                failed.append(f"{c} {step:+.2f}")
                continue
            used = _used_marker_frames(found)
            if used > best_used:
                unc = dict(trial.offset_uncertainty_frames)
                unc[c] = max(float(unc.get(c, 0.0)), abs(step))
                best_used, idn, sync = used, found, trial.replace(offset_uncertainty_frames=unc)
    if failed:
        ident.progress("detect", f"no identification at the trial phases {', '.join(failed)} frame")
    return idn, sync


def _used_marker_frames(idn) -> int:
    return int(sum(np.count_nonzero(np.asarray(r) == "") for r in idn.reason.values()))


def _phase_by_identification(ident: _Identifier, sync, idn):
    """The identification and sync with the phases of free-running cameras whose views the others' rejected.

    A camera whose views were found inconsistent in more than :data:`INCONSISTENT_SHARE_TO_SEARCH` of its
    marker-frames (:func:`inconsistent_shares`) is identified again with its phase moved by each of
    :data:`PHASE_TRIALS_FRAMES` (the worst camera first, the others at their best so far); the identification
    using the most marker-frames is kept. The markers refine the phase kept (:func:`_subframe_by_markers`).
    """
    session = ident.session
    shares = inconsistent_shares(idn.reason)
    ref = session.reference_camera
    worst = sorted((c for c in session.cameras if c != ref and shares[c] > INCONSISTENT_SHARE_TO_SEARCH),
                   key=lambda c: -shares[c])
    if not worst:
        return idn, sync
    before = ", ".join(f"{c} {100 * shares[c]:.0f} %" for c in worst)
    start = dict(sync.phase_frames)
    idn, sync = _phase_trials(ident, sync, idn, worst)
    best_used = _used_marker_frames(idn)
    moved = {c: sync.phase_frames.get(c, 0.0) - start.get(c, 0.0) for c in worst}
    ident.progress("detect", f"views found inconsistent with the other cameras' ({before} of their marker-frames): "
                       "identified again at other phases; "
                       + ", ".join(f"{c} {d:+.2f} frame" for c, d in moved.items())
                       + f" from the phases first identified at ({best_used} marker-frames used)")
    return idn, sync


def _identify(ident: _Identifier, sync, frames=None):
    """:func:`~horsemocap.detection.identify_markers` in ``sync`` (its phases, rates and offsets), the
    whole-frame searches kept in ``ident.searches`` for the identifications that follow."""
    session, searches = ident.session, ident.searches
    frames = frames or {c: synchronised_frames(session, sync, c) for c in session.cameras}
    kwargs = {} if ident.tolerance == DEFAULT_MAX_RESIDUAL_PX else {"max_residual_px": ident.tolerance}
    try:
        return identify_markers(frames, ident.rig, ident.static_points, session.marker_count, params=ident.given,
                                progress=ident.progress, phase=current_phases(sync, session.reference_camera),
                                row_timing=row_timing(session), rate_ratio=dict(sync.rate_ratio),
                                whole_frames=None if searches is None else searches.of_offsets(sync.offsets), **kwargs)
    except DetectionError as exc:
        raise AnalysisError("detect", f"{exc}{identification_hint(session, sync)}") from None
    finally:
        for f in frames.values():
            f.close()


def _checked_by_markers(ident: _Identifier, section, sync, idn):
    """Rounds of :func:`_check_round` until no camera moves (at most :data:`SYNC_CHECK_ROUNDS`).

    Returns the last identification, the synchronisation it is in and the per-camera check.
    """
    rounds, flash = [], sync
    for _ in range(SYNC_CHECK_ROUNDS):      # again after a correction: the others' markers have moved too
        shifts, sync = _check_round(ident.session, section, sync, ident.rig, idn, ident.progress)
        rounds.append(shifts)
        if not any(v["shift"] for v in shifts.values()):
            break
        idn = _identify(ident, sync)
    return idn, sync, _check_summary(rounds, sync, flash)


def _check_summary(rounds: list, sync: SyncResult, flash: SyncResult) -> dict:
    """Per camera over the rounds: the total shift from the flash's offset, whether a round moved it, the
    first round's residual, the last round's best residual, marker-frames and decision, and whether the
    rounds settled (the last round moved no camera)."""
    flash_offsets = flash.offsets
    settled = not any(v["shift"] for v in rounds[-1].values())
    return {c: CameraSyncCheck(shift=int(sync.offsets[c] - flash_offsets[c]),
                               moved=any(r[c]["shift"] for r in rounds), current_px=rounds[0][c]["current_px"],
                               best_px=last["best_px"], n_points=last["n_points"], decided=last["decided"],
                               rounds=len(rounds), settled=settled)
            for c, last in rounds[-1].items()}


def _check_round(session, section, sync, rig, idn, progress):
    """Each camera's flash offset checked against the instants of the others' markers.

    For every camera, the markers triangulated from the OTHER cameras (free-running cameras: their tracks at
    common instants, read at this camera's own, :func:`horsemocap.subframe.points_at_shifted_instants`) are
    projected into its frames shifted by up to one second
    (:func:`horsemocap.detection.timeshift.frame_shift_residuals`); when a
    shift clearly puts them on its marker regions
    (:func:`~horsemocap.detection.timeshift.best_frame_shift`), the camera's
    offset is corrected. Returns per camera the shift and the residuals, and
    the synchronisation after the round (a new :class:`SyncResult` when a
    camera moved, saying so in ``offsets_from`` and ``flash_offsets``).
    """
    offsets, n = sync.offsets, sync.n_frames
    reach = max(5, int(round(session.fps)))
    phase = current_phases(sync, session.reference_camera) if sync.free_running else {}
    out = {}
    for c in session.cameras:
        others = {o: idn.marker_px[o] for o in session.cameras if o != c}
        if phase:     # free-running: the others' markers at common instants, read at this camera's own
            others, _ = subframe.tracks_at_reference_instants(others, phase, sync.rate_ratio,
                                                              observation_frames(session, rig, others))
        points = triangulate(rig, others, mode="joint").points
        if phase:
            points = subframe.points_at_shifted_instants(points, phase.get(c, 0.0), sync.rate_ratio.get(c, 1.0))
        first = max(-reach, -offsets[c])
        stop = min(sync.frame_counts[c], offsets[c] + n + reach)
        seq = FrameSource(session.motion[c]).sequence(offsets[c] + first, stop, color=False)
        p = camera_detection_params(section, c) or DetectionParams()
        try:
            shifts, med, npts = frame_shift_residuals(rig[c], points, seq, first, range(-reach, reach + 1),
                                                      idn.thresholds[c], candidate_area_range(p), candidate_min_circularity(p),
                                                      centroid=p.centroid)
        finally:
            seq.close()
        fs = best_frame_shift(shifts, med, npts)
        out[c] = {"shift": fs.best, "current_px": fs.current_px, "best_px": fs.best_px, "n_points": fs.n_points,
                  "decided": fs.decided}
    moved = {c: v["shift"] for c, v in out.items() if v["shift"]}
    if not moved:
        return out, sync
    new = {c: int(offsets[c] + moved.get(c, 0)) for c in session.cameras}
    what = ", ".join(f"{c} {d:+d} frame(s) (residual {out[c]['current_px']:.1f} -> {out[c]['best_px']:.2f} px)"
                     for c, d in moved.items())
    again = sync.flash_offsets is not None              # a round after a correction
    progress("detect", f"the {'corrected offsets still disagree' if again else 'flash offsets disagree'} with "
                       f"the markers: {what}; offsets {new}, identifying again")
    how = f"{sync.offsets_from}{'; then' if again else ','} corrected by the markers ({what})"
    corrected = sync.replace(offsets=new, offsets_from=how,
                             n_frames=check_frame_counts(session, sync.frame_counts, new, offsets_from=how),
                             flash_offsets=dict(sync.flash_offsets or offsets))
    return out, corrected


def _detect_per_camera(session, section, sync, progress, why: str) -> DetectResult:
    """The thesis' chain: every camera on its own (chapter 4)."""
    n = sync.n_frames
    found, reasons, chosen = {}, {}, {}
    for cam in session.cameras:
        progress("detect", f"camera '{cam}': {n} frames ...")
        frames = synchronised_frames(session, sync, cam, progress, f"camera '{cam}' frames")
        track = detect_markers(frames, session.marker_count, params=camera_detection_params(section, cam))
        found[cam], reasons[cam] = track.marker_px, track.reason
        chosen[cam] = track.params.to_dict()
        frames.close()
    marker_px, by_fields = measured_by_fields(session, sync, found, {c: chosen[c]["threshold"] for c in chosen},
                                              progress)
    seen = np.all([np.all(np.isfinite(marker_px[c][..., 0]), axis=1) for c in session.cameras], axis=0)
    segment = longest_run(seen)
    if segment is None or segment[1] - segment[0] < MIN_SEGMENT_FRAMES:
        counts = {c: int(np.all(np.isfinite(marker_px[c][..., 0]), axis=1).sum()) for c in session.cameras}
        raise AnalysisError("detect", "fewer than 8 consecutive frames in which every camera sees every "
                            f"marker (frames with all markers, per camera: {counts}); check the motion "
                            "videos, the threshold and the marker count in session.json")
    progress("detect", f"frames {segment[0]}..{segment[1] - 1} seen by every camera")
    gaps = gaps_inside(seen, reasons)
    if gaps:
        progress("detect", "not every marker seen in frames " + "; ".join(gaps)
                 + f"; analysing the longest run {segment[0]}..{segment[1] - 1}")
    return DetectResult(marker_px=marker_px, reason=reasons, segment=segment, detection=chosen, all_seen=seen,
                        method="thesis", method_note=why, max_gap_frames=max_gap_frames(session, section),
                        sync=sync, fields=by_fields)


def gaps_inside(seen: np.ndarray, reasons: dict) -> list[str]:
    """Frames between the first and last all-seen frame where a marker is missing, and why.

    Examples
    --------
    >>> gaps_inside(np.array([True, False, True]), {"left": np.array([[""], ["dark"], [""]])})
    ['1 (left marker1 dark)']
    """
    idx = np.flatnonzero(seen)
    if idx.size == 0:
        return []
    out = []
    for k in range(idx[0], idx[-1] + 1):
        if seen[k]:
            continue
        why = sorted({f"{cam} marker{m + 1} {r[k, m]}" for cam, r in reasons.items()
                      for m in range(r.shape[1]) if r[k, m]})
        out.append(f"{k} ({', '.join(why)})")
    return out
