"""Bench section `train`: PPO training throughput (env steps per second) of the walking human with
the AMP callback, beside stable-baselines3 PPO on gymnasium's Humanoid-v5 measured in the same run,
same PPO settings, two environments in one process (DummyVecEnv), one torch thread (issue 6:
target ratio >= 0.8)."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv

from pipeline.params import Params
from pipeline.paths import PROCESSED_ROOT, human_xml, reference_npz
from sim.learn.amp import AMP, AMPCallback
from sim.learn.train import make_vec_env
from sim.learn.walk_env import AMP_SIZE, make_walk_env
from sim.motion.reference import load_reference

TRAIN_TARGETS = {"ratio_to_humanoid_v5": 0.8}


def _ppo(venv, p) -> PPO:
    return PPO("MlpPolicy", venv, n_steps=p.n_steps, batch_size=min(p.batch_size, p.n_steps * venv.num_envs),
               n_epochs=p.n_epochs, learning_rate=p.learning_rate, gamma=p.gamma, device="cpu", seed=0,
               policy_kwargs={"net_arch": {"pi": list(p.net_arch), "vf": list(p.net_arch)}})


def _rate(model: PPO, steps: int, callback=None) -> float:
    start = time.perf_counter()
    model.learn(total_timesteps=steps, callback=callback)
    return model.num_timesteps / (time.perf_counter() - start)


def time_training(params: Params, subject: str = "camargo", steps: int = 8192, n_envs: int = 2,
                  root: Path = PROCESSED_ROOT) -> dict:
    torch.set_num_threads(1)
    p = replace(params.train_params(), n_steps=1024)
    xml = human_xml(root, subject)
    cycle = load_reference(reference_npz(root, subject)).cycle
    walk = make_vec_env(xml, cycle, p, n_envs, subprocess=False)
    ref_env = make_walk_env(xml, cycle, p.env)
    rng = np.random.default_rng(0)
    amp = AMP(2 * AMP_SIZE, p.amp, lambda n: ref_env.ref.amp_pairs(rng, n, ref_env.step_phase))
    ours = _rate(_ppo(walk, p), steps, AMPCallback(amp, p.env.w_style, 6, lambda step, m: None))
    humanoid = DummyVecEnv([lambda: gym.make("Humanoid-v5") for _ in range(n_envs)])
    theirs = _rate(_ppo(humanoid, p), steps)
    walk.close()
    humanoid.close()
    return {"subject": subject, "n_envs": n_envs, "steps": steps, "walk_env_steps_per_s": round(ours, 1),
            "humanoid_v5_steps_per_s": round(theirs, 1), "ratio_to_humanoid_v5": round(ours / theirs, 3),
            "physics_substeps_per_env_step": {"walk_env": round(p.env.control_dt_s / 0.002),
                                              "humanoid_v5": 5}}
