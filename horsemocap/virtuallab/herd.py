"""The virtual herd: 4 horses x 4 gaits = the 16 sessions of thesis 8.5.

Only their description is stored in the repository
(``data_samples/herd.json``: horse and gait parameters, seeds); each session
is rendered deterministically on demand into
:func:`horsemocap.data.cache_dir` (outside the repository) by
:func:`herd_session`.
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from ..data import cache_dir, data_samples_dir
from ..store import atomic_write_json
from .horse import GAITS, HERD, HORSES
from .session import render_session

#: Bumped whenever the renderer changes its output (invalidates the cache).
RENDER_VERSION = 3
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
