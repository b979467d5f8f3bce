"""Free-running cameras through the default analysis: does it finish, the verdict, errors vs the truth.

Renders (on demand, into the cache) free-running sessions of the virtual laboratory
(:func:`horsemocap.virtuallab.herd.herd_free_running`, :func:`horsemocap.virtuallab.hard.hard_free_running`,
timing set ``--seed``) and runs the default analysis on each (:func:`horsemocap.pipeline.analyze` with no
parameters, what ``horsemocap analyze SESSION --out DIR`` runs). Per session it prints the frame rate, image
size and drawn camera timings, then the exit status the command would give (3 when the verdict is unreliable,
2 when a step stops), the verdict, the checks flagged (warning or unreliable) and the sync residual, the saddle's vertical acceleration error (% of rms), the Wb and Wk rms
errors (%), and the offsets found (frames after the reference camera's, with the fraction and its uncertainty; the flash's own in brackets
when the markers corrected them) against the true fractional offsets.

``--centroids`` adds, per camera, the detected centroids' error against the truth's projections at their
instants over the analysed frames: rms, and the standard deviation along the image's rows (u) and columns (v)
(px); for an interlaced camera also the fields' fitted vertical sampling error ``(a, b)`` and the marker-frames
that kept the blended frame's centroid (:class:`horsemocap.steps.detect.FieldsMeasured`).

``--genlocked`` runs the control: the same sessions, cameras and exposures with the cameras locked together
(phase 0, no rate offset, no rolling shutter), so what the timing alone costs shows.

Usage: ``python benchmarks/bench_freerun.py [--seed 0] [--genlocked] [--centroids] [NAME ...]`` (default: the three
sessions of ``results/freerun_before.txt``).
"""
import argparse
import time

import numpy as np

from horsemocap import accuracy, quality
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.virtuallab.hard import FREE_RUNNING_HARD, hard_free_running
from horsemocap.virtuallab.herd import FREE_RUNNING_HERD, herd_free_running
from horsemocap.virtuallab.truth import camera_timings, load_truth, true_offsets_frames

DEFAULT = ("free_horse2_sitting_trot_30", "free_canter720_toedin_60", "free_pal576_sitting_25_interlaced")
#: Offset errors (frames) and reported uncertainties of every run, for the summary line.
ERRORS: list = []


def session_folder(name: str, seed: int, genlocked: bool = False):
    if name in FREE_RUNNING_HERD:
        return herd_free_running(seed, names=[name], genlocked=genlocked)[name]
    if name in FREE_RUNNING_HARD:
        return hard_free_running(seed, names=[name], genlocked=genlocked)[name]
    raise SystemExit(f"unknown session {name!r}; expected one of {sorted(FREE_RUNNING_HERD) + sorted(FREE_RUNNING_HARD)}")


def describe(truth) -> str:
    size = truth.rig[truth.cameras[0]].size
    parts = []
    for cam, t in camera_timings(truth).items():
        extra = f" interlaced {t.interlaced}" if t.interlaced else f" readout {t.rolling_shutter_s * 1e3:4.1f} ms"
        parts.append(f"{cam} phase {t.phase_frames:.3f} {t.rate_offset_ppm:+6.1f} ppm{extra}")
    return f"{truth.fps:.3f} fps {size[0]}x{size[1]}; " + "; ".join(parts)


def centroid_errors(a, truth) -> str:
    """Per camera: the detected centroids minus the truth's projections (matched) over the analysed frames."""
    first, last = a.detect.segment
    parts = []
    for cam, px in a.detect.marker_px.items():
        m = px.shape[1]
        frames = a.synchronisation.offsets[cam] + np.arange(px.shape[0])
        diffs = []
        for k in range(first, min(last, px.shape[0])):
            if frames[k] >= truth.marker_px[cam].shape[0]:
                continue
            true = truth.marker_px[cam][frames[k], :m].copy()
            true[~truth.marker_visible[cam][frames[k], :m]] = np.nan
            pairs, _ = accuracy.match_points(px[k], true)
            diffs.extend(px[k, i] - true[j] for i, j in pairs)
        d = np.asarray(diffs)
        measured = a.detect.fields.get(cam)
        by_fields = "" if measured is None else (
            f"; fields: error ({measured.aliasing_px[0]:+.3f}, {measured.aliasing_px[1]:+.3f}) px"
            f"{'' if not measured.aliasing_note else ' not removed'}, {measured.kept_blended} kept blended")
        parts.append(f"{cam} rms {np.sqrt(np.mean(np.sum(d ** 2, axis=1))):.3f}, sd u {d[:, 0].std():.3f}, "
                     f"v {d[:, 1].std():.3f} ({len(d)}){by_fields}")
    return "\n  centroids vs truth (px): " + "; ".join(parts)


def run(name: str, seed: int, genlocked: bool = False, centroids: bool = False) -> str:
    folder = session_folder(name, seed, genlocked)
    truth = load_truth(folder)
    true = true_offsets_frames(truth)
    head = f"{name}{' (genlocked control)' if genlocked else ''}\n  {describe(truth)}\n  true offsets (frames after left): " + \
        ", ".join(f"{c} {v:.3f}" for c, v in true.items() if c != "left")
    t0 = time.perf_counter()
    try:
        a = analyze(folder, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        try:
            sy = analyze(folder, None, {}, until="sync", progress=lambda *x: None).synchronisation
            frac = sy.offsets_with_fraction("left")
            found = ", ".join(f"{c} {frac[c]:.3f} (error {frac[c] - true[c]:+.3f})" for c in truth.cameras[1:])
            ERRORS.extend((abs(frac[c] - true[c]), None) for c in truth.cameras[1:])
        except AnalysisError as sync_exc:
            found = f"none ({sync_exc})"
        return (f"{head}\n  exit 2, stopped: {exc}\n  flash offsets found: {found}  "
                f"({time.perf_counter() - t0:.0f} s)")
    checks = quality.post_checks(a)
    verdict = quality.verdict(checks)
    flagged = "; ".join(f"{c.name} {c.level}" for c in checks if c.level in ("warning", "unreliable")) or "none"
    sync_resid = next((c for c in checks if c.name == "sync_residual"), None)
    sync_text = "" if sync_resid is None else f"; sync residual {sync_resid.figure:.3f} px ({sync_resid.level})"
    st = accuracy.stage_errors(a, truth)
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms"))
    sync = a.synchronisation
    ref = sync.offsets["left"]
    found = []
    frac = sync.offsets_with_fraction("left")
    for c in truth.cameras[1:]:
        got = frac[c]
        flash = "" if not sync.flash_offsets else f" [flash {sync.flash_offsets[c] - sync.flash_offsets['left']}]"
        unc = sync.offset_uncertainty_frames.get(c)
        ERRORS.append((abs(got - true[c]), unc))
        found.append(f"{c} {got:.3f}{'' if unc is None else f' +- {unc:.3f}'}{flash} (error {got - true[c]:+.3f})")
    first, last = a.triangulate.segment
    frames = f"{last - first} of {sync.n_frames}"
    return (f"{head}\n  exit {3 if verdict == 'unreliable' else 0}, verdict {verdict}; saddle A_y error "
            f"{st['saddle_acc_y_rmse_pct_of_rms']:.1f} % of rms; Wb rms {ce['acc_y_Wb_rms']:+.1f} %, Wk rms "
            f"{ce['acc_y_Wk_rms']:+.1f} %; frames analysed {frames}\n  checks flagged: {flagged}{sync_text}"
            "\n  offsets found: " + ", ".join(found) +
            f"  ({time.perf_counter() - t0:.0f} s)" + (centroid_errors(a, truth) if centroids else ""))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=list(DEFAULT))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--genlocked", action="store_true",
                        help="the control: the same sessions with the cameras locked together")
    parser.add_argument("--centroids", action="store_true",
                        help="per camera, the centroids' error against the truth's projections")
    args = parser.parse_args()
    for name in args.names:
        print(run(name, args.seed, args.genlocked, args.centroids), flush=True)
    if ERRORS:
        err = np.array([e for e, _ in ERRORS])
        ratio = np.array([e / u for e, u in ERRORS if u])
        print(f"offsets: median |error| {np.median(err):.3f} frame, worst {err.max():.3f} over {err.size}"
              + (f"; |error| / reported uncertainty: median {np.median(ratio):.2f}, worst {ratio.max():.2f}, "
                 f"{np.mean(ratio <= 2):.0%} within 2" if ratio.size else ""))


if __name__ == "__main__":
    main()
