"""Speed-adaptive follow-me controller: user-velocity observer + feed-forward + LQR on the deflection.

Modelled on Wang et al. (IFAC 2023), who estimate the user's walking velocity with an observer from
the robot's sensors and close the loop with LQR state feedback. Here, from robot sensors only:

- Observer: the user's (harness point's) ground position ``p_u = p_base + R(yaw) [reach + a_x, a_y]``
  from odometry and the arm slides. Its velocity is averaged over one gait cycle, ``(p_u(t) -
  p_u(t - T)) / T`` with ``T = window_s`` (a moving average over a stride, ~1.1 s in adults, Winter
  2009), which cancels the intra-stride pelvis oscillation (the forward surge at step frequency and
  the lateral sway at stride frequency) while keeping the mean speed and heading.
- Feed-forward: the estimated speed along the base heading.
- Forward LQR on ``[int e_x, e_x, v_base - v_ff]`` with the base velocity as a first-order lag of
  time constant `drive_tau_s`; lateral LQR on ``[int e_y, e_y, psi_rel, w_base]`` with
  ``e_y' = -v psi_rel - reach w`` (``psi_rel``: base heading minus the estimated user heading). The
  lateral plant depends on the walking speed, so its gains are scheduled on the estimated speed
  (solved once per reset with `scipy.linalg.solve_continuous_are` on a speed grid).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy.linalg import solve_continuous_are

from sim.controllers.base import BaseCommand, Controller, RobotSensors

GAINS = ("log_q_int_x", "log_q_e_x", "log_r_x", "log_q_int_y", "log_q_e_y", "log_r_y")
SPEED_GRID_MPS = np.linspace(0.3, 2.0, 18)  # non-holonomic: heading and offset decouple only when moving


def lqr(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: float) -> np.ndarray:
    """Continuous-time LQR gain K (u = -K x)."""
    p = solve_continuous_are(a, b, q, np.array([[r]]))
    return (b.T @ p / r).ravel()


def forward_gain(tau_s: float, q_int: float, q_e: float, r: float) -> np.ndarray:
    a = np.array([[0, 1, 0], [0, 0, -1], [0, 0, -1 / tau_s]], dtype=float)
    b = np.array([[0], [0], [1 / tau_s]])
    return lqr(a, b, np.diag([q_int, q_e, 1.0]), r)


def lateral_gain(speed_mps: float, reach_m: float, tau_s: float, q_int: float, q_e: float,
                 r: float) -> np.ndarray:
    a = np.array([[0, 1, 0, 0], [0, 0, -speed_mps, -reach_m], [0, 0, 0, 1], [0, 0, 0, -1 / tau_s]],
                 dtype=float)
    b = np.array([[0], [0], [0], [1 / tau_s]])
    return lqr(a, b, np.diag([q_int, q_e, 1.0, 0.0]), r)


def _wrap(a: float) -> float:
    return (a + np.pi) % (2 * np.pi) - np.pi


class Adaptive(Controller):
    def reset(self) -> None:
        g, rb = self.gains, self.robot
        q = {k: 10.0 ** g[k] for k in GAINS}
        self.k_fwd = forward_gain(rb.drive_tau_s, q["log_q_int_x"], q["log_q_e_x"], q["log_r_x"])
        self.k_lat = np.array([lateral_gain(v, rb.reach_m, rb.drive_tau_s, q["log_q_int_y"],
                                            q["log_q_e_y"], q["log_r_y"]) for v in SPEED_GRID_MPS])
        n = max(int(round(g.get("window_s", 1.1) / rb.dt_s)), 2)
        self.history: deque[tuple[float, np.ndarray]] = deque(maxlen=n + 1)
        self.integral = np.zeros(2)
        self.t_prev: float | None = None
        self.speed_mps = 0.0

    def observe(self, s: RobotSensors) -> tuple[float, float]:
        """Estimated user speed (m/s) and heading (rad) over the last gait cycle."""
        x, y, yaw = s.base_pose
        c, sn = np.cos(yaw), np.sin(yaw)
        ax, ay = self.robot.reach_m + s.arm_q[0], s.arm_q[1]
        p = np.array([x + c * ax - sn * ay, y + sn * ax + c * ay])
        self.history.append((s.time_s, p))
        t0, p0 = self.history[0]
        if s.time_s - t0 >= 0.25:
            vel = (p - p0) / (s.time_s - t0)
        else:
            vel = s.base_speed_mps * np.array([c, sn])
        speed = float(np.hypot(*vel))
        heading = float(np.arctan2(vel[1], vel[0])) if speed > 0.1 else float(yaw)
        return speed, heading

    def step(self, s: RobotSensors) -> BaseCommand:
        dt = self.robot.dt_s if self.t_prev is None else s.time_s - self.t_prev
        self.t_prev = s.time_s
        speed, heading = self.observe(s)
        self.speed_mps = speed
        psi_rel = _wrap(float(s.base_pose[2]) - heading)
        v_ff = speed * np.cos(psi_rel)
        e = s.arm_q[:2]
        i_max = self.gains.get("i_max", 1.0)
        self.integral = np.clip(self.integral + e * dt, -i_max, i_max)
        x_fwd = np.array([self.integral[0], e[0], s.base_speed_mps - v_ff])
        v = v_ff - self.k_fwd @ x_fwd
        k_lat = np.array([np.interp(speed, SPEED_GRID_MPS, self.k_lat[:, j]) for j in range(4)])
        x_lat = np.array([self.integral[1], e[1], psi_rel, s.base_yaw_rate_rps])
        w = -k_lat @ x_lat
        return BaseCommand(float(v), float(w))
