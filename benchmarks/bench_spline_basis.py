"""The spline_basis check against the truth: long passes at 30-200 fps through analyze's rigid-body step.

The trot of ``tests/test_spline_basis.py`` (1.7 Hz, harmonics to 6.8 Hz, the stride wandering 2 % over 14 s,
three markers, 0.5 mm white noise, the saddle hidden) at several rates and lengths: the saddle acceleration's
error against the truth (% of its rms), the knot step of the fit, the check's figure
(:func:`horsemocap.basis_check.basis_resolution`) and level. Run from the repository's root:

    python benchmarks/bench_spline_basis.py      (writes nothing; results/spline_basis.txt holds a run)
"""
import sys
import time
from pathlib import Path

from horsemocap import quality
from horsemocap.threads import blas_single_threaded

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_spline_basis import _analysed  # noqa: E402  (the test's trot, not copied)
with blas_single_threaded():
    for fps, n in [(50, 600), (50, 800), (50, 1200), (50, 1600), (50, 2000), (100, 800), (100, 1200), (100, 1600), (100, 3000), (30, 600), (30, 900), (200, 4000)]:
        t0 = time.time()
        rb, err = _analysed(n, float(fps))
        r = rb.basis_resolution
        c = quality.check_spline_basis(r) if r is not None else None
        w = getattr(rb.pose, "windows", None)
        print(f"{fps:5.0f} fps {n:5d} frames ({'windows' if w is not None else 'whole'}): saddle acc error {err:5.1f} %; "
              f"knot step {r.knot_step} ({1000 * r.knot_spacing_s:.0f} ms), spline_basis {r.difference_pct:5.1f} % -> {c.level} ({time.time() - t0:.0f} s)", flush=True)
