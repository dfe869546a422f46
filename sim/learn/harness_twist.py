"""The follow-me robot's harness twist, as a training load on the walking human.

With the robot attached, the harness's yaw spring-damper (`robot.harness`, 6th DoF) couples the
pelvis to the robot base, whose heading follows the person's with a lag (the controllers turn the
base from the arm's deflection, which trails a turn). A policy trained free never felt this torque:
on camargo's committed policy, softening that one spring to 5 % removed every turn_90 fall with pid
and adaptive (0 of 4 walks against 4 of 4; softening roll/pitch or the slides did not), although it
stays below ~10 N m. `HarnessTwist` reproduces it without the robot: a virtual base heading follows
the pelvis yaw through a first-order lag (time constant drawn per episode), and the pelvis feels
`-(k q + d q')` with q the twist, held within the harness's yaw range (the base is dragged along).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

from pydantic import Field, with_config

from sim.angles import wrap_angle


@with_config(extra="forbid")
@dataclass(frozen=True)
class TwistParams:
    """`train.env.harness_twist` (probability, lag_s) with the harness's yaw spring from
    `robot.harness` (`pipeline.runs.setup.train_params` fills those in)."""

    # share of training episodes with the twist (0: off)
    probability: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    lag_s: tuple[float, float] = (0.2, 1.0)   # the virtual base heading's time constant, drawn per episode
    stiffness_nm_per_rad: float = 40.0
    damping_nms_per_rad: float = 3.0
    range_rad: float = 0.7


@dataclass
class HarnessTwist:
    """State of one episode's twist: the virtual base heading and the last twist."""

    p: TwistParams
    lag_s: float
    base_yaw: float = 0.0
    twist: float = 0.0

    def reset(self, pelvis_yaw: float) -> None:
        self.base_yaw, self.twist = pelvis_yaw, 0.0

    def torque(self, pelvis_yaw: float, dt: float) -> float:
        """Yaw torque on the pelvis (N m, world z) after the base heading moves `dt` toward it."""
        self.base_yaw += wrap_angle(pelvis_yaw - self.base_yaw) * min(1.0, dt / self.lag_s)
        q = wrap_angle(pelvis_yaw - self.base_yaw)
        if abs(q) > self.p.range_rad:
            q = math.copysign(self.p.range_rad, q)
            self.base_yaw = pelvis_yaw - q
        rate = (q - self.twist) / dt
        self.twist = q
        return -(self.p.stiffness_nm_per_rad * q + self.p.damping_nms_per_rad * rate)
