"""What each section of a subject's report shows, from that subject's rows of the store's views:
one pure function per section, returning the values and tables its template
(templates/sections.md.j2, the macro of the same name) prints."""

from __future__ import annotations

import json

import pandas as pd

from metrics.findings import (
    compliance_findings,
    level_text,
    region_text,
    responsiveness_comparisons,
    speed_findings,
    variability_findings,
)
from metrics.plots import VARIANT_ORDER, group_label
from metrics.quality import worst
from pipeline.report.cells import count, falls_of, mean_sd, num, versus, walks
from pipeline.report.published import (
    CLINICAL_MEASURES,
    CONTROLLER_ORDER,
    PAPER_PAIR,
    ClinicalRange,
    PaperValues,
    paper_compliance,
)
from pipeline.report.tables import Table, in_order, quality_table, worst_check_text

FINDING_PHASES = ("start", "steady", "stop")  # the walk_10m phases the compliance findings are read in
# The sections of the figures that stand alone, in report order, with their headings.
FIGURE_SECTIONS = {"events": "Around the commanded events", "kinematics_policy": "Gait per controller",
                   "kinematics": "Joint kinematics", "spm": "SPM1D", "tracking": "Tracking",
                   "harness": "Harness force and torque"}


def transfer(q: pd.DataFrame) -> dict | None:
    """What the report says first about a transferred policy (the `policy` quality rows of its gate,
    `metrics.quality.transfer_checks`): where it came from and the required checks it failed. None
    for a committed policy."""
    gate = q[q["stage"] == "policy"] if not q.empty else q
    if gate.empty:
        return None
    return {"origin": str(gate["note"].iloc[0]).split("; ")[0],  # "fine-tuned from S (distance d, n steps)"
            "failed": gate[gate["status"] == "fail"]["check"].tolist()}


def quality(q: pd.DataFrame) -> dict:
    """The quality gates (failed first), the worst status and the worst check."""
    table = quality_table(q)
    return {"table": table, "worst": worst(r[4] for r in table.rows),
            "worst_check": worst_check_text(q) if table.rows else ""}


def policy_checks(doc: dict | None) -> dict | None:
    """The `evaluate-policy` result of the subject's committed policy (its evaluation.json): every
    check with pass / FAIL, and per scenario and condition the walks, falls and timings."""
    if doc is None:
        return None
    checks = doc.get("checks", {})
    out = {"passed": sum(bool(v) for v in checks.values()), "n": len(checks), "scenarios": None,
           "checks": Table(["check", "result"],
                           [[name, "pass" if ok else ("not judged" if ok is None else "FAIL")]
                            for name, ok in checks.items()])}
    sc = doc.get("scenarios")
    if sc:
        rows = [[key, str(v["walks"]), str(v["human_falls"]), str(v.get("start_s", "–")),
                 str(v.get("start_from_onset_s", "–")), str(v.get("stop_s", "–")),
                 str(v.get("steady_speed_mps", "–"))]
                for key, v in sc.items() if isinstance(v, dict) and "walks" in v]
        out["scenarios"] = {
            "own_start_s": sc.get("own_start_s"), "start_window_s": sc.get("start_window_s"),
            "table": Table(["scenario condition", "walks", "human falls", "start (s)",
                            "start from onset (s, as recorded starts are timed)", "stop (s)",
                            "steady speed (m/s)"], rows)}
    return out


def spm(tests: pd.DataFrame, clusters: pd.DataFrame) -> dict:
    """The SPM clusters table and the comparisons skipped, with their reasons."""
    table = Table(["Comparison", "Joint", "A", "B", "Cluster (% cycle)", "p"],
                  [[c.comparison, c.joint, group_label(c.source_a, c.human_mode_a, c.condition_a),
                    group_label(c.source_b, c.human_mode_b, c.condition_b),
                    f"{c.start_pct:.1f}–{c.end_pct:.1f}", "<0.001" if c.p < 0.001 else f"{c.p:.3f}"]
                   for c in clusters.itertuples()])
    skipped = [{"joint": r.joint, "a": group_label(r.source_a, r.human_mode_a, r.condition_a),
                "b": group_label(r.source_b, r.human_mode_b, r.condition_b), "reason": r.reason}
               for r in tests[tests["status"] != "ok"].itertuples()]
    return {"table": table, "skipped": skipped}


def findings(phases: pd.DataFrame, table2: pd.DataFrame, table3: pd.DataFrame, paper: PaperValues,
             scenario: str, sens: pd.DataFrame | None = None) -> dict:
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
    header = ["Finding (paper)", "Paper sim", "This simulation (a vs b)", "Verdict", "Responsiveness region"]
    table = Table(header, [[f.claim, f.paper, f.measured, f.verdict, f.region] for f in found])
    return {"mode": mode, "scenario": scenario, "table": table}


def sensitivity(sens: pd.DataFrame, paper: PaperValues, scenario: str, figure: bool) -> dict:
    """The "Follow-me responsiveness" section: per factor and level, pid and adaptive mean |e_x| and
    |e_y| (± 95 % CI across walks), which is lower, and the walks that fell (`sensitivity` view)."""
    out = {"empty": sens.empty, "scenario": scenario, "figure": figure}
    if sens.empty:
        return out
    ex, ey = (responsiveness_comparisons(sens, c, PAPER_PAIR) for c in ("mean_abs_ex_cm", "mean_abs_ey_cm"))
    rows = [[f"{a.factor}{' (twin)' if a.twin else ''}", level_text(a.factor, a.level), versus(a), a.result,
             versus(b), b.result, f"{a.falls_pid}/{a.n} vs {a.falls_adaptive}/{a.n}"]
            for a, b in zip(ex.itertuples(index=False), ey.itertuples(index=False), strict=True)]
    cited = ", ".join(f"{c} {v[0]:.2f} / {v[1]:.2f}" for c, v in paper_compliance(paper).items())
    return {**out, "paper": cited,
            "table": Table(["Factor", "Level", "e_x pid vs adaptive (cm)", "adaptive vs pid",
                            "e_y pid vs adaptive (cm)", "adaptive vs pid", "Falls pid vs adaptive"], rows),
            "region_ex": region_text(ex, PAPER_PAIR), "region_ey": region_text(ey, PAPER_PAIR)}


def _gains(doc) -> str:
    gains = json.loads(doc) if isinstance(doc, str) else dict(doc)
    return ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in gains.items())


def _cost(mean, ci, n_falls, n) -> str:
    return f"{mean_sd(mean, ci, 4)} ({num(n_falls, 0)}/{num(n, 0)} falls)"


def _search_falls(status: str, n_falls, rollouts) -> str:
    if status == "unknown":
        return "–"
    text = f"{int(n_falls)}/{int(rollouts)}"
    return f"{text} **no signal**" if status == "no signal" else text


def tuning(t: pd.DataFrame, figure: bool) -> dict:
    """The "Controller tuning" section: per controller and variant the held-back objective with the
    generic and the tuned gains (mean ± 95 % CI across rollouts, falls) and the tuned gains; None
    for the table without tuned gains."""
    table = None if t.empty else Table(
        ["Controller", "Variant", "Search", "Search rollouts fallen", "Generic gains", "Tuned gains",
         "Tuned gain values"],
        [[r.controller, r.variant, f"{r.method}, {int(r.n_trials)} trials",
          _search_falls(r.search_status, r.search_falls, r.search_rollouts),
          _cost(r.generic_mean, r.generic_ci95, r.generic_falls, r.n_heldout),
          _cost(r.tuned_mean, r.tuned_ci95, r.tuned_falls, r.n_heldout), _gains(r.tuned_gains)]
         for r in t.sort_values(["controller", "variant"]).itertuples(index=False)])
    return {"table": table, "figure": figure}


# -- virtual cohort and fall intervention (issue 13; views cohort_gait, cohort_controllers,
#    fall_intervention, false_alarms of pipeline/store.py) ---------------------------------------------

def missing_variants(*tables: pd.DataFrame) -> list[str]:
    """The cohort variants that have no rows in any of `tables`."""
    present = set().union(*(set(t["variant"]) for t in tables))
    return [v for v in VARIANT_ORDER if v not in present]


def clinical_table(ranges: dict[str, ClinicalRange]) -> Table:
    """The published reference values, one row each: measure, value, what it means, source."""
    return Table(["Measure", "Published value", "Meaning", "Source"],
                 [[CLINICAL_MEASURES[r.measure], r.value_text(), r.meaning, r.source]
                  for r in ranges.values()])


def cohort(gait: pd.DataFrame, controllers: pd.DataFrame, ranges: dict[str, ClinicalRange],
           figure: bool) -> dict:
    """The "Virtual cohort" section: each variant's gait walking free (`cohort_gait`) beside the
    published clinical ranges, then each variant with each controller (`cohort_controllers`).
    `no_strides`: the variants and scenarios `cohort_gait` marks `no_strides` (no walk fell and the
    ingest code kept not one stride, so their rows describe no measured gait)."""
    out = {"empty": gait.empty and controllers.empty, "figure": figure}
    if out["empty"]:
        return out
    gait_rows = [[r.variant, r.scenario, walks(r.walks, r.distinct_walks), falls_of(r.falls, r.walks),
                  mean_sd(r.gait_speed_mps, r.gait_speed_sd, 3), num(r.stride_length_m, 3),
                  num(r.stance_ratio_lr, 3), num(r.swing_ratio_lr, 3), num(r.stride_time_cv_pct, 2),
                  num(r.strides, 0)]
                 for r in in_order(gait, "variant", "scenario").itertuples(index=False)]
    controller_rows = [[r.variant, r.scenario, r.condition, num(r.walks, 0), falls_of(r.falls, r.walks),
                        num(r.mean_abs_ex_cm, 2), num(r.mean_abs_ey_cm, 2), num(r.force_rms_n, 2),
                        num(r.speed_change_pct, 2), num(r.stride_change_pct, 2), num(r.cv_change_pct, 2)]
                       for r in in_order(controllers, "variant", "scenario", "condition")
                       .itertuples(index=False)]
    idle = in_order(gait[gait["status"] == "no_strides"], "variant", "scenario")
    return {**out, "missing": missing_variants(gait, controllers),
            "gait": Table(["Variant", "Scenario", "Walks", "Falls", "Gait speed (m/s)", "Stride length (m)",
                           "Stance ratio L/R", "Swing ratio L/R", "Stride time CV (%)", "Strides"],
                          gait_rows),
            "no_strides": [f"{r.variant} in {r.scenario}" for r in idle.itertuples(index=False)],
            "clinical": clinical_table(ranges) if ranges else None,
            "controllers": Table(["Variant", "Scenario", "Controller", "Walks", "Falls", "Mean abs e_x (cm)",
                                  "Mean abs e_y (cm)", "Harness force RMS (N)", "Gait speed change (%)",
                                  "Stride length change (%)", "Stride time CV change (points)"],
                                 controller_rows)}


def fall_table(fall: pd.DataFrame) -> Table:
    """One row per variant, event and controller (conditions with a robot) of `fall_intervention`;
    "Falls free" is "–" where the same variant and event have no walks without the robot."""
    header = ["Variant", "Event", "Controller", "Events", "Excluded (fell before onset)", "Falls free",
              "Human falls", "Detected", "Latency (s)", "Drop at lock (m), mean (worst)",
              "Caught, of falls free", "Peak harness force (N), max (mean)"]
    free = {(r.variant, r.event) for r in fall[fall["condition"] == "free"].itertuples(index=False)}
    robot = in_order(fall[fall["condition"] != "free"], "variant", "event", "condition")
    rows = []
    for r in robot.itertuples(index=False):
        has_free = (r.variant, r.event) in free
        drop = "–" if num(r.pelvis_drop_at_lock_m, 3) == "–" else \
            f"{num(r.pelvis_drop_at_lock_m, 3)} ({num(r.worst_drop_at_lock_m, 3)})"
        force = "–" if num(r.peak_harness_force_n, 0) == "–" else \
            f"{num(r.peak_harness_force_n, 0)} ({num(r.max_harness_force_n, 0)})"
        rows.append([r.variant, r.event, r.condition, num(r.events, 0), num(r.fell_before_onset, 0),
                     f"{int(r.events_falling_free)}/{int(r.events)}" if has_free else "–",
                     f"{int(r.human_falls)}/{int(r.events)}", count(r.detection_rate, r.events),
                     num(r.latency_s, 2), drop,
                     count(r.caught_rate_falling, r.events_falling_free) if has_free else "–", force])
    return Table(header, rows)


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


def not_caught_table(missed: pd.DataFrame, caught_drop_m: float, window_s: float) -> Table:
    """One row per event of `falls_not_caught` (fell walking free, not caught with this controller)."""
    return Table(["Variant", "Event", "Controller", "Scenario", "Seed", "Why not caught"],
                 [[r.variant, r.event, r.condition, r.scenario, num(r.seed, 0),
                   _not_caught_reason(r, caught_drop_m, window_s)]
                  for r in in_order(missed, "variant", "event", "condition", "scenario", "seed")
                  .itertuples(index=False)])


def false_alarm_table(alarms: pd.DataFrame) -> Table:
    """One row per variant and controller of `false_alarms`."""
    return Table(["Variant", "Controller", "Rollouts", "Walking (h)", "Arm locks", "False alarms",
                  "False alarms per hour"],
                 [[r.variant, r.condition, num(r.rollouts, 0), num(r.walking_h, 3), num(r.alarms, 0),
                   num(r.false_alarms, 0), num(r.false_alarms_per_h, 2)]
                  for r in in_order(alarms, "variant", "condition").itertuples(index=False)])


def fall(events: pd.DataFrame, missed: pd.DataFrame, alarms: pd.DataFrame, figure: bool, caught_drop_m: float,
         window_s: float) -> dict:
    """The "Fall intervention" section: how each controller met the scripted balance losses of each
    variant (`events`: `fall_intervention`), each fall it did not catch and why (`falls_not_caught`;
    the issue asks for every one to be caught or shown; `all_caught`: how many were, when all were),
    and how often it locked the arm in normal walking (`false_alarms`)."""
    out = {"empty": events.empty and alarms.empty, "figure": figure, "caught_drop_m": caught_drop_m,
           "window_s": window_s}
    if out["empty"]:
        return out
    robot = events.loc[events["condition"] != "free"] if not events.empty else events
    caught = int(robot["events_falling_free"].sum()) if not events.empty else 0
    return {**out, "missing": missing_variants(events, alarms), "table": fall_table(events),
            "not_caught": None if missed.empty else not_caught_table(missed, caught_drop_m, window_s),
            "all_caught": caught, "false_alarms": false_alarm_table(alarms)}
