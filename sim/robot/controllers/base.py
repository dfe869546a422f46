"""The follow-me controller interface: robot sensors in, base command out.

A controller sees only what the MRBA itself measures -- the passive arm's joint positions and
velocities, the base odometry and the time -- never the simulator's human state; it returns a
differential-drive command (forward speed, yaw rate). `RobotInfo` carries the robot constants a
controller may build a model from.

The rollout calls `step` once per control tick (`rollout.control_rate_hz`, 100 Hz as on a real mobile
base) and reuses one `RobotSensors` object, updating its fields in place, so no objects are built per
tick: a controller that keeps sensor values beyond its `step` call must copy them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

from sim.errors import SimulationError
from sim.robot.controllers.gains import Gain, gain_problems, with_defaults


@dataclass(slots=True)
class RobotSensors:
    """One control tick of the robot's own sensors (mutable: the rollout refills one instance).

    `arm_q` / `arm_qd`: forward, lateral, vertical arm slide positions (m) and velocities (m/s), zero
    at the neutral point; `base_pose`: odometry x, y (m), yaw (rad); `base_speed_mps`: forward speed;
    `base_yaw_rate_rps`: yaw rate. The sequences are tuples of floats in rollouts (numpy arrays work too).
    """

    time_s: float
    arm_q: Sequence[float]
    arm_qd: Sequence[float]
    base_pose: Sequence[float]
    base_speed_mps: float
    base_yaw_rate_rps: float


class BaseCommand(NamedTuple):
    """Differential-drive command: forward speed (m/s) and yaw rate (rad/s)."""

    speed_mps: float
    yaw_rate_rps: float


@dataclass(frozen=True)
class RobotInfo:
    """Robot constants available to controllers: arm reach (m), drive lag (s), control period (s),
    command latency (s, part of the drive lag; a controller may model it separately)."""

    reach_m: float
    drive_tau_s: float
    dt_s: float
    latency_s: float = 0.0


class Controller(ABC):
    """A follow-me controller. Construct with (gains dict, RobotInfo); `reset` before each rollout.

    `declared_gains` names every gain it reads (`sim.robot.controllers.gains.Gain`: meaning, unit,
    default, bounds, search scale). Construction checks the given gains against it (an unknown,
    out-of-bounds or missing required gain raises `SimulationError`) and sets `self.gains` to them over
    the declared defaults, so the controller reads ``self.gains[k]``. `declared_gains` None (a plug-in
    that does not say) takes any gains as given."""

    declared_gains: ClassVar[Mapping[str, Gain] | None] = None

    def __init__(self, gains: Mapping[str, float], robot: RobotInfo) -> None:
        problems = gain_problems(type(self), gains)
        if problems:
            raise SimulationError(f"controller {type(self).__name__}",
                                  "; ".join(f"gain {k}: {p}" for k, p in problems.items()))
        self.gains = with_defaults(type(self), gains)
        self.robot = robot

    @abstractmethod
    def reset(self) -> None: ...

    @abstractmethod
    def step(self, sensors: RobotSensors) -> BaseCommand: ...
