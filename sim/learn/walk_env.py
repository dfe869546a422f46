"""Gymnasium environment: the subject-scaled 27-DoF human learning to walk like the subject.

Actions are residual PD targets on the phase-indexed reference pose (DeepMimic, Peng et al. 2018
ACM TOG 37:143; residual targets as in Park et al. 2019): each of the 21 joint motors becomes a
torque-limited PD servo (the motor's gear, i.e. the literature torque limit of `human`, is the force
range), so the PD law runs in MuJoCo's C step and implicit integration handles its damping. A ball
joint's three servos act on the components of its exponential-map (axis-angle) coordinates, which is
MuJoCo's ball-joint actuator length. Target = reference(phase) + `action_scale_rad` x action.

The human is steered (sim/learn/steering.py): every step has a command, forward speed and heading;
the reference is the cycle time-warped to the commanded speed and blended with quiet standing by
the gait amplitude. Training draws random command profiles (stand, start, walk, turn, change speed,
stop); a rollout passes a scenario's profile.

Observation (the human's own state only, heading-relative): pelvis height, pelvis orientation without
yaw (two rotation-matrix columns), yaw (sin, cos) relative to the commanded heading, pelvis linear
and angular velocity, the 21 joint coordinates and 21 joint velocities, feet relative to the pelvis,
gait phase (sin, cos), commanded speed, a 6-slot harness wrench (zeros when no robot is attached),
gait amplitude and commanded yaw rate.

Reward = w_imit x imitation (DeepMimic exponentials of pose, joint velocity, feet, pelvis height
and velocity errors against the steered reference) + w_task x task (speed along the commanded
heading, no lateral drift, times a heading term). The adversarial style reward (sim/learn/amp.py)
is added to the rollout buffer by the training callback; the env returns the AMP transition
features in `info["amp"]`.

Reference-state initialisation (quiet standing, or walking at a random phase), early termination
when the pelvis drops or the trunk tilts, and random horizontal pushes on the pelvis (magnitude,
duration and interval in params) for robustness, and optionally the follow-me robot's harness
twist (sim/learn/harness_twist.py). Everything in a step is preallocated numpy on MuJoCo's arrays;
the physics runs `n_substeps` steps in one `mj_step` call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import gymnasium as gym
import mujoco
import numpy as np
from pydantic import Field, with_config

from sim.body.human_params import ByName, JointValues, joint_kind
from sim.body.variant import Variant
from sim.errors import SimulationError
from sim.learn.harness_twist import HarnessTwist, TwistParams
from sim.learn.steering import (
    CommandSampling,
    SteeredReference,
    command_at,
    lead_heading,
    level_speed_ratio,
    sample_commands,
    speed_law,
    standing_pose,
    turn_lean_offset,
)
from sim.motion.reference import ReferenceCycle, blend_qpos
from sim.rollout.scenarios import CommandProfile, ProfileParams

SIDE_SUFFIXES = ("l", "r")  # the model's side suffixes (foot_l, foot_r)
HUMAN_ACTUATORS = ("lumbar_x", "lumbar_y", "lumbar_z", "hip_l_x", "hip_l_y", "hip_l_z", "hip_r_x", "hip_r_y",
                   "hip_r_z", "shoulder_l_x", "shoulder_l_y", "shoulder_l_z", "shoulder_r_x", "shoulder_r_y",
                   "shoulder_r_z", "knee_l", "knee_r", "ankle_l", "ankle_r", "elbow_l", "elbow_r")
OBS_SIZE = 74
LEGACY_OBS_SIZE = 72  # the straight-walking policies before steering (no amplitude, no yaw rate)
AMP_SIZE = 61


@with_config(extra="forbid")
@dataclass(frozen=True)
class Imitation(ByName):
    """One value per imitation term of the reward."""

    pose: float
    velocity: float
    feet: float
    height: float
    root_velocity: float


@with_config(extra="forbid")
@dataclass(frozen=True)
class WalkEnvParams:
    """Numbers of the walking environment (params `train.env`); units in names. `profile`, `variant` and
    the harness twist's spring are not read from params.yaml's `train.env`: `train_params` (pipeline)
    sets them from `scenarios.profile`, the cohort variant and `robot.harness`."""

    control_dt_s: float = 0.03             # 33 Hz policy (DeepMimic uses 30 Hz)
    action_scale_rad: float = 0.25          # residual PD target range around the reference
    pd_kp_nm_per_rad: JointValues = JointValues(lumbar=1000.0, hip=800.0, knee=800.0, ankle=600.0,
                                                shoulder=200.0, elbow=100.0)
    pd_kd_ratio_s: float = 0.1              # kd = ratio x kp (DeepMimic's humanoid gains: kd = kp / 10)
    episode_s: float = 10.0
    min_pelvis_height_fraction: float = 0.7  # terminate below this x the reference mean pelvis height
    max_tilt_deg: float = 60.0              # terminate when the trunk tilts further from vertical
    w_imitation: float = 0.6
    w_task: float = 0.2
    w_style: float = 0.2                    # applied by the AMP callback
    imitation_weights: Imitation = Imitation(pose=0.5, velocity=0.1, feet=0.15, height=0.1,
                                             root_velocity=0.15)
    imitation_scales: Imitation = Imitation(pose=2.0, velocity=0.02, feet=40.0, height=40.0,
                                            root_velocity=2.0)
    task_scale: float = 2.0                 # exp(-scale (dv_forward^2 + v_lateral^2))
    push_force_n: tuple[float, float] = (0.0, 250.0)
    push_duration_s: float = 0.2
    push_interval_s: tuple[float, float] = (1.0, 3.0)
    push_probability: float = 0.5           # share of episodes with pushes
    heading_scale: float = 2.0              # task x exp(-scale (1 - cos heading error))
    # the imitation term x this while a turn is commanded (the cycle walks straight; a turn departs from it)
    turn_imitation_scale: Annotated[float, Field(ge=0.0, le=1.0)] = 1.0
    harness_twist: TwistParams = field(default_factory=TwistParams)  # the robot's harness yaw load (off)
    commands: CommandSampling = field(default_factory=CommandSampling)
    profile: ProfileParams = field(default_factory=ProfileParams)  # the scenarios' transitions
    variant: Variant = field(default_factory=Variant)  # cohort variant: torque limits, speed, noise



def pd_servo_spec(spec: mujoco.MjSpec, p: WalkEnvParams) -> None:
    """Turn the human's joint motors into torque-limited PD servos (in place): gear -> unit axis,
    force range -> +-the motor's torque limit (x the cohort variant's factor), gain kp and bias
    (-kp, -kd) by joint kind."""
    for act in spec.actuators:
        gear = np.array(act.gear[:3], dtype=float)
        limit = float(np.linalg.norm(gear))
        if limit <= 0:
            raise SimulationError(spec.modelname or "human", f"actuator {act.name!r} has no gear")
        kind = joint_kind(act.target)
        kp = p.pd_kp_nm_per_rad[kind]
        act.gear = [*(gear / limit), 0.0, 0.0, 0.0]
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.gainprm = [kp] + [0.0] * 9
        act.biasprm = [0.0, -kp, -p.pd_kd_ratio_s * kp] + [0.0] * 7
        act.ctrllimited = False
        act.forcelimited = True
        act.forcerange = [-limit, limit]
    p.variant.scale_torques(spec)


AMP_LEVELS = (0.0, 0.25, 0.5, 0.75, 1.0)  # gait amplitudes of the AMP reference transitions
AMP_LEVEL_WEIGHTS = (0.2, 0.1, 0.1, 0.1, 0.5)  # standing, start / stop blends, walking


class ReferenceTable:
    """The periodic reference cycle turned into lookup tables on the model: actuator coordinates
    (`ctrl`), joint velocities, feet relative to the pelvis, pelvis height and velocity, and AMP
    features, each (N, .) at phase k/N; plus quiet standing (`stand_*`) and the AMP features of the
    standing-to-walking blend at the gait amplitudes `AMP_LEVELS`, each at the speed and cadence the
    speed law of `commands` gives it (sim/learn/steering.py)."""

    def __init__(self, model: mujoco.MjModel, cycle: ReferenceCycle,
                 commands: CommandSampling | None = None) -> None:
        commands = commands or CommandSampling()
        data = mujoco.MjData(model)
        n = len(cycle.phase)
        self.n, self.period_s, self.speed_mps = n, float(cycle.period_s), float(cycle.speed_mps)
        self.timestep_s = float(model.opt.timestep)  # the physics step these servos were tuned and trained at
        self.qpos, self.qvel = cycle.qpos.copy(), cycle.qvel.copy()
        self.ctrl = np.empty((n, model.nu))
        self.feet = np.empty((n, 6))
        idx = BodyIndex(model)
        self.stand_qpos = standing_pose(model, idx.feet)
        data.qpos[:], data.qvel[:] = self.stand_qpos, 0.0
        mujoco.mj_forward(model, data)
        self.stand_ctrl = data.actuator_length.copy()
        self.stand_feet = feet_in_heading(data, idx)
        self.stand_height = float(self.stand_qpos[2])
        self.amp_levels = np.empty((len(AMP_LEVELS), n, AMP_SIZE))
        law = (commands.full_gait_fraction, commands.stride_speed_exponent, commands.min_cadence)
        ratios = [level_speed_ratio(a, *law) for a in AMP_LEVELS]
        self.level_rate = np.array([speed_law(r, *law)[1] for r in ratios])  # phase rate per level
        for i, a in enumerate(AMP_LEVELS):
            for k in range(n):
                data.qpos[:] = blend_qpos(model, self.stand_qpos, cycle.qpos[k], a)
                data.qvel[:6] = cycle.qvel[k, :6] * ratios[i]  # the root at the level's speed,
                data.qvel[6:] = cycle.qvel[k, 6:] * (a * self.level_rate[i])  # joints: amplitude x cadence
                mujoco.mj_forward(model, data)
                amp_features(data, idx, self.amp_levels[i, k])
                if a == 1.0:
                    self.ctrl[k] = data.actuator_length
                    self.feet[k] = feet_in_heading(data, idx)
        self.amp = self.amp_levels[-1]
        # actuator-coordinate velocity of the cycle (periodic central differences)
        diff = np.roll(self.ctrl, -1, axis=0) - np.roll(self.ctrl, 1, axis=0)
        self.ctrl_vel = diff / (2 * self.period_s / n)
        self.height = cycle.qpos[:, 2].copy()
        self.root_vel = cycle.qvel[:, :3].copy()
        self.joint_vel = cycle.qvel[:, 6:].copy()
        self.start_phase = start_phase(self.feet, commands.first_step)
        self.steered = SteeredReference(self, self.stand_ctrl, self.stand_feet, self.stand_height)

    def index(self, phase: float) -> tuple[int, int, float]:
        """(k, k + 1 mod N, fraction) for linear interpolation at `phase` in [0, 1)."""
        x = (phase % 1.0) * self.n
        k = int(x)
        return k % self.n, (k + 1) % self.n, x - k

    def amp_pairs(self, rng: np.random.Generator, size: int, step_phase: float,
                  motion: np.ndarray | None = None, motion_share: float = 0.0) -> np.ndarray:
        """`size` reference transitions (features at phase and phase + the step's phase advance at
        the amplitude's phase rate), drawn over the gait amplitudes by `AMP_LEVEL_WEIGHTS`,
        (size, 2 x AMP). With `motion` (`motion_amp_pairs`), about `motion_share` of them are drawn
        from the recorded motion instead."""
        if motion is not None and len(motion) and motion_share > 0.0:
            m = int(rng.binomial(size, motion_share))
            return np.vstack([self.amp_pairs(rng, size - m, step_phase),
                              motion[rng.integers(0, len(motion), m)]])
        level = rng.choice(len(AMP_LEVELS), size, p=AMP_LEVEL_WEIGHTS)
        ph = rng.random(size)
        rate = self.level_rate[level]
        return np.hstack([self._interp(level, ph), self._interp(level, ph + step_phase * rate)])

    def _interp(self, level: np.ndarray, phase: np.ndarray) -> np.ndarray:
        x = (phase % 1.0) * self.n
        k = x.astype(int) % self.n
        f = (x - np.floor(x))[:, None]
        return self.amp_levels[level, k] * (1 - f) + self.amp_levels[level, (k + 1) % self.n] * f


class BodyIndex:
    """Ids the env reads every step: bodies, the human's root qpos / dof address, its 21 servos and
    its 21 joint dofs (a world with the robot attached has more of each)."""

    def __init__(self, model: mujoco.MjModel, root: str = "root") -> None:
        def body(name: str) -> int:
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            if i < 0:
                raise SimulationError("human model", f"no body {name!r}")
            return i
        self.pelvis = body("pelvis")
        self.torso = body("torso")
        self.feet = np.array([body(f"foot_{s}") for s in SIDE_SUFFIXES])
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, root)
        if j < 0:
            raise SimulationError("human model", f"no free joint {root!r}")
        self.root_q, self.root_d = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        act = mujoco.mjtObj.mjOBJ_ACTUATOR
        self.act = np.array([mujoco.mj_name2id(model, act, n) for n in HUMAN_ACTUATORS])
        if (self.act < 0).any():
            raise SimulationError("human model", f"missing motors {np.array(HUMAN_ACTUATORS)[self.act < 0]}")
        human_joints = [model.actuator_trnid[a, 0] for a in self.act]
        dofs = sorted({int(model.jnt_dofadr[jj]) + k for jj in human_joints
                       for k in range(3 if model.jnt_type[jj] == mujoco.mjtJoint.mjJNT_BALL else 1)})
        self.jdof = np.array(dofs)
        ball = mujoco.mjtJoint.mjJNT_BALL
        self.nq = 7 + sum(4 if model.jnt_type[jj] == ball else 1 for jj in set(human_joints))


def pelvis_yaw(data: mujoco.MjData, idx: BodyIndex) -> float:
    """The pelvis heading (rad, world yaw of its forward axis)."""
    xmat = data.xmat[idx.pelvis]
    return math.atan2(float(xmat[3]), float(xmat[0]))


def _heading(xmat_row: np.ndarray) -> tuple[float, float]:
    """(cos, sin) of the pelvis yaw from its rotation matrix (row-major 9)."""
    return _yaw_cs(float(xmat_row[0]), float(xmat_row[3]))


def _yaw_cs(c: float, s: float) -> tuple[float, float]:
    """(c, s) normalised to the unit circle (the yaw's cosine and sine from two matrix entries)."""
    norm = math.hypot(c, s) + 1e-9
    return c / norm, s / norm


def feet_in_heading(data: mujoco.MjData, idx: BodyIndex) -> np.ndarray:
    """Both feet relative to the pelvis in the pelvis heading frame, (6,)."""
    out = np.empty(3 * len(idx.feet))
    _feet_into(data, idx, *_heading(data.xmat[idx.pelvis]), out)
    return out


def _feet_into(data: mujoco.MjData, idx: BodyIndex, c: float, s: float, out: np.ndarray) -> None:
    """`feet_in_heading` into `out` for the pelvis heading (c, s), on Python floats (called every
    policy step: a dozen float operations, cheaper than numpy's per-call overhead)."""
    px, py, pz = data.xpos[idx.pelvis].tolist()
    row: list[float] = []
    for x, y, z in data.xpos[idx.feet].tolist():
        dx, dy = x - px, y - py
        row += (c * dx + s * dy, -s * dx + c * dy, z - pz)
    out[:] = row


def amp_features(data: mujoco.MjData, idx: BodyIndex, out: np.ndarray) -> None:
    """AMP state features (Peng et al. 2021 Sec. 6: root height, root rotation and velocities in the
    heading frame, joint coordinates and velocities, end effectors relative to the root) into `out`.
    The root terms are Python floats (the same operations numpy would do, without its per-call cost)."""
    r = data.xmat[idx.pelvis].tolist()  # row-major 3 x 3
    c, s = _yaw_cs(r[0], r[3])
    q, d = idx.root_q, idx.root_d
    v = data.qvel[d:d + 6].tolist()
    # rotation without yaw: Rz(-yaw) R, first two columns; root velocity in the heading frame, then
    # the free joint's angular velocity (already in the pelvis frame)
    out[:13] = (data.qpos[q + 2], c * r[0] + s * r[3], -s * r[0] + c * r[3], r[6],
                c * r[1] + s * r[4], -s * r[1] + c * r[4], r[7],
                c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2], v[3], v[4], v[5])
    nu = len(idx.act)
    out[13:13 + nu] = data.actuator_length[idx.act]
    out[13 + nu:13 + 2 * nu] = data.qvel[idx.jdof]
    _feet_into(data, idx, c, s, out[13 + 2 * nu:])


def motion_amp_features(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray,
                        z_shift_m: float = 0.0) -> np.ndarray:
    """`amp_features` of every frame of a motion, (T, AMP); `z_shift_m` raises the root (a floor
    alignment such as `ReferenceCycle.floor_shift_m`)."""
    data = mujoco.MjData(model)
    idx = BodyIndex(model)
    feats = np.empty((len(qpos), AMP_SIZE))
    for k in range(len(qpos)):
        data.qpos[:], data.qvel[:] = qpos[k], qvel[k]
        data.qpos[idx.root_q + 2] += z_shift_m
        mujoco.mj_forward(model, data)
        amp_features(data, idx, feats[k])
    return feats


def motion_amp_pairs(model: mujoco.MjModel, time_s: np.ndarray, qpos: np.ndarray, qvel: np.ndarray,
                     trial: np.ndarray, dt_s: float, z_shift_m: float = 0.0) -> np.ndarray:
    """AMP reference transitions from recorded (retargeted) motion, (M, 2 x AMP): the features of
    every frame paired with those `dt_s` later in the same trial (linear interpolation between
    frames). A subject's whole recording holds what its cycle cannot: quiet standing, starting,
    turning and stopping in its own style (Camargo's circuits turn 180 deg in two ~90 deg corners at
    1.3-1.8 m/s). `z_shift_m`: the cycle's floor alignment (`ReferenceCycle.floor_shift_m`), so the
    root height matches the cycle's."""
    feats = motion_amp_features(model, qpos, qvel, z_shift_m)
    pairs = []
    for name in dict.fromkeys(trial.tolist()):
        rows = np.flatnonzero(trial == name)
        t, f = time_s[rows], feats[rows]
        later = t + dt_s
        ok = later <= t[-1]
        if not ok.any():
            continue
        j = np.clip(np.searchsorted(t, later[ok], side="right") - 1, 0, len(t) - 2)
        w = ((later[ok] - t[j]) / (t[j + 1] - t[j]))[:, None]
        pairs.append(np.hstack([f[ok], f[j] * (1 - w) + f[j + 1] * w]))
    return np.vstack(pairs) if pairs else np.empty((0, 2 * AMP_SIZE))


class WalkEnv(gym.Env):
    """The walking task on one subject (module docstring). `model` must already carry the PD servos
    (`pd_servo_spec`); `cycle` is the subject's periodic reference cycle. `reset(options=...)` takes
    `commands` (a `CommandProfile` at the policy rate) for a fixed scenario, `phase` for the start
    phase and `pushes` to switch the random pushes off; without commands it draws random ones."""

    metadata = {"render_modes": []}

    def __init__(self, model: mujoco.MjModel, cycle: ReferenceCycle, p: WalkEnvParams,
                 seed: int | None = None) -> None:
        if model.nu != 21 or model.nv != 27:
            raise SimulationError("human model", f"expected 27 DoF / 21 motors, got {model.nv} / {model.nu}")
        self.model, self.p = model, p
        self.data = mujoco.MjData(model)
        self.n_sub = max(1, int(round(p.control_dt_s / model.opt.timestep)))
        self.dt = self.n_sub * model.opt.timestep
        self.ref = ReferenceTable(model, cycle, p.commands)
        self.idx = BodyIndex(model)
        self.step_phase = self.dt / self.ref.period_s
        self.max_steps = int(round(p.episode_s / self.dt))
        self.min_height = p.min_pelvis_height_fraction * float(self.ref.height.mean())
        self.min_up = float(np.cos(np.radians(p.max_tilt_deg)))
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (OBS_SIZE,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (model.nu,), np.float32)
        self.ctrl_lo, self.ctrl_hi = servo_ranges(model, np.arange(model.nu))
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
        self._torque_factor = np.array([p.variant.torque_factor(n) for n in names])
        self._variant_range = model.actuator_forcerange.copy()
        self.variant_weight = 1.0  # fine-tuning curriculum: 0 the healthy body and speed .. 1 the variant's
        self.wrench = np.zeros(6)
        self._obs = np.zeros(OBS_SIZE, np.float32)
        self._amp_prev = np.zeros(AMP_SIZE)
        self._amp_cur = np.zeros(AMP_SIZE)
        self.gait = GaitState(self.ref, p.commands)
        self.commands: CommandProfile | None = None
        self.steps = 0
        self.push_force = np.zeros(3)
        self.push_until = -1.0
        self.next_push = np.inf
        self.pushes = False
        self.twist: HarnessTwist | None = None
        self.np_random, _ = gym.utils.seeding.np_random(seed)

    @property
    def phase(self) -> float:
        return self.gait.phase

    # -- state ---------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        rng, options = self.np_random, options or {}
        d = self.data
        mujoco.mj_resetData(self.model, d)
        w, v0 = self.variant_weight, self.ref.speed_mps
        factor = (1.0 + (self._torque_factor - 1.0) * w) / self._torque_factor
        self.model.actuator_forcerange[:] = self._variant_range * factor[:, None]
        speed = v0 + (self.p.variant.preferred_speed(v0) - v0) * w
        self.commands = options.get("commands") or sample_commands(
            rng, speed, self.p.episode_s + 1.0, 1.0 / self.dt, self.p.commands, self.p.profile)
        phase = float(options["phase"]) if "phase" in options else float(rng.random())
        k = int(phase * self.ref.n) % self.ref.n
        self.gait.start(k / self.ref.n, *self._command(0))
        start_pose(self.ref, k, self.gait.a, d.qpos, d.qvel, d.ctrl, self.gait.speed_ratio)
        self.steps = 0
        self.pushes = bool(options.get("pushes", True)) and rng.random() < self.p.push_probability
        self.next_push = self._draw_interval() if self.pushes else np.inf
        self.push_until = -1.0
        self.wrench[:] = 0.0
        tw = self.p.harness_twist
        self.twist = None  # drawn only when on, so that training without it draws as before
        if tw.probability > 0 and bool(options.get("pushes", True)) and rng.random() < tw.probability:
            self.twist = HarnessTwist(tw, float(rng.uniform(*tw.lag_s)))
        mujoco.mj_forward(self.model, d)
        if self.twist is not None:
            self.twist.reset(pelvis_yaw(d, self.idx))
        amp_features(d, self.idx, self._amp_cur)
        return self._observe(), {}

    def _command(self, i: int) -> tuple[float, float, float]:
        """(speed, heading, yaw rate) of policy step `i` (the last command holds after the profile)."""
        return command_at(self.commands.speed_mps, self.commands.heading_rad, i, 1, self.dt)

    def _draw_interval(self) -> float:
        lo, hi = self.p.push_interval_s
        return self.data.time + float(self.np_random.uniform(lo, hi))

    def _push(self) -> None:
        d = self.data
        if d.time >= self.next_push:
            lo, hi = self.p.push_force_n
            mag = float(self.np_random.uniform(lo, hi))
            ang = float(self.np_random.uniform(0, 2 * np.pi))
            self.push_force[:] = mag * np.cos(ang), mag * np.sin(ang), 0.0
            self.push_until = d.time + self.p.push_duration_s
            self.next_push = self._draw_interval() + self.p.push_duration_s
        if d.time < self.push_until:
            d.xfrc_applied[self.idx.pelvis, :3] = self.push_force
        else:
            d.xfrc_applied[self.idx.pelvis, :3] = 0.0

    def step(self, action):
        d = self.data
        facing = pelvis_yaw(d, self.idx)
        self.gait.advance(self.step_phase, *self._command(self.steps + 1), facing)
        if self.p.variant.training_noise:
            noise = self.np_random.normal(0.0, self.p.variant.training_noise, self.model.nu)
            action = np.asarray(action) + noise
        d.ctrl[:] = self.gait.targets(action, self.p, self.ctrl_lo, self.ctrl_hi)
        if self.pushes:
            self._push()
        if self.twist is not None:
            d.xfrc_applied[self.idx.pelvis, 5] = self.twist.torque(facing, self.dt)
        self._amp_prev[:] = self._amp_cur
        mujoco.mj_step(self.model, d, nstep=self.n_sub)
        self.steps += 1
        amp_features(d, self.idx, self._amp_cur)
        reward, terms = self._reward()
        fallen = self.fallen()
        truncated = self.steps >= self.max_steps
        info = {"amp": np.concatenate([self._amp_prev, self._amp_cur]), "terms": terms}
        return self._observe(), (0.0 if fallen else reward), fallen, truncated and not fallen, info

    def fallen(self) -> bool:
        d = self.data
        return bool(d.qpos[2] < self.min_height or d.xmat[self.idx.torso, 8] < self.min_up
                    or not np.isfinite(d.qacc).all())

    def _reward(self) -> tuple[float, np.ndarray]:
        d, p, g = self.data, self.p, self.gait
        ctrl, _, joint_vel, feet, height, root_vel = g.reference
        e_pose = float(np.sum((d.actuator_length - ctrl) ** 2))
        e_vel = float(np.sum((d.qvel[6:] - joint_vel) ** 2))
        e_feet = float(np.sum((self._amp_cur[-6:] - feet) ** 2))
        e_h = float((d.qpos[2] - height) ** 2)
        ch, sh = np.cos(g.heading), np.sin(g.heading)
        v_fwd = ch * d.qvel[0] + sh * d.qvel[1]
        v_lat = -sh * d.qvel[0] + ch * d.qvel[1]
        e_rv = float((v_fwd - root_vel[0]) ** 2 + (v_lat - root_vel[1]) ** 2)
        c, s = _heading(d.xmat[self.idx.pelvis])
        heading_error = 1.0 - (c * ch + s * sh)
        sc, w = p.imitation_scales, p.imitation_weights
        terms = np.array([np.exp(-sc["pose"] * e_pose), np.exp(-sc["velocity"] * e_vel),
                          np.exp(-sc["feet"] * e_feet), np.exp(-sc["height"] * e_h),
                          np.exp(-sc["root_velocity"] * e_rv),
                          np.exp(-p.task_scale * ((v_fwd - g.speed) ** 2 + v_lat ** 2)
                                 - p.heading_scale * heading_error)])
        imitation = (w["pose"] * terms[0] + w["velocity"] * terms[1] + w["feet"] * terms[2]
                     + w["height"] * terms[3] + w["root_velocity"] * terms[4])
        if g.yaw_rate != 0.0:
            imitation *= p.turn_imitation_scale
        return float(p.w_imitation * imitation + p.w_task * terms[5]), terms

    def _observe(self) -> np.ndarray:
        observe(self.data, self.idx, self._amp_cur, self.gait, self.wrench, self._obs)
        return self._obs.copy()


class GaitState:
    """Where the steered reference is: phase, and the command it was advanced with (speed, heading,
    yaw rate) with its speed ratio, gait amplitude and phase rate under the speed law of `commands`
    (sim/learn/steering.py). One per walking human, in training and in rollouts alike."""

    def __init__(self, ref: ReferenceTable, commands: CommandSampling) -> None:
        self.ref = ref
        self.law = (commands.full_gait_fraction, commands.stride_speed_exponent, commands.min_cadence)
        self.turn_lean = commands.turn_lean
        self.lead_rad = None if commands.heading_lead_deg is None else math.radians(commands.heading_lead_deg)
        self.lean_law = (commands.turn_lean_time_constant_s, commands.max_lean_tan)
        self.lean_m = 0.0  # the feet's current lateral lean offset (`_look_up`)
        self.phase = self.speed = self.heading = self.yaw_rate = self.a = self.rate = self.speed_ratio = 0.0
        self.reference = ref.steered.at(0.0, 0.0, 0.0, 0.0)

    def _set(self, speed: float, heading: float, yaw_rate: float) -> None:
        self.speed, self.heading, self.yaw_rate = speed, heading, yaw_rate
        self.speed_ratio = speed / self.ref.speed_mps
        self.a, self.rate = speed_law(self.speed_ratio, *self.law)

    def start(self, phase: float, speed: float, heading: float, yaw_rate: float) -> None:
        """Start at `phase`; standing (no commanded speed) waits at the cycle's start phase."""
        self._set(speed, heading, yaw_rate)
        self.phase = self.ref.start_phase if self.a == 0.0 else phase % 1.0
        self.lean_m = 0.0
        self._look_up(None)

    def advance(self, step_phase: float, speed: float, heading: float, yaw_rate: float,
                facing: float) -> None:
        """One policy step: the phase moves by `step_phase` x the commanded speed ratio; while
        standing it waits at the cycle's start phase (the reference is the standing pose then).
        `facing`: the pelvis heading (rad), which the steered heading stays within the lead of when
        `CommandSampling.heading_lead_deg` is set."""
        if self.lead_rad is not None:
            heading = lead_heading(heading, facing, self.lead_rad)
        self._set(speed, heading, yaw_rate)
        phase = (self.phase + step_phase * self.rate) % 1.0
        self.phase = self.ref.start_phase if self.a == 0.0 else phase
        self._look_up(step_phase)

    def _look_up(self, step_phase: float | None) -> None:
        """The steered reference at the current phase and command; when `CommandSampling.turn_lean`
        is set, the feet lean into a turn, the offset moving toward the command's over the lean's
        time constant (a step of `step_phase`; None: at once)."""
        self.reference = self.ref.steered.at(self.phase, self.a, self.rate, self.speed_ratio)
        if self.turn_lean:
            feet, height = self.reference[3], self.reference[4]
            target = turn_lean_offset(height, self.speed, self.yaw_rate, self.turn_lean, self.lean_law[1])
            blend = 1.0 if step_phase is None else min(1.0, step_phase * self.ref.period_s / self.lean_law[0])
            self.lean_m += (target - self.lean_m) * blend
            feet[1] += self.lean_m  # feet are (x, y, z) left then right, in a fresh array
            feet[4] += self.lean_m

    def targets(self, action: np.ndarray, p: WalkEnvParams, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Servo inputs: the reference's actuator coordinates plus the scaled residual (clipped to
        the joint ranges), plus kd/kp x the reference velocity, so the affine servo acts as
        kp (q* - q) + kd (q*' - q')."""
        ctrl, ctrl_vel = self.reference[0], self.reference[1]
        target = p.action_scale_rad * np.asarray(action, dtype=float)
        target += ctrl  # np.clip's numbers in place, without its wrapper (a policy step's hot path)
        np.minimum(np.maximum(target, lo, out=target), hi, out=target)
        target += p.pd_kd_ratio_s * ctrl_vel
        return target


def start_phase(feet: np.ndarray, first_step: str = "left") -> float:
    """The phase a gait starts from and a stop ends at, from the cycle's feet relative to the pelvis
    (N, 6: left xyz, right xyz): the legs passing each other (feet closest fore-aft), mid-swing. From
    standing the blend then lifts the swinging foot forward, a first step; a pose with the feet apart
    would need them to slide apart on the floor. `first_step` "left": the crossing while the left
    foot swings (it is the higher); "either": the closer of the two crossings, which are often within
    millimetres of each other, so the side flips between cycles and bodies and one policy for every
    body would have to learn both starts (docs/policies.md)."""
    gap = np.abs(feet[:, 0] - feet[:, 3])
    if first_step == "left":
        gap[feet[:, 2] <= feet[:, 5]] = np.inf  # the right foot swings (or neither)
    elif first_step != "either":
        raise ValueError(f"first_step: 'left' or 'either', not {first_step!r}")
    return float(np.argmin(gap)) / len(feet)


def start_pose(ref: ReferenceTable, k: int, a: float, qpos: np.ndarray, qvel: np.ndarray,
               ctrl: np.ndarray, rate: float = 1.0) -> None:
    """Initial human state (in place, the human's own slices): quiet standing when the gait
    amplitude is 0, else the cycle at sample `k` (reference-state initialisation), at x = y = 0,
    its velocities x `rate` (the commanded / cycle speed ratio, so a walk commanded slower than the
    cycle does not start at the cycle's speed)."""
    if a == 0.0:
        qpos[:], qvel[:], ctrl[:] = ref.stand_qpos, 0.0, ref.stand_ctrl
    else:
        qpos[:], qvel[:], ctrl[:] = ref.qpos[k], ref.qvel[k] * rate, ref.ctrl[k]
    qpos[:2] = 0.0


def servo_ranges(model: mujoco.MjModel, act: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """PD-target limits of servos `act`: hinge ranges, +-pi for ball-joint components."""
    j = model.actuator_trnid[act, 0]
    lo, hi = model.jnt_range[j, 0].copy(), model.jnt_range[j, 1].copy()
    ball = model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE
    lo[ball], hi[ball] = -np.pi, np.pi
    return lo, hi


def observe(data: mujoco.MjData, idx: BodyIndex, amp: np.ndarray, gait: GaitState,
            wrench: np.ndarray, out: np.ndarray) -> None:
    """The policy observation (module docstring) into `out` (OBS_SIZE,), from the current AMP
    features `amp` of the state in `data` and the command in `gait`."""
    c, s = _heading(data.xmat[idx.pelvis])
    ch, sh = math.cos(gait.heading), math.sin(gait.heading)
    out[0:7] = amp[0:7]
    out[7], out[8] = s * ch - c * sh, c * ch + s * sh  # yaw relative to the commanded heading
    out[9:15] = amp[7:13]
    nu = len(idx.act)
    out[15:15 + 2 * nu] = amp[13:13 + 2 * nu]
    out[15 + nu:15 + 2 * nu] *= 0.1  # joint velocities to O(1)
    out[57:63] = amp[-6:]
    angle = 2 * math.pi * gait.phase  # math on Python floats: numpy's per-call cost is the larger
    out[63], out[64] = math.sin(angle), math.cos(angle)
    out[65] = gait.speed
    out[66:72] = wrench * 0.01
    out[72], out[73] = gait.a, gait.yaw_rate


def make_walk_env(model_path: str | Path, cycle: ReferenceCycle, p: WalkEnvParams,
                  seed: int | None = None) -> WalkEnv:
    """Compile the human at `model_path` with PD servos and wrap it in a `WalkEnv`."""
    spec = mujoco.MjSpec.from_file(str(model_path))
    pd_servo_spec(spec, p)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model = spec.compile()
    return WalkEnv(model, cycle, p, seed=seed)


__all__ = ["AMP_LEVELS", "AMP_SIZE", "HUMAN_ACTUATORS", "LEGACY_OBS_SIZE", "OBS_SIZE", "BodyIndex",
           "GaitState",
           "ReferenceTable", "WalkEnv", "WalkEnvParams", "amp_features", "feet_in_heading", "make_walk_env",
           "motion_amp_features", "motion_amp_pairs",
           "observe", "pd_servo_spec", "pelvis_yaw", "servo_ranges", "start_phase", "start_pose"]
