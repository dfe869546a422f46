"""Baseline follow-me controller: PID on the arm deflection (Wang, Chan et al. ICRA 2025, `PID`).

Forward deflection drives the forward speed, lateral deflection the yaw rate; the derivative terms
use the arm's measured joint velocities. The integrators are clamped at `i_max` (anti-windup).
"""

from __future__ import annotations

from sim.robot.controllers.base import BaseCommand, Controller, RobotSensors
from sim.robot.controllers.gains import POSITIVE, Gain


class PID(Controller):
    """v = kp_x e_x + ki_x int e_x + kd_x de_x/dt, w = the same in y (e: arm deflection, m)."""

    declared_gains = {
        "kp_x": Gain("forward speed per forward deflection", "1/s", bounds=POSITIVE, search="log"),
        "ki_x": Gain("forward speed per integrated forward deflection", "1/s^2", bounds=POSITIVE,
                     search="log"),
        "kd_x": Gain("forward speed per forward deflection rate", "1", bounds=POSITIVE, search="log"),
        "kp_y": Gain("yaw rate per lateral deflection", "rad/(s m)", bounds=POSITIVE, search="log"),
        "ki_y": Gain("yaw rate per integrated lateral deflection", "rad/(s^2 m)", bounds=POSITIVE,
                     search="log"),
        "kd_y": Gain("yaw rate per lateral deflection rate", "rad/m", bounds=POSITIVE, search="log"),
        "i_max": Gain("integrator clamp (anti-windup), each axis", "m s", default=1.0, bounds=POSITIVE),
    }

    def reset(self) -> None:
        self.integral = (0.0, 0.0)
        self.t_prev: float | None = None
        self.i_max = float(self.gains["i_max"])

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


GAINS = tuple(k for k, g in PID.declared_gains.items() if g.search)  # the feedback gains (kp .. kd_y)
