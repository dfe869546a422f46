"""The figures of a subject's report: which ones its stored rows allow (`subject_figures`, in the
order the index shows them) and each one's caption (`FIGURES`)."""

from __future__ import annotations

from collections.abc import Callable

import pandas as pd
from matplotlib.figure import Figure

from metrics.plots import (
    cohort_heatmap,
    event_figure,
    fall_intervention_figure,
    harness_figure,
    kinematics_figure,
    sensitivity_figure,
    spm_figure,
    tracking_figure,
    tuning_figure,
)
from pipeline.paths import PAPER_FILE
from pipeline.report.published import CONTROLLER_ORDER, load_paper, paper_compliance
from pipeline.report.queries import of
from pipeline.runs.report_params import ReportParams

UNIVERSAL_FIGURE = "universal_progress.png"  # in reports/: the universal policy's gate against steps
PROGRESS_WINDOW = 10  # checkpoints in the quick gate's running mean (each check is one walk: it swings)


def evaluation_totals(adoption: dict | None,
                      progress: dict | None = None) -> list[tuple[float, int, int, bool]]:
    """Each adoption evaluation (adoption.json) with a checkpoint: (env steps in M, evaluate-policy's
    checks passed over every body, of how many, whether its checkpoint is on a branch the run gave up:
    its steps are a checkpoint of a `discarded` branch in `progress` and none of the run's own)."""
    own = {c["steps"] for c in (progress or {}).get("checkpoints", [])}
    given_up = {c["steps"] for d in (progress or {}).get("discarded", []) for c in d["checkpoints"]} - own
    return [(e["universal_steps"] / 1e6, sum(r["checks_passed"] for r in e["subjects"].values()),
             sum(r["checks"] for r in e["subjects"].values()), e["universal_steps"] in given_up)
            for e in (adoption or {}).get("evaluations", []) if "universal_steps" in e]


def progress_curves(progress: dict, adoption: dict | None, window: int = PROGRESS_WINDOW) -> dict:
    """What the universal run's progress figure draws (`metrics.plots.training_progress_figure`):
    env steps (M) of each checkpoint, its quick-gate checks passed in all and per subject's own body,
    their running means over the last `window` checkpoints, the run's stretches on one kind of machine
    (start step, machine; resumes on the same kind continue a stretch), where its observation or its
    hidden layers were widened, it was taken back to an earlier checkpoint, or its training envs'
    values, its action std's floor or the side of its first step from standing changed, or its
    observation statistics were re-estimated (`changes`: step, label), the stretches trained with
    teachers (`taught`: start and end step), the checkpoints of the branches given up (`discarded`:
    steps, passed, per branch), evaluate-policy's checks passed over every body at each adoption
    evaluation (`adoption`, adoption.json: `evaluation_totals`), and each body's share of
    falls in training's episodes without random pushes at the checkpoints that recorded it
    (`calm_falls`: body -> steps, share; `training` in the progress record)."""
    points = progress.get("checkpoints", [])
    steps = [c["steps"] / 1e6 for c in points]
    passed = pd.Series([c["passed"] for c in points], dtype=float)
    subjects = list(points[-1]["gate"]) if points else []
    own = {s: pd.Series([sum(r["pass"] for r in c["gate"].get(s, {}).values()) for c in points], dtype=float)
           for s in subjects}
    calm_falls: dict[str, tuple[list, list]] = {}
    for c in points:
        for body, n in c.get("training", {}).get("episodes", {}).items():
            calm = n["episodes"] - n["pushed"]
            if calm:
                x, y = calm_falls.setdefault(body, ([], []))
                x.append(c["steps"] / 1e6)
                y.append((n["falls"] - n["pushed_falls"]) / calm)
    segments, taught, retrained, before, done = [], [], [], {}, 0
    for run in progress.get("runs", []):
        # marked where the training envs' values, the std's floor, the first step, the bound or rate changed
        settings = {**run.get("env", {}),
                    **{k: run[k] for k in ("min_action_std", "first_step", "bound_weight", "learning_rate")
                       if k in run}}
        if settings != before:
            before = settings
            shown = ", ".join(f"{k} {v}" for k, v in settings.items()) or "train's env"
            retrained.append((done / 1e6, f"trained with {shown}"))
        where = f"{run.get('cpu_count', '?')} cores" + (", cuda" if run.get("device") == "cuda" else "")
        if not segments or segments[-1][1] != where:  # a resume on the same kind of machine: one stretch
            segments.append((done / 1e6, where))
        if run.get("teachers"):
            taught.append((done / 1e6, (done + run.get("steps", 0)) / 1e6))
        done += run.get("steps", 0)
    return {"steps": steps, "passed": passed.tolist(), "checks": points[-1]["checks"] if points else 0,
            "passed_mean": passed.rolling(window, min_periods=1).mean().tolist(),
            "own_mean": {s: v.rolling(window, min_periods=1).mean().tolist() for s, v in own.items()},
            "window": window, "segments": segments, "taught": taught,
            "evaluations": evaluation_totals(adoption, progress), "calm_falls": calm_falls,
            "changes": [(w["steps"] / 1e6, f"inputs {w['obs_size'][0]} -> {w['obs_size'][1]}"
                         if "obs_size" in w else f"layers {w['net_arch'][0]} -> {w['net_arch'][1]}")
                        for w in progress.get("widened", [])] +
                       [(d["from_steps"] / 1e6, f"taken back from {d['to_steps'] / 1e6:.2f} M")
                        for d in progress.get("discarded", [])] +
                       [(s["steps"] / 1e6, "statistics re-estimated")
                        for s in progress.get("statistics", [])] + retrained,
            "discarded": [([c["steps"] / 1e6 for c in d["checkpoints"]],
                           [c["passed"] for c in d["checkpoints"]]) for d in progress.get("discarded", [])]}

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


def paper_sensitivity(sens: pd.DataFrame, scenario: str) -> pd.DataFrame:
    """The responsiveness study's rows (`sensitivity` view, one subject) of the subject's own policy
    human in the paper's scenario."""
    if sens.empty:
        return sens
    return sens[(sens["variant"] == "healthy") & (sens["scenario"] == scenario)]


def subject_figures(subject: str, data: dict[str, pd.DataFrame], p: ReportParams = ReportParams()
                    ) -> dict[str, Callable[[], Figure]]:
    """The figures of `subject` (names in `FIGURES`, in that order), each drawn when called; which
    ones exist follows from the stored data alone, so the index can list them without drawing."""
    bands = of(data["kinematics"], subject)
    side = "both" if (bands["side"] == "both").any() else "right"
    bands = bands[bands["side"] == side]
    policy = bands[(bands["source"] == "sim") & (bands["human_mode"] == "policy")]
    events = of(data["events"], subject)
    chosen = [(e, s) in p.event_scenarios.items() for e, s in zip(events["event"], events["scenario"],
                                                                  strict=True)]
    events = events[chosen]
    tests = of(data["spm_tests"], subject)
    curves = data["spm_curves"][data["spm_curves"]["test_id"].isin(tests["test_id"])]
    tracking, harness = of(data["tracking"], subject), of(data["harness"], subject)
    statistic = "F" if (tests["test"] == "anova1").all() else "t"
    tuning = of(data["tuning"], subject)
    cohort, fall = of(data["cohort_controllers"], subject), of(data["fall"], subject)
    sens = paper_sensitivity(of(data.get("sensitivity", pd.DataFrame()), subject), p.paper_scenario)
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



def figure_names(subject: str, data: dict[str, pd.DataFrame], p: ReportParams = ReportParams()) -> list[str]:
    """The figures `subject_figures` draws for a subject, in index order."""
    return list(subject_figures(subject, data, p))
