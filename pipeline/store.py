"""The versioned results store: one DuckDB file (`data/results.duckdb`) kept across runs.

Every result row belongs to a version: one (subject, condition, source, human_mode) group's
results at one point in time, with the sha256 of its content, the hash of the params that made it,
the code revision (`git rev-parse HEAD`, 'unknown' outside git) and the creation time.

- A group whose content equals its latest version's content gets no new version: rerunning an
  unchanged pipeline adds nothing. Changed content gets a new version; an earlier version is never
  updated or deleted (content that returns to an older state is a new version, so "latest" is
  always what the last run computed).
- Readers never block a store run and a store run never changes what a reader sees: a run writes a
  copy of the store (`<store>.<pid>.tmp` beside it) and swaps it in (`os.replace`) once committed, so
  a reader (a notebook, any DuckDB client, `read_only=True`) keeps its snapshot until it reconnects,
  and a run killed midway leaves the store as it was (its temp file is deleted by the next run).
- One store run writes at a time: runs take `<store>.lock` (flock), and a DuckDB client holding the
  store itself open for writing is waited for too. A second writer retries for `busy_timeout_s`,
  then fails with `StoreError` "store is busy". Connections are always closed.

SPM tests belong to the group of their second sample (`*_b`: the simulated or the controller
condition); their curves and clusters to the test's version. Base tables are `result_<name>`.
`run_groups` records, for every store run, each group it stored and the version that group resolved
to; `latest_versions` (and every `latest_<name>` view) holds the groups of each subject's last run,
so a condition that a subject no longer has drops out of the latest views while its old versions
stay queryable. `quality` holds each subject's quality gates (`metrics.quality`) of every store run
(`quality_latest`: its last run's; each paper-table row carries its subject's worst status).
`policy_checks` holds `evaluate-policy`'s checks of each subject's policy and cohort variant, a new
version per (subject, variant) when they change (`policy_checks_latest`: the newest).
`paper_table1..3`, `phase_compliance`, `event_aligned`, `spm_clusters`,
`subject_summary` are described in README.md; `sensitivity` (the responsiveness study) in docs/robot.md.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager, suppress
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import duckdb
import numpy as np
import pandas as pd

from ingest.errors import GaitloopError
from pipeline.paths import REPO_ROOT, STORE_FILE

GROUP = ["subject", "condition", "source", "human_mode"]
_GROUP_DDL = "subject VARCHAR, source VARCHAR, human_mode VARCHAR, condition VARCHAR"
# Column types of each result table (names as the metrics tables write them).
SCHEMAS: dict[str, str] = {
    "gait": f"{_GROUP_DDL}, n_strides BIGINT, stride_length_m_mean DOUBLE, stride_length_m_sd DOUBLE, "
            "gait_speed_mps_mean DOUBLE, gait_speed_mps_sd DOUBLE, stride_time_s_mean DOUBLE, "
            "cadence_spm_mean DOUBLE",
    "stability": f"{_GROUP_DDL}, side VARCHAR, joint VARCHAR, n_cycles BIGINT, intercycle_sd_deg DOUBLE, "
                 "note VARCHAR",
    "rom": f"{_GROUP_DDL}, side VARCHAR, joint VARCHAR, n_cycles BIGINT, rom_deg_mean DOUBLE, "
           "rom_deg_sd DOUBLE, min_deg_mean DOUBLE, max_deg_mean DOUBLE",
    "kinematics": f"{_GROUP_DDL}, side VARCHAR, joint VARCHAR, pct DOUBLE, n_cycles BIGINT, mean_deg DOUBLE, "
                  "sd_deg DOUBLE",
    "compliance": f"{_GROUP_DDL}, n_trials BIGINT, n_samples BIGINT, mean_abs_ex_cm DOUBLE, "
                  "sd_abs_ex_cm DOUBLE, mean_abs_ey_cm DOUBLE, sd_abs_ey_cm DOUBLE, max_abs_ex_cm DOUBLE, "
                  "max_abs_ey_cm DOUBLE, "
                  "fall_rate DOUBLE",
    "harness": f"{_GROUP_DDL}, quantity VARCHAR, unit VARCHAR, n_samples BIGINT, rms DOUBLE, peak DOUBLE, "
               "mean DOUBLE",
    "tracking": f"{_GROUP_DDL}, trial VARCHAR, seed BIGINT, time_s DOUBLE, e_x_cm DOUBLE, e_y_cm DOUBLE, "
                "force_n DOUBLE, locked BOOLEAN",
    "spm_tests": "test_id VARCHAR, subject VARCHAR, comparison VARCHAR, side VARCHAR, joint VARCHAR, "
                 "source_a VARCHAR, human_mode_a VARCHAR, condition_a VARCHAR, source_b VARCHAR, "
                 "human_mode_b VARCHAR, condition_b VARCHAR, test VARCHAR, statistic VARCHAR, n_a BIGINT, "
                 "n_b BIGINT, alpha DOUBLE, zstar DOUBLE, df1 DOUBLE, df2 DOUBLE, h0_rejected BOOLEAN, "
                 "n_clusters BIGINT, min_p DOUBLE, status VARCHAR, reason VARCHAR",
    "phases": f"{_GROUP_DDL}, scenario VARCHAR, phase VARCHAR, n_runs BIGINT, n_samples BIGINT, "
              "falls BIGINT, "
              "abs_ex_cm_mean DOUBLE, abs_ex_cm_ci95 DOUBLE, abs_ey_cm_mean DOUBLE, abs_ey_cm_ci95 DOUBLE, "
              "force_rms_n_mean DOUBLE, force_rms_n_ci95 DOUBLE",
    "event_traces": f"{_GROUP_DDL}, scenario VARCHAR, event VARCHAR, t_s DOUBLE, n_runs BIGINT, "
                    "ex_cm_mean DOUBLE, ex_cm_ci95 DOUBLE, ey_cm_mean DOUBLE, ey_cm_ci95 DOUBLE, "
                    "force_n_mean DOUBLE, force_n_ci95 DOUBLE",
    "spm_curves": "test_id VARCHAR, pct DOUBLE, value DOUBLE",
    "spm_clusters": "test_id VARCHAR, cluster BIGINT, start_pct DOUBLE, end_pct DOUBLE, extent_pct DOUBLE, "
                    "p DOUBLE",
}
TABLES = tuple(SCHEMAS)
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
# a sweep walk's summary: two walks with the same one are the same walk (a deterministic walk from
# standing repeats itself in every seed); the fall time tells apart walks that fell before a stride
WALK_SUMMARY = "(gait_speed_mps, stride_length_m, stride_time_cv_pct, n_strides, fell, human_fall_s, walk_s)"
# how a variant's free walks went (cohort views): `no_strides` when none fell and the ingest code kept
# not one stride (it stood, shuffled, or stepped in a way the events do not make strides of: its rows
# describe no measured gait), `fell` when any fell, else `walked`
WALK_STATUS = ("CASE WHEN sum(n_strides) = 0 AND sum(fell::INT) < count(*) THEN 'no_strides' "
               "WHEN sum(fell::INT) > 0 THEN 'fell' ELSE 'walked' END")
LINKED = ("spm_curves", "spm_clusters")  # rows that belong to an SPM test's group via test_id
# The scripted balance-loss rollouts (ev) and, per variant, scenario, event and seed, whether the
# unsupported person fell walking free after the onset (unsupported.falls_free): the confirmation
# that `fall_intervention` counts against and `falls_not_caught` lists from.
EVENTS_FREE = ("WITH ev AS (SELECT * FROM sweep_rollouts WHERE coalesce(event, 'none') <> 'none'), "
               "unsupported AS (SELECT subject, variant, scenario, event, seed, "
               "human_fall_s IS NOT NULL AS falls_free FROM ev "
               "WHERE condition = 'free' AND NOT before_onset) ")


class StoreError(GaitloopError):
    """The results store cannot be opened, is busy, or is missing its inputs."""

    def __init__(self, where: str | Path, problem: str) -> None:
        self.where = str(where)
        super().__init__(f"{self.where}: {problem}")


@dataclass(frozen=True)
class StoreParams:
    """The `store` section of params.yaml."""

    path: Path = STORE_FILE
    busy_timeout_s: float = 10.0
    retry_interval_s: float = 0.2


@dataclass(frozen=True)
class SubjectResults:
    """One subject's metric tables (names in `TABLES`) and the params hash that made them."""

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


def code_rev(root: Path = REPO_ROOT) -> str:
    """`git rev-parse HEAD` of `root`, 'unknown' when not a git checkout."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                             timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() if out.returncode == 0 and out.stdout.strip() else "unknown"


def connect(path: Path, read_only: bool = False, busy_timeout_s: float = 10.0,
            retry_interval_s: float = 0.2) -> duckdb.DuckDBPyConnection:
    """Open the store, waiting up to `busy_timeout_s` while another process holds its lock."""
    path = Path(path)
    if read_only and not path.is_file():
        raise StoreError(path, "no results store here yet: run `python -m pipeline store` first")
    deadline = time.monotonic() + busy_timeout_s
    while True:
        try:
            return duckdb.connect(str(path), read_only=read_only)
        except duckdb.IOException as exc:
            if "lock" not in str(exc).lower():
                raise StoreError(path, f"cannot open the store ({exc})") from None
            if time.monotonic() >= deadline:
                raise StoreError(path, f"store is busy: another process holds its lock; waited "
                                 f"{busy_timeout_s:g} s ({str(exc).splitlines()[0]})") from None
            time.sleep(retry_interval_s)
        except duckdb.Error as exc:
            raise StoreError(path, f"cannot open the store ({exc})") from None


@contextmanager
def _writer_lock(path: Path, busy_timeout_s: float, retry_interval_s: float) -> Iterator[None]:
    """Hold `<path>.lock` (flock, released when this process ends whatever happens), waiting up to
    `busy_timeout_s` for another store run to finish."""
    fd = os.open(path.with_name(f"{path.name}.lock"), os.O_RDWR | os.O_CREAT, 0o644)
    try:
        deadline = time.monotonic() + busy_timeout_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise StoreError(path, f"store is busy: another store run is writing it; waited "
                                     f"{busy_timeout_s:g} s") from None
                time.sleep(retry_interval_s)
        yield
    finally:
        os.close(fd)


@contextmanager
def _writing_copy(path: Path, busy_timeout_s: float = 10.0, retry_interval_s: float = 0.2) -> Iterator[Path]:
    """A copy of the store at `path` (empty when there is none) to write to; once the block ends
    cleanly, the copy replaces the store at once (`os.replace`), otherwise it is deleted and the
    store stays as it was. Readers are never waited for and keep their snapshot; another store run,
    or a client holding the store open for writing, is waited for up to `busy_timeout_s`."""
    path = Path(path)
    with _writer_lock(path, busy_timeout_s, retry_interval_s):
        for stale in path.parent.glob(f"{path.name}.*.tmp*"):  # of runs killed midway: none runs now
            stale.unlink(missing_ok=True)
        temp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        try:
            with ExitStack() as held:
                if path.is_file():
                    if path.with_name(f"{path.name}.wal").is_file():  # a writer's log: fold it in first
                        connect(path, False, busy_timeout_s, retry_interval_s).close()
                    # readers share this read-only lock; it keeps other clients from writing the store
                    # in place until the copy has replaced it
                    held.enter_context(open_store(path, True, busy_timeout_s, retry_interval_s))
                    shutil.copyfile(path, temp)
                yield temp
                os.replace(temp, path)
        finally:
            temp.unlink(missing_ok=True)
            temp.with_name(f"{temp.name}.wal").unlink(missing_ok=True)


@contextmanager
def open_store(path: Path, read_only: bool = False, busy_timeout_s: float = 10.0,
               retry_interval_s: float = 0.2) -> Iterator[duckdb.DuckDBPyConnection]:
    """`connect`, closed on exit whatever happens."""
    con = connect(path, read_only, busy_timeout_s, retry_interval_s)
    try:
        yield con
    finally:
        con.close()


def _t95() -> str:
    """A `(n, t)` VALUES list: the two-sided 95 % Student t quantile for a mean over n samples (n - 1
    degrees of freedom), n = 2..200; the views use 1.96 beyond."""
    from scipy import stats

    return ", ".join(f"({n}, {float(stats.t.ppf(0.975, n - 1))!r})" for n in range(2, 201))


def _views() -> list[str]:
    key = " AND ".join(f"w.{c} = v.{c}" for c in GROUP)
    views = [
        # newest version of every group, whether or not the subject's last run still had it
        "CREATE OR REPLACE VIEW newest_versions AS SELECT * FROM versions v WHERE version_id = "
        f"(SELECT max(version_id) FROM versions w WHERE {key})",
        # the groups of each subject's last store run, each at the version that run resolved it to
        "CREATE OR REPLACE VIEW latest_versions AS SELECT v.* FROM versions v JOIN run_groups g "
        "USING (version_id) WHERE g.run_id = (SELECT max(h.run_id) FROM run_groups h "
        "WHERE h.subject = g.subject)",
    ]
    views += [f"CREATE OR REPLACE VIEW latest_{t} AS SELECT r.* FROM result_{t} r "
              "JOIN latest_versions USING (version_id)" for t in TABLES]

    views += [
        # each subject's quality gates as of its last store run, and its worst status
        "CREATE OR REPLACE VIEW quality_latest AS SELECT q.* FROM quality q WHERE q.run_id = "
        "(SELECT max(u.run_id) FROM quality u WHERE u.subject = q.subject) "
        "ORDER BY subject, stage, \"check\"",
        # the newest evaluation of each subject's policy and cohort variant, one row per check
        "CREATE OR REPLACE VIEW policy_checks_latest AS SELECT c.* EXCLUDE (content_hash) "
        "FROM policy_checks c WHERE c.version_id = (SELECT max(d.version_id) FROM policy_checks d "
        "WHERE d.subject = c.subject AND d.variant = c.variant) ORDER BY subject, variant, \"check\"",
        "CREATE OR REPLACE VIEW quality_worst AS SELECT subject, CASE max(CASE status WHEN 'fail' THEN 2 "
        "WHEN 'warn' THEN 1 WHEN 'ok' THEN 0 END) WHEN 2 THEN 'fail' WHEN 1 THEN 'warn' WHEN 0 THEN 'ok' "
        "ELSE 'unknown' END AS quality FROM quality_latest GROUP BY subject",
    ]

    def real_sim(table: str, keys: list[str], values: list[str], where: str = "TRUE") -> str:
        cols = ", ".join([*(f"r.{v} AS real_{v}" for v in values), *(f"s.{v} AS sim_{v}" for v in values)])
        on = " AND ".join(f"s.{k} = r.{k}" for k in keys)
        sel = ", ".join(f"coalesce(s.{k}, r.{k}) AS {k}" for k in keys)
        joined = (f"SELECT {sel}, s.human_mode AS sim_human_mode, {cols} FROM "
                  f"(SELECT * FROM latest_{table} WHERE source = 'real' AND {where}) r FULL OUTER JOIN "
                  f"(SELECT * FROM latest_{table} WHERE source = 'sim' AND {where}) s ON {on}")
        return (f"SELECT t.*, coalesce(w.quality, 'unknown') AS quality FROM ({joined}) t "
                f"LEFT JOIN quality_worst w ON w.subject = t.subject "
                f"ORDER BY {', '.join(f't.{k}' for k in keys)}, t.sim_human_mode")

    views += [
        "CREATE OR REPLACE VIEW paper_table1 AS " + real_sim(
            "compliance", ["subject", "condition"],
            ["mean_abs_ex_cm", "mean_abs_ey_cm", "sd_abs_ex_cm", "sd_abs_ey_cm", "n_trials", "n_samples",
             "fall_rate"]),
        "CREATE OR REPLACE VIEW paper_table2 AS " + real_sim(
            "gait", ["subject", "condition"],
            ["stride_length_m_mean", "stride_length_m_sd", "gait_speed_mps_mean", "gait_speed_mps_sd",
             "n_strides"]),
        "CREATE OR REPLACE VIEW paper_table3 AS " + real_sim(
            "stability", ["subject", "condition", "side", "joint"], ["intercycle_sd_deg", "n_cycles"]),
        "CREATE OR REPLACE VIEW phase_compliance AS SELECT subject, human_mode, condition, scenario, phase, "
        "n_runs, falls, abs_ex_cm_mean, abs_ex_cm_ci95, abs_ey_cm_mean, abs_ey_cm_ci95, force_rms_n_mean, "
        "force_rms_n_ci95, version_id FROM latest_phases ORDER BY subject, scenario, phase, condition",
        "CREATE OR REPLACE VIEW event_aligned AS SELECT subject, human_mode, condition, scenario, event, "
        "t_s, n_runs, ex_cm_mean, ex_cm_ci95, ey_cm_mean, ey_cm_ci95, force_n_mean, force_n_ci95, version_id "
        "FROM latest_event_traces ORDER BY subject, scenario, event, condition, t_s",
        "CREATE OR REPLACE VIEW spm_clusters AS SELECT t.subject, t.comparison, t.side, t.joint, t.source_a, "
        "t.human_mode_a, t.condition_a, t.source_b, t.human_mode_b, t.condition_b, t.test, t.statistic, "
        "t.zstar, c.cluster, c.start_pct, c.end_pct, c.extent_pct, c.p, t.version_id FROM latest_spm_tests t "
        "JOIN result_spm_clusters c USING (version_id, test_id) "
        "ORDER BY t.subject, t.comparison, t.joint, t.condition_a, t.condition_b, c.cluster",
        # the latest tuned gains per subject, variant and controller, beside the generic ones
        # search_status: 'no signal' when every search rollout fell (each trial scored the fall penalty,
        # so the tuned gains are the first trial's, the generic ones; pipeline.runs.tune.search_falls)
        "CREATE OR REPLACE VIEW tuning_comparison AS SELECT t.* EXCLUDE (content_hash, run_id), "
        "CASE WHEN t.search_rollouts > 0 AND t.search_falls = t.search_rollouts THEN 'no signal' "
        "WHEN t.search_rollouts IS NULL THEN 'unknown' ELSE 'ok' END AS search_status "
        "FROM tuned_gains t "
        "WHERE t.version_id = (SELECT max(u.version_id) FROM tuned_gains u WHERE u.subject = t.subject AND "
        "u.variant = t.variant AND u.controller = t.controller) ORDER BY subject, variant, controller",
        # a study's rollouts per subject, variant, condition and scenario: mean over seeds
        "CREATE OR REPLACE VIEW sweep_summary AS SELECT study, subject, variant, condition, scenario, "
        "coalesce(event, 'none') AS event, "
        "count(*) AS n_runs, sum(fell::INT) AS falls, avg(mean_abs_ex_cm) AS mean_abs_ex_cm, "
        "avg(mean_abs_ey_cm) AS mean_abs_ey_cm, avg(force_rms_n) AS force_rms_n, "
        "avg(gait_speed_mps) AS gait_speed_mps, avg(stride_length_m) AS stride_length_m FROM sweep_results "
        "JOIN sweep_current USING (study, job_key) "
        "GROUP BY ALL ORDER BY study, subject, variant, scenario, event, condition",
        # every rollout of the studies' current jobs once (a job in two studies is the same rollout)
        # (a robot moved away from the twin in the responsiveness study is not the twin: left out)
        "CREATE OR REPLACE VIEW sweep_rollouts AS SELECT DISTINCT ON (job_key) r.* EXCLUDE (study, run_id) "
        "FROM sweep_results r JOIN sweep_current c USING (study, job_key) WHERE (r.study, r.job_key) NOT IN "
        "(SELECT (study, job_key) FROM sensitivity_design WHERE NOT twin) ORDER BY job_key, study",
        # the responsiveness study per subject, variant, scenario, factor, level and controller: mean and
        # 95 % CI (Student t across walks) of the walks' mean |e_x|, |e_y| (cm, samples before an arm lock)
        # and harness force RMS (N); falls (a human fall, an arm lock or an unstable run), arm locks (the
        # fall rule fired: deflection, drop) and human falls counted apart
        "CREATE OR REPLACE VIEW sensitivity AS WITH r AS (SELECT d.factor, d.level, d.twin, s.* "
        "FROM sweep_results s JOIN sweep_current USING (study, job_key) "
        "JOIN sensitivity_design d USING (study, job_key)), "
        f"t AS (SELECT * FROM (VALUES {_t95()}) v(n, t95)), "
        "g AS (SELECT study, subject, variant, scenario, factor, level, condition, bool_and(twin) AS twin, "
        "count(*) AS n, sum(fell::INT) AS falls, count(robot_fall_s) AS arm_locks, "
        "count(human_fall_s) AS human_falls, "
        "avg(mean_abs_ex_cm) AS mean_abs_ex_cm, stddev_samp(mean_abs_ex_cm) AS sd_ex, "
        "avg(mean_abs_ey_cm) AS mean_abs_ey_cm, stddev_samp(mean_abs_ey_cm) AS sd_ey, "
        "avg(force_rms_n) AS force_rms_n, stddev_samp(force_rms_n) AS sd_f, "
        "avg(gait_speed_mps) AS gait_speed_mps FROM r GROUP BY ALL) "
        "SELECT g.study, g.subject, g.variant, g.scenario, g.factor, g.level, g.condition, g.twin, g.n, "
        "g.falls, g.arm_locks, g.human_falls, "
        "g.mean_abs_ex_cm, coalesce(t.t95, 1.96) * g.sd_ex / sqrt(g.n) AS mean_abs_ex_cm_ci95, "
        "g.mean_abs_ey_cm, coalesce(t.t95, 1.96) * g.sd_ey / sqrt(g.n) AS mean_abs_ey_cm_ci95, "
        "g.force_rms_n, coalesce(t.t95, 1.96) * g.sd_f / sqrt(g.n) AS force_rms_n_ci95, g.gait_speed_mps "
        "FROM g LEFT JOIN t ON t.n = g.n "
        "ORDER BY g.study, g.subject, g.variant, g.scenario, g.factor, g.level, g.condition",
        # balance loss x controller x variant: was it caught? (metrics.fall_intervention)
        "CREATE OR REPLACE VIEW fall_intervention AS " + EVENTS_FREE
        + "SELECT e.subject, e.variant, e.event, e.condition, count(*) AS rollouts, "
        "count(*) FILTER (WHERE e.before_onset) AS fell_before_onset, "
        "count(*) FILTER (WHERE NOT e.before_onset) AS events, "
        "count(*) FILTER (WHERE NOT e.before_onset AND u.falls_free) AS events_falling_free, "
        "count(*) FILTER (WHERE NOT e.before_onset AND e.human_fall_s IS NOT NULL) AS human_falls, "
        "avg(e.detected::INT) FILTER (WHERE NOT e.before_onset) AS detection_rate, "
        "avg(e.detected::INT) FILTER (WHERE NOT e.before_onset AND u.falls_free) AS detection_rate_falling, "
        "avg(e.caught::INT) FILTER (WHERE NOT e.before_onset AND u.falls_free) AS caught_rate_falling, "
        "avg(e.latency_s) FILTER (WHERE e.detected) AS latency_s, "
        "avg(e.pelvis_drop_at_lock_m) FILTER (WHERE e.detected) AS pelvis_drop_at_lock_m, "
        "max(e.pelvis_drop_at_lock_m) FILTER (WHERE e.detected) AS worst_drop_at_lock_m, "
        "avg(e.max_harness_force_n) FILTER (WHERE NOT e.before_onset) AS max_harness_force_n, "
        "max(e.max_harness_force_n) FILTER (WHERE NOT e.before_onset) AS peak_harness_force_n "
        "FROM ev e LEFT JOIN unsupported u USING (subject, variant, scenario, event, seed) "
        "GROUP BY ALL ORDER BY e.subject, e.variant, e.event, e.condition",
        # every event the unsupported person fell after (falls_free) that a controller did not catch,
        # with why (the first that applies): no event (the human fell, or the arm locked, before the
        # onset), the simulation went unstable (`fell` without a fall or lock time, sim.rollout.batch),
        # no lock within the detection window, or the pelvis already past the caught drop at the lock
        "CREATE OR REPLACE VIEW falls_not_caught AS " + EVENTS_FREE + "SELECT e.subject, e.variant, "
        "e.event, e.condition, e.scenario, e.seed, e.onset_s, e.human_fall_s, e.robot_fall_s, e.latency_s, "
        "e.pelvis_drop_at_lock_m, CASE WHEN e.before_onset AND e.human_fall_s < e.onset_s "
        "THEN 'fell_before_onset' WHEN e.before_onset THEN 'locked_before_onset' "
        "WHEN e.fell AND e.human_fall_s IS NULL AND e.robot_fall_s IS NULL THEN 'unstable' "
        "WHEN NOT coalesce(e.detected, FALSE) THEN 'not_detected' ELSE 'dropped' END AS reason "
        "FROM ev e JOIN unsupported u USING (subject, variant, scenario, event, seed) "
        "WHERE e.condition <> 'free' AND u.falls_free AND NOT coalesce(e.caught, FALSE) "
        "ORDER BY e.subject, e.variant, e.event, e.condition, e.scenario, e.seed",
        # locks of the arm in normal walking with the robot, over every study, scenario and variant
        "CREATE OR REPLACE VIEW false_alarms AS SELECT subject, variant, condition, count(*) AS rollouts, "
        "sum(walk_s) / 3600.0 AS walking_h, count(*) FILTER (WHERE robot_fall_s IS NOT NULL) AS alarms, "
        "count(*) FILTER (WHERE false_alarm) AS false_alarms, "
        "count(*) FILTER (WHERE false_alarm) / nullif(sum(walk_s) / 3600.0, 0) AS false_alarms_per_h "
        "FROM sweep_rollouts WHERE coalesce(event, 'none') = 'none' AND condition <> 'free' "
        "AND walk_s IS NOT NULL GROUP BY ALL ORDER BY subject, variant, condition",
        # each variant's gait signature walking free without events (metrics.gait_symmetry)
        # distinct_walks (WALK_SUMMARY); the SD across walks needs two distinct ones
        "CREATE OR REPLACE VIEW cohort_gait AS SELECT subject, variant, scenario, count(*) AS walks, "
        f"count(DISTINCT {WALK_SUMMARY}) AS distinct_walks, sum(fell::INT) AS falls, "
        f"avg(gait_speed_mps) AS gait_speed_mps, CASE WHEN count(DISTINCT {WALK_SUMMARY}) > 1 "
        "THEN stddev_samp(gait_speed_mps) END AS gait_speed_sd, avg(stride_length_m) AS stride_length_m, "
        "avg(stance_ratio_lr) AS stance_ratio_lr, avg(swing_ratio_lr) AS swing_ratio_lr, "
        f"avg(stride_time_cv_pct) AS stride_time_cv_pct, sum(n_strides) AS strides, {WALK_STATUS} AS status "
        "FROM sweep_rollouts WHERE coalesce(event, 'none') = 'none' AND condition = 'free' "
        "GROUP BY ALL ORDER BY subject, scenario, variant",
        # cohort x controller: following, harness force, and the gait change versus the same variant free
        "CREATE OR REPLACE VIEW cohort_controllers AS WITH normal AS (SELECT * FROM sweep_rollouts "
        "WHERE coalesce(event, 'none') = 'none'), free AS (SELECT subject, variant, scenario, "
        "avg(gait_speed_mps) AS free_speed, avg(stride_length_m) AS free_stride, "
        f"avg(stride_time_cv_pct) AS free_cv, {WALK_STATUS} AS free_status FROM normal "
        "WHERE condition = 'free' GROUP BY ALL) "
        "SELECT n.subject, n.variant, n.condition, n.scenario, count(*) AS walks, sum(n.fell::INT) AS falls, "
        "avg(n.mean_abs_ex_cm) AS mean_abs_ex_cm, avg(n.mean_abs_ey_cm) AS mean_abs_ey_cm, "
        "avg(n.force_rms_n) AS force_rms_n, 100 * (avg(n.gait_speed_mps) / any_value(f.free_speed) - 1) "
        "AS speed_change_pct, 100 * (avg(n.stride_length_m) / any_value(f.free_stride) - 1) "
        "AS stride_change_pct, avg(n.stride_time_cv_pct) - any_value(f.free_cv) AS cv_change_pct, "
        "any_value(f.free_status) AS free_status "
        "FROM normal n LEFT JOIN free f USING (subject, variant, scenario) WHERE n.condition <> 'free' "
        "GROUP BY ALL ORDER BY n.subject, n.scenario, n.variant, n.condition",
        "CREATE OR REPLACE VIEW subject_summary AS SELECT v.subject, "
        "count(*) AS n_groups, "
        "(SELECT count(*) FROM versions a WHERE a.subject = v.subject) AS n_versions, "
        "string_agg(DISTINCT v.condition, ',' ORDER BY v.condition) AS conditions, "
        "string_agg(DISTINCT v.source || ':' || v.human_mode, ',' ORDER BY v.source || ':' || v.human_mode) "
        "AS sources, "
        "(SELECT sum(n_strides) FROM latest_gait g WHERE g.subject = v.subject AND g.source = 'real') "
        "AS real_strides, "
        "(SELECT sum(n_strides) FROM latest_gait g WHERE g.subject = v.subject AND g.source = 'sim') "
        "AS sim_strides, "
        "(SELECT count(*) FROM latest_spm_tests t WHERE t.subject = v.subject AND t.status = 'ok') "
        "AS spm_tests, "
        "(SELECT count(*) FROM latest_spm_tests t WHERE t.subject = v.subject AND t.h0_rejected) "
        "AS spm_significant, "
        "max(v.created_at) AS last_change, "
        "(SELECT s.round_trip_of FROM subjects s WHERE s.subject = v.subject) AS round_trip_of "
        "FROM latest_versions v GROUP BY v.subject ORDER BY v.subject",
    ]
    return views


def ensure_schema(con: duckdb.DuckDBPyConnection) -> None:
    """Create the versions, runs and result tables and (re)create the views."""
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
    for table, ddl in SCHEMAS.items():
        con.execute(f"CREATE TABLE IF NOT EXISTS result_{table} (version_id BIGINT NOT NULL, {ddl})")
    for view in _views():
        con.execute(view)


def _group_rows(results: SubjectResults) -> dict[tuple, dict[str, pd.DataFrame]]:
    """Split each table into (subject, condition, source, human_mode) groups."""
    out: dict[tuple, dict[str, pd.DataFrame]] = {}
    test_keys = pd.DataFrame(columns=["test_id", *GROUP])
    tests = results.tables.get("spm_tests")
    if tests is not None and not tests.empty:
        test_keys = tests.rename(columns={f"{c}_b": c for c in GROUP[1:]})[["test_id", *GROUP]]
    for table in TABLES:
        df = results.tables.get(table)
        if df is None or df.empty:
            continue
        cols = [c.split()[0] for c in SCHEMAS[table].split(", ")]
        missing = [c for c in cols if c not in df.columns]
        if missing:
            raise StoreError(f"{results.subject}/{table}", f"table lacks columns {missing}")
        df = df[cols].reset_index(drop=True)
        if table == "spm_tests":
            keys = test_keys.reset_index(drop=True)[GROUP]
        elif table in LINKED:
            keys = df[["test_id"]].merge(test_keys, on="test_id", how="left")[GROUP]
            if keys.isna().any().any():
                raise StoreError(f"{results.subject}/{table}", "rows refer to SPM tests not in spm_tests")
        else:
            keys = df[GROUP]
        labels = pd.Series(map(tuple, keys.astype(str).to_numpy()), index=df.index)
        for key, idx in labels.groupby(labels).groups.items():
            out.setdefault(key, {})[table] = df.loc[idx]
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
                  policy_checks: pd.DataFrame | None = None) -> StoreReport:
    """Add new versions for every changed group of `results`, all in one transaction; plus the rows
    of `sweeps` (`SWEEP_COLUMNS`) not stored yet, a new version of each changed `tunings` result
    (`TUNING_COLUMNS` keys) and of each (subject, variant) whose `policy_checks` rows
    (`POLICY_CHECK_COLUMNS`) changed."""
    start = time.perf_counter()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rev = rev or code_rev()
    now = datetime.now(UTC).replace(tzinfo=None)
    with (_writing_copy(path, params.busy_timeout_s, params.retry_interval_s) as temp,
          open_store(temp, False, params.busy_timeout_s, params.retry_interval_s) as con):
        con.execute("BEGIN TRANSACTION")
        try:
            ensure_schema(con)
            latest = {tuple(r[:4]): (r[4], r[5]) for r in con.execute(
                f"SELECT {', '.join(GROUP)}, content_hash, version_id FROM newest_versions").fetchall()}
            next_id = con.execute("SELECT coalesce(max(version_id), 0) + 1 FROM versions").fetchall()[0][0]
            run_id = con.execute("SELECT coalesce(max(run_id), 0) + 1 FROM store_runs").fetchall()[0][0]
            new, n_groups = [], 0
            for res in results:
                for key, tables in _group_rows(res).items():
                    n_groups += 1
                    digest = content_hash(tables)
                    if key in latest and latest[key][0] == digest:
                        con.execute("INSERT INTO run_groups VALUES (?, ?, ?, ?, ?, ?)",
                                    [run_id, *key, latest[key][1]])
                        continue
                    con.execute("INSERT INTO run_groups VALUES (?, ?, ?, ?, ?, ?)", [run_id, *key, next_id])
                    con.execute("INSERT INTO versions VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                [next_id, *key, digest, res.params_hash, rev, now, run_id])
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
