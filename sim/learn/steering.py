"""Steering the walking human: commands (speed, heading) and the reference they imply.

A command is a forward speed and a heading (world yaw) per policy step, from a scenario
(`sim.rollout.scenarios.command_profile`) or, in training, from `sample_commands`, which strings
random scenario segments together (stand, start, walk at a speed, turn, stop) so one policy learns
every transition the scenarios ask for.

The imitation reference under a command (`SteeredReference`) is the subject's periodic cycle,
blended from and to a quiet standing pose by the gait amplitude `a` (0 standing, 1 walking: the
stride length is about `a` x the cycle's) and time-warped by the phase rate `r` (the cadence, x the
cycle's), with `a r` = commanded / cycle speed (`speed_law`). Above `full_gait_fraction` of the
cycle's speed the stride is kept and the cadence follows the speed; below it the stride shortens as
speed^`stride_speed_exponent` (0.42: the preferred step length of Kuo 2001, J Biomech Eng 123:264)
and the cadence takes the rest, so a walk slows and stops in short, quick steps. A cadence floor
(`min_cadence`, off unless set) keeps steps coming at the end of a stop and the beginning of a
start. Policies trained before this law (`stride_speed_exponent` None: `a` a smoothstep of the
speed, the cadence alone following it, so slow walking asked for long, slow strides) keep their own.

The heading steered toward stays within `heading_lead_deg` of where the pelvis faces
(`lead_heading`), so a turn faster than the body turns is followed at the body's own rate.

In a turn the feet may lean the body inward (`turn_lean`, off unless set): the cycle is straight
walking, so without it the reference keeps the straight walk's foot placement while the turn needs
the ground force pointing to its centre.

The standing pose is the body's anatomical neutral (every joint coordinate zero:
upright, arms down) with the feet on the floor. While standing, the cycle waits where the legs pass
each other (feet closest fore-aft, mid-swing), so every start leaves from there: the blend lifts
one foot forward, a first step. Every subject uses this blend; a recording's own start, turn and
stop (Camargo has them) are not used as reference yet: that needs the whole trial retargeted, not
only its cycle.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Annotated, Literal

import mujoco
import numpy as np
from pydantic import Field, with_config

from sim.angles import wrap_angle
from sim.rollout.scenarios import CommandProfile, ProfileParams, Segment, command_profile

Share = Annotated[float, Field(ge=0.0, le=1.0)]
Fraction = Annotated[float, Field(gt=0.0, le=1.0)]
Positive = Annotated[float, Field(gt=0.0)]


@with_config(extra="forbid")
@dataclass(frozen=True)
class CommandSampling:
    """Random training commands (params `train.env.commands`): episode starts, segment lengths,
    speeds (x the cycle's speed) and turn angles."""

    standing_start_probability: Share = 0.5   # else the episode starts walking at a random phase
    speed_range: tuple[float, float] = (0.6, 1.3)
    walk_s_range: tuple[float, float] = (1.5, 4.0)
    stand_s_range: tuple[float, float] = (0.5, 5.0)  # a start need not follow a stop soon
    turn_deg_range: tuple[float, float] = (30.0, 180.0)
    event_probabilities: tuple[float, float, float] = (0.25, 0.25, 0.5)  # turn, speed change, stop
    full_gait_fraction: Fraction = 1.0            # gait amplitude reaches 1 at this x the cycle's speed
    stride_speed_exponent: Fraction | None = 0.42  # stride ~ speed^this below it (None: the legacy law)
    start_s_range: tuple[float, float] = (1.7, 4.0)  # gentler starts, stops and turns than the
    stop_s_range: tuple[float, float] = (1.4, 3.0)   # scenarios' too, so the policy meets easier
    turn_rate_deg_s_range: tuple[float, float] = (40.0, 90.0)  # versions of each transition
    # Phase-rate floor while walking (None: none). Without it the law's cadence falls to 0 with the
    # speed, so the last ~0.3 s of a stop (and the first of a start) blend the gait amplitude from
    # ~0.3-0.4 to 0 while the phase moves ~3 % of a cycle: the reference slides the stance foot on
    # the floor instead of stepping. With a floor, steps keep coming and shorten with the speed.
    # 0.744: the law's cadence at 0.6 x the cycle's speed, the slowest trained.
    min_cadence: Fraction | None = 0.744
    # Lean into turns (None: off): the feet reference moves toward the outside of a turn by this x
    # the lateral offset of an inverted pendulum taking the turn's centripetal acceleration
    # (`turn_lean_offset`). The cycle is straight walking; without it the reference asks for the
    # straight walk's foot placement while the turn needs the ground force pointing inward.
    turn_lean: Annotated[float, Field(gt=0.0, le=2.0)] | None = None
    turn_lean_time_constant_s: Positive = 0.3  # the lean builds and fades over about a step
    max_lean_tan: Fraction = 0.35               # tan of the largest lean taken (~19 deg)
    # Steering lead (None: off): the heading the human steers toward is held within this many degrees
    # of where its pelvis faces (`lead_heading`), so a turn commanded faster than the body turns is
    # followed at the body's own rate (a pursuit "carrot") instead of asking for a sidestep.
    heading_lead_deg: Annotated[float, Field(gt=0.0, le=180.0)] | None = 20.0
    # The leg of the first step from standing (and the last of a stop): "left", the cycle's legs
    # passing while the left foot swings; "either", the closer of its two crossings, the side then
    # differing between cycles and bodies (policies that recorded none; `sim.learn.walk_env.start_phase`).
    first_step: Literal["left", "either"] = "left"


def sample_commands(rng: np.random.Generator, speed_mps: float, duration_s: float, rate_hz: float,
                    s: CommandSampling, profile: ProfileParams) -> CommandProfile:
    """A random command profile of at least `duration_s`: segments drawn from `s`, built by the
    scenarios' own `command_profile`, with start, stop and turn timing drawn per episode from `s`'s
    ranges (the scenarios' timing and gentler ones)."""
    profile = replace(profile, start_s=float(rng.uniform(*s.start_s_range)),
                      stop_s=float(rng.uniform(*s.stop_s_range)),
                      turn_rate_deg_s=float(rng.uniform(*s.turn_rate_deg_s_range)))
    segments: list[Segment] = []
    standing = rng.random() < s.standing_start_probability
    if standing:
        segments.append(Segment(stand_s=float(rng.uniform(*s.stand_s_range))))
    speed = float(rng.uniform(*s.speed_range)) if standing else 1.0
    segments.append(Segment(walk_s=float(rng.uniform(*s.walk_s_range)), speed=speed))
    while True:
        event = rng.choice(3, p=np.asarray(s.event_probabilities) / sum(s.event_probabilities))
        if event == 0:
            angle = float(rng.uniform(*s.turn_deg_range)) * (1 if rng.random() < 0.5 else -1)
            segments.append(Segment(turn_deg=angle))
        elif event == 1:
            speed = float(rng.uniform(*s.speed_range))
        else:
            segments += [Segment(stop=True), Segment(stand_s=float(rng.uniform(*s.stand_s_range)))]
            speed = float(rng.uniform(*s.speed_range))
        segments.append(Segment(walk_s=float(rng.uniform(*s.walk_s_range)), speed=speed))
        commands = command_profile("training", segments, speed_mps, rate_hz, profile)
        if len(commands.time_s) / rate_hz >= duration_s:
            return commands


def command_at(speed_mps: np.ndarray, heading_rad: np.ndarray, k: int, ahead: int,
               dt_s: float) -> tuple[float, float, float]:
    """(speed, heading, yaw rate) commanded at sample `k` of per-sample commands; the yaw rate is
    the heading change over the next `ahead` samples (`dt_s`); past the end the last command holds."""
    last = len(speed_mps) - 1
    k = min(k, last)
    j = min(k + ahead, last)
    rate = (heading_rad[j] - heading_rad[k]) / dt_s if j > k else 0.0
    return float(speed_mps[k]), float(heading_rad[k]), float(rate)


def lead_heading(heading_rad: float, facing_rad: float, lead_rad: float) -> float:
    """The commanded heading moved to within `lead_rad` of the pelvis heading `facing_rad`."""
    error = wrap_angle(heading_rad - facing_rad)
    return facing_rad + min(max(error, -lead_rad), lead_rad)


def speed_law(speed_ratio: float, full_gait_fraction: float, stride_speed_exponent: float | None,
              min_cadence: float | None = None) -> tuple[float, float]:
    """(gait amplitude `a`, phase rate `r`) at `speed_ratio` = commanded / cycle speed (module
    docstring): `a r` = `speed_ratio`; the legacy law (exponent None) has `a` a smoothstep and
    `r` = `speed_ratio`. `min_cadence` (None: none) floors the phase rate while walking: below the
    speed where the law's cadence reaches it, the cadence stays there and the stride shortens in
    proportion to the speed (see `CommandSampling.min_cadence`)."""
    x = min(max(speed_ratio / full_gait_fraction, 0.0), 1.0)
    if stride_speed_exponent is None:
        return x * x * (3 - 2 * x), max(speed_ratio, 0.0)
    a = x ** stride_speed_exponent
    rate = speed_ratio / a if a > 0.0 else 0.0
    if min_cadence is not None and 0.0 < rate < min_cadence:
        return speed_ratio / min_cadence, min_cadence
    return a, rate


def level_speed_ratio(a: float, full_gait_fraction: float, stride_speed_exponent: float | None,
                      min_cadence: float | None = None) -> float:
    """The speed ratio at which `speed_law` gives gait amplitude `a` (its inverse; 1 at `a` = 1, the
    cycle itself); the legacy law's reference transitions took the ratio equal to `a`."""
    if stride_speed_exponent is None or a >= 1.0:
        return a
    ratio = full_gait_fraction * a ** (1.0 / stride_speed_exponent)
    if min_cadence is not None and a > 0.0 and ratio / a < min_cadence:  # below the floor: ratio = a floor
        return a * min_cadence
    return ratio


GRAVITY_MPS2 = 9.81


def turn_lean_offset(height_m: float, speed_mps: float, yaw_rate_rps: float, gain: float,
                     max_tan: float) -> float:
    """Lateral shift (m, + left in the heading frame) of the feet relative to the pelvis that leans
    the body into a turn: a rigid inverted pendulum of the pelvis height whose lean balances the
    centripetal acceleration v w (tan lean = v w / g, at most `max_tan`; the same law as a cyclist's
    or runner's lean on a curve), so the feet sit `height x tan lean` outside the pelvis, x `gain`."""
    ratio = min(max(speed_mps * yaw_rate_rps / GRAVITY_MPS2, -max_tan), max_tan)
    return -gain * height_m * ratio


def standing_pose(model: mujoco.MjModel, foot_bodies: np.ndarray) -> np.ndarray:
    """qpos of quiet standing: root upright facing +x, every joint coordinate at zero (anatomical
    neutral), the lowest geom of the feet (`foot_bodies` and their children) on the floor."""
    data = mujoco.MjData(model)
    q = model.qpos0.copy()
    q[:3] = 0.0, 0.0, 1.0
    q[3:7] = 1.0, 0.0, 0.0, 0.0
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    feet = np.isin(model.geom_bodyid, subtree(model, foot_bodies))
    lowest = min(geom_bottom(model, data, g) for g in np.flatnonzero(feet))
    q[2] = 1.0 - lowest
    return q


def subtree(model: mujoco.MjModel, roots: np.ndarray) -> np.ndarray:
    ids = set(int(r) for r in roots)
    for b in range(model.nbody):
        parent = int(model.body_parentid[b])
        if parent in ids:
            ids.add(b)
    return np.array(sorted(ids))


def geom_bottom(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> float:
    """Lowest world z of geom `g` (sphere, capsule, box or ellipsoid; others by bounding sphere)."""
    size, r = model.geom_size[g], data.geom_xmat[g].reshape(3, 3)
    kind, g_type = int(model.geom_type[g]), mujoco.mjtGeom
    z = data.geom_xpos[g, 2]
    if kind == int(g_type.mjGEOM_SPHERE):
        return float(z - size[0])
    if kind == int(g_type.mjGEOM_CAPSULE):
        return float(z - abs(r[2, 2]) * size[1] - size[0])
    if kind in (int(g_type.mjGEOM_BOX), int(g_type.mjGEOM_ELLIPSOID)):
        return float(z - np.abs(r[2, :]) @ size[:3])
    return float(z - model.geom_rbound[g])


class SteeredReference:
    """The reference under a command: cycle tables (`sim.learn.walk_env.ReferenceTable`) blended
    with the standing pose by the gait amplitude and time-warped by the speed ratio.

    The tables are packed side by side into one row per cycle sample (the blended part, servo
    coordinates, feet and pelvis height, then the velocities, then the root velocity), so a lookup
    is one interpolation of one row and three scalings: the same element-wise operations as
    interpolating each table apart (bit for bit), with a third of numpy's per-call overhead; it runs
    at every policy step of every rollout."""

    def __init__(self, table, stand_ctrl: np.ndarray, stand_feet: np.ndarray, stand_height: float) -> None:
        self.table = table
        nu, nf = table.ctrl.shape[1], table.feet.shape[1]
        self._rows = np.hstack([table.ctrl, table.feet, table.height[:, None], table.ctrl_vel,
                                table.joint_vel, table.root_vel[:, :2]])
        self._stand = np.r_[stand_ctrl, stand_feet, float(stand_height)]
        self._n_pos = nu + nf + 1
        self._cut = (nu, nu + nf)

    def at(self, phase: float, a: float, rate: float, speed_ratio: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        """(servo coordinates, their velocity, joint velocities, feet, pelvis height, root xy
        velocity in the heading frame) at `phase`, gait amplitude `a`, phase rate `rate` and
        `speed_ratio` (commanded / cycle speed: the root's)."""
        k0, k1, f = self.table.index(phase)
        rows = self._rows
        row = rows[k0] * (1 - f)
        row += rows[k1] * f
        n_pos = self._n_pos
        pos = (1 - a) * self._stand
        pos += a * row[:n_pos]
        vel = (a * rate) * row[n_pos:-2]
        nu, feet_end = self._cut
        return (pos[:nu], vel[:nu], vel[nu:], pos[nu:feet_end], float(pos[feet_end]),
                speed_ratio * row[-2:])


__all__ = ["CommandSampling", "SteeredReference", "command_at", "geom_bottom", "lead_heading",
           "level_speed_ratio", "sample_commands", "speed_law", "standing_pose", "subtree",
           "turn_lean_offset"]
