"""One plotting function per kind of thesis figure.

The functions live in one sub-module per pipeline step
(``horsemocap.plots.detection`` ...) and are all re-exported here. Each takes
arrays (and an optional matplotlib ``Axes``) and returns the figure or axes.
"""
from __future__ import annotations

import importlib
import pkgutil

__all__: list[str] = []
for _info in pkgutil.iter_modules(__path__):
    _mod = importlib.import_module(f"{__name__}.{_info.name}")
    for _name in getattr(_mod, "__all__", [n for n in dir(_mod) if n.startswith("plot_")]):
        globals()[_name] = getattr(_mod, _name)
        __all__.append(_name)
