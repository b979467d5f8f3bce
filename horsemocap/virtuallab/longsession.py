"""A long session: ten minutes of three cameras, composed fast.

The renderer draws a few hundred frames in about a minute: 3 cameras x
18,000 frames (ten minutes at 30 fps) would take over an hour. A long
session is mostly empty arena between the horse's passes, so it is composed
instead of rendered frame by frame:

* the first ``offsets[c] + n_pass`` frames of each camera are exactly the
  frames :func:`~horsemocap.virtuallab.render_session` draws for the same
  horse, gait and seed (the flash, then the horse's pass across the views);
* the pass (its frames after the flash) comes again every ``pass_period_s``
  seconds, the same rendered frames, as a rider going round the arena
  passes the cameras once a lap;
* every other frame is the camera's empty arena (blurred as the renderer
  blurs) with fresh glints and fresh sensor noise of the renderer's model
  (``sigma^2 = 2.2^2 + 0.04 I``), drawn with OpenCV's generator.

The truth (``truth/``) is that of the first pass, exact (the single-pass
session's :func:`~horsemocap.virtuallab.build_truth`); pass ``i`` shows the
same motion ``pass_starts[i]`` frames later (``truth.json``, extras
``long_session``). The videos are written into the render cache on demand
(:func:`long_session`) and never committed: about 0.5 GB for ten minutes.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import cv2
import numpy as np

from ..camera import write_rig
from ..data import cache_dir
from ..store import atomic_write_json
from .herd import RENDER_VERSION, render_into_cache
from .render import add_glints
from .rig import FPS
from .session import (_scene_and_backgrounds, _write_video, build_truth, flash_frames, plan_timeline,
                      render_motion_frame, session_json, write_stills)
from .truth import save_truth

#: Bump when the composition changes (part of the cache key).
LONG_VERSION = 1
#: Seconds between the starts of two passes (a lap of the arena).
PASS_PERIOD_S = 30.0
#: The renderer's noise model (:func:`horsemocap.virtuallab.render.finish`).
_BLUR_SIGMA, _NOISE_SIGMA = 0.55, 2.2


def pass_starts(n_frames: int, n_pass: int, period_frames: int) -> list[int]:
    """Motion frames (0 = the flash) where each pass starts; every pass ends before ``n_frames``."""
    return [int(p) for p in range(0, n_frames - n_pass + 1, int(period_frames))]


class EmptyArena:
    """Empty-arena frames of one camera with fresh glints and sensor noise."""

    def __init__(self, bg: np.ndarray, seed: int):
        self.base = cv2.GaussianBlur(bg.astype(np.float32), (0, 0), _BLUR_SIGMA)
        sig = np.clip(self.base, 0, None) * np.float32(0.04) + np.float32(_NOISE_SIGMA ** 2)
        self.sigma = np.sqrt(sig).astype(np.float32)
        self.z = np.empty(self.base.shape, np.float32)
        self.rng = np.random.default_rng(seed)
        cv2.setRNGSeed(int(seed) % (2 ** 31))

    def frame(self) -> np.ndarray:
        img = self.base.copy()
        add_glints(img, self.rng, 5.0)
        cv2.randn(self.z, 0.0, 1.0)
        img += cv2.multiply(self.z, self.sigma)
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def render_long(out_dir, n_frames: int = 18000, *, horse: str = "Horse 2", gait: str = "canter", seed: int = 0,
                pass_period_s: float = PASS_PERIOD_S, progress=None) -> Path:
    """Compose a long session into ``out_dir`` (see the module docstring).

    Parameters
    ----------
    n_frames : int
        Frames after the flash in every camera (18,000: ten minutes at 30 fps);
        each video holds its camera's offset more.
    pass_period_s : float
        Seconds between the horse's passes.
    progress : callable, optional
        ``progress(message)`` every 3000 frames written.
    """
    t_start = time.perf_counter()
    say = progress or (lambda *_: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene, bgs = _scene_and_backgrounds(horse, gait, seed)
    rig = scene.rig
    offsets, n_pass = plan_timeline(scene, FPS)
    n_frames = int(n_frames)
    if n_frames < n_pass:
        raise ValueError(f"long session: {n_frames} frames cannot hold one pass ({n_pass} frames)")
    period = max(n_pass + 1, int(round(pass_period_s * FPS)))
    starts = pass_starts(n_frames, n_pass, period)
    F = flash_frames(FPS)
    motion_paths = {}
    for ci, cam in enumerate(rig):
        o = offsets[cam.name]
        passed = [render_motion_frame(scene, cam, o + j, o, bgs[cam.name], noise=True) for j in range(n_pass)]
        empty = EmptyArena(bgs[cam.name], int(np.random.SeedSequence([seed, 7, ci]).generate_state(1)[0] >> 1))
        in_pass = np.full(n_frames, -1)
        for p in starts:
            in_pass[p + (0 if p == 0 else F):p + n_pass] = np.arange(0 if p == 0 else F, n_pass)

        def frames(cam=cam, o=o, passed=passed, empty=empty, in_pass=in_pass):
            for k in range(o):                                  # before the flash: as rendered
                yield render_motion_frame(scene, cam, k, o, bgs[cam.name], noise=True)
            for j in range(n_frames):
                yield passed[in_pass[j]] if in_pass[j] >= 0 else empty.frame()
                if (j + 1) % 3000 == 0:
                    say(f"long session: camera {cam.name!r} {j + 1}/{n_frames} frames "
                        f"({time.perf_counter() - t_start:.0f} s)")
        _write_video(out / "motion" / f"{cam.name}.avi", frames(), cam.size, FPS, True)
        motion_paths[cam.name] = f"motion/{cam.name}.avi"
        del passed
    stills = write_stills(out, scene, bgs)
    (out / "calibration").mkdir(exist_ok=True)
    write_rig(rig, out / "calibration" / "rig.toml")
    truth = build_truth(scene, offsets, {c: offsets[c] + n_pass for c in offsets}, FPS)
    truth.extras["long_session"] = {"n_frames_after_flash": n_frames, "pass_frames": n_pass,
                                    "pass_starts": starts, "first_pass_exact": True,
                                    "repeated_pass_frames": [F, n_pass], "pass_period_frames": period}
    truth.extras["noise"] = True
    truth.extras["compress"] = True
    save_truth(truth, out)
    meta = {"horse": horse, "gait": gait, "direction": "CCW", "rider": "A", "seed": int(seed),
            "generator": "horsemocap.virtuallab.longsession", "virtual": True, "passes": len(starts)}
    sj = session_json(f"long_{n_frames}", meta, motion_paths, stills, False, fps=FPS)
    atomic_write_json(out / "session.json", sj)
    say(f"long session: {len(starts)} passes, {n_frames} frames per camera, composed in "
        f"{time.perf_counter() - t_start:.0f} s")
    return out


def long_key(n_frames: int, horse: str, gait: str, seed: int, pass_period_s: float) -> str:
    """Cache key: the composition's parameters and the renderer versions."""
    blob = json.dumps({"v": LONG_VERSION, "render": RENDER_VERSION, "n": int(n_frames), "horse": horse,
                       "gait": gait, "seed": int(seed), "period": float(pass_period_s)}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


def long_session(n_frames: int = 18000, *, horse: str = "Horse 2", gait: str = "canter", seed: int = 0,
                 pass_period_s: float = PASS_PERIOD_S, cache=None, force: bool = False, progress=None) -> Path:
    """Path of a long session, composed into the render cache if needed.

    The folder is ``<cache>/virtuallab/long_<n_frames>-<key>``, composed in a
    ``.partial`` folder and renamed when complete (as the herd and hard
    sessions). Ten minutes (the default) take a few minutes to compose and
    about 0.5 GB; ``long_session(1200, pass_period_s=10.0)`` is a short
    recording of four passes (``pass_starts`` 0, 300, 600, 900), composed in
    about the time of rendering one pass.
    """
    root = Path(cache) if cache else cache_dir()
    folder = root / "virtuallab" / f"long_{int(n_frames)}-{long_key(n_frames, horse, gait, seed, pass_period_s)}"
    render_into_cache(folder, lambda tmp: render_long(tmp, n_frames, horse=horse, gait=gait, seed=seed,
                                                     pass_period_s=pass_period_s, progress=progress),
                      "horsemocap.virtuallab.longsession.long_session", force)
    return folder
