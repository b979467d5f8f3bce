"""One plotting function per kind of thesis figure.

The functions live in one sub-module per pipeline step
(``horsemocap.plots.detection`` ...) and are all re-exported here. Each takes
arrays (and an optional matplotlib ``Axes``) and returns the figure or axes.

The sub-modules are imported when a function of this package is first asked
for (``plots.plot_marker_tracks``, ``from horsemocap.plots import ...``,
``dir(plots)``): a program that imports one sub-module (the report's
figures: :mod:`horsemocap.plots.report_figures`) loads only that one and
what it needs.

Examples
--------
>>> from horsemocap import plots
>>> callable(plots.plot_marker_tracks)
True
>>> "plot_marker_tracks" in plots.__all__
True
"""
from __future__ import annotations

import importlib
import pkgutil

from ..forking import EarlyCalls

#: Where the report's figures are drawn (:func:`figure_painter`): the module and its function of figure
#: descriptions. Named here, where no plotting module is loaded, so a program can fork the copy that draws
#: them before it loads anything else.
REPORT_FIGURES = (f"{__name__}.report_figures", "draw_pngs")


def figure_painter(fork: bool = True, hold: bool = False) -> EarlyCalls:
    """The calls that will draw the report's figures (:data:`REPORT_FIGURES`): forked now where that is
    safe, so that matplotlib loads beside the analysis; give it the descriptions of
    :func:`horsemocap.report.step_figures`, step by step as the steps end (or those of
    :func:`horsemocap.report.report_figures` at once). ``hold=True``: matplotlib loads only once
    ``start()`` is called (or the first figures are given), see :class:`horsemocap.forking.EarlyCalls`.

    Examples
    --------
    >>> with figure_painter(fork=False) as painter:
    ...     painter.submit([])
    ...     painter.results()
    [[]]
    """
    return EarlyCalls(*REPORT_FIGURES, fork=fork, hold=hold)

#: The sub-modules, by name.
_SUBMODULES = tuple(info.name for info in pkgutil.iter_modules(__path__))


def _load_all() -> list[str]:
    """Import every sub-module and re-export its plotting functions (its ``__all__``, else its ``plot_*``
    names), in the sub-modules' order; the names re-exported."""
    names = []
    for sub in _SUBMODULES:
        module = importlib.import_module(f"{__name__}.{sub}")
        for name in getattr(module, "__all__", [n for n in dir(module) if n.startswith("plot_")]):
            globals()[name] = getattr(module, name)
            names.append(name)
    globals()["__all__"] = names
    return names


def __getattr__(name: str):
    if name in _SUBMODULES:              # ``from horsemocap.plots import summary``: that sub-module alone
        return importlib.import_module(f"{__name__}.{name}")
    if name.startswith("__") and name != "__all__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    _load_all()
    if name in globals():
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    _load_all()
    return sorted(globals())
