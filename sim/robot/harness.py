"""Physical human-robot interface: the harness as a 6-DoF spring-damper with limits (ICRA 2025 Sec. II-C).

A body ``mrba_harness`` hangs from the arm's end through three slides (``mrba_harness_x/_y/_z``, robot
frame) and three hinges (``mrba_harness_yaw/_pitch/_roll``, intrinsic Z-Y-X); it is welded to the
human's pelvis. Each DoF has MuJoCo joint stiffness k and damping d (spring reference 0 = the harness
as donned in the reference posture) and a range, so inside the ranges the transmitted generalised force
is exactly ``F = k q + d q'`` and at a range the joint-limit constraint adds its force. The stiffness,
damping and limits are params (`robot.harness`); the paper gives the structure, not these numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from pydantic import with_config

# DoF order of every per-DoF tuple and of the wrench: forces along x, y, z, torques about x, y, z.
AXES = ("x", "y", "z", "roll", "pitch", "yaw")
HARNESS_JOINTS = tuple(f"mrba_harness_{a}" for a in AXES)
# Kinematic order inside the body: slides x, y, z, then hinges yaw (z), pitch (y), roll (x).
_CHAIN = (0, 1, 2, 5, 4, 3)

Vec6 = tuple[float, float, float, float, float, float]  # x, y, z, roll, pitch, yaw


@with_config(extra="forbid")
@dataclass(frozen=True)
class HarnessParams:
    """Per-DoF stiffness (N/m, N m/rad), damping (N s/m, N m s/rad), half ranges (m, rad)."""

    stiffness: Vec6 = (3000.0, 3000.0, 8000.0, 60.0, 60.0, 40.0)
    damping: Vec6 = (300.0, 300.0, 1000.0, 5.0, 5.0, 3.0)
    range: Vec6 = (0.05, 0.05, 0.05, 0.5, 0.5, 0.7)
    mass_kg: float = 0.5
    weld_timeconst_s: float = 0.005
    limit_timeconst_s: float = 0.005


def add_harness(spec: mujoco.MjSpec, arm_end: mujoco.MjsBody, target_body: str, p: HarnessParams,
                target_quat: np.ndarray) -> None:
    """Hang the harness chain from `arm_end` and weld it to `target_body`.

    With all harness joints at zero the weld holds the target body's origin at the harness origin
    (the arm's neutral point) with the orientation `target_quat` (world frame, robot facing +X): the
    harness as donned in the reference posture.
    """
    body = arm_end.add_body(name="mrba_harness", gravcomp=1.0)
    to_spec_angle = np.degrees(1.0) if spec.compiler.degree else 1.0  # the spec's angle unit
    for i in _CHAIN:
        jtype = mujoco.mjtJoint.mjJNT_SLIDE if i < 3 else mujoco.mjtJoint.mjJNT_HINGE
        half = p.range[i] * (to_spec_angle if i >= 3 else 1.0)
        body.add_joint(name=HARNESS_JOINTS[i], type=jtype, axis=np.eye(3)[i % 3],
                       stiffness=p.stiffness[i], damping=p.damping[i], range=[-half, half], limited=True,
                       solref_limit=[p.limit_timeconst_s, 1.0])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 0.17, 0.04], mass=p.mass_kg,
                  contype=0, conaffinity=0, rgba=[0.2, 0.6, 0.3, 0.6])
    weld = spec.add_equality(name="mrba_harness_weld", type=mujoco.mjtEq.mjEQ_WELD, name1="mrba_harness",
                             name2=target_body, objtype=mujoco.mjtObj.mjOBJ_BODY)
    weld.solref = [p.weld_timeconst_s, 1.0]
    data = np.zeros(len(weld.data))  # anchor 0; relpose: same origin, reference orientation; torquescale 1
    data[6:10] = target_quat
    data[10] = 1.0
    weld.data = data


@dataclass(frozen=True)
class HarnessIndex:
    """Joint ids, qpos and dof addresses of the harness DoFs, in `AXES` order."""

    joints: np.ndarray
    qpos: np.ndarray
    dof: np.ndarray
    axis_of_joint: np.ndarray  # joint id -> harness axis index, -1 for other joints
    range_: np.ndarray  # half ranges

    @classmethod
    def of(cls, model: mujoco.MjModel) -> HarnessIndex:
        ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in HARNESS_JOINTS])
        axis_of_joint = np.full(model.njnt, -1)
        axis_of_joint[ids] = np.arange(6)
        return cls(ids, model.jnt_qposadr[ids].copy(), model.jnt_dofadr[ids].copy(), axis_of_joint,
                   model.jnt_range[ids, 1].copy())


def limit_forces(data: mujoco.MjData, idx: HarnessIndex) -> np.ndarray:
    """Generalised force of the active joint-limit constraints on each harness DoF (`AXES` order).

    A limit row's force is >= 0 and pushes the joint back into its range: + at the lower limit,
    - at the upper one (the sign of -q, since the ranges are symmetric about 0).
    """
    out = np.zeros(6)
    if not (np.abs(data.qpos[idx.qpos]) >= idx.range_).any():  # no harness DoF at a limit
        return out
    rows = np.flatnonzero(data.efc_type == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT)
    if rows.size:
        axis = idx.axis_of_joint[data.efc_id[rows]]
        mine = axis >= 0
        axis, rows = axis[mine], rows[mine]
        np.add.at(out, axis, -np.sign(data.qpos[idx.qpos[axis]]) * data.efc_force[rows])
    return out


def harness_wrench(data: mujoco.MjData, idx: HarnessIndex) -> np.ndarray:
    """Wrench the user exerts on the harness: (fx, fy, fz) N in the robot frame, (tx, ty, tz) N m.

    ``-(spring + damper + limit)`` generalised forces at the harness DoFs, i.e. ``k q + d q'`` inside
    the limits. Valid after `mj_forward` / `mj_step` (then it refers to the start of the last step).
    """
    passive = data.qfrc_spring[idx.dof] + data.qfrc_damper[idx.dof]
    return -(passive + limit_forces(data, idx))


def wrench_from_sensors(model: mujoco.MjModel, idx: HarnessIndex, q: np.ndarray, qd: np.ndarray,
                        limit: np.ndarray) -> np.ndarray:
    """`harness_wrench` for many samples at once from the robot's harness sensors (n, 6) each:
    joint positions, velocities and joint-limit forces (>= 0, pushing back into the range).

    ``k (q - q_spring) + d q' + sign(q) f_limit``: the negated spring, damper and limit forces.
    """
    k = model.jnt_stiffness[idx.joints]
    d = model.dof_damping[idx.dof]
    q_spring = model.qpos_spring[idx.qpos]
    return k * (q - q_spring) + d * qd + np.sign(q) * limit
