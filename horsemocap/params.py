"""Analysis parameters: every choice the thesis asked the user for.

Each field has an automatic default (``None`` = chosen by the pipeline from
the data). A session's ``analysis`` object and ``--params analysis.json``
give overrides; the chosen values are written back to ``analysis.json`` so a
run can be repeated exactly.
"""
from __future__ import annotations

import difflib
import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path


class ParamsError(ValueError):
    """An analysis parameter file or value that cannot be used."""


# ---------------------------------------------------------------------------
# parameter sections: one per step (Pose2Sim's Config.toml has a section per step)
# ---------------------------------------------------------------------------

def _p(default=None, *, help: str, choices=None, range=None, kind=None, cli=None, legacy=None,
       nullable=False, factory=None):
    """A parameter field with what the one validation path and the generated command line need.

    ``help`` explains it; ``choices`` (allowed strings), ``range`` ((lo, hi) of a number, ``None``
    for an open end) or ``kind`` (``"bool"``, ``"int"``, ``"number"``, ``"dict"``, ``"list"``, ...) say
    what is valid; ``cli`` is its command-line flag; ``legacy`` the flat name of parameter files
    written before the sections (still read); ``nullable``: ``None`` is allowed (automatic).
    """
    meta = {"help": help, "choices": choices, "range": range, "kind": kind, "cli": cli,
            "legacy": legacy, "nullable": nullable}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class SyncParams:
    """Section ``sync``: the frame offsets between the cameras (eq. 3.11-3.14)."""

    offsets: dict | None = _p(None, nullable=True, kind="offsets", cli="--offsets", legacy="sync_offsets",
                              help="frame index of the same instant in every camera; null = found from the flashlight")


@dataclass(frozen=True)
class RigParams:
    """Section ``rig``: the calibrated rig (sections 3.3-3.6)."""

    recalibrate: bool = _p(False, kind="bool", cli="--recalibrate", legacy="recalibrate",
                           help="calibrate from the session's checkerboard views even if it has a rig")
    exclude: dict = _p(factory=dict, kind="exclude", cli="--exclude-views", legacy="calibration_exclude",
                       help="{camera: [view file names]} left out of the calibration")
    mode: str = _p("joint", choices=("joint", "pairwise"), cli="--calibration", legacy="calibration_mode",
                   help="joint: one bundle adjustment of every camera; pairwise: the thesis' stereo pairs")


@dataclass(frozen=True)
class StillsParams:
    """Section ``stills``: the plumb line's and the static shot's stills (Appendix A 7a, 8a, 12a)."""

    plumb: dict = _p(factory=dict, kind="stills", cli="--plumb-threshold",
                     help='{camera or "all": {"threshold": l, "labels": [...]}} of the plumb stills')
    static: dict = _p(factory=dict, kind="stills", cli="--static-threshold",
                      help='{camera or "all": {"threshold": l, "labels": [...]}} of the static-shot stills')


@dataclass(frozen=True)
class DetectParams:
    """Section ``detect``: the markers in the motion frames (chapter 4)."""

    method: str = _p("multiview", choices=("multiview", "thesis"), cli="--detection", legacy="detection_method",
                     help="multiview: identified by all cameras together; thesis: each camera alone (chapter 4)")
    cameras: dict = _p(factory=dict, kind="detection", cli="--threshold", legacy="detection",
                       help='{camera or "all": {detector parameter: value}} (threshold, labels, window, ...)')
    max_gap_frames: int | None = _p(None, nullable=True, kind="int", range=(0, None), cli="--max-gap",
                                    legacy="max_gap_frames",
                                    help="longest 3D gap bridged by interpolation; null = 0.1 s of frames")


@dataclass(frozen=True)
class TriangulateParams:
    """Section ``triangulate``: 3D positions from the cameras (section 5.1)."""

    mode: str = _p("joint", choices=("joint", "thesis"), cli="--triangulation", legacy="triangulation",
                   help="joint: all cameras at once; thesis: the three pairs averaged (eq. 5.5)")


@dataclass(frozen=True)
class SmoothParams:
    """Section ``smooth``: smoothing of the 3D positions (section 5.2)."""

    method: str = _p("loess", choices=("none", "rloess", "loess", "lowess", "rlowess", "moving"),
                     cli="--smoothing", legacy="smoothing_method", help="the smoother (thesis: rloess)")
    span: float = _p(0.1, kind="number", range=(0, 1), cli="--span", legacy="smoothing_span",
                     help="span as a fraction of the points, in (0, 1]")


@dataclass(frozen=True)
class MotionFrameParams:
    """Section ``motion_frame``: the motion reference frame (section 5.3)."""

    mode: str = _p("auto", choices=("auto", "record", "period"), cli="--motion-frame", legacy="motion_frame",
                   help="period: eq. 5.6/5.7; record: net displacement of the whole record; auto: period if found")
    x_marker: int = _p(0, kind="int", range=(0, None), cli="--x-marker", legacy="x_marker",
                       help="marker (0-based) whose net displacement defines x-motion (eq. 5.6)")
    period_frames: float | None = _p(None, nullable=True, kind="number", range=(2, None), cli="--period",
                                     legacy="period_frames", help="motion period in frames; null = estimated")
    n_periods: int | None = _p(None, nullable=True, kind="int", range=(1, None), legacy="n_periods",
                               help="periods used for the net displacement; null = two if the record holds them")


@dataclass(frozen=True)
class FitsParams:
    """Sub-section ``rigid_body.fits``: the thesis' chain of fits (section 5.5, chapter 6)."""

    x_degree: int = _p(1, kind="int", range=(0, 10), cli="--x-degree", legacy="x_degree",
                       help="polynomial degree of the x-motion fit (5.5.2.1)")
    fourier_orders: dict | list | None = _p(None, nullable=True, kind="fourier_orders", cli="--fourier-orders",
                                            legacy="fourier_orders",
                                            help='{"y": N, "z": N} or [[Ny, Nz], ...]; null = the order rule')
    order_rule: str = _p("significant", choices=("significant", "every_significant", "adjrsquare", "thesis"),
                         legacy="order_rule", help="the Fourier order rule (5.5.2.2)")
    trend: bool = _p(True, kind="bool", legacy="fourier_trend", help="a linear drift term in the y/z fits")
    angular_method: str = _p("rotation", choices=("rotation", "lstsq", "thesis"), cli="--angular",
                             legacy="angular_method", help="omega/alpha: fitted orientation, least squares, "
                                                           "or the thesis versions averaged")
    omega_versions: list = _p(factory=lambda: [True] * 6, kind="versions", cli="--omega-versions",
                              legacy="omega_versions", help="which of the six omega versions are averaged")
    alpha_versions: list = _p(factory=lambda: [True] * 6, kind="versions", cli="--alpha-versions",
                              legacy="alpha_versions", help="which of the six alpha versions are averaged")
    saddle_method: str = _p("pose", choices=("pose", "direct", "thesis"), cli="--saddle", legacy="saddle_method",
                            help="saddle kinematics: fitted pose, fitted eq. 6.48 path, or eq. 6.54/6.55")


@dataclass(frozen=True)
class PoseParams:
    """Sub-section ``rigid_body.pose``: the smoothed pose trajectory (not in the thesis)."""

    smoothing: str = _p("auto", choices=("auto", "adaptive", "gcv", "gcv_cubic", "none"), legacy="pose_smoothing",
                        help="the pose splines' smoothing choice")
    partial_frames: bool = _p(True, kind="bool", legacy="pose_partial_frames",
                              help="also smooth over the neighbouring frames where two markers are seen")
    harmonics: str = _p("auto", choices=("auto", "all", "none"), cli="--pose-harmonics", legacy="pose_harmonics",
                        help="unpenalised stride harmonics in the pose smoothing")
    weights: str = _p("covariance", choices=("covariance", "equal"), cli="--pose-weights", legacy="pose_weights",
                      help="markers weighted by their triangulation covariance, or alike (eq. 5.14-5.21)")
    rotation_weights: str = _p("auto", choices=("auto", "equal"), cli="--pose-rotation-weights",
                               legacy="pose_rotation_weights", help="frames weighted by predicted variance")
    events: list | None = _p(None, nullable=True, kind="events", cli="--pose-events", legacy="pose_events",
                             help="known instants (s) where the acceleration may jump")


@dataclass(frozen=True)
class RigidBodyParams:
    """Section ``rigid_body``: registration, kinematics and the hidden saddle marker (5.4-5.5, 6)."""

    kinematics: str = _p("pose_spline", choices=("pose_spline", "fits"), cli="--kinematics", legacy="kinematics",
                         help="pose_spline: the smoothed pose trajectory; fits: the thesis' chain of fits")
    saddle_marker: int | None = _p(None, nullable=True, kind="int", range=(0, None), cli="--saddle-marker",
                                   legacy="saddle_marker", help="which static-shot point is the saddle marker")
    fits: FitsParams = field(default_factory=FitsParams, metadata={"section": True})
    pose: PoseParams = field(default_factory=PoseParams, metadata={"section": True})


@dataclass(frozen=True)
class ComfortParams:
    """Section ``comfort``: the whole-body vibration indicators (chapter 7)."""

    weighting_mode: str = _p("iso", choices=("iso", "thesis"), cli="--weighting", legacy="weighting_mode",
                             help="iso: each harmonic weighted at its frequency; thesis: one scalar W")


@dataclass(frozen=True)
class AnalysisParams:
    """Every choice of the analysis (thesis Appendix A prompts).

    Attributes
    ----------
    sync_offsets : dict or None
        Frame index of the same instant in every camera (eq. 3.11-3.14);
        None = found from the flashlight.
    recalibrate : bool
        Calibrate from the session's checkerboard views even if it has a rig.
    calibration_exclude : dict
        ``{camera: [view file names]}`` left out of the calibration from the
        session's checkerboard views (the views the thesis user discarded in
        the toolbox; notebook 03's checkboxes); default none.
    calibration_mode : str
        How a calibration from the session's checkerboard views builds the
        rig: ``"joint"`` (default; one bundle adjustment of every camera) or
        ``"pairwise"`` (the thesis' stereo pairs with the reference camera,
        section 3.3; :func:`horsemocap.calibration.calibrate_rig`). Not used
        when the session gives a ``rig.toml`` (unless ``recalibrate``).
    detection_method : str
        ``"multiview"`` (default): the markers are identified by all cameras
        together (consistent triangulation, the static shot's rigid shape and
        handedness) and followed in 3D
        (:func:`horsemocap.detection.identify_markers`); ``"thesis"``: each
        camera on its own with the filters of chapter 4
        (:func:`horsemocap.detection.detect_markers`). Sessions without a
        static shot or with fewer than 3 markers use ``"thesis"``.
    detection : dict
        Per camera (or ``"all"``) overrides of the detector's parameters
        (threshold, area range, circularity, centroid; the thesis chain also
        window size, distance tolerance, labels).
    stills : dict
        The prompts of the still images (Appendix A 7a plumb, 8a static shot
        of the markers, 12a static shot of the saddle marker:
        ``left_levelinput``, ``left_labels``, ... per camera):
        ``{"plumb" or "static": {camera or "all": {"threshold": l, "labels": [...]}}}``.
        A threshold alone keeps the automatic matching of the cameras
        (:func:`horsemocap.detection.match_still_views`); labels (the
        :func:`~horsemocap.detection.label_regions` numbers at that
        threshold) must then be given for every camera and are taken as they
        are (:func:`horsemocap.detection.detect_still`). Default: automatic.
    saddle_marker : int or None
        Which static-shot point (0-based, in the static shot's order:
        ascending image ``u`` in the reference camera) is the saddle marker
        (Appendix A 12a); None = the point left over by the matching of the
        static shot to the ride (:func:`horsemocap.rigid.match_static_markers`).
    max_gap_frames : int or None
        Longest run of frames in which a marker has no 3D position (fewer
        than two cameras see it) that is bridged by interpolation and marked
        ``interpolated``; None = 0.1 s of frames, at least 2; 0 = none.
    triangulation : str
        ``"joint"`` (all cameras at once) or ``"thesis"`` (three pairs
        averaged, eq. 5.1-5.5).
    smoothing_span : float
        Span of ``smooth(y, span, 'rloess')`` as a fraction of the points.
    smoothing_method : str
        ``"loess"`` (default), ``"rloess"`` (the thesis' ``smooth(y, 0.1,
        'rloess')``), ``"lowess"``, ``"rlowess"``, ``"moving"`` or ``"none"``.
        Not the thesis' robust variant by default, on measurement over the 16
        virtual herd sessions (``benchmarks/bench_herd.py``, the same
        detections and rig for each method): median |error| of the Wb-weighted
        rms 7.9 % with loess, 9.5 % with rloess, 20.4 % without smoothing;
        worst session 17.6 %, 140 % and 53.5 %. On records of a few dozen
        frames a 0.1 span is 5-7 points, and the robust iterations of rloess
        reject good samples near the ends of the record (they moved the last
        frames of the bundled session by 15-24 mm; notebook 06).
    x_marker : int
        Marker (0-based) whose net displacement defines x-motion (eq. 5.6).
    period_frames : float or None
        Motion period in frames (the thesis typed 18); None = estimated.
    n_periods : int or None
        Periods used for the net displacement (eq. 5.6/5.7); None = two if
        the record holds them, else one.
    x_degree : int
        Polynomial degree of the x-motion fit (section 5.5.2.1).
    fourier_orders : dict, list or None
        ``{"y": N, "z": N}`` or per marker ``[[Ny, Nz], ...]``; None = the
        order rule of 5.5.2.2 with ``order_rule`` choosing between E/2 and E/2+1.
    order_rule : str
        ``"significant"``, ``"every_significant"``, ``"adjrsquare"`` or ``"thesis"`` (see
        :func:`horsemocap.fitting.choose_order`).
    fourier_trend : bool
        A linear drift term in the y/z fits (not in the thesis: absorbs the
        drift a slightly tilted estimated motion frame gives).
    angular_method : str
        ``"rotation"`` (from the Fourier fit of the registered orientation),
        ``"lstsq"`` (all markers, no singularity) or ``"thesis"`` (average of
        the versions of eq. 6.3/6.4/6.38/6.39 chosen by ``omega_versions``).
    omega_versions, alpha_versions : list of bool
        Which of the six thesis versions enter the averages (Figures 8.14-8.20).
    saddle_method : str
        ``"pose"`` (fit of the saddle path with the fitted orientation),
        ``"direct"`` (fit of the eq. 6.48 path) or ``"thesis"`` (mean of eq.
        6.54/6.55 over the three markers).
    weighting_mode : str
        ``"iso"`` (each harmonic weighted at its own frequency) or ``"thesis"``.
    kinematics : str
        What the rigid-body step passes on (omega, alpha, the markers' and the
        saddle's velocity and acceleration): ``"fits"`` (the thesis' chain of
        section 5.5 and chapter 6, chosen within by ``angular_method`` and
        ``saddle_method``) or ``"pose_spline"`` (not in the thesis: every
        frame's pose registered from all visible markers, the centroid and
        rotation vector smoothed by quintic splines whose smoothing is chosen
        by generalised cross-validation, analytic derivatives; no period and
        no eq. 6.35 singularity; :mod:`horsemocap.pose`). Both are computed
        when the record allows. Measured on the 16 virtual herd sessions
        through the pipeline with the multi-view detection
        (``benchmarks/bench_herd_kinematics.py``, the same detections for
        every variant; ``benchmarks/results/herd_kinematics_noise_test.txt``
        and ``herd_kinematics_merged.txt`` for the fits): saddle vertical
        acceleration RMSE median 2.7 % (worst 4.1 %) of its rms with
        pose_spline and its default ``pose_harmonics`` (10.6 %, worst
        13.0 %, with plain splines) against 24.1 % (38.6 %) with the fits;
        median |error| of the Wb-weighted rms 0.4 % (worst 2.8 %) against
        7.0 %, of the Wk-weighted rms 0.4 % (2.5 %) against 5.4 %, of VDV Wb
        0.7 % (2.6 %) against 9.5 %, of VDV Wk 0.6 % (2.4 %) against 8.3 %.
        With white detection noise (notebook 14's study, bundled session,
        medians of 3 draws, ``benchmarks/bench_noise_kinematics.py``;
        ``benchmarks/results/noise_kinematics.txt``) the saddle error at
        0.1 / 0.25 / 0.5 px is 32.4 / 37.3 / 48.6 % with pose_spline and
        84.0 / 192.9 / 673 % with the fits. A non-periodic record (a lift,
        a set-down, 10 Hz ringing) has only pose_spline
        (``benchmarks/bench_kinematics.py``). On the 8 harder sessions
        (``benchmarks/bench_identification.py --set hard``: other rigs,
        resolutions and frame rates, speed changes) the saddle error is
        1.1 % median (worst 2.3 %) with pose_spline against 17.9 % (28.6 %)
        with the fits, the Wb rms 0.3 % (1.0 %) against 5.7 % (11.4 %)
        (``benchmarks/bench_herd_kinematics.py --set hard``, ``benchmarks/results/hard_kinematics.txt``).
        The default is ``"pose_spline"``: better on 24 sessions of two
        independent sets, median and worst, and with noise. ``"fits"`` is
        the thesis' chain (``--kinematics fits``). On the bundled Horse 2
        canter (38 frames, a motion that is exactly a Fourier series) the
        saddle error is 2.5 % against 2.7 % with
        the fits and 10.1 % (-5.6 %) with plain splines.
    pose_smoothing : str
        Smoothing of the pose trajectory (:func:`horsemocap.splines.smoothing_spline`):
        ``"auto"`` (default: ``"gcv"`` with the stride harmonics on a periodic record, a
        fundamental found, and ``"adaptive"`` on one without, :func:`horsemocap.pose.choose_smoothing`;
        the choice and its reason in the progress output), ``"gcv"`` (quintic, one generalised
        cross-validation parameter per component), ``"adaptive"`` (a second GCV pass with a
        penalty weighted by the local roughness: better on motions that are
        calm then ringing), ``"gcv_cubic"`` (SciPy's ``make_smoothing_spline``) or ``"none"``.
    pose_partial_frames : bool
        With ``"pose_spline"``: smooth the pose trajectory also over the
        frames just beyond the analysed ones in which two markers are still
        triangulated (their pose completed by the trajectory's rotation about
        the two markers' line, :func:`horsemocap.pose.partial_pose`), and
        report only the analysed frames. The spline's natural boundary
        conditions then bias the acceleration outside the reported frames.
    pose_harmonics : str
        With ``"pose_spline"``: ``"auto"`` (default) smooths each pose
        component with a partial spline: harmonics of the stride, not
        penalised, plus a smoothing spline of the rest, the number of harmonics
        (0: none, a record that is not periodic) chosen with the smoothing by
        the same cross-validation; the fundamental is estimated from the record
        (:func:`horsemocap.splines.estimate_fundamental`); the rotation's
        harmonics only below the plain spline's cutoff frequency and larger
        than the rotation noise the registration residual and the marker
        geometry predict (a periodic measurement error is not told from
        motion below that size: Horse 1 canter 15.6 % without this test,
        2.7 % with it).
        ``"all"``: every component up to 0.4 of the frame rate. ``"none"``:
        plain smoothing splines (:func:`horsemocap.pose.fit_pose_trajectory`,
        ``harmonics``; ``--pose-harmonics``).
    pose_weights : str
        How each frame's pose is registered to its markers: ``"covariance"``
        (default) weights every marker by the inverse of its 3 x 3
        triangulation covariance (depth, measured about ten times worse than
        across the viewing rays, counts less; :func:`horsemocap.pose.register_pose`
        with ``covariance``; issue 13: saddle A_y on the herd 1.5 % median
        against 2.7 %, with 0.1 px of detection noise 5 % against 32 %);
        ``"equal"``: Horn's registration with equal marker weights (the
        thesis' eq. 5.14-5.21; ``--pose-weights``).
    pose_rotation_weights : str
        With ``"pose_spline"``, ``pose_weights`` ``"covariance"`` and GCV smoothing (``pose_smoothing``
        ``"gcv"``, or ``"auto"`` on a periodic record): ``"auto"`` (default) smooths each rotation component twice, with every
        frame weighted by its predicted variance (robustly) and with equal weights, and
        keeps the fit whose noise model explains its residuals better
        (:func:`horsemocap.pose.fit_pose_trajectory`, ``rotation_weights``; issue 13: with
        0.25 px of detection noise the saddle A_y error 8.3 % against 29.4 %, three draws);
        ``"equal"``: equal weights (``--pose-rotation-weights``).
    pose_events : list of float or None
        With ``"pose_spline"``: known instants (s, on the time axis of
        ``trajectories.csv``: from the first analysed frame) where the
        acceleration may jump, e.g. hoof impacts or an impact's onset from a
        force plate or an accelerometer: each pose component gets an
        unpenalised ``(t - tau)^2_+`` there (:func:`horsemocap.pose.fit_pose_trajectory`,
        ``events``; ``"auto"`` smoothing then runs ``"adaptive"``, ``"gcv"`` needs
        ``pose_harmonics`` ``"none"``). Not found from the data: no onset test
        tried holds on both the ringing fixtures and the lift
        (``benchmarks/bench_kinematics_tries.py --detect``). Issue 13's ringing
        fixture: hidden-point acceleration 18.4 % without, 14.9 % with the true
        onset (median of three draws), 19.9 % with it one frame early (draw 0,
        notebook 11): an instant must be known to the frame. ``--pose-events``;
        default ``None``: none.
    motion_frame : str
        x-motion axis: ``"auto"`` (default: the thesis' eq. 5.6/5.7 over one
        or two periods of ``x_marker`` when a period is given or found, else
        ``"record"``), ``"period"`` (always the thesis'; an error without a
        period) or ``"record"`` (the net displacement of the markers'
        centroid over the whole record, orthogonal to gravity: no period
        needed; the period is then only estimated for the comfort step).
    preset : str or None
        The named set of choices (:data:`PRESETS`) these parameters started
        from, recorded so ``analysis.json`` says so; ``None`` = the defaults.
        Values given explicitly override the preset's.
    """

    sync_offsets: dict | None = None
    recalibrate: bool = False
    calibration_exclude: dict = field(default_factory=dict)
    calibration_mode: str = "joint"
    detection_method: str = "multiview"
    detection: dict = field(default_factory=dict)
    stills: dict = field(default_factory=dict)
    saddle_marker: int | None = None
    max_gap_frames: int | None = None
    triangulation: str = "joint"
    smoothing_span: float = 0.1
    smoothing_method: str = "loess"
    x_marker: int = 0
    period_frames: float | None = None
    n_periods: int | None = None
    x_degree: int = 1
    fourier_orders: dict | list | None = None
    order_rule: str = "significant"
    fourier_trend: bool = True
    angular_method: str = "rotation"
    omega_versions: list = field(default_factory=lambda: [True] * 6)
    alpha_versions: list = field(default_factory=lambda: [True] * 6)
    saddle_method: str = "pose"
    weighting_mode: str = "iso"
    kinematics: str = "pose_spline"
    pose_smoothing: str = "auto"
    pose_partial_frames: bool = True
    pose_harmonics: str = "auto"
    pose_weights: str = "covariance"
    pose_rotation_weights: str = "auto"
    pose_events: list | None = None
    motion_frame: str = "auto"
    preset: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict, source: str = "analysis parameters") -> "AnalysisParams":
        """Build from a dict; unknown keys and bad values name ``source``."""
        if not isinstance(data, dict):
            raise ParamsError(f"{source}: expected an object of parameters, got {_show(data)}")
        names = [f.name for f in fields(cls)]
        for key in data:
            if key not in names:
                close = difflib.get_close_matches(key, names, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise ParamsError(f"{source}: unknown parameter '{key}'{hint}")
        preset = data.get("preset")
        if preset is not None:
            if not isinstance(preset, str) or preset not in PRESETS:
                raise ParamsError(f"{source}: parameter 'preset': expected "
                                  + " or ".join(f'"{k}"' for k in PRESETS) + f" or null, got {_show(preset)}")
            data = {**PRESETS[preset], **data}
        p = cls(**data)
        p.validate(source)
        return p

    def with_preset(self, name: str) -> "AnalysisParams":
        """These parameters with the values of preset ``name`` (:data:`PRESETS`) put over them.

        Options given after (e.g. on the command line, by :meth:`updated`)
        still override the preset's values.
        """
        if name not in PRESETS:
            raise ParamsError(f"preset: expected " + " or ".join(f'"{k}"' for k in PRESETS) + f", got {_show(name)}")
        p = replace(self, **PRESETS[name], preset=name)
        p.validate(f"preset '{name}'")
        return p

    def updated(self, **changes) -> "AnalysisParams":
        p = replace(self, **{k: v for k, v in changes.items() if v is not None})
        p.validate("command line")
        return p

    def validate(self, source: str) -> None:
        """Check every field's type and range; :class:`ParamsError` names the field.

        The message says the parameter, the expected type and range and the
        value given, e.g. ``analysis.json: parameter 'smoothing_span':
        expected a number in (0, 1], got 'wide'``. Checks against the session
        (cameras, marker count) are :meth:`check_session`'s.
        """
        def bad(name, expected, value=_MISSING):
            got = getattr(self, name) if value is _MISSING else value
            raise ParamsError(f"{source}: parameter '{name}': expected {expected}, got {_show(got)}")

        def choice(name, options):
            v = getattr(self, name)
            if not isinstance(v, str) or v not in options:
                bad(name, " or ".join(f'"{o}"' for o in options))

        def boolean(name):
            if not isinstance(getattr(self, name), bool):
                bad(name, "true or false")

        if self.sync_offsets is not None:
            if not isinstance(self.sync_offsets, dict) or not self.sync_offsets:
                bad("sync_offsets", "an object {camera: frame index} or null")
            for cam, v in self.sync_offsets.items():
                if not _is_int(v) or v < 0:
                    bad("sync_offsets", f"a frame index (integer >= 0) for camera '{cam}'", v)
        boolean("recalibrate")
        choice("calibration_mode", ("joint", "pairwise"))
        if not isinstance(self.detection, dict):
            bad("detection", 'an object {camera or "all": {detector parameter: value}}')
        from .detection import DetectionParams

        for cam, given in self.detection.items():
            if not isinstance(given, dict):
                bad("detection", f"an object of detector parameters for '{cam}'", given)
            try:
                DetectionParams.from_dict(given)
            except (ValueError, TypeError) as exc:
                raise ParamsError(f"{source}: parameter 'detection.{cam}': {exc}") from None
        choice("detection_method", ("multiview", "thesis"))
        ce = self.calibration_exclude
        if not isinstance(ce, dict) or not all(
                isinstance(v, (list, tuple)) and all(isinstance(x, str) and x for x in v) for v in ce.values()):
            bad("calibration_exclude", "an object {camera: [view file names]}")
        if not isinstance(self.stills, dict):
            bad("stills", 'an object {"plumb" or "static": {camera or "all": {"threshold": l, "labels": [...]}}}')
        for kind, per_cam in self.stills.items():
            if kind not in ("plumb", "static"):
                bad("stills", '"plumb" or "static" as keys', kind)
            if not isinstance(per_cam, dict):
                bad("stills", f'an object {{camera or "all": {{"threshold": l, "labels": [...]}}}} for "{kind}"',
                    per_cam)
            for cam, given in per_cam.items():
                if not isinstance(given, dict) or any(k not in ("threshold", "labels") for k in given):
                    bad("stills", f'{{"threshold": l, "labels": [...]}} for stills.{kind}.{cam}', given)
                thr = given.get("threshold")
                if thr is not None and (not _is_int(thr) or not 0 <= thr <= 254):
                    bad("stills", f"a gray level 0..254 for stills.{kind}.{cam}.threshold", thr)
                lab = given.get("labels")
                if lab is not None and (not isinstance(lab, (list, tuple)) or not lab
                                        or not all(_is_int(x) and x >= 1 for x in lab)
                                        or len(set(lab)) != len(lab)):
                    bad("stills", f"distinct region labels (integers >= 1) for stills.{kind}.{cam}.labels", lab)
                if lab is not None and thr is None:
                    bad("stills", f"a threshold with the labels of stills.{kind}.{cam} (labels name the "
                        "regions of one binary image)", given)
        if self.saddle_marker is not None and (not _is_int(self.saddle_marker) or self.saddle_marker < 0):
            bad("saddle_marker", "a static-shot point index (integer >= 0) or null")
        if self.max_gap_frames is not None and (not _is_int(self.max_gap_frames) or self.max_gap_frames < 0):
            bad("max_gap_frames", "an integer >= 0 (frames) or null")
        choice("triangulation", ("joint", "thesis"))
        if not _is_number(self.smoothing_span) or not 0 < self.smoothing_span <= 1:
            bad("smoothing_span", "a number in (0, 1] (a fraction of the points)")
        choice("smoothing_method", ("none", "rloess", "loess", "lowess", "rlowess", "moving"))
        if not _is_int(self.x_marker) or self.x_marker < 0:
            bad("x_marker", "a marker index (integer >= 0)")
        if self.period_frames is not None and (not _is_number(self.period_frames) or self.period_frames <= 2):
            bad("period_frames", "a period in frames (a number > 2) or null")
        if self.n_periods is not None and (not _is_int(self.n_periods) or self.n_periods < 1):
            bad("n_periods", "an integer >= 1 or null")
        if not _is_int(self.x_degree) or not 0 <= self.x_degree <= 10:
            bad("x_degree", "a polynomial degree (integer 0..10)")
        fo = self.fourier_orders
        if fo is not None:
            expected = '{"y": N, "z": N} or one [Ny, Nz] pair per marker (integers 1..40) or null'
            if isinstance(fo, dict):
                if set(fo) != {"y", "z"} or not all(_is_int(v) and 1 <= v <= 40 for v in fo.values()):
                    bad("fourier_orders", expected)
            elif isinstance(fo, (list, tuple)):
                if not fo or not all(isinstance(p, (list, tuple)) and len(p) == 2
                                     and all(_is_int(v) and 1 <= v <= 40 for v in p) for p in fo):
                    bad("fourier_orders", expected)
            else:
                bad("fourier_orders", expected)
        from .fitting import ORDER_RULES

        choice("order_rule", ORDER_RULES)
        boolean("fourier_trend")
        boolean("pose_partial_frames")
        choice("angular_method", ("rotation", "lstsq", "thesis"))
        for name in ("omega_versions", "alpha_versions"):
            v = getattr(self, name)
            if not isinstance(v, (list, tuple)) or len(v) != 6 or not all(isinstance(b, bool) for b in v) \
                    or not any(v):
                bad(name, "a list of six booleans, at least one true")
        choice("saddle_method", ("pose", "direct", "thesis"))
        choice("weighting_mode", ("iso", "thesis"))
        choice("kinematics", ("pose_spline", "fits"))
        choice("pose_smoothing", ("auto", "adaptive", "gcv", "gcv_cubic", "none"))
        choice("pose_harmonics", ("auto", "all", "none"))
        choice("pose_weights", ("covariance", "equal"))
        choice("pose_rotation_weights", ("auto", "equal"))
        self._validate_pose_events(bad)
        choice("motion_frame", ("auto", "record", "period"))
        if self.preset is not None and self.preset not in PRESETS:
            bad("preset", " or ".join(f'"{k}"' for k in PRESETS) + " or null")

    def _validate_pose_events(self, bad) -> None:
        """``pose_events``: null or distinct finite times, with a pose smoothing that fits change points."""
        ev = self.pose_events
        if ev is None or (isinstance(ev, (list, tuple)) and not ev):
            return
        if not isinstance(ev, (list, tuple)) or not all(_is_number(e) for e in ev) \
                or len(set(ev)) != len(ev):
            bad("pose_events", "a list of distinct times in seconds (the time_s of trajectories.csv), [] or null")
        if self.kinematics != "pose_spline":
            bad("pose_events", f'null with kinematics "{self.kinematics}" (change points are a pose_spline '
                'option; the thesis chain\'s fits have none)')
        if self.pose_smoothing in ("gcv_cubic", "none"):
            bad("pose_events", f'null with pose_smoothing "{self.pose_smoothing}" (change points are fitted by '
                'the quintic "auto", "adaptive" or "gcv" smoothing)')
        if self.pose_smoothing == "gcv" and self.pose_harmonics != "none":
            bad("pose_events", f'null with pose_smoothing "gcv" and pose_harmonics "{self.pose_harmonics}" '
                '(change points are fitted without stride harmonics: set pose_harmonics "none")')

    def check_session(self, session, source: str = "analysis parameters") -> None:
        """Check the parameters that refer to the session: cameras and markers.

        Raises :class:`ParamsError` naming the parameter, e.g. sync offsets
        for a camera the session does not have, or ``x_marker`` beyond the
        markers' count.
        """
        cams = list(session.cameras)
        if self.sync_offsets is not None:
            unknown = [c for c in self.sync_offsets if c not in cams]
            missing = [c for c in cams if c not in self.sync_offsets]
            if unknown or missing:
                what = f"no camera '{unknown[0]}'" if unknown else f"no offset for camera '{missing[0]}'"
                raise ParamsError(f"{source}: parameter 'sync_offsets': expected one frame index for each "
                                  f"camera {cams}, got {_show(self.sync_offsets)} ({what})")
        for cam in self.detection:
            if cam != "all" and cam not in cams:
                raise ParamsError(f"{source}: parameter 'detection': expected 'all' or a camera of {cams}, "
                                  f"got '{cam}'")
        for cam in self.calibration_exclude:
            if cam not in cams:
                raise ParamsError(f"{source}: parameter 'calibration_exclude': expected a camera of {cams}, "
                                  f"got '{cam}'")
        for kind, per_cam in self.stills.items():
            for cam in per_cam:
                if cam != "all" and cam not in cams:
                    raise ParamsError(f"{source}: parameter 'stills.{kind}': expected 'all' or a camera of "
                                      f"{cams}, got '{cam}'")
            count = 2 if kind == "plumb" else session.marker_count + 1
            labelled = [c for c in cams if {**per_cam.get("all", {}), **per_cam.get(c, {})}.get("labels")]
            if labelled and len(labelled) != len(cams):
                missing = [c for c in cams if c not in labelled]
                raise ParamsError(f"{source}: parameter 'stills.{kind}': labels given for {labelled} but not for "
                                  f"{missing}; labels are taken as they are, so every camera needs them")
            for cam in cams:
                lab = {**per_cam.get("all", {}), **per_cam.get(cam, {})}.get("labels")
                if lab is not None and len(lab) != count:
                    raise ParamsError(f"{source}: parameter 'stills.{kind}': expected {count} labels for camera "
                                      f"'{cam}' (the {kind} still's markers), got {len(lab)}")
        n = session.marker_count
        if self.saddle_marker is not None and self.saddle_marker > n:
            raise ParamsError(f"{source}: parameter 'saddle_marker': expected a static-shot point 0..{n} "
                              f"(the static shot has {n + 1}), got {self.saddle_marker}")
        if self.x_marker >= n:
            raise ParamsError(f"{source}: parameter 'x_marker': expected a marker index 0..{n - 1} "
                              f"(the session has {n} markers), got {self.x_marker}")
        if isinstance(self.fourier_orders, (list, tuple)) and len(self.fourier_orders) != n:
            raise ParamsError(f"{source}: parameter 'fourier_orders': expected {n} pairs [Ny, Nz] (one per "
                              f"marker), got {len(self.fourier_orders)}")


_MISSING = object()


PRESETS: dict[str, dict] = {
    "default": {},
    "thesis": {
        "calibration_mode": "pairwise",      # 3.3: stereo pairs with the left camera (Table 8.4)
        "detection_method": "thesis",        # chapter 4: each camera alone, threshold + filters
        "triangulation": "thesis",           # eq. 5.1-5.5: the three pairs averaged
        "smoothing_method": "rloess",        # 5.2.2: MATLAB smooth(y, 0.1, 'rloess')
        "smoothing_span": 0.1,
        "motion_frame": "period",            # eq. 5.6/5.7: net displacement over whole periods
        "x_degree": 1,                       # 5.5.2.1: x-motion a line in time
        "order_rule": "thesis",              # 5.5.2.2: N = E/2, the thesis' suggested order
        "fourier_trend": False,              # the thesis' Fourier series have no drift term
        "kinematics": "fits",                # 5.5 and chapter 6: the chain of fits
        "angular_method": "thesis",          # eq. 6.3/6.4/6.38/6.39: the versions averaged
        "omega_versions": [True] * 6,
        "alpha_versions": [True] * 6,
        "saddle_method": "thesis",           # eq. 6.54/6.55 averaged over the three markers
        "weighting_mode": "thesis",          # 7.2: one scalar weight W per record
        "pose_weights": "equal",             # eq. 5.14-5.21: every marker weighted alike
    },
}
"""Named sets of choices: ``"default"`` (the automatic pipeline) and
``"thesis"`` (the thesis' own chain end to end, each value with its
section). ``--preset thesis`` on the command line, ``{"preset": "thesis"}``
in a parameter file or ``results_for(params={"preset": "thesis"})`` in a
notebook; values given explicitly override the preset's. The pairwise
calibration only applies to sessions calibrated from checkerboard views
(the herd sessions carry a rig file)."""


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _show(v) -> str:
    try:
        return json.dumps(v)
    except (TypeError, ValueError):
        return repr(v)


def read_params(path) -> dict:
    """The parameters given in a file, validated, as a dict of only the parameters it names.

    ``analysis.json`` (its ``parameters`` object), a notebooks' ``choices.json``
    (the same layout, only the choices made) or a flat object.
    """
    data = load_params(path, _given_only=True)
    return data


def load_params(path, _given_only: bool = False) -> AnalysisParams:
    """Read ``analysis.json`` (its ``parameters`` object, or a flat object)."""
    path = Path(path)
    if not path.is_file():
        raise ParamsError(f"{path}: parameter file not found")
    from .store import read_text_utf8

    try:
        data = json.loads(read_text_utf8(path, ParamsError))
    except json.JSONDecodeError as exc:
        raise ParamsError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    if isinstance(data, dict) and "parameters" in data:
        data = data["parameters"]
    if not isinstance(data, dict):
        raise ParamsError(f"{path}: expected a JSON object of parameters")
    params = AnalysisParams.from_dict(data, str(path))
    return dict(data) if _given_only else params
