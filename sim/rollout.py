"""Closed-loop rollouts: a human driver, the MRBA (optional) and a follow-me controller, one seed.

`rollout` is a pure function of (world, human driver, controller, params, seed): it builds its own
model, so it can be called many times and in parallel processes. Physics runs at the largest step
<= `max_physics_dt_s` that divides the output sample period; the controller, the fall rule, the
drive and the human driver act once per output sample (the real capture rate, 100-200 Hz), and the
`mj_step(..., nstep)` call in between runs in C. Each sample records the state at the start of the
last physics step (MuJoCo's derived quantities of that step): e, harness wrench and base state share
that instant.

The seed sets the robot's start offset (arm deflection uniform in +-`start_offset_m`, x and y) and
the sensor noise of the arm and odometry.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np
import pandas as pd

from sim.controllers.base import BaseCommand, Controller, RobotInfo, RobotSensors
from sim.errors import SimulationError
from sim.fall import FallDetector
from sim.harness import HarnessIndex, harness_wrench
from sim.replay import HumanDriver, quat_conj, quat_mul, quat_to_zyx
from sim.robot import BaseDrive, RobotIndex, RobotParams, attach_robot, lock_arm

ROBOT_COLUMNS = ["subject", "source", "human_mode", "condition", "trial", "seed", "time_s", "e_x_m", "e_y_m",
                 "base_x_m", "base_y_m", "base_yaw_rad", "base_speed_mps", "base_yaw_rate_rps",
                 "cmd_speed_mps", "cmd_yaw_rate_rps", "harness_fx_n", "harness_fy_n", "harness_fz_n",
                 "harness_tx_nm", "harness_ty_nm", "harness_tz_nm", "fall", "locked"]


@dataclass(frozen=True)
class RolloutParams:
    """Everything a rollout needs besides the world, human driver, controller and seed."""

    robot: RobotParams
    sample_rate_hz: float = 100.0
    max_physics_dt_s: float = 0.002
    start_offset_m: float = 0.03
    with_robot: bool = True
    harness_body: str = "pelvis"
    subject: str = ""
    condition: str = ""
    trial: str = ""
    discard_s: float = 0.0  # lead-in simulated but not returned; returned time 0 is this instant


@dataclass(frozen=True)
class RolloutResult:
    """Samples of one rollout: human qpos (human model layout), robot table, full world qpos."""

    time_s: np.ndarray
    human_qpos: np.ndarray
    robot: pd.DataFrame
    world_qpos: np.ndarray
    fall_time_s: float | None
    physics_dt_s: float
    n_physics_steps: int
    wall_s: float
    warnings: dict[str, int]

    @property
    def stable(self) -> bool:
        return not self.warnings and bool(np.isfinite(self.world_qpos).all())


def physics_steps(sample_rate_hz: float, max_dt_s: float) -> tuple[float, int]:
    """(physics dt, steps per sample): the largest dt <= `max_dt_s` dividing the sample period."""
    n = int(np.ceil(1.0 / sample_rate_hz / max_dt_s - 1e-9))
    return 1.0 / sample_rate_hz / n, n


def build_world(world: mujoco.MjSpec, human: HumanDriver, p: RolloutParams) -> mujoco.MjModel:
    """Compile the rollout world: a copy of `world` prepared by the human driver, plus the robot."""
    spec = world.copy()
    human.prepare(spec)
    if p.with_robot:
        attach_robot(spec, p.robot, p.harness_body, neutral_height_m=float(human.start_pose()[0][2]))
    dt, _ = physics_steps(p.sample_rate_hz, p.max_physics_dt_s)
    spec.option.timestep = dt
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    try:
        return spec.compile()
    except ValueError as exc:
        raise SimulationError(world.modelname or "world", f"rollout world does not compile ({exc})") from None


def robot_info(p: RobotParams, sample_rate_hz: float) -> RobotInfo:
    """Constants a controller may model: reach, drive lag (latency + servo time constant), period."""
    b = p.base
    tau = b.latency_s + (b.mass_kg + 3 * p.arm.link_mass_kg) / b.drive_gain_n_per_mps
    return RobotInfo(reach_m=b.reach_m, drive_tau_s=tau, dt_s=1.0 / sample_rate_hz)


def _rot2(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _place_robot(model, data, idx: RobotIndex, hidx: HarnessIndex, human: HumanDriver, p: RolloutParams,
                 offset: np.ndarray) -> None:
    """Robot at rest-relative start: arm deflected by `offset`, neutral point under the pelvis."""
    pelvis, yaw = human.start_pose()
    b = p.robot.base
    base_spec = model.body_pos[idx.base_body]
    rot = _rot2(yaw)
    neutral = pelvis[:2] - rot @ offset
    base_world = neutral - rot @ np.array([b.reach_m, 0.0])
    data.qpos[idx.base_qpos] = (*(base_world - base_spec[:2]), yaw)
    z_neutral = model.body_pos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "mrba_arm_x")][2]
    data.qpos[idx.arm_qpos] = (offset[0], offset[1], pelvis[2] - z_neutral)
    # harness hinges: pelvis orientation relative to the arm end, relative to the reference pose
    mujoco.mj_kinematics(model, data)
    pid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, p.harness_body)
    q_pelvis = data.xquat[pid].copy()
    q_ref = model.eq_data[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, "mrba_harness_weld"), 6:10]
    q_yaw = np.array([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)])
    rel = quat_mul(quat_conj(q_yaw), quat_mul(q_pelvis, quat_conj(q_ref)))
    ypr = quat_to_zyx(rel)[0]
    data.qpos[hidx.qpos[3:]] = ypr[::-1]  # AXES order: roll, pitch, yaw


def _initial_speed(human: HumanDriver, times_s: np.ndarray) -> float:
    """Pelvis speed over the first 0.2 s of the motion, along its heading (0 when it starts at rest)."""
    if not hasattr(human, "target"):
        return 0.0
    k = min(max(int(round(0.2 / (times_s[1] - times_s[0]))), 1), len(times_s) - 1)
    d = human.target[k, :2] - human.target[0, :2]
    _, yaw = human.start_pose()
    return float(d @ np.array([np.cos(yaw), np.sin(yaw)]) / (times_s[k] - times_s[0]))


def rollout(world: mujoco.MjSpec, human: HumanDriver, controller: Controller | None, p: RolloutParams,
            seed: int, model: mujoco.MjModel | None = None, duration_s: float | None = None) -> RolloutResult:
    """Run one closed-loop rollout. `model`: a world already built by `build_world` for this `human`
    and `p` (saves compiling in loops); `duration_s`: default the human's motion length."""
    rng = np.random.default_rng(seed)
    model = build_world(world, human, p) if model is None else model
    dt, n_sub = physics_steps(p.sample_rate_hz, p.max_physics_dt_s)
    duration = human.duration_s if duration_s is None else min(duration_s, human.duration_s)
    times = np.arange(int(np.floor(duration * p.sample_rate_hz + 1e-9)) + 1) / p.sample_rate_hz
    n = len(times)
    if n < 2:
        raise SimulationError(p.trial or "rollout", f"motion of {duration:.3f} s is shorter than one sample")
    data = mujoco.MjData(model)
    human.reset(model, data, times)
    robot = p.with_robot
    eq_saved = model.eq_data.copy()
    rec = np.zeros((n, 17))
    fall_col, lock_col = np.zeros(n, bool), np.zeros(n, bool)
    qpos_out = np.zeros((n, model.nq))
    if robot:
        rp = p.robot
        idx, hidx = RobotIndex.of(model), HarnessIndex.of(model)
        offset = rng.uniform(-p.start_offset_m, p.start_offset_m, 2)
        _place_robot(model, data, idx, hidx, human, p, offset)
        v0 = _initial_speed(human, times)
        yaw0 = data.qpos[idx.base_qpos[2]]
        data.qvel[idx.base_dof[:2]] = v0 * np.cos(yaw0), v0 * np.sin(yaw0)
        drive = BaseDrive(rp.base, 1.0 / p.sample_rate_hz)
        drive.reset(v0, 0.0)
        drive.apply(data, idx)
        detector = FallDetector(rp.fall)
        if controller is not None:
            controller.reset()
        pelvis_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, p.harness_body)
        sd = np.array([rp.sensors.arm_noise_m] * 3 + [rp.sensors.velocity_noise_mps] * 5)
        noise_all = rng.normal(0.0, 1.0, (n, 8)) * sd
    mujoco.mj_forward(model, data)
    cmd = BaseCommand(0.0, 0.0)
    locked = False
    start = time.perf_counter()

    def record(k: int) -> None:
        human.record(model, data, k)
        qpos_out[k] = data.qpos
        if not robot:
            return
        yaw = data.qpos[idx.base_qpos[2]]
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = data.xpos[pelvis_id, :2] - data.site_xpos[idx.neutral_site, :2]
        vb = data.qvel[idx.base_dof]
        speed = vb[0] * c + vb[1] * s
        rec[k, :2] = c * dx + s * dy, -s * dx + c * dy
        rec[k, 2:5] = data.qpos[idx.base_qpos]
        rec[k, 5:7] = speed, vb[2]
        rec[k, 7:9] = cmd.speed_mps, cmd.yaw_rate_rps
        rec[k, 9:15] = harness_wrench(data, hidx)
        fall_col[k], lock_col[k] = detector.detected, locked

    try:
        record(0)
        for k in range(n - 1):
            if robot:
                vb = data.qvel[idx.base_dof]
                yaw = data.qpos[idx.base_qpos[2]]
                noise = noise_all[k]
                sensors = RobotSensors(
                    time_s=float(times[k]),
                    arm_q=data.qpos[idx.arm_qpos] + noise[:3],
                    arm_qd=data.qvel[idx.arm_dof] + noise[3:6],
                    base_pose=data.qpos[idx.base_qpos].copy(),
                    base_speed_mps=float(vb[0] * math.cos(yaw) + vb[1] * math.sin(yaw) + noise[6]),
                    base_yaw_rate_rps=float(vb[2] + noise[7]))
                if detector.update(sensors) and not locked:
                    lock_arm(model, data, idx)
                    locked = True
                if controller is not None and not locked:
                    cmd = controller.step(sensors)
                else:
                    cmd = BaseCommand(0.0, 0.0)
                drive.step(cmd.speed_mps, cmd.yaw_rate_rps, stop=locked)
                drive.apply(data, idx)
            human.before_sample(model, data, k)
            mujoco.mj_step(model, data, nstep=n_sub)
            record(k + 1)
            if not np.isfinite(data.qacc).all():
                break
    finally:
        model.eq_data[:] = eq_saved
    wall = time.perf_counter() - start
    keep = times >= p.discard_s - 1e-9
    human_qpos = human.qpos_samples()[keep]
    times, rec, fall_col, lock_col, qpos_out = times[keep] - p.discard_s, rec[keep], fall_col[keep], \
        lock_col[keep], qpos_out[keep]
    fall_time = None
    if robot and detector.time_s is not None:
        fall_time = detector.time_s - p.discard_s
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number}
    table = pd.DataFrame()
    if robot:
        table = pd.DataFrame(rec[:, :15], columns=ROBOT_COLUMNS[7:22])
        table.insert(0, "time_s", times)
        for col, val in reversed(list({"subject": p.subject, "source": "sim", "human_mode": human.mode,
                                       "condition": p.condition, "trial": p.trial, "seed": seed}.items())):
            table.insert(0, col, val)
        table["seed"] = table["seed"].astype("int64")
        table["fall"], table["locked"] = fall_col, lock_col
        table = table[ROBOT_COLUMNS]
    return RolloutResult(
        time_s=times, human_qpos=human_qpos, robot=table, world_qpos=qpos_out,
        fall_time_s=fall_time, physics_dt_s=dt, n_physics_steps=(n - 1) * n_sub,
        wall_s=wall, warnings=warnings)


__all__ = ["ROBOT_COLUMNS", "RolloutParams", "RolloutResult", "build_world", "physics_steps", "robot_info",
           "rollout"]
