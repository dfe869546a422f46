"""The store's tables as the reports print them: each a `Table` (header and rows of text cells),
built by a pure function of the store's rows. `TABLES` is the one list of the tables every report
prints from the store's paper views (a subject's report its own rows, the summary and the index
every subject's)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import pandas as pd

from metrics.plots import EVENT_ORDER, VARIANT_ORDER, ordered
from metrics.quality import NOT_COMPUTED, worst, worst_check
from metrics.tables import by_name
from pipeline.report.cells import falls, following, mean_sd, mode, num
from pipeline.report.published import CONTROLLER_ORDER, PaperValues
from pipeline.report.queries import of


@dataclass(frozen=True)
class Table:
    """A table as printed: column names and rows of text cells, as many in each row."""

    header: list[str]
    rows: list[list[str]] = field(default_factory=list)

    def with_subject(self, subjects) -> Table:
        """This table with a first "Subject" column (`subjects`: one per row)."""
        return Table(["Subject", *self.header], [[s, *r] for s, r in zip(subjects, self.rows, strict=True)])


def _paper(table: dict, condition: str, cell: Callable) -> list[str]:
    """The paper's real and sim cells of one condition ('–' where the paper has no such row)."""
    sources = table.get(condition, {})
    return [cell(sources[s]) if s in sources else "–" for s in ("real", "sim")]


def table1(t: pd.DataFrame, paper: PaperValues) -> Table:
    header = ["Condition", "Sim human", "Real mean abs e_x (cm)", "Real mean abs e_y (cm)",
              "Sim mean abs e_x (cm)", "Sim mean abs e_y (cm)", "Sim runs with a fall",
              "Paper real e_x / e_y (cm)", "Paper sim e_x / e_y (cm)"]
    rows = [[r.condition, mode(r.sim_human_mode), mean_sd(r.real_mean_abs_ex_cm, r.real_sd_abs_ex_cm, 2),
             mean_sd(r.real_mean_abs_ey_cm, r.real_sd_abs_ey_cm, 2),
             following(r.sim_mean_abs_ex_cm, r.sim_sd_abs_ex_cm, r.sim_n_samples),
             following(r.sim_mean_abs_ey_cm, r.sim_sd_abs_ey_cm, r.sim_n_samples),
             falls(r.sim_fall_rate, r.sim_n_trials),
             *_paper(paper.table1, r.condition, lambda v: f"{v.mean_abs_ex_cm:.2f} / {v.mean_abs_ey_cm:.2f}")]
            for r in t.itertuples(index=False)]
    return Table(header, rows)


def table2(t: pd.DataFrame, paper: PaperValues) -> Table:
    header = ["Condition", "Sim human", "Real stride length (m)", "Real gait speed (m/s)",
              "Sim stride length (m)", "Sim gait speed (m/s)", "Paper real stride (m) / speed (m/s)",
              "Paper sim stride (m) / speed (m/s)"]

    def cell(v) -> str:
        return f"{v.stride_length_m[0]:.2f} ± {v.stride_length_m[1]:.2f} / " \
               f"{v.gait_speed_mps[0]:.2f} ± {v.gait_speed_mps[1]:.2f}"

    rows = [[r.condition, mode(r.sim_human_mode),
             mean_sd(r.real_stride_length_m_mean, r.real_stride_length_m_sd, 3, r.real_n_strides),
             mean_sd(r.real_gait_speed_mps_mean, r.real_gait_speed_mps_sd, 3),
             mean_sd(r.sim_stride_length_m_mean, r.sim_stride_length_m_sd, 3, r.sim_n_strides),
             mean_sd(r.sim_gait_speed_mps_mean, r.sim_gait_speed_mps_sd, 3),
             *_paper(paper.table2, r.condition, cell)]
            for r in t.itertuples(index=False)]
    return Table(header, rows)


def table3(t: pd.DataFrame, paper: PaperValues) -> Table:
    header = ["Condition", "Side", "Joint", "Sim human", "Real SD (deg)", "Sim SD (deg)",
              "Paper real SD (deg)", "Paper sim SD (deg)"]
    rows = [[r.condition, r.side, r.joint, mode(r.sim_human_mode),
             mean_sd(r.real_intercycle_sd_deg, None, 2, r.real_n_cycles),
             mean_sd(r.sim_intercycle_sd_deg, None, 2, r.sim_n_cycles),
             *_paper(paper.table3, r.condition, lambda v, j=r.joint: num(v.get(j), 2))]
            for r in t.itertuples(index=False)]
    return Table(header, rows)


def phase_table(t: pd.DataFrame, paper: PaperValues) -> Table:
    header = ["Scenario", "Phase", "Condition", "Sim human", "Runs with a fall", "Mean abs e_x (cm)",
              "Mean abs e_y (cm)", "Harness force RMS (N)"]
    rows = [[r.scenario, r.phase, r.condition, r.human_mode, f"{int(r.falls)}/{int(r.n_runs)}",
             mean_sd(r.abs_ex_cm_mean, r.abs_ex_cm_ci95, 2), mean_sd(r.abs_ey_cm_mean, r.abs_ey_cm_ci95, 2),
             mean_sd(r.force_rms_n_mean, r.force_rms_n_ci95, 2)]
            for r in t.itertuples(index=False)]
    return Table(header, rows)


class StoreTable(NamedTuple):
    """A table of the store the reports print: its title and how its rows are printed."""

    title: str
    build: Callable[[pd.DataFrame, PaperValues], Table]


# The one list (store data key of `queries.QUERIES` -> title and builder); the paper's Tables I-III
# first (`PAPER_TABLES`: the paper's note goes under the last), then the per-phase table. The titles
# are the metric tables' own (`metrics.tables.REPORTED`).
TABLES = {key: StoreTable(by_name(table).title, build) for key, table, build in (
    ("table1", "compliance", table1), ("table2", "gait", table2), ("table3", "stability", table3),
    ("phases", "phases", phase_table))}
PAPER_TABLES = ("table1", "table2", "table3")
# a quality status's background in the index: ok green, warn amber, fail red
STATUS_COLOURS = {"ok": "#c8e6c9", "warn": "#ffe08a", "fail": "#f4a6a6", NOT_COMPUTED: "#eeeeee",
                  "unknown": "#e0e0e0"}


def subjects_table(summary: pd.DataFrame, quality: pd.DataFrame) -> Table:
    """One row per stored subject (`subject_summary`) with its worst quality status and check."""
    header = ["Subject", "Quality", "Worst check", "Conditions", "Sources", "Versions", "Real strides",
              "Sim strides", "SPM tests", "SPM significant", "Last change"]

    rows = [[r.subject, worst(of(quality, r.subject)["status"]), worst_check_text(of(quality, r.subject)),
             r.conditions,
             r.sources, str(r.n_versions), num(r.real_strides, 0), num(r.sim_strides, 0), str(r.spm_tests),
             str(r.spm_significant), str(r.last_change)[:19]]
            for r in summary.itertuples(index=False)]
    return Table(header, rows)


def quality_table(q: pd.DataFrame) -> Table:
    """The quality gates of one subject, failed first, then warned, not computed (`n/a`), ok."""
    header = ["Check", "Value", "Warn above", "Fail above", "Status", "Cause", "Note"]
    if q.empty:
        return Table(header)
    q = q.assign(_order=q["status"].map({"fail": 0, "warn": 1, NOT_COMPUTED: 2, "ok": 3}).fillna(4))
    q = q.sort_values(["_order", "stage", "check"], kind="stable")
    rows = [[f"{r.stage}/{r.check}", num(r.value, 4), num(r.warn_above, 4), num(r.fail_above, 4), r.status,
             getattr(r, "cause", None) or "", r.note or ""] for r in q.itertuples(index=False)]
    return Table(header, rows)


def worst_check_text(q: pd.DataFrame) -> str:
    """'stage/check: cause' of a subject's worst graded check (`metrics.quality.worst_check`); '' when
    none is graded."""
    row = worst_check(q) if not q.empty else None
    if row is None:
        return ""
    return f"{row['stage']}/{row['check']}: {row.get('cause') or row['note'] or ''}".rstrip(": ")


ORDERS = {"variant": VARIANT_ORDER, "event": EVENT_ORDER, "condition": CONTROLLER_ORDER}


def in_order(df: pd.DataFrame, *columns: str) -> pd.DataFrame:
    """`df` sorted by `columns`, variants, events and controllers in their usual order (`ORDERS`),
    other columns and unknown values alphabetically after them."""
    if df.empty:
        return df

    def rank(col: pd.Series) -> pd.Series:
        if col.name not in ORDERS:
            return col
        return col.map({v: i for i, v in enumerate(ordered(col, ORDERS[col.name]))})

    return df.sort_values(list(columns), key=rank, kind="stable")
