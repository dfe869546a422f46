"""Stage `simulate <subject>`: closed-loop rollouts of the subject's human in every condition and
seed, processed by the same ingest code as the real recordings.

The replay human (default) walks the subject's straight bouts: runs of kept real strides
(`ingest.strides.kept_stride_runs`), each entered after a lead-in (`sim.motion.replay.with_lead_in`)
so that every controller meets the bout in the same natural state: the robot-only baseline. `--human
policy` runs the trained, steerable walking policy through every scenario (params `scenarios`), each
row tagged with its scenario and commanded phase. Both go through the one batch runner,
`sim.rollout.batch`, with the setups and jobs of `pipeline.runs.jobs`.

Outputs in `<root>/<subject>/sim/` (replay) or `sim_policy/` (policy): events, strides, cycles,
robot.parquet, summary.json; replay also draws `reports/<subject>/robot_tracking.png`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ingest.process import IngestParams
from metrics.outcomes import compliance_headline
from metrics.plots import tracking_figure
from metrics.tracking import tracking_table
from pipeline import paths
from pipeline.params import Params
from pipeline.runs.gate_record import gate_failed, gate_summary, read_gate
from pipeline.runs.jobs import (
    policy_body_is_current,
    policy_setup,
    replay_jobs,
    replay_setup,
    scenario_jobs,
    scenario_profiles,
)
from pipeline.runs.report_params import ReportParams
from pipeline.stages.outputs import write_figure, write_outputs
from sim.rollout.batch import RolloutJob, RolloutOutcome, batch_tables, run_batch
from sim.rollout.scenarios import ScenariosSection, measured_phases, phase_agreement, phase_at
from sim.rollout.section import RolloutSection


def run_summary(outcomes: list[RolloutOutcome], robot: pd.DataFrame, exclude_locked: bool) -> dict:
    """What a simulate run reports: rollouts, instabilities, skipped trials, speed, compliance."""
    wall = sum(o.wall_s for o in outcomes)
    sim_s = sum(o.sim_s for o in outcomes)
    return {"rollouts": len(outcomes), "unstable": sum(not o.stable for o in outcomes),
            "warnings": sorted({k for o in outcomes for k in o.warnings}),
            "skipped": [f"{o.job.trial} {o.job.condition}: {o.skipped}" for o in outcomes if o.skipped],
            "falls": {c: sum(o.fell for o in outcomes if o.job.condition == c)
                      for c in sorted({o.job.condition for o in outcomes})},
            "realtime_factor": round(sim_s / wall, 2) if wall else None,  # lead-ins included
            "conditions": compliance_headline(robot, exclude_locked)}


def run_simulate(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                 reports: Path = paths.REPORTS_ROOT, progress: bool = True) -> dict:
    """Replay-human rollouts of every straight bout x condition x seed -> `<root>/<subject>/sim/`."""
    setup, workers = replay_setup(subject, params, root), params.section("rollout", RolloutSection).workers
    outcomes = run_batch(setup, replay_jobs(subject, params, root), workers,
                         f"simulate {subject}", progress)
    tables = batch_tables(outcomes)
    summary = {"human_mode": "replay", "bouts": "straight bouts only (kept real strides)",
               **run_summary(outcomes, tables["robot"], params.section("metrics.exclude_locked", bool))}
    write_outputs(paths.sim_dir(root, subject), tables, {"summary": summary})
    tracking = tracking_table(tables["robot"], params.section("metrics.tracking_rate_hz", float))
    fig = tracking_figure(tracking, f"{subject}: pelvis offset from the arm's neutral point, replay human, "
                          "first bout and seed")
    dpi = params.section("report", ReportParams).dpi
    write_figure(fig, paths.report_dir(reports, subject) / "robot_tracking.png", dpi)
    return summary


def tag_scenarios(tables: dict[str, pd.DataFrame], jobs: list[RolloutJob], profiles: dict) -> None:
    """Add `scenario` and the commanded `phase` (sim.rollout.scenarios.phase_at) to the rollout tables
    in place: robot rows by sample time, strides by the phase they end in (a stride inside one phase
    has that phase), events by time; cycles get their stride's phase."""
    scenario_of = {j.trial: j.human.scenario for j in jobs}
    for name, table in tables.items():
        if table.empty:
            tables[name] = table.assign(scenario=pd.Series(dtype=str), phase=pd.Series(dtype=str))
            continue
        table["scenario"] = table["trial"].map(scenario_of).astype(str)
        time_col = {"robot": "time_s", "events": "time_s", "strides": "t_end_s"}.get(name)
        if time_col is None:
            continue
        table["phase"] = ""
        for scenario, rows in table.groupby("scenario").groups.items():
            table.loc[rows, "phase"] = phase_at(profiles[scenario], table.loc[rows, time_col].to_numpy(float))
    keys = ["trial", "seed", "side", "stride"]
    if not tables["cycles"].empty:
        tables["cycles"] = tables["cycles"].merge(tables["strides"][[*keys, "phase"]], on=keys, how="left")


def commanded_vs_measured(outcomes: list[RolloutOutcome], profiles: dict, ingest: IngestParams,
                          tolerance_s: float) -> dict[str, dict[str, float]]:
    """Per scenario and commanded phase, the share of samples whose phase read from the simulated
    pelvis path (`sim.rollout.scenarios.measured_phases`) agrees, within `tolerance_s`, averaged over
    the walks without a fall (a walk that fell did not do what it was asked)."""
    shares: dict[str, dict[str, list[float]]] = {}
    for o in outcomes:
        if o.fell or o.pelvis_xy is None or len(o.pelvis_xy) < 10:
            continue
        name = o.job.human.scenario
        t = np.arange(len(o.pelvis_xy)) / o.sample_rate_hz
        measured = measured_phases(o.pelvis_xy, o.sample_rate_hz, ingest)
        tolerance = int(round(tolerance_s * o.sample_rate_hz))
        ok = phase_agreement(phase_at(profiles[name], t), measured, tolerance)
        for phase, share in ok.items():
            shares.setdefault(name, {}).setdefault(phase, []).append(share)
    return {name: {ph: round(float(np.mean(v)), 3) for ph, v in by.items()} for name, by in shares.items()}


def run_simulate_policy(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                        policy_root: Path = paths.POLICIES_ROOT, progress: bool = True) -> dict:
    """Policy-human rollouts of every scenario x condition x walk -> `<root>/<subject>/sim_policy/`
    (events, strides, cycles, robot tagged with scenario and phase; summary.json). A subject without
    a trained policy, or whose transferred policy failed its gate (`pipeline.runs.gate`), gets
    empty tables and a summary that says so; a transferred policy's gate (`transfer`) and whether
    the policy's own body is the subject's current model (`policy_body`) go into the summary, which
    the metrics stage turns into quality rows."""
    folder = paths.policy_dir(policy_root, subject)
    out = paths.sim_policy_dir(root, subject)
    gate = read_gate(folder)
    transfer = {} if gate is None else {"transfer": gate_summary(gate)}
    if not folder.exists() or gate_failed(gate):
        empty = {name: pd.DataFrame() for name in ("events", "strides", "cycles", "robot")}
        note = (f"no trained policy in {folder}: run `python -m pipeline train {subject}`" if gate is None
                else f"the policy fine-tuned from {gate.get('source')} failed its transfer gate "
                f"({', '.join(gate.get('failed', [])) or 'no check required'}): replay rows only")
        summary = {"human_mode": "policy", "rollouts": 0, "note": note, **transfer}
        write_outputs(out, empty, {"summary": summary})
        return summary
    from sim.learn.train import load_body

    setup = policy_setup(subject, params, root, policy_root)
    jobs, r = scenario_jobs(params), params.section("rollout", RolloutSection)
    sc = params.section("scenarios", ScenariosSection)
    outcomes = run_batch(setup, jobs, r.workers, f"scenario rollouts {subject}", progress)
    tables = batch_tables(outcomes)
    body_xml, cycle = load_body(folder)
    profiles = scenario_profiles(params, cycle.speed_mps, setup.drivers.sample_rate_hz)
    tag_scenarios(tables, jobs, profiles)
    agreement = commanded_vs_measured(outcomes, profiles, params.section("ingest", IngestParams),
                                      sc.phase_tolerance_s)
    exclude = params.section("metrics.exclude_locked", bool)
    summary = {"human_mode": "policy", **run_summary(outcomes, tables["robot"], exclude),
               "falls_by_scenario": {f"{name} {c}": sum(o.fell for o in outcomes if o.job.condition == c
                                                         and o.job.human.scenario == name)
                                     for name in sc.commands
                                     for c in r.conditions},
               "phase_agreement": agreement,
               "policy_body": {"file": paths.repo_relative(body_xml),
                               "current_model": policy_body_is_current(body_xml, root, subject)},
               **transfer}
    write_outputs(out, tables, {"summary": summary})
    return summary


__all__ = ["run_simulate", "run_simulate_policy", "run_summary", "tag_scenarios"]
