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
        ``"rloess"`` (thesis), ``"loess"``, ``"lowess"``, ``"rlowess"``, ``"moving"``.
    x_marker : int
        Marker (0-based) whose net displacement defines x-motion (eq. 5.6).
    period_frames : float or None
        Motion period in frames (the thesis typed 18); None = estimated.
    n_periods : int
        Periods used for the net displacement (eq. 5.6/5.7).
    x_degree : int
        Polynomial degree of the x-motion fit (section 5.5.2.1).
    fourier_orders : dict or None
        ``{"y": N, "z": N}`` Fourier orders; None = order rule of 5.5.2.2.
    angular_method : str
        ``"lstsq"`` (all markers, no singularity) or ``"versions"`` (average
        of the thesis versions eq. 6.3/6.4/6.38/6.39 chosen by ``omega_versions``).
    omega_versions : list of bool
        Which of the six thesis versions enter the average.
    weighting_mode : str
        ``"iso"`` (each harmonic weighted at its own frequency) or ``"thesis"``.
    """

    sync_offsets: dict | None = None
    recalibrate: bool = False
    detection: dict = field(default_factory=dict)
    triangulation: str = "joint"
    smoothing_span: float = 0.1
    smoothing_method: str = "rloess"
    x_marker: int = 0
    period_frames: float | None = None
    n_periods: int = 2
    x_degree: int = 1
    fourier_orders: dict | None = None
    angular_method: str = "lstsq"
    omega_versions: list = field(default_factory=lambda: [True] * 6)
    weighting_mode: str = "iso"

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
        if self.smoothing_method not in ("rloess", "loess", "lowess", "rlowess", "moving"):
            bad("smoothing_method", "rloess, loess, lowess, rlowess or moving")
        if self.angular_method not in ("lstsq", "versions"):
            bad("angular_method", '"lstsq" or "versions"')
        if len(self.omega_versions) != 6 or not any(self.omega_versions):
            bad("omega_versions", "six booleans, at least one true")
        if self.weighting_mode not in ("iso", "thesis"):
            bad("weighting_mode", '"iso" or "thesis"')
        if self.period_frames is not None and float(self.period_frames) <= 2:
            bad("period_frames", "a period in frames (> 2) or null")
        if int(self.n_periods) < 1:
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
