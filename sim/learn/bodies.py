"""Bodies around a subject's: segment lengths and masses drawn within a range, and the reference
cycle such a body walks by dynamic similarity.

A body-conditioned walking policy learns one controller for many bodies (Won & Lee 2019, "Learning
body shape variation in physics-based characters", ACM TOG 38:207). Here a body is a bundled
subject's scaled human with each segment's length x a factor and its mass x another (`BodyScales`,
left and right alike), the motor torque limits x mass x length (torque ~ m g L), and the subject's
reference cycle carried over by dynamic similarity (Alexander & Jayes 1983, J Zool 201:135): the
same joint angles, stride x the leg-length ratio lambda, time x sqrt(lambda), so speed x
sqrt(lambda) (equal Froude number). The policy sees the body through `body_observation`: log
ratios of standing height, mass, leg length, cycle speed and cycle period to a nominal adult, then
where the standing body's centre of mass lies fore-aft of the ankles and of the pelvis, per leg
length (bodies alike in the first five can need different balance: a subject's upper body leaning
back puts it behind the ankles). Values are only ever appended: a policy trained on the first n
(`BODY_OBS_SIZES`) reads the first n.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np
from pydantic import with_config

from sim.body.human import standing_height
from sim.learn.steering import geom_bottom, standing_pose, subtree
from sim.learn.walk_env import SIDE_SUFFIXES
from sim.motion.reference import ReferenceCycle

SEGMENTS = ("pelvis", "torso", "head", "upper_arm", "forearm", "thigh", "shank", "foot")
# nominal adult the body observation is relative to (about the bundled subjects' middle)
NOMINAL = {"height_m": 1.70, "mass_kg": 70.0, "leg_length_m": 0.85, "speed_mps": 1.25, "period_s": 1.10}
BALANCE = ("com_ahead_of_ankles", "com_ahead_of_pelvis")  # standing, / leg length (appended to NOMINAL's)
BODY_OBS_SIZE = len(NOMINAL) + len(BALANCE)
BODY_OBS_SIZES = (len(NOMINAL), BODY_OBS_SIZE)  # every body observation a policy has been trained on


@dataclass(frozen=True)
class BodyScales:
    """Length and mass factors per segment (`SEGMENTS`), both sides alike."""

    length: tuple[float, ...] = (1.0,) * len(SEGMENTS)
    mass: tuple[float, ...] = (1.0,) * len(SEGMENTS)

    @classmethod
    def uniform(cls, length: float, mass: float) -> BodyScales:
        """Every segment scaled alike (a geometric scaling when mass = length^3)."""
        return cls((length,) * len(SEGMENTS), (mass,) * len(SEGMENTS))

    def factor(self, body_name: str) -> tuple[float, float] | None:
        """(length, mass) factors of a body of the human (None: not a segment)."""
        seg = body_name
        for s in SIDE_SUFFIXES:
            seg = seg.removesuffix(f"_{s}")
        if seg not in SEGMENTS:
            return None
        i = SEGMENTS.index(seg)
        return self.length[i], self.mass[i]


@with_config(extra="forbid")
@dataclass(frozen=True)
class BodyDraw:
    """How far drawn bodies stray from their subject's (params `universal.bodies`): a whole-body
    factor within +-`range` for lengths and another for mass, times a per-segment one within
    +-`segment_jitter`, each factor clipped to +-`range`."""

    range: float
    segment_jitter: float


def draw_scales(rng: np.random.Generator, p: BodyDraw) -> BodyScales:
    """A random body around a subject's (`BodyDraw`)."""
    lo, hi = 1.0 - p.range, 1.0 + p.range
    n = len(SEGMENTS)
    g_len, g_mass = rng.uniform(lo, hi, 2)
    jit = rng.uniform(1.0 - p.segment_jitter, 1.0 + p.segment_jitter, (2, n))
    length = np.clip(g_len * jit[0], lo, hi)
    mass = np.clip(g_mass * jit[1], lo, hi)
    return BodyScales(tuple(float(x) for x in length), tuple(float(x) for x in mass))


def _scale3(v: np.ndarray, f: float) -> list[float]:
    return [float(x) * f for x in v]


def scale_spec(spec: mujoco.MjSpec, s: BodyScales) -> None:
    """Scale the human in `spec` in place (module docstring): inside each segment's frame every
    position (child bodies, geoms, sites, centre of mass) and geom size x its length factor, its
    mass x its mass factor and its inertia x mass x length^2; motor gears (torque limits) x the
    whole body's mass factor x its mean leg length factor."""
    total = sum(b.mass for b in spec.bodies)
    for b in spec.bodies:
        f = s.factor(b.name)
        if f is None:
            continue
        fl, fm = f
        for child in b.bodies:
            child.pos = _scale3(child.pos, fl)
        for g in b.geoms:
            g.pos = _scale3(g.pos, fl)
            g.size = _scale3(g.size, fl)
            if np.all(np.isfinite(g.fromto)):
                g.fromto = _scale3(g.fromto, fl)
        for site in b.sites:
            site.pos = _scale3(site.pos, fl)
        b.ipos = _scale3(b.ipos, fl)
        b.mass = float(b.mass) * fm
        b.inertia = _scale3(b.inertia, fm * fl * fl)
    new_total = sum(b.mass for b in spec.bodies)
    leg = 0.5 * (s.length[SEGMENTS.index("thigh")] + s.length[SEGMENTS.index("shank")])
    torque = (new_total / total if total > 0 else 1.0) * leg
    for act in spec.actuators:
        act.gear = _scale3(act.gear, torque)
    for key in list(spec.keys):  # a keyframe of the unscaled body would stand it in the floor
        spec.delete(key)


def leg_length(model: mujoco.MjModel) -> float:
    """Thigh + shank length (hip to ankle joint centre, m), mean of both sides."""
    legs = [float(np.linalg.norm(model.body(f"shank_{s}").pos) + np.linalg.norm(model.body(f"foot_{s}").pos))
            for s in SIDE_SUFFIXES]
    return float(np.mean(legs))


def _lowest_foot(model: mujoco.MjModel, data: mujoco.MjData, feet: np.ndarray) -> float:
    return min(geom_bottom(model, data, g) for g in feet)


def similar_cycle(source: mujoco.MjModel, body: mujoco.MjModel, cycle: ReferenceCycle) -> ReferenceCycle:
    """`cycle` of the `source` human carried over to `body` (module docstring): joint angles kept,
    horizontal root path x lambda, time x sqrt(lambda), the root height moved frame by frame so
    the lowest point of the feet clears the floor as much as on the source body."""
    lam = leg_length(body) / leg_length(source)
    tau = math.sqrt(lam)
    qpos, qvel = cycle.qpos.copy(), cycle.qvel.copy()
    qpos[:, :2] *= lam
    feet_ids = [source.body(f"foot_{s}").id for s in SIDE_SUFFIXES]  # same tree in both
    feet_src = np.flatnonzero(np.isin(source.geom_bodyid, subtree(source, np.array(feet_ids))))
    feet_body = np.flatnonzero(np.isin(body.geom_bodyid, subtree(body, np.array(feet_ids))))
    d_src, d_body = mujoco.MjData(source), mujoco.MjData(body)
    for k in range(len(qpos)):
        d_src.qpos[:], d_body.qpos[:] = cycle.qpos[k], cycle.qpos[k]
        mujoco.mj_kinematics(source, d_src)
        mujoco.mj_kinematics(body, d_body)
        qpos[k, 2] += _lowest_foot(source, d_src, feet_src) - _lowest_foot(body, d_body, feet_body)
    qvel[:, :3] *= lam / tau
    qvel[:, 3:] /= tau
    return replace(cycle, qpos=qpos, qvel=qvel, time_s=cycle.time_s * tau, period_s=cycle.period_s * tau,
                   stride_length_m=cycle.stride_length_m * lam, speed_mps=cycle.speed_mps * lam / tau)


def body_observation(model: mujoco.MjModel, cycle: ReferenceCycle, size: int = BODY_OBS_SIZE) -> np.ndarray:
    """What the policy knows of the body it walks (module docstring), (size,): log ratios of standing
    height (joints at zero, feet on the floor), mass, leg length and the cycle's speed and period to
    `NOMINAL`, then the standing centre of mass's fore-aft distance ahead of the ankle joints' midpoint
    and of the pelvis, each / leg length (`BALANCE`); `size`: the first values only (`BODY_OBS_SIZES`)."""
    if size not in BODY_OBS_SIZES:
        raise ValueError(f"a body observation has {' or '.join(map(str, BODY_OBS_SIZES))} values, not {size}")
    data = mujoco.MjData(model)
    feet = np.array([model.body(f"foot_{s}").id for s in SIDE_SUFFIXES])
    data.qpos[:] = standing_pose(model, feet)
    mujoco.mj_forward(model, data)  # subtree_com: the root's is the whole body's (facing +x)
    leg, pelvis = leg_length(model), model.body("pelvis").id
    values = {"height_m": standing_height(model, data), "mass_kg": float(model.body_mass.sum()),
              "leg_length_m": leg, "speed_mps": float(cycle.speed_mps), "period_s": float(cycle.period_s)}
    com_x = float(data.subtree_com[pelvis, 0])
    balance = (com_x - float(data.xpos[feet, 0].mean()), com_x - float(data.xpos[pelvis, 0]))
    obs = [math.log(values[k] / NOMINAL[k]) for k in NOMINAL] + [b / leg for b in balance]
    return np.array(obs[:size], np.float32)


__all__ = ["BALANCE", "BODY_OBS_SIZE", "BODY_OBS_SIZES", "NOMINAL", "SEGMENTS", "BodyDraw", "BodyScales",
           "body_observation", "draw_scales", "leg_length", "scale_spec", "similar_cycle"]
