"""Bench section `train`: how fast the universal walking policy trains here, against its physics
(`sim.learn.throughput.measure`): raw `mj_step` of camargo's human, env steps of the pool of
bodies alone and training steps (PPO + AMP updates), on one env, on one env per core, and on
`train.n_envs` envs in the training process with the updates on every core (how a 2-core machine
trains), with the machine's core count. Target (issue 33): training at least 0.7 x the env-only rate
at the same env count, i.e. not update-bound."""

from __future__ import annotations

from pathlib import Path

from pipeline.params import Params
from pipeline.paths import POLICIES_ROOT, PROCESSED_ROOT
from pipeline.runs.setup import train_params
from sim.learn.pool import UniversalParams
from sim.learn.throughput import measure
from sim.learn.universal import sources_of
from sim.rollout.scenarios import ScenariosSection

TRAIN_TARGETS = {"train_to_env_all": 0.7, "train_to_env_in_process": 0.7}


def time_training(params: Params, root: Path = PROCESSED_ROOT, policy_root: Path = POLICIES_ROOT) -> dict:
    up = params.section("universal", UniversalParams)
    scenarios = params.section("scenarios", ScenariosSection).build()
    return measure(sources_of(up.subjects, root), up, train_params(params), scenarios,
                   init_from=str(policy_root / up.init_from))
