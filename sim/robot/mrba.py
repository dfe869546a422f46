"""The Mobile Robotic Balance Assistant (MRBA) twin, built with `mujoco.MjSpec` and attached to a world.

The real MRBA (NTU Singapore / Tan Tock Seng Hospital, press release 2022; Wang, Chan et al. ICRA 2025)
is a wheeled, battery-powered base that follows *behind* the user and holds a padded harness worn
around the hips through a passive arm; it stops and locks the arm when it detects a fall. The press
material gives no dimensions; the ~100 kg, ~1 m tall, ~0.7 m wide figures of DESIGN.md are used
and live in params.yaml (`robot.base`).

Model (every name prefixed ``mrba_``):

- ``mrba_base``: planar joints ``mrba_base_x``, ``mrba_base_y`` (world slides) and ``mrba_base_yaw``
  (hinge), driven by three velocity servos (``mrba_drive_*``). The differential drive is expressed by
  the servo targets: world velocity ``v (cos yaw, sin yaw)`` and yaw rate ``w`` -- the lateral target
  is always zero, so the base is non-holonomic, and the force limits play the wheels' traction. The
  base has no floor contact, so it cannot tip; a 100 kg base under a stiff velocity servo is not
  pushed around by harness forces of tens of newtons (the servo gain is `drive_gain_n_per_mps`).
  Command latency and acceleration limits are applied to the commands in `BaseDrive` (Python,
  per control sample), before the servo.
- Passive 3-DoF arm: ``mrba_arm_x`` (forward), ``mrba_arm_y`` (lateral), ``mrba_arm_z`` (vertical)
  slides in series, with damping and friction loss from params (the paper added friction losses
  empirically) and range limits. The arm is counterbalanced (gravity compensation), as a real
  vertical carriage would be. Joint zero is the arm's *neutral point*, `reach_m` ahead of the base
  centre at the user's standing pelvis height. ``mrba_neutral`` is a site at that point on the base.
- ``mrba_lock_*``: joint equality constraints, inactive until a fall locks the arm.
- The harness (sim.robot.harness) hangs from the arm's end body ``mrba_arm_z``.
- Sensors (``mrba_sens_*``, `SENSORS`, one contiguous block of ``data.sensordata``): the harness
  body's position in the neutral-point frame (e_x, e_y, e_z in the robot frame), base joint positions
  and velocities (odometry), and per harness DoF its position, velocity and joint-limit force, from
  which the harness wrench follows exactly (`sim.robot.harness.wrench_from_sensors`). A rollout records the
  block with one array copy per output sample.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import mujoco
import numpy as np
from pydantic import with_config

from sim.errors import SimulationError
from sim.robot.harness import HARNESS_JOINTS, HarnessParams, add_harness

PREFIX = "mrba_"
BASE_JOINTS = ("mrba_base_x", "mrba_base_y", "mrba_base_yaw")
ARM_JOINTS = ("mrba_arm_x", "mrba_arm_y", "mrba_arm_z")
DRIVE_ACTUATORS = ("mrba_drive_x", "mrba_drive_y", "mrba_drive_yaw")
LOCKS = ("mrba_lock_x", "mrba_lock_y", "mrba_lock_z")
# sensordata block of the robot: name -> (start, width) relative to the block's first value
SENSORS = {"e": (0, 3), "base_pos": (3, 3), "base_vel": (6, 3), "harness_pos": (9, 6), "harness_vel": (15, 6),
           "harness_limit": (21, 6)}
SENSOR_WIDTH = 27


@with_config(extra="forbid")
@dataclass(frozen=True)
class BaseParams:
    """Mobile base: size, mass, drive servo and command limits (params `robot.base`)."""

    mass_kg: float = 100.0
    length_m: float = 0.6
    width_m: float = 0.7
    height_m: float = 1.0
    reach_m: float = 0.55
    drive_gain_n_per_mps: float = 4000.0
    yaw_gain_nm_per_radps: float = 400.0
    max_force_n: float = 800.0
    max_torque_nm: float = 300.0
    max_speed_mps: float = 2.5
    max_yaw_rate_rps: float = 1.5
    max_accel_mps2: float = 2.0
    max_yaw_accel_rps2: float = 4.0
    latency_s: float = 0.03
    control_rate_hz: float = 100.0


@with_config(extra="forbid")
@dataclass(frozen=True)
class ArmParams:
    """Passive arm (forward, lateral, vertical slides): per-joint values, params `robot.arm`."""

    link_mass_kg: float = 2.0
    damping_ns_per_m: tuple[float, float, float] = (20.0, 20.0, 20.0)
    frictionloss_n: tuple[float, float, float] = (5.0, 5.0, 5.0)
    range_m: tuple[float, float, float] = (0.25, 0.2, 0.25)
    lock_timeconst_s: float = 0.005


@with_config(extra="forbid")
@dataclass(frozen=True)
class FallParams:
    """Fall rule on robot-sensed arm signals (params `robot.fall`)."""

    drop_speed_mps: float = 0.7
    drop_m: float = 0.12
    deflection_m: float = 0.22


@with_config(extra="forbid")
@dataclass(frozen=True)
class SensorParams:
    """Noise of the robot's own sensors (params `robot.sensors`)."""

    arm_noise_m: float = 0.0005
    velocity_noise_mps: float = 0.005


@dataclass(frozen=True)
class RobotParams:
    """The MRBA's parts: `robot.base`, `robot.arm`, `robot.harness`, `robot.fall`, `robot.sensors` of
    params.yaml (`sim.robot.section.RobotSection` is the whole section)."""

    base: BaseParams = BaseParams()
    arm: ArmParams = ArmParams()
    harness: HarnessParams = HarnessParams()
    fall: FallParams = FallParams()
    sensors: SensorParams = SensorParams()


def body_pose_at_qpos0(spec: mujoco.MjSpec, body: str) -> tuple[np.ndarray, np.ndarray]:
    """World position and quaternion of `body` at the world's reference configuration."""
    model = spec.copy().compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0:
        raise SimulationError(spec.modelname or "world", f"no body {body!r} to attach the harness to")
    return data.xpos[bid].copy(), data.xquat[bid].copy()


def attach_robot(spec: mujoco.MjSpec, p: RobotParams, harness_body: str = "pelvis",
                 neutral_height_m: float | None = None) -> None:
    """Add the MRBA behind `harness_body` (in place): base, arm, locks and harness welded to it.

    The arm's neutral point is placed above the body's reference-configuration position at
    `neutral_height_m` (default: the body's height there), the base `reach_m` behind it along -X
    (the human faces +X at qpos0).
    """
    pelvis_pos, pelvis_quat = body_pose_at_qpos0(spec, harness_body)
    if neutral_height_m is not None:
        pelvis_pos = np.array([pelvis_pos[0], pelvis_pos[1], neutral_height_m])
    b, a = p.base, p.arm
    base = spec.worldbody.add_body(name="mrba_base", pos=[pelvis_pos[0] - b.reach_m, pelvis_pos[1], 0.0])
    slide, hinge = mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE
    for name, jtype, axis in zip(BASE_JOINTS, (slide, slide, hinge), np.eye(3), strict=True):
        base.add_joint(name=name, type=jtype, axis=axis)
    box = mujoco.mjtGeom.mjGEOM_BOX
    chassis_h = 0.3
    arm_mass = 3 * a.link_mass_kg
    base.add_geom(name="mrba_chassis", type=box, size=[b.length_m / 2, b.width_m / 2, chassis_h / 2],
                  pos=[0, 0, chassis_h / 2], mass=0.85 * (b.mass_kg - arm_mass), contype=0, conaffinity=0,
                  rgba=[0.3, 0.35, 0.45, 1])
    mast_h = b.height_m - chassis_h
    base.add_geom(name="mrba_mast", type=box, size=[0.08, 0.25, mast_h / 2],
                  pos=[-b.length_m / 2 + 0.1, 0, chassis_h + mast_h / 2],
                  mass=0.15 * (b.mass_kg - arm_mass), contype=0, conaffinity=0, rgba=[0.3, 0.35, 0.45, 1])
    z0 = pelvis_pos[2]
    base.add_site(name="mrba_neutral", pos=[b.reach_m, 0, z0], size=[0.02, 0, 0])
    parent = base
    offsets = ([b.reach_m, 0, z0], [0, 0, 0], [0, 0, 0])
    for i, name in enumerate(ARM_JOINTS):
        link = parent.add_body(name=name, pos=offsets[i], gravcomp=1.0)
        link.add_joint(name=name, type=slide, axis=np.eye(3)[i], damping=a.damping_ns_per_m[i],
                       frictionloss=a.frictionloss_n[i], range=[-a.range_m[i], a.range_m[i]], limited=True)
        link.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.03, 0, 0], mass=a.link_mass_kg,
                      contype=0, conaffinity=0, rgba=[0.8, 0.5, 0.1, 1])
        parent = link
    parent.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[-b.reach_m + 0.1, 0, 0, -0.15, 0, 0],
                    size=[0.025, 0, 0], mass=0.0, contype=0, conaffinity=0, rgba=[0.8, 0.5, 0.1, 1])
    for name, joint in zip(LOCKS, ARM_JOINTS, strict=True):
        lock = spec.add_equality(name=name, type=mujoco.mjtEq.mjEQ_JOINT, name1=joint, active=False,
                                 objtype=mujoco.mjtObj.mjOBJ_JOINT)
        lock.data = np.zeros(len(lock.data))  # joint = polycoef[0], set when the lock engages
        lock.solref = [a.lock_timeconst_s, 1.0]
    gains = (b.drive_gain_n_per_mps, b.drive_gain_n_per_mps, b.yaw_gain_nm_per_radps)
    limits = (b.max_force_n, b.max_force_n, b.max_torque_nm)
    for name, joint, kv, lim in zip(DRIVE_ACTUATORS, BASE_JOINTS, gains, limits, strict=True):
        act = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=kv)
        act.forcelimited = True
        act.forcerange = [-lim, lim]
    add_harness(spec, parent, harness_body, p.harness, pelvis_quat)
    add_sensors(spec, harness_body)


# Virtual markers on the robot (`robot_markers`): two on the mast along the heading, one on the arm's end
ROBOT_MARKERS = ("MRBA_base_front", "MRBA_base_rear", "MRBA_arm_end")
BASE_MARKER_OFFSETS_M = ((0.25, 0.0, 0.5), (-0.25, 0.0, 0.5))  # base frame, from the base body's origin


def robot_markers(model: mujoco.MjModel, world_qpos: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Positions (n, 3) of `ROBOT_MARKERS` along the world configurations `world_qpos` (n, nq), and
    the arm's neutral point relative to the base markers' midpoint in the base frame (what a lab
    declares as `robot_markers.neutral_in_base_m`, ingest.subject.RobotMarkers)."""
    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "mrba_base")
    arm_end = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, ARM_JOINTS[-1])
    neutral = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "mrba_neutral")
    if min(base, arm_end, neutral) < 0:
        raise SimulationError("world", "robot markers need the MRBA (attach_robot)")
    data = mujoco.MjData(model)
    offsets = np.array(BASE_MARKER_OFFSETS_M)
    out = np.empty((len(world_qpos), 3, 3))
    for k, q in enumerate(np.atleast_2d(world_qpos)):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        rot = data.xmat[base].reshape(3, 3)
        out[k, :2] = data.xpos[base] + offsets @ rot.T
        out[k, 2] = data.xpos[arm_end]
    midpoint = offsets.mean(axis=0)
    neutral_in_base = model.site_pos[neutral] - midpoint if model.site_bodyid[neutral] == base else None
    if neutral_in_base is None:
        raise SimulationError("world", "the neutral point is not on the base body")
    return {name: out[:, j].copy() for j, name in enumerate(ROBOT_MARKERS)}, neutral_in_base


def add_sensors(spec: mujoco.MjSpec, harness_body: str) -> None:
    """The robot's sensor block (`SENSORS` order); see the module docstring."""
    S, obj = mujoco.mjtSensor, mujoco.mjtObj
    spec.add_sensor(name="mrba_sens_e", type=S.mjSENS_FRAMEPOS, objtype=obj.mjOBJ_XBODY, objname=harness_body,
                    reftype=obj.mjOBJ_SITE, refname="mrba_neutral")
    for kind, stype in (("pos", S.mjSENS_JOINTPOS), ("vel", S.mjSENS_JOINTVEL)):
        for j in BASE_JOINTS:
            spec.add_sensor(name=f"mrba_sens_{kind}_{j}", type=stype, objtype=obj.mjOBJ_JOINT, objname=j)
    harness_kinds = (("pos", S.mjSENS_JOINTPOS), ("vel", S.mjSENS_JOINTVEL), ("lim", S.mjSENS_JOINTLIMITFRC))
    for kind, stype in harness_kinds:
        for j in HARNESS_JOINTS:
            spec.add_sensor(name=f"mrba_sens_{kind}_{j}", type=stype, objtype=obj.mjOBJ_JOINT, objname=j)


@dataclass(frozen=True)
class RobotIndex:
    """Addresses of the robot's joints, actuators and locks in a compiled model."""

    base_qpos: np.ndarray
    base_dof: np.ndarray
    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    drive_act: np.ndarray
    locks: np.ndarray
    neutral_site: int
    base_body: int
    sensor_adr: int  # first value of the robot's sensor block in data.sensordata

    @classmethod
    def of(cls, model: mujoco.MjModel) -> RobotIndex:
        def jid(n):
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
            if i < 0:
                raise SimulationError("model", f"no robot joint {n!r}: was attach_robot called?")
            return i

        base = [jid(n) for n in BASE_JOINTS]
        arm = [jid(n) for n in ARM_JOINTS]
        return cls(
            base_qpos=model.jnt_qposadr[base].copy(), base_dof=model.jnt_dofadr[base].copy(),
            arm_qpos=model.jnt_qposadr[arm].copy(), arm_dof=model.jnt_dofadr[arm].copy(),
            drive_act=np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n)
                                for n in DRIVE_ACTUATORS]),
            locks=np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, n) for n in LOCKS]),
            neutral_site=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "mrba_neutral"),
            base_body=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "mrba_base"),
            sensor_adr=int(model.sensor_adr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR,
                                                               "mrba_sens_e")]),
        )


def lock_arm(model: mujoco.MjModel, data: mujoco.MjData, idx: RobotIndex) -> None:
    """Lock the arm where it is now: activate the joint equalities with their current positions."""
    model.eq_data[idx.locks, 0] = data.qpos[idx.arm_qpos]
    data.eq_active[idx.locks] = 1


class BaseDrive:
    """Differential-drive command path: latency FIFO, saturation, acceleration limits, servo targets.

    Commands (forward speed, yaw rate) are delayed by `latency_s` (rounded to control ticks of
    `dt_s`), clipped to the speed limits and rate-limited by the acceleration limits, then written as
    the velocity-servo targets of the planar base joints once per control tick (the base heading
    changes by < 0.02 rad within a 10 ms tick, so the non-holonomic targets stay aligned).
    """

    def __init__(self, p: BaseParams, dt_s: float) -> None:
        self.p, self.dt_s = p, dt_s
        self.delay = deque([(0.0, 0.0)] * max(int(round(p.latency_s / dt_s)), 0))
        self.v = 0.0
        self.w = 0.0
        # limits as plain floats (read every control tick)
        self._vmax, self._wmax = p.max_speed_mps, p.max_yaw_rate_rps
        self._dv, self._dw = p.max_accel_mps2 * dt_s, p.max_yaw_accel_rps2 * dt_s

    def reset(self, v: float = 0.0, w: float = 0.0) -> None:
        self.delay = deque([(v, w)] * len(self.delay))
        self.v, self.w = v, w

    def step(self, speed_mps: float, yaw_rate_rps: float, stop: bool = False) -> tuple[float, float]:
        """Apply one control sample's command; returns the (speed, yaw rate) reference now in force."""
        self.delay.append((0.0, 0.0) if stop else (speed_mps, yaw_rate_rps))
        v_cmd, w_cmd = self.delay.popleft()
        if stop:
            v_cmd = w_cmd = 0.0
        vmax, wmax, dv, dw = self._vmax, self._wmax, self._dv, self._dw
        v_cmd = min(max(v_cmd, -vmax), vmax)
        w_cmd = min(max(w_cmd, -wmax), wmax)
        self.v += min(max(v_cmd - self.v, -dv), dv)
        self.w += min(max(w_cmd - self.w, -dw), dw)
        return self.v, self.w

    def apply(self, data: mujoco.MjData, idx: RobotIndex) -> None:
        """Write the servo targets: world velocity along the base heading, yaw rate."""
        yaw = data.qpos[idx.base_qpos[2]]
        data.ctrl[idx.drive_act] = (self.v * math.cos(yaw), self.v * math.sin(yaw), self.w)
