"""pytest setup shared by the unit tests and nbval.

Every notebook run starts from a clean results folder (and without the user-level board cache): ``HORSEMOCAP_RESULTS``
points at a fresh temporary folder for the whole test session (the kernels
nbval starts inherit it), removed when the session ends; when
``HORSEMOCAP_RESULTS`` is already set, that folder is used and no other is made.
"""
import os
import shutil
import tempfile

# The folder is made only when HORSEMOCAP_RESULTS is not given, and removed when the session ends.
_RESULTS = None if os.environ.get("HORSEMOCAP_RESULTS") else tempfile.mkdtemp(prefix="horsemocap-results-")
if _RESULTS:
    os.environ["HORSEMOCAP_RESULTS"] = _RESULTS
os.environ.setdefault("MPLBACKEND", "module://matplotlib_inline.backend_inline")
# The user-level board-detection cache stays out of the tests (a test that counts a calibration's
# views, or a skipped view's message, must not depend on what an earlier run left there);
# tests/test_batch.py gives its own.
os.environ["HORSEMOCAP_BOARD_CACHE"] = "off"


def pytest_sessionfinish(session, exitstatus):
    """Remove the session's own results folder (and only it)."""
    if _RESULTS:
        shutil.rmtree(_RESULTS, ignore_errors=True)


def pytest_collectstart(collector):
    """Notebooks: stderr (warnings, progress) is never compared."""
    if collector.fspath and collector.fspath.ext == ".ipynb":
        collector.skip_compare += ("stderr",)
