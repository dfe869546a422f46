"""Stage `report`: the store's latest results -> Markdown reports, figures and a static index.

Reads the results store (read-only, one query per table in `QUERIES`), the reference paper's
published values (`data/paper/wang2025.yaml`, `load_paper`) and each subject's policy evaluation
(`data/policies/<subject>/evaluation.json`, when present), and writes:
- `reports/<subject>/report.md`, opening with its quality gates (`quality_latest`, failed and warned
  first), then Tables I-III (Real, Sim and the paper's published columns),
  the per-phase compliance table, the policy checks, SPM clusters and the figures of `subject_figures` in
  `reports/<subject>/figures/`;
- `reports/summary.md` and `reports/index.html`: every subject's figures first (`FIGURES`), then the
  tables side by side (the subjects' table with each one's worst quality status, coloured in the
  index), linking the per-subject reports.
Numbers are printed rounded (cm, N and deg to 2 decimals, m and m/s to 3, the paper's values as
published); the store keeps them exact.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import duckdb
import pandas as pd
import yaml
from matplotlib.figure import Figure
from pydantic import BaseModel, ConfigDict, ValidationError

from ingest.errors import GaitloopError
from metrics.plots import (
    event_figure,
    group_label,
    harness_figure,
    kinematics_figure,
    spm_figure,
    tracking_figure,
    tuning_figure,
)
from metrics.quality import worst
from pipeline.params import ReportParams
from pipeline.paths import PAPER_FILE, POLICIES_ROOT, REPORTS_ROOT, policy_dir, report_dir
from pipeline.stages.outputs import replacing, write_figure
from pipeline.store import StoreError, open_store
from sim.rollout.scenarios import PHASES

# -- the reference paper's published values (data/paper/wang2025.yaml) --------------------------------
# Wang, Chan et al., ICRA 2025 (arXiv:2503.05825), Tables I-III, for their own participant: printed
# beside each subject's Real and Sim columns for orientation (the file cites its source). Keys mirror
# the tables: condition -> `real` (their recorded trials) or `sim` (their simulation) -> values.

Source = Literal["real", "sim"]


class PaperError(GaitloopError):
    """The paper values file is missing, not YAML, or not in the expected layout."""

    def __init__(self, path: str | Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PaperCompliance(_Strict):
    """Table I: mean |e_x| and |e_y| (cm); no SD published."""

    mean_abs_ex_cm: float
    mean_abs_ey_cm: float


class PaperGait(_Strict):
    """Table II: (mean, SD) of stride length (m) and gait speed (m/s)."""

    stride_length_m: tuple[float, float]
    gait_speed_mps: tuple[float, float]


class PaperValues(_Strict):
    """The whole file: citation, the paper's participant, and the three tables by condition."""

    citation: str
    participant: str
    table1: dict[str, dict[Source, PaperCompliance]]
    table2: dict[str, dict[Source, PaperGait]]
    table3: dict[str, dict[Source, dict[str, float]]]  # inter-cycle SD (deg) per joint

    def note(self) -> str:
        """The sentence that goes under the tables that show these values."""
        return (f"Paper columns: the values published by {self.citation}, for their own participant: "
                f"{self.participant}. Paper real = their recorded trials, paper sim = their simulation. "
                "They describe another person and robot: shown for orientation only, not as targets.")


def load_paper(path: Path = PAPER_FILE) -> PaperValues:
    """Read and check the paper values file; `PaperError` names the file and the problem."""
    try:
        return PaperValues.model_validate(yaml.safe_load(Path(path).read_text()))
    except OSError as exc:
        raise PaperError(path, f"cannot read the paper values ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise PaperError(path, f"not YAML ({exc})") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(k) for k in first["loc"])
        raise PaperError(path, f"{where}: {first['msg']}") from None


# -- the store's tables -------------------------------------------------------------------------------

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
}
# Every figure a report can have, in the order the index shows them, with its caption.
FIGURES = {
    "events": "Forward and lateral offset e_x, e_y and harness force |f| around the commanded start, turn "
              "and stop, per controller (policy human; mean and 95 % CI across runs)",
    "kinematics_policy": "Gait per controller: the policy human's joint angles walking free, with pid and "
                         "with adaptive (mean ± SD over the cycles sampled like the paper)",
    "tracking": "e_x, e_y and harness |F| over the first run of each condition",
    "harness": "Harness force and torque magnitude, RMS and peak per condition",
    "kinematics": "Joint angles of every source and condition (mean ± SD over cycles)",
    "spm": "SPM1D statistic curves, thresholds (dashed) and supra-threshold clusters (shaded)",
    "tuning": "Per-subject controller tuning (`tune`): the objective of metrics/outcomes.py on the held-back "
              "walks with the generic and the tuned gains (mean and 95 % CI across rollouts; falls above "
              "each bar)",
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


def _num(x, digits: int) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)) or x is pd.NA:
        return "–"
    return f"{float(x):.{digits}f}"


def _mean_sd(mean, sd, digits: int, n=None) -> str:
    if _num(mean, digits) == "–":
        return "–" if n is None or _num(n, 0) == "–" else f"– (n={int(n)})"
    text = _num(mean, digits) + ("" if _num(sd, digits) == "–" else f" ± {_num(sd, digits)}")
    return text + ("" if n is None or _num(n, 0) == "–" else f" (n={int(n)})")


def md_table(header: list[str], rows: list[list[str]]) -> str:
    if not rows:
        return "_No rows._\n"
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _mode(x) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else str(x)


def _following(mean, sd, n_samples) -> str:
    if _num(n_samples, 0) == "0":
        return "no samples (arm locked by a fall in every run)"
    return _mean_sd(mean, sd, 2)


def _falls(rate, n_trials) -> str:
    if _num(rate, 2) == "–":
        return "–"
    return f"{round(float(rate) * int(n_trials))}/{int(n_trials)}"


def _paper(table: dict, condition: str, cell: Callable) -> list[str]:
    """The paper's real and sim cells of one condition ('–' where the paper has no such row)."""
    sources = table.get(condition, {})
    return [cell(sources[s]) if s in sources else "–" for s in ("real", "sim")]


def table1_rows(t: pd.DataFrame, paper: PaperValues) -> tuple[list[str], list[list[str]]]:
    header = ["Condition", "Sim human", "Real mean abs e_x (cm)", "Real mean abs e_y (cm)",
              "Sim mean abs e_x (cm)", "Sim mean abs e_y (cm)", "Sim runs with a fall",
              "Paper real e_x / e_y (cm)", "Paper sim e_x / e_y (cm)"]
    rows = [[r.condition, _mode(r.sim_human_mode), _mean_sd(r.real_mean_abs_ex_cm, r.real_sd_abs_ex_cm, 2),
             _mean_sd(r.real_mean_abs_ey_cm, r.real_sd_abs_ey_cm, 2),
             _following(r.sim_mean_abs_ex_cm, r.sim_sd_abs_ex_cm, r.sim_n_samples),
             _following(r.sim_mean_abs_ey_cm, r.sim_sd_abs_ey_cm, r.sim_n_samples),
             _falls(r.sim_fall_rate, r.sim_n_trials),
             *_paper(paper.table1, r.condition, lambda v: f"{v.mean_abs_ex_cm:.2f} / {v.mean_abs_ey_cm:.2f}")]
            for r in t.itertuples(index=False)]
    return header, rows


def table2_rows(t: pd.DataFrame, paper: PaperValues) -> tuple[list[str], list[list[str]]]:
    header = ["Condition", "Sim human", "Real stride length (m)", "Real gait speed (m/s)",
              "Sim stride length (m)", "Sim gait speed (m/s)", "Paper real stride (m) / speed (m/s)",
              "Paper sim stride (m) / speed (m/s)"]

    def cell(v) -> str:
        return f"{v.stride_length_m[0]:.2f} ± {v.stride_length_m[1]:.2f} / " \
               f"{v.gait_speed_mps[0]:.2f} ± {v.gait_speed_mps[1]:.2f}"

    rows = [[r.condition, _mode(r.sim_human_mode),
             _mean_sd(r.real_stride_length_m_mean, r.real_stride_length_m_sd, 3, r.real_n_strides),
             _mean_sd(r.real_gait_speed_mps_mean, r.real_gait_speed_mps_sd, 3),
             _mean_sd(r.sim_stride_length_m_mean, r.sim_stride_length_m_sd, 3, r.sim_n_strides),
             _mean_sd(r.sim_gait_speed_mps_mean, r.sim_gait_speed_mps_sd, 3),
             *_paper(paper.table2, r.condition, cell)]
            for r in t.itertuples(index=False)]
    return header, rows


def table3_rows(t: pd.DataFrame, paper: PaperValues) -> tuple[list[str], list[list[str]]]:
    header = ["Condition", "Side", "Joint", "Sim human", "Real SD (deg)", "Sim SD (deg)",
              "Paper real SD (deg)", "Paper sim SD (deg)"]
    rows = [[r.condition, r.side, r.joint, _mode(r.sim_human_mode),
             _mean_sd(r.real_intercycle_sd_deg, None, 2, r.real_n_cycles),
             _mean_sd(r.sim_intercycle_sd_deg, None, 2, r.sim_n_cycles),
             *_paper(paper.table3, r.condition, lambda v, j=r.joint: _num(v.get(j), 2))]
            for r in t.itertuples(index=False)]
    return header, rows


def phase_rows(t: pd.DataFrame, paper: PaperValues) -> tuple[list[str], list[list[str]]]:
    header = ["Scenario", "Phase", "Condition", "Sim human", "Runs with a fall", "Mean abs e_x (cm)",
              "Mean abs e_y (cm)", "Harness force RMS (N)"]
    rows = [[r.scenario, r.phase, r.condition, r.human_mode, f"{int(r.falls)}/{int(r.n_runs)}",
             _mean_sd(r.abs_ex_cm_mean, r.abs_ex_cm_ci95, 2), _mean_sd(r.abs_ey_cm_mean, r.abs_ey_cm_ci95, 2),
             _mean_sd(r.force_rms_n_mean, r.force_rms_n_ci95, 2)]
            for r in t.itertuples(index=False)]
    return header, rows


TABLES = {
    "table1": ("Table I: compliance, mean absolute offset of the pelvis from the arm's neutral point "
               "(mean ± SD over samples)", table1_rows),
    "table2": ("Table II: stride length and gait speed (mean ± SD over kept strides, n strides)",
               table2_rows),
    "table3": ("Table III: inter-cycle SD of the sagittal joint angles, averaged over the cycle "
               "(n cycles)", table3_rows),
    "phases": ("Compliance and harness force per scenario phase (mean ± 95 % CI across runs; falls "
               "count the runs that had fallen by the end of the phase)", phase_rows),
}
PAPER_TABLES = ("table1", "table2", "table3")


NO_GATES = "No quality gates stored for this subject (run `python -m pipeline metrics` and `store`)."
STATUS_COLOURS = {"ok": "#c8e6c9", "warn": "#ffe08a", "fail": "#f4a6a6", "unknown": "#e0e0e0"}


def quality_rows(q: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """The quality gates of one subject, failed first, then warned, then ok."""
    header = ["Check", "Value", "Warn above", "Fail above", "Status", "Note"]
    if q.empty:
        return header, []
    q = q.assign(_order=q["status"].map({"fail": 0, "warn": 1, "ok": 2}).fillna(3))
    q = q.sort_values(["_order", "stage", "check"], kind="stable")
    rows = [[f"{r.stage}/{r.check}", _num(r.value, 4), _num(r.warn_above, 4), _num(r.fail_above, 4), r.status,
             r.note or ""] for r in q.itertuples(index=False)]
    return header, rows


def _of(df: pd.DataFrame, subject: str) -> pd.DataFrame:
    return df[df["subject"] == subject] if "subject" in df.columns else df.iloc[0:0]


def subject_figures(subject: str, data: dict[str, pd.DataFrame], p: ReportParams = ReportParams()
                    ) -> dict[str, Callable[[], Figure]]:
    """The figures of `subject` (names in `FIGURES`, in that order), each drawn when called; which
    ones exist follows from the stored data alone, so the index can list them without drawing."""
    bands = _of(data["kinematics"], subject)
    side = "both" if (bands["side"] == "both").any() else "right"
    bands = bands[bands["side"] == side]
    policy = bands[(bands["source"] == "sim") & (bands["human_mode"] == "policy")]
    events = _of(data["events"], subject)
    chosen = [(e, s) in p.event_scenarios.items() for e, s in zip(events["event"], events["scenario"],
                                                                  strict=True)]
    events = events[chosen]
    tests = _of(data["spm_tests"], subject)
    curves = data["spm_curves"][data["spm_curves"]["test_id"].isin(tests["test_id"])]
    tracking, harness = _of(data["tracking"], subject), _of(data["harness"], subject)
    statistic = "F" if (tests["test"] == "anova1").all() else "t"
    tuning = _of(data["tuning"], subject)
    figures = {
        "events": lambda: event_figure(events, list(p.event_scenarios),
                                       f"{subject}: around the commanded events (mean, 95 % CI across runs)"),
        "kinematics_policy": lambda: kinematics_figure(
            policy, f"{subject}: gait per controller, policy human (mean ± SD, side {side})"),
        "tracking": lambda: tracking_figure(tracking, f"{subject}: tracking (first run per condition)"),
        "harness": lambda: harness_figure(harness, f"{subject}: harness interaction"),
        "kinematics": lambda: kinematics_figure(
            bands, f"{subject}: joint kinematics (mean ± SD, side {side})"),
        "spm": lambda: spm_figure(tests, curves, f"{subject}: SPM{{{statistic}}} (alpha 0.05)"),
        "tuning": lambda: tuning_figure(tuning, f"{subject}: controller tuning, held-back objective "
                                                "(mean, 95 % CI)"),
    }
    present = {"events": not events.empty, "kinematics_policy": not policy.empty,
               "tracking": not tracking.empty, "harness": not harness.empty, "tuning": not tuning.empty}
    return {name: draw for name, draw in figures.items() if present.get(name, True)}


def _image(name: str) -> list[str]:
    return [f"![{name}](figures/{name}.png)", "", f"*{FIGURES[name]}.*", ""]


def policy_check_lines(doc: dict | None) -> list[str]:
    """The `evaluate-policy` result of the subject's committed policy (its evaluation.json): every
    check with pass / FAIL, and per scenario and condition the walks, falls and timings."""
    if doc is None:
        return ["No `evaluate-policy` result for this subject's policy (run `python -m pipeline "
                "evaluate-policy <subject> --out data/policies/<subject>/evaluation.json`).", ""]
    checks = doc.get("checks", {})
    rows = [[name, "pass" if ok else ("not judged" if ok is None else "FAIL")] for name, ok in checks.items()]
    lines = [f"{sum(bool(v) for v in checks.values())} of {len(checks)} checks pass.", "",
             md_table(["check", "result"], rows)]
    sc = doc.get("scenarios")
    if sc:
        lines += [f"Scenario walks (the subject's own start: {sc.get('own_start_s')} s; accepted start "
                  f"window {sc.get('start_window_s')} s):", ""]
        rows = [[key, str(v["walks"]), str(v["human_falls"]), str(v.get("start_s", "–")),
                 str(v.get("stop_s", "–")), str(v.get("steady_speed_mps", "–"))]
                for key, v in sc.items() if isinstance(v, dict) and "walks" in v]
        lines += [md_table(["scenario condition", "walks", "human falls", "start (s)", "stop (s)",
                            "steady speed (m/s)"], rows)]
    return lines


def subject_report(subject: str, data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams(), paper: PaperValues | None = None,
                   evaluation: dict | None = None) -> Path:
    """Write `reports/<subject>/report.md` and its figures; returns the report path. `evaluation`:
    the evaluate-policy result of its policy, if any."""
    paper = paper or load_paper(PAPER_FILE)
    summary = _of(data["summary"], subject)
    if summary.empty:
        raise StoreError(subject, "no stored results for this subject: run `python -m pipeline store`")
    folder = report_dir(reports, subject)
    figures = subject_figures(subject, data, p)
    for name, draw in figures.items():
        write_figure(draw(), folder / "figures" / f"{name}.png", p.dpi)
    s = summary.iloc[0]
    lines = [f"# {subject}: HITL gait report", ""]
    if isinstance(s["round_trip_of"], str) and s["round_trip_of"]:
        lines += [f"**Round trip:** this subject's \"recorded\" trials are {s['round_trip_of']}'s simulated "
                  "trials, exported as OpenSim files and robot logs (`python -m pipeline export`) and read "
                  "back; its Real columns test the pipeline, not a person.", ""]
    header, rows = quality_rows(_of(data["quality"], subject))
    gates = [md_table(header, rows)] if rows else [NO_GATES, ""]
    lines += ["## Quality gates", "", *gates,
              f"Worst status: **{worst(r[4] for r in rows)}**.", "",
              "Built from the results store (`data/results.duckdb`, latest version of each subject, "
              "condition, source and human mode). Real = recorded mocap; Sim = the human digital twin "
              "walking with the MRBA twin (`replay` or `policy` human).", ""]
    lines += [f"Conditions: {s['conditions']}. Sources: {s['sources']}. Kept strides real/sim: "
              f"{_num(s['real_strides'], 0)}/{_num(s['sim_strides'], 0)}. "
              f"SPM tests run: {int(s['spm_tests'])}, "
              f"with supra-threshold clusters: {int(s['spm_significant'])}.", ""]
    for key in PAPER_TABLES:
        title, build = TABLES[key]
        header, rows = build(_of(data[key], subject), paper)
        lines += [f"## {title}", "", md_table(header, rows)]
        if key == "table1" and not rows:
            lines += ["No robot data for this subject yet (Table I needs simulated robot tables).", ""]
    lines += [paper.note(), ""]

    title, build = TABLES["phases"]
    lines += [f"## {title}", "", md_table(*build(_of(data["phases"], subject), paper))]
    lines += ["## Policy human checks (evaluate-policy)", "", *policy_check_lines(evaluation)]
    sections = {"events": "Around the commanded events", "kinematics_policy": "Gait per controller",
                "kinematics": "Joint kinematics", "spm": "SPM1D", "tracking": "Tracking",
                "harness": "Harness force and torque"}
    for name, heading in sections.items():
        if name in figures:
            lines += [f"## {heading}", "", *_image(name)]
        if name == "spm":
            lines += _spm_lines(_of(data["spm_tests"], subject), _of(data["clusters"], subject))
    if "tracking" not in figures and "harness" not in figures:
        lines += ["## Tracking and harness force", "", "No simulated robot runs for this subject yet.", ""]
    lines += tuning_lines(_of(data["tuning"], subject), "tuning" in figures)
    path = folder / "report.md"
    with replacing(path) as (temp,):
        temp.write_text("\n".join(lines))
    return path


def _gains(doc) -> str:
    gains = json.loads(doc) if isinstance(doc, str) else dict(doc)
    return ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in gains.items())


def _cost(mean, ci, falls, n) -> str:
    return f"{_mean_sd(mean, ci, 4)} ({_num(falls, 0)}/{_num(n, 0)} falls)"


def tuning_lines(tuning: pd.DataFrame, figure: bool) -> list[str]:
    """The "Controller tuning" section: per controller and variant the held-back objective with the
    generic and the tuned gains (mean ± 95 % CI across rollouts, falls) and the tuned gains."""
    lines = ["## Controller tuning", ""]
    if tuning.empty:
        return lines + ["No tuned gains for this subject yet (run `python -m pipeline tune <subject> "
                        "--controller <name>`, then `store`).", ""]
    rows = [[r.controller, r.variant, f"{r.method}, {int(r.n_trials)} trials",
             _cost(r.generic_mean, r.generic_ci95, r.generic_falls, r.n_heldout),
             _cost(r.tuned_mean, r.tuned_ci95, r.tuned_falls, r.n_heldout), _gains(r.tuned_gains)]
            for r in tuning.sort_values(["controller", "variant"]).itertuples(index=False)]
    lines += ["Objective (metrics/outcomes.py, lower is better): |e_x| + |e_y| (m) + harness force RMS and "
              "gait-speed change versus walking free, weighted, + a penalty per fall; on held-back walks "
              "the search never saw (mean ± 95 % CI across rollouts).", "",
              md_table(["Controller", "Variant", "Search", "Generic gains", "Tuned gains",
                        "Tuned gain values"], rows)]
    return lines + (_image("tuning") if figure else [])


def _spm_lines(tests: pd.DataFrame, clusters: pd.DataFrame) -> list[str]:
    """The SPM clusters table and the skipped comparisons with their reasons."""
    lines = ["The paper's one-way ANOVA unless params say `ttest2`.", "",
             md_table(["Comparison", "Joint", "A", "B", "Cluster (% cycle)", "p"],
                      [[c.comparison, c.joint, group_label(c.source_a, c.human_mode_a, c.condition_a),
                        group_label(c.source_b, c.human_mode_b, c.condition_b),
                        f"{c.start_pct:.1f}–{c.end_pct:.1f}", "<0.001" if c.p < 0.001 else f"{c.p:.3f}"]
                       for c in clusters.itertuples()])]
    skipped = tests[tests["status"] != "ok"]
    if not skipped.empty:
        lines += ["Skipped comparisons:", ""] + [
            f"- {r.joint}: {group_label(r.source_a, r.human_mode_a, r.condition_a)} vs "
            f"{group_label(r.source_b, r.human_mode_b, r.condition_b)}: {r.reason}"
            for r in skipped.itertuples()
        ] + [""]
    return lines


def figure_names(subject: str, data: dict[str, pd.DataFrame], p: ReportParams = ReportParams()) -> list[str]:
    """The figures `subject_report` draws for a subject, in index order."""
    return list(subject_figures(subject, data, p))


def _html_cell(header: str, cell: str) -> str:
    """A table cell; a quality status is coloured (ok green, warn amber, fail red)."""
    if header in ("Status", "Quality") and cell in STATUS_COLOURS:
        return f'<td class="q-{cell}" style="background:{STATUS_COLOURS[cell]}">{html.escape(cell)}</td>'
    return f"<td>{html.escape(cell)}</td>"


def _html_table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(_html_cell(h, c) for h, c in zip(header, r, strict=True)) + "</tr>"
                   for r in rows)
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>{body}</tbody>\n</table>\n"


def summary_report(subjects: list[str], data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams(), paper: PaperValues | None = None) -> tuple[Path, Path]:
    """Write `reports/summary.md` and `reports/index.html` across subjects: figures first, then the
    subject summary, Tables I-III with the paper's values and the per-phase table."""
    paper = paper or load_paper(PAPER_FILE)
    reports = Path(reports)
    stored = set(data["summary"]["subject"]) if not data["summary"].empty else set()
    md = ["# gaitloop: cross-subject summary", "", "## Figures", ""]
    body = ["<h1>gaitloop: cross-subject summary</h1>", '<p><a href="summary.md">summary.md</a></p>',
            "<h2>Figures</h2>"]
    for s in subjects:
        if s not in stored:
            md.append(f"- {s}: no stored results yet")
            body.append(f"<p>{html.escape(s)}: no stored results yet</p>")
            continue
        md += [f"### [{s}]({s}/report.md)", ""]
        body.append(f'<h3><a href="{s}/report.md">{html.escape(s)}</a></h3>')
        for name in figure_names(s, data, p):
            md += [f"![{s} {name}]({s}/figures/{name}.png)", "", f"*{FIGURES[name]}.*", ""]
            img = f'<img src="{s}/figures/{name}.png" alt="{html.escape(s)} {name}" width="900">'
            body.append(f"<figure>{img}<figcaption>{html.escape(FIGURES[name])}</figcaption></figure>")
        videos = sorted((reports / s).glob("rollout_walk_10m_*.mp4"))  # `make videos`
        if videos:
            links = [f'<a href="{s}/{v.name}">{html.escape(v.stem.removeprefix("rollout_walk_10m_"))}</a>'
                     for v in videos]
            md += ["Videos, walk_10m: " + ", ".join(f"[{v.stem}]({s}/{v.name})" for v in videos), ""]
            body.append("<p>Videos of the policy human in walk_10m: " + ", ".join(links) + "</p>")
    sh = ["Subject", "Quality", "Conditions", "Sources", "Versions", "Real strides", "Sim strides",
          "SPM tests", "SPM significant", "Last change"]
    srows = [[r.subject, worst(_of(data["quality"], r.subject)["status"]), r.conditions, r.sources,
              str(r.n_versions), _num(r.real_strides, 0), _num(r.sim_strides, 0), str(r.spm_tests),
              str(r.spm_significant), str(r.last_change)[:19]]
             for r in data["summary"].itertuples(index=False)]
    md += ["## Subjects", "", md_table(sh, srows)]
    body += ["<h2>Subjects</h2>", _html_table(sh, srows)]
    for key, (title, build) in TABLES.items():
        header, rows = build(data[key], paper)
        rows = [[s, *r] for s, r in zip(data[key]["subject"], rows, strict=True)]
        header = ["Subject", *header]
        md += [f"## {title}", "", md_table(header, rows)]
        body += [f"<h2>{html.escape(title)}</h2>", _html_table(header, rows) if rows else "<p>No rows.</p>"]
        if key == PAPER_TABLES[-1]:
            md += [paper.note(), ""]
            body += [f"<p>{html.escape(paper.note())}</p>"]
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>gaitloop reports</title>"
            "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
            "font-size:13px}td,th{border:1px solid #bbb;padding:2px 6px}img{max-width:100%;height:auto}"
            "</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")
    md_path, html_path = reports / "summary.md", reports / "index.html"
    with replacing(md_path, html_path) as (tmd, thtml):
        tmd.write_text("\n".join(md) + "\n")
        thtml.write_text(page)
    return md_path, html_path


def _evaluation(subject: str) -> dict | None:
    path = policy_dir(POLICIES_ROOT, subject) / "evaluation.json"
    return json.loads(path.read_text()) if path.is_file() else None


def run_report(subjects: list[str], all_subjects: list[str], db: Path, reports: Path = REPORTS_ROOT,
               summary: bool = True, p: ReportParams = ReportParams(),
               busy_timeout_s: float = 10.0) -> list[Path]:
    """Reports of `subjects`, then (with `summary`) the summary and index over `all_subjects`."""
    data = load_report_data(db, busy_timeout_s)
    paper = load_paper(PAPER_FILE)
    written = [subject_report(s, data, reports, p, paper, _evaluation(s)) for s in subjects]
    if summary:
        written += list(summary_report(all_subjects, data, reports, p, paper))
    return written
