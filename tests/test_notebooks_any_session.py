"""The notebooks run on a session without ground truth (every recorded session).

The bundled session is copied without its ``truth/`` folder into a temporary
folder, made the workspace's session (``workspace.json`` in a temporary
``$HORSEMOCAP_RESULTS``), and each notebook is executed top to bottom with
nbclient, as JupyterLab's "Run All" would. A cell that raises fails the test,
naming the notebook, the cell and the error. Cells that compare with the truth
must print :data:`horsemocap.workspace.NO_TRUTH` instead, and at least one cell
of each notebook that has such cells does (checked below).

Notebook 13 analyses the virtual herd as one batch (its own sessions, with
their truth) and then sets the workspace's session beside it, where it must
print :data:`NO_TRUTH`. Its batch is resumable by run key: the folder nbval's
run of 13 filled in this test session (the results folder of ``conftest.py``)
is copied in when it is there, and this run's is copied out for nbval when it
is not, so the herd is analysed once per test session.
"""
from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

from horsemocap.batch_table import TABLE_CSV
from horsemocap.data import default_session_dir
from horsemocap.workspace import (NO_TRUTH, WORKSPACE_FILE, current_session, downstream_text, session_truth,
                                  set_current_session)

NB_DIR = Path(__file__).resolve().parents[1] / "notebooks"
HERD_NOTEBOOK = "13_horses_and_gaits.ipynb"   # its herd batch takes longest: started first
HERD_BATCH = "herd_batch"                     # the notebook's batch folder in the results folder
NOTEBOOKS = sorted(p.name for p in NB_DIR.glob("[0-9][0-9]_*.ipynb"))
# notebooks that never look at the workspace's session's truth (their comparisons use bundled sessions)
NO_TRUTH_CELLS = {"00_start_here.ipynb", "07_gravity_check.ipynb"}
# notebooks that print both chains' downstream numbers (workspace.downstream_text)
DOWNSTREAM_CELLS = {p for p in NOTEBOOKS if "04" <= p[:2] <= "14" and p[:2] not in ("11", "13")}


@pytest.fixture(scope="module")
def truthless_workspace(tmp_path_factory):
    """A copy of the bundled session without ``truth/``, chosen as the workspace's session."""
    root = tmp_path_factory.mktemp("any_session")
    session = root / "recorded_session"
    shutil.copytree(default_session_dir(), session, ignore=shutil.ignore_patterns("truth"))
    before = os.environ.get("HORSEMOCAP_RESULTS")
    shared = Path(before) / HERD_BATCH if before else None
    own = root / "results" / HERD_BATCH
    if shared is not None and (shared / TABLE_CSV).is_file():
        shutil.copytree(shared, own)              # nbval's run of 13 analysed the herd: resumed, not redone
    os.environ["HORSEMOCAP_RESULTS"] = str(root / "results")   # the kernels inherit it
    try:
        set_current_session(session)
        yield session
        if shared is not None and (own / TABLE_CSV).is_file() and not shared.exists():
            _copy_whole(own, shared)              # for nbval's run of 13, later in this test session
    finally:
        if before is None:
            os.environ.pop("HORSEMOCAP_RESULTS", None)
        else:
            os.environ["HORSEMOCAP_RESULTS"] = before


def _copy_whole(source: Path, target: Path) -> None:
    """``source`` copied to ``target`` whole (a sibling copy renamed), or not at all if ``target`` appeared."""
    partial = target.with_name(target.name + f".partial-{os.getpid()}")
    shutil.copytree(source, partial)
    try:
        partial.rename(target)
    except OSError:
        shutil.rmtree(partial, ignore_errors=True)


def test_the_copy_has_no_truth(truthless_workspace):
    assert session_truth(truthless_workspace) is None
    assert current_session() == truthless_workspace.resolve()
    assert (Path(os.environ["HORSEMOCAP_RESULTS"]) / WORKSPACE_FILE).is_file()


def _execute(name: str) -> dict:
    """Run one notebook as "Run All" does; its errors and printed text (in a worker process)."""
    nb = nbformat.read(NB_DIR / name, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
    t0 = time.perf_counter()
    # the herd notebook renders the 16 herd sessions into the render cache on first use: about 12 minutes on an
    # idle two-core machine, over 10 under load (a first CI run timed out at 600 s in its batch cell)
    timeout = 2400 if name == HERD_NOTEBOOK else 600
    NotebookClient(nb, timeout=timeout, kernel_name="python3", allow_errors=True,
                   resources={"metadata": {"path": str(NB_DIR)}}).execute()
    errors = []
    for i, cell in enumerate(nb.cells):
        for o in cell.get("outputs", []):
            if o.get("output_type") == "error":
                first = cell.source.splitlines()[0] if cell.source else ""
                errors.append(f"cell {i} ({first[:60]!r}): {o.ename}: {o.evalue[:300]}")
    printed = "\n".join(o.get("text", "") for c in nb.cells for o in c.get("outputs", [])
                        if o.get("output_type") == "stream")
    return {"errors": errors, "printed": printed, "seconds": time.perf_counter() - t0}


@pytest.fixture(scope="module")
def executed(truthless_workspace):
    """Every notebook executed on the truthless session, a few at once."""
    # the analysis of both chains first, so that the notebooks load it instead of computing it side by side
    downstream_text(truthless_workspace)
    workers = max(1, min(3, os.cpu_count() or 1))
    order = sorted(NOTEBOOKS, key=lambda name: name != HERD_NOTEBOOK)
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        return dict(zip(order, pool.map(_execute, order)))


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_runs_without_truth(executed, name):
    run = executed[name]
    assert not run["errors"], f"{name} on a session without truth/:\n" + "\n".join(run["errors"])
    if name not in NO_TRUTH_CELLS:
        assert NO_TRUTH in run["printed"], f"{name}: no cell says {NO_TRUTH!r}"
    if name == HERD_NOTEBOOK:   # section 8: the workspace's session beside the herd, without a truth
        assert f"{NO_TRUTH} (a recorded session)" in run["printed"], f"{name}: the session's truth not refused"
        shown = f"your session: {json.loads((default_session_dir() / 'session.json').read_text())['name']} ("
        assert shown in run["printed"], f"{name}: the workspace's session not shown"
    if name in DOWNSTREAM_CELLS:
        assert "the thesis' chain" in run["printed"] and "saddle A_y rms" in run["printed"], \
            f"{name}: the two chains' downstream numbers are not shown"


# ---------------------------------------------------------------------------
# every widget of notebooks 04-12 changes a number downstream, on its own chain
# ---------------------------------------------------------------------------

def _still_threshold(session_dir, kind):
    from horsemocap.detection import still_candidates
    from horsemocap.session import load_session
    from horsemocap.sources import read_image

    session = load_session(session_dir, open_sources=False)
    return int(still_candidates(read_image(getattr(session, kind)["left"])).threshold)


def _widget_changes(session_dir):
    """(notebook, the bound parameter, a value the widget can take, the chain it belongs to)."""
    from horsemocap.workspace import results_for

    an = results_for(session_dir)
    left = an.detect.detection["left"]["threshold"]
    right = an.detect.detection["right"]["threshold"]
    orders = an.rigid_body.body.motion_fit.orders if an.rigid_body.body.motion_fit is not None else None
    n_static = len(next(iter(an.static.static_px.values())))
    return [
        ("04 threshold slider", "detection.left.threshold", left + 12, "default"),
        ("04 all prompts (left)", "detection.left", {"threshold": left - 12}, "default"),
        ("04 every camera's prompts", "detection.right", {"threshold": right + 12}, "default"),
        ("05 triangulation", "triangulation", "thesis", "default"),
        ("06 smoothing method", "smoothing_method", "rloess", "default"),
        ("06 smoothing span", "smoothing_span", 0.3, "default"),
        ("06 x-motion marker", "x_marker", 2, "default"),
        ("06 period", "period_frames", 16.0, "default"),
        ("06 number of periods", "n_periods", 1, "default"),
        ("07 plumb prompts", "stills.plumb", {"left": {"threshold": _still_threshold(session_dir, "plumb") + 25}},
         "default"),
        ("08 static-shot prompts", "stills.static",
         {"left": {"threshold": _still_threshold(session_dir, "static") + 25}}, "default"),
        ("09 Fourier orders", "fourier_orders", [[1, 1]] * 3 if orders is None else
         [[int(o) % 4 + 1 for o in row[1:]] for row in orders], "thesis"),
        ("09 x degree", "x_degree", 2, "thesis"),
        ("10 omega versions", "omega_versions", [True, False, True, False, True, False], "thesis"),
        ("10 alfa versions", "alpha_versions", [True, False, True, False, True, False], "thesis"),
        ("10 angular method", "angular_method", "lstsq", "thesis"),
        ("11 saddle method", "saddle_method", "direct", "thesis"),
        ("11 saddle marker", "saddle_marker", (an.rigid_body.saddle_index + 1) % n_static, "default"),
        ("12 weighting mode", "weighting_mode", "iso", "thesis"),
    ]


DOWNSTREAM_KEYS = ("saddle_acc_y_rms", "acc_y_Wb_rms", "acc_y_Wk_rms")


@pytest.fixture(scope="module")
def bundled_workspace(tmp_path_factory):
    """The bundled session with a temporary results store (its choices start empty)."""
    before = os.environ.get("HORSEMOCAP_RESULTS")
    os.environ["HORSEMOCAP_RESULTS"] = str(tmp_path_factory.mktemp("widgets") / "results")
    try:
        yield default_session_dir().resolve()
    finally:
        if before is None:
            os.environ.pop("HORSEMOCAP_RESULTS", None)
        else:
            os.environ["HORSEMOCAP_RESULTS"] = before


def test_every_widget_changes_a_downstream_number(bundled_workspace):
    from horsemocap.workspace import Workspace, clear_choices, downstream

    ws = Workspace(bundled_workspace)
    base = {c: downstream(bundled_workspace, c) for c in ("default", "thesis")}
    for chain, row in base.items():
        assert "error" not in row, (chain, row)
    unchanged = []
    for label, name, value, chain in _widget_changes(bundled_workspace):
        ws.choose(name, value)         # what the widget's callback does (Workspace.bind)
        try:
            row = downstream(bundled_workspace, chain)
        finally:
            clear_choices(bundled_workspace)
        assert "error" not in row, f"{label}: {row['error']}"
        if all(abs(row[k] - base[chain][k]) <= 1e-9 * abs(base[chain][k]) for k in DOWNSTREAM_KEYS):
            unchanged.append(f"{label} ({name}={value!r}) on the {chain} chain")
    assert not unchanged, "no downstream number changed for:\n" + "\n".join(unchanged)


def test_label_picker_drives_the_thesis_chain(bundled_workspace):
    """Notebook 04, section 2: the picked labels are what the thesis' per-camera detection follows.

    Two of the automatic markers and another region of the area range in their place: the
    thesis' chain follows that region, so its numbers change or it stops, naming the step (as
    the thesis' own chain did with a wrong answer). The default chain identifies the markers
    in 3D and does not read labels.
    """
    from horsemocap import detection
    from horsemocap.steps.detect import synchronised_frames
    from horsemocap.workspace import Workspace, chain_choices, clear_choices, downstream, results_for, session_params

    sd = bundled_workspace
    base = downstream(sd, "thesis")
    an = results_for(sd, params=session_params(sd, chain_choices({}, "thesis")))
    auto = an.detect.detection["left"]
    image = synchronised_frames(an.session, an.synchronisation, "left")[auto["first_frame"]]
    regions = detection.label_regions(detection.binarize(detection.to_gray(image), auto["threshold"]))
    others = [int(lab) for lab, area in zip(regions.ids, regions.area)
              if lab not in auto["labels"] and auto["area_min"] <= area <= auto["area_max"]]
    assert others, "no other region in the area range to pick"
    picked = list(auto["labels"][:2]) + [others[0]]
    Workspace(sd).choose("detection.left", {"labels": picked, "first_frame": auto["first_frame"]})
    try:
        row = downstream(sd, "thesis")
    finally:
        clear_choices(sd)
    if "error" in row:
        assert row["error"].startswith("step '"), row["error"]
    else:
        assert any(abs(row[k] - base[k]) > 1e-9 * abs(base[k]) for k in DOWNSTREAM_KEYS), (picked, row)


def test_label_picker_follows_the_threshold():
    """Notebook 04, section 3: after a threshold change the picker's options, selection and value agree."""
    from horsemocap import detection, widgets
    from horsemocap.session import load_session
    from horsemocap.sources import FrameSource

    frames = FrameSource(load_session(default_session_dir(), open_sources=False).motion["left"]).read()
    p = detection.detect_markers(frames, 3).params
    control = widgets.ui_detection(frames, p)
    assert control.labels.value == tuple(p.labels) == control.value.labels
    control.threshold.slider.value = p.threshold + 10
    options = {o[1] for o in control.labels.select.options}
    assert control.labels.value == () and control.value.labels is None and options
    assert control.labels.threshold == p.threshold + 10
    picked = tuple(sorted(options))[:3]
    control.labels.select.value = picked
    assert control.value.labels == picked and control.value.threshold == p.threshold + 10
    assert control.value.first_frame == p.first_frame
    control.threshold.slider.value = p.threshold
    assert control.value.labels == tuple(p.labels)
