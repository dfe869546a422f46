"""`WarmStarted`: a follow-me controller that enters a rollout already following a walking user."""

from __future__ import annotations

import numpy as np

from sim.robot.controllers.base import BaseCommand, Controller, RobotSensors


class WarmStarted(Controller):
    """A follow-me controller that enters the rollout already following a user at `speed_mps`.

    The policy human starts mid-walk (it was trained on steady walking), while the replay mode lets
    human, robot and controller start together from rest (`sim.motion.replay.with_lead_in`). So that every
    controller meets the policy human in the same natural state - following steadily - its `reset`
    runs the wrapped controller for `duration_s` in closed loop on a synthetic steady walk through its
    public interface: a user at constant `speed_mps`, the base a first-order lag with the robot's
    drive time constant (`RobotInfo.drive_tau_s`). The pre-roll runs at the first `step`, laid along
    the robot's first odometry pose (ending there) with times before the first sample, so odometry
    and time continue seamlessly. Only the controller's internal state (integrators, observers) is
    set this way; no force acts on the human."""

    def __init__(self, inner: Controller, speed_mps: float, duration_s: float = 5.0) -> None:
        super().__init__(inner.gains, inner.robot)
        self.inner, self.speed_mps, self.duration_s = inner, float(speed_mps), float(duration_s)

    def reset(self) -> None:
        self.inner.reset()
        self.pending = True

    def _preroll(self, first: RobotSensors) -> None:
        dt, tau = self.robot.dt_s, max(self.robot.drive_tau_s, self.robot.dt_s)
        n = int(round(self.duration_s / dt))
        x0, y0, yaw = first.base_pose
        c, sn = float(np.cos(yaw)), float(np.sin(yaw))
        v = self.speed_mps
        back = v * n * dt  # base path length of the pre-roll (it starts and stays near the user's speed)
        x_h = x_b = 0.0
        v_b = v
        s = RobotSensors(0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0)
        for i in range(n):
            s.time_s = first.time_s + (i - n) * dt
            s.arm_q = (x_h - x_b, 0.0, first.arm_q[2])
            s.arm_qd = (v - v_b, 0.0, 0.0)
            s.base_pose = (x0 + c * (x_b - back), y0 + sn * (x_b - back), yaw)
            s.base_speed_mps, s.base_yaw_rate_rps = v_b, 0.0
            cmd = self.inner.step(s)
            v_b += (cmd[0] - v_b) * dt / tau
            x_b += v_b * dt
            x_h += v * dt

    def step(self, sensors: RobotSensors) -> BaseCommand:
        if self.pending:
            self._preroll(sensors)
            self.pending = False
        return self.inner.step(sensors)
