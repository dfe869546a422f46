"""Writing the results store: a new version of each group whose content changed (see `pipeline.store`)."""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Iterable
from contextlib import suppress
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from metrics.groups import GROUP
from metrics.table import MetricTable
from metrics.tables import REGISTRY
from pipeline.store.connection import StoreError, StoreParams, code_rev, open_store, writing_copy
from pipeline.store.records import DESIGN_COLUMNS, POLICY_CHECK_COLUMNS, SWEEP_COLUMNS, TUNING_COLUMNS
from pipeline.store.schema import ensure_schema


@dataclass(frozen=True)
class SubjectResults:
    """One subject's metric tables (names of `metrics.tables.REGISTRY`) and the params hash that made them."""

    subject: str
    tables: dict[str, pd.DataFrame]
    params_hash: str
    round_trip_of: str | None = None  # its "recorded" trials are this subject's exported simulations
    quality: pd.DataFrame | None = None  # its quality gates (`metrics.quality.QUALITY_COLUMNS`)


@dataclass(frozen=True)
class StoreReport:
    run_id: int
    n_groups: int
    new_versions: tuple[int, ...]
    seconds: float



# a group's rows in run_groups and versions, its key in GROUP's order
RUN_GROUP_ROW = f"INSERT INTO run_groups (run_id, {', '.join(GROUP)}, version_id) VALUES (?, ?, ?, ?, ?, ?)"
VERSION_ROW = (f"INSERT INTO versions (version_id, {', '.join(GROUP)}, content_hash, params_hash, code_rev, "
               "created_at, run_id) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)")


def _group_rows(results: SubjectResults, registry: Iterable[MetricTable] = REGISTRY
                ) -> dict[tuple, dict[str, pd.DataFrame]]:
    """Split each table into groups (`GROUP` values, in its order): a table's rows by its `group`
    columns, a linked table's rows by the group of the row they link to."""
    out: dict[tuple, dict[str, pd.DataFrame]] = {}
    keyed: dict[str, pd.DataFrame] = {}  # table -> its columns and each row's GROUP, for linked tables
    for table in registry:
        df = results.tables.get(table.name)
        if table.linked is None:
            keyed[table.name] = pd.DataFrame(columns=[*(c for c in table.columns if c not in GROUP), *GROUP])
        if df is None or df.empty:
            continue
        cols = table.column_names
        missing = [c for c in cols if c not in df.columns]
        if missing:
            raise StoreError(f"{results.subject}/{table.name}", f"table lacks columns {missing}")
        df = df[cols].reset_index(drop=True)
        if table.linked:
            parent, column = table.linked
            keys = df[[column]].merge(keyed[parent][[column, *GROUP]], on=column, how="left")[GROUP]
            if keys.isna().any().any():
                raise StoreError(f"{results.subject}/{table.name}",
                                 f"rows refer to {parent} rows not in {parent} (by {column})")
        else:
            keys = df[list(table.group)].set_axis(GROUP, axis=1)
            keyed[table.name] = pd.concat([df.drop(columns=GROUP, errors="ignore"), keys], axis=1)
        labels = pd.Series(map(tuple, keys.astype(str).to_numpy()), index=df.index)
        for key, idx in labels.groupby(labels).groups.items():
            out.setdefault(key, {})[table.name] = df.loc[idx]
    return out


def content_hash(tables: dict[str, pd.DataFrame]) -> str:
    """sha256 of a group's rows: tables by name, rows sorted, floats rounded to 9 decimals."""
    digest = hashlib.sha256()
    for name in sorted(tables):
        df = tables[name]
        df = df.round({c: 9 for c in df.columns if pd.api.types.is_float_dtype(df[c])})
        df = df.sort_values(list(df.columns)).reset_index(drop=True)
        digest.update(name.encode())
        digest.update(",".join(df.columns).encode())
        rows = pd.util.hash_pandas_object(df.astype(object), index=False).to_numpy(np.uint64)
        digest.update(rows.tobytes())
    return digest.hexdigest()


def store_results(path: Path, results: list[SubjectResults], params: StoreParams = StoreParams(),
                  rev: str | None = None, progress: Callable[[str], None] | None = None,
                  sweeps: list[pd.DataFrame] = (), tunings: list[dict] = (),
                  policy_checks: pd.DataFrame | None = None,
                  registry: Iterable[MetricTable] = REGISTRY) -> StoreReport:
    """Add new versions for every changed group of `results` (its tables: those of `registry`), all in
    one transaction; plus the rows
    of `sweeps` (`SWEEP_COLUMNS`) not stored yet, a new version of each changed `tunings` result
    (`TUNING_COLUMNS` keys) and of each (subject, variant) whose `policy_checks` rows
    (`POLICY_CHECK_COLUMNS`) changed."""
    start = time.perf_counter()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rev = rev or code_rev()
    now = datetime.now(UTC).replace(tzinfo=None)
    with (writing_copy(path, params.busy_timeout_s, params.retry_interval_s) as temp,
          open_store(temp, False, params.busy_timeout_s, params.retry_interval_s) as con):
        con.execute("BEGIN TRANSACTION")
        try:
            ensure_schema(con, registry)
            latest = {tuple(r[:4]): (r[4], r[5]) for r in con.execute(
                f"SELECT {', '.join(GROUP)}, content_hash, version_id FROM newest_versions").fetchall()}
            next_id = con.execute("SELECT coalesce(max(version_id), 0) + 1 FROM versions").fetchall()[0][0]
            run_id = con.execute("SELECT coalesce(max(run_id), 0) + 1 FROM store_runs").fetchall()[0][0]
            new, n_groups = [], 0
            for res in results:
                for key, tables in _group_rows(res, registry).items():
                    n_groups += 1
                    digest = content_hash(tables)
                    if key in latest and latest[key][0] == digest:
                        con.execute(RUN_GROUP_ROW, [run_id, *key, latest[key][1]])
                        continue
                    con.execute(RUN_GROUP_ROW, [run_id, *key, next_id])
                    con.execute(VERSION_ROW, [next_id, *key, digest, res.params_hash, rev, now, run_id])
                    for name, df in tables.items():
                        con.register("incoming", df)
                        con.execute(f"INSERT INTO result_{name} BY NAME "
                                    f"SELECT {next_id}::BIGINT AS version_id, * FROM incoming")
                        con.unregister("incoming")
                        if progress:
                            progress(f"{res.subject}/{'/'.join(key[1:])}/{name}")
                    new.append(next_id)
                    next_id += 1
            for sweep in sweeps:  # a job's rows once, however often it ran (older rows lack newer columns)
                rows = sweep.reindex(columns=SWEEP_COLUMNS).drop_duplicates(["study", "job_key"])
                con.register("incoming", rows.assign(run_id=run_id))
                con.execute("INSERT OR IGNORE INTO sweep_results BY NAME SELECT * FROM incoming")
                con.execute("DELETE FROM sweep_current WHERE study IN (SELECT DISTINCT study FROM incoming)")
                con.execute("INSERT INTO sweep_current SELECT DISTINCT study, job_key FROM incoming")
                con.unregister("incoming")
                if "factor" in sweep.columns:  # the responsiveness study: its design replaces the last one
                    con.register("incoming", sweep.reindex(columns=DESIGN_COLUMNS))
                    con.execute("DELETE FROM sensitivity_design "
                                "WHERE study IN (SELECT DISTINCT study FROM incoming)")
                    con.execute("INSERT INTO sensitivity_design BY NAME SELECT * FROM incoming")
                    con.unregister("incoming")
            for tuning in tunings:
                _store_tuning(con, tuning, run_id, now)
            if policy_checks is not None and not policy_checks.empty:
                _store_policy_checks(con, policy_checks, run_id, now)
            for res in results:  # what each subject is, as of its last store run
                con.execute("INSERT OR REPLACE INTO subjects VALUES (?, ?, ?)",
                            [res.subject, res.round_trip_of, run_id])
                if res.quality is not None and not res.quality.empty:
                    _store_quality(con, res, run_id)
            con.execute("INSERT INTO store_runs VALUES (?, ?, ?, ?, ?, ?)",
                        [run_id, now, rev, ",".join(r.subject for r in results), n_groups, len(new)])
            con.execute("COMMIT")
        except BaseException as exc:
            with suppress(duckdb.Error):  # a failed COMMIT has ended it; the copy is deleted anyway
                con.execute("ROLLBACK")
            if isinstance(exc, duckdb.Error):  # e.g. IO Error: ... No space left on device
                raise StoreError(path, f"cannot write the store ({' '.join(str(exc).split())})") from None
            raise
    return StoreReport(run_id, n_groups, tuple(new), time.perf_counter() - start)


def _store_quality(con: duckdb.DuckDBPyConnection, res: SubjectResults, run_id: int) -> None:
    """The subject's quality rows of this run (`quality_latest` shows the last run's)."""
    columns = ["subject", "stage", "check", "value", "warn_above", "fail_above", "status", "cause", "note"]
    missing = [c for c in columns if c not in res.quality.columns]
    if missing:
        raise StoreError(f"{res.subject}/quality", f"table lacks columns {missing}")
    rows = res.quality[columns].assign(subject=res.subject, run_id=run_id)
    con.register("incoming", rows)
    con.execute("INSERT INTO quality BY NAME SELECT * FROM incoming")
    con.unregister("incoming")


def _store_tuning(con: duckdb.DuckDBPyConnection, tuning: dict, run_id: int, now: datetime) -> None:
    """A new `tuned_gains` version unless the latest of its subject, variant and controller has the
    same content."""
    row = {c: tuning[c] for c in TUNING_COLUMNS}
    row = {k: json.dumps(v, sort_keys=True) if isinstance(v, dict) else v for k, v in row.items()}
    digest = hashlib.sha256(json.dumps(row, sort_keys=True, default=str).encode()).hexdigest()[:16]
    latest = con.execute("SELECT content_hash FROM tuned_gains WHERE subject = ? AND variant = ? AND "
                         "controller = ? ORDER BY version_id DESC LIMIT 1",
                         [row["subject"], row["variant"], row["controller"]]).fetchall()
    latest = latest[0] if latest else None
    if latest and latest[0] == digest:
        return
    version = con.execute("SELECT coalesce(max(version_id), 0) + 1 FROM tuned_gains").fetchall()[0][0]
    con.execute(f"INSERT INTO tuned_gains (version_id, {', '.join(TUNING_COLUMNS)}, content_hash, run_id, "
                f"created_at) VALUES ({', '.join(['?'] * (len(TUNING_COLUMNS) + 4))})",
                [version, *row.values(), digest, run_id, now])


def _store_policy_checks(con: duckdb.DuckDBPyConnection, rows: pd.DataFrame, run_id: int,
                         now: datetime) -> None:
    """A new `policy_checks` version of each (subject, variant) whose rows differ from its latest."""
    missing = [c for c in POLICY_CHECK_COLUMNS if c not in rows.columns]
    if missing:
        raise StoreError("policy_checks", f"rows lack columns {missing}")
    for (subject, variant), group in rows.groupby(["subject", "variant"], sort=True):
        records = [[None if pd.isna(x) else x.item() if isinstance(x, np.generic) else x for x in r]
                   for r in group[POLICY_CHECK_COLUMNS].sort_values("check").itertuples(index=False)]
        digest = hashlib.sha256(json.dumps(records).encode()).hexdigest()[:16]
        latest = con.execute("SELECT content_hash FROM policy_checks WHERE subject = ? AND variant = ? "
                             "ORDER BY version_id DESC LIMIT 1", [subject, variant]).fetchall()
        if latest and latest[0][0] == digest:
            continue
        version = con.execute("SELECT coalesce(max(version_id), 0) + 1 FROM policy_checks").fetchall()[0][0]
        columns = ", ".join(f'"{c}"' for c in POLICY_CHECK_COLUMNS)
        marks = ", ".join(["?"] * (len(POLICY_CHECK_COLUMNS) + 4))
        con.executemany(f"INSERT INTO policy_checks (version_id, {columns}, content_hash, run_id, "
                        f"created_at) VALUES ({marks})",
                        [[version, *r, digest, run_id, now] for r in records])

