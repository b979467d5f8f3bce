"""Free-running cameras over a ride of several laps: the sync found, each pass against its own truth.

    python benchmarks/bench_laps.py [--draws 400-409] [--laps 4 --lap-s 30] [--genlocked] [--out FILE]

Renders into the cache (on demand) sessions of :mod:`horsemocap.virtuallab.laps`: Horse 2's canter on the thesis
rig at 30 fps, marker noise correlated over the recording's frames (``LAPS_NOISE``), cameras that run free with
timings drawn by :func:`horsemocap.virtuallab.herd.free_running_timings` (set 0, draw index ``--draws``).

* ``--draws A-B``: one pass per draw (a short session each). Per draw: the drawn phases and rolling-shutter
  readouts, the exit status ``horsemocap analyze`` would give, the verdict, the fractional offsets found against
  the truth (frames), the saddle's vertical acceleration error (% of its rms) and the Wb / Wk rms errors (%).
* ``--laps N``: one ride of ``N`` passes ``--lap-s`` seconds apart (first draw of ``--draws``): per pass found,
  the pass it lies in, its verdict and its errors against that pass' own truth
  (:func:`horsemocap.virtuallab.laps.pass_truth`), and the combined comfort against the truth's.

``--rate-ppm right=-999``: a camera's clock rate offset (ppm) in place of the draw's (here a camera at 30000/1001 fps
labelled 30 among cameras at 30: it gains a frame every thousand).
``--genlocked``: the control, the same cameras locked together; ``--no-marker-noise``: the images' own noise only
(the sync and the passes without the rig's depth scatter of correlated centroid noise). Each run is the default analysis
(:func:`horsemocap.pipeline.analyze` with no parameters).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from horsemocap import accuracy, quality
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.virtuallab import load_truth
from horsemocap.virtuallab.laps import LAPS_NOISE, LapsPlan, laps_session, pass_truth

KEYS = ("acc_y_Wb_rms", "acc_y_Wk_rms")


def _span(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def _errors(analysis, truth) -> str:
    st = accuracy.stage_errors(analysis, truth)
    indicators = getattr(analysis.comfort, "indicators", None)
    if indicators is None:
        return f"A_y {st.get('saddle_acc_y_rmse_pct_of_rms', np.nan):6.1f} % (comfort not computed)"
    ce = accuracy.comfort_errors(indicators, truth.comfort, KEYS)
    return (f"A_y {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} % Wb {ce.get('acc_y_Wb_rms', np.nan):+6.1f} % "
            f"Wk {ce.get('acc_y_Wk_rms', np.nan):+6.1f} %")


def _offsets(analysis, truth) -> str:
    found = analysis.synchronisation.offsets_with_fraction(analysis.session.reference_camera)
    true = truth.extras.get("true_offsets_frames", {})
    return " ".join(f"{c} {found[c]:.3f} ({found[c] - true[c]:+.3f})" for c in found if c in true and c != "left")


def _timing(truth) -> str:
    t = truth.extras["camera_timing"]
    return " ".join(f"{c} {v['phase_frames']:.2f}/{1000 * v['rolling_shutter_s']:.0f}ms" for c, v in t.items())


def _rates(text: str | None) -> dict | None:
    """``"right=-999,middle=20"`` -> ``{"right": -999.0, "middle": 20.0}`` (None for None)."""
    return None if not text else {c: float(v) for c, v in (part.split("=") for part in text.split(","))}


def run_draw(index: int, genlocked: bool, noise, rate_ppm=None) -> str:
    folder = laps_session(laps=1, lap_s=8.0, timing_index=index, genlocked=genlocked, marker_noise=noise,
                          rate_ppm=rate_ppm)
    truth = load_truth(folder)
    head = f"draw {index} [{_timing(truth)}]"
    t0 = time.perf_counter()
    try:
        a = analyze(folder, progress=lambda *x: None)
    except AnalysisError as exc:
        return f"{head}\n    exit 2 ({exc.step}: {str(exc)[:150]})"
    checks = quality.post_checks(a)
    verdict = quality.verdict(checks)
    flagged = ", ".join(c.name + (f" {c.figure:.0f} %" if c.name == "saddle_scatter" and c.figure is not None else "")
                        for c in checks if c.level in ("warning", "unreliable"))
    return (f"{head}\n    exit {3 if verdict == 'unreliable' else 0} {verdict} ({flagged}); offsets {_offsets(a, truth)}; "
            f"{_errors(a, truth)}; {time.perf_counter() - t0:.0f} s")


def run_laps(laps: int, lap_s: float, index: int, genlocked: bool, noise, rate_ppm=None) -> str:
    folder = laps_session(laps=laps, lap_s=lap_s, timing_index=index, genlocked=genlocked, marker_noise=noise,
                          rate_ppm=rate_ppm, progress=print)
    truth = load_truth(folder)
    plan = LapsPlan.from_dict(truth.extras["laps"])
    t0 = time.perf_counter()
    lines = [f"laps {laps} x {lap_s:g} s, draw {index} [{_timing(truth)}]{' genlocked' if genlocked else ''}: {folder}"]
    try:
        a = analyze(folder, progress=lambda *x: None)
    except AnalysisError as exc:
        return "\n".join(lines + [f"    exit 2 ({exc.step}: {exc})"])
    lines.append(f"    analysed in {time.perf_counter() - t0:.0f} s; verdict {quality.verdict(quality.post_checks(a))}; offsets "
                 f"{_offsets(a, truth)}")
    ref = a.synchronisation.offsets[a.session.reference_camera]
    passes = a.passes.passes if a.passes is not None else ()
    truths = {}
    for p in passes:
        k0 = ref + p.run[0]
        lap = [i for i in range(plan.laps) if plan.pass_window(i)[0] <= k0 < plan.pass_window(i)[1]]
        if p.analysis is None or not lap:
            lines.append(f"    pass {p.index} (frames {p.run[0]}..{p.run[1] - 1}): {p.verdict} {p.error}")
            continue
        truths.setdefault(lap[0], pass_truth(folder, lap[0]))
        lines.append(f"    pass {p.index} (frames {p.run[0]}..{p.run[1] - 1}, lap {lap[0]}): {p.verdict:10s} "
                     f"{_errors(p.analysis, truths[lap[0]])}")
    found = {i for i in truths}
    lines.append(f"    passes found {len(passes)}, analysed in {len(found)} of {plan.laps} laps")
    if a.passes is not None and a.passes.combined:
        ce = accuracy.comfort_errors(a.passes.combined, truth.comfort, KEYS)
        lines.append("    combined comfort: " + ", ".join(f"{k} {v:+.1f} %" for k, v in ce.items()))
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", default="400-409")
    ap.add_argument("--laps", type=int, default=0)
    ap.add_argument("--lap-s", type=float, default=30.0)
    ap.add_argument("--genlocked", action="store_true")
    ap.add_argument("--no-marker-noise", action="store_true")
    ap.add_argument("--rate-ppm", default=None)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    draws = _span(args.draws)
    noise = None if args.no_marker_noise else LAPS_NOISE
    out = []
    if args.laps:
        out.append(run_laps(args.laps, args.lap_s, draws[0], args.genlocked, noise, _rates(args.rate_ppm)))
        print(out[-1], flush=True)
    else:
        for d in draws:
            out.append(run_draw(d, args.genlocked, noise, _rates(args.rate_ppm)))
            print(out[-1], flush=True)
    if args.out:
        args.out.write_text("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
