"""What each page shows: a subject's report (`subject_page`) and the summary across subjects that
both reports/summary.md and reports/index.html print (`summary_page`), gathered from the store's
tables (`queries.load_report_data`) and the published values; the templates print them (render.py)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from pipeline.report import sections
from pipeline.report.figures import (
    FIGURES,
    UNIVERSAL_FIGURE,
    evaluation_totals,
    figure_names,
    paper_sensitivity,
)
from pipeline.report.published import ClinicalRange, PaperValues
from pipeline.report.queries import of
from pipeline.report.tables import PAPER_TABLES, TABLES, subjects_table
from pipeline.runs.report_params import ReportParams


def subject_page(subject: str, data: dict[str, pd.DataFrame], figures: set[str], p: ReportParams,
                 paper: PaperValues, evaluation: dict | None, clinical: dict[str, ClinicalRange]) -> dict:
    """Everything `subject`'s report.md shows, linking the figures named in `figures`."""
    s = of(data["summary"], subject).iloc[0]
    q = of(data["quality"], subject)
    sens = paper_sensitivity(of(data.get("sensitivity", pd.DataFrame()), subject), p.paper_scenario)
    round_trip = s["round_trip_of"] if isinstance(s["round_trip_of"], str) and s["round_trip_of"] else None
    return {
        "subject": subject, "round_trip_of": round_trip, "transfer": sections.transfer(q),
        "quality": sections.quality(q),
        "counts": {"conditions": s["conditions"], "sources": s["sources"], "real_strides": s["real_strides"],
                   "sim_strides": s["sim_strides"], "spm_tests": int(s["spm_tests"]),
                   "spm_significant": int(s["spm_significant"])},
        "paper_tables": [(key, TABLES[key].title, TABLES[key].build(of(data[key], subject), paper))
                         for key in PAPER_TABLES],
        "paper_note": paper.note(),
        "findings": sections.findings(of(data["phases"], subject), of(data["table2"], subject),
                                      of(data["table3"], subject), paper, p.paper_scenario, sens),
        "phases": (TABLES["phases"].title, TABLES["phases"].build(of(data["phases"], subject), paper)),
        "policy_checks": sections.policy_checks(evaluation),
        "figure_sections": [(name, heading, name in figures)
                            for name, heading in sections.FIGURE_SECTIONS.items()],
        "spm": sections.spm(of(data["spm_tests"], subject), of(data["clusters"], subject)),
        "robot_figures": "tracking" in figures or "harness" in figures,
        "tuning": sections.tuning(of(data["tuning"], subject), "tuning" in figures),
        "cohort": sections.cohort(of(data["cohort_gait"], subject), of(data["cohort_controllers"], subject),
                                  clinical, "cohort" in figures),
        "fall": sections.fall(of(data["fall"], subject), of(data["not_caught"], subject),
                              of(data["false_alarms"], subject), "fall_intervention" in figures,
                              p.caught_drop_m, p.detection_window_s),
        "sensitivity": sections.sensitivity(sens, paper, p.paper_scenario, "sensitivity" in figures),
    }


def universal_lines(progress: dict, adoption: dict | None = None) -> list[str]:
    """The universal walking policy's run in a few lines: steps, wall time, its machines, the
    adoption rule's evaluations (`adoption`: checks passed over every body, what was adopted) and
    the last gate, per subject's own body (`sim.learn.universal.quick_gate`)."""
    points = progress.get("checkpoints", [])
    machines = sorted({f"{r.get('cpu_count', '?')} cores" + (" + GPU" if r.get("device") == "cuda" else "")
                       for r in progress.get("runs", [])})
    steps_m, hours = progress.get("steps", 0) / 1e6, progress.get("wall_s", 0) / 3600
    start = progress.get("initialised_from", "scratch")
    lines = [f"One run of {steps_m:.2f} M env steps in {hours:.1f} h of training ({', '.join(machines)}), "
             f"from {start}."]
    evaluations = evaluation_totals(adoption, progress)
    if evaluations:
        each = ", ".join(f"{passed} of {of} at {steps_m:.2f} M" + (" (a branch given up)" if gone else "")
                         for steps_m, passed, of, gone in evaluations)
        lines.append(f"evaluate-policy by the adoption rule, every body: {each} checks passed; adopted: "
                     f"{', '.join(adoption.get('adopted') or []) or 'none'}.")
    if points:
        last = points[-1]
        best = max(c["passed"] for c in points)
        at = ", ".join(f"{c['steps'] / 1e6:.2f}" for c in points if c["passed"] == best)
        lines.append(f"Last gate ({last['steps'] / 1e6:.2f} M steps): {last['passed']} of {last['checks']} "
                     f"checks; best {best}, at {at} M steps.")
        for subject, rows in last["gate"].items():
            failed = [k for k, r in rows.items() if not r["pass"]]
            lines.append(f"{subject}: {len(rows) - len(failed)} of {len(rows)}"
                         + (f" (failed: {', '.join(failed)})" if failed else ""))
    return lines


def summary_page(subjects: list[str], data: dict[str, pd.DataFrame], reports: Path, p: ReportParams,
                 paper: PaperValues, progress: dict | None, adoption: dict | None = None) -> dict:
    """Everything summary.md and index.html show across `subjects`: each one's figures (none for a
    subject without stored results) and videos of walk_10m (`make videos`, found in `reports`), the
    subjects' table, `TABLES` with every subject's rows, then the universal walking policy's training
    progress (`progress`, its progress.json, and `adoption`, its adoption.json; figure `UNIVERSAL_FIGURE`)."""
    stored = set(data["summary"]["subject"]) if not data["summary"].empty else set()
    return {
        "subjects": [{"name": s, "stored": s in stored,
                      "figures": figure_names(s, data, p) if s in stored else [],
                      "videos": sorted((reports / s).glob("rollout_walk_10m_*.mp4")) if s in stored else []}
                     for s in subjects],
        "captions": FIGURES,
        "subjects_table": subjects_table(data["summary"], data["quality"]),
        "tables": [(TABLES[key].title, TABLES[key].build(data[key], paper).with_subject(data[key]["subject"]),
                    key == PAPER_TABLES[-1]) for key in TABLES],
        "paper_note": paper.note(),
        "universal": None if progress is None else {"figure": UNIVERSAL_FIGURE,
                                                    "lines": universal_lines(progress, adoption)},
    }
