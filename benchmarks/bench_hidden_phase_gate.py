"""The linearised gate against the search, for cameras behind a fully lit flash (review item R6).

For each session folder given, the default analysis runs up to the detect step; when the flash lit every
camera's first lit frame fully (the detect step then asks whether free-running cameras hide behind it,
:func:`horsemocap.steps.detect._phases_behind_a_full_flash`), the markers' phases are measured on the same
inputs both ways: the linearised step at zero phase (:func:`horsemocap.subframe.linearised_phases`, the gate)
and the search (:func:`horsemocap.subframe.refine_phases` from zero). Per session it prints both phases with
their uncertainties, the gate's verdict (``skip``: the cameras stay genlocked without the search), what the
search alone would decide (``FREE`` / ``gen``), the largest difference of the two phases in the search's
uncertainties, and both times. Sessions whose flash lit a first frame partly are said and skipped.

Usage: ``python benchmarks/bench_hidden_phase_gate.py SESSION_DIR ...`` (e.g. the cached sessions of the
virtual laboratory, ``~/.cache/horsemocap/virtuallab/horse1_walk-*``).
"""
import sys
import time

from horsemocap import subframe
from horsemocap.pipeline import analyze
from horsemocap.steps import detect


def _inputs(path):
    """The detect step's inputs to the hidden-phase check of ``path``, or None when the check does not run."""
    got = []

    def capture(session, sync, rig, marker_px, progress):
        got.append((session, rig, marker_px))
        return sync

    real = detect._phases_behind_a_full_flash
    detect._phases_behind_a_full_flash = capture
    try:
        analyze(path, until="detect", progress=lambda *a: None, write_outputs=False)
    finally:
        detect._phases_behind_a_full_flash = real
    return got[0] if got else None


def main(paths):
    for path in paths:
        inputs = _inputs(path)
        name = path.rstrip("/").rsplit("/", 1)[-1]
        if inputs is None:
            print(f"{name}: the flash lit a first frame partly (no hidden-phase check)", flush=True)
            continue
        session, rig, px = inputs
        ref, zero = session.reference_camera, {c: 0.0 for c in session.cameras}
        others = [c for c in session.cameras if c != ref]
        times = detect.observation_frames(session, rig, px)
        t0 = time.perf_counter()
        quick = subframe.linearised_phases(rig, px, zero, ref, times=times)
        t1 = time.perf_counter()
        fits = subframe.refine_phases(rig, px, zero, ref, times=times)
        t2 = time.perf_counter()
        free = any(abs(f.phase) > max(detect.HIDDEN_PHASE_Z * f.uncertainty, detect.HIDDEN_PHASE_MIN_FRAMES)
                   for f in fits.values())
        apart = max(abs(quick[c].phase - fits[c].phase) / fits[c].uncertainty for c in others) if quick else float("nan")
        print(f"{name}: gate " + " ".join(f"{quick[c].phase:+.4f}+-{quick[c].uncertainty:.4f}" for c in others if c in quick)
              + f" {'SEARCH' if detect.phases_may_be_hidden(quick, others) else 'skip'} ({t1 - t0:.3f} s) | search "
              + " ".join(f"{fits[c].phase:+.4f}+-{fits[c].uncertainty:.4f}" for c in others)
              + f" {'FREE' if free else 'gen'} ({t2 - t1:.2f} s) | apart {apart:.2f} unc", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
