"""Speed-adaptive follow-me controller: an observer of the user's walking velocity, its feed-forward,
and LQR state feedback on the arm deflection (after Wang et al., IFAC 2023), from robot sensors only.

- Observer: the user's ground position (odometry + arm slides, every control tick) gives the stride
  period (autocorrelation peak of the user's velocity, every `stride_update_s`) and the speed, the
  velocity averaged over exactly one stride, which cancels the intra-stride oscillation; until a
  stride is found, the speed over the last `startup_window_s`.
- Heading: a comb filter (velocity now minus one stride ago, `comb_compensation`) takes the stride
  average's half-stride lag out of the heading and gives the heading rate. This is a disclosed
  trade-off kept on purpose: it helps a walk entering a turn, as every straight bout of a real
  walkway ends, and costs on a constant curve. Only the comb term's part across the average
  velocity turns the heading; its part along it is a change of speed (added whole, a stopping user's
  heading pointed backward and the base spun in place).
- Gait-periodic feed-forward: the velocity one stride ago, `drive_tau_s` later in the stride,
  predicts the coming sway, fed forward as yaw rate (`oscillation_ff_lateral`; the forward surge is
  left out, it would take the drive's acceleration limit for millimetres of e_x).
- Standing: below `walking_min_speed_mps` (the gain schedule's lowest speed) the heading is held
  at its last walking value, with no heading rate and no gait feed-forward: the direction of a
  nearly standing user's averaged velocity is sway and noise.
- Feedback: the speed and heading rate are fed forward; LQR on ``[int e_x, e_x, v_base - v_user]``
  (base = first-order lag of `drive_tau_s`) and ``[int e_y, e_y, psi_rel, w_base]``, the lateral
  gains scheduled on the estimated speed (Riccati solutions on a speed grid, once per reset).

Numbers: every gain is declared in `Adaptive.declared_gains`. The LQR weights (the tuned-gains file,
data/tuning/controllers.yaml) are tuned by `sim.rollout.tuning` on synthetic walks, never the
evaluation data; `comb_compensation`, `lag_compensation` and the observer constants (their declared
defaults, or params `robot.controllers.adaptive.gains`) are design constants, not searched. Stride
bounds follow Winter (2009, adult strides 0.9-1.3 s); the periodic prediction follows
adaptive-oscillator gait prediction (Ronsse et al. 2011) and repetitive control. Per-tick arithmetic
is on Python floats (see sim/rollout/loop.py).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.linalg import solve_continuous_are

from sim.angles import wrap_angle
from sim.robot.controllers.base import BaseCommand, Controller, RobotSensors
from sim.robot.controllers.gains import POSITIVE, Gain

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


@functools.lru_cache(maxsize=64)
def scheduled_gains(tau_s: float, reach_m: float, q_int_x: float, q_e_x: float, r_x: float, q_int_y: float,
                    q_e_y: float, r_y: float) -> tuple[tuple[float, ...], tuple[tuple[float, ...], ...]]:
    """The forward gain and the lateral gains on `SPEED_GRID_MPS`, as Python floats. Cached: the 19
    Riccati solutions take ~10 ms, and every rollout of a sweep or a tuning trial with the same
    gains and robot asks for the same ones (a pure function of its arguments, so bit-identical)."""
    k_fwd = forward_gain(tau_s, q_int_x, q_e_x, r_x)
    k_lat = [lateral_gain(v, reach_m, tau_s, q_int_y, q_e_y, r_y) for v in SPEED_GRID_MPS]
    return tuple(k_fwd.tolist()), tuple(tuple(k.tolist()) for k in k_lat)


def _log10_weight(what: str) -> Gain:
    return Gain(f"log10 of the LQR weight on {what} (the speed-error weight is 1)", "log10", search="linear")


def _constant(meaning: str, unit: str, default: float, bounds: tuple[float, float] = POSITIVE) -> Gain:
    return Gain(meaning, unit, default=default, bounds=bounds)


class Adaptive(Controller):
    """LQR weights (searched by the tuners) and the observer's design constants (module docstring)."""

    declared_gains = {
        "log_q_int_x": _log10_weight("int e_x"),
        "log_q_e_x": _log10_weight("e_x"),
        "log_r_x": _log10_weight("the forward command (R)"),
        "log_q_int_y": _log10_weight("int e_y"),
        "log_q_e_y": _log10_weight("e_y"),
        "log_r_y": _log10_weight("the yaw-rate command (R)"),
        "i_max": _constant("integrator clamp (anti-windup), each axis", "m s", 1.0),
        "stride_init_s": _constant("stride period assumed until one is found", "s", 1.1),
        "stride_min_s": _constant("shortest stride period searched (Winter 2009)", "s", 0.6),
        "stride_max_s": _constant("longest stride period searched (Winter 2009)", "s", 1.6),
        "stride_buffer_s": _constant("user-position history kept for the stride search", "s", 4.0),
        "stride_update_s": _constant("period of the stride search", "s", 1.0),
        "lag_compensation": _constant("share of the stride average's speed lag added back", "1", 0.0),
        "heading_lag_compensation": _constant("share of the stride average's heading lag added back", "1",
                                              0.0),
        "oscillation_ff_lateral": _constant("gait-periodic feed-forward of the sway, as yaw rate", "1", 1.0),
        "oscillation_ff_forward": _constant("gait-periodic feed-forward of the surge, as speed", "1", 0.0),
        "comb_compensation": _constant("comb filter's share in the heading (0: off)", "1", 1.0),
        "osc_half_window_s": _constant("half window of the gait-periodic velocity", "s", 0.15),
        "startup_window_s": _constant("speed window until a stride is found", "s", 0.5),
        # below it the user is taken as standing (the lowest speed of the gain schedule)
        "walking_min_speed_mps": _constant("user speed below which the heading is held", "m/s",
                                           float(SPEED_GRID_MPS[0])),
    }

    def reset(self) -> None:
        g, rb = self.gains, self.robot
        q = [10.0 ** g[k] for k in LQR_WEIGHTS]
        self.k_fwd, self.k_lat = scheduled_gains(float(rb.drive_tau_s), float(rb.reach_m), *map(float, q))
        self.obs = {k: float(g[k]) for k in OBSERVER}
        grid = SPEED_GRID_MPS
        self.grid = (float(grid[0]), float(grid[1] - grid[0]), len(grid))  # Python floats: fast per tick
        self.k_osc = (self.obs["oscillation_ff_forward"], self.obs["oscillation_ff_lateral"] / rb.reach_m)
        self.i_max = float(g["i_max"])
        self.integral = [0.0, 0.0]
        self.t_prev: float | None = None
        self.speed_mps = 0.0
        self.stride_s = self.obs["stride_init_s"]
        self.window_n = max(int(round(self.stride_s / rb.dt_s)), 2)
        # ring buffers of the user's position and its time (long enough for the stride search and for
        # a window plus half a window)
        o = self.obs
        n = max(int(round(o["stride_buffer_s"] / rb.dt_s)), int(1.5 * o["stride_max_s"] / rb.dt_s) + 2)
        self.xs, self.ys, self.ts = [0.0] * n, [0.0] * n, [0.0] * n
        self.n_seen = 0
        # the stride search needs two of the longest strides and a margin; then it runs on what is there
        self.min_fill = min(n, int(2 * o["stride_max_s"] / rb.dt_s) + 4)
        self.stride_found = False
        self.startup_n = max(int(round(o["startup_window_s"] / rb.dt_s)), 2)
        self.update_every = max(int(round(self.obs["stride_update_s"] / rb.dt_s)), 1)
        self.osc_h = max(int(round(self.obs["osc_half_window_s"] / rb.dt_s)), 1)
        self.osc_lead = int(round(rb.drive_tau_s / rb.dt_s))
        self.osc = (0.0, 0.0)
        self.held_heading: float | None = None

    def estimate_stride(self) -> float | None:
        """Stride period (s) from the autocorrelation of the buffered user velocity, or None."""
        o, dt = self.obs, self.robot.dt_s
        n = len(self.xs)
        i = self.n_seen % n
        p = np.array([self.xs[i:] + self.xs[:i], self.ys[i:] + self.ys[:i]]).T[-min(self.n_seen, n):]
        v = np.diff(p, axis=0) / dt
        mean = v.mean(axis=0)
        speed = float(np.hypot(*mean))
        if speed < o["walking_min_speed_mps"]:
            return None
        u = mean / speed
        t = np.arange(len(v)) - (len(v) - 1) / 2
        score = np.zeros(len(v))
        for sig in (v @ u, v @ np.array([-u[1], u[0]])):
            sig = sig - sig.mean()
            sig = sig - t * (sig @ t) / (t @ t)  # remove a linear speed trend
            energy = float(sig @ sig)
            if energy <= 1e-12:
                return None
            score += np.correlate(sig, sig, "full")[len(v) - 1:] / energy
        lo = int(math.ceil(o["stride_min_s"] / dt))
        hi = min(int(o["stride_max_s"] / dt), len(v) // 2)
        if hi <= lo + 2:
            return None
        j = lo + int(np.argmax(score[lo:hi + 1]))
        if score[j] < 0.6 or j in (lo, hi):  # two signals, 1 each at best: a clear common peak only
            return None
        y0, y1, y2 = score[j - 1:j + 2]
        shift = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) if (y0 - 2 * y1 + y2) != 0 else 0.0
        return (j + shift) * dt

    def _startup_speed(self, speed: float, heading: float, px: float, py: float, i: int, t: float) -> float:
        """Until a stride period is found (the user is starting to walk; the callers check), the speed
        along `heading` over the last `startup_window_s` instead of the stride average `speed`, which
        lags an accelerating user by half a window."""
        k = min(self.startup_n, self.n_seen - 1, len(self.xs) - 1)
        if k < 2:
            return speed
        j = (i - k) % len(self.xs)
        dt = t - self.ts[j]
        return max(((px - self.xs[j]) * math.cos(heading) + (py - self.ys[j]) * math.sin(heading)) / dt, 0.0)

    def observe(self, s: RobotSensors) -> tuple[float, float, float]:
        """Estimated user speed (m/s), heading (rad) and heading rate (rad/s) now (module docstring);
        also sets `self.osc` to the predicted oscillation velocity (world x, y; m/s)."""
        self.osc = (0.0, 0.0)
        x, y, yaw = s.base_pose
        c, sn = math.cos(yaw), math.sin(yaw)
        ax, ay = self.robot.reach_m + s.arm_q[0], s.arm_q[1]
        px, py = x + c * ax - sn * ay, y + sn * ax + c * ay
        size = len(self.xs)
        i = self.n_seen % size
        self.xs[i], self.ys[i], self.ts[i] = px, py, s.time_s
        self.n_seen += 1
        seen = self.n_seen
        if seen >= self.min_fill and seen % self.update_every == 0:
            stride = self.estimate_stride()
            if stride is not None:
                self.stride_s, self.stride_found = stride, True
                self.window_n = max(int(round(stride / self.robot.dt_s)), 2)
        n = self.window_n
        if seen <= n:  # less than a stride seen: average over what there is, or the base speed
            dt = s.time_s - self.ts[0]  # the buffer holds more than a window: nothing overwritten yet
            if dt < 0.25:
                vx, vy = s.base_speed_mps * c, s.base_speed_mps * sn
            else:
                vx, vy = (px - self.xs[0]) / dt, (py - self.ys[0]) / dt
            speed = math.hypot(vx, vy)
            heading = math.atan2(vy, vx) if speed > 0.1 else float(yaw)
            if not self.stride_found:
                speed = self._startup_speed(speed, heading, px, py, i, s.time_s)
            return speed, heading, 0.0
        ja = (i - n) % size
        dt = s.time_s - self.ts[ja]
        vx, vy = (px - self.xs[ja]) / dt, (py - self.ys[ja]) / dt
        speed = math.hypot(vx, vy)
        heading = math.atan2(vy, vx) if speed > 0.1 else float(yaw)
        if not self.stride_found:
            speed = self._startup_speed(speed, heading, px, py, i, s.time_s)
        half = n // 2
        if seen <= n + half or speed <= 0.1:
            return speed, heading, 0.0
        h, m = self.osc_h, self.osc_lead
        if m + h < n - h:  # velocity one stride ago, drive_tau later in the stride, minus the average
            j1, j0 = (i - n + m + h) % size, (i - n + m - h) % size
            dto = self.ts[j1] - self.ts[j0]
            self.osc = ((self.xs[j1] - self.xs[j0]) / dto - vx, (self.ys[j1] - self.ys[j0]) / dto - vy)
        comb = self.obs["comb_compensation"]
        if comb > 0.0 and self.stride_found and seen > n + 2 * h:
            # the user's velocity now minus one stride ago (both over the last 2h): the periodic part
            # cancels, leaving the change of the mean over one stride, twice what the average lags
            j2, j3 = (i - 2 * h) % size, (i - n - 2 * h) % size
            ja2 = (i - n) % size
            d1, d0 = s.time_s - self.ts[j2], self.ts[ja2] - self.ts[j3]
            wx, wy = (self.xs[ja2] - self.xs[j3]) / d0, (self.ys[ja2] - self.ys[j3]) / d0
            cx = (px - self.xs[j2]) / d1 - wx
            cy = (py - self.ys[j2]) / d1 - wy
            # only its part across the average velocity turns the heading: the part along it is a
            # change of speed (a stopping user's would point the heading backward)
            across = (vx * cy - vy * cx) / speed
            turn = math.atan2(0.5 * comb * across, speed)
            return speed, wrap_angle(heading + turn), turn / (0.5 * n * self.robot.dt_s)
        jb, jc = (i - half) % size, (i - half - n) % size
        tb = self.ts[jb]
        dt0 = tb - self.ts[jc]
        ux, uy = (self.xs[jb] - self.xs[jc]) / dt0, (self.ys[jb] - self.ys[jc]) / dt0
        lead, lead_h = self.obs["lag_compensation"], self.obs["heading_lag_compensation"]
        dtl = s.time_s - tb
        accel = (speed - math.hypot(ux, uy)) / dtl
        rate = wrap_angle(heading - math.atan2(uy, ux)) / dtl
        return speed + lead * accel * dtl, heading + lead_h * rate * dtl, lead_h * rate

    def step(self, s: RobotSensors) -> BaseCommand:
        dt = self.robot.dt_s if self.t_prev is None else s.time_s - self.t_prev
        self.t_prev = s.time_s
        speed, heading, heading_rate = self.observe(s)
        self.speed_mps = speed
        yaw = s.base_pose[2]
        if speed < self.obs["walking_min_speed_mps"]:
            # standing or nearly: the averaged velocity's direction is sway and noise, and the gait
            # prediction describes a stride no longer walked; hold the last walking heading
            heading = float(yaw) if self.held_heading is None else self.held_heading
            heading_rate, self.osc = 0.0, (0.0, 0.0)
        else:
            self.held_heading = heading
        psi_rel = wrap_angle(yaw - heading)
        ox, oy = self.osc
        c, sn = math.cos(yaw), math.sin(yaw)
        k_fwd_osc, k_lat_osc = self.k_osc
        v_ff = speed * math.cos(psi_rel) + k_fwd_osc * (c * ox + sn * oy)
        w_osc = k_lat_osc * (-sn * ox + c * oy)
        ex, ey = float(s.arm_q[0]), float(s.arm_q[1])
        i_max = self.i_max
        ix = min(max(self.integral[0] + ex * dt, -i_max), i_max)
        iy = min(max(self.integral[1] + ey * dt, -i_max), i_max)
        self.integral = [ix, iy]
        kf = self.k_fwd
        # base speed relative to the user: measured by the arm's forward slide, -de_x/dt
        v = v_ff - (kf[0] * ix + kf[1] * ex - kf[2] * float(s.arm_qd[0]))
        g0, dg, ng = self.grid
        u = min(max((speed - g0) / dg, 0.0), ng - 1.0)
        i0 = min(int(u), ng - 2)
        f = u - i0
        a0, a1, a2, a3 = self.k_lat[i0]
        b0, b1, b2, b3 = self.k_lat[i0 + 1]
        w_ff = heading_rate + w_osc
        w = w_ff - ((a0 + f * (b0 - a0)) * iy + (a1 + f * (b1 - a1)) * ey + (a2 + f * (b2 - a2)) * psi_rel
                    + (a3 + f * (b3 - a3)) * (s.base_yaw_rate_rps - w_ff))
        return BaseCommand(float(v), float(w))


LQR_WEIGHTS = tuple(k for k, g in Adaptive.declared_gains.items() if g.search)  # in scheduled_gains' order
OBSERVER = tuple(k for k in Adaptive.declared_gains if k not in (*LQR_WEIGHTS, "i_max"))  # design constants
