"""Baseline follow-me controller: PID on the arm deflection (Wang, Chan et al. ICRA 2025, `PID`).

Forward deflection drives the forward speed, lateral deflection the yaw rate; the derivative terms
use the arm's measured joint velocities. The integrators are clamped at `i_max` (anti-windup).
"""

from __future__ import annotations

from sim.robot.controllers.base import BaseCommand, Controller, RobotSensors

GAINS = ("kp_x", "ki_x", "kd_x", "kp_y", "ki_y", "kd_y")


class PID(Controller):
    required_gains = GAINS
    optional_gains = ("i_max",)

    def reset(self) -> None:
        self.integral = (0.0, 0.0)
        self.t_prev: float | None = None
        self.i_max = float(self.gains.get("i_max", 1.0))

    def step(self, s: RobotSensors) -> BaseCommand:
        g = self.gains
        dt = self.robot.dt_s if self.t_prev is None else s.time_s - self.t_prev
        self.t_prev = s.time_s
        ex, ey = float(s.arm_q[0]), float(s.arm_q[1])
        i_max = self.i_max
        ix = min(max(self.integral[0] + ex * dt, -i_max), i_max)
        iy = min(max(self.integral[1] + ey * dt, -i_max), i_max)
        self.integral = (ix, iy)
        v = g["kp_x"] * ex + g["ki_x"] * ix + g["kd_x"] * float(s.arm_qd[0])
        w = g["kp_y"] * ey + g["ki_y"] * iy + g["kd_y"] * float(s.arm_qd[1])
        return BaseCommand(v, w)
