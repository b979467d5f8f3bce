"""``horsemocap batch``: N sessions on W worker processes against the same sessions one after another.

Copies of the bundled session (and, with ``--herd``, the virtual herd
sessions already rendered into the render cache) are analysed twice into
fresh folders: serially in this process (``--workers 1``: ``run_analysis``
one after another, as ``horsemocap analyze`` one by one) and with ``W``
workers. The user-level board cache is warmed first and shared by both runs,
so both measure the analysis proper. Reports the wall times, their ratio,
the mean time per session, whether every ``comfort.csv`` is byte-identical
between the two runs, and the load average before and after.

Usage: ``python benchmarks/bench_batch.py [--copies 8] [--workers 2] [--herd]``;
writes ``benchmarks/results/batch.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from horsemocap.batch import run_batch
from horsemocap.data import cache_dir, default_session_dir

OUT = Path(__file__).resolve().parent / "results" / "batch.json"


class _Quiet:
    """A progress that shows nothing (the benchmark prints its own lines)."""

    workers = 1

    def finished(self, row):
        pass


def _sessions(root: Path, copies: int, herd: bool) -> list:
    out = []
    for k in range(copies):
        target = root / f"canter{k + 1:02d}"
        shutil.copytree(default_session_dir(), target)
        out.append(target)
    if herd:
        out += sorted(p for p in (cache_dir() / "virtuallab").glob("horse*") if (p / "session.json").is_file())
    return out


def _timed(sessions, out: Path, workers: int):
    load = os.getloadavg()[0]
    start = time.perf_counter()
    summary = run_batch(sessions, out, workers=workers, progress=_Quiet())
    wall = time.perf_counter() - start
    return {"workers": workers, "wall_s": wall, "load_before": load, "load_after": os.getloadavg()[0],
            "per_session_s": [r["seconds"] for r in summary.rows], "failed": summary.failed}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--copies", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--herd", action="store_true", help="add the herd sessions of the render cache")
    args = ap.parse_args(argv)
    root = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    sessions = _sessions(root / "sessions", args.copies, args.herd)
    warm = run_batch(sessions[:1], root / "warm", workers=1, progress=_Quiet())   # the board cache warmed
    serial = _timed(sessions, root / "serial", 1)
    parallel = _timed(sessions, root / "parallel", args.workers)
    names = sorted(p.name for p in (root / "serial").iterdir() if p.is_dir())
    identical = all((root / "serial" / n / "comfort.csv").read_bytes()
                    == (root / "parallel" / n / "comfort.csv").read_bytes() for n in names)
    result = {"sessions": len(sessions), "copies_of_bundled": args.copies, "herd_sessions": len(sessions) - args.copies,
              "cpu_count": os.cpu_count(), "warm_up_s": warm.seconds, "serial": serial, "parallel": parallel,
              "ratio_parallel_to_serial": parallel["wall_s"] / serial["wall_s"],
              "comfort_csv_identical": identical}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    print(f"{len(sessions)} sessions: serial {serial['wall_s']:.1f} s (load {serial['load_before']:.1f}), "
          f"{args.workers} workers {parallel['wall_s']:.1f} s (load {parallel['load_before']:.1f}); "
          f"ratio {result['ratio_parallel_to_serial']:.2f}; comfort.csv identical: {identical}")
    shutil.rmtree(root, ignore_errors=True)
    return result


if __name__ == "__main__":
    main()
