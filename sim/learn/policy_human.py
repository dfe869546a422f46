"""`PolicyHuman`: the torque-driven human walking under its trained policy (human mode ``policy``).

It implements the rollout's `HumanDriver` (sim/motion/driver.py), so `sim.rollout.loop.rollout`
runs it with or without the robot exactly as it runs the replay human. `prepare` turns the human's
motors into the same torque-limited PD servos as in training (`sim.learn.walk_env.pd_servo_spec`);
the human keeps its free root, its contacts and all its joints, so the harness and the robot act on
it physically.
The policy acts every `control_dt_s` (a multiple of the output sample period); between its
decisions the PD servos run inside MuJoCo's step, which must step at the training timestep.
A scenario's commands (speed, heading per sample) steer it (`sim.learn.steering`); without them
it walks straight at its cycle's speed.

The policy sees the human's own state and its command only. The harness-wrench slot of the
observation stays zero: the committed policy was trained without the robot, so feeding it forces
it never saw would be extrapolation; the harness still pushes and pulls the body through the
physics.

An optional scripted balance-loss event (`sim.body.balance_loss`: trip, slip, collapse, or a push
such as the evaluation's 200 N / 0.2 s lateral one) acts at its onset; nothing else acts on the
body from outside.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from sim.body.balance_loss import BalanceLoss, BalanceLossRun, add_trip_constraints, steady_onset
from sim.errors import SimulationError
from sim.learn.bodies import BODY_OBS_SIZES, body_observation
from sim.learn.steering import command_at
from sim.learn.walk_env import (
    AMP_SIZE,
    LEGACY_OBS_SIZE,
    OBS_SIZE,
    SIDE_SUFFIXES,
    BodyIndex,
    GaitState,
    ReferenceTable,
    WalkEnvParams,
    amp_features,
    observe,
    pd_servo_spec,
    pelvis_yaw,
    servo_ranges,
    start_pose,
)
from sim.motion.driver import HumanDriver
from sim.motion.reference import ReferenceCycle
from sim.rollout.scenarios import CommandProfile, ProfileParams, Segment, command_profile

FEET = tuple(f"foot_{s}" for s in SIDE_SUFFIXES)  # the foot bodies, in `BodyIndex.feet` order


class PolicyHuman(HumanDriver):
    """The trained walking policy driving the scaled human (module docstring).

    `policy(obs) -> action` maps a normalised-or-raw observation (the caller composes any
    normaliser into it) to the 21 residual actions in [-1, 1]. `ref`: the reference tables of the
    human alone with its PD servos (`sim.learn.walk_env.make_walk_env(...).ref`; built once per
    worker, shared by its walks).
    `commands`: the scenario's per-sample commands at the rollout's sample rate (its length is the
    walk's); None walks straight at the cycle's speed for `duration_s`."""

    mode = "policy"

    def __init__(self, policy, ref: ReferenceTable, cycle: ReferenceCycle, p: WalkEnvParams,
                 duration_s: float, start_phase: float = 0.0, event: BalanceLoss | None = None,
                 fall_height_fraction: float = 0.7, root: str = "root",
                 commands: CommandProfile | None = None, seed: int = 0, motor_noise: float = 0.0) -> None:
        self.policy, self.cycle, self.p = policy, cycle, p
        # motor noise on the actions, seeded by the walk: `motor_noise` (every policy human's, so
        # seeds are distinct walks) and the variant's own (`Variant.action_noise`), independent
        self.noise = np.random.default_rng(seed)
        self.action_noise = float(np.hypot(motor_noise, p.variant.action_noise))
        self.commands = commands
        self.duration_s = float(duration_s if commands is None else commands.time_s[-1])
        self.start_phase, self.event, self.root = float(start_phase) % 1.0, event, root
        self.event_run: BalanceLossRun | None = None
        self.fall_height_fraction = fall_height_fraction
        k = int(self.start_phase * len(cycle.phase)) % len(cycle.phase)
        self.k0 = k
        self.fall_time_s: float | None = None
        self.ref = ref

    @property
    def standing_start(self) -> bool:
        return self.commands is not None and self.commands.speed_mps[0] == 0.0

    def prepare(self, spec: mujoco.MjSpec) -> None:
        pd_servo_spec(spec, self.p)
        if self.event is not None and self.event.kind == "trip":
            add_trip_constraints(spec, FEET, self.event.magnitude)

    def start_pose(self) -> tuple[np.ndarray, float]:
        z = self.ref.stand_height if self.standing_start else self.cycle.qpos[self.k0, 2]
        return np.array([0.0, 0.0, z]), 0.0

    def _commands_at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.commands is None:
            speed = self.p.variant.preferred_speed(self.ref.speed_mps)
            return np.full(len(times), speed), np.zeros(len(times))
        c = self.commands
        return np.interp(times, c.time_s, c.speed_mps), np.interp(times, c.time_s, c.heading_rad)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData, sample_times_s: np.ndarray) -> None:
        step_ms, trained_ms = model.opt.timestep * 1e3, self.ref.timestep_s * 1e3
        if abs(step_ms - trained_ms) > 1e-6:  # stiff PD servos: the policy knows one step only
            raise SimulationError("policy human", f"the world steps {step_ms:.3f} ms, the policy was trained "
                                  f"at {trained_ms:.3f} ms: sample at a rate whose period is a whole number "
                                  "of training steps (rollout.policy_sample_rate_hz)")
        self.idx = BodyIndex(model, self.root)
        self.lo, self.hi = servo_ranges(model, self.idx.act)
        dt_sample = float(sample_times_s[1] - sample_times_s[0])
        self.every = max(1, int(round(self.p.control_dt_s / dt_sample)))
        self.control_dt = self.every * dt_sample
        self.step_phase = self.control_dt / self.ref.period_s
        self.times = sample_times_s
        self.speed, self.heading = self._commands_at(sample_times_s)
        self.gait = GaitState(self.ref, self.p.commands)
        self.gait.start(self.k0 / self.ref.n, *self._command(0))
        q, d = self.idx.root_q, self.idx.root_d
        self.qslice = slice(q, q + self.idx.nq)
        qpos, qvel = np.empty(self.idx.nq), np.empty(6 + len(self.idx.jdof))
        ctrl = np.empty(len(self.idx.act))
        start_pose(self.ref, self.k0, self.gait.a, qpos, qvel, ctrl, self.gait.speed_ratio)
        data.qpos[self.qslice] = qpos
        data.qvel[d:d + 6] = qvel[:6]
        data.qvel[self.idx.jdof] = qvel[6:]
        self.amp = np.zeros(AMP_SIZE)
        self.obs = np.zeros(OBS_SIZE, np.float32)
        # the walk's motor noise, one row per policy step, drawn at once: the same numbers as a draw
        # per step (the generator fills an array element by element in order)
        n_steps = -(-(len(sample_times_s) - 1) // self.every)
        self.noise_rows = self.noise.normal(0.0, self.action_noise, (n_steps, len(self.idx.act))) \
            if self.action_noise else None
        self.wrench = np.zeros(6)
        self.min_height = self.fall_height_fraction * float(self.ref.height.mean())
        self.min_up = float(np.cos(np.radians(self.p.max_tilt_deg)))
        self.qpos = np.zeros((len(sample_times_s), self.idx.nq))
        self.fall_time_s = None
        # the commanded pelvis path (sim.rollout.world.initial_speed reads `target` for the robot)
        step = np.r_[0.0, self.speed[:-1] * dt_sample]
        self.target = np.column_stack([np.cumsum(step * np.cos(np.r_[0.0, self.heading[:-1]])),
                                       np.cumsum(step * np.sin(np.r_[0.0, self.heading[:-1]]))])
        mujoco.mj_forward(model, data)
        data.ctrl[self.idx.act] = ctrl
        if self.event is not None:
            self.event_run = BalanceLossRun(self.event, self.idx.pelvis, self.idx.feet, FEET, self.idx.act,
                                            lambda t: float(np.interp(t, sample_times_s, self.heading)))

    def _command(self, k: int) -> tuple[float, float, float]:
        """(speed, heading, yaw rate) commanded at sample `k` (held after the last sample)."""
        return command_at(self.speed, self.heading, k, self.every, self.control_dt)

    def before_sample(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        if k % self.every == 0:  # a policy step; falls are checked at the policy's rate (33 Hz)
            idx = self.idx
            if self.fall_time_s is None and (data.qpos[idx.root_q + 2] < self.min_height
                                             or data.xmat[idx.torso, 8] < self.min_up):
                self.fall_time_s = float(self.times[k])
            amp_features(data, idx, self.amp)
            observe(data, idx, self.amp, self.gait, self.wrench, self.obs)
            action = np.asarray(self.policy(self.obs), float).reshape(-1)
            action = np.minimum(np.maximum(action, -1.0), 1.0)  # np.clip's numbers, without its wrapper
            if self.noise_rows is not None:
                action = action + self.noise_rows[k // self.every]
            self.gait.advance(self.step_phase, *self._command(k + self.every), pelvis_yaw(data, idx))
            data.ctrl[idx.act] = self.gait.targets(action, self.p, self.lo, self.hi)
        if self.event_run is not None:
            self.event_run.apply(model, data, float(self.times[k]))

    def record(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        """Not called: the samples come from the world qpos (`from_world_qpos`)."""
        self.qpos[k] = data.qpos[self.qslice]

    def from_world_qpos(self, world_qpos: np.ndarray) -> None:
        self.qpos = world_qpos[:, self.qslice]

    def qpos_samples(self) -> np.ndarray:
        return self.qpos


def check_policy_io(folder: str, n_obs: int, n_act: int) -> None:
    """A policy fits the steered walking human: `OBS_SIZE` observations (a body-conditioned one
    that many followed by a body observation of one of `BODY_OBS_SIZES`, `BodyConditioned`), 21
    actions."""
    if n_obs - OBS_SIZE not in (0, *BODY_OBS_SIZES) or n_act != 21:
        hint = " (a straight walker from before steering: retrain with `--init-from`)" \
            if n_obs == LEGACY_OBS_SIZE else ""
        raise SimulationError(folder, f"policy expects {n_obs} observations / {n_act} actions, the "
                              f"walking human gives {OBS_SIZE} / 21{hint}")


@dataclass(frozen=True)
class ActorMlp:
    """The trained policy's deterministic action as plain numpy: observation normalisation
    (VecNormalize, in float64 as stable-baselines3 does it: (obs - mean) / sqrt(var + eps), clipped),
    then the ReLU MLP and the action layer in float32, the precision the policy was trained and is
    run in by torch. The numbers of stable-baselines3's `predict(deterministic=True)` up to float32
    summation order, without its per-call tensor and preprocessing overhead, which cost more than
    the physics between two policy steps; float32 halves the weights a policy step reloads after
    the physics has evicted them from the cache."""

    weights: tuple[np.ndarray, ...]  # float32
    biases: tuple[np.ndarray, ...]   # float32
    obs_mean: np.ndarray
    obs_scale: np.ndarray  # 1 / sqrt(var + eps)
    clip_obs: float

    @classmethod
    def from_sb3(cls, model, norm) -> ActorMlp:
        import torch

        layers = [m for m in model.policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
        layers.append(model.policy.action_net)
        n = model.observation_space.shape[0]
        mean = norm.obs_rms.mean if norm is not None else np.zeros(n)
        scale = 1.0 / np.sqrt(norm.obs_rms.var + norm.epsilon) if norm is not None else np.ones(n)
        return cls(tuple(np.ascontiguousarray(layer.weight.detach().numpy(), np.float32) for layer in layers),
                   tuple(np.ascontiguousarray(layer.bias.detach().numpy(), np.float32) for layer in layers),
                   np.asarray(mean, float), np.asarray(scale, float),
                   float(norm.clip_obs) if norm is not None else np.inf)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        # in place on the one array each product makes: the same operations as
        # clip((obs - mean) x scale), relu(w h + b) and clip(w h + b, -1, 1), fewer temporaries
        h = np.subtract(obs, self.obs_mean)
        h *= self.obs_scale
        np.minimum(np.maximum(h, -self.clip_obs, out=h), self.clip_obs, out=h)
        h = h.astype(np.float32)
        for w, b in zip(self.weights[:-1], self.biases[:-1], strict=True):
            h = w @ h
            h += b
            np.maximum(h, 0.0, out=h)
        h = self.weights[-1] @ h
        h += self.biases[-1]
        return np.minimum(np.maximum(h, -1.0, out=h), 1.0, out=h)


@dataclass(frozen=True)
class BodyConditioned:
    """A body-conditioned policy (sim/learn/universal.py) on one body: the walking human's
    observation followed by that body's `body_observation`."""

    policy: ActorMlp
    body: np.ndarray

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.policy(np.concatenate([obs, self.body]))


@dataclass(frozen=True)
class PolicyWalk:
    """One policy-human job: a walk of `duration_s` from a random phase (the seed's), or the
    scenario `scenario` (its commands set the length), optionally with a lateral pelvis push of
    `push_n` (signed, left of the heading) at `push_time_s`, or a balance-loss `event`; an event
    without an onset happens mid-way through the first steady phase, +- `event_jitter_s` by seed."""

    duration_s: float = 0.0
    push_n: float = 0.0
    push_time_s: float = 0.0
    push_duration_s: float = 0.0
    scenario: str | None = None
    event: BalanceLoss | None = None
    event_jitter_s: float = 0.0


@dataclass(frozen=True)
class PolicySource:
    """Policy humans of one subject for the batch runner (`sim.rollout.batch.DriverSource`): the
    trained policy in `policy_dir` on its own body, sampled at `sample_rate_hz`; `scenarios` name
    the command segments a `PolicyWalk` may ask for, `profile` their transitions."""

    policy_dir: str
    env: WalkEnvParams
    sample_rate_hz: float
    fall_height_fraction: float
    scenarios: dict[str, tuple[Segment, ...]] = field(default_factory=dict)
    profile: ProfileParams = field(default_factory=ProfileParams)
    motor_noise: float = 0.0  # std of the seeded noise on every walk's actions (`PolicyHuman`)

    def open(self, world: mujoco.MjSpec):
        import torch

        from sim.learn.train import load_body, load_policy, policy_env
        from sim.learn.walk_env import make_walk_env
        from sim.rollout.batch import HumanRun

        torch.set_num_threads(1)
        model, norm = load_policy(self.policy_dir)
        check_policy_io(self.policy_dir, model.observation_space.shape[0], model.action_space.shape[0])
        body_xml, cycle = load_body(self.policy_dir)
        env = policy_env(self.policy_dir, self.env)  # the speed law it was trained under
        walk_env = make_walk_env(str(body_xml), cycle, env)
        ref = walk_env.ref
        policy = ActorMlp.from_sb3(model, norm)
        n_body = model.observation_space.shape[0] - OBS_SIZE
        if n_body:  # the body values it was trained on (an export from before values were appended: fewer)
            policy = BodyConditioned(policy, body_observation(walk_env.model, cycle, n_body))

        def make(walk: PolicyWalk, seed: int) -> HumanRun:
            rng = np.random.default_rng(seed)
            commands = None
            if walk.scenario is not None:
                if walk.scenario not in self.scenarios:
                    raise SimulationError(f"scenario {walk.scenario!r}", f"not in params scenarios "
                                          f"({', '.join(self.scenarios)})")
                commands = command_profile(walk.scenario, list(self.scenarios[walk.scenario]),
                                           self.env.variant.preferred_speed(cycle.speed_mps),
                                           self.sample_rate_hz, self.profile)
            start_phase = float(rng.random())
            event = walk.event
            if walk.push_n:
                event = BalanceLoss("push", walk.push_duration_s, walk.push_n, walk.push_time_s)
            elif event is not None and event.onset_s is None:
                spans = commands.spans() if commands is not None else [("steady", 0.0, walk.duration_s)]
                event = event.at(steady_onset(spans, rng, walk.event_jitter_s))
            human = PolicyHuman(policy, ref, cycle, env, walk.duration_s,
                                start_phase=start_phase, event=event,
                                fall_height_fraction=self.fall_height_fraction, commands=commands, seed=seed,
                                motor_noise=self.motor_noise)
            v0 = self.env.variant.preferred_speed(cycle.speed_mps) if commands is None \
                else float(commands.speed_mps[0])
            return HumanRun(human, self.sample_rate_hz, warm_speed_mps=v0 if v0 > 0 else None)

        return make
