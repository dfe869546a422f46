"""The results store's tables and views: the tables' DDL here, the views' SQL in `views/`.

The result tables are `result_<name>` of each metric table in `metrics.tables.REGISTRY`, with its
columns and types. The views are the `views/*.sql` files whose names start with a number, created in
the order of their names (a view can use those before it). In their SQL, `$name` stands for
`views/_name.sql` (a fragment that several views share) or for what `substitutions` computes: `$t95`
(the Student t table), `$same_group` (w's group is v's: `metrics.groups.GROUP`); a view file that
uses `$table` is made once per registered metric table. Lines starting with `--` are comments.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from string import Template

import duckdb

from metrics.groups import GROUP
from metrics.table import MetricTable
from metrics.tables import REGISTRY
from pipeline.store.records import (
    DESIGN_DDL,
    POLICY_CHECKS_DDL,
    QUALITY_DDL,
    SWEEP_DDL,
    SWEEP_EVENT_DDL,
    TUNING_DDL,
)

VIEWS = Path(__file__).with_name("views")


def _t95() -> str:
    """A `(n, t)` VALUES list: the two-sided 95 % Student t quantile for a mean over n samples (n - 1
    degrees of freedom), n = 2..200; the views use 1.96 beyond."""
    from scipy import stats

    return ", ".join(f"({n}, {float(stats.t.ppf(0.975, n - 1))!r})" for n in range(2, 201))



def _sql(path: Path) -> str:
    """A SQL file's text without its comment lines."""
    lines = path.read_text(encoding="utf-8").splitlines()
    return "\n".join(line for line in lines if not line.lstrip().startswith("--")).strip()


def substitutions() -> dict[str, str]:
    """What `$name` stands for in the views' SQL: each fragment (`views/_<name>.sql`), `t95`, `same_group`."""
    fragments = {p.stem[1:]: _sql(p) for p in sorted(VIEWS.glob("_*.sql"))}
    return {**fragments, "t95": _t95(), "same_group": " AND ".join(f"w.{c} = v.{c}" for c in GROUP)}


def view_files() -> list[Path]:
    """The view files in the order they are created."""
    return sorted(VIEWS.glob("[0-9]*.sql"))


def views(registry: Iterable[MetricTable] = REGISTRY) -> list[str]:
    """Every view's `CREATE OR REPLACE VIEW` statement, in order."""
    subs, out = substitutions(), []
    for path in view_files():
        sql = Template(_sql(path))
        if "$table" in sql.template:
            out += [sql.substitute(subs, table=t.name) for t in registry]
        else:
            out.append(sql.substitute(subs))
    return out


def ensure_schema(con: duckdb.DuckDBPyConnection, registry: Iterable[MetricTable] = REGISTRY) -> None:
    """Create the versions, runs and result tables (`result_<name>` of each metric table in `registry`)
    and (re)create the views."""
    con.execute("CREATE TABLE IF NOT EXISTS versions (version_id BIGINT PRIMARY KEY, "
                "subject VARCHAR NOT NULL, condition VARCHAR NOT NULL, source VARCHAR NOT NULL, "
                "human_mode VARCHAR NOT NULL, "
                "content_hash VARCHAR NOT NULL, params_hash VARCHAR NOT NULL, code_rev VARCHAR NOT NULL, "
                "created_at TIMESTAMP NOT NULL, run_id BIGINT NOT NULL)")
    con.execute("CREATE TABLE IF NOT EXISTS store_runs (run_id BIGINT PRIMARY KEY, created_at TIMESTAMP, "
                "code_rev VARCHAR, subjects VARCHAR, n_groups BIGINT, n_new_versions BIGINT)")
    con.execute(f"CREATE TABLE IF NOT EXISTS sweep_results ({SWEEP_DDL})")
    # the job keys of each study's latest stored results: what the views summarise (sweep_results
    # keeps every job ever stored, e.g. those of older params or policies)
    con.execute("CREATE TABLE IF NOT EXISTS sweep_current (study VARCHAR NOT NULL, job_key VARCHAR NOT NULL, "
                "PRIMARY KEY (study, job_key))")
    for col, kind in SWEEP_EVENT_DDL.items():
        con.execute(f"ALTER TABLE sweep_results ADD COLUMN IF NOT EXISTS {col} {kind}")
    con.execute(f"CREATE TABLE IF NOT EXISTS sensitivity_design ({DESIGN_DDL})")
    con.execute(f"CREATE TABLE IF NOT EXISTS tuned_gains ({TUNING_DDL})")
    for col in ("search_rollouts", "search_falls"):  # stores from before these columns
        con.execute(f"ALTER TABLE tuned_gains ADD COLUMN IF NOT EXISTS {col} BIGINT")
    con.execute(f"CREATE TABLE IF NOT EXISTS quality ({QUALITY_DDL})")
    con.execute("ALTER TABLE quality ADD COLUMN IF NOT EXISTS cause VARCHAR")  # stores from before it
    con.execute(f"CREATE TABLE IF NOT EXISTS policy_checks ({POLICY_CHECKS_DDL})")
    con.execute("ALTER TABLE policy_checks ADD COLUMN IF NOT EXISTS walks INTEGER")  # stores from before it
    con.execute("CREATE TABLE IF NOT EXISTS subjects (subject VARCHAR PRIMARY KEY, round_trip_of VARCHAR, "
                "run_id BIGINT NOT NULL)")
    con.execute("CREATE TABLE IF NOT EXISTS run_groups (run_id BIGINT NOT NULL, subject VARCHAR NOT NULL, "
                "condition VARCHAR NOT NULL, source VARCHAR NOT NULL, human_mode VARCHAR NOT NULL, "
                "version_id BIGINT NOT NULL)")
    for table in registry:
        con.execute(f"CREATE TABLE IF NOT EXISTS result_{table.name} "
                    f"(version_id BIGINT NOT NULL, {table.ddl()})")
    for view in views(registry):
        con.execute(view)

