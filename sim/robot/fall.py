"""Fall detection on what the robot senses: the passive arm's vertical motion and its deflection.

A fall pulls the harness, and with it the arm's vertical slide, down faster and further than walking
does (pelvis vertical speed stays within about +-0.45 m/s even in fast walking: Camargo replay).
The rule fires when the arm's vertical slide moves down faster than `drop_speed_mps`, or sits more
than `drop_m` below its neutral height, or the horizontal deflection exceeds `deflection_m` (the
user leaving the arm's workspace). It latches: once detected, the robot locks the arm and stops the base.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.robot.controllers.base import RobotSensors
from sim.robot.mrba import FallParams


@dataclass
class FallDetector:
    p: FallParams
    detected: bool = False
    time_s: float | None = None

    def reset(self) -> None:
        self.detected, self.time_s = False, None

    def update(self, s: RobotSensors) -> bool:
        """True from the first sample that meets the rule on."""
        if not self.detected:
            z, zd = s.arm_q[2], s.arm_qd[2]
            deflection = math.hypot(s.arm_q[0], s.arm_q[1])
            if zd < -self.p.drop_speed_mps or z < -self.p.drop_m or deflection > self.p.deflection_m:
                self.detected, self.time_s = True, s.time_s
        return self.detected
