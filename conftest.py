"""pytest setup shared by the unit tests and nbval.

Every notebook run starts from a clean results folder: ``HORSEMOCAP_RESULTS``
points at a fresh temporary folder for the whole test session (the kernels
nbval starts inherit it).
"""
import os
import tempfile

_RESULTS = tempfile.mkdtemp(prefix="horsemocap-results-")
os.environ.setdefault("HORSEMOCAP_RESULTS", _RESULTS)
os.environ.setdefault("MPLBACKEND", "module://matplotlib_inline.backend_inline")


def pytest_collectstart(collector):
    """Notebooks: stderr (warnings, progress) is never compared."""
    if collector.fspath and collector.fspath.ext == ".ipynb":
        collector.skip_compare += ("stderr",)
