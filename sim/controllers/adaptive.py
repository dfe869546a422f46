"""Speed-adaptive follow-me controller: user-velocity observer + feed-forward + LQR on the deflection.

Modelled on Wang et al. (IFAC 2023), who estimate the user's walking velocity with an observer from
the robot's sensors and close the loop with LQR state feedback. Here, from robot sensors only:

- Observer: the user's (harness point's) ground position ``p_u = p_base + R(yaw) [reach + a_x, a_y]``
  from odometry and the arm slides. Its velocity is averaged over one gait cycle, ``(p_u(t) -
  p_u(t - T)) / T`` with ``T = window_s`` (a moving average over a stride, ~1.1 s in adults, Winter
  2009), which cancels the intra-stride pelvis oscillation (the forward surge at step frequency and
  the lateral sway at stride frequency) while keeping the mean speed and heading.
  The averages lag by half a window; consecutive averages give the rate of change of speed and
  heading, used to extrapolate over that half window (`lag_compensation`).
- Feed-forward: the estimated speed along the base heading, and the user's heading rate as yaw rate.
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
        self.window_n = n
        self.history: deque[tuple[float, np.ndarray]] = deque(maxlen=n + n // 2 + 1)
        self.integral = np.zeros(2)
        self.t_prev: float | None = None
        self.speed_mps = 0.0

    def observe(self, s: RobotSensors) -> tuple[float, float, float]:
        """Estimated user speed (m/s), heading (rad) and heading rate (rad/s) now.

        Two consecutive gait-cycle averages of the user's velocity (windows ending now and half a
        window ago) give its rate of change; the newest average, which describes the user half a
        window ago, is extrapolated by that rate over the half window (`lag_compensation` = 1), so
        a user who speeds up or walks a curve is not followed with the averaging delay.
        """
        x, y, yaw = s.base_pose
        c, sn = np.cos(yaw), np.sin(yaw)
        ax, ay = self.robot.reach_m + s.arm_q[0], s.arm_q[1]
        p = np.array([x + c * ax - sn * ay, y + sn * ax + c * ay])
        self.history.append((s.time_s, p))
        n = self.window_n
        if len(self.history) <= n:
            t0, p0 = self.history[0]
            if s.time_s - t0 < 0.25:
                vel = s.base_speed_mps * np.array([c, sn])
            else:
                vel = (p - p0) / (s.time_s - t0)
            speed = float(np.hypot(*vel))
            return speed, float(np.arctan2(vel[1], vel[0])) if speed > 0.1 else float(yaw), 0.0
        t_a, p_a = self.history[-1 - n]
        v1 = (p - p_a) / (s.time_s - t_a)
        speed = float(np.hypot(*v1))
        heading = float(np.arctan2(v1[1], v1[0])) if speed > 0.1 else float(yaw)
        half = n // 2
        if len(self.history) <= n + half or speed <= 0.1:
            return speed, heading, 0.0
        t_b, p_b = self.history[-1 - half]
        t_c, p_c = self.history[-1 - half - n]
        v0 = (p_b - p_c) / (t_b - t_c)
        lead = self.gains.get("lag_compensation", 1.0)
        dt = s.time_s - t_b
        accel = (speed - float(np.hypot(*v0))) / dt
        rate = _wrap(heading - float(np.arctan2(v0[1], v0[0]))) / dt
        return speed + lead * accel * dt, heading + lead * rate * dt, lead * rate

    def step(self, s: RobotSensors) -> BaseCommand:
        dt = self.robot.dt_s if self.t_prev is None else s.time_s - self.t_prev
        self.t_prev = s.time_s
        speed, heading, heading_rate = self.observe(s)
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
        w = heading_rate - k_lat @ (x_lat - np.array([0, 0, 0, heading_rate]))
        return BaseCommand(float(v), float(w))
