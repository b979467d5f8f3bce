"""Widgets that stand in for the thesis' MATLAB prompts.

Each ``ui_*`` builder returns an ipywidgets control whose ``.value`` is a
parameter of a package function; its default is the pipeline's automatic
choice. The builders live in one sub-module per pipeline step
(``horsemocap.widgets.detection`` ...) and are all re-exported here.
"""
from __future__ import annotations

import importlib
import pkgutil

__all__: list[str] = []
for _info in pkgutil.iter_modules(__path__):
    _mod = importlib.import_module(f"{__name__}.{_info.name}")
    for _name in dir(_mod):
        if _name.startswith("ui_"):
            globals()[_name] = getattr(_mod, _name)
            __all__.append(_name)
