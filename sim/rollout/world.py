"""World assembly for rollouts: what a rollout is built from (`RolloutParams`), the physics step
grid, the compiled world (human prepared by its driver, plus the robot), the robot constants a
controller may model, and the robot's start state.

The physics step is the largest dt <= `max_physics_dt_s` that divides both the output sample period
and the control period (`step_grid`), so samples and control ticks fall on physics steps. The robot
starts at rest relative to the human: the arm deflected by a seeded offset, its neutral point under
the pelvis, the harness hinges at the pelvis' orientation relative to the arm end, and the base
moving at the pelvis' initial speed along its heading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from sim.errors import SimulationError
from sim.motion.driver import HumanDriver
from sim.robot.controllers.base import RobotInfo
from sim.robot.harness import HarnessIndex
from sim.robot.mrba import RobotIndex, RobotParams, attach_robot


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
    stop_after_fall_s: float | None = None  # a human that fell (its driver's `fall_time_s`) is simulated
                                            # this much longer, then the rollout ends (None: to the end)

    @property
    def control_rate_hz(self) -> float:
        """The robot's control rate (params `robot.base.control_rate_hz`)."""
        return self.robot.base.control_rate_hz


def _period(rate_hz: float) -> Fraction:
    return 1 / Fraction(rate_hz).limit_denominator(1000)


def step_grid(sample_rate_hz: float, max_dt_s: float, control_rate_hz: float | None = None
              ) -> tuple[float, int, int]:
    """(physics dt, steps per output sample, steps per control tick): the largest dt <= `max_dt_s`
    dividing both periods (control rate default: the sample rate)."""
    ps = _period(sample_rate_hz)
    pc = ps if control_rate_hz is None else _period(control_rate_hz)
    g = Fraction(math.gcd(ps.numerator * pc.denominator, pc.numerator * ps.denominator),
                 ps.denominator * pc.denominator)
    n = int(math.ceil(float(g) / max_dt_s - 1e-9))
    dt = g / n
    return float(dt), int(ps / dt), int(pc / dt)


def physics_steps(sample_rate_hz: float, max_dt_s: float, control_rate_hz: float | None = None
                  ) -> tuple[float, int]:
    """(physics dt, steps per output sample); see `step_grid`."""
    dt, n_sample, _ = step_grid(sample_rate_hz, max_dt_s, control_rate_hz)
    return dt, n_sample


def build_world(world: mujoco.MjSpec, human: HumanDriver, p: RolloutParams) -> mujoco.MjModel:
    """Compile the rollout world: a copy of `world` prepared by the human driver, plus the robot."""
    spec = world.copy()
    human.prepare(spec)
    if p.with_robot:
        attach_robot(spec, p.robot, p.harness_body, neutral_height_m=float(human.start_pose()[0][2]))
    dt, _ = physics_steps(p.sample_rate_hz, p.max_physics_dt_s, p.control_rate_hz)
    spec.option.timestep = dt
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    try:
        return spec.compile()
    except ValueError as exc:
        raise SimulationError(world.modelname or "world", f"rollout world does not compile ({exc})") from None


def robot_info(p: RobotParams, control_rate_hz: float | None = None) -> RobotInfo:
    """Constants a controller may model: reach, drive lag (latency + servo time constant), control
    period (default the robot's `control_rate_hz`), latency."""
    b = p.base
    control_rate_hz = b.control_rate_hz if control_rate_hz is None else control_rate_hz
    tau = b.latency_s + (b.mass_kg + 3 * p.arm.link_mass_kg) / b.drive_gain_n_per_mps
    return RobotInfo(reach_m=b.reach_m, drive_tau_s=tau, dt_s=1.0 / control_rate_hz, latency_s=b.latency_s)


def place_robot(model: mujoco.MjModel, data: mujoco.MjData, idx: RobotIndex, hidx: HarnessIndex,
                human: HumanDriver, p: RolloutParams, offset: np.ndarray) -> None:
    """Robot at rest-relative start: arm deflected by `offset`, neutral point under the pelvis."""
    pelvis, yaw = human.start_pose()
    b = p.robot.base
    base_spec = model.body_pos[idx.base_body]
    heading = Rotation.from_euler("z", yaw)
    rot = heading.as_matrix()[:2, :2]
    neutral = pelvis[:2] - rot @ offset
    base_world = neutral - rot @ np.array([b.reach_m, 0.0])
    data.qpos[idx.base_qpos] = (*(base_world - base_spec[:2]), yaw)
    z_neutral = model.body_pos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "mrba_arm_x")][2]
    data.qpos[idx.arm_qpos] = (offset[0], offset[1], pelvis[2] - z_neutral)
    # harness hinges: pelvis orientation relative to the arm end, relative to the reference pose
    mujoco.mj_kinematics(model, data)
    pid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, p.harness_body)
    pelvis_rot = Rotation.from_quat(data.xquat[pid], scalar_first=True)
    q_ref = model.eq_data[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, "mrba_harness_weld"), 6:10]
    rel = heading.inv() * pelvis_rot * Rotation.from_quat(q_ref, scalar_first=True).inv()
    data.qpos[hidx.qpos[3:]] = rel.as_euler("ZYX")[::-1]  # AXES order: roll, pitch, yaw


def initial_speed(human: HumanDriver, times_s: np.ndarray) -> float:
    """Pelvis speed over the first 0.2 s of the motion, along its heading (0 when it starts at rest)."""
    if not hasattr(human, "target"):
        return 0.0
    k = min(max(int(round(0.2 / (times_s[1] - times_s[0]))), 1), len(times_s) - 1)
    d = human.target[k, :2] - human.target[0, :2]
    _, yaw = human.start_pose()
    return float(d @ np.array([np.cos(yaw), np.sin(yaw)]) / (times_s[k] - times_s[0]))


__all__ = ["RolloutParams", "build_world", "initial_speed", "physics_steps", "place_robot", "robot_info",
           "step_grid"]
