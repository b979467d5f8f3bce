"""The virtual herd: 4 horses x 4 gaits = the 16 sessions of thesis 8.5.

Only their description is stored in the repository
(``data_samples/herd.json``: horse and gait parameters, seeds); each session
is rendered deterministically on demand into
:func:`horsemocap.data.cache_dir` (outside the repository) by
:func:`herd_session`. :func:`herd_free_running` renders a few of them again
as ordinary free-running cameras would film them
(:mod:`horsemocap.virtuallab.timing`), short records at other frame rates.
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np

from ..data import cache_dir, data_samples_dir
from ..store import atomic_write_json
from .horse import GAITS, HERD, HORSES, saddle_motion
from .rig import thesis_rig
from .session import build_truth, plan_timeline, render_session, Scene
from .timing import CameraTiming, draw_free_running

#: Bumped whenever the renderer changes its output (invalidates the cache).
RENDER_VERSION = 3
#: Bumped whenever the renderer changes only its interlaced frames: in the keys of sessions with an
#: interlaced camera (:func:`timing_render_versions`), so the other renders stay valid.
INTERLACED_RENDER_VERSION = 2
#: Default session = Horse 2 canter with seed 0 (thesis 8.4.1).
DEFAULT = ("Horse 2", "canter")


def herd_seed(horse: str, gait: str) -> int:
    """Seed of one herd session (Horse 2 canter: 0, the default session)."""
    if (horse, gait) == DEFAULT:
        return 0
    return 1000 + 10 * HORSES.index(horse) + GAITS.index(gait)


def session_slug(horse: str, gait: str) -> str:
    return f"{horse.lower().replace(' ', '')}_{gait}"


def herd_description() -> dict:
    """The content of ``data_samples/herd.json``."""
    sessions = []
    for h in HORSES:
        for g in GAITS:
            gait = HERD[h].gait(g)
            sessions.append({"horse": h, "gait": g, "name": session_slug(h, g), "seed": herd_seed(h, g),
                             "speed_kmh": round(gait.speed_mps * 3.6, 3), "stride_hz": round(gait.stride_hz, 5),
                             "call": f"horsemocap.virtuallab.herd_session({h!r}, {g!r})"})
    return {
        "format": "horsemocap-herd/1",
        "description": "The 16 horse x gait sessions of thesis section 8.5, rendered on demand by "
                       "horsemocap.virtuallab.herd_session into horsemocap.data.cache_dir().",
        "render_version": RENDER_VERSION,
        "horses": {h: HERD[h].to_dict() for h in HORSES},
        "gaits": {g: HERD["Horse 2"].gait(g).to_dict() for g in GAITS},
        "sessions": sessions,
    }


def write_herd_description(path=None) -> Path:
    """Write :func:`herd_description` as JSON (atomically) and return the file's path.

    Parameters
    ----------
    path : str or Path, optional
        Where to write; default ``data_samples/herd.json`` in the repository.
    """
    path = Path(path) if path else data_samples_dir() / "herd.json"
    return atomic_write_json(path, herd_description())


def _key(horse, gait) -> str:
    blob = json.dumps({"v": RENDER_VERSION, "h": HERD[horse].to_dict(), "g": HERD[horse].gait(gait).to_dict(),
                       "seed": herd_seed(horse, gait)}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


def herd_session(horse: str, gait: str, *, cache=None, force: bool = False) -> Path:
    """Path of a herd session, rendering it into the cache if needed.

    Parameters
    ----------
    horse : str
        One of ``"Horse 1"`` .. ``"Horse 4"``.
    gait : str
        One of ``"walk"``, ``"sitting_trot"``, ``"rising_trot"``, ``"canter"``.
    cache : path, optional
        Root folder (default :func:`horsemocap.data.cache_dir`).
    force : bool
        Render again even if a complete render exists.
    """
    if horse not in HORSES:
        raise ValueError(f"unknown horse {horse!r}; expected one of {HORSES}")
    if gait not in GAITS:
        raise ValueError(f"unknown gait {gait!r}; expected one of {GAITS}")

    root = Path(cache) if cache else cache_dir()
    folder = root / "virtuallab" / f"{session_slug(horse, gait)}-{_key(horse, gait)}"
    # herd sessions carry the rig (calibrated once for the whole herd): no views to render
    return render_into_cache(folder, lambda tmp: render_session(
        tmp, horse, gait, seed=herd_seed(horse, gait), name=session_slug(horse, gait), calibration_views=0),
        "horsemocap.virtuallab.herd_session", force)


def render_into_cache(folder: Path, render, by: str, force: bool = False) -> Path:
    """``folder``, rendered by ``render(tmp)`` unless a complete render exists.

    The render goes into ``<folder>.partial`` and is renamed when complete
    (a ``.complete`` marker inside), so an interrupted render is never taken
    for a session; ``force`` renders again.
    """
    if (folder / ".complete").is_file() and not force:
        return folder
    if folder.exists():
        shutil.rmtree(folder)
    tmp = folder.with_name(folder.name + ".partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    render(tmp)
    (tmp / ".complete").write_text(f"rendered by {by}\n")
    tmp.rename(folder)
    return folder


def scenario_session(kind: str, name: str, scenarios: dict, key, render, by: str, cache=None,
                     force: bool = False) -> Path:
    """Path of the ``kind`` session ``name`` of ``scenarios``, rendered into the cache by
    ``render(folder, scenario)`` if needed (:func:`render_into_cache`): the folder is
    ``<cache>/virtuallab/<kind>-<name>-<key(scenario)>``, so a changed scenario renders anew.

    Examples
    --------
    >>> import tempfile
    >>> made = scenario_session("demo", "one", {"one": 3}, str, lambda folder, n: folder.mkdir(parents=True),
    ...                         "a doctest", cache=tempfile.mkdtemp())
    >>> made.name, (made / ".complete").is_file()
    ('demo-one-3', True)
    >>> scenario_session("demo", "two", {"one": 3}, str, None, "a doctest")
    Traceback (most recent call last):
    ValueError: unknown demo session 'two'; expected one of ['one']
    """
    if name not in scenarios:
        raise ValueError(f"unknown {kind} session {name!r}; expected one of {sorted(scenarios)}")
    scenario = scenarios[name]
    root = Path(cache) if cache else cache_dir()
    folder = root / "virtuallab" / f"{kind}-{name}-{key(scenario)}"
    return render_into_cache(folder, lambda tmp: render(tmp, scenario), by, force)


# ---------------------------------------------------------------------------
# free-running versions
# ---------------------------------------------------------------------------

#: Herd sessions filmed again by free-running cameras: name -> (horse, gait, nominal fps), thesis rig (640 x 480).
FREE_RUNNING_HERD = {
    "free_horse2_sitting_trot_30": ("Horse 2", "sitting_trot", 30.0),
    "free_horse2_canter_60": ("Horse 2", "canter", 60.0),
    "free_horse3_rising_trot_25": ("Horse 3", "rising_trot", 25.0),
}
#: Start delays left->middle, middle->right of the free-running records (s; shorter than the thesis').
FREE_RUNNING_SYNC_DELTAS_S = (0.45, 0.30)
#: Fully visible stride periods a free-running record keeps (render time).
FREE_RUNNING_STRIDES = 3.0


def free_running_timings(seed: int, index: int, fps: float, interlaced: str | None = None, *,
                         genlocked: bool = False) -> dict:
    """The drawn camera timings of free-running session ``index`` of set ``seed``
    (:func:`horsemocap.virtuallab.timing.draw_free_running`, the left camera the reference).

    ``genlocked``: the control, the same cameras locked together (phase 0, no
    rate offset, no rolling shutter; exposure and interlacing kept).
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 29, int(index)]))
    timing = draw_free_running(rng, fps, interlaced=interlaced)
    if genlocked:
        timing = {c: CameraTiming(nominal_fps=t.nominal_fps, exposure_s=t.exposure_s, interlaced=t.interlaced)
                  for c, t in timing.items()}
    return timing


def short_record(scene, fps: float, left_offset: int, sync_deltas_s, strides: float = FREE_RUNNING_STRIDES):
    """``(offsets, n_after)`` of a short record: ``strides`` fully visible stride periods plus 0.15 s.

    The timeline of :func:`horsemocap.virtuallab.session.plan_timeline`, cut
    after ``strides`` stride periods of frames in which every skin marker is
    inside every image (or after the last such frame).
    """
    offsets, n_after = plan_timeline(scene, fps, left_offset=left_offset, sync_deltas_s=sync_deltas_s)
    n_frames = {c: offsets[c] + n_after for c in offsets}
    ref = build_truth(scene, offsets, n_frames, fps).ref_frames
    if len(ref):
        last = min(int(ref[-1]), int(ref[0]) + int(np.ceil(strides * fps / scene.motion.gait.stride_hz)))
        n_after = int(last - offsets["left"] + round(0.15 * fps))
    return offsets, n_after


def timing_render_versions(timing: dict) -> dict:
    """Renderer versions a free-running session's cache key adds for its cameras' timings.

    ``{"interlaced_render": INTERLACED_RENDER_VERSION}`` when a camera records
    interlaced fields, else nothing (the key of a progressive session is unchanged).

    Examples
    --------
    >>> timing_render_versions({"left": CameraTiming(nominal_fps=25.0)})
    {}
    >>> timing_render_versions({"left": CameraTiming(nominal_fps=25.0, interlaced="bottom_first")})
    {'interlaced_render': 2}
    """
    return {"interlaced_render": INTERLACED_RENDER_VERSION} if any(t.interlaced for t in timing.values()) else {}


def _free_key(blob: dict) -> str:
    return hashlib.sha256(json.dumps({"v": RENDER_VERSION, **blob}, sort_keys=True).encode()).hexdigest()[:12]


def herd_free_running(seed: int = 0, *, names=None, cache=None, force: bool = False, genlocked: bool = False) -> dict:
    """Free-running versions of a few herd sessions, rendered into the cache on demand.

    Each of :data:`FREE_RUNNING_HERD` (thesis rig, 640 x 480, at its own
    frame rate) with the herd session's horse, gait and scene seed, filmed
    by cameras whose timings are drawn for set ``seed``
    (:func:`free_running_timings`: phases uniform in [0, 1), rates within
    +-100 ppm, rolling-shutter readouts 0-30 ms, exposure half a frame); a
    short record (:func:`short_record`). The truth gives every camera's
    instants (:func:`horsemocap.virtuallab.build_truth`).

    Parameters
    ----------
    seed : int
        Selects the timing draws (0: the set the benchmarks use).
    names : iterable of str, optional
        A subset of :data:`FREE_RUNNING_HERD` (default: all).
    cache : path, optional
        Root folder (default :func:`horsemocap.data.cache_dir`).
    force : bool
        Render again even if a complete render exists.
    genlocked : bool
        Render the control instead: the same sessions with the cameras
        locked together (:func:`free_running_timings`).

    Returns
    -------
    dict
        name -> session folder.
    """
    names = list(FREE_RUNNING_HERD) if names is None else list(names)
    root = Path(cache) if cache else cache_dir()
    out = {}
    for name in names:
        if name not in FREE_RUNNING_HERD:
            raise ValueError(f"unknown free-running herd session {name!r}; expected one of {sorted(FREE_RUNNING_HERD)}")
        horse, gait, fps = FREE_RUNNING_HERD[name]
        timing = free_running_timings(seed, list(FREE_RUNNING_HERD).index(name), fps, genlocked=genlocked)
        key = _free_key({"h": HERD[horse].to_dict(), "g": HERD[horse].gait(gait).to_dict(),
                         "seed": herd_seed(horse, gait), "fps": fps, "timing": {c: t.to_dict() for c, t in timing.items()},
                         "strides": FREE_RUNNING_STRIDES, "deltas": FREE_RUNNING_SYNC_DELTAS_S,
                         **timing_render_versions(timing)})
        folder = root / "virtuallab" / f"{name}{'-genlocked' if genlocked else ''}-s{int(seed)}-{key}"
        out[name] = render_into_cache(folder, lambda tmp, h=horse, g=gait, f=fps, t=timing, n=name:
                                      _render_free_herd(tmp, h, g, f, t, n, seed),
                                      "horsemocap.virtuallab.herd.herd_free_running", force)
    return out


def _render_free_herd(out, horse: str, gait: str, fps: float, timing: dict, name: str, seed: int):
    scene = Scene(thesis_rig(), saddle_motion(horse, gait), herd_seed(horse, gait))
    left = int(round(0.1 * fps))
    offsets, n_after = short_record(scene, fps, left, FREE_RUNNING_SYNC_DELTAS_S)
    return render_session(out, horse, gait, seed=herd_seed(horse, gait), name=name, calibration_views=0, fps=fps,
                          left_offset=left, sync_deltas_s=FREE_RUNNING_SYNC_DELTAS_S, n_motion_frames=n_after,
                          timing=timing, metadata={"free_running_set": int(seed)})
