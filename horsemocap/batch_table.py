"""The table of a batch: ``sessions.csv`` (and ``sessions.parquet`` where pyarrow is present), a row per session.

:func:`horsemocap.batch.run_batch` writes it after every session; :func:`read_table` reads it back
(numbers as floats, empty cells as None), e.g. for :func:`horsemocap.herd.table_indicators`.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from .store import atomic_write_text

TABLE_CSV = "sessions.csv"
TABLE_PARQUET = "sessions.parquet"
METADATA_COLUMNS = ("horse", "gait", "rider", "direction")
BASE_COLUMNS = ("name", "folder", "results", "session_name", *METADATA_COLUMNS, "verdict", "exit_status",
                "reused", "seconds", "error")
"""The table's first columns; the indicators of ``comfort.csv`` follow, one column each."""


def _json_row(row: dict) -> dict:
    """The row with NaN as None (JSON has no NaN)."""
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}


# ---------------------------------------------------------------------------
# The table
# ---------------------------------------------------------------------------

def _columns(rows) -> list[str]:
    columns = list(BASE_COLUMNS)
    for row in rows:
        columns.extend(k for k in row if k not in columns)
    return columns


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if not math.isfinite(value) else repr(value)
    return str(value)


def write_table(out_dir, rows) -> tuple[Path, Path | None]:
    """``sessions.csv`` (and ``sessions.parquet`` where pyarrow is importable), each written whole.

    Returns
    -------
    csv_path, parquet_path (None without pyarrow)
    """
    out_dir = Path(out_dir)
    columns = _columns(rows)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in columns])
    csv_path = atomic_write_text(out_dir / TABLE_CSV, buf.getvalue())
    return csv_path, _write_parquet(out_dir / TABLE_PARQUET, rows, columns)


def _write_parquet(path: Path, rows, columns) -> Path | None:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:      # optional: the CSV is the table
        return None
    table = pa.Table.from_pylist([{c: _json_row(r).get(c) for c in columns} for r in rows])
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)
    return path


def read_table(path) -> list[dict]:
    """The rows of a ``sessions.csv``: numbers as floats (NaN where empty), ``exit_status`` an int, ``reused`` a bool."""
    text_columns = {"name", "folder", "results", "session_name", *METADATA_COLUMNS, "verdict", "error"}
    rows = []
    with open(path, newline="", encoding="utf-8") as fh:
        for raw in csv.DictReader(fh):
            row = {}
            for k, v in raw.items():
                if k in text_columns:
                    row[k] = v
                elif k == "exit_status":
                    row[k] = int(v)
                elif k == "reused":
                    row[k] = v == "true"
                else:
                    row[k] = float(v) if v != "" else float("nan")
            rows.append(row)
    return rows


# ---------------------------------------------------------------------------
# Progress and the run
# ---------------------------------------------------------------------------
