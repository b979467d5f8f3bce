"""`horsemocap kinematics` on long records: time and peak memory against the record's length.

A rigid cluster of 4 markers (and a hidden point) trotting at 1.7 Hz for N
frames at 200 Hz with 0.5 mm marker noise, exact truth from
:class:`horsemocap.synthetic.Jet`. Writes the record with the trajectories.csv
layout, runs the command in a child process (``/usr/bin/time``-like peak RSS
from ``resource.getrusage(RUSAGE_CHILDREN)``) and compares the hidden point's
acceleration with the truth.

    python benchmarks/bench_streaming_kinematics.py 10000 100000 [--log FILE]

``--log FILE``: the command's progress (its stderr) goes to FILE as it runs.
The load average (1 min) is sampled every 10 s during the command's run.
"""
from __future__ import annotations

import argparse
import csv
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from horsemocap.synthetic import Jet, _rotation_jets

FPS = 200.0
MODEL = np.array([[0.20, 0.10, 0.15], [-0.20, 0.10, 0.15], [0.05, 0.10, -0.15], [-0.20, -0.02, -0.15]])
HIDDEN = np.array([0.20, -0.10, -0.15])


def sine(t, amplitude, hz, phase=0.0) -> Jet:
    w = 2 * np.pi * hz
    s, c = np.sin(w * t + phase), np.cos(w * t + phase)
    return Jet(amplitude * s, amplitude * w * c, -amplitude * w * w * s)


def trot(n: int, noise_m: float = 5e-4, seed: int = 0, start: int = 0) -> dict:
    """Frames ``start .. start+n-1`` of the trotting cluster (markers noisy, hidden point exact)."""
    t = (start + np.arange(n)) / FPS
    f0 = 1.7
    x = Jet(1.5 * t, np.full(n, 1.5), np.zeros(n)) + sine(t, 0.01, f0)
    y = sine(t, 0.03, 2 * f0) + sine(t, 0.008, 4 * f0, 0.7) + 1.2
    z = sine(t, 0.01, f0, 0.3)
    yaw, pitch, roll = sine(t, 0.03, f0, 1.0), sine(t, 0.05, 2 * f0, 0.2), sine(t, 0.04, f0, 2.0)
    R, omega, alpha = _rotation_jets(yaw, pitch, roll)
    c = np.stack([x.f, y.f, z.f], -1)
    cdd = np.stack([x.d2, y.d2, z.d2], -1)
    mk = np.einsum("kij,mj->kmi", R, MODEL) + c[:, None]
    r = R @ HIDDEN
    acc = cdd + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))
    rng = np.random.default_rng(seed + start)
    return {"t": t, "markers": mk + rng.normal(0, noise_m, mk.shape), "hidden_acc": acc}


def write_record(folder: Path, n: int, chunk: int = 50_000) -> tuple[Path, Path]:
    names = ["m1", "m2", "m3", "m4"]
    traj = folder / "traj.csv"
    with open(traj, "w") as fh:
        fh.write("frame,time_s,point,x_m,y_m,z_m\n")
        for s in range(0, n, chunk):
            d = trot(min(chunk, n - s), start=s)
            fr = np.repeat(np.arange(s, s + d["t"].size), 4)
            tt = np.repeat(d["t"], 4)
            nm = np.tile(names, d["t"].size)
            xyz = d["markers"].reshape(-1, 3)
            fh.writelines(f"{a},{b:.6f},{c},{p:.6f},{q:.6f},{r:.6f}\n"
                          for a, b, c, (p, q, r) in zip(fr, tt, nm, xyz))
    static = folder / "static.csv"
    with open(static, "w") as fh:
        fh.write("frame,time_s,point,x_m,y_m,z_m\n")
        for nm, p in zip(names + ["hidden"], np.vstack([MODEL, HIDDEN])):
            fh.write(f"0,0.0,{nm},{float(p[0])!r},{float(p[1])!r},{float(p[2])!r}\n")
    return traj, static


def hidden_error(out: Path, n: int) -> float:
    """RMS error of the hidden point's acceleration (m/s^2), frames read in chunks."""
    sq, count = 0.0, 0
    with open(out / "kinematics.csv") as fh:
        rows = csv.reader(fh)
        next(rows)
        acc, frames = [], []
        for row in rows:
            if row[2] == "hidden" and row[6]:
                frames.append(int(row[0]))
                acc.append([float(v) for v in row[6:9]])
                if len(frames) == 50_000:
                    truth = trot(frames[-1] - frames[0] + 1, start=frames[0])["hidden_acc"]
                    e = np.asarray(acc) - truth[np.asarray(frames) - frames[0]]
                    sq, count = sq + float(np.sum(e ** 2)), count + len(frames)
                    acc, frames = [], []
        if frames:
            truth = trot(frames[-1] - frames[0] + 1, start=frames[0])["hidden_acc"]
            e = np.asarray(acc) - truth[np.asarray(frames) - frames[0]]
            sq, count = sq + float(np.sum(e ** 2)), count + len(frames)
    return float(np.sqrt(sq / max(count, 1)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("frames", type=int, nargs="+")
    ap.add_argument("--keep", type=Path, default=None, help="folder to keep the records in")
    ap.add_argument("--log", type=Path, default=None, help="file the command's progress goes to as it runs")
    args = ap.parse_args()
    for n in args.frames:
        with tempfile.TemporaryDirectory() as tmp:
            folder = args.keep or Path(tmp)
            folder.mkdir(parents=True, exist_ok=True)
            t0 = time.perf_counter()
            traj, static = write_record(folder, n)
            written = time.perf_counter() - t0
            out = folder / f"kin{n}"
            t0 = time.perf_counter()
            cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            loads, running = [], threading.Event()
            running.set()

            def sample_load():
                while running.is_set():
                    loads.append(os.getloadavg()[0])
                    time.sleep(10)

            sampler = threading.Thread(target=sample_load, daemon=True)
            sampler.start()
            log = open(args.log, "w") if args.log else subprocess.PIPE
            proc = subprocess.run([sys.executable, "-c", "import resource, sys; from horsemocap.cli import main; "
                                   "rc = main(sys.argv[1:]); print('peak_rss_kb', resource.getrusage("
                                   "resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr); sys.exit(rc)",
                                   "kinematics", str(traj), "--static", str(static), "--out", str(out)],
                                  stdout=subprocess.PIPE, stderr=log, text=True)
            running.clear()
            if args.log:
                log.close()
                proc.stderr = Path(args.log).read_text()
            took = time.perf_counter() - t0
            cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
            peak = [ln for ln in proc.stderr.splitlines() if ln.startswith("peak_rss_kb")]
            err = hidden_error(out, n) if proc.returncode in (0, 3) else float("nan")
            print(f"{n} frames: exit {proc.returncode}, {took:.1f} s wall, {cpu:.1f} s CPU, peak RSS "
                  f"{int(peak[0].split()[1]) / 1024 if peak else float('nan'):.0f} MB, hidden-point acceleration "
                  f"RMS error {err:.3f} m/s^2 (record written in {written:.1f} s); load average during the run "
                  f"{min(loads):.1f} .. {max(loads):.1f} (mean {np.mean(loads):.1f})", flush=True)
            if proc.returncode not in (0, 3):
                print(proc.stderr[-2000:])
            else:
                print("\n".join(ln for ln in proc.stderr.splitlines() if "windows" in ln and "[#" not in ln)[-600:])


if __name__ == "__main__":
    main()
