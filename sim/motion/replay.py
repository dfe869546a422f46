"""The kinematic human driver `ReplayHuman` and the motions it replays.

`ReplayHuman` (human mode ``replay``) makes the subject's recorded motion drive the human:

- All human joints are removed from the physics world; the body keeps its reference posture as one
  rigid body with the whole body mass, so the harness carries and is loaded by a body of the
  subject's mass. The limb motion is not needed by the robot and is taken straight from the
  reference when the human's qpos is sampled.
- The free root is replaced by six drive joints on the pelvis (world slides x, y, z, then hinges
  yaw, pitch, roll about the pelvis axes), each servoed to the reference by
  ``k (target - q) + d (v_target - q')`` where the target moves linearly between output samples
  (integrator actuator + velocity actuator, so no Python runs per physics step). The vertical servo
  adds the body weight as feed-forward and can only push up (legs cannot pull the pelvis down), so
  when the reference drops (a fall) and the harness holds, the body hangs in the harness with its
  weight. The servo gains are params (`rollout.replay`); they are stiff, so the pelvis follows
  the recording within millimetres while the harness forces stay small.
- Human geoms do not collide (the replayed feet would fight the floor).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from pydantic import with_config
from scipy.spatial.transform import Rotation

from sim.errors import SimulationError
from sim.motion.driver import HumanDriver

DRIVE_JOINTS = ("replay_x", "replay_y", "replay_z", "replay_yaw", "replay_pitch", "replay_roll")


@dataclass(frozen=True)
class Motion:
    """A human motion: `qpos` (n, nq) in the human model's layout sampled at `time_s` (n,)."""

    time_s: np.ndarray
    qpos: np.ndarray


@with_config(extra="forbid")
@dataclass(frozen=True)
class ReplayParams:
    """Servo of the replayed pelvis (params `rollout.replay`): spring (N/m, N m/rad), damper (N s/m,
    N m s/rad) and limits of the force and torque that pull it along the recorded path."""

    kp_n_per_m: float = 60000.0
    kd_ns_per_m: float = 3000.0
    kp_nm_per_rad: float = 3000.0
    kd_nms_per_rad: float = 150.0
    max_force_n: float = 5000.0
    max_torque_nm: float = 500.0
    max_vertical_bodyweights: float = 3.0  # the vertical force at most, in body weights


def interpolate_qpos(motion: Motion, times_s: np.ndarray, root_adr: int) -> np.ndarray:
    """Linear interpolation of every qpos column; the root quaternion is renormalised."""
    out = np.column_stack([np.interp(times_s, motion.time_s, c) for c in motion.qpos.T])
    q = out[:, root_adr + 3:root_adr + 7]
    out[:, root_adr + 3:root_adr + 7] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return out


def scripted_fall(motion: Motion, t_fall_s: float, drop_m: float, duration_s: float,
                  root_adr: int = 0) -> Motion:
    """`motion` with a scripted fall from `t_fall_s`: the root drops `drop_m` over `duration_s`
    (smoothstep) and stays down, and its horizontal progression fades out over the same time (a
    falling person stops walking). Issue 4 uses 20 cm in 0.3 s."""
    t = motion.time_s
    u = np.clip((t - t_fall_s) / duration_s, 0, 1)
    s = 3 * u**2 - 2 * u**3
    qpos = motion.qpos.copy()
    qpos[:, root_adr + 2] -= drop_m * s
    xy = motion.qpos[:, root_adr:root_adr + 2]
    step = np.diff(xy, axis=0) * (1 - s[1:, None])  # progression scaled down as the fall proceeds
    qpos[:, root_adr:root_adr + 2] = xy[0] + np.vstack([np.zeros((1, 2)), np.cumsum(step, axis=0)])
    return Motion(t, qpos)


def with_lead_in(motion: Motion, stride_s: float, lead_in_s: float, ramp_s: float,
                 root_adr: int = 0) -> Motion:
    """`motion` preceded by `lead_in_s` of walking that starts from rest and ramps (smoothstep over
    `ramp_s`) up to the motion's opening pace, so a rollout of a mid-walk bout does not begin with
    the robot and controller in an arbitrary state. The lead-in repeats the first `stride_s` of the
    motion: its mean root velocity scaled by the ramp plus its intra-stride oscillation scaled the
    same way, joined continuously at the bout start; time 0 stays the bout start (lead-in times < 0).
    """
    t = motion.time_s - motion.time_s[0]
    dt = float(np.median(np.diff(t)))
    n_stride = min(int(np.searchsorted(t, stride_s)), len(t) - 1)  # a bout shorter than a stride: all of it
    if n_stride < 4:
        raise SimulationError("replay motion", f"cannot take a {stride_s:.2f} s stride from {t[-1]:.2f} s")
    first = motion.qpos[:n_stride + 1]
    a = root_adr
    v_mean = (first[-1, a:a + 2] - first[0, a:a + 2]) / (t[n_stride] - t[0])
    residual = first[:, a:a + 2] - first[0, a:a + 2] - np.outer(t[:n_stride + 1], v_mean)
    n_lead = int(round(lead_in_s / dt))
    t_lead = -dt * np.arange(n_lead, 0, -1)
    u = np.clip((t_lead + lead_in_s) / ramp_s, 0, 1)
    env = 3 * u**2 - 2 * u**3
    # displacement back from the bout start: integral of env * v_mean from t to 0
    back = np.cumsum((env * dt)[::-1])[::-1]
    phase = np.mod(t_lead, t[n_stride]) / dt
    idx = np.clip(np.round(phase).astype(int), 0, n_stride)
    qpos = first[idx].copy()  # limbs, height and orientation: the first stride repeated
    qpos[:, a:a + 2] = first[0, a:a + 2] - np.outer(back, v_mean) + env[:, None] * residual[idx]
    return Motion(np.concatenate([t_lead, t]), np.vstack([qpos, motion.qpos]))


class ReplayHuman(HumanDriver):
    """Kinematic replay of `motion` through a stiff pelvis servo (module docstring)."""

    mode = "replay"

    def __init__(self, motion: Motion, p: ReplayParams, root: str = "root", pelvis: str = "pelvis") -> None:
        if motion.qpos.ndim != 2 or len(motion.time_s) != motion.qpos.shape[0] or len(motion.time_s) < 2:
            raise SimulationError("replay motion", f"time_s {motion.time_s.shape} and qpos "
                                  f"{motion.qpos.shape} do not describe a trajectory")
        self.motion, self.p, self.root, self.pelvis = motion, p, root, pelvis
        self.duration_s = float(motion.time_s[-1] - motion.time_s[0])
        self.root_adr = 0

    def prepare(self, spec: mujoco.MjSpec) -> None:
        original = spec.copy().compile()
        jid = mujoco.mj_name2id(original, mujoco.mjtObj.mjOBJ_JOINT, self.root)
        if jid < 0 or original.jnt_type[jid] != mujoco.mjtJoint.mjJNT_FREE:
            raise SimulationError(spec.modelname or "world", f"no free joint {self.root!r} to replay")
        if original.nq != self.motion.qpos.shape[1]:
            raise SimulationError(spec.modelname or "world", f"motion has {self.motion.qpos.shape[1]} qpos "
                                  f"columns, the human model {original.nq}")
        self.root_adr = int(original.jnt_qposadr[jid])
        body = spec.body(self.pelvis)
        if body is None:
            raise SimulationError(spec.modelname or "world", f"no body {self.pelvis!r}")
        self.p0 = np.array(body.pos, dtype=float)
        self.q0 = np.array(body.quat, dtype=float) / np.linalg.norm(body.quat)
        self.r0 = Rotation.from_quat(self.q0, scalar_first=True)
        # the human's own actuators, sensors, tendons, keyframes and equalities refer to its joints:
        # a kinematic replay uses none of them
        for group in (spec.actuators, spec.sensors, spec.tendons, spec.keys, spec.equalities, spec.pairs):
            for element in list(group):
                spec.delete(element)
        for joint in list(spec.joints):
            spec.delete(joint)
        for geom in spec.geoms:
            geom.contype, geom.conaffinity = 0, 0
        rot0 = np.zeros(9)
        mujoco.mju_quat2Mat(rot0, self.q0)
        world_axes = rot0.reshape(3, 3).T  # world axes expressed in the pelvis frame
        p = self.p
        for i, name in enumerate(DRIVE_JOINTS):
            lin = i < 3
            axis = world_axes[i] if lin else np.eye(3)[(2, 1, 0)[i - 3]]
            jtype = mujoco.mjtJoint.mjJNT_SLIDE if lin else mujoco.mjtJoint.mjJNT_HINGE
            lim = p.max_force_n if lin else p.max_torque_nm
            joint = body.add_joint(name=name, type=jtype, axis=axis, actfrclimited=True,
                                   actfrcrange=[-lim, lim])
            kp, kd = (p.kp_n_per_m, p.kd_ns_per_m) if lin else (p.kp_nm_per_rad, p.kd_nms_per_rad)
            pos = spec.add_actuator(name=f"{name}_pos", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            pos.set_to_intvelocity(kp=kp)
            vel = spec.add_actuator(name=f"{name}_vel", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            vel.set_to_velocity(kv=kd)
            if name == "replay_z":
                self._z_joint = joint

    def bind(self, model: mujoco.MjModel) -> None:
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in DRIVE_JOINTS]
        self.qadr = model.jnt_qposadr[ids].copy()
        self.dadr = model.jnt_dofadr[ids].copy()
        self.pos_act = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{n}_pos")
                                 for n in DRIVE_JOINTS])
        self.vel_act = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{n}_vel")
                                 for n in DRIVE_JOINTS])
        self.act_adr = model.actuator_actadr[self.pos_act].copy()
        self.pelvis_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.pelvis)
        weight = float(model.body_subtreemass[self.pelvis_id] * np.linalg.norm(model.opt.gravity))
        self.weight_n = weight
        model.actuator_biasprm[self.pos_act[2], 0] = weight  # body weight carried by the legs
        z = ids[2]
        model.jnt_actfrcrange[z] = (0.0, self.p.max_vertical_bodyweights * weight)

    def targets(self, times_s: np.ndarray) -> np.ndarray:
        """Drive-joint targets (n, 6) at `times_s`: position offsets and Z-Y-X angles."""
        q = interpolate_qpos(self.motion, times_s + self.motion.time_s[0], self.root_adr)
        root = q[:, self.root_adr:self.root_adr + 7]
        zyx = (self.r0.inv() * Rotation.from_quat(root[:, 3:], scalar_first=True)).as_euler("ZYX")
        zyx[:, 0] = np.unwrap(zyx[:, 0])
        return np.column_stack([root[:, :3] - self.p0, zyx])

    def start_pose(self) -> tuple[np.ndarray, float]:
        root = self.motion.qpos[0, self.root_adr:self.root_adr + 7]
        yaw = Rotation.from_quat(root[3:], scalar_first=True).as_euler("ZYX")[0]
        return root[:3].copy(), float(yaw)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData, sample_times_s: np.ndarray) -> None:
        self.bind(model)
        self.times_s = sample_times_s
        self.target = self.targets(sample_times_s)
        dt = np.diff(sample_times_s)
        self.rate = np.diff(self.target, axis=0) / dt[:, None]
        data.qpos[self.qadr] = self.target[0]
        data.qvel[self.dadr] = self.rate[0]
        data.act[self.act_adr] = self.target[0]
        # The position servos' targets are integrator states (act' = ctrl): with ctrl = the segment's
        # rate they reach the next sample's target exactly, so only ctrl is written per sample. The
        # drive actuators come in (position, velocity) pairs per joint, so their controls are one
        # contiguous block set from the rate repeated pairwise.
        if model.actuator_actlimited[self.pos_act].any():
            raise SimulationError("replay", "replay servo targets must not be range-limited")
        pairs = np.column_stack([self.pos_act, self.vel_act]).ravel()
        ctrl = data.ctrl[pairs[0]:pairs[0] + 12] if np.array_equal(pairs, pairs[0] + np.arange(12)) else None
        self._ctrl_view = ctrl
        self._rate2 = np.repeat(self.rate, 2, axis=1)
        self.drive_q = np.zeros((len(sample_times_s), 6))

    def before_sample(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        """Servo targets for the sample interval from k: position now, velocity of the linear segment."""
        if self._ctrl_view is not None:
            self._ctrl_view[:] = self._rate2[k]
            return
        data.ctrl[self.pos_act] = self.rate[k]
        data.ctrl[self.vel_act] = self.rate[k]

    def sample_controls(self) -> tuple[np.ndarray, np.ndarray] | None:
        return None if self._ctrl_view is None else (self._ctrl_view, self._rate2)

    def record(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        self.drive_q[k] = data.qpos[self.qadr]

    def from_world_qpos(self, world_qpos: np.ndarray) -> None:
        self.drive_q = world_qpos[:, self.qadr]

    def qpos_samples(self) -> np.ndarray:
        """Reference joints at the sample times with the simulated pelvis pose as the free root."""
        q = interpolate_qpos(self.motion, self.times_s + self.motion.time_s[0], self.root_adr)
        drive_q = self.drive_q
        a = self.root_adr
        q[:, a:a + 3] = self.p0 + drive_q[:, :3]
        q[:, a + 3:a + 7] = (self.r0 * Rotation.from_euler("ZYX", drive_q[:, 3:])).as_quat(scalar_first=True)
        return q


@dataclass(frozen=True)
class ReplaySegment:
    """One replay job: `[t0_s, t1_s]` of a retargeted trial, entered after a lead-in of its strides."""

    trial: str
    t0_s: float
    t1_s: float
    stride_s: float


@dataclass(frozen=True)
class ReplaySource:
    """Replay humans of one subject for the batch runner (`sim.rollout.batch.DriverSource`): the
    retargeted motion of `reference_npz`, each segment entered after a lead-in (`with_lead_in`) that
    is simulated but not recorded."""

    reference_npz: str
    replay: ReplayParams
    lead_in_s: float
    lead_in_ramp_s: float

    def open(self, world: mujoco.MjSpec):
        from sim.motion.reference import load_reference
        from sim.rollout.batch import HumanRun

        ref = load_reference(self.reference_npz)

        def make(seg: ReplaySegment, seed: int) -> HumanRun:
            time_s, qpos = ref.motion(seg.trial)
            rows = (time_s >= seg.t0_s) & (time_s <= seg.t1_s)
            t, q = time_s[rows], qpos[rows]
            motion = with_lead_in(Motion(t - t[0], q), seg.stride_s, self.lead_in_s, self.lead_in_ramp_s)
            return HumanRun(ReplayHuman(motion, self.replay), ref.rate_hz(seg.trial),
                            discard_s=self.lead_in_s, t0_s=float(t[0]))

        return make
