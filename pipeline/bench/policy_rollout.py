"""Bench section `policy_rollout`: the policy-human rollout loop against raw `mj_step`.

One worker of the batch runner (`sim.rollout.batch.Worker`) runs camargo's committed policy human
walking with the `adaptive` controller for `duration_s`; the loop time (policy inference, PD
servos, robot control and recording included) is compared with raw `mj_step` of the same steps:
the same compiled world (a copy), from the rollout's initial state, with the inputs the rollout set
between its physics calls (the policy's and the drive's `ctrl`, and whatever else the loop or a
driver writes: applied forces, equality activation and data such as the arm lock, mocap, the model
fields a balance-loss event changes; `INPUTS`) written back at the same steps, each stretch between
two changes one `mj_step(model, data, nstep=k)` call with no other Python in between. That replay
reproduces the rollout's trajectory bit for bit (`baseline_reproduces_rollout`, checked on every
recorded sample, `baseline_max_qpos_diff` = 0.0; the bench raises otherwise), so the two timings
differ by exactly the loop's Python. Loop and replay are timed in adjacent pairs (median of the pair
ratios, `ratio_to_mj_step`). Target >= 0.8 (the closed-loop scenarios issue).

The inputs are recorded in an untimed run of the same job (`sim.rollout.loop.recording_steps`; a
rollout is a pure function of its job, and the timed run's samples are checked to equal the
recorded run's), so recording costs the timed loop nothing.

Why not the earlier baseline, kept as `raw_mj_step_fixed_controls_s` /
`ratio_to_mj_step_fixed_controls`: one `mj_step(nstep=n)` call from the initial state keeps the
initial controls, so the human does not walk (pelvis at 0.58 m after 10 s; 0.3 contacts a step
against the walk's 2.4, 15 constraint rows against 19): cheaper physics (~122 ms against ~140 ms of
thread time for the walk's own steps), not the same steps, and a ratio that charges the walk's
contacts to the loop's Python. Measured here under load (3 runs): `ratio_to_mj_step` 0.64-0.70 with
the replayed inputs, 0.56-0.60 with the fixed controls.

Where a 10 s walk's loop time goes (2-core machine, the other core training; measured 2026-11-26):
loop ~125 ms against ~100 ms of replayed physics. The Python: 334 policy steps ~15 ms (the forward
pass, plain numpy `sim.learn.policy_human.ActorMlp` in float32, ~11 us hot and ~14 us after the
physics has evicted its 0.3 MB of weights (float64 took ~15 / ~17 us); AMP features ~4 us,
observation ~3 us, the steered reference ~6 us, one lookup in a packed table; the servo targets
~2 us), the adaptive controller's 1000 ticks and its warm start's 500 ~7 ms, sensors, drive and
recording the rest. Batching the forward pass across rollouts run in lockstep would save a few ms a
walk at most, and a matrix product of a batch rounds differently from one vector's (1-2 ulp), so
trajectories would not stay bit-identical; not done.
"""

from __future__ import annotations

import copy
import time

import mujoco
import numpy as np

from ingest.subject import load_subject
from pipeline import paths
from pipeline.bench.rollout import raw_step_s
from pipeline.params import Params
from pipeline.runs.setup import batch_setup, train_params
from sim.rollout.batch import RolloutJob, Worker
from sim.rollout.loop import RolloutResult, recording_steps
from sim.rollout.section import RolloutSection

POLICY_ROLLOUT_TARGETS = {"ratio_to_mj_step": 0.8}
SUBJECT = "camargo"

# What a rollout may change between its physics calls: MuJoCo's user inputs (mjSTATE_USER) in
# MjData, and the MjModel fields the loop (`sim.robot.mrba.lock_arm`) and the drivers
# (`sim.body.balance_loss`) write.
INPUTS = (("data", "ctrl"), ("data", "qfrc_applied"), ("data", "xfrc_applied"), ("data", "eq_active"),
          ("data", "mocap_pos"), ("data", "mocap_quat"), ("data", "userdata"), ("model", "eq_data"),
          ("model", "geom_friction"), ("model", "geom_priority"), ("model", "actuator_forcerange"))

Program = list[tuple[int, list[tuple[np.ndarray, np.ndarray]]]]


class StepInputs:
    """Recorder for `sim.rollout.loop.recording_steps`: per `mj_step` call of a rollout, its number
    of steps and a copy of every input of `INPUTS` as the loop left it for those steps."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, list[np.ndarray]]] = []

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
        src = {"model": model, "data": data}
        self.calls.append((nstep, [getattr(src[o], f).copy() for o, f in INPUTS]))

    def program(self, model: mujoco.MjModel, data: mujoco.MjData) -> Program:
        """The calls as (nstep, writes) for `model` / `data` set to the rollout's initial state: a
        write (target array, values) only where the value differs bitwise from what it holds then."""
        dst = {"model": model, "data": data}
        targets = [getattr(dst[o], f) for o, f in INPUTS]
        held = [t.tobytes() for t in targets]
        out: Program = []
        for nstep, values in self.calls:
            writes = []
            for i, v in enumerate(values):
                if v.tobytes() != held[i]:
                    writes.append((targets[i], v))
                    held[i] = v.tobytes()
            out.append((nstep, writes))
        return out


def _replay_world(model: mujoco.MjModel, result: RolloutResult, inputs: StepInputs
                  ) -> tuple[mujoco.MjModel, mujoco.MjData, Program]:
    m = copy.copy(model)  # the replay's model writes (eq_data, ...) stay off the rollout's world
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, result.initial_state, mujoco.mjtState.mjSTATE_INTEGRATION)
    return m, d, inputs.program(m, d)


def replay_s(model: mujoco.MjModel, result: RolloutResult, inputs: StepInputs) -> tuple[float, np.ndarray]:
    """Seconds of raw `mj_step` replaying the recorded calls from `result`'s initial state, and
    the world qpos at the end."""
    m, d, program = _replay_world(model, result, inputs)
    step = mujoco.mj_step
    start = time.perf_counter()
    for nstep, writes in program:
        for target, values in writes:
            target[...] = values
        step(m, d, nstep=nstep)
    elapsed = time.perf_counter() - start
    return elapsed, d.qpos.copy()


def replayed_samples(model: mujoco.MjModel, result: RolloutResult, inputs: StepInputs,
                     steps_per_sample: int) -> np.ndarray:
    """World qpos of the replay at every output sample instant (untimed), the initial one first."""
    m, d, program = _replay_world(model, result, inputs)
    out, done = [d.qpos.copy()], 0
    for nstep, writes in program:
        for target, values in writes:
            target[...] = values
        mujoco.mj_step(m, d, nstep=nstep)
        done += nstep
        if done % steps_per_sample == 0:
            out.append(d.qpos.copy())
    return np.array(out)


def time_policy_rollout(params: Params, repeat: int = 3, duration_s: float = 10.0,
                        rate_hz: float = 100.0) -> dict:
    from sim.learn.policy_human import PolicySource, PolicyWalk
    from sim.learn.train import BODY_FILE

    folder = paths.policy_dir(paths.POLICIES_ROOT, SUBJECT)
    source = PolicySource(str(folder), train_params(params).env, rate_hz,
                          params.section("evaluate_policy.fall_height_fraction", float),
                          motor_noise=params.section("rollout", RolloutSection).policy_motor_noise)
    setup = batch_setup(params, SUBJECT, load_subject(SUBJECT).markerset, folder / BODY_FILE, source,
                        process=False)
    worker = Worker(setup)
    walls, replays, fixed = [], [], []
    max_diff, same_runs, calls = 0.0, True, 0
    for seed in range(repeat):
        job = RolloutJob("adaptive", seed, f"bench_seed{seed}", PolicyWalk(duration_s))
        inputs = StepInputs()
        with recording_steps(inputs):
            recorded = worker.run(job, keep_result=True).result
        out = worker.run(job, keep_result=True)  # timed: no recorder
        result = out.result
        seconds, end_qpos = replay_s(out.world, result, inputs)
        walls.append(result.wall_s)
        replays.append(seconds)
        fixed.append(raw_step_s(out.world, result))
        same_runs &= (np.array_equal(recorded.world_qpos, result.world_qpos)
                      and np.array_equal(recorded.initial_state, result.initial_state))
        per_sample = round(1.0 / (result.physics_dt_s * rate_hz))
        samples = replayed_samples(out.world, result, inputs, per_sample)
        n = len(result.world_qpos)
        if len(samples) < n:
            max_diff = float("inf")
        else:
            max_diff = max(max_diff, float(np.abs(samples[-n:] - result.world_qpos).max()),
                           float(np.abs(end_qpos - result.world_qpos[-1]).max()))
        calls = len(inputs.calls)
    reproduces = bool(same_runs and max_diff == 0.0)
    if not reproduces:
        raise RuntimeError(f"policy_rollout bench: replaying the rollout's inputs through mj_step does not "
                           f"reproduce it (max qpos difference {max_diff}, recorded run equals timed run: "
                           f"{same_runs}); an input the loop changes is not in INPUTS")
    walls_a, replays_a, fixed_a = np.array(walls), np.array(replays), np.array(fixed)
    return {"subject": SUBJECT, "controller": "adaptive", "duration_s": duration_s, "sample_rate_hz": rate_hz,
            "physics_steps": result.n_physics_steps, "rollout_loop_s": round(float(walls_a.min()), 4),
            "raw_mj_step_s": round(float(replays_a.min()), 4),
            "ratio_to_mj_step": round(float(np.median(replays_a / walls_a)), 3),
            "baseline": "the rollout's recorded inputs replayed through mj_step",
            "baseline_mj_step_calls": calls,
            "baseline_reproduces_rollout": reproduces, "baseline_max_qpos_diff": max_diff,
            "raw_mj_step_fixed_controls_s": round(float(fixed_a.min()), 4),
            "ratio_to_mj_step_fixed_controls": round(float(np.median(fixed_a / walls_a)), 3),
            "realtime_factor": round(duration_s / float(walls_a.min()), 1)}
