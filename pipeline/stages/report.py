"""Stage `report`: the store's latest results -> Markdown reports, figures and a static index.

Reads only the results store (read-only, one query per table in `QUERIES`) and writes:
- `reports/<subject>/report.md` with Tables I-III (Real and Sim columns), SPM clusters and figures
  in `reports/<subject>/figures/`: kinematics (mean ± SD bands), SPM, and once a robot was
  simulated, tracking and harness force;
- `reports/summary.md` and `reports/index.html`: every subject's tables side by side, linking the
  per-subject reports and figures.
Numbers are printed rounded (cm and deg to 2 decimals, m and m/s to 3); the store keeps them exact.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import pandas as pd

from metrics.plots import group_label, harness_figure, kinematics_figure, spm_figure, tracking_figure
from pipeline.params import ReportParams
from pipeline.paths import REPORTS_ROOT, report_dir
from pipeline.stages.outputs import replacing, write_figure
from pipeline.store import StoreError, open_store

QUERIES = {
    "table1": "SELECT * FROM paper_table1 ORDER BY subject, condition, sim_human_mode",
    "table2": "SELECT * FROM paper_table2 ORDER BY subject, condition, sim_human_mode",
    "table3": "SELECT * FROM paper_table3 ORDER BY subject, condition, side, joint, sim_human_mode",
    "summary": "SELECT * FROM subject_summary ORDER BY subject",
    "kinematics": "SELECT * FROM latest_kinematics "
                  "ORDER BY subject, source, human_mode, condition, joint, pct",
    "spm_tests": "SELECT * FROM latest_spm_tests ORDER BY subject, comparison, joint, condition_b",
    "spm_curves": "SELECT c.* FROM result_spm_curves c JOIN latest_spm_tests t USING (version_id, test_id) "
                  "ORDER BY c.test_id, c.pct",
    "clusters": "SELECT * FROM spm_clusters",
    "tracking": "SELECT * FROM latest_tracking ORDER BY subject, source, human_mode, condition, time_s",
    "harness": "SELECT * FROM latest_harness ORDER BY subject, source, human_mode, condition, quantity",
}
PAPER = "Paper, own subject (published)"
PAPER_NOTE = (
    "The column *Paper, own subject (published)* is for orientation only: it would hold the values "
    "Wang, Chan et al. (ICRA 2025, arXiv:2503.05825) report for their own participant, not for this "
    "subject. Those per-table numbers could not be retrieved in this environment (only the paper's "
    "abstract was reachable), so the column says *not retrieved* rather than showing invented numbers."
)


# Columns the report reads from views that have grown over time: a store file whose views predate
# this code is named as such instead of failing on a missing attribute.
REQUIRED_COLUMNS = {"table1": ("sim_n_samples", "sim_fall_rate"), "table3": ("side",)}


def load_report_data(db: Path, busy_timeout_s: float = 10.0) -> dict[str, pd.DataFrame]:
    """Every table the reports need, one query each, on one read-only connection."""
    with open_store(db, read_only=True, busy_timeout_s=busy_timeout_s) as con:
        data = {name: con.execute(sql).df() for name, sql in QUERIES.items()}
    for name, cols in REQUIRED_COLUMNS.items():
        missing = [c for c in cols if c not in data[name].columns]
        if missing:
            raise StoreError(db, f"its views lack {missing}: they predate this code; rerun "
                             "`python -m pipeline store` (it recreates the views)")
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


def table1_rows(t: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    header = ["Condition", "Sim human", "Real mean abs e_x (cm)", "Real mean abs e_y (cm)",
              "Sim mean abs e_x (cm)", "Sim mean abs e_y (cm)", "Sim runs with a fall", PAPER]
    rows = [[r.condition, _mode(r.sim_human_mode), _mean_sd(r.real_mean_abs_ex_cm, r.real_sd_abs_ex_cm, 2),
             _mean_sd(r.real_mean_abs_ey_cm, r.real_sd_abs_ey_cm, 2),
             _following(r.sim_mean_abs_ex_cm, r.sim_sd_abs_ex_cm, r.sim_n_samples),
             _following(r.sim_mean_abs_ey_cm, r.sim_sd_abs_ey_cm, r.sim_n_samples),
             _falls(r.sim_fall_rate, r.sim_n_trials), "not retrieved"]
            for r in t.itertuples(index=False)]
    return header, rows


def table2_rows(t: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    header = ["Condition", "Sim human", "Real stride length (m)", "Real gait speed (m/s)",
              "Sim stride length (m)", "Sim gait speed (m/s)", PAPER]
    rows = [[r.condition, _mode(r.sim_human_mode),
             _mean_sd(r.real_stride_length_m_mean, r.real_stride_length_m_sd, 3, r.real_n_strides),
             _mean_sd(r.real_gait_speed_mps_mean, r.real_gait_speed_mps_sd, 3),
             _mean_sd(r.sim_stride_length_m_mean, r.sim_stride_length_m_sd, 3, r.sim_n_strides),
             _mean_sd(r.sim_gait_speed_mps_mean, r.sim_gait_speed_mps_sd, 3), "not retrieved"]
            for r in t.itertuples(index=False)]
    return header, rows


def table3_rows(t: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    header = ["Condition", "Side", "Joint", "Sim human", "Real SD (deg)", "Sim SD (deg)", PAPER]
    rows = [[r.condition, r.side, r.joint, _mode(r.sim_human_mode),
             _mean_sd(r.real_intercycle_sd_deg, None, 2, r.real_n_cycles),
             _mean_sd(r.sim_intercycle_sd_deg, None, 2, r.sim_n_cycles), "not retrieved"]
            for r in t.itertuples(index=False)]
    return header, rows


TABLES = {
    "table1": ("Table I: compliance, mean absolute offset of the pelvis from the arm's neutral point "
               "(mean ± SD over samples)", table1_rows),
    "table2": ("Table II: stride length and gait speed (mean ± SD over kept strides, n strides)",
               table2_rows),
    "table3": ("Table III: inter-cycle SD of the sagittal joint angles, averaged over the cycle "
               "(n cycles)", table3_rows),
}


def _of(df: pd.DataFrame, subject: str) -> pd.DataFrame:
    return df[df["subject"] == subject] if "subject" in df.columns else df.iloc[0:0]


def subject_report(subject: str, data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams()) -> Path:
    """Write `reports/<subject>/report.md` and its figures; returns the report path."""
    summary = _of(data["summary"], subject)
    if summary.empty:
        raise StoreError(subject, "no stored results for this subject: run `python -m pipeline store`")
    folder = report_dir(reports, subject)
    figs = folder / "figures"
    lines = [f"# {subject}: HITL gait report", "",
             "Built from the results store (`data/results.duckdb`, latest version of each subject, "
             "condition, source and human mode). Real = recorded mocap; Sim = the human digital twin "
             "walking with the MRBA twin (`replay` or `policy` human).", ""]
    s = summary.iloc[0]
    lines += [f"Conditions: {s['conditions']}. Sources: {s['sources']}. Kept strides real/sim: "
              f"{_num(s['real_strides'], 0)}/{_num(s['sim_strides'], 0)}. "
              f"SPM tests run: {int(s['spm_tests'])}, "
              f"with supra-threshold clusters: {int(s['spm_significant'])}.", ""]
    for key, (title, build) in TABLES.items():
        header, rows = build(_of(data[key], subject))
        lines += [f"## {title}", "", md_table(header, rows)]
        if key == "table1" and not rows:
            lines += ["No robot data for this subject yet (Table I needs simulated robot tables).", ""]
    lines += [PAPER_NOTE, ""]

    bands = _of(data["kinematics"], subject)
    side = "both" if (bands["side"] == "both").any() else "right"
    write_figure(kinematics_figure(bands[bands["side"] == side], f"{subject}: joint kinematics (mean ± SD, "
                            f"side {side})"), figs / "kinematics.png", p.dpi)
    lines += ["## Joint kinematics", "", "![kinematics](figures/kinematics.png)", ""]

    tests = _of(data["spm_tests"], subject)
    curves = data["spm_curves"][data["spm_curves"]["test_id"].isin(tests["test_id"])]
    statistic = "F" if (tests["test"] == "anova1").all() else "t"
    write_figure(spm_figure(tests, curves, f"{subject}: SPM{{{statistic}}} (alpha 0.05)"), figs / "spm.png",
                 p.dpi)
    clusters = _of(data["clusters"], subject)
    lines += ["## SPM1D", "", "Statistic curves, critical thresholds (dashed) and supra-threshold clusters "
              "(shaded); the paper's one-way ANOVA unless params say `ttest2`.", "",
              "![spm](figures/spm.png)", "",
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

    tracking, harness = _of(data["tracking"], subject), _of(data["harness"], subject)
    if not tracking.empty:
        write_figure(tracking_figure(tracking, f"{subject}: tracking (first run per condition)"),
              figs / "tracking.png", p.dpi)
        lines += ["## Tracking", "", "![tracking](figures/tracking.png)", ""]
    if not harness.empty:
        write_figure(harness_figure(harness, f"{subject}: harness interaction"), figs / "harness.png", p.dpi)
        lines += ["## Harness force and torque", "", "![harness](figures/harness.png)", ""]
    if tracking.empty and harness.empty:
        lines += ["## Tracking and harness force", "", "No simulated robot runs for this subject yet.", ""]
    path = folder / "report.md"
    with replacing(path) as (temp,):
        temp.write_text("\n".join(lines))
    return path


def figure_names(subject: str, data: dict[str, pd.DataFrame]) -> list[str]:
    """The figures `subject_report` draws for a subject, known from the stored data alone (so the
    index can be written before, after or without the per-subject reports)."""
    names = ["kinematics", "spm"]
    names += [n for n in ("tracking", "harness") if not _of(data[n], subject).empty]
    return names


def _html_table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>{body}</tbody>\n</table>\n"


def summary_report(subjects: list[str], data: dict[str, pd.DataFrame],
                   reports: Path = REPORTS_ROOT) -> tuple[Path, Path]:
    """Write `reports/summary.md` and `reports/index.html` across subjects."""
    reports = Path(reports)
    summ = data["summary"]
    sh = ["Subject", "Conditions", "Sources", "Versions", "Real strides", "Sim strides", "SPM tests",
          "SPM significant", "Last change"]
    srows = [[r.subject, r.conditions, r.sources, str(r.n_versions), _num(r.real_strides, 0),
              _num(r.sim_strides, 0), str(r.spm_tests), str(r.spm_significant), str(r.last_change)[:19]]
             for r in summ.itertuples(index=False)]
    md = ["# gaitloop: cross-subject summary", "", md_table(sh, srows)]
    body = ["<h1>gaitloop: cross-subject summary</h1>", '<p><a href="summary.md">summary.md</a></p>',
            _html_table(sh, srows)]
    for key, (title, build) in TABLES.items():
        header, rows = build(data[key])
        rows = [[s, *r] for s, r in zip(data[key]["subject"], rows, strict=True)]
        header = ["Subject", *header]
        md += [f"## {title}", "", md_table(header, rows)]
        body += [f"<h2>{html.escape(title)}</h2>", _html_table(header, rows) if rows else "<p>No rows.</p>"]
    md += [PAPER_NOTE, "", "## Subjects", ""]
    body += [f"<p>{html.escape(PAPER_NOTE).replace('*', '')}</p>", "<h2>Subjects</h2>"]
    for s in subjects:
        if data["summary"].empty or s not in set(data["summary"]["subject"]):
            md.append(f"- {s}: no stored results yet")
            body.append(f"<p>{html.escape(s)}: no stored results yet</p>")
            continue
        md.append(f"- [{s}]({s}/report.md)")
        body.append(f'<h3><a href="{s}/report.md">{html.escape(s)}</a></h3>')
        for name in figure_names(s, data):
            img = f'<img src="{s}/figures/{name}.png" alt="{html.escape(s)} {name}" width="720">'
            body.append(f"<figure>{img}<figcaption>{html.escape(name)}</figcaption></figure>")
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>gaitloop reports</title>"
            "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
            "font-size:13px}td,th{border:1px solid #bbb;padding:2px 6px}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
    md_path, html_path = reports / "summary.md", reports / "index.html"
    with replacing(md_path, html_path) as (tmd, thtml):
        tmd.write_text("\n".join(md) + "\n")
        thtml.write_text(page)
    return md_path, html_path


def run_report(subjects: list[str], all_subjects: list[str], db: Path, reports: Path = REPORTS_ROOT,
               summary: bool = True, p: ReportParams = ReportParams(),
               busy_timeout_s: float = 10.0) -> list[Path]:
    """Reports of `subjects`, then (with `summary`) the summary and index over `all_subjects`."""
    data = load_report_data(db, busy_timeout_s)
    written = [subject_report(s, data, reports, p) for s in subjects]
    if summary:
        written += list(summary_report(all_subjects, data, reports))
    return written
