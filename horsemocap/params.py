"""Analysis parameters: every choice the thesis asked the user for.

Each field has an automatic default (``None`` = chosen by the pipeline from
the data). A session's ``analysis`` object and ``--params analysis.json``
give overrides; the chosen values are written back to ``analysis.json`` so a
run can be repeated exactly.
"""
from __future__ import annotations

import difflib
import json
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path


class ParamsError(ValueError):
    """An analysis parameter file or value that cannot be used."""


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
    detection : dict
        Per camera (or ``"all"``) overrides of the detector's parameters
        (threshold, area range, window size, distance tolerance, labels).
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
        (``benchmarks/bench_herd_kinematics.py``, the same detections for
        both; ``benchmarks/results/herd_kinematics.txt``): saddle vertical
        acceleration median 15.8 % (worst 24.8 %) with pose_spline against
        24.6 % (45.4 %) with the fits; median |error| of the Wb-weighted rms
        5.0 % against 7.9 %, of the Wk-weighted rms 4.4 % against 6.7 %, of
        VDV Wb 6.4 % against 9.2 %. On the bundled Horse 2 canter alone (38
        frames) the fits do better (3.0 % against 18.3 %). With detection
        noise (notebook 14's study, bundled session, medians of 3 draws) the
        saddle error at 0.1 / 0.25 / 0.5 px is 32.9 / 36.9 / 56.3 % with
        pose_spline and 19.0 / 108.8 / 560 % with the fits. A non-periodic
        record (a lift, a set-down, 10 Hz ringing) has only pose_spline
        (``benchmarks/bench_kinematics.py``).
        The default stays ``"fits"`` until the notebooks that print the
        default's numbers (08-14, 13 with the whole herd) are rebuilt with
        ``"pose_spline"``.
    pose_smoothing : str
        Smoothing of the pose trajectory (:func:`horsemocap.splines.smoothing_spline`):
        ``"gcv"`` (default; quintic, one generalised cross-validation
        parameter per component), ``"adaptive"`` (a second GCV pass with a
        penalty weighted by the local roughness: better on motions that are
        calm then ringing), ``"gcv_cubic"`` (SciPy's ``make_smoothing_spline``) or ``"none"``.
    motion_frame : str
        x-motion axis: ``"auto"`` (default: the thesis' eq. 5.6/5.7 over one
        or two periods of ``x_marker`` when a period is given or found, else
        ``"record"``), ``"period"`` (always the thesis'; an error without a
        period) or ``"record"`` (the net displacement of the markers'
        centroid over the whole record, orthogonal to gravity: no period
        needed; the period is then only estimated for the comfort step).
    """

    sync_offsets: dict | None = None
    recalibrate: bool = False
    detection: dict = field(default_factory=dict)
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
    kinematics: str = "fits"
    pose_smoothing: str = "gcv"
    motion_frame: str = "auto"

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict, source: str = "analysis parameters") -> "AnalysisParams":
        """Build from a dict; unknown keys and bad values name ``source``."""
        names = [f.name for f in fields(cls)]
        for key in data:
            if key not in names:
                close = difflib.get_close_matches(key, names, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise ParamsError(f"{source}: unknown parameter '{key}'{hint}")
        p = cls(**data)
        p.validate(source)
        return p

    def updated(self, **changes) -> "AnalysisParams":
        p = replace(self, **{k: v for k, v in changes.items() if v is not None})
        p.validate("command line")
        return p

    def validate(self, source: str) -> None:
        def bad(name, expected):
            raise ParamsError(f"{source}: parameter '{name}': expected {expected}, got {getattr(self, name)!r}")
        if self.triangulation not in ("joint", "thesis"):
            bad("triangulation", '"joint" or "thesis"')
        if not (0 < float(self.smoothing_span) <= 1):
            bad("smoothing_span", "a fraction in (0, 1]")
        if self.smoothing_method not in ("none", "rloess", "loess", "lowess", "rlowess", "moving"):
            bad("smoothing_method", "none, rloess, loess, lowess, rlowess or moving")
        if self.angular_method not in ("rotation", "lstsq", "thesis"):
            bad("angular_method", '"rotation", "lstsq" or "thesis"')
        for name in ("omega_versions", "alpha_versions"):
            if len(getattr(self, name)) != 6 or not any(getattr(self, name)):
                bad(name, "six booleans, at least one true")
        if self.saddle_method not in ("pose", "direct", "thesis"):
            bad("saddle_method", '"pose", "direct" or "thesis"')
        from .fitting import ORDER_RULES

        if self.order_rule not in ORDER_RULES:
            bad("order_rule", " or ".join(f'"{r}"' for r in ORDER_RULES))
        if self.kinematics not in ("pose_spline", "fits"):
            bad("kinematics", '"pose_spline" or "fits"')
        if self.pose_smoothing not in ("adaptive", "gcv", "gcv_cubic", "none"):
            bad("pose_smoothing", '"adaptive", "gcv", "gcv_cubic" or "none"')
        if self.motion_frame not in ("auto", "record", "period"):
            bad("motion_frame", '"auto", "record" or "period"')
        if self.weighting_mode not in ("iso", "thesis"):
            bad("weighting_mode", '"iso" or "thesis"')
        if self.period_frames is not None and float(self.period_frames) <= 2:
            bad("period_frames", "a period in frames (> 2) or null")
        if self.n_periods is not None and int(self.n_periods) < 1:
            bad("n_periods", "an integer >= 1")


def load_params(path) -> AnalysisParams:
    """Read ``analysis.json`` (its ``parameters`` object, or a flat object)."""
    path = Path(path)
    if not path.is_file():
        raise ParamsError(f"{path}: parameter file not found")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ParamsError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    if isinstance(data, dict) and "parameters" in data:
        data = data["parameters"]
    if not isinstance(data, dict):
        raise ParamsError(f"{path}: expected a JSON object of parameters")
    return AnalysisParams.from_dict(data, str(path))
