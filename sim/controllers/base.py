"""The follow-me controller interface: robot sensors in, base command out.

A controller sees only what the MRBA itself measures -- the passive arm's joint positions and
velocities, the base odometry and the time -- never the simulator's human state; it returns a
differential-drive command (forward speed, yaw rate). `RobotInfo` carries the robot constants a
controller may build a model from.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RobotSensors:
    """One control sample of the robot's own sensors.

    `arm_q` / `arm_qd`: forward, lateral, vertical arm slide positions (m) and velocities (m/s), zero
    at the neutral point; `base_pose`: odometry x, y (m), yaw (rad); `base_speed_mps`: forward speed;
    `base_yaw_rate_rps`: yaw rate.
    """

    time_s: float
    arm_q: np.ndarray
    arm_qd: np.ndarray
    base_pose: np.ndarray
    base_speed_mps: float
    base_yaw_rate_rps: float


@dataclass(frozen=True)
class BaseCommand:
    speed_mps: float
    yaw_rate_rps: float


@dataclass(frozen=True)
class RobotInfo:
    """Robot constants available to controllers: arm reach (m), drive lag (s), control period (s)."""

    reach_m: float
    drive_tau_s: float
    dt_s: float


class Controller(ABC):
    """A follow-me controller. Construct with (gains dict, RobotInfo); `reset` before each rollout."""

    def __init__(self, gains: dict, robot: RobotInfo) -> None:
        self.gains = dict(gains)
        self.robot = robot

    @abstractmethod
    def reset(self) -> None: ...

    @abstractmethod
    def step(self, sensors: RobotSensors) -> BaseCommand: ...
