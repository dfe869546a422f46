"""Stage `report`: the store's latest results -> Markdown reports, figures and a static index.

Reads the results store (read-only, one query per table in `QUERIES`), the reference paper's
published values (`data/paper/wang2025.yaml`, `load_paper`), the published clinical ranges
(`data/paper/clinical_ranges.yaml`, `load_clinical_ranges`) and each subject's policy evaluation
(`data/policies/<subject>/evaluation.json`, when present), and writes:
- `reports/<subject>/report.md`, opening with its quality gates (`quality_latest`, failed and warned
  first; one line before them says whether a transferred policy passed its gate), then Tables I-III
  (Real, Sim and the paper's published columns), the per-phase compliance table, the policy checks,
  SPM clusters, controller tuning, the virtual cohort (each variant's gait beside the clinical
  ranges, and with each controller) and the fall intervention (scripted balance losses and false
  alarms), with the figures of `subject_figures` in `reports/<subject>/figures/` (replaced as a set
  with the report: a killed run leaves the earlier figures whole, no mix of old and new);
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
from typing import Annotated, Literal, TypeVar

import duckdb
import pandas as pd
import yaml
from matplotlib.figure import Figure
from pydantic import BaseModel, ConfigDict, Field, RootModel, ValidationError, model_validator

from ingest.errors import GaitloopError
from metrics.findings import (
    Pair,
    compliance_findings,
    level_text,
    region_text,
    responsiveness_comparisons,
    speed_findings,
    variability_findings,
)
from metrics.plots import (
    EVENT_ORDER,
    VARIANT_ORDER,
    cohort_heatmap,
    event_figure,
    fall_intervention_figure,
    group_label,
    harness_figure,
    kinematics_figure,
    ordered,
    sensitivity_figure,
    spm_figure,
    tracking_figure,
    training_progress_figure,
    tuning_figure,
)
from metrics.quality import NOT_COMPUTED, worst, worst_check
from pipeline.params import ReportParams
from pipeline.paths import PAPER_FILE, POLICIES_ROOT, REPORTS_ROOT, UNIVERSAL_DIR, policy_dir, report_dir
from pipeline.stages.outputs import read_json, replacing, replacing_folder, write_figure
from pipeline.store import StoreError, open_store
from sim.rollout.scenarios import PHASES

# -- the reference paper's published values (data/paper/wang2025.yaml) --------------------------------
# Wang, Chan et al., ICRA 2025 (arXiv:2503.05825), Tables I-III, for their own participant: printed
# beside each subject's Real and Sim columns for orientation (the file cites its source). Keys mirror
# the tables: condition -> `real` (their recorded trials) or `sim` (their simulation) -> values.

Source = Literal["real", "sim"]


# The paper's two controllers (Wang, Chan et al. ICRA 2025): its finding is its speed-adaptive controller
# below its PID baseline. The report names them here, once; metrics/ takes them as data.
PAPER_PAIR = Pair("adaptive", "pid")
CONTROLLER_ORDER = (PAPER_PAIR.b, PAPER_PAIR.a)  # tables and figures: the baseline first; others after
UNIVERSAL_FIGURE = "universal_progress.png"  # in reports/: the universal policy's gate against steps


class PaperError(GaitloopError):
    """A file of published values (the paper's, the clinical ranges) is missing, not YAML, or not in
    the expected layout."""

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


M = TypeVar("M", bound=BaseModel)


def _published(path: Path, model: type[M], what: str) -> M:
    """Read a YAML file of published values and check it against `model`; `PaperError` names the
    file and the problem."""
    try:
        return model.model_validate(yaml.safe_load(Path(path).read_text()))
    except OSError as exc:
        raise PaperError(path, f"cannot read the {what} ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise PaperError(path, f"not YAML ({exc})") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(k) for k in first["loc"])
        raise PaperError(path, f"{where}: {first['msg']}") from None


def load_paper(path: Path = PAPER_FILE) -> PaperValues:
    """Read and check the paper values file; `PaperError` names the file and the problem."""
    return _published(path, PaperValues, "paper values")


# -- published clinical reference values (data/paper/clinical_ranges.yaml) ---------------------------
# Printed beside the virtual cohort's gait so a reader can place each variant: the stroke walking
# categories, healthy adults' comfortable speed, the symmetry ratios counted as asymmetric and the
# stride-time variability of healthy young adults, each with its citation.

CLINICAL_FILE = PAPER_FILE.parent / "clinical_ranges.yaml"
# measure key (unit in the name) -> how the report names it
CLINICAL_MEASURES = {"speed_mps": "gait speed (m/s)",
                     "stance_ratio": "stance time ratio, larger / smaller side",
                     "swing_ratio": "swing time ratio, larger / smaller side",
                     "step_length_ratio": "step length ratio, larger / smaller side",
                     "stride_time_cv_pct": "stride time CV (%)"}
Bound = float | None


class ClinicalRange(_Strict):
    """One published reference: exactly one measure, as [low, high] (None: an open end) or a single
    published value, what it describes (`meaning`) and where it was published (`source`)."""

    speed_mps: tuple[Bound, Bound] | float | None = None
    stance_ratio: tuple[Bound, Bound] | float | None = None
    swing_ratio: tuple[Bound, Bound] | float | None = None
    step_length_ratio: tuple[Bound, Bound] | float | None = None
    stride_time_cv_pct: tuple[Bound, Bound] | float | None = None
    meaning: Annotated[str, Field(min_length=1)]
    source: Annotated[str, Field(min_length=1)]

    @model_validator(mode="after")
    def _one_measure(self) -> ClinicalRange:
        given = [m for m in CLINICAL_MEASURES if getattr(self, m) is not None]
        if len(given) != 1:
            raise ValueError(f"needs exactly one measure of {list(CLINICAL_MEASURES)}, got {given}")
        value = getattr(self, given[0])
        low, high = value if isinstance(value, tuple) else (value, value)
        if (low is None and high is None) or (None not in (low, high) and low > high):
            raise ValueError(f"{given[0]}: [low, high] needs low <= high and one end at least, "
                             f"got {list(value)}")
        return self

    @property
    def measure(self) -> str:
        return next(m for m in CLINICAL_MEASURES if getattr(self, m) is not None)

    def value_text(self) -> str:
        """The value as printed: "0.4–0.8", "< 0.4", "> 0.8" or the single value."""
        value = getattr(self, self.measure)
        if not isinstance(value, tuple):
            return f"{value:g}"
        low, high = value
        return f"< {high:g}" if low is None else f"> {low:g}" if high is None else f"{low:g}–{high:g}"


class ClinicalRanges(RootModel[dict[str, ClinicalRange]]):
    """The whole file: entry name -> `ClinicalRange`."""


def load_clinical_ranges(path: Path = CLINICAL_FILE) -> dict[str, ClinicalRange]:
    """Read and check the clinical ranges file; `PaperError` names the file and the problem."""
    return _published(path, ClinicalRanges, "clinical ranges").root


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
    "fall": "SELECT * FROM fall_intervention ORDER BY subject, variant, event, condition",
    "not_caught": "SELECT * FROM falls_not_caught "
                  "ORDER BY subject, variant, event, condition, scenario, seed",
    "false_alarms": "SELECT * FROM false_alarms ORDER BY subject, variant, condition",
    "cohort_gait": "SELECT * FROM cohort_gait ORDER BY subject, variant, scenario",
    "cohort_controllers": "SELECT * FROM cohort_controllers ORDER BY subject, variant, scenario, condition",
    "sensitivity": "SELECT * FROM sensitivity ORDER BY subject, variant, scenario, factor, level, condition",
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
    "cohort": "Virtual cohort with each controller, walking without events: mean |e_x|, |e_y|, harness force "
              "RMS and gait speed change versus the same variant walking free, per variant (rows) and "
              "controller (columns), each panel on its own colour scale",
    "fall_intervention": "Scripted balance losses per event type and controller: share detected (circles: "
                         "share caught of the events that fell walking free), onset-to-lock latency, "
                         "pelvis drop at the lock (triangles: worst; dashed: caught threshold) and peak "
                         "harness force",
    "sensitivity": "The twin's follow-me responsiveness (one factor at a time, the others at the twin's "
                   "values, dotted): mean |e_x| and |e_y| per controller (policy human in the paper's walk, "
                   "mean and 95 % CI across walks; falls/walks where any fell), the paper's simulated values "
                   "dashed (their robot and participant)",
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


def _walks(walks, distinct) -> str:
    """`walks`, and how many are distinct when fewer are."""
    text = _num(walks, 0)
    if text == "–" or _num(distinct, 0) == "–" or int(distinct) >= int(walks):
        return text
    return f"{text} ({int(distinct)} distinct)"


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
STATUS_COLOURS = {"ok": "#c8e6c9", "warn": "#ffe08a", "fail": "#f4a6a6", NOT_COMPUTED: "#eeeeee",
                  "unknown": "#e0e0e0"}


def quality_rows(q: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """The quality gates of one subject, failed first, then warned, not computed (`n/a`), ok."""
    header = ["Check", "Value", "Warn above", "Fail above", "Status", "Cause", "Note"]
    if q.empty:
        return header, []
    q = q.assign(_order=q["status"].map({"fail": 0, "warn": 1, NOT_COMPUTED: 2, "ok": 3}).fillna(4))
    q = q.sort_values(["_order", "stage", "check"], kind="stable")
    rows = [[f"{r.stage}/{r.check}", _num(r.value, 4), _num(r.warn_above, 4), _num(r.fail_above, 4), r.status,
             getattr(r, "cause", None) or "", r.note or ""] for r in q.itertuples(index=False)]
    return header, rows


def worst_check_text(q: pd.DataFrame) -> str:
    """'stage/check: cause' of a subject's worst graded check (`metrics.quality.worst_check`); '' when
    none is graded."""
    row = worst_check(q) if not q.empty else None
    if row is None:
        return ""
    return f"{row['stage']}/{row['check']}: {row.get('cause') or row['note'] or ''}".rstrip(": ")


def transfer_lines(q: pd.DataFrame) -> list[str]:
    """What the report says first about a transferred policy (the `policy` quality rows of its gate,
    `metrics.quality.transfer_checks`): whether its policy human passed, and if not which required
    checks failed and that it has replay rows only. Nothing for a committed policy."""
    gate = q[q["stage"] == "policy"] if not q.empty else q
    if gate.empty:
        return []
    origin = str(gate["note"].iloc[0]).split("; ")[0]  # "fine-tuned from S (distance d, n steps)"
    failed = gate[gate["status"] == "fail"]["check"].tolist()
    if failed:
        return [f"**Policy human: transfer gate FAILED.** The policy {origin} failed {len(failed)} required "
                f"check(s): {', '.join(failed)}. This subject has replay rows only; the `policy` rows of the "
                "quality gates below list every check.", ""]
    return [f"**Policy human:** {origin}; its transfer gate passed (the `policy` rows of the quality gates "
            "below).", ""]


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
    cohort, fall = _of(data["cohort_controllers"], subject), _of(data["fall"], subject)
    sens = paper_sensitivity(_of(data.get("sensitivity", pd.DataFrame()), subject), p.paper_scenario)
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
        "cohort": lambda: cohort_heatmap(cohort, f"{subject}: virtual cohort with each controller",
                                         CONTROLLER_ORDER),
        "fall_intervention": lambda: fall_intervention_figure(
            fall, f"{subject}: scripted balance losses per controller", p.caught_drop_m, CONTROLLER_ORDER),
        "sensitivity": lambda: sensitivity_figure(
            sens, paper_compliance(load_paper(PAPER_FILE)),
            f"{subject}: follow-me responsiveness, {p.paper_scenario} (mean, 95 % CI across walks)",
            CONTROLLER_ORDER),
    }
    present = {"events": not events.empty, "kinematics_policy": not policy.empty,
               "tracking": not tracking.empty, "harness": not harness.empty, "tuning": not tuning.empty,
               "cohort": not cohort.empty, "fall_intervention": (fall["condition"] != "free").any(),
               "sensitivity": not sens.empty}
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
                 str(v.get("start_from_onset_s", "–")), str(v.get("stop_s", "–")),
                 str(v.get("steady_speed_mps", "–"))]
                for key, v in sc.items() if isinstance(v, dict) and "walks" in v]
        lines += [md_table(["scenario condition", "walks", "human falls", "start (s)",
                            "start from onset (s, as recorded starts are timed)", "stop (s)",
                            "steady speed (m/s)"], rows)]
    return lines


def subject_report(subject: str, data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams(), paper: PaperValues | None = None,
                   evaluation: dict | None = None, clinical: dict[str, ClinicalRange] | None = None) -> Path:
    """Write `reports/<subject>/report.md` and its figures; returns the report path. `evaluation`:
    the evaluate-policy result of its policy, if any; `clinical`: the clinical ranges (default: read
    from `CLINICAL_FILE`). The figures folder is replaced as a set, the report right after it
    (`replacing_folder`): a killed run leaves the earlier figures and report whole."""
    paper = paper or load_paper(PAPER_FILE)
    clinical = load_clinical_ranges(CLINICAL_FILE) if clinical is None else clinical
    summary = _of(data["summary"], subject)
    if summary.empty:
        raise StoreError(subject, "no stored results for this subject: run `python -m pipeline store`")
    folder = report_dir(reports, subject)
    figures = subject_figures(subject, data, p)
    path = folder / "report.md"
    with replacing_folder(folder / "figures", path) as (figure_dir, (temp,)):
        for name, draw in figures.items():
            write_figure(draw(), figure_dir / f"{name}.png", p.dpi)
        temp.write_text("\n".join(report_lines(subject, data, set(figures), p, paper, evaluation, clinical)))
    return path


def report_lines(subject: str, data: dict[str, pd.DataFrame], figures: set[str], p: ReportParams,
                 paper: PaperValues, evaluation: dict | None, clinical: dict[str, ClinicalRange]
                 ) -> list[str]:
    """The lines of `subject`'s report.md, linking the figures named in `figures`."""
    s = _of(data["summary"], subject).iloc[0]
    lines = [f"# {subject}: HITL gait report", ""]
    if isinstance(s["round_trip_of"], str) and s["round_trip_of"]:
        lines += [f"**Round trip:** this subject's \"recorded\" trials are {s['round_trip_of']}'s simulated "
                  "trials, exported as OpenSim files and robot logs (`python -m pipeline export`) and read "
                  "back; its Real columns test the pipeline, not a person.", ""]
    lines += transfer_lines(_of(data["quality"], subject))
    header, rows = quality_rows(_of(data["quality"], subject))
    gates = [md_table(header, rows)] if rows else [NO_GATES, ""]
    lines += ["## Quality gates", "", *gates,
              f"Worst status: **{worst(r[4] for r in rows)}**"
              + (f" ({worst_check_text(_of(data['quality'], subject))})." if rows else "."), "",
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

    sens = paper_sensitivity(_of(data.get("sensitivity", pd.DataFrame()), subject), p.paper_scenario)
    lines += findings_lines(_of(data["phases"], subject), _of(data["table2"], subject),
                            _of(data["table3"], subject), paper, p.paper_scenario, sens)
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
    lines += cohort_lines(_of(data["cohort_gait"], subject), _of(data["cohort_controllers"], subject),
                          clinical, "cohort" in figures)
    lines += fall_lines(_of(data["fall"], subject), _of(data["not_caught"], subject),
                        _of(data["false_alarms"], subject), "fall_intervention" in figures, p.caught_drop_m,
                        p.detection_window_s)
    return lines + sensitivity_lines(sens, paper, p.paper_scenario, "sensitivity" in figures)


FINDING_PHASES = ("start", "steady", "stop")  # the walk_10m phases the compliance findings are read in


def paper_compliance(paper: PaperValues) -> dict[str, tuple[float, float]]:
    """condition -> the paper's simulated (mean |e_x|, mean |e_y|) in cm (Table I)."""
    return {c: (v["sim"].mean_abs_ex_cm, v["sim"].mean_abs_ey_cm)
            for c, v in paper.table1.items() if "sim" in v}


def paper_sensitivity(sens: pd.DataFrame, scenario: str) -> pd.DataFrame:
    """The responsiveness study's rows (`sensitivity` view, one subject) of the subject's own policy
    human in the paper's scenario."""
    if sens.empty:
        return sens
    return sens[(sens["variant"] == "healthy") & (sens["scenario"] == scenario)]


def findings_lines(phases: pd.DataFrame, table2: pd.DataFrame, table3: pd.DataFrame, paper: PaperValues,
                   scenario: str, sens: pd.DataFrame | None = None) -> list[str]:
    """The paper's findings beside this subject's simulation (metrics/findings.py): the policy human
    where it has rows, else the replay human; each with the paper's simulated numbers and, for the
    tracking findings, where on the twin's responsiveness it holds (`sens`: `paper_sensitivity` rows;
    the study runs the policy human)."""
    modes = set(phases["human_mode"]) | set(table2["sim_human_mode"].dropna())
    mode = "policy" if "policy" in modes else "replay"
    paper_ex = paper_compliance(paper)
    paper_speed = {c: v["sim"].gait_speed_mps[0] for c, v in paper.table2.items() if "sim" in v}
    paper_sd = {c: v["sim"] for c, v in paper.table3.items() if "sim" in v}
    sens = pd.DataFrame() if sens is None else sens
    axes = (("e_x", "mean_abs_ex_cm"), ("e_y", "mean_abs_ey_cm"))
    regions = {axis: region_text(responsiveness_comparisons(sens, col, PAPER_PAIR), PAPER_PAIR)
               for axis, col in axes if len(sens)}
    found = [*compliance_findings(phases[phases["human_mode"] == mode], scenario, FINDING_PHASES, paper_ex,
                                  regions, pair=PAPER_PAIR),
             *speed_findings(table2[table2["sim_human_mode"] == mode], paper_speed,
                             controllers=CONTROLLER_ORDER),
             *variability_findings(table3[table3["sim_human_mode"] == mode], paper_sd, pair=PAPER_PAIR)]
    rows = [[f.claim, f.paper, f.measured, f.verdict, f.region] for f in found]
    return [f"## The paper's findings beside this simulation ({mode} human)", "",
            "Each finding of the paper (its own participant, simulated) against this subject's simulation: "
            f"compliance per phase of {scenario} (mean ± 95 % CI over walks), gait speed over kept strides "
            "(± 1.96 SD / sqrt(n), strides taken as independent), inter-cycle SD on the means alone. "
            "Reported as measured; nothing was tuned toward them. *Responsiveness region*: the twin's own "
            "point and where adaptive is below pid (95 % CIs apart, whole walks) when the twin's base drive "
            "lag, command latency or PID gains are moved one at a time (section Follow-me responsiveness).",
            "", md_table(["Finding (paper)", "Paper sim", "This simulation (a vs b)", "Verdict",
                          "Responsiveness region"], rows)]


def _versus(c) -> str:
    """`pid ± ci vs adaptive ± ci` of a `responsiveness_comparisons` row."""
    return f"{_mean_sd(c.pid_mean, c.pid_ci95, 2)} vs {_mean_sd(c.adaptive_mean, c.adaptive_ci95, 2)}"


def sensitivity_lines(sens: pd.DataFrame, paper: PaperValues, scenario: str, figure: bool) -> list[str]:
    """The "Follow-me responsiveness" section: per factor and level, pid and adaptive mean |e_x| and
    |e_y| (± 95 % CI across walks), which is lower, and the walks that fell (`sensitivity` view)."""
    lines = ["## Follow-me responsiveness", ""]
    if sens.empty:
        return lines + ["No responsiveness study for this subject yet (`python -m pipeline sweep --study "
                        "responsiveness`, then `store`).", ""]
    ex, ey = (responsiveness_comparisons(sens, c, PAPER_PAIR) for c in ("mean_abs_ex_cm", "mean_abs_ey_cm"))
    rows = []
    for a, b in zip(ex.itertuples(index=False), ey.itertuples(index=False), strict=True):
        rows.append([f"{a.factor}{' (twin)' if a.twin else ''}", level_text(a.factor, a.level),
                     _versus(a), a.result, _versus(b), b.result,
                     f"{a.falls_pid}/{a.n} vs {a.falls_adaptive}/{a.n}"])
    paper_ex = paper_compliance(paper)
    cited = ", ".join(f"{c} {v[0]:.2f} / {v[1]:.2f}" for c, v in paper_ex.items())
    lines += [f"The policy human in {scenario} with the robot twin's responsiveness moved one factor at a "
              "time (the others at the twin's values; params `sensitivity`, sim/robot/responsiveness.py): "
              "base drive time constant (drive gain = base mass / tau), command latency, PID gains x a scale "
              "(adaptive does not read them: its rows there are the twin's). Mean ± 95 % CI (Student t) "
              "across walks of each walk's mean |e_x|, |e_y| in cm over the samples before an arm lock; "
              "*adaptive vs pid*: `lower` when adaptive is below pid with the CIs apart. Falls: a human fall "
              f"or an arm lock. The paper's simulated e_x / e_y (cm): {cited} (their robot and "
              "participant).", "",
              md_table(["Factor", "Level", "e_x pid vs adaptive (cm)", "adaptive vs pid",
                        "e_y pid vs adaptive (cm)", "adaptive vs pid", "Falls pid vs adaptive"], rows),
              f"e_x: {region_text(ex, PAPER_PAIR)}.", "", f"e_y: {region_text(ey, PAPER_PAIR)}.", ""]
    return lines + (_image("sensitivity") if figure else [])


def _gains(doc) -> str:
    gains = json.loads(doc) if isinstance(doc, str) else dict(doc)
    return ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in gains.items())


def _cost(mean, ci, falls, n) -> str:
    return f"{_mean_sd(mean, ci, 4)} ({_num(falls, 0)}/{_num(n, 0)} falls)"


def _search_falls(status: str, falls, rollouts) -> str:
    if status == "unknown":
        return "–"
    text = f"{int(falls)}/{int(rollouts)}"
    return f"{text} **no signal**" if status == "no signal" else text


def tuning_lines(tuning: pd.DataFrame, figure: bool) -> list[str]:
    """The "Controller tuning" section: per controller and variant the held-back objective with the
    generic and the tuned gains (mean ± 95 % CI across rollouts, falls) and the tuned gains."""
    lines = ["## Controller tuning", ""]
    if tuning.empty:
        return lines + ["No tuned gains for this subject yet (run `python -m pipeline tune <subject> "
                        "--controller <name>`, then `store`).", ""]
    rows = [[r.controller, r.variant, f"{r.method}, {int(r.n_trials)} trials",
             _search_falls(r.search_status, r.search_falls, r.search_rollouts),
             _cost(r.generic_mean, r.generic_ci95, r.generic_falls, r.n_heldout),
             _cost(r.tuned_mean, r.tuned_ci95, r.tuned_falls, r.n_heldout), _gains(r.tuned_gains)]
            for r in tuning.sort_values(["controller", "variant"]).itertuples(index=False)]
    lines += ["Objective (metrics/outcomes.py, lower is better): |e_x| + |e_y| (m) + harness force RMS and "
              "gait-speed change versus walking free, weighted, + a penalty per fall, over the walk itself "
              "(a fall or arm lock in a scenario's final standing is not scored); on held-back walks "
              "the search never saw (mean ± 95 % CI across rollouts). Each variant's tuned gain values "
              "stand beside the healthy twin's. **no signal**: every search rollout "
              "fell, so every trial scored the same and the tuned gains are the first trial's, the generic "
              "ones; that row compares nothing.", "",
              md_table(["Controller", "Variant", "Search", "Search rollouts fallen", "Generic gains",
                        "Tuned gains", "Tuned gain values"], rows)]
    return lines + (_image("tuning") if figure else [])


# -- virtual cohort and fall intervention (issue 13; views cohort_gait, cohort_controllers,
#    fall_intervention, false_alarms of pipeline/store.py) ---------------------------------------------

NO_COHORT = ("No cohort walks stored for this subject yet (run the sweep studies, `python -m pipeline sweep` "
             "and `python -m pipeline sweep --study fall_intervention`, then `store`).")
NO_FALLS = ("No fall-intervention rollouts stored for this subject yet (run `python -m pipeline sweep "
            "--study fall_intervention`, then `store`).")
ORDERS = {"variant": VARIANT_ORDER, "event": EVENT_ORDER, "condition": CONTROLLER_ORDER}


def _in_order(df: pd.DataFrame, *columns: str) -> pd.DataFrame:
    """`df` sorted by `columns`, variants, events and controllers in their usual order (`ORDERS`),
    other columns and unknown values alphabetically after them."""
    if df.empty:
        return df

    def rank(col: pd.Series) -> pd.Series:
        if col.name not in ORDERS:
            return col
        return col.map({v: i for i, v in enumerate(ordered(col, ORDERS[col.name]))})

    return df.sort_values(list(columns), key=rank, kind="stable")


def _count(rate, n) -> str:
    """A share written as the count it is of `n` ("3/4"); "–" without a rate or with n = 0."""
    if _num(rate, 4) == "–" or _num(n, 0) in ("–", "0"):
        return "–"
    return f"{round(float(rate) * int(n))}/{int(n)}"


def _falls_of(falls, walks) -> str:
    return "–" if _num(falls, 0) == "–" else f"{int(falls)}/{int(walks)}"


def _missing_variants(*tables: pd.DataFrame) -> str:
    """The sentence naming the cohort variants that have no rows in any of `tables`."""
    present = set().union(*(set(t["variant"]) for t in tables))
    missing = [v for v in VARIANT_ORDER if v not in present]
    text = ("A variant without a fine-tuned policy (`python -m pipeline train <subject> --variant V`), or "
            "not swept yet, has no walks and is missing from these tables")
    return text + (f": here {', '.join(missing)}." if missing else "; none is missing here.")


def _no_strides_note(gait: pd.DataFrame) -> str:
    """The sentence naming the variants and scenarios `cohort_gait` marks `no_strides` (no walk fell
    and the ingest code kept not one stride, so their rows here and with the robot describe no
    measured gait); empty when every variant's strides were measured or it fell."""
    idle = gait[gait["status"] == "no_strides"]
    if idle.empty:
        return ""
    names = ", ".join(f"{r.variant} in {r.scenario}" for r in _in_order(idle, "variant", "scenario")
                      .itertuples(index=False))
    return (f"**No stride measured:** {names}: walks without a fall in which the ingest code kept not "
            f"one stride (the policy stands, shuffles, or steps in a way its events do not make strides "
            f"of); their rows describe no measured gait.")


def clinical_rows(ranges: dict[str, ClinicalRange]) -> tuple[list[str], list[list[str]]]:
    """The published reference values, one row each: measure, value, what it means, source."""
    header = ["Measure", "Published value", "Meaning", "Source"]
    rows = [[CLINICAL_MEASURES[r.measure], r.value_text(), r.meaning, r.source] for r in ranges.values()]
    return header, rows


def cohort_lines(gait: pd.DataFrame, controllers: pd.DataFrame, ranges: dict[str, ClinicalRange],
                 figure: bool) -> list[str]:
    """The "Virtual cohort" section: each variant's gait walking free (`cohort_gait`) beside the
    published clinical ranges, then each variant with each controller (`cohort_controllers`)."""
    lines = ["## Virtual cohort", ""]
    if gait.empty and controllers.empty:
        return lines + [NO_COHORT, ""]
    lines += ["Variants of this subject's policy human (sim/body/variant.py, params `cohort`): healthy is "
              "the subject's own twin; weak has lower torque limits everywhere, hemiparetic_left / _right "
              "on one leg's hip, knee and ankle, slow a lower preferred speed, unsteady noise on its "
              "actions. Each walks with its own policy, fine-tuned for that body. "
              + _missing_variants(gait, controllers), "",
              "### Gait signature, walking free", "",
              "Walking without robot and without scripted events, per scenario. Walks: how many, and how "
              "many of them differ when some seeds repeat one walk (a walk from standing without motor "
              "noise is the same in every seed). Falls: walks in which the human fell, of all walks. Gait "
              "speed: mean ± SD across walks (no SD from fewer than two distinct walks). Stride length: "
              "mean over walks. "
              "Stance (swing) ratio L/R: the left leg's mean stance (swing) time divided by the right's; "
              "1 is symmetric, above 1 the left leg's phase lasts longer. Stride time CV: the SD of the kept "
              "strides' durations over their mean in one walk (%), averaged over walks; higher is less "
              "steady. Strides: kept strides over all walks.", ""]
    header = ["Variant", "Scenario", "Walks", "Falls", "Gait speed (m/s)", "Stride length (m)",
              "Stance ratio L/R", "Swing ratio L/R", "Stride time CV (%)", "Strides"]
    rows = [[r.variant, r.scenario, _walks(r.walks, r.distinct_walks), _falls_of(r.falls, r.walks),
             _mean_sd(r.gait_speed_mps, r.gait_speed_sd, 3), _num(r.stride_length_m, 3),
             _num(r.stance_ratio_lr, 3), _num(r.swing_ratio_lr, 3), _num(r.stride_time_cv_pct, 2),
             _num(r.strides, 0)]
            for r in _in_order(gait, "variant", "scenario").itertuples(index=False)]
    lines += [md_table(header, rows)]
    if idle := _no_strides_note(gait):
        lines += [idle, ""]
    if ranges:
        lines += ["Published clinical reference values to compare with (data/paper/clinical_ranges.yaml). "
                  "They describe real people; the variants are simulated bodies, so this places them, it "
                  "does not score them. The symmetry ratios there are the larger side over the smaller: for "
                  "a ratio L/R below 1 compare its inverse.", "", md_table(*clinical_rows(ranges))]
    lines += ["### With each controller", "",
              "Walking without scripted events with the robot. Mean abs e_x, e_y: mean absolute forward and "
              "lateral offset of the pelvis from the arm's neutral point (cm); harness force RMS (N); the "
              "changes are versus the same variant walking free in the same scenario: gait speed and stride "
              "length in %, stride time CV in percentage points (negative: steadier). Means over walks.", ""]
    header = ["Variant", "Scenario", "Controller", "Walks", "Falls", "Mean abs e_x (cm)", "Mean abs e_y (cm)",
              "Harness force RMS (N)", "Gait speed change (%)", "Stride length change (%)",
              "Stride time CV change (points)"]
    rows = [[r.variant, r.scenario, r.condition, _num(r.walks, 0), _falls_of(r.falls, r.walks),
             _num(r.mean_abs_ex_cm, 2), _num(r.mean_abs_ey_cm, 2), _num(r.force_rms_n, 2),
             _num(r.speed_change_pct, 2), _num(r.stride_change_pct, 2), _num(r.cv_change_pct, 2)]
            for r in _in_order(controllers, "variant", "scenario", "condition").itertuples(index=False)]
    lines += [md_table(header, rows)]
    return lines + (_image("cohort") if figure else [])


def fall_rows(fall: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """One row per variant, event and controller (conditions with a robot) of `fall_intervention`;
    "Falls free" is "–" where the same variant and event have no walks without the robot."""
    header = ["Variant", "Event", "Controller", "Events", "Excluded (fell before onset)", "Falls free",
              "Human falls", "Detected", "Latency (s)", "Drop at lock (m), mean (worst)",
              "Caught, of falls free", "Peak harness force (N), max (mean)"]
    free = {(r.variant, r.event) for r in fall[fall["condition"] == "free"].itertuples(index=False)}
    robot = _in_order(fall[fall["condition"] != "free"], "variant", "event", "condition")
    rows = []
    for r in robot.itertuples(index=False):
        has_free = (r.variant, r.event) in free
        drop = "–" if _num(r.pelvis_drop_at_lock_m, 3) == "–" else \
            f"{_num(r.pelvis_drop_at_lock_m, 3)} ({_num(r.worst_drop_at_lock_m, 3)})"
        force = "–" if _num(r.peak_harness_force_n, 0) == "–" else \
            f"{_num(r.peak_harness_force_n, 0)} ({_num(r.max_harness_force_n, 0)})"
        rows.append([r.variant, r.event, r.condition, _num(r.events, 0), _num(r.fell_before_onset, 0),
                     f"{int(r.events_falling_free)}/{int(r.events)}" if has_free else "–",
                     f"{int(r.human_falls)}/{int(r.events)}", _count(r.detection_rate, r.events),
                     _num(r.latency_s, 2), drop,
                     _count(r.caught_rate_falling, r.events_falling_free) if has_free else "–", force])
    return header, rows


def _not_caught_reason(r, caught_drop_m: float, window_s: float) -> str:
    """Why one event of `falls_not_caught` was not caught, in words, with its times and drop."""
    if r.reason == "fell_before_onset":
        return f"no event: the human fell at {r.human_fall_s:.2f} s, before the onset at {r.onset_s:.2f} s"
    if r.reason == "locked_before_onset":
        return f"no event: the arm locked at {r.robot_fall_s:.2f} s, before the onset at {r.onset_s:.2f} s"
    if r.reason == "unstable":
        return "the simulation went unstable"
    if r.reason == "dropped":
        return (f"detected, but the pelvis had dropped {r.pelvis_drop_at_lock_m:.3f} m at the lock "
                f"(> {caught_drop_m:.2f} m)")
    if pd.notna(r.robot_fall_s):
        return f"not detected: the arm locked {r.latency_s:.2f} s after the onset (window {window_s:.2f} s)"
    fell = "did not fall" if pd.isna(r.human_fall_s) else \
        f"fell {r.human_fall_s - r.onset_s:.2f} s after the onset"
    return f"not detected: the arm never locked; the human {fell}"


def not_caught_rows(missed: pd.DataFrame, caught_drop_m: float,
                    window_s: float) -> tuple[list[str], list[list[str]]]:
    """One row per event of `falls_not_caught` (fell walking free, not caught with this controller)."""
    header = ["Variant", "Event", "Controller", "Scenario", "Seed", "Why not caught"]
    rows = [[r.variant, r.event, r.condition, r.scenario, _num(r.seed, 0),
             _not_caught_reason(r, caught_drop_m, window_s)]
            for r in _in_order(missed, "variant", "event", "condition", "scenario", "seed")
            .itertuples(index=False)]
    return header, rows


def false_alarm_rows(alarms: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """One row per variant and controller of `false_alarms`."""
    header = ["Variant", "Controller", "Rollouts", "Walking (h)", "Arm locks", "False alarms",
              "False alarms per hour"]
    rows = [[r.variant, r.condition, _num(r.rollouts, 0), _num(r.walking_h, 3), _num(r.alarms, 0),
             _num(r.false_alarms, 0), _num(r.false_alarms_per_h, 2)]
            for r in _in_order(alarms, "variant", "condition").itertuples(index=False)]
    return header, rows


def fall_lines(fall: pd.DataFrame, missed: pd.DataFrame, alarms: pd.DataFrame, figure: bool,
               caught_drop_m: float, window_s: float) -> list[str]:
    """The "Fall intervention" section: how each controller met the scripted balance losses of each
    variant (`fall_intervention`), each fall it did not catch and why (`falls_not_caught`; the issue
    asks for every one to be caught or shown), and how often it locked the arm in normal walking
    (`false_alarms`)."""
    lines = ["## Fall intervention", ""]
    if fall.empty and alarms.empty:
        return lines + [NO_FALLS, ""]
    lines += ["Scripted balance losses mid-walk (sim/body/balance_loss.py, params `fall_intervention`): trip "
              "(the swing foot held in place), slip (the stance foot on a slippery floor), collapse (the "
              "torque limits cut for a moment), push (a sideways push). Each is walked free (no robot: would "
              "the person fall unsupported?) and with each controller, with the same seeds. "
              + _missing_variants(fall, alarms), "",
              "Per variant, event and controller: Events: rollouts in which the human was still walking "
              "at the onset; Excluded: rollouts left out because the human had already fallen, or the arm "
              "locked, before it. Falls free: of these events, how many the same seed walking free fell "
              "(the falls the robot should catch; – without free walks). Human falls: events after which "
              "the human fell (pelvis below the fall height or trunk past its tilt limit) with this "
              "controller. Detected: events where the arm locked within the detection window after the "
              "onset (params `fall_intervention.detection_window_s`). Latency: mean time from the onset to "
              "the lock over the detected events. Drop at lock: how far the pelvis was below its walking "
              "height when the arm locked, mean (worst) over the detected events; negative is above. "
              "Caught: of the events that fell free, those where the arm locked with the pelvis at most "
              f"{caught_drop_m:.2f} m down (the fall rule's drop threshold + "
              "`fall_intervention.caught_margin_m`). Peak harness force: the largest harness force from the "
              "onset on, max over the rollouts (mean of their peaks).", "",
              md_table(*fall_rows(fall)),
              "### Falls not caught", "", *_not_caught_lines(fall, missed, caught_drop_m, window_s),
              "### False alarms", "",
              "Normal walking with the robot (no scripted event; every study and scenario): Arm locks: "
              "rollouts whose arm locked; a lock that no fall of the human follows within params "
              "`fall_intervention.confirm_s` is a false alarm. Walking (h): walking time before any lock, "
              "summed; false alarms per hour of it.", "", md_table(*false_alarm_rows(alarms))]
    return lines + (_image("fall_intervention") if figure else [])


def _not_caught_lines(fall: pd.DataFrame, missed: pd.DataFrame, caught_drop_m: float,
                      window_s: float) -> list[str]:
    """The "Falls not caught" table, or one line saying every fall was caught."""
    if missed.empty:
        n = int(fall.loc[fall["condition"] != "free", "events_falling_free"].sum()) if not fall.empty else 0
        return [f"Every event that fell walking free was caught: {n} of {n} rollouts with a controller.", ""]
    return ["Every rollout with a controller whose event the same seed walking free fell after, and that "
            "it did not catch, with why: no event (the human fell, or the arm locked, before the onset: "
            "not counted in \"Caught, of falls free\" above), the simulation went unstable, not detected "
            f"within the {window_s:.2f} s window, or detected with the pelvis already more than "
            f"{caught_drop_m:.2f} m down.", "", md_table(*not_caught_rows(missed, caught_drop_m, window_s))]


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


def universal_lines(progress: dict) -> list[str]:
    """The universal walking policy's run in a few lines: steps, wall time, its machines and the
    last gate, per subject's own body (`sim.learn.universal.quick_gate`)."""
    points = progress.get("checkpoints", [])
    machines = sorted({f"{r.get('cpu_count', '?')} cores" + (" + GPU" if r.get("device") == "cuda" else "")
                       for r in progress.get("runs", [])})
    steps_m, hours = progress.get("steps", 0) / 1e6, progress.get("wall_s", 0) / 3600
    start = progress.get("initialised_from", "scratch")
    lines = [f"One run of {steps_m:.2f} M env steps in {hours:.1f} h of training ({', '.join(machines)}), "
             f"from {start}."]
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


def summary_report(subjects: list[str], data: dict[str, pd.DataFrame], reports: Path = REPORTS_ROOT,
                   p: ReportParams = ReportParams(), paper: PaperValues | None = None,
                   progress: dict | None = None) -> tuple[Path, Path]:
    """Write `reports/summary.md` and `reports/index.html` across subjects: figures first, then the
    subject summary, Tables I-III with the paper's values and the per-phase table, then the universal
    walking policy's training progress (`progress`, its progress.json; figure `UNIVERSAL_FIGURE`)."""
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
    sh = ["Subject", "Quality", "Worst check", "Conditions", "Sources", "Versions", "Real strides",
          "Sim strides", "SPM tests", "SPM significant", "Last change"]
    srows = [[r.subject, worst(_of(data["quality"], r.subject)["status"]),
              worst_check_text(_of(data["quality"], r.subject)), r.conditions, r.sources,
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
    if progress is not None:
        write_figure(training_progress_figure(progress), reports / UNIVERSAL_FIGURE, p.dpi)
        lines = universal_lines(progress)
        md += ["## Universal walking policy: training progress", "",
               f"![training progress]({UNIVERSAL_FIGURE})", "", *[f"- {x}" for x in lines], ""]
        body += ["<h2>Universal walking policy: training progress</h2>",
                 f'<img src="{UNIVERSAL_FIGURE}" alt="training progress" width="900">', "<ul>",
                 *[f"<li>{html.escape(x)}</li>" for x in lines], "</ul>"]
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
        written += list(summary_report(all_subjects, data, reports, p, paper, progress))
    return written
