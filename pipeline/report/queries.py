"""The store's tables the reports read: one query each (`QUERIES`), on one read-only connection
(`load_report_data`), and one subject's rows of any of them (`of`)."""

from __future__ import annotations

from pathlib import Path

import duckdb
import pandas as pd

from pipeline.store.connection import StoreError, open_store
from sim.rollout.scenarios import PHASES

QUERIES = {
    "table1": "SELECT * FROM paper_table1 ORDER BY subject, condition, sim_human_mode",
    "table2": "SELECT * FROM paper_table2 ORDER BY subject, condition, sim_human_mode",
    "table3": "SELECT * FROM paper_table3 ORDER BY subject, condition, side, joint, sim_human_mode",
    "phases": "SELECT * FROM phase_compliance ORDER BY subject, scenario, "
              f"list_position({list(PHASES)}, phase), condition, human_mode",
    "summary": "SELECT * FROM subject_summary ORDER BY subject",
    "kinematics": "SELECT * FROM latest_kinematics "
                  "ORDER BY subject, source, human_mode, condition, joint, pct",
    "spm_tests": "SELECT * FROM latest_spm_tests ORDER BY subject, comparison, joint, condition_b",
    "spm_curves": "SELECT c.* FROM result_spm_curves c JOIN latest_spm_tests t USING (version_id, test_id) "
                  "ORDER BY c.test_id, c.pct",
    "clusters": "SELECT * FROM spm_clusters",
    "tracking": "SELECT * FROM latest_tracking ORDER BY subject, source, human_mode, condition, time_s",
    "harness": "SELECT * FROM latest_harness ORDER BY subject, source, human_mode, condition, quantity",
    "events": "SELECT * FROM event_aligned ORDER BY subject, human_mode, condition, scenario, event, t_s",
    "tuning": "SELECT * FROM tuning_comparison",
    "quality": 'SELECT * FROM quality_latest ORDER BY subject, stage, "check"',
    "fall": "SELECT * FROM fall_intervention ORDER BY subject, variant, event, condition",
    "not_caught": "SELECT * FROM falls_not_caught "
                  "ORDER BY subject, variant, event, condition, scenario, seed",
    "false_alarms": "SELECT * FROM false_alarms ORDER BY subject, variant, condition",
    "cohort_gait": "SELECT * FROM cohort_gait ORDER BY subject, variant, scenario",
    "cohort_controllers": "SELECT * FROM cohort_controllers ORDER BY subject, variant, scenario, condition",
    "sensitivity": "SELECT * FROM sensitivity ORDER BY subject, variant, scenario, factor, level, condition",
}

# Columns the report reads from views that have grown over time: a store file whose views predate
# this code is named as such instead of failing on a missing attribute.
REQUIRED_COLUMNS = {"table1": ("sim_n_samples", "sim_fall_rate"), "table3": ("side",),
                    "summary": ("round_trip_of",)}
STALE = "they predate this code; rerun `python -m pipeline store` (it recreates the views)"


def load_report_data(db: Path, busy_timeout_s: float = 10.0) -> dict[str, pd.DataFrame]:
    """Every table the reports need, one query each, on one read-only connection."""
    with open_store(db, read_only=True, busy_timeout_s=busy_timeout_s) as con:
        try:
            data = {name: con.execute(sql).df() for name, sql in QUERIES.items()}
        except duckdb.CatalogException as exc:
            raise StoreError(db, f"a view is missing ({str(exc).splitlines()[0]}): {STALE}") from None
    for name, cols in REQUIRED_COLUMNS.items():
        missing = [c for c in cols if c not in data[name].columns]
        if missing:
            raise StoreError(db, f"its views lack {missing}: {STALE}")
    return data


def of(df: pd.DataFrame, subject: str) -> pd.DataFrame:
    """The rows of `subject` (none when `df` has no subject column)."""
    return df[df["subject"] == subject] if "subject" in df.columns else df.iloc[0:0]
