"""Reading the results store: one query on a read-only connection; comparing two stores' views."""

from __future__ import annotations

from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from pipeline.store.connection import StoreError, open_store


def query(path: Path, sql: str, busy_timeout_s: float = 10.0) -> pd.DataFrame:
    """Run one SQL statement on a read-only connection and return its result."""
    with open_store(path, True, busy_timeout_s) as con:
        try:
            return con.execute(sql).df()
        except duckdb.Error as exc:
            raise StoreError(path, f"query failed ({' '.join(str(exc).split())})") from None


COMPARED_VIEWS = ("paper_table1", "paper_table2", "paper_table3", "spm_clusters", "latest_harness")
VERSION_COLUMNS = frozenset({"version_id", "run_id", "created_at", "code_rev", "params_hash"})


def _sorted_frame(df: pd.DataFrame) -> pd.DataFrame:
    df = df.drop(columns=[c for c in df.columns if c in VERSION_COLUMNS])
    keys = [c for c in df.columns if not pd.api.types.is_float_dtype(df[c])]
    return df.sort_values(keys + [c for c in df.columns if c not in keys]).reset_index(drop=True)


def compare_views(before: Path, after: Path, views: tuple[str, ...] = COMPARED_VIEWS,
                  rtol: float = 1e-9) -> dict[str, dict]:
    """Per view of two stores: rows, whether they are equal (float columns within `rtol` relative,
    NaN equal to NaN; version bookkeeping ignored) and the largest relative difference."""
    out = {}
    with open_store(before, read_only=True) as a, open_store(after, read_only=True) as b:
        for view in views:
            x = _sorted_frame(a.sql(f"SELECT * FROM {view}").df())
            y = _sorted_frame(b.sql(f"SELECT * FROM {view}").df())
            doc: dict = {"rows_before": len(x), "rows_after": len(y), "max_relative_difference": 0.0}
            same = len(x) == len(y) and list(x.columns) == list(y.columns)
            if same:
                for col in x.columns:
                    if pd.api.types.is_float_dtype(x[col]):
                        u, v = x[col].to_numpy(float), y[col].to_numpy(float)
                        both_nan = np.isnan(u) & np.isnan(v)
                        scale = np.maximum(np.maximum(np.abs(u), np.abs(v)), 1e-300)
                        rel = np.where(both_nan, 0.0, np.abs(u - v) / scale)
                        rel = np.where(np.isnan(rel), np.inf, rel)
                        worst = float(rel.max()) if rel.size else 0.0
                        doc["max_relative_difference"] = max(doc["max_relative_difference"], worst)
                    elif not x[col].astype(str).equals(y[col].astype(str)):
                        same = False
                        doc["differs_in"] = col
                same = same and doc["max_relative_difference"] <= rtol
            doc["equal"] = bool(same)
            out[view] = doc
    return out
