"""``report.html``: the analysis of a session for a person, self-contained.

Figures are embedded as base64 PNG and the page carries its own CSS, so it
opens in any browser without Python, a network or the results folder. They
are described here as data (:func:`report_figures`) and drawn by
:mod:`horsemocap.plots.report_figures`, the only part that needs
matplotlib: usually in a copy of the process forked before the analysis
(:func:`horsemocap.plots.figure_painter`), which loads matplotlib while the analysis runs
and draws each step's figures as soon as the step has ended
(:func:`step_figures`).
"""
from __future__ import annotations

import html
import re
from pathlib import Path

from .forking import EarlyCalls
from .plots import figure_painter
from .readable import distance_km, hours_minutes
from .results import analysis_record
from .store import atomic_write_text
from .vibration import COMFORT_UNITS, comfort_table_rows, unit_text

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;color:#222;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em} h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0} td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left}
th{background:#f3f3f3} td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0} figcaption{color:#555;font-size:.9em} img{max-width:100%}
.note{color:#555;font-size:.9em}
.summary{font-size:1.05em;background:#f6f8fa;border:1px solid #d0d7de;border-radius:6px;padding:.6em .9em}
.alert{border-radius:6px;padding:.6em .9em;margin:1em 0;border:2px solid #d4a72c;background:#fff8c5}
.alert.unreliable{border-color:#cf222e;background:#ffebe9} .alert h2{margin-top:.2em;border:none}
.alert li{margin:.4em 0} .alert .means{display:block;color:#333;margin-top:.2em}
"""


#: The steps that have figures in the report, in the report's order.
FIGURE_STEPS = ("detect", "triangulate", "rigid_body")


def _figure_html(png: str, caption: str) -> str:
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{png}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def report_figures(analysis) -> list:
    """The report's figures as ``((function, args, kwargs), caption)``: ``function`` names a plotting
    function of :data:`horsemocap.plots.report_figures.FIGURE_FUNCTIONS`, the arguments are arrays.
    Those of every step of :data:`FIGURE_STEPS` (:func:`step_figures`), in that order."""
    return [figure for step in FIGURE_STEPS for figure in step_figures(analysis, step)]


def _described_figures(analysis) -> tuple[list, list[str]]:
    """:func:`report_figures`, leaving out a step whose figures cannot be described: ``(figures,
    reasons)``, one reason per step left out (shown in the report instead of its figures)."""
    figures, left_out = [], []
    for step in FIGURE_STEPS:
        try:
            figures += step_figures(analysis, step)
        except Exception as exc:    # noqa: BLE001 - one step's figures missing does not lose the report
            left_out.append(f"The figures of step '{step}' are left out: describing them failed "
                            f"({type(exc).__name__}: {exc}).")
    return figures, left_out


def step_figures(analysis, step: str) -> list:
    """The report's figures of ``step`` (as :func:`report_figures`'), from its result in ``analysis``;
    none for a step without figures or without a result.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> step_figures(SimpleNamespace(comfort=None), "comfort")
    []
    """
    if step not in FIGURE_STEPS or getattr(analysis, step) is None:
        return []
    if step == "detect":
        size = analysis.rig.rig.cameras[0].size
        return [(("marker_tracks", (analysis.detect.marker_px, size), {}),
                 "Detected marker centroids in each camera, in pixels (chapter 4).")]
    if step == "triangulate":
        return [(("reprojection_residuals", (analysis.triangulate.residual_px,), {}),
                 "Reprojection residuals of the triangulated markers, in pixels (section 5.1).")]
    rb = analysis.rigid_body
    t, pos = rb.t, rb.registered
    series = {f"marker {m + 1}": pos[:, m] for m in range(pos.shape[1])}
    series["saddle"] = rb.saddle_position
    figures = []
    for data, unit, title, quantity, caption in (
            (series, "m", "Positions in the motion frame", None,
             "Registered marker positions and the saddle marker, in metres (sections 5.3-5.4, 6.3)."),
            ({"omega": rb.omega}, "rad/s", "Angular velocity", "angular velocity about",
             "Angular velocity of the body about the motion frame's axes, in rad/s (chapter 6)."),
            ({"alpha": rb.alpha}, "rad/s²", "Angular acceleration", "angular acceleration about",
             "Angular acceleration of the body about the motion frame's axes, in rad/s² (chapter 6)."),
            ({"saddle": rb.saddle_acceleration}, "m/s²", "Saddle acceleration", "acceleration along",
             "Acceleration of the hidden saddle marker along the motion frame's axes, in m/s² (section 6.4).")):
        figures.append((("axes_timeseries", (t, data, unit, title), {"quantity": quantity}), caption))
    return figures


def _table(rows, header) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(
        f'<td class="num">{v}</td>' if isinstance(v, str) and _is_num(v) else f"<td>{html.escape(str(v))}</td>"
        for v in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _is_num(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


PARAMETER_NAMES = {
    "preset": "preset",
    "sync.offsets": "synchronisation offsets (frame of the flash per camera)",
    "rig.recalibrate": "calibrate again from the checkerboard views",
    "rig.mode": "calibration of the rig",
    "rig.exclude": "checkerboard views left out of the calibration",
    "detect.method": "marker detection",
    "detect.cameras": "detector settings",
    "detect.max_gap_frames": "longest gap bridged (frames)",
    "rigid_body.saddle_marker": "saddle marker in the static shot (given)",
    "rigid_body.marker_model": "marker shape of the pose registration",
    "stills.plumb": "plumb stills' threshold and labels",
    "stills.static": "static-shot stills' threshold and labels",
    "triangulate.mode": "triangulation",
    "smooth.span": "smoothing span (fraction of the points)",
    "smooth.method": "smoothing of the 3D positions",
    "motion_frame.x_marker": "marker defining the direction of motion",
    "motion_frame.period_frames": "stride period (frames)",
    "motion_frame.n_periods": "periods used for the direction of motion",
    "rigid_body.fits.x_degree": "polynomial degree of the forward (x) motion",
    "rigid_body.fits.fourier_orders": "Fourier orders (y, z) per marker",
    "rigid_body.fits.order_rule": "rule choosing the Fourier order",
    "rigid_body.fits.trend": "linear drift term in the Fourier fits",
    "rigid_body.fits.angular_method": "angular velocity and acceleration from",
    "rigid_body.fits.omega_versions": "thesis versions averaged for the angular velocity",
    "rigid_body.fits.alpha_versions": "thesis versions averaged for the angular acceleration",
    "rigid_body.fits.saddle_method": "saddle velocity and acceleration from",
    "comfort.weighting_mode": "frequency weighting (ISO 2631)",
    "rigid_body.kinematics": "kinematics passed on",
    "rigid_body.pose.smoothing": "smoothing of the pose trajectory",
    "rigid_body.pose.partial_frames": "pose also smoothed over the frames with two markers beyond the analysed ones",
    "rigid_body.pose.harmonics": "stride harmonics kept unpenalised in the pose smoothing",
    "rigid_body.pose.weights": "marker weights in each frame's pose registration",
    "rigid_body.pose.rotation_weights": "frame weights in the rotation's smoothing",
    "rigid_body.pose.events": "known change points of the pose smoothing (s)",
    "rigid_body.pose.correlated_noise_criterion": "criterion of the pose smoothing under correlated noise",
    "motion_frame.mode": "direction of motion (x axis) from",
}
"""A person's name for each parameter of ``analysis.json`` (its dotted field)."""

CHOICE_NAMES = {
    "sync": "synchronisation",
    "rig": "rig",
    "detection_method_note": "why the detection method changed",
    "identification": "marker labelling",
    "analysed_frames": "analysed frames (first, last + 1)",
    "static_order": "markers in the static shot's order",
    "saddle_index_in_static": "saddle marker in the static shot",
    "rigid_body_warnings": "warnings of the rigid-body step",
    "detection_method": "marker detection",
    "pose_smoothing": "smoothing of the pose trajectory",
    "comfort_not_computed": "comfort indicators not computed",
}


VALUE_WORDS = {
    "joint": "joint (all cameras at once)",
    "pairwise": "pairwise (stereo pairs with the reference camera, as the thesis)",
    "multiview": "all cameras together, followed in 3D",
    "loess": "loess (local quadratic regression)",
    "rloess": "robust loess (the thesis' rloess)",
    "lowess": "lowess (local linear regression)",
    "rlowess": "robust lowess",
    "moving": "moving average",
    "significant": "E/2, or E/2 + 1 if its extra harmonic is significant",
    "every_significant": "highest significant harmonic",
    "adjrsquare": "larger adjusted R-square",
    "rotation": "the fitted orientation",
    "lstsq": "least squares over all markers",
    "pose": "the fitted pose",
    "direct": "the fitted saddle path (eq. 6.48)",
    "iso": "each harmonic at its own frequency",
    "fits": "the thesis' chain of fits",
    "pose_spline": "the smoothed pose trajectory",
    "gcv": "generalised cross-validation",
    "auto": "automatic",
    "period": "net displacement over whole periods (eq. 5.6/5.7)",
    "record": "net displacement over the whole record",
}
"""Readable forms of the string values of parameters (the thesis' own choices say "thesis")."""

INDICATORS = {
    "acc_y_Wb_rms": ("vertical acceleration, Wb-weighted rms", "the vertical vibration a seated person feels, "
                     "weighted for comfort (BS 6841 Wb)"),
    "acc_y_Wk_rms": ("vertical acceleration, Wk-weighted rms", "the vertical vibration a seated person feels, "
                     "weighted for health (ISO 2631-1 Wk; the EU values apply to it)"),
    "VDV_y_Wb": ("vibration dose value, Wb", "fourth-power dose: weighs the shocks more than the rms"),
    "VDV_y_Wk": ("vibration dose value, Wk", "fourth-power dose: weighs the shocks more than the rms"),
    "acc_y_max": ("largest vertical acceleration", "the peak of the saddle's vertical acceleration, unweighted"),
    "crest_factor_y": ("crest factor", "peak over rms of the Wb-weighted acceleration; above 9 the rms "
                       "understates the shocks"),
    "TA_8_action_Wb": ("time to the daily action value by A(8), Wb", "riding time until the EU action value is reached"),
    "TA_8_action_Wk": ("time to the daily action value by A(8), Wk", "riding time until the EU action value is reached"),
    "TA_8_limit_Wb": ("time to the daily limit value by A(8), Wb", "riding time until the EU limit value is reached"),
    "TA_8_limit_Wk": ("time to the daily limit value by A(8), Wk", "riding time until the EU limit value is reached"),
    "TVDV_action_Wb": ("time to the action value by VDV, Wb", "riding time until the dose reaches the action value"),
    "TVDV_action_Wk": ("time to the action value by VDV, Wk", "riding time until the dose reaches the action value"),
    "TVDV_limit_Wb": ("time to the limit value by VDV, Wb", "riding time until the dose reaches the limit value"),
    "TVDV_limit_Wk": ("time to the limit value by VDV, Wk", "riding time until the dose reaches the limit value"),
    "acc_x_Wd_rms": ("fore-aft acceleration, Wd-weighted rms", "the saddle's surge along the motion (ISO 2631-1 Wd, "
                     "horizontal); the Directive counts it 1.4 times"),
    "acc_y_Wk_rms_iso": ("vertical acceleration, Wk-weighted rms, each harmonic weighted", "what the Directive "
                         "compares: the same as acc_y_Wk_rms unless the thesis' one-weight mode is chosen"),
    "acc_z_Wd_rms": ("lateral acceleration, Wd-weighted rms", "the saddle's sway across the motion (Wd); counted 1.4 times"),
    "VDV_y_Wk_iso": ("vibration dose value, vertical, Wk, each harmonic weighted", "the Directive's vertical dose"),
    "VDV_x_Wd": ("vibration dose value, fore-aft, Wd", "fourth-power dose of the surge"),
    "VDV_z_Wd": ("vibration dose value, lateral, Wd", "fourth-power dose of the sway"),
    "A_w_directive": ("the Directive's weighted acceleration", "the highest of 1.4 fore-aft (Wd), vertical (Wk) and "
                      "1.4 lateral (Wd) rms: what A(8) is computed from (2002/44/EC, Annex B)"),
    "VDV_directive": ("the Directive's vibration dose value", "the highest of 1.4 fore-aft, vertical (Wk) and 1.4 "
                      "lateral VDV"),
    "TA_8_action_directive": ("time to the daily action value by A(8), Directive", "riding time until the EU action "
                              "value is reached, judged on all three axes"),
    "TA_8_limit_directive": ("time to the daily limit value by A(8), Directive", "riding time until the EU limit "
                             "value is reached, judged on all three axes"),
    "TVDV_action_directive": ("time to the action value by VDV, Directive", "the same by the dose, all three axes"),
    "TVDV_limit_directive": ("time to the limit value by VDV, Directive", "the same by the dose, all three axes"),
    "vel_x_avg": ("average forward speed", "net distance over time along the direction of motion"),
    "amplitude_y": ("vertical amplitude of the saddle", "half the peak-to-peak of its fitted vertical position "
                    "(the thesis does not define it)"),
    "duration_s": ("duration of the record", "the time the indicators are computed over"),
    "f0_hz": ("stride frequency", "strides per second, the base of the harmonic series"),
    "period_s": ("stride period", "the time of one stride"),
}
INDICATORS.update({f"Distance_{key}": (name.replace("time to the daily", "distance to the").replace("time to the",
                                                                                                 "distance to the"),
                                        "distance ridden in that time at the measured speed")
                   for key, (name, _) in list(INDICATORS.items()) if key.startswith(("TA_8_", "TVDV_"))})
"""For each comfort indicator (:data:`horsemocap.vibration.COMFORT_KEYS`, ``DIRECTIVE_KEYS``): a
name and a one-line meaning (chapter 7, EU directive 2002/44/EC); the distances' from their times'."""


def unit_html(unit: str) -> str:
    """A unit with its powers as superscripts: ``m/s^2`` -> ``m/s<sup>2</sup>``;
    ``"1"`` (a ratio) -> ``""``; other text escaped."""
    if unit == "1":
        return ""

    parts = re.split(r"\^([0-9.+-]+)", unit)
    out = html.escape(parts[0])
    for i in range(1, len(parts), 2):
        out += f"<sup>{html.escape(parts[i])}</sup>" + html.escape(parts[i + 1])
    return out


def format_value(value, digits: int = 4) -> str:
    """A parameter or chosen value as a person reads it.

    Floats to ``digits`` significant digits (``17.98881515983109`` ->
    ``17.99``), strings unquoted and spelled out by :data:`VALUE_WORDS`,
    ``None`` -> ``automatic``, booleans yes/no, lists comma-separated (a list
    of six booleans: the numbers of the versions used), dicts as
    ``key: value`` pairs.
    """
    if value is None:
        return "automatic"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "not a number" if value != value else f"{value:.{digits}g}"
    if isinstance(value, str):
        return VALUE_WORDS.get(value, value)
    if isinstance(value, (list, tuple, dict)) and len(value) == 0:
        return "none"
    if isinstance(value, (list, tuple)):
        if len(value) == 6 and all(isinstance(v, bool) for v in value):
            used = [str(i + 1) for i, v in enumerate(value) if v]
            return "all six" if len(used) == 6 else "versions " + ", ".join(used)
        if value and all(isinstance(v, (list, tuple)) for v in value):
            return "; ".join("(" + ", ".join(format_value(x, digits) for x in v) + ")" for v in value)
        return ", ".join(format_value(v, digits) for v in value)
    if isinstance(value, dict):
        return "; ".join(f"{str(k).replace('_', ' ')}: {format_value(v, digits)}" for k, v in value.items())
    return str(value)


def choice_rows(record: dict) -> list[tuple[str, str]]:
    """``(name, value)`` rows of an ``analysis.json`` record's parameters and choices, rounded.

    One row per parameter (its dotted field, :data:`PARAMETER_NAMES`); the
    detection settings get one row per camera.

    Examples
    --------
    >>> choice_rows({"parameters": {"smooth": {"span": 0.1}}, "chosen": {"rig": "read rig.toml"}})
    [('smoothing span (fraction of the points)', '0.1'), ('rig', 'read rig.toml')]
    """
    def shown(path, v):
        if path == "motion_frame.x_marker" and isinstance(v, int):
            return f"marker {v + 1}"
        if path == "preset" and v is None:
            return "none (the automatic choices)"
        return format_value(v)

    rows = []
    for path, v in _leaves(record["parameters"]):
        if path == "detect.cameras":
            rows += [(f"detector settings ({cam})", format_value(d)) for cam, d in (v or {}).items()]
        else:
            rows.append((PARAMETER_NAMES.get(path, path), shown(path, v)))
    rows += [(CHOICE_NAMES.get(k, k), format_value(v)) for k, v in record["chosen"].items()]
    return rows


def _leaves(parameters: dict, prefix: str = ""):
    """``(dotted path, value)`` of every parameter field in a nested parameters object."""
    for k, v in parameters.items():
        path = f"{prefix}{k}"
        if isinstance(v, dict) and path not in PARAMETER_NAMES and path != "detect.cameras":
            yield from _leaves(v, path + ".")
        else:
            yield path, v


def comfort_rows(indicators: dict) -> list[tuple[str, str, str, str]]:
    """``(name, meaning, value, unit as HTML)`` for every indicator of ``comfort.csv``, Table 8.7's order.

    Values to 4 significant digits, times in hours also in hours and
    minutes; the identifier of ``comfort.csv`` is kept in the name, in brackets.
    """
    out = []
    for key, value, unit in comfort_table_rows(indicators):
        name, meaning = INDICATORS.get(key, (key, ""))
        shown = format_value(float(value)) + (f" ({hours_minutes(value)})" if unit == "h" else "")
        out.append((f"{name} [{key}]", meaning, shown, unit_html(unit)))
    return out


def x_acceleration_note(params) -> str | None:
    """Why the x acceleration is flat zero, if it is by construction (section 5.5.2.1)."""
    x_degree = params.rigid_body.fits.x_degree
    if params.rigid_body.kinematics == "fits" and x_degree <= 1:
        return (f"The forward (x) motion is fitted by a polynomial of degree {x_degree} in time (section "
                "5.5.2.1: the horse moves at a steady speed), so its second derivative, the x acceleration, is zero "
                "by construction: the flat line in the x panels is the model, not a measurement. A higher degree "
                "(x_degree) or kinematics 'pose_spline' measures it.")
    return None


def text_html(text: str) -> str:
    """Escaped text with the powers of its units as superscripts (``m/s^2`` -> ``m/s<sup>2</sup>``)."""
    return re.sub(r"\^([0-9]+(?:\.[0-9]+)?)", r"<sup>\1</sup>", html.escape(str(text)))


def threshold_text(text: str) -> str:
    """A check's threshold as a person reads it.

    Numbers rounded (``0.314271`` -> ``0.3143``), ranges with a dash
    (``0.5..40`` -> ``0.5 – 40``), a range of one value as that value,
    ``unreliable outside <= 7.7`` as ``unreliable above 7.7``, and an
    unreliable band that is the ok band itself as ``unreliable otherwise``.
    """
    t = re.sub(r"\d+\.\d{5,}", lambda m: format_value(float(m.group(0))), str(text))
    t = re.sub(r"(?<![\d.])(-?\d+(?:\.\d+)?)\.\.\1(?![\d.])", r"\1", t)
    t = re.sub(r"(\d)\.\.(-?\d)", "\\1\u00a0–\u00a0\\2", t)   # no line break inside a range
    t = t.replace(" ;", ";").replace("unreliable outside <=", "unreliable above")
    m = re.fullmatch(r"ok (.+); unreliable outside (.+)", t)
    if m and m.group(1).strip() == m.group(2).strip():
        t = f"ok {m.group(1).strip()}; unreliable otherwise"
    return t


def quality_section(record: dict) -> list[str]:
    """The report's first section: the verdict of :mod:`horsemocap.quality` and every check."""
    colour = {"ok": "#1a7f37", "warning": "#9a6700", "unreliable": "#cf222e"}.get(record["verdict"], "#222")
    rows = [(html.escape(c["name"].replace("_", " ")),
             "" if c["figure"] is None else (format_value(float(c["figure"])) if isinstance(c["figure"], (int, float))
                                            else html.escape(str(c["figure"]))),
             unit_html(c["unit"]) if c["unit"] else "",
             text_html(threshold_text(c["threshold"]) if isinstance(c["threshold"], str)
                       else format_value(c["threshold"])),
             html.escape(c["level"]), text_html(c["message"])) for c in record["checks"]]
    words = {"ok": "every plausibility check passed.",
             "warning": "some figures are outside their usual range; read the checks before using the numbers.",
             "unreliable": "do not use these numbers: a check shows the input or the result is wrong."}
    return [f'<h2>Quality verdict: <span style="color:{colour}">{html.escape(record["verdict"].upper())}</span></h2>',
            f'<p class="note">{html.escape(words.get(record["verdict"], ""))} Also in quality.json.</p>',
            _html_table(rows, ["check", "figure", "unit", "threshold", "level", "message"])]


def _html_table(rows, header, align_numbers: bool = True) -> str:
    """A table whose cells are already HTML (escaped by the caller); numbers right-aligned unless told."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f'<td class="num">{v}</td>' if align_numbers and _is_num(v) else f"<td>{v}</td>"
                                    for v in row)
                   + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def summary_items(indicators: dict | None, verdict: str | None) -> list[tuple[str, str]]:
    """The summary line's ``(label, value as text)`` pairs: the quality verdict, the vertical
    acceleration's Wb and Wk rms, the VDV (Wb, Wk), and the riding time (h:min) and distance (km)
    to the EU action and limit values by A(8) (vertical, Wk; and the Directive's three axes when computed).

    Examples
    --------
    >>> from horsemocap.vibration import THESIS_TABLE_8_7
    >>> dict(summary_items(THESIS_TABLE_8_7, "ok"))["EU action value (A(8), vertical Wk)"]
    '0 h 09 min, 2.58 km'
    """
    items = [("quality verdict", (verdict or "not judged").upper())]
    if indicators is None:
        return items

    def value(key):
        return f"{format_value(float(indicators[key]), 3)} {unit_text(COMFORT_UNITS[key])}"

    items += [("Wb rms", value("acc_y_Wb_rms")), ("Wk rms", value("acc_y_Wk_rms")),
              ("VDV", f"Wb {value('VDV_y_Wb')}, Wk {value('VDV_y_Wk')}")]
    for what in ("action", "limit"):
        items.append((f"EU {what} value (A(8), vertical Wk)",
                      f"{hours_minutes(indicators[f'TA_8_{what}_Wk'])}, "
                      f"{distance_km(indicators[f'Distance_TA_8_{what}_Wk'])}"))
    if "TA_8_action_directive" in indicators:
        items.append(("the Directive's three axes",
                      "action " + hours_minutes(indicators["TA_8_action_directive"]) + ", "
                      + distance_km(indicators["Distance_TA_8_action_directive"]) + "; limit "
                      + hours_minutes(indicators["TA_8_limit_directive"]) + ", "
                      + distance_km(indicators["Distance_TA_8_limit_directive"])))
    return items


def summary_html(comfort, quality: dict | None) -> str:
    """The report's summary line (:func:`summary_items`), or why the comfort was not computed."""
    indicators = comfort.indicators if comfort is not None else None
    parts = [f"<b>{html.escape(k)}</b>: {text_html(v)}"
             for k, v in summary_items(indicators, quality["verdict"] if quality else None)]
    if comfort is None:
        parts.append("comfort: not computed (the analysis stopped before it)")
    elif indicators is None:
        parts.append(f"comfort: not computed ({html.escape(comfort.reason)})")
    return f'<p class="summary">{" · ".join(parts)}</p>'


WARNING_MEANINGS = {
    "thin marker triangle": (
        "The check predicts the noise of each frame's rotation from the markers' noise and the triangle's "
        "height, before any smoothing, and how far it moves a point at the saddle's distance. The roll, pitch, "
        "yaw, angular velocity and angular acceleration carry this noise, and so does the saddle's path: the "
        "saddle is such a far point, and the comfort figures are computed from its acceleration. The smoothing "
        "removes part of the noise; the check does not measure how much is left. Noise that is left adds to "
        "the saddle's acceleration, so the Wb/Wk rms and VDV tend to be overstated and the times and "
        "distances to the EU values understated: use the comfort figures as a cautious (upper) estimate, "
        "not as a measurement, and the angular results not at all."),
    "frames have no pose": (
        "In these frames too few markers were found for a pose: the kinematics there are bridged by the "
        "smoothing from the frames around them, not measured. The comfort figures include the bridged "
        "frames; with many of them, or a long gap, they describe the interpolation there."),
    "omega within": (
        "The thesis' versions of the angular velocity divide by its component normal to the markers' plane "
        "(eq. 6.35), which is small in these frames: the angular results, the saddle's acceleration built "
        "from them and so every comfort figure of this chain are unreliable. Kinematics 'pose_spline' does "
        "not divide by it."),
}
"""What each rigid-body warning (by the words it starts with) means for the report's numbers."""


def warning_meaning(message: str) -> str:
    """What a warning of the analysis means for the numbers (:data:`WARNING_MEANINGS`), or ``""``.

    Examples
    --------
    >>> warning_meaning("thin marker triangle: smallest height 32 mm; ...").split(".")[0]
    "The check predicts the noise of each frame's rotation from the markers' noise and the triangle's height, before any smoothing, and how far it moves a point at the saddle's distance"
    >>> warning_meaning("something else")
    ''
    """
    for start, meaning in WARNING_MEANINGS.items():
        if start in message:
            return meaning
    return ""


def warnings_box(rigid_body_warnings, quality: dict | None) -> list[str]:
    """The report's highlighted box of warnings (empty when there is none).

    Each rigid-body warning with what it means for the numbers
    (:func:`warning_meaning`), and each quality check whose level is not
    ``ok`` (the marker-geometry check only repeats the rigid-body warnings:
    left out). Red when a check is ``unreliable``, amber otherwise.
    """
    items = [(w, warning_meaning(w)) for w in rigid_body_warnings]
    checks = [c for c in (quality or {}).get("checks", [])
              if c["level"] in ("warning", "unreliable") and not (c["name"] == "marker_geometry" and items)]
    items += [(f"{c['name'].replace('_', ' ')} ({c['level']}): {c['message']}",
               "Do not use the numbers: the input or the result is wrong." if c["level"] == "unreliable" else "")
              for c in checks]
    if not items:
        return []
    unreliable = any(c["level"] == "unreliable" for c in checks)
    lis = "".join(f"<li>{text_html(text)}" + (f'<span class="means"><b>For the numbers:</b> {html.escape(m)}</span>'
                                              if m else "") + "</li>" for text, m in items)
    return [f'<div class="alert{" unreliable" if unreliable else ""}"><h2>Warnings ({len(items)})</h2>'
            f"<ul>{lis}</ul></div>"]


def passes_section(analysis) -> list[str]:
    """Every pass of a recording with several (:mod:`horsemocap.passes`): a table of the analysed frames
    (the reference camera's numbering, as in ``passes.csv``), duration, verdict and the vertical Wb/Wk
    rms, and the row of all passes (durations weighted); nothing for a record of one pass."""
    passes = getattr(analysis, "passes", None)
    if passes is None:
        return []
    offset = analysis.synchronisation.offsets[analysis.session.reference_camera]

    def rms(indicators, key):
        return format_value(float(indicators[key]), 4) if indicators and key in indicators else ""

    rows = []
    for p in passes.passes:
        first, stop = p.segment if p.segment is not None else p.run
        note = "the result files" if p.main else (f"not analysed: {p.error}" if p.analysis is None else "")
        rows.append((str(p.index), f"{first + offset}..{stop - 1 + offset}",
                     format_value(p.duration_s, 3) if p.analysis is not None else "", p.verdict,
                     rms(p.indicators, "acc_y_Wb_rms"), rms(p.indicators, "acc_y_Wk_rms"), note))
    combined = passes.combined
    rows.append(("all", "", format_value(combined["duration_s"], 3) if "duration_s" in combined else "",
                 passes.verdict, rms(combined, "acc_y_Wb_rms"), rms(combined, "acc_y_Wk_rms"),
                 "weighted by the durations"))
    rms_unit = unit_text(COMFORT_UNITS["acc_y_Wb_rms"])
    analysed = sum(p.analysis is not None for p in passes.passes)
    return [f"<h2>Passes of the horse through the views ({len(passes.passes)})</h2>",
            '<p class="note">The recording holds several passes; each analysed on its own frames '
            f"({analysed} of {len(passes.passes)}). The sections below and the result files describe the longest "
            "(marked); the row <i>all</i> is the comfort over every analysed pass, each weighted by its duration "
            "(every indicator in passes.csv). The overall quality verdict accounts for every pass (check "
            "<i>passes</i>).</p>",
            _table(rows, ["pass", "frames", "duration (s)", "verdict", f"Wb rms ({rms_unit})",
                          f"Wk rms ({rms_unit})", ""])]


def report_html(analysis, quality: dict | None = None, painter: EarlyCalls | None = None) -> str:
    """The text of the report for an :class:`~horsemocap.pipeline.Analysis`.

    Below the title: the summary line (:func:`summary_html`), the warnings
    with what each means for the numbers (:func:`warnings_box`, only when
    there is one), then ``quality`` (the record of
    :func:`horsemocap.quality.quality_record`) check by check.

    ``painter`` (:func:`horsemocap.plots.figure_painter`) draws the figures; given
    the figures of ``analysis``' first steps already (:meth:`EarlyCalls.submit`,
    :func:`step_figures`) or not. Without it they are drawn in this process.
    """
    s = analysis.session
    parts = [f"<h1>Saddle motion analysis: {html.escape(s.name)}</h1>",
             '<p class="note">horsemocap, after G. Dogan, METU 2009. Session folder: '
             f"{html.escape(str(s.root))}</p>"]
    parts.append(summary_html(analysis.comfort, quality))
    warn = list(analysis.rigid_body.warnings) if analysis.rigid_body is not None else []
    parts += warnings_box(warn, quality)
    parts += passes_section(analysis)
    if quality is not None:
        parts += quality_section(quality)
    meta = [(k, format_value(v)) for k, v in s.metadata.items()] + [
        ("frames per second", f"{s.fps:g}"), ("cameras", ", ".join(s.cameras))]
    parts += ["<h2>Session</h2>", _table(meta, ["field", "value"])]

    comfort = analysis.comfort
    if comfort is not None and comfort.indicators is None:
        parts += ["<h2>Comfort indicators</h2>", f"<p>Not computed: {html.escape(comfort.reason)}</p>"]
    elif comfort is not None:
        rows = [(html.escape(n), html.escape(m), v, u) for n, m, v, u in comfort_rows(comfort.indicators)]
        verdict = f" (quality verdict: {html.escape(quality['verdict'])})" if quality is not None else ""
        weighting = ("one weight per record, at the dominant harmonic of the vertical acceleration (the thesis)"
                     if analysis.params.comfort.weighting_mode == "thesis" else "each harmonic weighted at its own frequency")
        parts += [f"<h2>Comfort indicators (thesis Table 8.7){verdict}</h2>",
                  f'<p class="note">Frequency weighting (Wb of BS 6841, Wk of ISO 2631-1): {html.escape(weighting)}. '
                  "The times are how long a rider can ride this way before reaching the exposure action value "
                  "(EAV) and the exposure limit value (ELV) of the EU directive 2002/44/EC, by the daily "
                  "exposure A(8) and by the vibration dose value (VDV); the distances are those ridden in "
                  "those times at the measured speed. The thesis' times (Wb, Wk) judge the vertical axis "
                  "alone; the Directive judges the highest of 1.4 times the fore-aft and lateral (Wd) and the "
                  "vertical (Wk) values: its times are the rows marked Directive (computed with each "
                  "harmonic weighted at its own frequency whatever the weighting above), and they are the "
                  "shorter when the horse's surge or sway outweighs its vertical motion."
                  + (" Here the saddle's fore-aft acceleration is zero (the thesis' straight-line x fit), so "
                     "the Directive's values see only the other two axes."
                     if comfort.indicators.get("acc_x_Wd_rms") == 0 else "")
                  + "</p>",
                  _html_table(rows, ["indicator", "meaning", "value", "unit"])]

    record = analysis_record(analysis)
    parts += ["<h2>Choices made</h2>", '<p class="note">Automatic unless given; values rounded here, '
              "exact in analysis.json (<code>horsemocap analyze --params analysis.json</code> repeats the run "
              "exactly).</p>", _html_table([(html.escape(a), html.escape(b)) for a, b in choice_rows(record)],
                                            ["choice", "value"], align_numbers=False)]

    parts.append("<h2>Figures</h2>")
    figures, left_out = _described_figures(analysis)
    pngs = _drawn(painter, [description for description, _ in figures])
    parts += [_figure_html(png, caption) for png, (_, caption) in zip(pngs, figures)]
    parts += [f'<p class="note">{html.escape(reason)}</p>' for reason in left_out]
    note = x_acceleration_note(analysis.params) if analysis.rigid_body is not None else None
    if note:
        parts.append(f'<p class="note">{html.escape(note)}</p>')
    timing = [(CHOICE_NAMES.get(k, k) if k in ("sync", "rig") else k.replace("_", " "), f"{v:.2f}")
              for k, v in analysis.timings.items()]
    parts += ["<h2>Steps</h2>", _table(timing, ["step", "seconds"])]
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>horsemocap: {html.escape(s.name)}</title><style>{CSS}</style></head><body>"
            + "\n".join(parts) + "</body></html>\n")


def _drawn(painter: EarlyCalls | None, descriptions) -> list[str]:
    """The PNGs of ``descriptions``, from ``painter``: it may have been given the first of them already (in
    parts, step by step: :func:`step_figures`); it is given the rest here."""
    if painter is None:
        with figure_painter(fork=False) as painter:
            return _drawn(painter, descriptions)
    given = [d for (part,) in painter.given for d in part]
    if [name for name, _, _ in given] != [name for name, _, _ in descriptions[:len(given)]]:
        raise ValueError("the figures given to the painter are not the first of the report's")
    if len(given) < len(descriptions):
        painter.submit(descriptions[len(given):])
    return [png for part in painter.results() for png in part]


def write_report(path, analysis, quality: dict | None = None, painter: EarlyCalls | None = None) -> Path:
    """Write ``report.html`` atomically; returns its path (``painter``: :func:`report_html`)."""
    return atomic_write_text(Path(path), report_html(analysis, quality, painter))
