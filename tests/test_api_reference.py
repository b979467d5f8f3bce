"""The API reference builds from the docstrings, and the docstrings' examples hold.

The reference is what ``python tools/apidoc.py`` writes into ``docs/api/``
(README, "Where to go next"); here it is built into a temporary folder.
"""
from __future__ import annotations

import doctest
import importlib
import inspect
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import apidoc  # noqa: E402  (tools/ is not a package)

#: The modules whose public functions carry a NumPy "Examples" section; each
#: example is run here, so that it stays true.
DOCTEST_MODULES = [
    "horsemocap.vibration",
    "horsemocap.smoothing",
    "horsemocap.fitting",
    "horsemocap.frames",
    "horsemocap.reconstruction",
    "horsemocap.camera",
    "horsemocap.sync",
    "horsemocap.io3d",
    "horsemocap.sources",
    "horsemocap.synthetic",
    "horsemocap.progress",
    "horsemocap.session",
    "horsemocap.data",
    "horsemocap.runfolder",
    "horsemocap.calibration.board",
    "horsemocap.virtuallab.rig",
    "horsemocap.threads",
    "horsemocap.weighting_filters",
    "horsemocap.iir_filters",
    "horsemocap.probability",
    "horsemocap.subframe",
]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The reference built once for this file's tests (without the source listings: faster)."""
    out_dir = tmp_path_factory.mktemp("api")
    modules = apidoc.public_modules()
    problems = apidoc.build(out_dir, modules, show_source=False)
    return out_dir, modules, problems


def test_builds_without_warning(built):
    out_dir, _, problems = built
    assert problems == [], "\n".join(problems)
    assert (out_dir / "index.html").is_file()
    assert (out_dir / "search.js").stat().st_size > 0


def test_every_public_module_has_a_page(built):
    out_dir, modules, _ = built
    assert "horsemocap.vibration" in modules and "horsemocap.calibration.rig" in modules
    assert not [m for m in modules if any(part.startswith("_") for part in m.split("."))]
    for name in modules:
        page = apidoc.module_page(out_dir, name)
        assert page.is_file(), f"no page for {name}"
        assert name in page.read_text(encoding="utf-8"), f"{page} does not name {name}"
    for name in modules:                 # a package's page links to each of its modules
        parent, _, leaf = name.rpartition(".")
        if parent:
            parent_page = apidoc.module_page(out_dir, parent).read_text(encoding="utf-8")
            assert f'href="{parent.rpartition(".")[2]}/{leaf}.html"' in parent_page, f"{parent}'s page lacks {name}"


def _exported(package: str) -> list[tuple[str, object]]:
    """The functions and classes a package's ``__init__`` exports (its ``__all__``, else its public names)."""
    module = importlib.import_module(package)
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n in dir(module) if not n.startswith("_")]
    objects = [(n, getattr(module, n)) for n in names]
    return [(n, obj) for n, obj in objects
            if (inspect.isfunction(obj) or inspect.isclass(obj))
            and getattr(obj, "__module__", "").startswith("horsemocap")]


def _own_docstring(obj) -> str:
    """The object's own docstring; a dataclass's generated ``Name(field, ...)`` does not count."""
    doc = obj.__doc__ or ""
    if inspect.isclass(obj) and doc.startswith(f"{obj.__name__}("):
        return ""
    return doc.strip()


def test_every_exported_function_and_class_has_a_docstring():
    packages = ["horsemocap"] + [m for m in apidoc.public_modules()
                                 if hasattr(importlib.import_module(m), "__path__") and m != "horsemocap"]
    assert "horsemocap.detection" in packages and "horsemocap.calibration" in packages
    exported = [(package, name, obj) for package in packages for name, obj in _exported(package)]
    assert len(exported) > 100
    missing = [f"{package}.{name}" for package, name, obj in exported if not _own_docstring(obj)]
    assert missing == [], f"exported without a docstring: {missing}"


@pytest.mark.parametrize("module_name", DOCTEST_MODULES)
def test_docstring_examples_hold(module_name):
    module = importlib.import_module(module_name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                             verbose=False, report=True)
    assert result.attempted > 0, f"{module_name} has no example"
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {module_name} failed"
