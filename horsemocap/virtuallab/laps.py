"""A ride of several laps, filmed by cameras that run free, every pass with its own noise.

:mod:`.longsession` composes one rendered pass again and again: every pass
has the same images, so the same marker noise, and its cameras are
genlocked. A rider's own session is neither. Cameras that run free for
minutes drift against each other by their rate offsets (100 ppm is a tenth
of a frame every 33 s at 30 fps), and every pass has noise of its own. Here:

* the horse goes round the arena once every ``lap_s`` seconds
  (:class:`LapMotion`: lap ``i`` is the single pass' motion ``i * lap_s``
  later), so each pass shows the same analytic motion of the body and its
  markers (the legs and the rider are drawn at the recording's own time,
  so their stride phase differs from lap to lap: the picture, not the truth);
* every frame in which the horse can be seen is rendered at its own
  instants by :func:`~horsemocap.virtuallab.session.render_free_running_frame`
  (phase, rate, rolling shutter, exposure of its camera), with the marker
  noise of its own time (:class:`~horsemocap.virtuallab.noise.MarkerNoise`
  is a series over the recording's frames, so no two passes share it);
* every other frame is the camera's empty arena
  (:class:`~horsemocap.virtuallab.longsession.EmptyArena`).

The truth (``truth/``) is the first pass' (exact, every camera's instants);
:func:`pass_truth` gives any other pass' from the session folder alone.
``truth.json`` extras ``laps`` holds the lap and where each pass lies.

Examples
--------
>>> m = LapMotion.around(saddle_motion("Horse 2", "canter"), lap_s=20.0)
>>> p0, p1 = m.pose([1.5]).position, m.pose([21.5]).position
>>> bool(np.allclose(p0, p1)), m.lap_index([-0.1, 19.9, 20.0]).tolist()
(True, [0, 0, 1])
"""
from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from ..camera import write_rig
from ..data import cache_dir
from ..store import atomic_write_json
from .herd import HERD, RENDER_VERSION, free_running_timings, herd_seed, render_into_cache, timing_render_versions
from .horse import Gait, Harmonics, Horse, SaddleMotion, saddle_motion  # noqa: F401 (LapMotion's inherited fields' types)
from .longsession import EmptyArena
from .noise import MarkerNoise
from .rig import FPS, thesis_rig
from .timing import CameraTiming
from .session import (Scene, _scene_and_backgrounds, _static_clip_times, _write_video, build_truth, flash_frames,
                      free_running_frame_starts, plan_timeline, render_free_running_frame, session_json,
                      write_stills)
from .truth import Truth, load_truth, save_truth

#: Bump when the laps' rendering changes (part of the cache key).
LAPS_VERSION = 1
#: The timing draws of the laps' cameras (:func:`~horsemocap.virtuallab.herd.free_running_timings`, set 0).
LAPS_TIMING_INDEX = 400
#: Marker noise of the laps: as the correlated-noise hard and herd sessions (px, AR(1), px).
LAPS_NOISE = MarkerNoise(sigma_px=0.1, rho=0.8, bias_px=0.05)
#: How far (m) the horse goes after its markers have left every view before its body has too (the frames
#: rendered after a pass: this over the gait's speed).
BODY_TAIL_M = 3.0
#: Frames of the static clip (the horse standing, its markers' noise evolving).
STATIC_FRAMES = 15


@dataclass(frozen=True)
class LapMotion(SaddleMotion):
    """A :class:`SaddleMotion` that starts again every ``lap_s`` seconds (one pass of the cameras per lap).

    Times before 0 are the first lap's; lap ``i`` covers ``[i * lap_s, (i + 1) * lap_s)``.
    """

    lap_s: float = 30.0

    @classmethod
    def around(cls, motion: SaddleMotion, lap_s: float) -> "LapMotion":
        """``motion`` repeated every ``lap_s`` seconds."""
        if not (np.isfinite(lap_s) and lap_s > 0):
            raise ValueError(f"lap_s: expected a positive lap time (s), got {lap_s!r}")
        return cls(**{f.name: getattr(motion, f.name) for f in fields(motion)}, lap_s=float(lap_s))

    def lap_index(self, t) -> np.ndarray:
        """The lap of each time ``t`` (s): 0 before the first lap's end, including negative times."""
        t = np.atleast_1d(np.asarray(t, float))
        return np.maximum(np.floor(t / self.lap_s), 0).astype(int)

    def pose_ground(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        _, P, V, A, ang = super().pose_ground(t - self.lap_index(t) * self.lap_s)
        return t, P, V, A, ang

    def to_dict(self):
        return {**super().to_dict(), "lap_s": float(self.lap_s)}


@dataclass(frozen=True)
class LapsPlan:
    """Where the passes lie in a laps session (all times from the flash's onset, s).

    Attributes
    ----------
    lap_s : float
        Seconds from one pass' start to the next.
    laps : int
        Number of passes.
    pass_frames : int
        Frames of one pass after its start, until its markers left every view.
    visible_s : float
        Seconds after a pass' start in which any part of the horse may be seen (frames rendered).
    n_frames : int
        Frames of every camera after its flash frame (its offset).
    offsets : dict
        Each camera's frame of the flash (the start delays).
    """

    lap_s: float
    laps: int
    pass_frames: int
    visible_s: float
    n_frames: int
    offsets: dict

    def pass_window(self, i: int, fps: float = FPS, reference: str = "left") -> tuple[int, int]:
        """Reference frames (the video's numbering) of pass ``i``: its start to its last visible frame."""
        o = self.offsets[reference]
        k0 = o + int(round(i * self.lap_s * fps))
        return k0, k0 + self.pass_frames

    def to_dict(self) -> dict:
        return {"lap_s": self.lap_s, "laps": self.laps, "pass_frames": self.pass_frames,
                "visible_s": self.visible_s, "n_frames_after_flash": self.n_frames, "offsets": dict(self.offsets)}

    @classmethod
    def from_dict(cls, d: dict) -> "LapsPlan":
        """The plan :meth:`to_dict` wrote (``truth.json`` extras ``laps``)."""
        return cls(d["lap_s"], d["laps"], d["pass_frames"], d["visible_s"], d["n_frames_after_flash"], d["offsets"])


def plan_laps(scene: Scene, laps: int, lap_s: float, fps: float = FPS) -> LapsPlan:
    """The timeline of ``laps`` passes ``lap_s`` apart of the (single-pass) ``scene``.

    Raises
    ------
    ValueError
        When a lap is shorter than the time the horse is in view (the passes would overlap).
    """
    if int(laps) < 1:
        raise ValueError(f"laps: expected at least one pass, got {laps!r}")
    offsets, n_pass = plan_timeline(scene, fps)
    visible = n_pass / fps + BODY_TAIL_M / max(scene.motion.gait.speed_mps, 0.5)
    if lap_s <= visible + 1.0:
        raise ValueError(f"lap_s: {lap_s:g} s cannot hold a pass: the horse is in view for {visible:.1f} s "
                         "(expected a lap at least a second longer)")
    n_frames = int(np.ceil(((int(laps) - 1) * lap_s + visible) * fps))
    return LapsPlan(float(lap_s), int(laps), int(n_pass), float(visible), n_frames, dict(offsets))


def _frames(scene: Scene, cam, timing, plan: LapsPlan, bg, seed: int, fps: float):
    """Every frame of one camera: rendered while the horse may be seen (or the flash is on), else empty arena."""
    o = plan.offsets[cam.name]
    starts = free_running_frame_starts(timing, o, o + plan.n_frames)
    middle = starts + timing.exposure / 2
    lap = scene.motion.lap_index(middle)
    into = middle - lap * plan.lap_s
    flash_end = flash_frames(fps) / fps + 2.0 / fps
    render = (middle < flash_end) | ((into >= 0) & (into <= plan.visible_s))
    empty = EmptyArena(bg, int(np.random.SeedSequence([seed, 17, scene.rig.names.index(cam.name)]).generate_state(1)[0] >> 1))
    for k in range(len(starts)):
        yield (render_free_running_frame(scene, cam, k, float(starts[k]), timing, bg, noise=True) if render[k]
               else empty.frame())


def render_laps(out_dir, *, horse: str = "Horse 2", gait: str = "canter", laps: int = 4, lap_s: float = 30.0,
                timing_index: int = LAPS_TIMING_INDEX, marker_noise: MarkerNoise | None = LAPS_NOISE,
                genlocked: bool = False, fps: float = FPS, rate_ppm: dict | None = None, progress=None) -> Path:
    """Render a ride of ``laps`` passes into ``out_dir`` (see the module docstring).

    Parameters
    ----------
    horse, gait : str
        The herd horse and its gait (the herd session's scene seed, the thesis rig).
    laps : int
        Passes of the cameras, one per lap.
    lap_s : float
        Seconds from one pass' start to the next.
    timing_index : int
        The cameras' timing draw (:func:`~horsemocap.virtuallab.herd.free_running_timings`, set 0).
    marker_noise : MarkerNoise or None
        Marker-centroid noise correlated over the whole recording's frames.
    genlocked : bool
        The control: the same cameras locked together (phase 0, nominal rate, no rolling shutter).
    rate_ppm : dict camera -> float, optional
        Clocks' rate offsets (ppm) replacing the draw's (:func:`drawn_timings`): a camera at 30000/1001 fps
        labelled 30 among cameras at 30 is ``(1000 / 1001 - 1) x 1e6``, about -999 ppm.
    progress : callable, optional
        ``progress(message)`` once per camera.
    """
    t_start = time.perf_counter()
    say = progress or (lambda *_: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    seed = herd_seed(horse, gait)
    base = Scene(thesis_rig(), saddle_motion(horse, gait), seed)
    plan = plan_laps(base, laps, lap_s, fps)
    scene, bgs = _scene_and_backgrounds(horse, gait, seed, replace(base, motion=LapMotion.around(base.motion, lap_s)))
    if marker_noise is not None:
        scene = replace(scene, marker_noise=replace(marker_noise, frame_rate_hz=float(fps)))
    timing = drawn_timings(timing_index, fps, genlocked, rate_ppm)
    motion_paths = {}
    for cam in scene.rig:
        _write_video(out / "motion" / f"{cam.name}.avi",
                     _frames(scene, cam, timing[cam.name], plan, bgs[cam.name], seed, fps), cam.size, fps, True)
        motion_paths[cam.name] = f"motion/{cam.name}.avi"
        say(f"laps: camera {cam.name!r} {plan.offsets[cam.name] + plan.n_frames} frames "
            f"({time.perf_counter() - t_start:.0f} s)")
    stills = write_stills(out, scene, bgs, noise=True, compress=True, fps=fps,
                          static_clip_times=_static_clip_times(scene, STATIC_FRAMES, plan.offsets, fps))
    (out / "calibration").mkdir(exist_ok=True)
    write_rig(scene.rig, out / "calibration" / "rig.toml")
    truth = _truth(scene, plan, timing, fps, 0)
    truth.extras["laps"] = plan.to_dict()
    truth.extras["noise"] = True
    truth.extras["compress"] = True
    truth.extras["static_frames"] = STATIC_FRAMES
    if scene.marker_noise is not None:
        truth.extras["marker_noise"] = scene.marker_noise.to_dict()
    save_truth(truth, out)
    meta = {"horse": horse, "gait": gait, "direction": "CCW", "rider": "A", "seed": int(seed),
            "generator": "horsemocap.virtuallab.laps", "virtual": True, "passes": int(laps),
            "camera_timing": {c: timing[c].to_dict() for c in scene.rig.names}}
    sj = session_json(f"laps_{int(laps)}_{horse.lower().replace(' ', '')}_{gait}", meta, motion_paths, stills, False,
                      fps=fps, marker_count=len(scene.motion.horse.marker_body))
    atomic_write_json(out / "session.json", sj)
    say(f"laps: {laps} passes, {plan.n_frames} frames per camera after the flash, rendered in "
        f"{time.perf_counter() - t_start:.0f} s")
    return out


def drawn_timings(timing_index: int, fps: float = FPS, genlocked: bool = False, rate_ppm: dict | None = None) -> dict:
    """The cameras' timings of a ride: draw ``timing_index`` of
    :func:`~horsemocap.virtuallab.herd.free_running_timings` (set 0), with the clocks' rate offsets of
    ``rate_ppm`` (camera -> ppm) in place of the drawn ones.

    Examples
    --------
    >>> t = drawn_timings(400, rate_ppm={"right": -999.0})
    >>> t["right"].rate_offset_ppm, t["left"].rate_offset_ppm == drawn_timings(400)["left"].rate_offset_ppm
    (-999.0, True)
    >>> drawn_timings(400, genlocked=True, rate_ppm={"right": -999.0})
    Traceback (most recent call last):
    ...
    ValueError: rate_ppm {'right': -999.0}: genlocked cameras share one clock (the control ride has no drift)
    """
    if genlocked and rate_ppm:
        raise ValueError(f"rate_ppm {rate_ppm}: genlocked cameras share one clock (the control ride has no drift)")
    timing = free_running_timings(0, timing_index, fps, genlocked=genlocked)
    unknown = sorted(set(rate_ppm or {}) - set(timing))
    if unknown:
        raise ValueError(f"rate_ppm: no camera {unknown} in the ride (cameras {sorted(timing)})")
    return {c: (replace(t, rate_offset_ppm=float(rate_ppm[c])) if c in (rate_ppm or {}) else t)
            for c, t in timing.items()}


def _truth(scene: Scene, plan: LapsPlan, timing: dict, fps: float, i: int) -> Truth:
    n_frames = {c: plan.offsets[c] + plan.n_frames for c in plan.offsets}
    return build_truth(scene, plan.offsets, n_frames, fps, timing=timing, ref_window=plan.pass_window(i, fps))


def pass_truth(session_dir, i: int) -> Truth:
    """The exact truth of pass ``i`` of a laps session (pass 0: the saved truth).

    Rebuilt from ``session.json`` and ``truth/`` alone: the scene of the
    session's horse, gait and seed, its lap and the cameras' timings.
    """
    saved = load_truth(session_dir)
    if i == 0:
        return saved
    info = saved.extras.get("laps")
    if info is None:
        raise ValueError(f"{session_dir}: truth.json has no 'laps' extras (not a laps session)")
    meta = json.loads((Path(session_dir) / "session.json").read_text())["metadata"]
    plan = LapsPlan.from_dict(info)
    if not 0 <= i < plan.laps:
        raise ValueError(f"pass {i}: the session has passes 0 .. {plan.laps - 1}")
    timing = {c: CameraTiming.from_dict(d) for c, d in meta["camera_timing"].items()}
    base = Scene(thesis_rig(), saddle_motion(meta["horse"], meta["gait"]), int(meta["seed"]))
    scene = replace(base, motion=LapMotion.around(base.motion, plan.lap_s))
    return _truth(scene, plan, timing, saved.fps, i)


def laps_key(horse: str, gait: str, laps: int, lap_s: float, timing_index: int, marker_noise, genlocked: bool,
             rate_ppm: dict | None = None) -> str:
    """Cache key: the ride's parameters, the timings' renderer versions and the renderer's."""
    timing = drawn_timings(timing_index, FPS, genlocked, rate_ppm)
    if horse not in HERD:
        raise ValueError(f"horse: expected one of {sorted(HERD)}, got {horse!r}")
    blob = json.dumps({"v": LAPS_VERSION, "render": RENDER_VERSION, "horse": HERD[horse].to_dict(), "gait": gait,
                       "laps": int(laps), "lap_s": float(lap_s), "timing": {c: t.to_dict() for c, t in timing.items()},
                       "noise": None if marker_noise is None else marker_noise.to_dict(), "fps": FPS,
                       "body_tail_m": BODY_TAIL_M, "static_frames": STATIC_FRAMES,
                       **timing_render_versions(timing)}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


def laps_session(*, horse: str = "Horse 2", gait: str = "canter", laps: int = 4, lap_s: float = 30.0,
                 timing_index: int = LAPS_TIMING_INDEX, marker_noise: MarkerNoise | None = LAPS_NOISE,
                 genlocked: bool = False, rate_ppm: dict | None = None, cache=None, force: bool = False,
                 progress=None) -> Path:
    """Path of a laps session, rendered into the render cache if needed (``rate_ppm``: :func:`render_laps`').

    The folder is ``<cache>/virtuallab/laps_<laps>-<key>`` (``-genlocked`` for
    the control), rendered in a ``.partial`` folder and renamed when complete.
    Four laps of 30 s at 30 fps: 3 x 3,600 frames, of which about 300 per
    camera are rendered (a few minutes), the rest composed.
    """
    root = Path(cache) if cache else cache_dir()
    key = laps_key(horse, gait, laps, lap_s, timing_index, marker_noise, genlocked, rate_ppm)
    folder = root / "virtuallab" / f"laps_{int(laps)}{'-genlocked' if genlocked else ''}-{key}"
    return render_into_cache(folder, lambda tmp: render_laps(tmp, horse=horse, gait=gait, laps=laps, lap_s=lap_s,
                                                            timing_index=timing_index, marker_noise=marker_noise,
                                                            genlocked=genlocked, rate_ppm=rate_ppm,
                                                            progress=progress),
                             "horsemocap.virtuallab.laps.laps_session", force)
