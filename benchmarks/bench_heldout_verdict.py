"""Sessions the code was not developed on, through the pipeline: exit status, verdict, errors vs the truth.

The held-out test of 2026-11-25 rendered 6 new hard scenarios (seeds 3001-3006) and 4 probes (3101-3104)
outside the package (``/work/scratch/heldout/heldout.py`` defines them; not part of the repository), and
``bench_sync.py --render-fresh DIR`` renders 6 fresh ones (seeds 4001-4006). This script runs the default
analysis on every session folder given (each with its ``truth/``) and prints per session the exit status
the command would give (3 when the verdict is unreliable, 2 when a step stops), the verdict, wrong identities,
the saddle's vertical acceleration error (% of rms), the Wb and Wk rms errors, the flash offsets against the
truth and the checks above ok.

Usage: ``python benchmarks/bench_heldout_verdict.py SESSION_DIR [...]``
(``results/heldout_verdict.txt``: the 16 sessions of 2026-11-25).
"""
import sys
import time
from horsemocap import accuracy, quality
from horsemocap.pipeline import AnalysisError, analyze
from horsemocap.virtuallab import load_truth
for d in sys.argv[1:]:
    name = d.split("/")[-1][:44]
    t0 = time.perf_counter()
    try:
        a = analyze(d, None, {}, progress=lambda *x: None)
    except AnalysisError as exc:
        print(f"{name:44s} exit 2 stopped: {str(exc)[:150]}", flush=True); continue
    except Exception as exc:
        print(f"{name:44s} CRASH {exc!r}"[:250], flush=True); continue
    checks = quality.post_checks(a)
    v = quality.verdict(checks)
    truth = load_truth(d)
    ide = accuracy.identification_errors(a, truth)
    st = accuracy.stage_errors(a, truth)
    ce = accuracy.comfort_errors(a.comfort.indicators, truth.comfort, ("acc_y_Wb_rms", "acc_y_Wk_rms"))
    bad = [f"{c.name}" for c in checks if c.level in ("warning", "unreliable")]
    print(f"{name:44s} exit {3 if v == 'unreliable' else 0} {v:10s} wrong {ide['wrong_total']:4d} "
          f"A_y {st['saddle_acc_y_rmse_pct_of_rms']:6.1f} % Wb {ce['acc_y_Wb_rms']:+6.1f} % Wk {ce['acc_y_Wk_rms']:+6.1f} % "
          f"offsets {a.synchronisation.offsets} truth {truth.offsets} {bad} {time.perf_counter() - t0:.0f}s", flush=True)
