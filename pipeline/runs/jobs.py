"""The batch runner's setups and jobs (`sim.rollout.batch`) for a subject, built from params: the
replay human's (`replay_setup`, `replay_jobs`: one job per straight bout of kept real strides,
condition and seed) and the policy human's (`policy_setup`, `policy_job`, `scenario_jobs`: every
scenario of params `scenarios` x condition x walk), and the scenarios' command profiles
(`scenario_profiles`). The simulate stage, evaluate-policy, the sweep, tuning, render and export all
build their rollouts here.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from ingest.strides import kept_stride_runs
from ingest.subject import load_subject
from pipeline import paths
from pipeline.params import Params
from pipeline.runs.setup import batch_setup, train_params
from sim.body.variant import HEALTHY
from sim.errors import SimulationError
from sim.motion.reference import load_reference
from sim.motion.replay import ReplaySegment, ReplaySource
from sim.rollout.batch import BatchSetup, RolloutJob
from sim.rollout.scenarios import CommandProfile, ScenariosSection, command_profile
from sim.rollout.section import RolloutSection

if TYPE_CHECKING:
    from sim.learn.policy_human import PolicyWalk


def require_inputs(*files: Path, what: str) -> None:
    """`SimulationError` naming the first of `files` that does not exist (an earlier stage's output)."""
    for f in files:
        if not f.exists():
            raise SimulationError(f, f"missing input of {what} (run the stage that makes it)")


def policy_digest(folder: Path) -> str:
    """sha256 (16 hex) of the policy file in `folder`: which policy a result (a sweep job, a tuning)
    came from."""
    return hashlib.sha256((folder / "policy.zip").read_bytes()).hexdigest()[:16]


def replay_setup(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT) -> BatchSetup:
    """The batch runner's setup for `subject`'s replay human (scaled model and reference motion)."""
    xml, npz = paths.human_xml(root, subject), paths.reference_npz(root, subject)
    require_inputs(xml, npz, what=f"`simulate {subject}`")
    r = params.section("rollout", RolloutSection)
    source = ReplaySource(str(npz), r.replay, r.lead_in_s, r.lead_in_ramp_s)
    return batch_setup(params, subject, load_subject(subject).markerset, xml, source)


def replay_jobs(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                conditions: tuple[str, ...] | None = None, seeds: range | None = None) -> list[RolloutJob]:
    """One job per straight bout, condition and seed (default: `rollout.conditions`, `n_seeds`)."""
    r = params.section("rollout", RolloutSection)
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
    sc, r = params.section("scenarios", ScenariosSection), params.section("rollout", RolloutSection)
    scenarios = {name: tuple(segs) for name, segs in sc.build().items()}
    source = PolicySource(str(folder), train_params(params, variant).env, r.policy_sample_rate_hz,
                          params.section("evaluate_policy.fall_height_fraction", float), scenarios,
                          sc.profile, r.policy_motor_noise)
    return batch_setup(params, subject, load_subject(subject).markerset, folder / BODY_FILE, source)


def policy_body_is_current(policy_body: Path, root: Path, subject: str) -> bool:
    """Whether a policy's own body (the human.xml it was trained on, which its rollouts walk) is
    byte for byte `subject`'s current scaled model; when scaling has changed since training, the
    policy's results describe the older body."""
    xml = paths.human_xml(root, subject)
    return xml.is_file() and policy_body.read_bytes() == xml.read_bytes()


def policy_job(condition: str, seed: int, walk: PolicyWalk, tag: str = "") -> RolloutJob:
    """A policy-human job; its trial id names the condition (or `tag`) and the seed."""
    return RolloutJob(condition, seed, f"policy_{tag or condition}_seed{seed}", walk)


def scenario_jobs(params: Params, conditions: tuple[str, ...] | None = None,
                  walks: int | None = None, scenarios: tuple[str, ...] | None = None) -> list[RolloutJob]:
    """One policy-human job per scenario x condition x walk (default: every scenario,
    `rollout.conditions`, `scenarios.walks(name)` walks); trial id `<scenario>_<condition>_seed<k>`."""
    from sim.learn.policy_human import PolicyWalk

    sc = params.section("scenarios", ScenariosSection)
    conditions = params.section("rollout", RolloutSection).conditions if conditions is None else conditions
    names = tuple(sc.commands) if scenarios is None else scenarios
    return [RolloutJob(c, k, f"{name}_{c}_seed{k}", PolicyWalk(scenario=name))
            for name in names for c in conditions for k in range(walks or sc.walks(name))]


def scenario_profiles(params: Params, speed_mps: float, rate_hz: float) -> dict[str, CommandProfile]:
    """Every scenario's command profile for a person whose preferred speed is `speed_mps`."""
    sc = params.section("scenarios", ScenariosSection)
    return {name: command_profile(name, segs, speed_mps, rate_hz, sc.profile)
            for name, segs in sc.build().items()}


__all__ = ["policy_body_is_current", "policy_job", "policy_setup", "replay_jobs", "replay_setup",
           "require_inputs", "scenario_jobs", "scenario_profiles"]
