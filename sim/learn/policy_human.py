"""`PolicyHuman`: the torque-driven human walking under its trained policy (human mode ``policy``).

It implements the rollout's `HumanDriver` (sim/motion/driver.py), so `sim.rollout.loop.rollout`
runs it with or without the robot exactly as it runs the replay human. `prepare` turns the human's
motors into the same torque-limited PD servos as in training (`sim.learn.walk_env.pd_servo_spec`);
the human keeps its free root, its contacts and all its joints, so the harness and the robot act on
it physically.
The policy acts every `control_dt_s` (a multiple of the output sample period); between its
decisions the PD servos run inside MuJoCo's step.

The policy sees the human's own state only. The harness-wrench slot of the observation stays zero:
the committed policy was trained without the robot, so feeding it forces it never saw would be
extrapolation; the harness still pushes and pulls the body through the physics.

An optional scripted push (`Push`) applies a horizontal force at the pelvis for a duration (the
evaluation's 200 N / 0.2 s lateral push); nothing else acts on the body from outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from sim.errors import SimulationError
from sim.learn.walk_env import (
    AMP_SIZE,
    OBS_SIZE,
    BodyIndex,
    ReferenceTable,
    WalkEnvParams,
    amp_features,
    observe,
    pd_servo_spec,
)
from sim.motion.driver import HumanDriver
from sim.motion.reference import ReferenceCycle


@dataclass(frozen=True)
class Push:
    """A horizontal force `force_n` (x, y in the world) on the pelvis from `time_s` for `duration_s`."""

    time_s: float
    force_n: tuple[float, float]
    duration_s: float


class PolicyHuman(HumanDriver):
    """The trained walking policy driving the scaled human (module docstring).

    `policy(obs) -> action` maps a normalised-or-raw observation (the caller composes any
    normaliser into it) to the 21 residual actions in [-1, 1]. `human_model`: the human alone with
    its PD servos (`sim.learn.walk_env.make_walk_env(...).model`), for the reference tables."""

    mode = "policy"

    def __init__(self, policy, human_model: mujoco.MjModel, cycle: ReferenceCycle, p: WalkEnvParams,
                 duration_s: float,
                 start_phase: float = 0.0, push: Push | None = None, fall_height_fraction: float = 0.7,
                 root: str = "root") -> None:
        self.policy, self.cycle, self.p = policy, cycle, p
        self.duration_s = float(duration_s)
        self.start_phase, self.push, self.root = float(start_phase) % 1.0, push, root
        self.fall_height_fraction = fall_height_fraction
        k = int(self.start_phase * len(cycle.phase)) % len(cycle.phase)
        self.k0 = k
        self.fall_time_s: float | None = None
        self.ref = ReferenceTable(human_model, cycle)

    def prepare(self, spec: mujoco.MjSpec) -> None:
        pd_servo_spec(spec, self.p)

    def start_pose(self) -> tuple[np.ndarray, float]:
        q = self.cycle.qpos[self.k0]
        return np.array([0.0, 0.0, q[2]]), 0.0

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData, sample_times_s: np.ndarray) -> None:
        self.idx = BodyIndex(model, self.root)
        self.lo, self.hi = joint_ranges(model, self.idx)
        dt_sample = float(sample_times_s[1] - sample_times_s[0])
        self.every = max(1, int(round(self.p.control_dt_s / dt_sample)))
        self.control_dt = self.every * dt_sample
        self.step_phase = self.control_dt / self.ref.period_s
        self.times = sample_times_s
        q, d = self.idx.root_q, self.idx.root_d
        self.qslice = slice(q, q + self.idx.nq)
        data.qpos[self.qslice] = self.cycle.qpos[self.k0]
        data.qpos[q:q + 2] = 0.0
        data.qvel[d:d + 6] = self.cycle.qvel[self.k0, :6]
        data.qvel[self.idx.jdof] = self.cycle.qvel[self.k0, 6:]
        self.phase = self.k0 / self.ref.n
        self.amp = np.zeros(AMP_SIZE)
        self.obs = np.zeros(OBS_SIZE, np.float32)
        self.wrench = np.zeros(6)
        self.min_height = self.fall_height_fraction * float(self.ref.height.mean())
        self.min_up = float(np.cos(np.radians(self.p.max_tilt_deg)))
        self.qpos = np.zeros((len(sample_times_s), self.idx.nq))
        self.fall_time_s = None
        # the pelvis path the robot may expect at the start (sim.rollout.world.initial_speed reads `target`)
        self.target = np.column_stack([self.ref.speed_mps * sample_times_s, np.zeros(len(sample_times_s))])
        mujoco.mj_forward(model, data)
        data.ctrl[self.idx.act] = self.ref.ctrl[self.k0]

    def before_sample(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        if k % self.every == 0:
            amp_features(data, self.idx, self.amp)
            observe(data, self.idx, self.amp, self.phase, self.ref.speed_mps, self.wrench, self.obs)
            action = np.clip(np.asarray(self.policy(self.obs), float).reshape(-1), -1.0, 1.0)
            self.phase = (self.phase + self.step_phase) % 1.0
            data.ctrl[self.idx.act] = self._targets(action, self.phase)
        if self.push is not None:
            t = self.times[k]
            on = self.push.time_s <= t < self.push.time_s + self.push.duration_s
            data.xfrc_applied[self.idx.pelvis, :2] = self.push.force_n if on else (0.0, 0.0)

    def _targets(self, action: np.ndarray, phase: float) -> np.ndarray:
        k0, k1, f = self.ref.index(phase)
        g = 1 - f
        ref = self.ref.ctrl[k0] * g + self.ref.ctrl[k1] * f
        target = np.clip(ref + self.p.action_scale_rad * action, self.lo, self.hi)
        return target + self.p.pd_kd_ratio_s * (self.ref.ctrl_vel[k0] * g + self.ref.ctrl_vel[k1] * f)

    def record(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        self.qpos[k] = data.qpos[self.qslice]
        if self.fall_time_s is None and (data.qpos[self.idx.root_q + 2] < self.min_height
                                         or data.xmat[self.idx.torso, 8] < self.min_up):
            self.fall_time_s = float(self.times[k])

    def qpos_samples(self) -> np.ndarray:
        return self.qpos


def joint_ranges(model: mujoco.MjModel, idx: BodyIndex) -> tuple[np.ndarray, np.ndarray]:
    """PD-target limits per servo: hinge ranges, +-pi for ball-joint components (as in training)."""
    j = model.actuator_trnid[idx.act, 0]
    lo, hi = model.jnt_range[j, 0].copy(), model.jnt_range[j, 1].copy()
    ball = model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE
    lo[ball], hi[ball] = -np.pi, np.pi
    return lo, hi


def check_policy_io(n_obs: int, n_act: int) -> None:
    if n_obs != OBS_SIZE or n_act != 21:
        raise SimulationError("policy", f"policy expects {n_obs} observations / {n_act} actions, the "
                              f"walking human gives {OBS_SIZE} / 21")


@dataclass(frozen=True)
class PolicyWalk:
    """One policy-human job: a walk of `duration_s` from a random phase (the seed's), optionally
    with a lateral pelvis push of `push_n` (signed, world y) at `push_time_s`."""

    duration_s: float
    push_n: float = 0.0
    push_time_s: float = 0.0
    push_duration_s: float = 0.0


@dataclass(frozen=True)
class PolicySource:
    """Policy humans of one subject for the batch runner (`sim.rollout.batch.DriverSource`): the
    trained policy in `policy_dir` on its own body, sampled at `sample_rate_hz`."""

    policy_dir: str
    env: WalkEnvParams
    sample_rate_hz: float
    fall_height_fraction: float

    def open(self, world: mujoco.MjSpec):
        import torch

        from sim.learn.train import load_body, load_policy
        from sim.learn.walk_env import make_walk_env
        from sim.rollout.batch import HumanRun

        torch.set_num_threads(1)
        model, norm = load_policy(self.policy_dir)
        body_xml, cycle = load_body(self.policy_dir)
        pd_model = make_walk_env(str(body_xml), cycle, self.env).model

        def policy(obs: np.ndarray) -> np.ndarray:
            o = norm.normalize_obs(obs) if norm is not None else obs
            return model.predict(o, deterministic=True)[0]

        def make(walk: PolicyWalk, seed: int) -> HumanRun:
            rng = np.random.default_rng(seed)
            push = Push(walk.push_time_s, (0.0, walk.push_n), walk.push_duration_s) if walk.push_n else None
            human = PolicyHuman(policy, pd_model, cycle, self.env, walk.duration_s,
                                start_phase=float(rng.random()), push=push,
                                fall_height_fraction=self.fall_height_fraction)
            return HumanRun(human, self.sample_rate_hz, warm_speed_mps=cycle.speed_mps)

        return make
