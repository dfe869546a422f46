"""A pool of bodies for the body-conditioned walking policy (sim/learn/universal.py): every bundled
subject's scaled human with its own reference cycle and bodies drawn around them
(`sim.learn.bodies`), one walking per episode, the body observation appended to the walking env's.
Bodies are picked half uniformly and half in proportion to how often each fell lately (Won & Lee
2019 sample bodies where control is still poor; here the falls are the measure), and now and then a
drawn body is replaced by a new draw. No torch here: `pipeline.params` checks `UniversalParams`.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields

import gymnasium as gym
import mujoco
import numpy as np
from pydantic import TypeAdapter, with_config

from sim.learn.bodies import (
    BODY_OBS_SIZE,
    BodyDraw,
    BodyScales,
    body_observation,
    draw_scales,
    scale_spec,
    similar_cycle,
)
from sim.learn.walk_env import OBS_SIZE, WalkEnv, WalkEnvParams, pd_servo_spec
from sim.motion.reference import ReferenceCycle, load_reference

UNIVERSAL_OBS_SIZE = OBS_SIZE + BODY_OBS_SIZE


@with_config(extra="forbid")
@dataclass(frozen=True)
class UniversalParams:
    """The `universal` section of params.yaml, where the values and their units are (one place)."""

    subjects: tuple[str, ...]            # bundled subjects whose bodies and cycles it trains on
    drawn: int                           # drawn bodies in each env's pool
    refresh_probability: float           # chance, at each episode, that a drawn body is replaced
    adaptive_share: float                # share of episodes on bodies picked by their recent falls
    fall_memory: float                   # weight of the newest episode in a body's fall rate
    motion_share: float                  # discriminator references from the recordings (sim.learn.universal)
    init_from: str                       # the single-body policy the run starts from
    critic_warmup_steps: int             # from `init_from`: only the value network learns at first
    gate_scenarios: tuple[str, ...]      # `sim.learn.universal.quick_gate`
    gate_seeds: int
    gate_speed_tolerance: float          # steady speed within +- this of the cycle's
    gate_standing_mps: float             # standing at the end: pelvis slower than this over the last second
    bodies: BodyDraw
    teachers: tuple[str, ...]            # committed single-body policies distilled on their own bodies
    teacher_weight: float                # its term's weight in PPO's loss (0: none)
    teacher_batch: int                   # teacher states per PPO optimizer step
    net_arch: tuple[int, ...] | None = None  # the run's hidden layers: narrower ones are widened (None: kept)
    env: dict = field(default_factory=dict)  # the training envs' values that differ from `train.env`'s
    min_action_std: float | None = None  # the policy's action std kept at or above this (None: free)
    bound_weight: float = 0.0            # the action-bound term's weight in PPO's loss (0: none)
    bound_batch: int = 256               # ... rollout states per PPO optimizer step
    learning_rate: float | None = None   # the run's PPO learning rate (None: `train.learning_rate`)

    @classmethod
    def from_dict(cls, d: dict) -> UniversalParams:
        known = {f.name: f for f in fields(cls)}
        out: dict = {}
        for k, v in d.items():
            if k not in known:
                raise KeyError(f"universal: unknown key {k!r}")
            if k == "bodies":
                names = {f.name for f in fields(BodyDraw)}
                if set(v) != names:
                    bad = sorted(set(v) - names) or sorted(names - set(v))
                    what = "unknown" if set(v) - names else "missing"
                    raise KeyError(f"universal.bodies: {what} key {bad[0]!r}")
                out[k] = BodyDraw(**{a: float(b) for a, b in v.items()})
            elif k == "net_arch":
                out[k] = None if v is None else tuple(int(x) for x in v)
            elif k in ("min_action_std", "learning_rate"):
                out[k] = None if v is None else float(v)
            elif k == "env":  # checked and typed as `train.env` is; only the values named are kept
                named = dict(v or {})
                bad = sorted(set(named) - {f.name for f in fields(WalkEnvParams)})
                if bad:
                    raise KeyError(f"universal.env: {bad[0]!r} is not a train.env key")
                typed = TypeAdapter(WalkEnvParams).validate_python(named)
                out[k] = {a: getattr(typed, a) for a in named}
            elif k in ("subjects", "gate_scenarios", "teachers"):
                out[k] = tuple(str(x) for x in v)
            elif k == "init_from":
                out[k] = str(v)
            elif k in ("drawn", "gate_seeds", "critic_warmup_steps", "teacher_batch", "bound_batch"):
                out[k] = int(v)
            else:
                out[k] = float(v)
        required = {f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING}
        missing = sorted(required - set(out))
        if missing:
            raise KeyError(f"universal: missing key {missing[0]!r}")
        return cls(**out)


@dataclass(frozen=True)
class Source:
    """A bundled subject's scaled human and reference motion (its cycle and whole recording)."""

    name: str
    xml: str
    reference_npz: str


def compile_body(xml: str, scales: BodyScales | None, p: WalkEnvParams) -> mujoco.MjModel:
    """The human of `xml`, scaled by `scales` (None: as it is), with the walking env's PD servos."""
    spec = mujoco.MjSpec.from_file(xml)
    if scales is not None:
        scale_spec(spec, scales)
    pd_servo_spec(spec, p)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    return spec.compile()


@dataclass
class Body:
    """One body of a pool: its walking env, body observation and recent fall rate."""

    source: str
    scales: BodyScales | None
    env: WalkEnv
    obs: np.ndarray
    fall_rate: float = 0.5


def make_body(src: Source, cycle: ReferenceCycle, scales: BodyScales | None, p: WalkEnvParams,
              seed: int | None) -> Body:
    """A `Body` of subject `src` (scaled by `scales`; None: the subject's own)."""
    model = compile_body(src.xml, scales, p)
    if scales is not None:
        cycle = similar_cycle(mujoco.MjModel.from_xml_path(src.xml), model, cycle)
    return Body(src.name, scales, WalkEnv(model, cycle, p, seed=seed), body_observation(model, cycle))


class MultiBodyEnv(gym.Env):
    """A pool of bodies, one walking per episode (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, sources: tuple[Source, ...], up: UniversalParams, p: WalkEnvParams, seed: int) -> None:
        self.sources, self.up, self.p = sources, up, p
        self.rng = np.random.default_rng(seed)
        self.cycles = {s.name: load_reference(s.reference_npz).cycle for s in sources}
        self.bodies = [make_body(s, self.cycles[s.name], None, p, seed) for s in sources]
        self.bodies += [self._draw(seed + 1 + i) for i in range(up.drawn)]
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (UNIVERSAL_OBS_SIZE,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (21,), np.float32)
        self.current = self.bodies[0]
        self._seed = seed + 1 + up.drawn

    def _draw(self, seed: int) -> Body:
        src = self.sources[int(self.rng.integers(len(self.sources)))]
        return make_body(src, self.cycles[src.name], draw_scales(self.rng, self.up.bodies), self.p, seed)

    def _pick(self) -> Body:
        n = len(self.bodies)
        falls = np.array([b.fall_rate for b in self.bodies]) + 1e-3
        prob = (1.0 - self.up.adaptive_share) / n + self.up.adaptive_share * falls / falls.sum()
        return self.bodies[int(self.rng.choice(n, p=prob / prob.sum()))]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        n_own = len(self.sources)
        if self.up.drawn and self.rng.random() < self.up.refresh_probability:
            i = n_own + int(self.rng.integers(self.up.drawn))
            self._seed += 1
            self.bodies[i] = self._draw(self._seed)
        self.current = self._pick()
        obs, info = self.current.env.reset(seed=seed, options=options)
        return np.concatenate([obs, self.current.obs]), info

    def step(self, action):
        obs, reward, fallen, truncated, info = self.current.env.step(action)
        if fallen or truncated:
            m = self.up.fall_memory
            self.current.fall_rate = (1 - m) * self.current.fall_rate + m * float(fallen)
            body = self.current.source if self.current.scales is None else "drawn"
            env = self.current.env
            phase = str(env.commands.phase[min(env.steps - 1, len(env.commands.phase) - 1)])  # as the gate
            info = {**info, "pool_episode": (body, bool(fallen), bool(env.pushes), phase)}
        return np.concatenate([obs, self.current.obs]), reward, fallen, truncated, info


__all__ = ["UNIVERSAL_OBS_SIZE", "Body", "MultiBodyEnv", "Source", "UniversalParams", "compile_body",
           "make_body"]
