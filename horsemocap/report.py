"""``report.html``: the analysis of a session for a person, self-contained.

Figures are embedded as base64 PNG and the page carries its own CSS, so it
opens in any browser without Python, a network or the results folder.
"""
from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

import matplotlib.pyplot as plt

from .store import atomic_write_text

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;color:#222;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em} h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0} td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left}
th{background:#f3f3f3} td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0} figcaption{color:#555;font-size:.9em} img{max-width:100%}
.note{color:#555;font-size:.9em}
"""


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _figure(fig, caption: str) -> str:
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{_png(fig)}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


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


def quality_section(record: dict) -> list[str]:
    """The report's first section: the verdict of :mod:`horsemocap.quality` and every check."""
    colour = {"ok": "#1a7f37", "warning": "#9a6700", "unreliable": "#cf222e"}.get(record["verdict"], "#222")
    rows = [(c["name"], "" if c["figure"] is None else (f"{c['figure']:.4g}" if isinstance(c["figure"], (int, float))
                                                         else str(c["figure"])),
             c["unit"], c["threshold"], c["level"], c["message"]) for c in record["checks"]]
    words = {"ok": "every plausibility check passed.",
             "warning": "some figures are outside their usual range; read the checks before using the numbers.",
             "unreliable": "do not use these numbers: a check shows the input or the result is wrong."}
    return [f'<h2>Quality verdict: <span style="color:{colour}">{html.escape(record["verdict"].upper())}</span></h2>',
            f'<p class="note">{html.escape(words.get(record["verdict"], ""))} Also in quality.json.</p>',
            _table(rows, ["check", "figure", "unit", "threshold", "level", "message"])]


def report_html(analysis, quality: dict | None = None) -> str:
    """The text of the report for an :class:`~horsemocap.pipeline.Analysis`.

    ``quality``: the record of :func:`horsemocap.quality.quality_record`,
    shown first.
    """
    from . import plots
    from .results import analysis_record

    s, res = analysis.session, analysis.results
    parts = [f"<h1>Saddle motion analysis: {html.escape(s.name)}</h1>",
             '<p class="note">horsemocap, after G. Dogan, METU 2009. Session folder: '
             f"{html.escape(str(s.root))}</p>"]
    if quality is not None:
        parts += quality_section(quality)
    meta = [(k, v) for k, v in s.metadata.items()] + [("fps", f"{s.fps:g}"), ("cameras", ", ".join(s.cameras))]
    parts += ["<h2>Session</h2>", _table(meta, ["field", "value"])]

    record = analysis_record(analysis)
    choices = [(k, json.dumps(v)) for k, v in record["parameters"].items() if k != "detection"]
    choices += [(f"detection ({cam})", json.dumps(v)) for cam, v in record["parameters"].get("detection", {}).items()]
    choices += [(k, json.dumps(v)) for k, v in record["chosen"].items()]
    parts += ["<h2>Choices made</h2>", '<p class="note">Automatic unless given; '
              "<code>--params analysis.json</code> repeats the run exactly.</p>",
              _table(choices, ["parameter", "value"])]

    warn = res.get("rigid_body", {}).get("warnings") or []
    if warn:
        parts += ["<h2>Warnings</h2>", "<p class=\"note\">The rigid-body step's conditioning (angular.csv: "
                  "singularity_deg, triangle_height_m, registration_rms_m) makes these results unreliable:</p>",
                  "<ul>" + "".join(f"<li>{html.escape(w)}</li>" for w in warn) + "</ul>"]
    if "comfort" in res and res["comfort"].get("indicators") is None:
        parts += ["<h2>Comfort indicators</h2>",
                  f"<p>Not computed: {html.escape(str(res['comfort'].get('reason', '')))}</p>"]
    elif "comfort" in res:
        from .vibration import comfort_table_rows

        rows = [(name, f"{value:.4f}", unit) for name, value, unit in comfort_table_rows(res["comfort"]["indicators"])]
        verdict = f" (quality verdict: {html.escape(quality['verdict'])})" if quality is not None else ""
        parts += [f"<h2>Comfort indicators (thesis Table 8.7){verdict}</h2>",
                  f'<p class="note">Weighting mode: {html.escape(analysis.params.weighting_mode)}. '
                  "Times to reach the EU directive 2002/44/EC exposure action (EAV) and limit (ELV) values "
                  "by A(8) and by VDV, and the distances ridden in those times at the measured speed. "
                  "amplitude_y is half the peak-to-peak of the saddle's fitted vertical position (the thesis "
                  "does not define it).</p>",
                  _table(rows, ["indicator", "value", "unit"])]

    parts.append("<h2>Figures</h2>")
    if "detect" in res:
        rig = res["rig"]["rig"]
        parts.append(_figure(plots.plot_marker_tracks(res["detect"]["marker_px"], rig.cameras[0].size),
                             "Detected marker centroids in each camera (chapter 4)."))
    if "triangulate" in res:
        parts.append(_figure(plots.plot_reprojection_residuals(res["triangulate"]["residual_px"]),
                             "Reprojection residuals of the triangulated markers (section 5.1)."))
    if "rigid_body" in res:
        rb = res["rigid_body"]
        t, pos = rb["t"], rb["registered"]
        series = {f"marker {m + 1}": pos[:, m] for m in range(pos.shape[1])}
        series["saddle"] = rb["saddle_position"]
        parts.append(_figure(plots.plot_axes_timeseries(t, series, "m", "Positions in the motion frame"),
                             "Registered marker positions and the saddle marker (sections 5.3-5.4, 6.3)."))
        parts.append(_figure(plots.plot_axes_timeseries(
            t, {"omega (rad/s)": rb["omega"], "alpha / 10 (rad/s^2)": rb["alpha"] / 10},
            "", "Angular velocity and acceleration"), "Angular kinematics of the body (chapter 6)."))
        parts.append(_figure(plots.plot_axes_timeseries(t, {"saddle": rb["saddle_acceleration"]}, "m/s^2",
                                                        "Saddle acceleration"),
                             "Acceleration of the hidden saddle marker (section 6.4)."))
    timing = [(k, f"{v:.2f}") for k, v in analysis.timings.items()]
    parts += ["<h2>Steps</h2>", _table(timing, ["step", "seconds"])]
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>horsemocap: {html.escape(s.name)}</title><style>{CSS}</style></head><body>"
            + "\n".join(parts) + "</body></html>\n")


def write_report(path, analysis, quality: dict | None = None) -> Path:
    """Write ``report.html`` atomically; returns its path."""
    return atomic_write_text(Path(path), report_html(analysis, quality))
