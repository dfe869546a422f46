"""OpenSim `.mot`/`.sto` storage files: joint coordinates (IK) or ground reactions (GRF).

Layout: `key=value` header lines up to `endheader`, then a tab-separated table whose first row
names the columns. `inDegrees=yes|no` says whether rotational columns are degrees or radians.
Every cell read must hold a number: an empty or NaN cell is refused naming its column and rows
(`missing_cells`), never passed on as a hole in a joint curve or a force that never loads.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ingest.errors import IngestError
from ingest.readers.delimited import NON_NEWLINE, NON_SPACE, strict_float_rows


@dataclass(frozen=True)
class MotTable:
    """A storage table as read: `header` holds the `key=value` lines (keys lower-cased)."""

    path: Path
    header: dict[str, str]
    table: pd.DataFrame

    @property
    def in_degrees(self) -> bool | None:
        """True/False as declared by `inDegrees`, None when the header does not say."""
        value = self.header.get("indegrees")
        if value is None:
            return None
        return value.strip().lower() in ("yes", "true", "1")

    @property
    def time_s(self):
        return self.table["time"].to_numpy(dtype=float)

    @property
    def rate_hz(self) -> float:
        t = self.time_s
        return float((len(t) - 1) / (t[-1] - t[0]))

    def values(self, columns: list[str]) -> np.ndarray:
        """The named columns as one (n, len(columns)) float array: one conversion of the whole table,
        since selecting from a table as read (one block per column) costs several times more."""
        index = self.table.columns.get_indexer(columns)
        if (index < 0).any():
            raise KeyError(f"{[c for c, i in zip(columns, index, strict=True) if i < 0]} not in {self.path}")
        return self.table.to_numpy(float)[:, index]


ENDHEADER = re.compile(rb"^[ \t]*endheader[ \t]*\r?$", re.IGNORECASE | re.MULTILINE)


def read_mot(path: str | Path, columns: Callable[[str], bool] | None = None) -> MotTable:
    """Read a `.mot`/`.sto` file; raises `IngestError` naming the file on structural problems. The
    file is read once, as bytes: the header from the text before `endheader`, the table from the
    bytes after it by the strict fast reader (`ingest.readers.delimited`), or by pandas when that
    refuses them (rows ending in a tab, as OpenSim-JAM's GRF files have, are then read with that
    trailing delimiter ignored). `columns`, when given, picks the columns to keep by name (`time`
    is always kept): the others are not converted."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise IngestError(path, f"cannot read file ({exc.strerror})") from None
    end = ENDHEADER.search(raw)
    if end is None:
        raise IngestError(path, "not an OpenSim storage file: no 'endheader' line")
    header = {}
    for ln in raw[:end.start()].decode(errors="replace").splitlines():
        if "=" in ln:
            key, _, value = ln.partition("=")
            header[key.strip().lower()] = value.strip()
    body = raw[end.end():]
    if NON_SPACE.search(body) is None:
        raise IngestError(path, "no column names or data after 'endheader'")
    table, width = _fast_table(body, columns)
    if table is None:
        names = body.decode(errors="replace").strip().split("\n", 1)[0].rstrip("\r").split("\t")
        named = [c.strip() for c in names if c.strip()]
        if len(set(named)) != len(named):
            twice = sorted({c for c in named if named.count(c) > 1})
            raise IngestError(path, f"duplicate column(s) {', '.join(twice)}: each column needs a name "
                                    "of its own")
        table = _float_table(path, body)
        table.columns = [str(c).strip() for c in table.columns]
        trailing = [c for c in table.columns if c.startswith("Unnamed:") and table[c].isna().all()]
        table = table.drop(columns=trailing) if trailing else table  # a header line ending in a tab
        width = table.shape[1]
        if columns is not None:
            table = table[[c for c in table.columns if c == "time" or columns(c)]]
    if "time" not in table.columns:
        raise IngestError(path, f"no 'time' column (columns: {', '.join(table.columns[:6])}, ...)")
    if table.empty:
        raise IngestError(path, "no data rows")
    values = table.to_numpy()
    end_of_rows = len(body)  # the last row: after the last newline before trailing blanks
    while body[end_of_rows - 1] in b" \t\r\n\x0b\x0c":
        end_of_rows -= 1
    last = body[body.rfind(b"\n", 0, end_of_rows) + 1:end_of_rows]
    if len(last.rstrip(b" \r\n").split(b"\t")) < width:
        raise IngestError(path, "truncated: the last row is incomplete")
    if np.isnan(values).any():
        raise IngestError(path, missing_cells(table))
    n_rows = header.get("nrows") or header.get("datarows")
    if n_rows is not None and int(n_rows) != len(table):
        raise IngestError(path, f"truncated: header declares {n_rows} rows, file holds {len(table)}")
    if len(table) > 1 and not (np.diff(values[:, table.columns.get_loc("time")]) > 0).all():
        raise IngestError(path, "time column is not strictly increasing")
    return MotTable(path, header, table)


def missing_cells(table: pd.DataFrame, shown: int = 4) -> str:
    """What a table's empty or NaN cells are, by column: `column: rows a-b (t0-t1 s)`, rows counted
    from 1 after the column names, runs of consecutive rows joined (the first `shown` columns)."""
    time = table["time"].to_numpy(float)
    parts = []
    holes = table.isna().to_numpy()
    columns = [j for j in range(table.shape[1]) if holes[:, j].any()]
    for j in columns[:shown]:
        rows = np.flatnonzero(holes[:, j])
        breaks = np.flatnonzero(np.diff(rows) > 1)
        starts, ends = rows[np.r_[0, breaks + 1]], rows[np.r_[breaks, len(rows) - 1]]
        runs = [f"{a + 1}" if a == b else f"{a + 1}-{b + 1}" for a, b in zip(starts, ends, strict=True)]
        span = "" if table.columns[j] == "time" else f" ({time[rows[0]]:.4g}-{time[rows[-1]]:.4g} s)"
        parts.append(f"{table.columns[j]} rows {', '.join(runs[:3])}{', ...' if len(runs) > 3 else ''}{span}")
    more = f"; and {len(columns) - shown} more columns" if len(columns) > shown else ""
    return f"empty or NaN cells: {'; '.join(parts)}{more} (every cell read must hold a number)"


def _fast_table(body: bytes, columns: Callable[[str], bool] | None) -> tuple[pd.DataFrame | None, int]:
    """The table after `endheader` (its first non-blank line names the columns) by the strict fast
    reader, the kept columns in one float block, and the file's number of columns; (None, 0) when
    the names are not distinct and non-empty or the rows do not read strictly."""
    start = NON_NEWLINE.search(body).start()
    cut = body.find(b"\n", start)
    if cut < 0:
        return None, 0
    names = [c.strip() for c in body[start:cut].decode(errors="replace").split("\t")]
    if not all(names) or len(set(names)) != len(names):
        return None, 0
    keep = [j for j, c in enumerate(names) if columns is None or c == "time" or columns(c)]
    data = strict_float_rows(memoryview(body)[cut + 1:], len(names), keep)
    if data is None:
        return None, 0
    return pd.DataFrame(data, columns=[names[j] for j in keep], copy=False), len(names)


def _float_table(path: Path, body: bytes) -> pd.DataFrame:
    """The table after `endheader`, every column float64: parsed as floats at once (no type
    inference; 4.8 ms against 6.5 ms for Camargo's 55-column GRF file), and only when a cell is
    not a number parsed again untyped to name the columns that hold text."""
    def parse(**typed) -> pd.DataFrame:
        return pd.read_csv(io.BytesIO(body), sep="\t", engine="c", low_memory=False, index_col=False, **typed)

    try:
        return parse(dtype=float)
    except pd.errors.ParserError as exc:
        raise IngestError(path, f"malformed table: {exc}") from None
    except ValueError as exc:
        try:
            table = parse()
        except (ValueError, pd.errors.ParserError) as again:
            raise IngestError(path, f"malformed table: {again}") from None
        non_numeric = [str(c).strip() for c, dtype in table.dtypes.items()
                       if not pd.api.types.is_numeric_dtype(dtype)]
        if non_numeric:
            raise IngestError(path, f"non-numeric values in columns {non_numeric[:5]}") from None
        raise IngestError(path, f"malformed table: {exc}") from None


def write_mot(path: str | Path, table: pd.DataFrame, name: str, in_degrees: bool) -> Path:
    """Write `table` (a `time` column first) as an OpenSim storage file (`version=1`, `nRows`,
    `nColumns`, `inDegrees`, `endheader`), the layout `read_mot` reads."""
    path = Path(path)
    if table.columns[0] != "time":
        raise IngestError(path, f"the first column must be 'time', not {table.columns[0]!r}")
    header = [name, "version=1", f"nRows={len(table)}", f"nColumns={table.shape[1]}",
              f"inDegrees={'yes' if in_degrees else 'no'}", "endheader"]
    body = table.to_csv(sep="\t", index=False, float_format="%.8g", lineterminator="\n")
    path.write_text("\n".join(header) + "\n" + body)
    return path
