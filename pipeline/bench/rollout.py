"""Benchmark of replay rollouts (part of `python -m pipeline bench`).

- `ratio_to_mj_step`: raw `mj_step` time for the rollout's number of physics steps on the same
  human+robot model (from the rollout's exact initial state, `RolloutResult.initial_state`, one
  `mj_step(nstep)` call, no Python in between) divided by the rollout's loop time; 1.0 would mean
  zero Python overhead. Rollout and raw run are timed in adjacent pairs and the median of the pair
  ratios is reported (the CPU is shared, so far-apart timings would compare different loads).
  Target >= 0.8 (issue 4). The controller runs at `robot.base.control_rate_hz`, the output at
  `rate_hz` (sim/rollout/loop.py).
- `realtime_factor`: simulated seconds per wall second of one rollout.
- `parallel_speedup`: wall time of `n_parallel` rollouts (each with its world build) run by the
  batch runner (`sim.rollout.batch`, as `simulate` runs them) in this process, over the same
  rollouts in its 2-process pool (both cores) whose workers have started (a warm-up map first:
  process start and imports are paid once per `simulate` run, not per rollout).

The world is the camargo human (data/processed/camargo/model/human.xml) when it exists, else the
capsule world of sim.motion.synthetic; the human replays the synthetic tuning walk; controller
`adaptive`.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from pipeline.params import Params
from pipeline.paths import PROCESSED_ROOT, human_xml
from pipeline.runs.setup import batch_setup, controller_specs
from sim.motion.replay import Motion, ReplayHuman
from sim.motion.synthetic import capsule_world, synthetic_walk
from sim.robot.controllers import make_controller
from sim.robot.section import RobotSection
from sim.rollout.batch import BatchRunner, RolloutJob
from sim.rollout.loop import RolloutParams, RolloutResult, rollout
from sim.rollout.section import RolloutSection
from sim.rollout.world import build_world, robot_info

TARGETS = {"ratio_to_mj_step": 0.8}
HUMAN_XML = human_xml(PROCESSED_ROOT, "camargo")


def _setup(params: Params, rate_hz: float):
    section = params.section("robot", RobotSection)
    robot, replay = section.build(), params.section("rollout", RolloutSection).replay
    walk = section.tuning.walk
    if HUMAN_XML.exists():
        spec = mujoco.MjSpec.from_file(str(HUMAN_XML))
        m0 = spec.copy().compile()
        w = synthetic_walk(walk)
        qpos = np.tile(m0.qpos0, (len(w.time_s), 1))
        qpos[:, :7] = w.qpos
        qpos[:, 2] += m0.qpos0[2] - walk.pelvis_height_m
        motion, world = Motion(w.time_s, qpos), "camargo human"
    else:
        spec, motion = capsule_world(walk.mass_kg, walk.pelvis_height_m), synthetic_walk(walk)
        world = "capsule"
    ctrl = make_controller(controller_specs(params)["adaptive"], robot_info(robot))
    return spec, ReplayHuman(motion, replay), ctrl, RolloutParams(robot=robot, sample_rate_hz=rate_hz), world


@dataclass(frozen=True)
class SyntheticSource:
    """The bench's human for the batch runner: the replayed synthetic tuning walk."""

    params: Params
    rate_hz: float

    def open(self, world: mujoco.MjSpec):
        from sim.rollout.batch import HumanRun

        _, human, _, _, _ = _setup(self.params, self.rate_hz)
        return lambda job, seed: HumanRun(ReplayHuman(human.motion, human.p), self.rate_hz)


def raw_step_s(model: mujoco.MjModel, result: RolloutResult) -> float:
    """Seconds of raw `mj_step` for `result`'s physics steps from its initial state, in one call."""
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, result.initial_state, mujoco.mjtState.mjSTATE_INTEGRATION)
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=result.n_physics_steps)
    return time.perf_counter() - start


def run_rollout_bench(params: Params, rate_hz: float = 200.0, repeat: int = 9, n_parallel: int = 8) -> dict:
    spec, human, ctrl, p, world = _setup(params, rate_hz)
    model = build_world(spec, human, p)
    walls, raws = [], []
    for seed in range(repeat):
        result = rollout(spec, human, ctrl, p, seed, model=model)
        raws.append(raw_step_s(model, result))
        walls.append(result.wall_s)
    walls_a, raws_a = np.array(walls), np.array(raws)
    best, raw = float(walls_a.min()), float(raws_a.min())
    with tempfile.TemporaryDirectory() as tmp:
        xml = Path(tmp) / "world.xml"
        xml.write_text(spec.to_xml())
        setup = batch_setup(params, "bench", {}, xml, SyntheticSource(params, rate_hz), process=False)
        jobs = [RolloutJob("adaptive", s, f"bench_seed{s}", None) for s in range(n_parallel)]
        start = time.perf_counter()
        with BatchRunner(setup, workers=1) as runner:
            runner.map(jobs)
        sequential = time.perf_counter() - start
        with BatchRunner(setup, workers=2) as runner:
            runner.map(jobs[:2])  # workers started and imports done, as in a long simulate run
            start = time.perf_counter()
            runner.map(jobs)
            parallel = time.perf_counter() - start
    out = {"world": world, "sample_rate_hz": rate_hz, "control_rate_hz": p.control_rate_hz,
           "physics_dt_s": result.physics_dt_s,
           "physics_steps": result.n_physics_steps, "rollout_loop_s": round(best, 4),
           "raw_mj_step_s": round(raw, 4), "ratio_to_mj_step": round(float(np.median(raws_a / walls_a)), 3),
           "ratio_of_best_times": round(raw / best, 3),
           "realtime_factor": round(float(result.time_s[-1]) / best, 1),
           "parallel_speedup": round(sequential / parallel, 2), "targets": TARGETS}
    out["meets_targets"] = all(out[k] >= v for k, v in TARGETS.items())
    return out
