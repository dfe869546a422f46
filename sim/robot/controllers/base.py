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
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple


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

    `required_gains` are the gains it cannot run without, `optional_gains` those it reads when given;
    `gain_problems` checks a gains dict against them (params load calls it, so a misspelt or missing
    gain fails there). `optional_gains` None (a plug-in that does not say) accepts any other gain."""

    required_gains: tuple[str, ...] = ()
    optional_gains: tuple[str, ...] | None = None

    def __init__(self, gains: dict, robot: RobotInfo) -> None:
        self.gains = dict(gains)
        self.robot = robot

    @classmethod
    def gain_problems(cls, gains: dict) -> str | None:
        """What is wrong with `gains` for this controller (missing and unknown gains), or None."""
        missing = [g for g in cls.required_gains if g not in gains]
        allowed = None if cls.optional_gains is None else {*cls.required_gains, *cls.optional_gains}
        unknown = [] if allowed is None else sorted(g for g in gains if g not in allowed)
        if not missing and not unknown:
            return None
        said = [f"missing gain(s) {', '.join(map(repr, missing))}" if missing else "",
                f"unknown gain(s) {', '.join(map(repr, unknown))}" if unknown else ""]
        takes = f"{cls.__name__} takes {', '.join(cls.required_gains)}"
        if cls.optional_gains:
            takes += f"; optional {', '.join(cls.optional_gains)}"
        return f"{'; '.join(p for p in said if p)} ({takes})"

    @abstractmethod
    def reset(self) -> None: ...

    @abstractmethod
    def step(self, sensors: RobotSensors) -> BaseCommand: ...
