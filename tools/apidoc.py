"""Build the API reference of horsemocap from its docstrings.

The reference is rendered by pdoc (NumPy docstring style) into one HTML page
per module, with a search box; open ``docs/api/index.html`` in a browser::

    python tools/apidoc.py                 # into docs/api/
    python tools/apidoc.py --out /tmp/api  # elsewhere

The pages are built, not committed (``docs/api/`` is in ``.gitignore``);
``tests/test_api_reference.py`` builds them on every test run. The command
exits with status 1 if pdoc warned about anything (a docstring it could not
read, a signature it could not resolve), after printing the warnings.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import re
import sys
import warnings
from pathlib import Path

import pdoc
import pdoc.doc
import pdoc.render

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "horsemocap"
DEFAULT_OUT = REPO / "docs" / "api"


def public_modules(package: str = PACKAGE) -> list[str]:
    """Every public module of ``package``: no part of its dotted name starts with ``_``.

    Each module is imported here, before pdoc imports it, so that what a module
    does once on import (matplotlib's font cache, for one) happens outside
    pdoc's import guard.
    """
    root = importlib.import_module(package)
    names = [package]
    for info in pkgutil.walk_packages(root.__path__, prefix=f"{package}."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        importlib.import_module(info.name)
        names.append(info.name)
    return sorted(names)


def module_page(out_dir: Path, module: str) -> Path:
    """The HTML page pdoc writes for ``module`` under ``out_dir``."""
    return Path(out_dir, *module.split(".")).with_suffix(".html")


def build(out_dir: Path | str = DEFAULT_OUT, modules: list[str] | None = None,
          search: bool = True, show_source: bool = True) -> list[str]:
    """Render the reference of ``modules`` (default: every public module) into ``out_dir``.

    One page per module, whether or not its package's ``__all__`` names it (pdoc's
    own walk follows ``__all__``), an index page and the search index. Returns
    pdoc's warnings as text, one entry each (empty when the build is clean).
    ``show_source=False`` leaves out each function's source (three times faster).
    """
    out_dir = Path(out_dir)
    modules = public_modules() if modules is None else modules
    pdoc.render.configure(docformat="numpy", search=search, show_source=show_source,
                          footer_text="horsemocap: saddle motion analysis of horses")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        documented = {name: pdoc.doc.Module.from_name(name) for name in modules}
        _list_every_submodule(documented)
        for name, module in documented.items():
            page = module_page(out_dir, name)
            page.parent.mkdir(parents=True, exist_ok=True)
            page.write_text(pdoc.render.html_module(module, documented), encoding="utf-8")
        index = pdoc.render.html_index(documented)
        if index:
            (out_dir / "index.html").write_text(index, encoding="utf-8")
        search_index = pdoc.render.search_index(documented) if search else ""
        if search_index:
            (out_dir / "search.js").write_text(search_index, encoding="utf-8")
    return [f"{w.category.__name__}: {w.message}" for w in caught if not _namedtuple_annotation(w.message)]


def _list_every_submodule(documented: dict) -> None:
    """Let each package's page list all its documented submodules.

    pdoc lists only the submodules a package's ``__all__`` names; ours name the
    functions they re-export, so ``horsemocap.detection``'s page would link to
    none of its modules. ``Module.submodules`` is a cached property: it is
    filled here with the documented modules one level below.
    """
    for name, module in documented.items():
        children = [child for child_name, child in documented.items()
                    if child_name.rpartition(".")[0] == name]
        module.__dict__["submodules"] = children


def _namedtuple_annotation(message) -> bool:
    """Whether a warning is pdoc failing to resolve a ``typing.NamedTuple``'s field annotation.

    A NamedTuple's generated constructor is compiled outside its module, so a
    string annotation (``from __future__ import annotations``) such as
    ``"np.ndarray"`` cannot be resolved there; the page still shows the
    annotation as written. Any other warning counts.
    """
    match = re.match(r"Error parsing type annotation .* for ([\w.]+)\.__init__\. Import of \w+ failed",
                     str(message))
    if not match:
        return False
    module_name, _, class_name = match.group(1).rpartition(".")
    cls = getattr(sys.modules.get(module_name), class_name, None)
    return isinstance(cls, type) and issubclass(cls, tuple) and hasattr(cls, "_fields")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    args = parser.parse_args(argv)
    problems = build(args.out)
    for problem in problems:
        print(problem, file=sys.stderr)
    print(f"API reference: {args.out / 'index.html'}"
          + (f" ({len(problems)} warnings)" if problems else ""))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
