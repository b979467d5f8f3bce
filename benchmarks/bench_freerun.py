"""Free-running cameras through the default analysis: does it finish, the verdict, errors vs the truth.

Renders (on demand, into the cache) free-running sessions of the virtual laboratory
(:func:`horsemocap.virtuallab.herd.herd_free_running`, :func:`horsemocap.virtuallab.hard.hard_free_running`,
timing set ``--seed``) and runs the default analysis on each (:func:`horsemocap.pipeline.analyze` with no
parameters, what ``horsemocap analyze SESSION --out DIR`` runs). Per session it prints the frame rate, image
size and drawn camera timings, then the exit status the command would give (3 when the verdict is unreliable,
2 when a step stops), the verdict, the checks flagged (warning or unreliable) and the sync residual, the saddle's vertical acceleration error (% of rms), the Wb and Wk rms
errors (%), the temporal aperture the pose trajectory is fitted through (from the session's camera timing), and
the offsets found (frames after the reference camera's, with the fraction and its uncertainty; the flash's own in
brackets when the markers corrected them) against the true fractional offsets.

``--centroids`` adds, per camera, the detected centroids' error against the truth's projections at their
instants over the analysed frames: rms, and the standard deviation along the image's rows (u) and columns (v)
(px); for an interlaced camera also the fields' fitted vertical sampling error ``(a, b)`` and the marker-frames
that kept the blended frame's centroid (:class:`horsemocap.steps.detect.FieldsMeasured`).

For an interlaced camera it adds each field's own centroids (:func:`horsemocap.detection.remeasure_by_fields`)
against the truth's projections at that field's own instant, as measured and with the fitted vertical sampling
error removed; and what the fields' mean costs against two observations at their own instants: the truth's
position at the middle instant against the mean of its positions at the two fields' instants (rms and worst, px).

``--genlocked`` runs the control: the same sessions, cameras and exposures with the cameras locked together
(phase 0, no rate offset, no rolling shutter), so what the timing alone costs shows.

Usage: ``python benchmarks/bench_freerun.py [--seed 0] [--genlocked] [--centroids] [NAME ...]`` (default: the three
sessions of ``results/freerun_before.txt``).
"""
import argparse
import time

import numpy as np

from horsemocap import accuracy, quality
from horsemocap.aperture import session_aperture
from horsemocap.detection import remeasure_by_fields
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.session import load_session
from horsemocap.sources import FrameSource
from horsemocap.virtuallab.hard import build_scene, FREE_RUNNING_HARD, hard_free_running
from horsemocap.virtuallab.herd import FREE_RUNNING_HERD, herd_free_running
from horsemocap.virtuallab.session import marker_projection_truth, true_saddle_harmonics
from horsemocap.vibration import weighting
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


def _sd_text(d: np.ndarray) -> str:
    d = d[np.all(np.isfinite(d), axis=1)]
    return (f"rms {np.sqrt(np.mean(np.sum(d ** 2, axis=1))):.3f}, "
            f"mean u {d[:, 0].mean():+.3f}, v {d[:, 1].mean():+.3f}, sd u {d[:, 0].std():.3f}, v {d[:, 1].std():.3f}")


def field_centroid_errors(a, truth, folder, name: str) -> str:
    """Per interlaced camera: each field's centroids against the truth's projections at the field's own instant.

    The fields' centres are measured again around the detect step's centroids (analysed frames), as measured
    and with the fitted vertical sampling error removed (:func:`_one_field_corrected`); and the truth's mean of
    the two fields' positions against its position at the middle instant (what averaging the fields costs a
    moving marker), in px and as a filter on the true saddle acceleration (:func:`field_mean_filter_text`).
    """
    if name not in FREE_RUNNING_HARD:
        return ""
    scene = build_scene(FREE_RUNNING_HARD[name][0])[0]
    session = load_session(folder)
    first, last = a.detect.segment
    lines = []
    for cam, timing in camera_timings(truth).items():
        if not timing.interlaced:
            continue
        px = a.detect.marker_px[cam]
        offset = a.synchronisation.offsets[cam]
        seq = FrameSource(session.motion[cam]).sequence(offset, offset + px.shape[0], color=False)
        try:
            fm = remeasure_by_fields(seq, px, int(a.detect.detection[cam]["threshold"]))
        finally:
            seq.close()
        frames = offset + np.arange(first, min(last, px.shape[0]))
        frames = frames[frames < truth.marker_px[cam].shape[0]]
        m = px.shape[1]
        mid = truth.extras[f"marker_time_s__{cam}"][frames, :m]
        half = timing.field_delay_s / 2
        # parity 1 (odd rows) is the first field when bottom first
        first_parity = 1 if timing.interlaced == "bottom_first" else 0
        at = {first_parity: mid - half, 1 - first_parity: mid + half}
        own = {}
        for parity, t in at.items():
            own[parity] = np.stack([marker_projection_truth(scene, truth.rig[cam], t[:, j], ride=True)[0][:, j]
                                    for j in range(m)], axis=1)
        mid_true = truth.marker_px[cam][frames, :m]
        rebuilt = np.stack([marker_projection_truth(scene, truth.rig[cam], mid[:, j], ride=True)[0][:, j]
                            for j in range(m)], axis=1)
        check = np.nanmax(np.abs(rebuilt - mid_true))
        if check > 1e-6:
            raise SystemExit(f"{name}: the rebuilt scene does not give the truth's projections ({check:.3g} px)")
        k = frames - offset
        per_field = fm.per_field[k]
        parts = []
        for parity in (first_parity, 1 - first_parity):
            raw = per_field[:, parity] - own[parity]
            fixed = np.where(np.isfinite(per_field[:, parity]), _one_field_corrected(per_field, parity, fm.aliasing),
                             np.nan) - own[parity]
            parts.append(f"field {'1st' if parity == first_parity else '2nd'} (rows {parity}::2) "
                         f"{_sd_text(raw.reshape(-1, 2))} as measured; {_sd_text(fixed.reshape(-1, 2))} corrected")
        both = fm.marker_px[k] - mid_true
        blend = 0.5 * (own[0] + own[1]) - mid_true
        dist = np.linalg.norm(blend.reshape(-1, 2), axis=1)
        fitted = f"vertical sampling error fitted a {fm.aliasing[0]:+.3f}, b {fm.aliasing[1]:+.3f} px"
        lines.append(f"  {cam} fields ({fitted}): " + "; ".join(parts) + f"; mean {_sd_text(both.reshape(-1, 2))}; "
                     f"true mean of the fields vs middle instant rms {np.sqrt(np.nanmean(dist ** 2)):.3f}, "
                     f"worst {np.nanmax(dist):.3f} px")
    if lines:
        lines.append(field_mean_filter_text(scene, truth.fps))
    return "\n" + "\n".join(lines) if lines else ""


def field_mean_filter_text(scene, fps: float) -> str:
    """What the mean of two fields half a frame apart does to the true saddle's vertical acceleration.

    A signal's mean at ``t -+ d/2`` passes a harmonic of frequency ``f`` times ``cos(pi f d)``; the exposure's
    smear (a box of ``e`` s) times ``sinc(f e)``. Applied to the exact harmonics of the true A_y
    (:func:`horsemocap.virtuallab.session.true_saddle_harmonics`), unweighted and Wb / Wk weighted: the rms
    ratios (1 = no loss), what two observations per frame at their own instants would not lose."""
    freq, coef, _ = true_saddle_harmonics(scene.motion)
    power = np.abs(coef) ** 2 / 2
    d = 0.5 / fps
    gain = np.cos(np.pi * freq * d)
    ratios = []
    for name in ("unweighted", "Wb", "Wk"):
        w = power if name == "unweighted" else power * np.abs(weighting(name, freq)) ** 2
        ratios.append(f"{name} x{np.sqrt(np.sum(w * gain ** 2) / np.sum(w)):.4f}")
    error = np.sqrt(np.sum(power * (1 - gain) ** 2) / np.sum(power))
    return (f"  the fields' mean ({d * 1e3:.0f} ms apart) as a filter on the true saddle A_y: rms " + ", ".join(ratios)
            + f"; A_y error {100 * error:.2f} % of rms")


def _one_field_corrected(per_field: np.ndarray, parity: int, aliasing) -> np.ndarray:
    """Field ``parity``'s centres with the fitted vertical sampling error removed, (n, m, 2): the row ``r`` with
    ``v = r + E(r)`` (parity 0) or ``v = r - E(r)`` (parity 1), ``E(r) = a cos(pi r) + b sin(pi r)``, as
    :func:`horsemocap.detection.fields.corrected_mean` solves it before averaging the fields."""
    a, b = (float(c) for c in aliasing)
    out = per_field[:, parity].copy()
    sign = 1.0 if parity == 0 else -1.0
    v = out[..., 1].copy()
    row = v
    for _ in range(12):
        row = v - sign * (a * np.cos(np.pi * row) + b * np.sin(np.pi * row))
    out[..., 1] = row
    return out


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
    session = load_session(folder)
    aperture = session_aperture(session.fps, [session.camera_timing(c) for c in session.cameras])
    frames += f"; pose fitted through the aperture: {'none' if aperture is None else aperture.description}"
    return (f"{head}\n  exit {3 if verdict == 'unreliable' else 0}, verdict {verdict}; saddle A_y error "
            f"{st['saddle_acc_y_rmse_pct_of_rms']:.1f} % of rms; Wb rms {ce['acc_y_Wb_rms']:+.1f} %, Wk rms "
            f"{ce['acc_y_Wk_rms']:+.1f} %; frames analysed {frames}\n  checks flagged: {flagged}{sync_text}"
            "\n  offsets found: " + ", ".join(found) +
            f"  ({time.perf_counter() - t0:.0f} s)"
            + (centroid_errors(a, truth) + field_centroid_errors(a, truth, folder, name) if centroids else ""))


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
