"""Render timings of the virtual laboratory (not a test; run by hand).

    python benchmarks/bench_render.py [out_dir]

Prints the time per frame of each stage and of a whole session, and checks
that two renders of the same seed are byte-identical.
"""
from __future__ import annotations

import hashlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from horsemocap import virtuallab as vl
from horsemocap.virtuallab import render as R
from horsemocap.virtuallab import session as S


def digest(folder: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file() and "truth" not in p.parts:
            h.update(p.name.encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def main(out=None):
    rig = vl.thesis_rig()
    m = vl.saddle_motion()
    scene = S.Scene(rig, m, 0)
    cam = rig["left"]
    t0 = time.perf_counter()
    bg = R.render_arena(cam, m.R_wg, m.c_g)
    print(f"arena background (per camera, once): {time.perf_counter() - t0:.2f} s")
    offsets, n_after = S.plan_timeline(scene)
    o = offsets["left"]
    for label, ks in (("pre-roll frame", range(0, 5)), ("frame with the horse", range(o + 30, o + 40))):
        t0 = time.perf_counter()
        for k in ks:
            S.render_motion_frame(scene, cam, k, o, bg, noise=True)
        print(f"{label}: {(time.perf_counter() - t0) / len(ks) * 1000:.1f} ms")
    root = Path(out) if out else Path(tempfile.mkdtemp())
    times, digests = [], []
    for rep in range(2):
        t0 = time.perf_counter()
        p = vl.render_session(root / f"run{rep}")
        times.append(time.perf_counter() - t0)
        digests.append(digest(p))
    n = sum(offsets.values()) + 3 * n_after
    print(f"whole default session ({n} video frames, stills, 45 board views): {np.min(times):.1f} s")
    print("byte-identical renders:", digests[0] == digests[1])


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
