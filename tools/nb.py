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
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

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


def build(src: Path, execute: bool = True) -> Path:
    nb = nbformat.v4.new_notebook()
    nb.cells = parse(src.read_text())
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    out = NB_DIR / (src.stem + ".ipynb")
    if execute:
        NotebookClient(nb, timeout=900, kernel_name="python3",
                       resources={"metadata": {"path": str(NB_DIR)}}).execute()
    nbformat.write(nb, out)
    if execute:
        # Run by us: trusted for this user, so JupyterLab draws the saved widgets before the
        # notebook is run again (trust is kept per user; others run `jupyter trust`, see README)
        from nbformat.sign import NotebookNotary

        NotebookNotary().sign(nb)
    return out


if __name__ == "__main__":
    srcs = [Path(a) for a in sys.argv[1:]] or sorted((NB_DIR / "src").glob("*.py"))
    for s in srcs:
        print("built", build(s.resolve()))
