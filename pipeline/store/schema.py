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

VIEWS = Path(__file__).with_name("views")

# Studies (`sweep`): one row per rollout job, stored once per (study, job_key) whatever retried it.
# The balance-loss event (metrics.fall_intervention) and left/right timing (metrics.gait_symmetry)
# columns came later: a store from before gets them added (NULL in its old rows).
SWEEP_EVENT_DDL = {
    "event": "VARCHAR", "onset_s": "DOUBLE", "human_fall_s": "DOUBLE", "robot_fall_s": "DOUBLE",
    "before_onset": "BOOLEAN", "detected": "BOOLEAN", "caught": "BOOLEAN", "latency_s": "DOUBLE",
    "pelvis_drop_at_lock_m": "DOUBLE", "max_pelvis_drop_m": "DOUBLE", "max_harness_force_n": "DOUBLE",
    "false_alarm": "BOOLEAN", "walk_s": "DOUBLE", "stance_l_s": "DOUBLE", "stance_r_s": "DOUBLE",
    "swing_l_s": "DOUBLE", "swing_r_s": "DOUBLE", "stance_ratio_lr": "DOUBLE", "swing_ratio_lr": "DOUBLE",
    "stride_time_cv_pct": "DOUBLE"}
SWEEP_COLUMNS = ["study", "job_key", "subject", "variant", "condition", "gains_hash", "scenario", "seed",
                 "params_hash", "mean_abs_ex_cm", "mean_abs_ey_cm", "force_rms_n", "fell",
                 "gait_speed_mps", "stride_length_m", "n_strides", "n_samples", *SWEEP_EVENT_DDL, "wall_s"]
SWEEP_DDL = ("study VARCHAR NOT NULL, job_key VARCHAR NOT NULL, subject VARCHAR, variant VARCHAR, "
             "condition VARCHAR, gains_hash VARCHAR, scenario VARCHAR, seed BIGINT, params_hash VARCHAR, "
             "mean_abs_ex_cm DOUBLE, mean_abs_ey_cm DOUBLE, force_rms_n DOUBLE, fell BOOLEAN, "
             "gait_speed_mps DOUBLE, stride_length_m DOUBLE, n_strides BIGINT, n_samples BIGINT, "
             "wall_s DOUBLE, run_id BIGINT, PRIMARY KEY (study, job_key)")
# Per-subject controller tuning (`tune`): a new version per (subject, variant, controller) when the
# tuned result changes (data/tuning/<subject>/<variant>/<controller>.json).
TUNING_COLUMNS = ["subject", "variant", "controller", "method", "n_trials", "seed", "generic_gains",
                  "tuned_gains", "search_best_objective", "generic_mean", "generic_ci95", "generic_falls",
                  "tuned_mean", "tuned_ci95", "tuned_falls", "n_heldout", "search_rollouts", "search_falls"]
TUNING_DDL = ("version_id BIGINT NOT NULL, subject VARCHAR, variant VARCHAR, controller VARCHAR, "
              "method VARCHAR, n_trials BIGINT, seed BIGINT, generic_gains VARCHAR, tuned_gains VARCHAR, "
              "search_best_objective DOUBLE, generic_mean DOUBLE, generic_ci95 DOUBLE, generic_falls BIGINT, "
              "tuned_mean DOUBLE, tuned_ci95 DOUBLE, tuned_falls BIGINT, n_heldout BIGINT, "
              "content_hash VARCHAR, run_id BIGINT, created_at TIMESTAMP, search_rollouts BIGINT, "
              "search_falls BIGINT")
# The responsiveness study's design (`pipeline.stages.sweep.sensitivity_jobs`): which (factor, level) cells
# each of its jobs stands in, `twin` when the job's robot is the twin's. Each study's latest design only
# (its rows in sweep_results keep every job ever stored).
DESIGN_COLUMNS = ["study", "job_key", "factor", "level", "twin"]
DESIGN_DDL = ("study VARCHAR NOT NULL, job_key VARCHAR NOT NULL, factor VARCHAR NOT NULL, "
              "level DOUBLE NOT NULL, twin BOOLEAN, PRIMARY KEY (study, job_key, factor, level)")
QUALITY_DDL = ('run_id BIGINT NOT NULL, subject VARCHAR NOT NULL, stage VARCHAR, "check" VARCHAR, '
               "value DOUBLE, warn_above DOUBLE, fail_above DOUBLE, status VARCHAR, note VARCHAR, "
               "cause VARCHAR")
# evaluate-policy's checks (`evaluation.json` of each policy folder): one row per check with its
# measured value and the closed interval [low, high] it must lie in (NULL: open side; value, low,
# high and unit NULL for an evaluation from before `check_rows`); a new version per (subject,
# variant) when its rows change.
POLICY_CHECK_COLUMNS = ["subject", "variant", "check", "passed", "value", "low", "high", "unit"]
POLICY_CHECKS_DDL = ('version_id BIGINT NOT NULL, subject VARCHAR NOT NULL, variant VARCHAR NOT NULL, '
                     '"check" VARCHAR NOT NULL, passed BOOLEAN, value DOUBLE, low DOUBLE, high DOUBLE, '
                     "unit VARCHAR, content_hash VARCHAR, run_id BIGINT, created_at TIMESTAMP")


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

