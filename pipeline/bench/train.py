"""Bench section `train`: how fast the universal walking policy trains here, against its physics
(`sim.learn.throughput.measure`): raw `mj_step` of camargo's human, env steps of the pool of
bodies alone and training steps (PPO + AMP updates), on one env, on one env per core, and on
`train.n_envs` envs in the training process with the updates on every core (how a 2-core machine
trains), with the machine's core count; training resumes a copy of the run's committed checkpoint
(its own policy, statistics and discriminator) where there is one, else starts as the run did.
Target (issue 33): training at least 0.7 x the env-only rate
at the same env count, i.e. not update-bound."""

from __future__ import annotations

from pathlib import Path

from pipeline.params import Params
from pipeline.paths import POLICIES_ROOT, PROCESSED_ROOT, UNIVERSAL_DIR
from pipeline.runs.setup import train_params
from sim.learn.pool import UniversalParams
from sim.learn.throughput import measure
from sim.learn.train import PROGRESS_FILE
from sim.learn.universal import sources_of
from sim.rollout.scenarios import ScenariosSection

TRAIN_TARGETS = {"train_to_env_all": 0.7, "train_to_env_in_process": 0.7}


def time_training(params: Params, root: Path = PROCESSED_ROOT, policy_root: Path = POLICIES_ROOT,
                  universal_dir: Path | None = UNIVERSAL_DIR) -> dict:
    up = params.section("universal", UniversalParams)
    scenarios = params.section("scenarios", ScenariosSection).build()
    resume = universal_dir is not None and (universal_dir / PROGRESS_FILE).is_file()
    return measure(sources_of(up.subjects, root), up, train_params(params), scenarios,
                   init_from=str(policy_root / up.init_from), resume_from=universal_dir if resume else None)
