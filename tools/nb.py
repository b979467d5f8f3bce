"""Build notebooks from their percent-format sources and execute them.

Each notebook ``notebooks/NN_name.ipynb`` is generated from
``notebooks/src/NN_name.py`` (cells start with ``# %%``; markdown cells with
``# %% [markdown]``; tags with ``# %% tags=["nbval-ignore-output"]``), then
executed top to bottom in ``notebooks/`` with the inline backend, so the stored
outputs are the ones nbval compares against.

The widget state is saved in the notebook (nbclient stores it). JupyterLab
draws saved widgets only in a trusted notebook: the builder's own signature
database trusts what is built here; anyone else runs ``jupyter trust
notebooks/*.ipynb`` once (README).

Usage: ``python tools/nb.py notebooks/src/04_marker_detection.py [...]``
(no argument: every source).

``--sources-only`` rewrites each stored notebook's cell sources (and tags)
from its source file and keeps the stored outputs and widget state, without
executing anything: for a change that alters no output (a rename, a comment).
It needs the same cells, one to one in kind (code or markdown); otherwise it
says so and builds and executes that notebook as without the option. Check the
result with nbval (``python -m pytest notebooks/NN_name.ipynb``).
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import nbformat
from jupyter_client.kernelspec import KernelSpecManager
from nbclient import NotebookClient
from nbformat.sign import NotebookNotary

ROOT = Path(__file__).resolve().parents[1]
NB_DIR = ROOT / "notebooks"
HEADER = re.compile(r"^# %%(?P<md>\s*\[markdown\])?(?:\s+tags=(?P<tags>\[.*\]))?\s*$")


def parse(text: str):
    cells, kind, tags, lines = [], None, [], []

    def flush():
        if kind is None:
            return
        body = "\n".join(lines).strip("\n")
        if kind == "markdown":
            body = "\n".join(l[2:] if l.startswith("# ") else l.lstrip("#") for l in body.splitlines())
            cells.append(nbformat.v4.new_markdown_cell(body))
        elif body.strip():
            cell = nbformat.v4.new_code_cell(body)
            if tags:
                cell.metadata["tags"] = tags
            cells.append(cell)

    for line in text.splitlines():
        m = HEADER.match(line)
        if m:
            flush()
            kind = "markdown" if m.group("md") else "code"
            tags = json.loads(m.group("tags")) if m.group("tags") else []
            lines = []
        elif kind is not None:
            lines.append(line)
    flush()
    return cells


def kernelspec() -> dict:
    """The ``kernelspec`` metadata JupyterLab writes for the installed python3 kernel.

    JupyterLab replaces a notebook's kernelspec with the running kernel's as
    it opens it; any difference (a display name "Python 3" against the
    kernel's "Python 3 (ipykernel)") marks the notebook modified at once.
    """
    try:
        spec = KernelSpecManager().get_kernel_spec("python3")
        return {"display_name": spec.display_name, "language": spec.language, "name": "python3"}
    except Exception:  # noqa: BLE001 - no kernelspec installed: the generic one
        return {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"}


def build(src: Path, execute: bool = True) -> Path:
    nb = nbformat.v4.new_notebook()
    nb.cells = parse(src.read_text())
    nb.metadata["kernelspec"] = kernelspec()
    nb.metadata["language_info"] = {"name": "python"}
    out = NB_DIR / (src.stem + ".ipynb")
    if execute:
        NotebookClient(nb, timeout=900, kernel_name="python3",
                       resources={"metadata": {"path": str(NB_DIR)}}).execute()
    nbformat.write(nb, out)
    if execute:
        # Run by us: trusted for this user, so JupyterLab draws the saved widgets before the
        # notebook is run again (trust is kept per user; others run `jupyter trust`, see README)
        NotebookNotary().sign(nb)
    return out


def sources_mismatch(new_cells, stored_cells) -> str:
    """Why ``new_cells`` cannot replace the sources of ``stored_cells`` one to one ("" when they can)."""
    if len(new_cells) != len(stored_cells):
        return f"{len(new_cells)} cells in the source, {len(stored_cells)} stored"
    for i, (new, old) in enumerate(zip(new_cells, stored_cells)):
        if new.cell_type != old.cell_type:
            return f"cell {i + 1} is {new.cell_type} in the source, {old.cell_type} stored"
    return ""


def rewrite_sources(src: Path) -> tuple[Path, str]:
    """Put the cell sources of ``src`` into its stored notebook, keeping outputs and widget state.

    Returns the notebook's path and "" when done, or why the cells do not
    match (then nothing is written).
    """
    out = NB_DIR / (src.stem + ".ipynb")
    if not out.exists():
        return out, f"{out.name} is not stored yet"
    nb = nbformat.read(out, as_version=4)
    new_cells = parse(src.read_text())
    why = sources_mismatch(new_cells, nb.cells)
    if why:
        return out, why
    nb.metadata["kernelspec"] = kernelspec()
    for new, old in zip(new_cells, nb.cells):
        old.source = new.source
        if new.metadata.get("tags"):
            old.metadata["tags"] = new.metadata["tags"]
        else:
            old.metadata.pop("tags", None)
    nbformat.write(nb, out)
    NotebookNotary().sign(nb)  # its outputs are ours, as after build()
    return out, ""


if __name__ == "__main__":
    args = sys.argv[1:]
    if {"-h", "--help"} & set(args):
        print(__doc__)
        sys.exit(0)
    sources_only = "--sources-only" in args
    args = [a for a in args if a != "--sources-only"]
    srcs = [Path(a) for a in args] or sorted((NB_DIR / "src").glob("*.py"))
    for s in srcs:
        if sources_only:
            out, why = rewrite_sources(s.resolve())
            if not why:
                print("sources rewritten, outputs kept:", out)
                continue
            print(f"{out.name}: cannot keep the outputs ({why}); executing it")
        print("built", build(s.resolve()))
