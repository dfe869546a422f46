"""Stage `simulate <subject>`: closed-loop rollouts of the subject's human in every condition and
seed, processed by the same ingest code as the real recordings.

The replay human (default) walks the subject's straight bouts: runs of kept real strides
(`ingest.strides.kept_stride_runs`), each entered after a lead-in (`sim.motion.replay.with_lead_in`)
so that every controller meets the bout in the same natural state: the robot-only baseline. `--human
policy` runs the trained, steerable walking policy through every scenario (params `scenarios`), each
row tagged with its scenario and commanded phase. Both go through the one batch runner,
`sim.rollout.batch`.

Outputs in `<root>/<subject>/sim/` (replay) or `sim_policy/` (policy): events, strides, cycles,
robot.parquet, summary.json; replay also draws `reports/<subject>/robot_tracking.png`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ingest.process import IngestParams
from ingest.strides import kept_stride_runs
from ingest.subject import load_subject
from metrics.compliance import compliance_headline
from metrics.plots import tracking_figure
from metrics.tracking import tracking_table
from pipeline import paths
from pipeline.params import Params
from pipeline.stages.outputs import write_figure, write_outputs
from pipeline.stages.transfer import gate_failed, gate_summary, read_gate
from sim.body.variant import HEALTHY
from sim.errors import SimulationError
from sim.motion.reference import load_reference
from sim.motion.replay import ReplaySegment, ReplaySource
from sim.rollout.batch import BatchSetup, RolloutJob, RolloutOutcome, batch_tables, run_batch
from sim.rollout.scenarios import CommandProfile, command_profile, measured_phases, phase_agreement, phase_at

if TYPE_CHECKING:
    from sim.learn.policy_human import PolicyWalk


def require_inputs(*files: Path, what: str) -> None:
    """`SimulationError` naming the first of `files` that does not exist (an earlier stage's output)."""
    for f in files:
        if not f.exists():
            raise SimulationError(f, f"missing input of {what} (run the stage that makes it)")


def replay_setup(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT) -> BatchSetup:
    """The batch runner's setup for `subject`'s replay human (scaled model and reference motion)."""
    xml, npz = paths.human_xml(root, subject), paths.reference_npz(root, subject)
    require_inputs(xml, npz, what=f"`simulate {subject}`")
    r = params.rollout
    source = ReplaySource(str(npz), r.replay.build(), r.lead_in_s, r.lead_in_ramp_s)
    return params.batch_setup(subject, load_subject(subject).markerset, xml, source)


def replay_jobs(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                conditions: tuple[str, ...] | None = None, seeds: range | None = None) -> list[RolloutJob]:
    """One job per straight bout, condition and seed (default: `rollout.conditions`, `n_seeds`)."""
    r = params.rollout
    strides_file = paths.real_dir(root, subject) / "strides.parquet"
    require_inputs(strides_file, what=f"`simulate {subject}`")
    strides = pd.read_parquet(strides_file)
    ref = load_reference(paths.reference_npz(root, subject))
    conditions = r.conditions if conditions is None else conditions
    seeds = range(r.n_seeds) if seeds is None else seeds
    jobs = []
    for trial in sorted(set(ref.trial.tolist())):
        kept = strides[(strides["trial"] == trial) & strides["kept"]]
        stride_s = float(kept["stride_time_s"].median())
        for b, (t0, t1) in enumerate(kept_stride_runs(strides, trial, r.bout_margin_s, r.bout_join_gap_s)):
            segment = ReplaySegment(trial, t0, t1, stride_s)
            jobs += [RolloutJob(c, s, f"{trial}_bout{b}_seed{s}", segment) for c in conditions for s in seeds]
    if not jobs:
        raise SimulationError(strides_file, f"no straight bout (kept strides) in the retargeted trials of "
                              f"{subject}")
    return jobs


def policy_setup(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                 policy_root: Path = paths.POLICIES_ROOT, variant: str = HEALTHY) -> BatchSetup:
    """The batch runner's setup for `subject`'s trained walking policy (or cohort `variant`'s
    fine-tuned one, on the variant's body), sampled at `rollout.policy_sample_rate_hz` (its physics
    step must be the training timestep)."""
    from sim.learn.policy_human import PolicySource  # torch and SB3: only for the policy human
    from sim.learn.train import BODY_FILE, CYCLE_FILE, POLICY_FILE

    folder = paths.policy_dir(policy_root, subject, variant)
    for f in (POLICY_FILE, BODY_FILE, CYCLE_FILE):
        if not (folder / f).exists():
            how = f"train {subject}" + ("" if variant == HEALTHY else f" --variant {variant}")
            raise SimulationError(folder / f, f"no trained policy: run `python -m pipeline {how}`")
    scenarios = {name: tuple(segs) for name, segs in params.scenarios.build().items()}
    source = PolicySource(str(folder), params.train_params(variant).env, params.rollout.policy_sample_rate_hz,
                          params.evaluate_policy.fall_height_fraction, scenarios,
                          params.scenarios.profile.build(), params.rollout.policy_motor_noise)
    return params.batch_setup(subject, load_subject(subject).markerset, folder / BODY_FILE, source)


def policy_job(condition: str, seed: int, walk: PolicyWalk, tag: str = "") -> RolloutJob:
    """A policy-human job; its trial id names the condition (or `tag`) and the seed."""
    return RolloutJob(condition, seed, f"policy_{tag or condition}_seed{seed}", walk)


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
    setup = replay_setup(subject, params, root)
    outcomes = run_batch(setup, replay_jobs(subject, params, root), params.rollout.workers,
                         f"simulate {subject}", progress)
    tables = batch_tables(outcomes)
    summary = {"human_mode": "replay", "bouts": "straight bouts only (kept real strides)",
               **run_summary(outcomes, tables["robot"], params.metrics.exclude_locked)}
    write_outputs(paths.sim_dir(root, subject), tables, {"summary": summary})
    tracking = tracking_table(tables["robot"], params.metrics.tracking_rate_hz)
    fig = tracking_figure(tracking, f"{subject}: pelvis offset from the arm's neutral point, replay human, "
                          "first bout and seed")
    write_figure(fig, paths.report_dir(reports, subject) / "robot_tracking.png", params.report.dpi)
    return summary


def scenario_jobs(params: Params, conditions: tuple[str, ...] | None = None,
                  walks: int | None = None, scenarios: tuple[str, ...] | None = None) -> list[RolloutJob]:
    """One policy-human job per scenario x condition x walk (default: every scenario,
    `rollout.conditions`, `scenarios.walks(name)` walks); trial id `<scenario>_<condition>_seed<k>`."""
    from sim.learn.policy_human import PolicyWalk

    sc = params.scenarios
    conditions = params.rollout.conditions if conditions is None else conditions
    names = tuple(sc.commands) if scenarios is None else scenarios
    return [RolloutJob(c, k, f"{name}_{c}_seed{k}", PolicyWalk(scenario=name))
            for name in names for c in conditions for k in range(walks or sc.walks(name))]


def scenario_profiles(params: Params, speed_mps: float, rate_hz: float) -> dict[str, CommandProfile]:
    """Every scenario's command profile for a person whose preferred speed is `speed_mps`."""
    profile = params.scenarios.profile.build()
    return {name: command_profile(name, segs, speed_mps, rate_hz, profile)
            for name, segs in params.scenarios.build().items()}


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
    a trained policy, or whose transferred policy failed its gate (`pipeline.stages.transfer`), gets
    empty tables and a summary that says so; a transferred policy's gate goes into the summary
    (`transfer`), which the metrics stage turns into quality rows."""
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
    jobs = scenario_jobs(params)
    outcomes = run_batch(setup, jobs, params.rollout.workers, f"scenario rollouts {subject}", progress)
    tables = batch_tables(outcomes)
    _, cycle = load_body(folder)
    profiles = scenario_profiles(params, cycle.speed_mps, setup.drivers.sample_rate_hz)
    tag_scenarios(tables, jobs, profiles)
    agreement = commanded_vs_measured(outcomes, profiles, params.ingest.build(),
                                      params.scenarios.phase_tolerance_s)
    exclude = params.metrics.exclude_locked
    summary = {"human_mode": "policy", **run_summary(outcomes, tables["robot"], exclude),
               "falls_by_scenario": {f"{name} {c}": sum(o.fell for o in outcomes if o.job.condition == c
                                                         and o.job.human.scenario == name)
                                     for name in params.scenarios.commands
                                     for c in params.rollout.conditions},
               "phase_agreement": agreement, **transfer}
    write_outputs(out, tables, {"summary": summary})
    return summary


__all__ = ["policy_job", "policy_setup", "replay_jobs", "replay_setup", "run_simulate", "run_simulate_policy",
           "run_summary", "scenario_jobs", "scenario_profiles", "tag_scenarios"]
