"""Stage `report`: the store's latest results -> Markdown reports, figures and a static index.

What the pages show is gathered by pipeline/report/ (the store's tables, the paper's published
values, the clinical ranges, each subject's policy evaluation) and printed by its templates; this
stage reads those inputs and writes:
- `reports/<subject>/report.md` with the figures of `subject_figures` in `reports/<subject>/figures/`
  (replaced as a set with the report: a killed run leaves the earlier figures whole, no mix of old
  and new);
- `reports/summary.md` and `reports/index.html` across subjects, and the universal walking policy's
  progress figure beside them (`UNIVERSAL_FIGURE`).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from metrics.plots import training_progress_figure
from pipeline.paths import (
    ADOPTION_FILE,
    PAPER_FILE,
    POLICIES_ROOT,
    REPORTS_ROOT,
    UNIVERSAL_DIR,
    policy_dir,
    report_dir,
)
from pipeline.report.figures import UNIVERSAL_FIGURE, progress_curves, subject_figures
from pipeline.report.pages import subject_page, summary_page
from pipeline.report.published import (
    CLINICAL_FILE,
    ClinicalRange,
    PaperValues,
    load_clinical_ranges,
    load_paper,
)
from pipeline.report.queries import load_report_data, of
from pipeline.report.render import index_html, subject_markdown, summary_markdown
from pipeline.runs.report_params import ReportParams
from pipeline.stages.outputs import read_json, replacing, replacing_folder, write_figure
from pipeline.store.connection import StoreError


def subject_report(subject: str, data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams(), paper: PaperValues | None = None,
                   evaluation: dict | None = None, clinical: dict[str, ClinicalRange] | None = None) -> Path:
    """Write `reports/<subject>/report.md` and its figures; returns the report path. `evaluation`:
    the evaluate-policy result of its policy, if any; `clinical`: the clinical ranges (default: read
    from `CLINICAL_FILE`). The figures folder is replaced as a set, the report right after it
    (`replacing_folder`): a killed run leaves the earlier figures and report whole."""
    paper = paper or load_paper(PAPER_FILE)
    clinical = load_clinical_ranges(CLINICAL_FILE) if clinical is None else clinical
    if of(data["summary"], subject).empty:
        raise StoreError(subject, "no stored results for this subject: run `python -m pipeline store`")
    folder = report_dir(reports, subject)
    figures = subject_figures(subject, data, p)
    path = folder / "report.md"
    with replacing_folder(folder / "figures", path) as (figure_dir, (temp,)):
        for name, draw in figures.items():
            write_figure(draw(), figure_dir / f"{name}.png", p.dpi)
        temp.write_text(subject_markdown(subject_page(subject, data, set(figures), p, paper, evaluation,
                                                      clinical)))
    return path


def summary_report(subjects: list[str], data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams(), paper: PaperValues | None = None,
                   progress: dict | None = None, adoption: dict | None = None) -> tuple[Path, Path]:
    """Write `reports/summary.md` and `reports/index.html` across subjects (`summary_page`), and the
    universal walking policy's progress figure from `progress` (its progress.json) and `adoption`
    (its adoption.json) when given."""
    paper = paper or load_paper(PAPER_FILE)
    reports = Path(reports)
    page = summary_page(subjects, data, reports, p, paper, progress, adoption)
    if progress is not None:
        curves = progress_curves(progress, adoption)
        write_figure(training_progress_figure(curves), reports / UNIVERSAL_FIGURE, p.dpi)
    md_path, html_path = reports / "summary.md", reports / "index.html"
    with replacing(md_path, html_path) as (tmd, thtml):
        tmd.write_text(summary_markdown(page))
        thtml.write_text(index_html(page))
    return md_path, html_path


def _evaluation(subject: str) -> dict | None:
    return read_json(policy_dir(POLICIES_ROOT, subject) / "evaluation.json")


def run_report(subjects: list[str], all_subjects: list[str], db: Path, reports: Path = REPORTS_ROOT,
               summary: bool = True, p: ReportParams = ReportParams(),
               busy_timeout_s: float = 10.0) -> list[Path]:
    """Reports of `subjects`, then (with `summary`) the summary and index over `all_subjects`."""
    data = load_report_data(db, busy_timeout_s)
    paper = load_paper(PAPER_FILE)
    clinical = load_clinical_ranges(CLINICAL_FILE) if subjects else {}
    written = [subject_report(s, data, reports, p, paper, _evaluation(s), clinical) for s in subjects]
    if summary:
        progress = read_json(UNIVERSAL_DIR / "progress.json")
        adoption = read_json(UNIVERSAL_DIR / ADOPTION_FILE)
        written += list(summary_report(all_subjects, data, reports, p, paper, progress, adoption))
    return written
