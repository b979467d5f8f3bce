"""Where the bundled samples and the render cache live.

``data_samples/`` sits beside the package in the repository (the package is
installed in editable mode, ``-e .``). Sessions of the virtual herd are
rendered on demand into a cache outside the repository:
``$HORSEMOCAP_CACHE`` if set, else ``~/.cache/horsemocap``.
"""
from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def data_samples_dir() -> Path:
    """The repository's ``data_samples/`` folder."""
    return REPO_ROOT / "data_samples"


def default_session_dir() -> Path:
    """The bundled default session (Horse 2, canter; thesis section 8.4.1).

    Examples
    --------
    >>> default_session_dir().name
    'horse2_canter'
    """
    return data_samples_dir() / "horse2_canter"


def cache_dir() -> Path:
    """Folder for renders made on demand (outside the repository)."""
    root = os.environ.get("HORSEMOCAP_CACHE")
    path = Path(root) if root else Path.home() / ".cache" / "horsemocap"
    path.mkdir(parents=True, exist_ok=True)
    return path


def repository_file(relative: str) -> Path:
    """A file of the repository (e.g. a committed benchmark result), by its relative path.

    Raises
    ------
    FileNotFoundError
        Naming the path, if the file is not there (a package installed
        without its repository).
    """
    path = REPO_ROOT / relative
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not found; it is part of the horsemocap repository "
                                f"(install it from a clone with 'pip install -e .')")
    return path
