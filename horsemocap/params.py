"""Analysis parameters: every choice the thesis asked the user for, one section per step.

:class:`AnalysisParams` holds one section per step of the analysis (``sync``,
``rig``, ``stills``, ``detect``, ``triangulate``, ``smooth``,
``motion_frame``, ``rigid_body``, ``comfort``), and each step is given its
own (:meth:`AnalysisParams.section`). Every field has an automatic default
(``None`` = chosen by the pipeline from the data). A session's ``analysis``
object, ``--params analysis.json``, the notebooks' ``choices.json`` and the
command line give overrides, in the nested form ``{"smooth": {"span": 0.2}}``
or by the flat names of the files written before the sections
(``{"smoothing_span": 0.2}``, :func:`legacy_names`); the values used are
written back to ``analysis.json`` in the nested form
(:meth:`AnalysisParams.to_dict`) so a run can be repeated exactly.

Each field's metadata (help, choices, range, kind, command-line flag, flat
name) drives the one validation path (:meth:`AnalysisParams.validate`) and
the command line's options (:func:`params_fields`).

Examples
--------
>>> p = AnalysisParams.from_dict({"smooth": {"span": 0.2}, "triangulation": "thesis"})
>>> p.smooth.span, p.triangulate.mode
(0.2, 'thesis')
>>> p.updated({"smooth.method": "rloess"}).smooth.method
'rloess'
"""
from __future__ import annotations

import copy
import difflib
import json
import math
from dataclasses import MISSING, asdict, dataclass, field, fields
from functools import lru_cache
from pathlib import Path

from .store import MAX_JSON_DEPTH, json_depth, read_text_utf8


class ParamsError(ValueError):
    """An analysis parameter file or value that cannot be used."""


# ---------------------------------------------------------------------------
# parameter sections: one per step (Pose2Sim's Config.toml has a section per step)
# ---------------------------------------------------------------------------

def _p(default=None, *, help: str, choices=None, range=None, bounds="[]", kind=None, cli=None, legacy=None,
       nullable=False, factory=None, metavar=None, cli_values=()):
    """A parameter field with what the one validation path and the generated command line need.

    ``help`` explains it; ``choices`` (allowed strings), ``range`` ((lo, hi) of a number, ``None``
    for an open end; ``bounds`` says which ends are included, ``"[]"`` both, ``"(]"`` the upper
    only) or ``kind`` (``"bool"``, ``"int"``, ``"number"``, or a structured kind such as
    ``"offsets"``: :data:`_KIND_CHECKS`) say what is valid; ``cli`` is its command-line flag
    (``metavar`` names its value there); ``cli_values`` are flags that set one value inside a dict
    field, ``(flag, path inside the field, metavar, help)``; ``legacy`` the flat name of parameter
    files written before the sections (still read); ``nullable``: ``None`` is allowed (automatic).
    """
    meta = {"help": help, "choices": choices, "range": range, "bounds": bounds, "kind": kind, "cli": cli,
            "legacy": legacy, "nullable": nullable, "metavar": metavar, "cli_values": tuple(cli_values)}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


def _section(cls):
    """A field holding a (sub-)section of parameters."""
    return field(default_factory=cls, metadata={"section": True})


@dataclass(frozen=True)
class SyncParams:
    """Section ``sync``: the frame offsets between the cameras (eq. 3.11-3.14).

    Attributes
    ----------
    offsets : dict or None
        ``{camera: frame index}`` of the same instant in every camera;
        ``None`` = found from the flashlight (:mod:`horsemocap.sync`).
        Flat name ``sync_offsets``.

    Examples
    --------
    >>> SyncParams(offsets={"left": 0, "middle": 53, "right": 126}).offsets["right"]
    126
    """

    offsets: dict | None = _p(None, nullable=True, kind="offsets", cli="--offsets", legacy="sync_offsets",
                              metavar="CAM=FRAME,...",
                              help="frame index of the same instant in every camera, e.g. left=0,middle=53,"
                                   "right=126, instead of the flashlight's")


@dataclass(frozen=True)
class RigParams:
    """Section ``rig``: the calibrated rig (sections 3.3-3.6).

    Attributes
    ----------
    recalibrate : bool
        Calibrate from the session's checkerboard views even if the session
        gives a rig (``rig.toml``).
    exclude : dict
        ``{camera: [view file names]}`` left out of a calibration from the
        session's checkerboard views (the views the thesis' user discarded in
        the toolbox; notebook 03's checkboxes); default none. Flat name
        ``calibration_exclude``.
    mode : str
        How a calibration from the session's checkerboard views builds the
        rig: ``"joint"`` (default; one bundle adjustment of every camera) or
        ``"pairwise"`` (the thesis' stereo pairs with the reference camera,
        section 3.3; :func:`horsemocap.calibration.calibrate_rig`). Not used
        when the session gives a ``rig.toml`` (unless ``recalibrate``). Flat
        name ``calibration_mode``.

    Examples
    --------
    >>> RigParams(mode="pairwise", exclude={"left": ["view03.png"]}).exclude["left"]
    ['view03.png']
    """

    recalibrate: bool = _p(False, kind="bool", cli="--recalibrate", legacy="recalibrate",
                           help="calibrate from the session's checkerboard views even if it has a rig")
    exclude: dict = _p(factory=dict, kind="exclude", cli="--exclude-views", legacy="calibration_exclude",
                       metavar="CAM=VIEW[+VIEW],...",
                       help="checkerboard views left out of the calibration, e.g. "
                            "left=view03.png+view07.png,right=view03.png")
    mode: str = _p("joint", choices=("joint", "pairwise"), cli="--calibration", legacy="calibration_mode",
                   help="joint: one bundle adjustment of every camera; pairwise: the thesis' stereo pairs with "
                        "the reference camera (used when the rig is calibrated from the session's views)")


_STILL_HELP = ('{camera or "all": {"threshold": l, "labels": [...]}}; labels, when given, for every camera '
               'and with a threshold')


@dataclass(frozen=True)
class StillsParams:
    """Section ``stills``: the plumb line's and the static shot's stills (Appendix A 7a, 8a, 12a).

    Attributes
    ----------
    plumb, static : dict
        The prompts of the still images (Appendix A 7a: the plumb line; 8a
        and 12a: the static shot of the markers and of the saddle marker;
        the thesis' ``left_levelinput``, ``left_labels``, ... per camera):
        ``{camera or "all": {"threshold": l, "labels": [...]}}``. A threshold
        alone keeps the automatic matching of the cameras
        (:func:`horsemocap.detection.match_still_views`); labels (the
        :func:`~horsemocap.detection.label_regions` numbers at that
        threshold) must then be given for every camera and are taken as they
        are (:func:`horsemocap.detection.detect_still`). Default: automatic.
        Flat form: ``"stills": {"plumb": ..., "static": ...}``, the same
        object.

    Examples
    --------
    >>> StillsParams(static={"all": {"threshold": 200}}).static["all"]["threshold"]
    200
    """

    plumb: dict = _p(factory=dict, kind="stills", help="the plumb stills' prompts: " + _STILL_HELP,
                     cli_values=[("--plumb-threshold", "all.threshold", "LEVEL",
                                  "gray-level threshold of the plumb stills, every camera (Appendix A 7a)")])
    static: dict = _p(factory=dict, kind="stills", help="the static-shot stills' prompts: " + _STILL_HELP,
                      cli_values=[("--static-threshold", "all.threshold", "LEVEL",
                                   "gray-level threshold of the static-shot stills, every camera "
                                   "(Appendix A 8a, 12a)")])


@dataclass(frozen=True)
class DetectParams:
    """Section ``detect``: the markers in the motion frames (chapter 4).

    Attributes
    ----------
    method : str
        ``"multiview"`` (default): the markers are identified by all cameras
        together (consistent triangulation, the static shot's rigid shape and
        handedness) and followed in 3D
        (:func:`horsemocap.detection.identify_markers`); ``"thesis"``: each
        camera on its own with the filters of chapter 4
        (:func:`horsemocap.detection.detect_markers`). Sessions without a
        static shot or with fewer than 3 markers use ``"thesis"``. Flat name
        ``detection_method``.
    cameras : dict
        Per camera (or ``"all"``) overrides of the detector's parameters
        (:class:`horsemocap.detection.DetectionParams`: threshold, area
        range, circularity, centroid; the thesis' chain also the first frame,
        window size, distance tolerance, labels). Flat name ``detection``.
    max_gap_frames : int or None
        Longest run of frames in which a marker has no 3D position (fewer
        than two cameras see it) that is bridged by interpolation and marked
        ``interpolated``; ``None`` = 0.1 s of frames, at least 2; 0 = none.

    Examples
    --------
    >>> DetectParams(cameras={"all": {"threshold": 150}}).cameras["all"]["threshold"]
    150
    """

    method: str = _p("multiview", choices=("multiview", "thesis"), cli="--detection", legacy="detection_method",
                     help="multiview: markers identified by all cameras together and followed in 3D; "
                          "thesis: each camera alone with the filters of chapter 4")
    cameras: dict = _p(factory=dict, kind="detection", legacy="detection",
                       help='{camera or "all": {detector parameter: value}} (threshold, labels, first_frame, '
                            'window, distance_tolerance, area_min, ...)',
                       cli_values=[("--threshold", "all.threshold", "LEVEL",
                                    "gray-level threshold for every camera (thesis eq. 4.5; default Otsu-based)"),
                                   ("--first-frame", "all.first_frame", "FRAME",
                                    "frame (0-based, synchronised) in which the markers are picked for every "
                                    "camera (Appendix A step 4; default found automatically)")])
    max_gap_frames: int | None = _p(None, nullable=True, kind="int", range=(0, None), cli="--max-gap",
                                    legacy="max_gap_frames", metavar="FRAMES",
                                    help="longest gap of a marker's 3D position bridged by interpolation "
                                         "(automatic: 0.1 s of frames, at least 2; 0: none)")


@dataclass(frozen=True)
class TriangulateParams:
    """Section ``triangulate``: 3D positions from the cameras (section 5.1).

    Attributes
    ----------
    mode : str
        ``"joint"`` (all cameras at once) or ``"thesis"`` (the three pairs
        averaged, eq. 5.1-5.5). Flat name ``triangulation``.

    Examples
    --------
    >>> TriangulateParams().mode
    'joint'
    """

    mode: str = _p("joint", choices=("joint", "thesis"), cli="--triangulation", legacy="triangulation",
                   help="joint: all cameras at once; thesis: the three pairs averaged (eq. 5.5)")


@dataclass(frozen=True)
class SmoothParams:
    """Section ``smooth``: smoothing of the 3D positions (section 5.2).

    Attributes
    ----------
    method : str
        ``"loess"`` (default), ``"rloess"`` (the thesis' ``smooth(y, 0.1,
        'rloess')``), ``"lowess"``, ``"rlowess"``, ``"moving"`` or ``"none"``
        (:func:`horsemocap.smoothing.smooth`). The default is not the thesis'
        robust variant: on records of a few dozen frames a 0.1 span is 5-7
        points, and the robust iterations of rloess reject good samples near
        the ends of the record (measured over the virtual herd:
        ``benchmarks/README.md``). Flat name ``smoothing_method``.
    span : float
        Span of the smoother as a fraction of the points, in (0, 1]. Flat
        name ``smoothing_span``.

    Examples
    --------
    >>> SmoothParams(method="rloess").span
    0.1
    """

    method: str = _p("loess", choices=("none", "rloess", "loess", "lowess", "rlowess", "moving"),
                     cli="--smoothing", legacy="smoothing_method",
                     help="smoothing of the 3D positions (thesis: rloess)")
    span: float = _p(0.1, kind="number", range=(0, 1), bounds="(]", cli="--span", legacy="smoothing_span",
                     metavar="FRACTION", help="smoothing span as a fraction of the points (the thesis' 0.1)")


@dataclass(frozen=True)
class MotionFrameParams:
    """Section ``motion_frame``: the motion reference frame (section 5.3).

    Attributes
    ----------
    mode : str
        x-motion axis: ``"auto"`` (default: the thesis' eq. 5.6/5.7 over one
        or two periods of ``x_marker`` when a period is given or found, else
        ``"record"``), ``"period"`` (always the thesis'; an error without a
        period) or ``"record"`` (the net displacement of the markers'
        centroid over the whole record, orthogonal to gravity: no period
        needed; the period is then only estimated for the comfort step).
        Flat name ``motion_frame`` (a string).
    x_marker : int
        Marker (0-based) whose net displacement defines x-motion (eq. 5.6).
    period_frames : float or None
        Motion period in frames (the thesis typed 18); ``None`` = estimated.
    n_periods : int or None
        Periods used for the net displacement (eq. 5.6/5.7); ``None`` = two
        if the record holds them, else one.

    Examples
    --------
    >>> MotionFrameParams(mode="period", period_frames=18.0).period_frames
    18.0
    """

    mode: str = _p("auto", choices=("auto", "record", "period"), cli="--motion-frame", legacy="motion_frame",
                   help="x-motion from one or two periods (period, the thesis), from the whole record's net "
                        "displacement (record: no period needed), or auto (period if one is found)")
    x_marker: int = _p(0, kind="int", range=(0, None), cli="--x-marker", legacy="x_marker", metavar="INDEX",
                       help="marker (0-based) whose net displacement defines x-motion (eq. 5.6)")
    period_frames: float | None = _p(None, nullable=True, kind="number", range=(2, None), bounds="(]",
                                     cli="--period", legacy="period_frames", metavar="FRAMES",
                                     help="motion period in frames (the thesis typed 18; automatic: estimated)")
    n_periods: int | None = _p(None, nullable=True, kind="int", range=(1, None), legacy="n_periods",
                               help="periods used for the net displacement (automatic: two if the record "
                                    "holds them, else one)")


@dataclass(frozen=True)
class FitsParams:
    """Sub-section ``rigid_body.fits``: the thesis' chain of fits (section 5.5, chapter 6).

    Attributes
    ----------
    x_degree : int
        Polynomial degree of the x-motion fit (section 5.5.2.1; Appendix A
        9.i, ``fit_type_x``; the thesis' poly1: 1).
    fourier_orders : dict, list or None
        ``{"y": N, "z": N}`` or per marker ``[[Ny, Nz], ...]``; ``None`` = the
        order rule of 5.5.2.2.
    order_rule : str
        ``"significant"``, ``"every_significant"``, ``"adjrsquare"`` or
        ``"thesis"`` (E/2): :func:`horsemocap.fitting.choose_order`.
    trend : bool
        A linear drift term in the y/z fits (not in the thesis: absorbs the
        drift a slightly tilted estimated motion frame gives). Flat name
        ``fourier_trend``.
    angular_method : str
        ``"rotation"`` (from the Fourier fit of the registered orientation),
        ``"lstsq"`` (all markers, no singularity) or ``"thesis"`` (average of
        the versions of eq. 6.3/6.4/6.38/6.39 chosen by ``omega_versions``
        and ``alpha_versions``).
    omega_versions, alpha_versions : list of bool
        Which of the six thesis versions enter the averages (Figures
        8.14-8.20); at least one.
    saddle_method : str
        ``"pose"`` (fit of the saddle path with the fitted orientation),
        ``"direct"`` (fit of the eq. 6.48 path) or ``"thesis"`` (mean of eq.
        6.54/6.55 over the three markers).

    Examples
    --------
    >>> FitsParams(fourier_orders={"y": 3, "z": 2}).fourier_orders["y"]
    3
    """

    x_degree: int = _p(1, kind="int", range=(0, 10), cli="--x-degree", legacy="x_degree", metavar="N",
                       help="degree of the polynomial fitted to the x-motion (Appendix A 9.i, fit_type_x; "
                            "the thesis' poly1: 1)")
    fourier_orders: dict | list | None = _p(None, nullable=True, kind="fourier_orders", cli="--fourier-orders",
                                            legacy="fourier_orders", metavar="Y,Z",
                                            help="Fourier orders of the y and z fits (automatic: the order "
                                                 "rule of 5.5.2.2)")
    order_rule: str = _p("significant", choices=("significant", "every_significant", "adjrsquare", "thesis"),
                         legacy="order_rule", help="the Fourier order rule (5.5.2.2)")
    trend: bool = _p(True, kind="bool", legacy="fourier_trend", help="a linear drift term in the y/z fits")
    angular_method: str = _p("rotation", choices=("rotation", "lstsq", "thesis"), cli="--angular",
                             legacy="angular_method",
                             help="omega/alpha from the fitted orientation, least squares over all markers, "
                                  "or the average of the thesis versions")
    omega_versions: list = _p(factory=lambda: [True] * 6, kind="versions", cli="--omega-versions",
                              legacy="omega_versions", metavar="N,N,...",
                              help="with --angular thesis: which of the six thesis versions of omega (1-6, "
                                   "eq. 6.3/6.4) are averaged, e.g. 1,2,4")
    alpha_versions: list = _p(factory=lambda: [True] * 6, kind="versions", cli="--alpha-versions",
                              legacy="alpha_versions", metavar="N,N,...",
                              help="with --angular thesis: which of the six versions of alpha (1-6, "
                                   "eq. 6.38/6.39) are averaged")
    saddle_method: str = _p("pose", choices=("pose", "direct", "thesis"), cli="--saddle", legacy="saddle_method",
                            help="saddle velocity/acceleration from the fitted pose, the fitted eq. 6.48 path, "
                                 "or the thesis' eq. 6.54/6.55")


@dataclass(frozen=True)
class PoseParams:
    """Sub-section ``rigid_body.pose``: the smoothed pose trajectory (not in the thesis).

    Used with ``rigid_body.kinematics`` ``"pose_spline"`` (:mod:`horsemocap.pose`).

    Attributes
    ----------
    smoothing : str
        Smoothing of the pose trajectory
        (:func:`horsemocap.splines.smoothing_spline`): ``"auto"`` (default:
        ``"gcv"`` with the stride harmonics on a periodic record, a
        fundamental found, ``"adaptive"`` on one without, and, when the
        markers' rigidity residual shows correlated noise (rho, from the
        residual's frame-to-frame differences, at least 0.3 and more than two
        standard errors, about 4 / sqrt(frames), above zero; no events given),
        as real systems' filtered trajectories do, a smoothing chosen under
        it: with four or more markers by leaving each marker out in turn and
        predicting its acceleration from the others' pose (without and with
        the stride's harmonics, the lower left-out error kept), with three,
        without harmonics, by GCV with the noise's AR(1) correlation
        (``correlated_noise_criterion``); otherwise the noise is taken as
        white, :func:`horsemocap.pose.choose_smoothing`; the choice and its
        reason in the progress output and ``analysis.json``), ``"gcv"`` (quintic, one generalised
        cross-validation parameter per component), ``"adaptive"`` (a second
        GCV pass with a penalty weighted by the local roughness: better on
        motions that are calm then ringing), ``"gcv_cubic"`` (SciPy's
        ``make_smoothing_spline``) or ``"none"``. Flat name ``pose_smoothing``.
    partial_frames : bool
        Smooth the pose trajectory also over the frames just beyond the
        analysed ones in which two markers are still triangulated (their pose
        completed by the trajectory's rotation about the two markers' line,
        :func:`horsemocap.pose.partial_pose`), and report only the analysed
        frames: the spline's natural boundary conditions then bias the
        acceleration outside the reported frames. Flat name
        ``pose_partial_frames``.
    harmonics : str
        ``"auto"`` (default) smooths each pose component with a partial
        spline: harmonics of the stride, not penalised, plus a smoothing
        spline of the rest, the number of harmonics (0: none, a record that is
        not periodic) chosen with the smoothing by the same cross-validation;
        the fundamental is estimated from the record
        (:func:`horsemocap.splines.estimate_fundamental`); the rotation's
        harmonics only below the plain spline's cutoff frequency and larger
        than the rotation noise the registration residual and the marker
        geometry predict (a periodic measurement error is not told from
        motion below that size). ``"all"``: every component up to 0.4 of the
        frame rate. ``"none"``: plain smoothing splines
        (:func:`horsemocap.pose.fit_pose_trajectory`, ``harmonics``). Flat
        name ``pose_harmonics``.
    weights : str
        How each frame's pose is registered to its markers: ``"covariance"``
        (default) weights every marker by the inverse of its 3 x 3
        triangulation covariance (depth, less precise than the position
        across the viewing rays, counts less;
        :func:`horsemocap.pose.register_pose` with ``covariance``);
        ``"equal"``: Horn's registration with equal marker weights (the
        thesis' eq. 5.14-5.21). Flat name ``pose_weights``.
    rotation_weights : str
        With ``weights`` ``"covariance"`` and GCV smoothing (``smoothing``
        ``"gcv"``, or ``"auto"`` on a periodic record, or ``"auto"`` under
        correlated noise where ``correlated_noise_criterion`` ``"loo"``
        leaves markers out, four or more): ``"auto"`` (default)
        smooths each rotation component twice, with every frame weighted by
        its predicted variance (robustly) and with equal weights, and keeps
        the fit whose noise model explains its residuals better
        (:func:`horsemocap.pose.fit_pose_trajectory`, ``rotation_weights``);
        ``"equal"``: equal weights. Flat name ``pose_rotation_weights``.
    events : list of float or None
        Known instants (s, on the time axis of ``trajectories.csv``: from the
        first analysed frame) where the acceleration may jump, e.g. hoof
        impacts or an impact's onset from a force plate or an accelerometer:
        each pose component gets an unpenalised ``(t - tau)^2_+`` there
        (:func:`horsemocap.pose.fit_pose_trajectory`, ``events``; ``"auto"``
        smoothing then runs ``"adaptive"``, ``"gcv"`` needs ``harmonics``
        ``"none"``). Not found from the data, and an instant must be known to
        the frame (``benchmarks/README.md``, change points). Default
        ``None``: none. Flat name ``pose_events``.
    correlated_noise_criterion : str
        How ``smoothing`` ``"auto"`` chooses the smoothing when it finds
        correlated noise (:func:`horsemocap.pose.choose_smoothing`'s
        ``"gcv_ar1"``). ``"loo"`` (default): with four or more markers each
        marker is left out in turn and its acceleration predicted from the
        others' pose
        (:func:`horsemocap.pose.marker_cross_validation_per_component`; the
        spline with and without the stride's harmonics, whichever predicts
        the left-out markers better): a marker's noise is not in that pose, so the criterion measures the
        error directly whatever the noise's correlation over frames, as long
        as the markers' noises are independent of each other; with three
        markers (the other two leave a rotation unseen) the correlated-error
        GCV. ``"gcv"``: the correlated-error GCV, which estimates the noise's
        level from the residual of the fit it chooses. ``"reml"``: restricted
        maximum likelihood with the residual's AR(1) correlation
        (``method="reml"`` of :func:`horsemocap.splines.smoothing_spline`),
        which estimates the noise's level together with the signal's.
        ``"risk"``: the unbiased risk with the noise's covariance known, its
        level from the rigidity residual (:func:`horsemocap.pose.pose_noise`
        with the points), its correlation the residual's AR(1)
        (``method="noise"`` with ``noise_correlation``); with three markers,
        whose residual does not see the noise normal to their plane, the
        correlated-error GCV. Not used when the noise is taken as white. How
        each fares on noise draws and on real clusters:
        ``benchmarks/README.md``.

    Examples
    --------
    >>> PoseParams(smoothing="gcv", harmonics="none", events=[2.8]).events
    [2.8]
    """

    smoothing: str = _p("auto", choices=("auto", "adaptive", "gcv", "gcv_cubic", "none"), legacy="pose_smoothing",
                        help="the pose splines' smoothing choice")
    partial_frames: bool = _p(True, kind="bool", legacy="pose_partial_frames",
                              help="also smooth over the neighbouring frames where two markers are seen")
    harmonics: str = _p("auto", choices=("auto", "all", "none"), cli="--pose-harmonics", legacy="pose_harmonics",
                        help="with pose_spline: unpenalised harmonics of the stride in the pose smoothing, their "
                             "number chosen with the smoothing; auto: the rotation keeps a harmonic only below "
                             "the plain spline's cutoff and above the noise; all: every harmonic up to 0.4 of the "
                             "frame rate; none: plain smoothing splines")
    weights: str = _p("covariance", choices=("covariance", "equal"), cli="--pose-weights", legacy="pose_weights",
                      help="with pose_spline: each marker weighted by its triangulation covariance in the pose "
                           "registration, or all alike (Horn, the thesis' eq. 5.14-5.21)")
    rotation_weights: str = _p("auto", choices=("auto", "equal"), cli="--pose-rotation-weights",
                               legacy="pose_rotation_weights",
                               help="with pose_spline and covariance weights: the rotation smoothed with each "
                                    "frame weighted by its predicted variance where that explains the residuals "
                                    "better (auto), or every frame alike (equal)")
    events: list | None = _p(None, nullable=True, kind="events", cli="--pose-events", legacy="pose_events",
                             metavar="SECONDS",
                             help="with pose_spline: known instants (s, the time_s of trajectories.csv) where "
                                  "the acceleration may jump, such as impacts timed by a force plate; 2.8,3.35 "
                                  "(or the option repeated; not found from the data)")
    correlated_noise_criterion: str = _p("loo", choices=("loo", "gcv", "reml", "risk"),
                                         help="with pose_spline and auto smoothing, under correlated noise: the "
                                              "smoothing chosen by leaving each marker out (loo, four or more "
                                              "markers), the correlated-error GCV (gcv), REML with the AR(1) "
                                              "correlation (reml) or the unbiased risk with the rigidity "
                                              "residual's noise (risk)")


@dataclass(frozen=True)
class RigidBodyParams:
    """Section ``rigid_body``: registration, kinematics and the hidden saddle marker (5.4-5.5, 6).

    Attributes
    ----------
    kinematics : str
        What the rigid-body step passes on (omega, alpha, the markers' and
        the saddle's velocity and acceleration): ``"pose_spline"`` (default,
        not in the thesis: every frame's pose registered from all visible
        markers, the centroid and rotation vector smoothed by quintic splines
        whose smoothing is chosen by generalised cross-validation, analytic
        derivatives; no period and no eq. 6.35 singularity;
        :mod:`horsemocap.pose`, chosen within by ``pose``) or ``"fits"`` (the
        thesis' chain of section 5.5 and chapter 6, chosen within by
        ``fits``). Both are computed when the record allows; a record that is
        not periodic (a lift, a set-down, ringing) has only ``"pose_spline"``.
        The default is the better of the two on the virtual herd and the
        harder sessions, median and worst, with and without detection noise
        (``benchmarks/README.md``).
    saddle_marker : int or None
        Which static-shot point (0-based, in the static shot's order:
        ascending image ``u`` in the reference camera) is the saddle marker
        (Appendix A 12a); ``None`` = the point left over by the matching of
        the static shot to the ride
        (:func:`horsemocap.rigid.match_static_markers`).
    marker_model : str
        The markers' shape the pose registration uses: ``"auto"`` (default:
        the static shot's, or the moving frames' mean shape when the static
        shot's is off by more than a frame's noise,
        :func:`horsemocap.rigid.choose_marker_model`) or ``"static"`` (always
        the static shot's, as the thesis). The thesis' chain of fits
        (``kinematics="fits"``, eq. 6.3-6.55) always uses the static shot.
    fits : FitsParams
        The thesis' chain of fits.
    pose : PoseParams
        The smoothed pose trajectory.

    Examples
    --------
    >>> RigidBodyParams(kinematics="fits").fits.angular_method
    'rotation'
    >>> RigidBodyParams(marker_model="static").marker_model
    'static'
    """

    kinematics: str = _p("pose_spline", choices=("pose_spline", "fits"), cli="--kinematics", legacy="kinematics",
                         help="pose_spline: the smoothed pose trajectory of all markers (no period, no eq. 6.35 "
                              "singularity); fits: the thesis' chain of fits")
    saddle_marker: int | None = _p(None, nullable=True, kind="int", range=(0, None), cli="--saddle-marker",
                                   legacy="saddle_marker", metavar="INDEX",
                                   help="which static-shot point (0-based, left to right in the reference "
                                        "camera) is the saddle marker (Appendix A 12a; automatic: the one the "
                                        "ride's markers leave over)")
    marker_model: str = _p("auto", choices=("auto", "static"),
                           help="the markers' shape of the pose registration: auto: the static shot's unless it "
                                "is off by more than a frame's noise (then the moving frames' mean shape); static: "
                                "always the static shot's (the thesis' chain of fits always uses it)")
    fits: FitsParams = _section(FitsParams)
    pose: PoseParams = _section(PoseParams)


@dataclass(frozen=True)
class ComfortParams:
    """Section ``comfort``: the whole-body vibration indicators (chapter 7).

    Attributes
    ----------
    weighting_mode : str
        ``"iso"`` (each harmonic weighted at its own frequency) or
        ``"thesis"`` (one scalar weight W per record, section 7.2).

    Examples
    --------
    >>> ComfortParams().weighting_mode
    'iso'
    """

    weighting_mode: str = _p("iso", choices=("iso", "thesis"), cli="--weighting", legacy="weighting_mode",
                             help="iso: each harmonic weighted at its frequency; thesis: one scalar W")


PRESETS: dict[str, dict] = {
    "default": {},
    "thesis": {
        "rig": {"mode": "pairwise"},              # 3.3: stereo pairs with the left camera (Table 8.4)
        "detect": {"method": "thesis"},           # chapter 4: each camera alone, threshold + filters
        "triangulate": {"mode": "thesis"},        # eq. 5.1-5.5: the three pairs averaged
        "smooth": {"method": "rloess",            # 5.2.2: MATLAB smooth(y, 0.1, 'rloess')
                   "span": 0.1},
        "motion_frame": {"mode": "period"},       # eq. 5.6/5.7: net displacement over whole periods
        "rigid_body": {
            "kinematics": "fits",                 # 5.5 and chapter 6: the chain of fits
            "marker_model": "static",             # 6.3: the static shot's markers are the body's shape
            "fits": {
                "x_degree": 1,                    # 5.5.2.1: x-motion a line in time
                "order_rule": "thesis",           # 5.5.2.2: N = E/2, the thesis' suggested order
                "trend": False,                   # the thesis' Fourier series have no drift term
                "angular_method": "thesis",       # eq. 6.3/6.4/6.38/6.39: the versions averaged
                "omega_versions": [True] * 6,
                "alpha_versions": [True] * 6,
                "saddle_method": "thesis",        # eq. 6.54/6.55 averaged over the three markers
            },
            "pose": {"weights": "equal"},         # eq. 5.14-5.21: every marker weighted alike
        },
        "comfort": {"weighting_mode": "thesis"},  # 7.2: one scalar weight W per record
    },
}
"""Named sets of choices, in the nested form: ``"default"`` (the automatic
pipeline) and ``"thesis"`` (the thesis' own chain end to end, each value with
its section). ``--preset thesis`` on the command line, ``{"preset":
"thesis"}`` in a parameter file or ``results_for(params={"preset":
"thesis"})`` in a notebook; values given explicitly override the preset's.
The pairwise calibration only applies to sessions calibrated from
checkerboard views (the herd sessions carry a rig file)."""


STEP_SECTIONS = {"sync": "sync", "rig": "rig", "plumb": "stills", "static": "stills", "detect": "detect",
                 "triangulate": "triangulate", "smooth": "smooth", "motion_frame": "motion_frame",
                 "rigid_body": "rigid_body", "comfort": "comfort"}
"""The section of :class:`AnalysisParams` each step of the pipeline is given (:meth:`AnalysisParams.section`)."""


@dataclass(frozen=True)
class AnalysisParams:
    """Every choice of the analysis (thesis Appendix A prompts), one section per step.

    Build it with :meth:`from_dict` (nested sections, the flat names of
    earlier files, or a mix), change it with :meth:`updated` or
    :meth:`with_path`; every way validates (:meth:`validate`).

    Attributes
    ----------
    preset : str or None
        The named set of choices (:data:`PRESETS`) these parameters started
        from, recorded so ``analysis.json`` says so; ``None`` = the defaults.
        Values given explicitly override the preset's.
    sync : SyncParams
    rig : RigParams
    stills : StillsParams
        Given to the plumb and the static step.
    detect : DetectParams
    triangulate : TriangulateParams
    smooth : SmoothParams
    motion_frame : MotionFrameParams
    rigid_body : RigidBodyParams
    comfort : ComfortParams

    Examples
    --------
    >>> p = AnalysisParams.from_dict({"preset": "thesis", "smooth": {"method": "loess"}})
    >>> p.triangulate.mode, p.smooth.method, p.section("plumb") is p.stills
    ('thesis', 'loess', True)
    >>> p.to_dict()["rigid_body"]["fits"]["angular_method"]
    'thesis'
    """

    preset: str | None = _p(None, nullable=True, choices=tuple(PRESETS), cli="--preset",
                            help="a named set of choices; thesis: the thesis' own chain end to end (pairwise "
                                 "calibration, per-camera detection, pairs triangulation, rloess 0.1, the E/2 "
                                 "order, the averaged versions, one scalar weight); the options below still "
                                 "override it")
    sync: SyncParams = _section(SyncParams)
    rig: RigParams = _section(RigParams)
    stills: StillsParams = _section(StillsParams)
    detect: DetectParams = _section(DetectParams)
    triangulate: TriangulateParams = _section(TriangulateParams)
    smooth: SmoothParams = _section(SmoothParams)
    motion_frame: MotionFrameParams = _section(MotionFrameParams)
    rigid_body: RigidBodyParams = _section(RigidBodyParams)
    comfort: ComfortParams = _section(ComfortParams)

    def to_dict(self) -> dict:
        """The nested form, JSON-able: what ``analysis.json`` records and the results store's keys use."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict, source: str = "analysis parameters") -> "AnalysisParams":
        """Build from a dict of parameters, validated; errors name ``source`` and the parameter.

        ``data`` is the nested form (``{"smooth": {"span": 0.2}}``), the flat
        names of the files written before the sections
        (``{"smoothing_span": 0.2}``, :func:`legacy_names`) or a mix; a
        ``"preset"`` (:data:`PRESETS`) fills in what is not given. Unknown
        names are refused with the closest known one; a flat name and its
        field given with different values are refused naming both.
        """
        return cls.from_layers(data, source=source)

    @classmethod
    def from_layers(cls, *layers: dict | None, source: str = "analysis parameters") -> "AnalysisParams":
        """Build from dicts of parameters, each overriding the ones before it field by field, validated.

        Each layer is what :meth:`from_dict` takes (``None`` = nothing). A
        preset named in any layer (the last one naming it wins) sits under
        every value given, e.g. ``from_layers(session.analysis, choices)``
        keeps the session's values and applies the choices and the preset
        over the defaults.
        """
        values, given_as = {}, {}
        for layer in layers:
            if layer is None:
                continue
            flat, named = _normalize(layer, source)
            for path in flat:
                given_as.pop(path, None)
            values.update(flat)
            given_as.update(named)
        preset = values.get("preset")
        if preset is not None:
            _check_preset(preset, source)
            values = {**preset_values(preset), **values}
        return _make(values, given_as, source)

    def with_preset(self, name: str) -> "AnalysisParams":
        """These parameters with the values of preset ``name`` (:data:`PRESETS`) put over them.

        Options given after (e.g. on the command line, by :meth:`updated`)
        still override the preset's values.
        """
        _check_preset(name, "preset")
        return _make({**_leaf_values(self), **preset_values(name), "preset": name}, {}, f"preset '{name}'")

    def updated(self, changes: dict | None = None, /, *, source: str = "updated parameters",
                **more) -> "AnalysisParams":
        """These parameters with some changed, validated.

        ``changes`` (and keyword arguments) name a field by its dotted name
        (``{"smooth.span": 0.2}``), its flat name (``smoothing_span=0.2``),
        a value inside a dict field (``"detect.cameras.left.threshold"`` or
        ``"detection.left.threshold"``: the dicts on the way are created) or
        a whole section (``{"smooth": {"span": 0.2}}``: the fields it names).
        ``None`` sets a field to ``None`` (automatic where that is allowed).
        """
        values, given_as = _leaf_values(self), dict(_given_names(self))
        for name, value in {**(changes or {}), **more}.items():
            _assign_path(values, given_as, name, value, source)
        return _make(values, given_as, source)

    def with_path(self, path: str, value, source: str | None = None) -> "AnalysisParams":
        """One value changed by its dotted path, new or flat (``--set NAME=VALUE``); see :meth:`updated`.

        ``with_path("detection.left.threshold", 140)`` is
        ``with_path("detect.cameras.left.threshold", 140)``;
        ``"stills.static.left.threshold"`` names a still's threshold.
        """
        return self.updated({path: value}, source=source or "updated parameters")

    def value(self, path: str, default=None):
        """The value at a dotted path, new or flat (``"detection.left.threshold"``); ``default`` if absent.

        A path into a dict field that does not hold the key gives ``default``.
        """
        field_path, rest, _ = _resolve(path.split("."), None, "parameter")
        node = _value_at(self, field_path.split("."))
        for key in rest:
            if not isinstance(node, dict) or key not in node:
                return default
            node = node[key]
        return node

    def section(self, step: str):
        """The section the pipeline step ``step`` is given (:data:`STEP_SECTIONS`; plumb and static: ``stills``)."""
        if step not in STEP_SECTIONS:
            raise ParamsError(f"no step '{step}': expected one of {', '.join(STEP_SECTIONS)}")
        return getattr(self, STEP_SECTIONS[step])

    def validate(self, source: str = "analysis parameters") -> None:
        """Check every field's type and range; :class:`ParamsError` names the field.

        One path for every field, driven by its metadata (choices, range,
        kind, nullable): the message says the dotted parameter (and the flat
        name it was given by), the expected type and range and the value
        given, e.g. ``analysis.json: parameter 'smooth.span' (given as
        'smoothing_span'): expected a number in (0, 1], got "wide"``. Numbers
        must be finite, everywhere. Checks against the session (cameras,
        marker count) are :meth:`check_session`'s.
        """
        for path, cls in _section_paths().items():
            node = _value_at(self, path.split("."))
            if not isinstance(node, cls):
                raise ParamsError(f"{source}: parameter '{path}': expected the section's parameters "
                                  f"({cls.__name__}), got {_show(node)}")
        for f in params_fields():
            try:
                _check_value(f, _value_at(self, f.path.split(".")))
            except _Invalid as bad:
                raise _error(source, f.path, bad.where, _given_names(self), bad.text) from None
        _check_pose_events(self, source)

    def check_session(self, session, source: str = "analysis parameters") -> None:
        """Check the parameters that refer to the session: cameras and markers.

        Raises :class:`ParamsError` naming the parameter, e.g. sync offsets
        for a camera the session does not have, or ``motion_frame.x_marker``
        beyond the markers' count.
        """
        cams = list(session.cameras)

        def bad(path, text, where=()):
            return _error(source, path, where, _given_names(self), text)

        offsets = self.sync.offsets
        if offsets is not None:
            unknown = [c for c in offsets if c not in cams]
            missing = [c for c in cams if c not in offsets]
            if unknown or missing:
                what = f"no camera '{unknown[0]}'" if unknown else f"no offset for camera '{missing[0]}'"
                raise bad("sync.offsets", f"expected one frame index for each camera {cams}, "
                                          f"got {_show(offsets)} ({what})")
        for cam in self.detect.cameras:
            if cam != "all" and cam not in cams:
                raise bad("detect.cameras", f"expected 'all' or a camera of {cams}, got '{cam}'")
        _check_first_frames(self.detect.cameras, session, offsets, bad)
        for cam in self.rig.exclude:
            if cam not in cams:
                raise bad("rig.exclude", f"expected a camera of {cams}, got '{cam}'")
        _check_excluded_views(self.rig.exclude, session, bad)
        for kind in ("plumb", "static"):
            _check_still_cameras(getattr(self.stills, kind), kind, session, bad)
        n = session.marker_count
        saddle = self.rigid_body.saddle_marker
        if saddle is not None and saddle > n:
            raise bad("rigid_body.saddle_marker", f"expected a static-shot point 0..{n} (the static shot has "
                                                  f"{n + 1}), got {saddle}")
        if self.motion_frame.x_marker >= n:
            raise bad("motion_frame.x_marker", f"expected a marker index 0..{n - 1} (the session has {n} "
                                               f"markers), got {self.motion_frame.x_marker}")
        orders = self.rigid_body.fits.fourier_orders
        if isinstance(orders, (list, tuple)) and len(orders) != n:
            raise bad("rigid_body.fits.fourier_orders", f"expected {n} pairs [Ny, Nz] (one per marker), "
                                                        f"got {len(orders)}")


def _check_first_frames(per_cam: dict, session, offsets, bad) -> None:
    """``detect.cameras.<cam>.first_frame`` within the session's synchronised frames (counted only when given)."""
    given = {cam: v["first_frame"] for cam, v in per_cam.items()
             if isinstance(v, dict) and v.get("first_frame") is not None}
    if not given:
        return
    try:
        counts = {cam: len(session.source(cam)) for cam in session.cameras}
    except Exception:  # noqa: BLE001 - a source that cannot be read: the step that reads it says so
        return
    n = min(counts[c] - (offsets or {}).get(c, 0) for c in counts)
    for cam, first in given.items():
        if first >= n:
            raise bad("detect.cameras", f"expected a frame index 0..{n - 1} (the session's "
                                        f"{'synchronised ' if offsets else ''}frames), got {first}",
                      (cam, "first_frame"))


def _check_still_cameras(per_cam: dict, kind: str, session, bad) -> None:
    """``stills.<kind>`` against the session: known cameras, labels for all or none, their count."""
    cams = list(session.cameras)
    path = f"stills.{kind}"
    for cam in per_cam:
        if cam != "all" and cam not in cams:
            raise bad(path, f"expected 'all' or a camera of {cams}, got '{cam}'")
    count = 2 if kind == "plumb" else session.marker_count + 1
    labels = {c: {**per_cam.get("all", {}), **per_cam.get(c, {})}.get("labels") for c in cams}
    labelled = [c for c in cams if labels[c]]
    if labelled and len(labelled) != len(cams):
        missing = [c for c in cams if c not in labelled]
        raise bad(path, f"labels given for {labelled} but not for {missing}; labels are taken as they are, "
                        "so every camera needs them")
    for cam in cams:
        if labels[cam] is not None and len(labels[cam]) != count:
            raise bad(path, f"expected {count} labels for camera '{cam}' (the {kind} still's markers), "
                            f"got {len(labels[cam])}")


# ---------------------------------------------------------------------------
# the fields, their dotted and flat names
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ParamField:
    """One leaf field of :class:`AnalysisParams`: its dotted name, default and metadata.

    Attributes
    ----------
    path : str
        Dotted name, e.g. ``"smooth.span"``.
    legacy : str or None
        Its flat name in the files written before the sections
        (``"smoothing_span"``).
    default
        The default value (a fresh one for lists and dicts).
    help, choices, range, bounds, kind, nullable, cli, metavar, cli_values
        As given to the field (:func:`_p`): what it is, what is valid, its
        command-line flag and the flags setting one value inside it.
    """

    path: str
    legacy: str | None
    default: object
    help: str
    choices: tuple | None
    range: tuple | None
    bounds: str
    kind: str | None
    nullable: bool
    cli: str | None
    metavar: str | None
    cli_values: tuple

    @property
    def section(self) -> str:
        """The top-level section holding it (``"rigid_body"`` for ``"rigid_body.fits.x_degree"``)."""
        return self.path.split(".")[0]


@lru_cache(maxsize=None)
def params_fields() -> tuple[ParamField, ...]:
    """Every leaf field of :class:`AnalysisParams`, in order, with its dotted name and metadata.

    The command line's options and the documentation are generated from it.

    Examples
    --------
    >>> f = next(f for f in params_fields() if f.path == "smooth.span")
    >>> f.legacy, f.cli, f.default, f.range
    ('smoothing_span', '--span', 0.1, (0, 1))
    """
    def walk(cls, prefix):
        for f in fields(cls):
            if f.metadata.get("section"):
                yield from walk(f.default_factory, f"{prefix}{f.name}.")
                continue
            m = f.metadata
            default = f.default_factory() if f.default is MISSING else f.default
            yield ParamField(f"{prefix}{f.name}", m["legacy"], default, m["help"], m["choices"], m["range"],
                             m["bounds"], m["kind"], m["nullable"], m["cli"], m["metavar"], m["cli_values"])

    return tuple(walk(AnalysisParams, ""))


def legacy_names() -> dict[str, str]:
    """Flat name of the files written before the sections -> dotted field (``"smoothing_span": "smooth.span"``).

    ``"stills"`` is not among them: its flat form is the ``stills`` section's
    nested form.
    """
    return dict(_legacy_paths())


def section_title(path: str) -> str:
    """What a (sub-)section holds, in words: the first line of its docstring.

    Examples
    --------
    >>> section_title("smooth")
    'smoothing of the 3D positions (section 5.2)'
    """
    cls = _section_paths()[path]
    first = (cls.__doc__ or path).strip().splitlines()[0]
    return first.split(": ", 1)[-1].rstrip(".")


@lru_cache(maxsize=None)
def _legacy_paths() -> dict[str, str]:
    return {f.legacy: f.path for f in params_fields() if f.legacy}


@lru_cache(maxsize=None)
def _section_paths() -> dict[str, type]:
    """Dotted name of every section and sub-section -> its class."""
    def walk(cls, prefix):
        for f in fields(cls):
            if f.metadata.get("section"):
                yield f"{prefix}{f.name}", f.default_factory
                yield from walk(f.default_factory, f"{prefix}{f.name}.")

    return dict(walk(AnalysisParams, ""))


def _value_at(node, keys):
    for key in keys:
        node = getattr(node, key)
    return node


def _leaf_values(params: AnalysisParams) -> dict:
    """Dotted name -> a copy of the value, for every leaf field."""
    return {f.path: copy.deepcopy(_value_at(params, f.path.split("."))) for f in params_fields()}


def _build(values: dict, cls=AnalysisParams, prefix: str = ""):
    """The (sub-)section ``cls`` from dotted name -> value (absent fields at their defaults), not validated."""
    kwargs = {}
    for f in fields(cls):
        path = f"{prefix}{f.name}"
        if f.metadata.get("section"):
            kwargs[f.name] = _build(values, f.default_factory, path + ".")
        elif path in values:
            kwargs[f.name] = values[path]
    return cls(**kwargs)


def _given_names(params: AnalysisParams) -> dict:
    """Dotted field -> the flat name it was given by, for the messages (kept on the object by :func:`_make`)."""
    return params.__dict__.get("_given_as", {})


def _make(values: dict, given_as: dict, source: str) -> AnalysisParams:
    """Build from dotted name -> value, remember the flat names given, and validate."""
    params = _build(copy.deepcopy(values))
    object.__setattr__(params, "_given_as", dict(given_as))
    params.validate(source)
    return params


# ---------------------------------------------------------------------------
# names given -> dotted fields
# ---------------------------------------------------------------------------

def _resolve(keys: list, value, source: str) -> tuple[str, list, str | None]:
    """A name given (split at its dots) -> (dotted field or section, the keys inside its value, flat name used).

    ``["detection", "left", "threshold"]`` -> ``("detect.cameras", ["left", "threshold"], "detection")``;
    ``["motion_frame"]`` with a string is the flat name of ``motion_frame.mode``, with an object the section.
    """
    if not all(keys):
        raise ParamsError(f"{source}: expected a parameter name or a dotted path such as "
                          f"'detect.cameras.left.threshold', got '{'.'.join(keys)}'")
    legacy, sections = _legacy_paths(), _section_paths()
    head = keys[0]
    if head in legacy and not (head in sections and (len(keys) > 1 or isinstance(value, dict))):
        return legacy[head], keys[1:], head
    cls, path = AnalysisParams, []
    for i, key in enumerate(keys):
        by_name = {f.name: f for f in fields(cls)}
        if key not in by_name:
            known = list(by_name) + (list(legacy) if cls is AnalysisParams else [])
            close = difflib.get_close_matches(key, known, n=1)
            hint = f"; did you mean '{'.'.join([*path, close[0]])}'?" if close else ""
            raise ParamsError(f"{source}: unknown parameter '{'.'.join([*path, key])}'{hint}")
        path.append(key)
        if not by_name[key].metadata.get("section"):
            return ".".join(path), keys[i + 1:], None
        cls = by_name[key].default_factory
    return ".".join(path), [], None


def _normalize(data, source: str) -> tuple[dict, dict]:
    """One dict of parameters (nested, flat or mixed) -> (dotted field -> value, dotted field -> flat name used)."""
    if not isinstance(data, dict):
        raise ParamsError(f"{source}: expected an object of parameters, got {_show(data)}")
    values, given_as, named = {}, {}, {}

    def take(keys, value):
        if any("." in k for k in keys):
            raise ParamsError(f"{source}: unknown parameter '{'.'.join(keys)}' (a parameter object nests its "
                              "sections: {\"smooth\": {\"span\": 0.2}})")
        path, _, legacy = _resolve(keys, value, source)
        if path in _section_paths():
            for key, inner in _section_items(path, value, source):
                take([*path.split("."), key], inner)
            return
        used = legacy or path
        if path in values and values[path] != value:
            raise ParamsError(f"{source}: parameter '{path}' given twice with different values: as "
                              f"'{named[path]}' ({_show(values[path])}) and as '{used}' ({_show(value)})")
        values[path], named[path] = value, used
        if legacy:
            given_as[path] = legacy

    for key, value in data.items():
        take([str(key)], value)
    return values, given_as


def _assign_path(values: dict, given_as: dict, name: str, value, source: str) -> None:
    """Set one value by its dotted name (new or flat) in dotted field -> value, creating dicts on the way."""
    keys = name.split(".")
    path, rest, legacy = _resolve(keys, value, source)
    if path in _section_paths():
        for key, inner in _section_items(path, value, source):
            _assign_path(values, given_as, f"{path}.{key}", inner, source)
        return
    values[path] = _set_inside(values.get(path), path, rest, value, source) if rest else value
    if legacy:
        given_as[path] = legacy
    else:
        given_as.pop(path, None)


def _section_items(path: str, value, source: str):
    """The (name, value) pairs given for section ``path``; an object is expected."""
    if not isinstance(value, dict):
        names = ", ".join(f.name for f in fields(_section_paths()[path]))
        raise ParamsError(f"{source}: parameter '{path}': expected an object of its parameters ({names}), "
                          f"got {_show(value)}")
    return value.items()


def _set_inside(whole, path: str, keys: list, value, source: str):
    """A copy of the dict field ``whole`` (``None``: empty) with ``value`` at ``keys``, dicts created on the way."""
    whole = {} if whole is None else copy.deepcopy(whole)
    node = whole
    for depth, key in enumerate(keys):
        if not isinstance(node, dict):
            raise ParamsError(f"{source}: parameter '{'.'.join([path, *keys[:depth]])}' is not an object of "
                              "named values")
        if depth == len(keys) - 1:
            node[key] = value
        else:
            if node.get(key) is None:
                node[key] = {}
            node = node[key]
    return whole


def _check_preset(name, source: str) -> None:
    if not isinstance(name, str) or name not in PRESETS:
        raise ParamsError(f"{source}: parameter 'preset': expected " + " or ".join(f'"{k}"' for k in PRESETS)
                          + f" or null, got {_show(name)}")


def preset_values(name: str) -> dict:
    """Dotted field -> value of every field preset ``name`` (:data:`PRESETS`) sets.

    Examples
    --------
    >>> preset_values("thesis")["triangulate.mode"]
    'thesis'
    """
    _check_preset(name, "preset")
    return _normalize(PRESETS[name], f"preset '{name}'")[0]


# ---------------------------------------------------------------------------
# the one validation path
# ---------------------------------------------------------------------------

class _Invalid(Exception):
    """A value that does not fit its field: what was expected (or a whole message) and where inside it."""

    def __init__(self, expected: str, value=None, where: tuple = (), message: str | None = None):
        super().__init__(expected)
        self.where = tuple(str(w) for w in where)
        self.text = message or f"expected {expected}, got {_show(value)}"


def _error(source: str, path: str, where, given_as: dict, text: str) -> ParamsError:
    """``source: parameter 'a.b[.inside]' (given as 'flat[.inside]'): text``."""
    where = tuple(str(w) for w in where)
    name = ".".join((path, *where))
    legacy = given_as.get(path)
    given = f" (given as '{'.'.join((legacy, *where))}')" if legacy else ""
    return ParamsError(f"{source}: parameter '{name}'{given}: {text}")


def _check_value(f: ParamField, value) -> None:
    """Raise :class:`_Invalid` unless ``value`` fits field ``f`` (its choices, range, kind, nullable)."""
    if value is None:
        if f.nullable:
            return
        raise _Invalid(_expected(f), value)
    if f.choices is not None:
        if not isinstance(value, str) or value not in f.choices:
            raise _Invalid(_expected(f), value)
        return
    if f.kind not in ("bool", "int", "number"):   # those say their type and range for NaN and infinity
        where = _non_finite(value)
        if where is not None:
            raise _Invalid("a finite number", _value_inside(value, where), where)
    _KIND_CHECKS[f.kind](value, f)


def _expected(f: ParamField) -> str:
    """What field ``f`` takes, in words: ``"joint" or "thesis"``, ``a number in (0, 1]``, ``... or null``."""
    if f.choices is not None:
        text = " or ".join(f'"{c}"' for c in f.choices)
    elif f.kind == "bool":
        text = "true or false"
    elif f.kind in ("int", "number"):
        text = _range_text(f)
    else:
        text = _KIND_EXPECTED[f.kind]
    return text + (" or null" if f.nullable else "")


def _range_text(f: ParamField) -> str:
    noun = "an integer" if f.kind == "int" else "a number"
    lo, hi = f.range or (None, None)
    if lo is not None and hi is not None:
        return f"{noun} in {lo}..{hi}" if f.kind == "int" else f"{noun} in {f.bounds[0]}{lo}, {hi}{f.bounds[1]}"
    if lo is not None:
        return f"{noun} {'>' if f.bounds[0] == '(' else '>='} {lo}"
    if hi is not None:
        return f"{noun} {'<' if f.bounds[1] == ')' else '<='} {hi}"
    return noun


def _in_range(v, f: ParamField) -> bool:
    lo, hi = f.range or (None, None)
    if lo is not None and (v < lo or (f.bounds[0] == "(" and v == lo)):
        return False
    return not (hi is not None and (v > hi or (f.bounds[1] == ")" and v == hi)))


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _non_finite(value, where=()):
    """Where (dict keys) inside ``value`` a float is NaN or infinite, a list naming itself; ``None`` if nowhere."""
    if isinstance(value, float) and not math.isfinite(value):
        return where
    if isinstance(value, dict):
        for key, inner in value.items():
            found = _non_finite(inner, (*where, key))
            if found is not None:
                return found
    elif isinstance(value, (list, tuple)) and any(_non_finite(inner) is not None for inner in value):
        return where
    return None


def _value_inside(value, where):
    for key in where:
        value = value[key]
    return value


def _check_bool(value, f):
    if not isinstance(value, bool):
        raise _Invalid(_expected(f), value)


def _check_int(value, f):
    if not _is_int(value) or not _in_range(value, f):
        raise _Invalid(_expected(f), value)


def _check_number(value, f):
    if not _is_number(value) or not _in_range(value, f):
        raise _Invalid(_expected(f), value)


def _check_offsets(value, f):
    if not isinstance(value, dict) or not value:
        raise _Invalid(_expected(f), value)
    for cam, frame in value.items():
        if not (_is_int(frame) or (isinstance(frame, float) and math.isfinite(frame))) or frame < 0:
            raise _Invalid(f"a frame index (>= 0; a fraction for free-running cameras) for camera '{cam}'", frame)


def _check_excluded_views(exclude: dict, session, bad) -> None:
    """Every view left out of the calibration is one of its camera's checkerboard views (a key or a file name):
    said before any view is detected."""
    folders = getattr(session, "calibration_images", None) or {}
    if not exclude or not folders:
        return
    # imported here: the board module loads OpenCV, which a session without views left out need not wait for
    from .calibration.board import CalibrationError, exclusion_keys

    try:
        exclusion_keys(folders, exclude)
    except CalibrationError as exc:
        raise bad("rig.exclude", str(exc)) from None


def _check_exclude(value, f):
    if not isinstance(value, dict):
        raise _Invalid(_expected(f), value)
    for cam, views in value.items():
        if not isinstance(views, (list, tuple)) or not all(isinstance(x, str) and x for x in views):
            raise _Invalid(f"a list of view file names for camera '{cam}'", views)


def _check_detection(value, f):
    if not isinstance(value, dict):
        raise _Invalid(_expected(f), value)
    # imported here: horsemocap.detection loads OpenCV and the detectors (0.2 s), which `horsemocap --help`
    # and the command line's early board detection should not wait for; only a given detection dict needs it
    from .detection import DetectionParams

    for cam, given in value.items():
        if not isinstance(given, dict):
            raise _Invalid(f"an object of detector parameters for '{cam}'", given, (cam,))
        first = given.get("first_frame")
        if first is not None and (not _is_int(first) or first < 0):
            raise _Invalid("a frame index (integer >= 0) or null", first, (cam, "first_frame"))
        for name, (expected, ok) in _DETECTOR_RANGES.items():
            if given.get(name) is not None and not ok(given[name]):
                raise _Invalid(expected, given[name], (cam, name))
        try:
            DetectionParams.from_dict(given)
        except (ValueError, TypeError, OverflowError) as exc:
            raise _Invalid("", where=(cam,), message=str(exc)) from None


# detector parameters whose range DetectionParams leaves open: what they take, and the test
_DETECTOR_RANGES = {
    "threshold": ("a gray level (integer 0..254) or null", lambda v: not isinstance(v, bool)),
    "area_min": ("an area in pixels (a number >= 0) or null", lambda v: _is_number(v) and v >= 0),
    "area_max": ("an area in pixels (a number > 0) or null", lambda v: _is_number(v) and v > 0),
    "distance_tolerance": ("a fraction (a number > 0) or null", lambda v: _is_number(v) and v > 0),
    "min_circularity": ("a circularity (a number in [0, 1]) or null", lambda v: _is_number(v) and 0 <= v <= 1),
    "window_predict": ("true or false", lambda v: isinstance(v, bool)),
}


def _check_stills(value, f):
    if not isinstance(value, dict):
        raise _Invalid(_expected(f), value)
    for cam, given in value.items():
        if not isinstance(given, dict) or any(k not in ("threshold", "labels") for k in given):
            raise _Invalid('{"threshold": l, "labels": [...]}', given, (cam,))
        threshold, labels = given.get("threshold"), given.get("labels")
        if threshold is not None and (not _is_int(threshold) or not 0 <= threshold <= 254):
            raise _Invalid("a gray level (integer 0..254)", threshold, (cam, "threshold"))
        if labels is not None and (not isinstance(labels, (list, tuple)) or not labels
                                   or not all(_is_int(x) and x >= 1 for x in labels)
                                   or len(set(labels)) != len(labels)):
            raise _Invalid("distinct region labels (integers >= 1)", labels, (cam, "labels"))
        if labels is not None and threshold is None:
            raise _Invalid("a threshold with the labels (labels name the regions of one binary image)",
                           given, (cam,))


def _check_fourier_orders(value, f):
    def order(v):
        return _is_int(v) and 1 <= v <= 40

    if isinstance(value, dict):
        ok = set(value) == {"y", "z"} and all(order(v) for v in value.values())
    elif isinstance(value, (list, tuple)):
        ok = bool(value) and all(isinstance(p, (list, tuple)) and len(p) == 2 and all(order(v) for v in p)
                                 for p in value)
    else:
        ok = False
    if not ok:
        raise _Invalid(_expected(f), value)


def _check_versions(value, f):
    if not isinstance(value, (list, tuple)) or len(value) != 6 or not all(isinstance(b, bool) for b in value) \
            or not any(value):
        raise _Invalid(_expected(f), value)


def _check_events(value, f):
    if not isinstance(value, (list, tuple)) or not all(_is_number(e) for e in value) \
            or len(set(value)) != len(value):
        raise _Invalid(_expected(f), value)


_KIND_CHECKS = {"bool": _check_bool, "int": _check_int, "number": _check_number, "offsets": _check_offsets,
                "exclude": _check_exclude, "detection": _check_detection, "stills": _check_stills,
                "fourier_orders": _check_fourier_orders, "versions": _check_versions, "events": _check_events}
"""Field kind -> its check (raises :class:`_Invalid`); fields with ``choices`` need none."""

_KIND_EXPECTED = {
    "offsets": "an object {camera: frame index}",
    "exclude": "an object {camera: [view file names]}",
    "detection": 'an object {camera or "all": {detector parameter: value}}',
    "stills": 'an object {camera or "all": {"threshold": l, "labels": [...]}}',
    "fourier_orders": '{"y": N, "z": N} or one [Ny, Nz] pair per marker (integers 1..40)',
    "versions": "a list of six booleans, at least one true",
    "events": "a list of distinct times in seconds (the time_s of trajectories.csv), []",
}


def _check_pose_events(params: AnalysisParams, source: str) -> None:
    """``rigid_body.pose.events``: only with a pose smoothing that fits change points."""
    rigid = params.rigid_body
    events, pose = rigid.pose.events, rigid.pose
    if not events:
        return
    why = None
    if rigid.kinematics != "pose_spline":
        why = (f'null with rigid_body.kinematics "{rigid.kinematics}" (change points are a pose_spline option; '
               "the thesis chain's fits have none)")
    elif pose.smoothing in ("gcv_cubic", "none"):
        why = (f'null with rigid_body.pose.smoothing "{pose.smoothing}" (change points are fitted by the '
               'quintic "auto", "adaptive" or "gcv" smoothing)')
    elif pose.smoothing == "gcv" and pose.harmonics != "none":
        why = (f'null with rigid_body.pose.smoothing "gcv" and rigid_body.pose.harmonics "{pose.harmonics}" '
               '(change points are fitted without stride harmonics: set rigid_body.pose.harmonics "none")')
    if why is not None:
        raise _error(source, "rigid_body.pose.events", (), _given_names(params),
                     f"expected {why}, got {_show(events)}")


def _show(v) -> str:
    try:
        return json.dumps(v)
    except (TypeError, ValueError):
        return repr(v)


# ---------------------------------------------------------------------------
# parameter files
# ---------------------------------------------------------------------------

def read_params(path) -> dict:
    """The parameters given in a file, validated, as a dict of only the parameters it names.

    ``analysis.json`` (its ``parameters`` object), a notebooks' ``choices.json``
    (the same layout, only the choices made) or a bare object; nested
    sections, flat names or a mix, returned as written.
    """
    data = _read_params_object(path)
    AnalysisParams.from_dict(data, str(path))
    return data


def load_params(path) -> AnalysisParams:
    """Read ``analysis.json`` (its ``parameters`` object, or a bare object) into :class:`AnalysisParams`."""
    return AnalysisParams.from_dict(_read_params_object(path), str(path))


def _read_params_object(path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ParamsError(f"{path}: parameter file not found")
    text = read_text_utf8(path, ParamsError)
    if json_depth(text) > MAX_JSON_DEPTH:
        raise ParamsError(f"{path}: JSON nested too deeply to read (a parameter file is a few levels deep)")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParamsError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    if isinstance(data, dict) and "parameters" in data:
        data = data["parameters"]
    if not isinstance(data, dict):
        raise ParamsError(f"{path}: expected a JSON object of parameters")
    return dict(data)


def resolve_params(session, params=None) -> AnalysisParams:
    """Defaults, then the session's ``analysis`` object, then ``params``.

    ``params``: None (the session's alone), an :class:`AnalysisParams`
    (taken as it is) or a dict of the values a parameter file gives, layered
    over the session's (only those values, not the defaults filled in, so a
    preset named in either is not undone).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> session = SimpleNamespace(analysis={"smooth": {"span": 0.2}}, json_path="session.json")
    >>> resolve_params(session).smooth.span
    0.2
    >>> given = resolve_params(session, {"rigid_body": {"pose": {"smoothing": "gcv"}}})
    >>> given.rigid_body.pose.smoothing, given.smooth.span
    ('gcv', 0.2)
    """
    base = AnalysisParams.from_dict(session.analysis, f"{session.json_path}: 'analysis'")
    if params is None:
        return base
    if isinstance(params, AnalysisParams):
        return params
    return AnalysisParams.from_layers(session.analysis, params)
