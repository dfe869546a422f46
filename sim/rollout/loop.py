"""Closed-loop rollouts: a human driver, the MRBA (optional) and a follow-me controller, one seed.

`rollout` is a pure function of (world, human driver, controller, params, seed): it builds its own
model (`sim.rollout.world`: the compiled world, the physics step grid, the robot's start state), so it
can be called many times and in parallel processes. `RolloutParams` (defined beside the world it
builds, in `sim.rollout.world`) and `RolloutResult` are its input and output; its robot table has the
columns of `ingest.robot.ROBOT_COLUMNS`.

Timing: the controller, the fall rule and the drive act once per control tick (`control_rate_hz`,
100 Hz as on a real mobile base: the command path of a differential drive); the human driver acts
once per output sample (the real capture rate, 100-200 Hz); physics runs at the largest step <=
`max_physics_dt_s` dividing both periods, and the `mj_step(..., nstep)` calls in between run in C.
Per control tick the Python work is a handful of float operations: sensors are read from contiguous
`qpos` / `qvel` views as floats into one reused `RobotSensors`, the controller answers a `BaseCommand`
tuple, the drive writes three servo targets into a `ctrl` view. Per output sample the rollout copies
`qpos` and the robot's sensor block (sim.robot.mrba `SENSORS`) into preallocated arrays; the robot table
(`ingest.robot.ROBOT_COLUMNS`: e_x, e_y, e_z from the arm's joint positions as its encoders read
them, the harness point's offset, base state, harness wrench, commands, fall flags) is computed
from them with numpy after the loop. Recorded sensors are MuJoCo's values of the last physics step
(evaluated at its start, one step before the sample instant; at t = 0, the initial state).

The seed sets the robot's start offset (arm deflection uniform in +-`start_offset_m`, x and y) and
the sensor noise of the arm and odometry.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import mujoco
import numpy as np
import pandas as pd

from ingest.robot import ROBOT_COLUMNS, ROBOT_SIGNAL_COLUMNS
from sim.errors import SimulationError
from sim.motion.driver import HumanDriver
from sim.robot.controllers.base import BaseCommand, Controller, RobotSensors
from sim.robot.fall import FallDetector
from sim.robot.harness import HarnessIndex, wrench_from_sensors
from sim.robot.mrba import SENSOR_WIDTH, SENSORS, BaseDrive, RobotIndex, lock_arm
from sim.rollout.world import RolloutParams, build_world, initial_speed, place_robot, step_grid


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
    initial_state: np.ndarray  # mj_getState(mjSTATE_INTEGRATION) when the loop starts (for benchmarks)

    @property
    def stable(self) -> bool:
        return not self.warnings and bool(np.isfinite(self.world_qpos).all())


StepRecorder = Callable[[mujoco.MjModel, mujoco.MjData, int], None]
_step_recorder: StepRecorder | None = None


@contextmanager
def recording_steps(recorder: StepRecorder) -> Iterator[None]:
    """Within the block, rollouts call `recorder(model, data, nstep)` just before each of their
    `mj_step(model, data, nstep=nstep)` calls: the inputs the loop set for the coming steps can be
    read there (pipeline.bench.policy_rollout replays them through raw `mj_step`). Off by default;
    the rollout's numbers are the same either way."""
    global _step_recorder
    previous, _step_recorder = _step_recorder, recorder
    try:
        yield
    finally:
        _step_recorder = previous


def _recording_step(recorder: StepRecorder) -> Callable[..., None]:
    def step(model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
        recorder(model, data, nstep)
        mujoco.mj_step(model, data, nstep=nstep)
    return step


def _schedule(n_samples: int, n_sample: int, n_control: int) -> list[tuple[int, int, int]]:
    """Events of a rollout as (physics steps to run first, output sample or -1, control tick or -1)."""
    total = (n_samples - 1) * n_sample
    events = sorted(set(range(0, total + 1, n_sample)) | set(range(0, total, n_control)))
    out, prev = [], 0
    for s in events:
        out.append((s - prev, s // n_sample if s % n_sample == 0 else -1,
                    s // n_control if s % n_control == 0 and s < total else -1))
        prev = s
    return out


def _view(arr: np.ndarray, idx: np.ndarray) -> np.ndarray | None:
    """A strided view of `arr[idx]` when the indices are evenly spaced, else None."""
    idx = np.asarray(idx)
    if len(idx) == 1:
        return arr[idx[0]:idx[0] + 1]
    step = int(idx[1] - idx[0])
    if step <= 0 or not np.all(np.diff(idx) == step):
        return None
    return arr[idx[0]:idx[-1] + 1:step]


def rollout(world: mujoco.MjSpec, human: HumanDriver, controller: Controller | None, p: RolloutParams,
            seed: int, model: mujoco.MjModel | None = None, duration_s: float | None = None,
            probe: Callable[[mujoco.MjModel, mujoco.MjData, int], None] | None = None) -> RolloutResult:
    """Run one closed-loop rollout. `model`: a world already built by `build_world` for this `human`
    and `p` (saves compiling in loops); `duration_s`: default the human's motion length; `probe`:
    called with (model, data, sample index) at every output sample, lead-in included (e.g.
    `sim.body.ground_reaction.GroundReactionProbe`). The controller's `RobotInfo.dt_s` must be the
    control period."""
    rng = np.random.default_rng(seed)
    model = build_world(world, human, p) if model is None else model
    dt, n_sample, n_control = step_grid(p.sample_rate_hz, p.max_physics_dt_s, p.control_rate_hz)
    if abs(model.opt.timestep - dt) > 1e-12:
        raise SimulationError(p.trial or "rollout", f"model timestep {model.opt.timestep} is not {dt}")
    dt_control = n_control * dt
    if controller is not None and abs(controller.robot.dt_s - dt_control) > 1e-9:
        raise SimulationError(p.trial or "rollout", f"controller period {controller.robot.dt_s} s differs "
                              f"from the control period {dt_control} s (robot_info(..., control_rate_hz))")
    duration = human.duration_s if duration_s is None else min(duration_s, human.duration_s)
    times = np.arange(int(np.floor(duration * p.sample_rate_hz + 1e-9)) + 1) / p.sample_rate_hz
    n = len(times)
    if n < 2:
        raise SimulationError(p.trial or "rollout", f"motion of {duration:.3f} s is shorter than one sample")
    plan = _schedule(n, n_sample, n_control)
    n_ticks = (n - 1) * n_sample // n_control + (1 if (n - 1) * n_sample % n_control else 0)
    data = mujoco.MjData(model)
    human.reset(model, data, times)
    robot = p.with_robot
    eq_saved = model.eq_data.copy()
    qpos_out = np.zeros((n, model.nq))
    sens_out = np.zeros((n, SENSOR_WIDTH if robot else 0))
    cmd_log: list[BaseCommand] = []
    fall_tick = -1
    if robot:
        rp = p.robot
        idx, hidx = RobotIndex.of(model), HarnessIndex.of(model)
        offset = rng.uniform(-p.start_offset_m, p.start_offset_m, 2)
        place_robot(model, data, idx, hidx, human, p, offset)
        v0 = initial_speed(human, times)
        yaw0 = data.qpos[idx.base_qpos[2]]
        data.qvel[idx.base_dof[:2]] = v0 * np.cos(yaw0), v0 * np.sin(yaw0)
        drive = BaseDrive(rp.base, dt_control)
        drive.reset(v0, 0.0)
        drive.apply(data, idx)
        detector = FallDetector(rp.fall)
        if controller is not None:
            controller.reset()
        sd = np.array([rp.sensors.arm_noise_m] * 3 + [rp.sensors.velocity_noise_mps] * 5)
        noise = (rng.normal(0.0, 1.0, (n_ticks, 8)) * sd).tolist()
        # contiguous views: base x, y, yaw then arm x, y, z (attach_robot adds them in this order)
        qb, vb = idx.base_qpos[0], idx.base_dof[0]
        if not (np.array_equal(np.r_[idx.base_qpos, idx.arm_qpos], qb + np.arange(6))
                and np.array_equal(np.r_[idx.base_dof, idx.arm_dof], vb + np.arange(6))):
            raise SimulationError(p.trial or "rollout", "robot joints are not contiguous in qpos / qvel")
        q_view, v_view = data.qpos[qb:qb + 6], data.qvel[vb:vb + 6]
        ctrl_view = _view(data.ctrl, idx.drive_act)
        sens_view = data.sensordata[idx.sensor_adr:idx.sensor_adr + SENSOR_WIDTH]
        sensors = RobotSensors(0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0)
        stop_cmd = BaseCommand(0.0, 0.0)
    mujoco.mj_forward(model, data)
    initial_state = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(model, data, initial_state, mujoco.mjtState.mjSTATE_INTEGRATION)
    record_hook = type(human).from_world_qpos is HumanDriver.from_world_qpos
    fast = human.sample_controls()
    h_view, h_rows = fast if fast is not None else (None, None)
    locked = False
    cmd = BaseCommand(0.0, 0.0)
    bad_qacc = data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
    qpos = data.qpos
    last = n - 1
    stop_after = None if record_hook else p.stop_after_fall_s  # drivers that take the world qpos only
    n_done = n
    cos, sin = math.cos, math.sin
    step = mujoco.mj_step if _step_recorder is None else _recording_step(_step_recorder)
    start = time.perf_counter()
    try:
        for nstep, k, j in plan:
            if nstep:
                step(model, data, nstep)  # positional: pybind parses no keyword (~0.3 us a call)
            if k >= 0:
                qpos_out[k] = qpos
                if probe is not None:
                    probe(model, data, k)
                if record_hook:
                    human.record(model, data, k)
                if robot:
                    sens_out[k] = sens_view
                if bad_qacc.number:
                    break
                if stop_after is not None:
                    fell = getattr(human, "fall_time_s", None)
                    if fell is not None and times[k] >= fell + stop_after:
                        n_done = k + 1
                        break
            if j >= 0 and robot:
                q = q_view.tolist()
                v = v_view.tolist()
                z = noise[j]
                yaw = q[2]
                c, s = cos(yaw), sin(yaw)
                sensors.time_s = j * dt_control
                sensors.arm_q = (q[3] + z[0], q[4] + z[1], q[5] + z[2])
                sensors.arm_qd = (v[3] + z[3], v[4] + z[4], v[5] + z[5])
                sensors.base_pose = (q[0], q[1], yaw)
                sensors.base_speed_mps = v[0] * c + v[1] * s + z[6]
                sensors.base_yaw_rate_rps = v[2] + z[7]
                if not locked and detector.update(sensors):
                    lock_arm(model, data, idx)
                    locked, fall_tick = True, j
                cmd = controller.step(sensors) if controller is not None and not locked else stop_cmd
                cmd_log.append(cmd)
                vd, wd = drive.step(cmd[0], cmd[1], stop=locked)
                if ctrl_view is not None:  # three scalar writes: cheaper than one from a tuple
                    ctrl_view[0] = vd * c
                    ctrl_view[1] = vd * s
                    ctrl_view[2] = wd
                else:
                    drive.apply(data, idx)
            if 0 <= k < last:
                if h_view is not None:
                    h_view[:] = h_rows[k]
                else:
                    human.before_sample(model, data, k)
    finally:
        model.eq_data[:] = eq_saved
    wall = time.perf_counter() - start
    if n_done < n:  # ended after a fall: keep what was simulated
        n, times, qpos_out, sens_out = n_done, times[:n_done], qpos_out[:n_done], sens_out[:n_done]
    if not record_hook:
        human.from_world_qpos(qpos_out)
    keep = times >= p.discard_s - 1e-9
    human_qpos = human.qpos_samples()[keep]
    fall_time = None if fall_tick < 0 else fall_tick * dt_control - p.discard_s
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number}
    table = pd.DataFrame()
    if robot:
        step_of = np.arange(n) * n_sample
        tick_of = -(-step_of // n_control) - 1  # last control tick strictly before each sample
        cmds = np.vstack([np.zeros((1, 2)), np.array(cmd_log, dtype=float).reshape(-1, 2)])
        cmd_col = cmds[np.clip(tick_of + 1, 0, len(cmds) - 1)]
        fall_col = (step_of > fall_tick * n_control) if fall_tick >= 0 else np.zeros(n, bool)

        def block(name: str) -> np.ndarray:
            a, w = SENSORS[name]
            return sens_out[:, a:a + w]

        yaw = block("base_pos")[:, 2]
        bv = block("base_vel")
        speed = bv[:, 0] * np.cos(yaw) + bv[:, 1] * np.sin(yaw)
        wrench = wrench_from_sensors(model, hidx, block("harness_pos"), block("harness_vel"),
                                     block("harness_limit"))
        rec = np.column_stack([qpos_out[:, idx.arm_qpos], block("e")[:, :2], block("base_pos"), speed,
                               bv[:, 2], cmd_col, wrench])[keep]
        table = pd.DataFrame(rec, columns=ROBOT_SIGNAL_COLUMNS)
        table.insert(0, "time_s", times[keep] - p.discard_s)
        for col, val in reversed(list({"subject": p.subject, "source": "sim", "human_mode": human.mode,
                                       "condition": p.condition, "trial": p.trial, "seed": seed}.items())):
            table.insert(0, col, val)
        table["seed"] = table["seed"].astype("int64")
        table["fall"], table["locked"] = fall_col[keep], fall_col[keep]
        table = table[ROBOT_COLUMNS]
    return RolloutResult(
        time_s=times[keep] - p.discard_s, human_qpos=human_qpos, robot=table, world_qpos=qpos_out[keep],
        fall_time_s=fall_time, physics_dt_s=dt, n_physics_steps=(n - 1) * n_sample,
        wall_s=wall, warnings=warnings, initial_state=initial_state)


__all__ = ["RolloutParams", "RolloutResult", "recording_steps", "rollout"]
