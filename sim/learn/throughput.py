"""How fast the universal policy trains on this machine, against what its physics allows.

Three rates, each measured here in one run: raw `mj_step` of a subject's human (one process, and
one process per core side by side), env steps of the pool of bodies alone (random actions, no
learning) and training (PPO + AMP updates included), each on one env and on `n_envs` worker
processes (the updates then on every core while the workers wait, as the run's `--subprocess
--threads` trains). A third configuration: `in_process_envs` envs stepped in the training process
itself, the updates on every core (`UpdateThreads`). Training is update-bound when its rate is
well below the env-only one at the same env count; the ratio is what `python -m pipeline bench`
holds to its target.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import replace
from functools import partial
from multiprocessing import get_context
from pathlib import Path

import mujoco
import numpy as np
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

from sim.learn.pool import Source, UniversalParams
from sim.learn.train import TrainParams
from sim.learn.universal import copy_checkpoint, make_pool_env, train_universal
from sim.learn.vec import GroupedSubprocVecEnv
from sim.rollout.scenarios import Segment


def _mj_steps(xml: str, seconds: float) -> float:
    model = mujoco.MjModel.from_xml_path(xml)
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=100)
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        mujoco.mj_resetData(model, data)
        mujoco.mj_step(model, data, nstep=500)
        n += 500
    return n / (time.perf_counter() - start)


def raw_step_rate(xml: str, processes: int, seconds: float = 2.0) -> float:
    """`mj_step` per second of the human in `xml`, summed over `processes` processes side by side.
    Spawned, not forked: a forked worker inherits the parent's signal handlers (Ray's, a trainer's),
    and one that catches SIGTERM without exiting hangs the pool's terminate."""
    if processes == 1:
        return _mj_steps(xml, seconds)
    with get_context("spawn").Pool(processes) as pool:
        return float(sum(pool.starmap(_mj_steps, [(xml, seconds)] * processes)))


def env_step_rate(sources: tuple[Source, ...], up: UniversalParams, p: TrainParams, n_envs: int,
                  steps: int, workers: int | None = None, in_process: bool = False) -> float:
    """Env steps per second of `n_envs` pools of bodies (in `workers` processes, default one per
    env, when more than one and not `in_process`), random actions, resets included."""
    fns = [partial(make_pool_env, sources, up, p.env, 100 + i) for i in range(n_envs)]
    venv = GroupedSubprocVecEnv(fns, workers or n_envs) if n_envs > 1 and not in_process else DummyVecEnv(fns)
    rng = np.random.default_rng(0)
    venv.reset()
    venv.step(rng.uniform(-1, 1, (n_envs, 21)).astype(np.float32))
    start, n = time.perf_counter(), 0
    while n < steps:
        venv.step(rng.uniform(-1, 1, (n_envs, 21)).astype(np.float32))
        n += n_envs
    rate = n / (time.perf_counter() - start)
    venv.close()
    return rate


Scenarios = dict[str, list[Segment]]


def train_step_rate(sources: tuple[Source, ...], up: UniversalParams, p: TrainParams, scenarios: Scenarios,
                    n_envs: int, steps: int, device: str, init_from: str | None,
                    workers: int | None = None, in_process: bool = False, threads: int = 1,
                    resume_from: str | Path | None = None) -> float:
    """Training env steps per second (PPO + AMP updates on `threads` torch threads) with `n_envs`
    envs (in `workers` processes, default one per env, when more than one and not `in_process`),
    no gate: from `init_from` as the run started, or resuming a copy of the run's checkpoint in
    `resume_from` (its policy, statistics, discriminator and progress record), as the run goes on."""
    with tempfile.TemporaryDirectory() as tmp:
        start = 0
        if resume_from is not None:
            start = int(copy_checkpoint(resume_from, tmp)["steps"])
        rec = train_universal(sources, replace(p, checkpoint_steps=10 ** 12), up, tmp, scenarios,
                              init_from=None if resume_from is not None else init_from,
                              resume=resume_from is not None, total_steps=start + steps, n_envs=n_envs,
                              subprocess=n_envs > 1 and not in_process, device=device, gate=False,
                              workers=workers, threads=threads)
    return float(rec["runs"][-1]["steps_per_s"])


def measure(sources: tuple[Source, ...], up: UniversalParams, p: TrainParams, scenarios: Scenarios, *,
            n_envs: int | None = None, device: str = "auto", init_from: str | None = None,
            env_steps: int = 4000, train_steps: int = 8192, envs_per_worker: int = 1,
            in_process_envs: int | None = None, resume_from: str | Path | None = None) -> dict:
    """The three rates on 1 env, on `n_envs` (default: every core) worker processes of
    `envs_per_worker` envs each, and on `in_process_envs` (default `p.n_envs`) envs in the training
    process; the updates of the last two on every core (module docstring). Training starts from
    `init_from`, or resumes a copy of the run's checkpoint in `resume_from` (`train_step_rate`)."""
    cores = os.cpu_count() or 1
    n = n_envs or cores
    up = replace(up, refresh_probability=0.0)
    out: dict = {"cpu_count": cores, "workers": n, "envs_per_worker": envs_per_worker, "device": device,
                 "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
                 **({"resumed_from": str(resume_from)} if resume_from is not None else
                    {"initialised_from": str(init_from)})}
    m = in_process_envs or p.n_envs
    out["in_process_envs"], out["update_threads"] = m, cores
    # label, processes stepping the envs (None: the training process), envs, torch threads of the update
    # (every core where the env workers wait out the update, as the run's `--threads` does)
    for label, k, envs, threads in (("one", 1, 1, 1), ("all", n, n * envs_per_worker, cores),
                                    ("in_process", None, m, cores)):
        if k is not None:  # the physics' own rate over as many processes
            out[f"mj_step_per_s_{label}"] = round(raw_step_rate(sources[0].xml, k), 1)
        out[f"env_steps_per_s_{label}"] = round(
            env_step_rate(sources, up, p, envs, env_steps * envs, k, in_process=k is None), 1)
        out[f"train_steps_per_s_{label}"] = round(
            train_step_rate(sources, up, p, scenarios, envs, max(train_steps * envs, p.n_steps * envs * 2),
                            device, init_from, k, in_process=k is None, threads=threads,
                            resume_from=resume_from), 1)
        ratio = out[f"train_steps_per_s_{label}"] / out[f"env_steps_per_s_{label}"]
        out[f"train_to_env_{label}"] = round(ratio, 3)
    out["env_scaling"] = round(out["env_steps_per_s_all"] / out["env_steps_per_s_one"], 2)
    return out


def main(argv: list[str] | None = None) -> int:
    """`python -m sim.learn.throughput`: `measure` on this machine, printed and written as JSON."""
    import argparse

    from sim.learn.universal import params_from_yaml, sources_of

    ap = argparse.ArgumentParser(prog="python -m sim.learn.throughput", description=measure.__doc__)
    ap.add_argument("--params", type=Path, default=Path("params.yaml"))
    ap.add_argument("--processed", type=Path, default=Path("data/processed"))
    ap.add_argument("--init-from", default="data/policies/camargo")
    ap.add_argument("--resume-from", type=Path, default=None,
                    help="a copy of the run's checkpoint in this folder resumed instead (data/universal)")
    ap.add_argument("--n-envs", type=int, default=None)
    ap.add_argument("--device", default="auto")
    ap.add_argument("--train-steps", type=int, default=8192)
    ap.add_argument("--envs-per-worker", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    p, up, scenarios = params_from_yaml(args.params)
    doc = measure(sources_of(up.subjects, args.processed), up, p, scenarios, n_envs=args.n_envs,
                  device=args.device, init_from=args.init_from, train_steps=args.train_steps,
                  envs_per_worker=args.envs_per_worker, resume_from=args.resume_from)
    text = json.dumps(doc, indent=1)
    print(text, flush=True)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = ["env_step_rate", "measure", "raw_step_rate", "train_step_rate"]
