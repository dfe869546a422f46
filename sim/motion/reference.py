"""The subject's reference motion on the scaled human: retargeted trials and a periodic gait cycle.

`retarget_trial` turns one processed real trial (gap-filled, filtered markers; gait events) into
model configurations (`sim.motion.retarget`), their velocities and a per-frame gait phase.
`periodic_cycle` averages the kept steady strides into one periodic stride for policy training
(the imitation target of an adversarial motion prior, Peng et al. 2021), and `Reference` is what
`reference.npz` holds. `fit_metrics` and `cycle_summary` measure how well the retargeted trials and
the cycle reproduce the recording (marker fit, joint angles against the real `.mot` angles, stride
length and speed against the real strides): the `reference` stage's metrics file. Everything here
is a pure function of arrays and a MuJoCo model.
"""

from __future__ import annotations

import time
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Annotated, Literal

import mujoco
import numpy as np
import pandas as pd
from pydantic import Field, with_config

from ingest.filtering import lowpass
from ingest.process import ProcessedTrial
from ingest.trial import JOINTS, SIDES
from sim.errors import SimulationError
from sim.motion.retarget import ROOT_JOINT, MarkerFit, RetargetParams, joint_angles, retarget


@with_config(extra="forbid")
@dataclass(frozen=True)
class ReferenceParams:
    """The `retarget` section of params.yaml: which trials become the reference motion and how, and
    the marker IK that fits them (`ik`)."""

    conditions: tuple[str, ...] = ("free",)  # trial conditions retargeted; the first builds the cycle
    qvel_cutoff_hz: Annotated[float, Field(gt=0.0)] = 8.0  # low-pass (zero-phase, 4th order) on velocities
    cycle_samples: int = 100        # samples per periodic reference cycle
    cycle_side: Literal["left", "right"] = "right"  # strides from this side's heel strike to its next one
    floor_align: bool = True        # shift the cycle vertically so its lowest foot point is on z = 0
    ik: RetargetParams = field(default_factory=RetargetParams)


@dataclass(frozen=True)
class RetargetedTrial:
    """One real trial on the model: configurations, velocities, gait phase and fit quality."""

    trial: str
    condition: str
    time_s: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    phase: np.ndarray
    fit: MarkerFit
    ik_s: float


def velocities(model: mujoco.MjModel, qpos: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """Generalised velocities (n, nv) of a uniformly sampled configuration path: central differences
    in the tangent space (`mj_differentiatePos`, so quaternion joints are handled), one-sided at
    the ends, then a zero-phase 4th-order Butterworth low-pass at `cutoff_hz`."""
    n = len(qpos)
    qvel = np.zeros((n, model.nv))
    if n < 2:
        return qvel
    for k in range(n):
        a, b = max(k - 1, 0), min(k + 1, n - 1)
        mujoco.mj_differentiatePos(model, qvel[k], (b - a) / rate_hz, qpos[a], qpos[b])
    if n > 15 and cutoff_hz < rate_hz / 2:
        qvel = lowpass(qvel, rate_hz, cutoff_hz, 4)
    return qvel


def gait_phase(time_s: np.ndarray, heel_strikes_s: np.ndarray) -> np.ndarray:
    """Phase in [0, 1) from each heel strike to the next one of the same side; NaN before the
    first and after the last heel strike (no complete cycle there)."""
    hs = np.sort(np.asarray(heel_strikes_s, float))
    phase = np.full(len(time_s), np.nan)
    if len(hs) < 2:
        return phase
    k = np.searchsorted(hs, time_s, side="right") - 1
    inside = (k >= 0) & (k < len(hs) - 1)
    phase[inside] = (time_s[inside] - hs[k[inside]]) / (hs[k[inside] + 1] - hs[k[inside]])
    return phase


def retarget_trial(model: mujoco.MjModel, processed: ProcessedTrial, ik: RetargetParams,
                   p: ReferenceParams, window_s: tuple[float, float] | None = None,
                   progress: bool = False) -> RetargetedTrial:
    """Marker IK of one processed trial (or of its frames within `window_s`), its velocities, and
    its gait phase (`p.cycle_side` heel strikes from the ingest events of the whole trial)."""
    trial = processed.trial
    keep = np.ones(trial.n_frames, bool)
    if window_s is not None:
        keep = (trial.time_s >= window_s[0]) & (trial.time_s <= window_s[1])
        if keep.sum() < 2:
            raise SimulationError(trial.origin, f"window {window_s} s holds {keep.sum()} frames")
    time_s = trial.time_s[keep]
    start = time.perf_counter()
    fit = retarget(model, {n: x[keep] for n, x in trial.markers.items()}, ik, progress=progress)
    ik_s = time.perf_counter() - start
    ev = processed.events
    hs = ev.loc[(ev["side"] == p.cycle_side) & (ev["event"] == "heel_strike"), "time_s"].to_numpy()
    return RetargetedTrial(trial.trial, trial.condition, time_s, fit.qpos,
                           velocities(model, fit.qpos, trial.rate_hz, p.qvel_cutoff_hz),
                           gait_phase(time_s, hs), fit, ik_s)


@dataclass(frozen=True)
class ReferenceCycle:
    """One periodic stride: `qpos` (N, nq) and `qvel` (N, nv) at phase k/N, k = 0..N-1, starting at
    the heel strike of `side`; the root starts at x = y = 0 heading +X and the stride continues
    seamlessly into the next one shifted by `stride_length_m` along +X."""

    phase: np.ndarray
    time_s: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    period_s: float
    stride_length_m: float
    speed_mps: float
    n_strides: int
    side: str
    floor_shift_m: float = 0.0

    def qpos_at(self, k: int) -> np.ndarray:
        """Configuration of sample `k` of any cycle (k may exceed N: later strides move on in x)."""
        n = len(self.phase)
        q = self.qpos[k % n].copy()
        q[0] += (k // n) * self.stride_length_m
        return q


def _root_addresses(model: mujoco.MjModel) -> tuple[int, int]:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, ROOT_JOINT)
    if j < 0:
        raise SimulationError("reference", f"the model has no free joint named {ROOT_JOINT!r}")
    return int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])


_MIRROR_AXIAL = np.array([-1.0, 1.0, -1.0])  # an axial vector (rotation axis) reflected in the x-z plane


def mirrored_motion(model: mujoco.MjModel, qpos: np.ndarray,
                    qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The motion reflected in the sagittal (x-z) plane, left and right exchanged: a left turn becomes
    a right one. Positions and linear velocities flip y; rotations (free and ball joint quaternions,
    angular velocities) keep w and their y component and flip x and z; a `_l` joint takes its `_r`
    twin's value (hinge angles keep their sign where the twin's axis is this axis reflected, as in
    `sim.body.human`). qpos (T, nq), qvel (T, nv) -> the reflected pair."""
    jt = mujoco.mjtJoint
    names = [model.joint(j).name for j in range(model.njnt)]
    out_q, out_v = qpos.copy(), qvel.copy()
    for j, name in enumerate(names):
        side = name[-2:]
        twin = name[:-2] + {"_l": "_r", "_r": "_l"}[side] if side in ("_l", "_r") else name
        if twin not in names:
            raise SimulationError("reference", f"joint {name!r} has no mirror twin {twin!r}")
        k = names.index(twin)
        qa, da, qb, db = model.jnt_qposadr[j], model.jnt_dofadr[j], model.jnt_qposadr[k], model.jnt_dofadr[k]
        kind = model.jnt_type[j]
        if kind == jt.mjJNT_FREE:
            out_q[:, qa:qa + 3] = qpos[:, qb:qb + 3] * [1.0, -1.0, 1.0]
            out_q[:, qa + 3:qa + 7] = qpos[:, qb + 3:qb + 7] * [1.0, *_MIRROR_AXIAL]
            out_v[:, da:da + 3] = qvel[:, db:db + 3] * [1.0, -1.0, 1.0]
            out_v[:, da + 3:da + 6] = qvel[:, db + 3:db + 6] * _MIRROR_AXIAL
        elif kind == jt.mjJNT_BALL:
            out_q[:, qa:qa + 4] = qpos[:, qb:qb + 4] * [1.0, *_MIRROR_AXIAL]
            out_v[:, da:da + 3] = qvel[:, db:db + 3] * _MIRROR_AXIAL
        else:
            sign = float(np.sign(np.dot(model.jnt_axis[j], model.jnt_axis[k] * _MIRROR_AXIAL)))
            out_q[:, qa], out_v[:, da] = sign * qpos[:, qb], sign * qvel[:, db]
    return out_q, out_v


def _heading_normalised(model: mujoco.MjModel, qpos: np.ndarray, start: np.ndarray,
                        heading: float) -> np.ndarray:
    """Configurations with the root moved so `start` (xy) is the origin and `heading` is +X."""
    qa, _ = _root_addresses(model)
    c, s = np.cos(-heading), np.sin(-heading)
    out = qpos.copy()
    xy = qpos[:, qa:qa + 2] - start
    out[:, qa] = c * xy[:, 0] - s * xy[:, 1]
    out[:, qa + 1] = s * xy[:, 0] + c * xy[:, 1]
    yaw = np.array([np.cos(-heading / 2), 0.0, 0.0, np.sin(-heading / 2)])
    for k in range(len(out)):
        mujoco.mju_mulQuat(out[k, qa + 3:qa + 7], yaw, qpos[k, qa + 3:qa + 7])
    return out


def periodic_cycle(model: mujoco.MjModel, strides: list[tuple[np.ndarray, np.ndarray, float, float]],
                   n_samples: int, side: str = "right") -> ReferenceCycle:
    """Mean periodic stride from `strides`, each (time_s, qpos, t_start_s, t_end_s) of one trial.

    Each stride is moved to start at the origin heading +X (heading = direction of the root's
    displacement over the stride), mapped to the tangent space of a reference pose
    (`mj_differentiatePos` from `qpos0` with the root at the origin), resampled on the phase grid
    k/N, k = 0..N, and averaged over strides. The mean is made periodic by removing the linear
    drift of the end-minus-start mismatch from every coordinate except the root's forward position,
    whose advance over the stride is the mean stride length. The period is the mean stride time;
    velocities are periodic central differences.
    """
    if not strides:
        raise SimulationError("reference", "no kept stride to build the periodic cycle from")
    qa, da = _root_addresses(model)
    q_ref = model.qpos0.copy()
    q_ref[qa:qa + 3] = 0.0
    grid = np.linspace(0.0, 1.0, n_samples + 1)
    tangents, periods = [], []
    for time_s, qpos, t0, t1 in strides:
        inside = (time_s >= t0) & (time_s <= t1)
        idx = np.flatnonzero(inside)
        lo, hi = max(idx[0] - 1, 0), min(idx[-1] + 1, len(time_s) - 1)
        t, q = time_s[lo:hi + 1], qpos[lo:hi + 1]
        p0 = np.array([np.interp(t0, t, q[:, qa + i]) for i in range(2)])
        p1 = np.array([np.interp(t1, t, q[:, qa + i]) for i in range(2)])
        heading = float(np.arctan2(*(p1 - p0)[::-1]))
        qn = _heading_normalised(model, q, p0, heading)
        u = np.empty((len(qn), model.nv))
        for k, qk in enumerate(qn):
            mujoco.mj_differentiatePos(model, u[k], 1.0, q_ref, qk)
        phase_t = (t - t0) / (t1 - t0)
        tangents.append(np.column_stack([np.interp(grid, phase_t, u[:, j]) for j in range(model.nv)]))
        periods.append(t1 - t0)
    mean = np.mean(tangents, axis=0)
    drift = mean[-1] - mean[0]
    length = float(drift[da])
    drift[da] = 0.0
    mean = mean - grid[:, None] * drift[None, :]
    mean[:, da] -= mean[0, da]
    qpos = np.empty((n_samples + 1, model.nq))
    for k in range(n_samples + 1):
        qpos[k] = q_ref
        mujoco.mj_integratePos(model, qpos[k], mean[k], 1.0)
    period = float(np.mean(periods))
    dt = period / n_samples
    qvel = np.empty((n_samples, model.nv))
    for k in range(n_samples):
        before = qpos[k - 1].copy() if k > 0 else qpos[n_samples - 1].copy()
        if k == 0:
            before[qa] -= length
        mujoco.mj_differentiatePos(model, qvel[k], 2 * dt, before, qpos[k + 1])
    return ReferenceCycle(grid[:-1], grid[:-1] * period, qpos[:-1], qvel, period, length,
                          length / period, len(strides), side)


def lowest_foot_z(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Height (m) of the lowest point of the feet's contact spheres (geoms in collision class
    `sim.body.human.FOOT_BIT` on a body) for each configuration."""
    from sim.body.human import FOOT_BIT

    sphere = int(mujoco.mjtGeom.mjGEOM_SPHERE)
    feet = np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] > 0
                     and model.geom_contype[g] & FOOT_BIT and model.geom_type[g] == sphere])
    if not len(feet):
        raise SimulationError("reference", "the model has no foot contact spheres")
    data = mujoco.MjData(model)
    out = np.empty(len(qpos))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[k] = np.min(data.geom_xpos[feet, 2] - model.geom_size[feet, 0])
    return out


def floor_aligned(model: mujoco.MjModel, cycle: ReferenceCycle) -> ReferenceCycle:
    """The cycle moved vertically so that the median over the cycle of its lowest foot point is
    on the floor (z = 0): in walking one foot is always down, so the lowest point should stay on
    the floor; marker IK leaves it off by the difference between the static and walking floors
    and the soft-tissue motion of the foot markers (about 1 cm)."""
    qa, _ = _root_addresses(model)
    shift = -float(np.median(lowest_foot_z(model, cycle.qpos)))
    qpos = cycle.qpos.copy()
    qpos[:, qa + 2] += shift
    return replace(cycle, qpos=qpos, floor_shift_m=cycle.floor_shift_m + shift)


def blend_qpos(model: mujoco.MjModel, q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """(1 - a) q0 + a q1 joint by joint: positions and hinges linearly, quaternions (free-joint
    orientation, ball joints) by normalised linear interpolation on the short arc."""
    if a in (0.0, 1.0):
        return (q1 if a == 1.0 else q0).copy()
    out = (1 - a) * q0 + a * q1
    free, ball = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
    for j in range(model.njnt):
        kind, adr = int(model.jnt_type[j]), int(model.jnt_qposadr[j])
        if kind in (free, ball):
            s = adr + 3 if kind == free else adr
            p, r = q0[s:s + 4], q1[s:s + 4]
            r = r if p @ r >= 0 else -r
            quat = (1 - a) * p + a * r
            out[s:s + 4] = quat / np.linalg.norm(quat)
    return out


def foot_forward_m(model: mujoco.MjModel, qpos: np.ndarray, side: str) -> np.ndarray:
    """World x (m, the walking direction of a cycle) of `side`'s foot body for each configuration."""
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"foot_{side[0]}")
    if body < 0:
        raise SimulationError("reference", f"the model has no body foot_{side[0]}")
    data = mujoco.MjData(model)
    out = np.empty(len(qpos))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[k] = data.xpos[body, 0]
    return out


def swing_mask(cycle: ReferenceCycle, foot_x_m: np.ndarray) -> np.ndarray:
    """Samples of the cycle in which the foot at forward positions `foot_x_m` swings: it moves
    forward faster than the walking speed (a stance foot stands still, a swinging one moves at
    about twice the speed); central differences over the periodic cycle (the next stride starts
    `stride_length_m` ahead)."""
    n = len(foot_x_m)
    x = np.r_[foot_x_m[-1] - cycle.stride_length_m, foot_x_m, foot_x_m[0] + cycle.stride_length_m]
    velocity = (x[2:] - x[:-2]) / (2.0 * cycle.period_s / n)
    return velocity > cycle.speed_mps


def with_longer_swing(model: mujoco.MjModel, cycle: ReferenceCycle, side: str,
                      ratio: float) -> ReferenceCycle:
    """The cycle time-warped so that `side`'s swing lasts `ratio` x the other foot's, period, stride
    and speed unchanged: the whole body plays slower by f1 = s + (1 - s) / ratio while that foot
    swings (share s of the cycle, `swing_mask`) and faster by ratio f1 otherwise, so that
    s / f1 + (1 - s) / (ratio f1) = 1. Configurations are interpolated at the warped phase
    (`blend_qpos`), velocities scaled by the local rate (the chain rule)."""
    n = len(cycle.phase)
    swing = swing_mask(cycle, foot_forward_m(model, cycle.qpos, side))
    s = float(swing.mean())
    slow = s + (1.0 - s) / ratio
    rate = np.where(swing, slow, ratio * slow)       # old phase per new phase, sample k to k + 1
    new_at_old = np.r_[0.0, np.cumsum(1.0 / rate)]    # new phase of old samples 0..N (x N)
    new_at_old *= n / new_at_old[-1]
    old = np.interp(np.arange(n), new_at_old, np.arange(n + 1.0))  # old (fractional) sample per new one
    k = np.minimum(old.astype(int), n - 1)
    f = old - k
    qpos = np.array([blend_qpos(model, cycle.qpos_at(int(i)), cycle.qpos_at(int(i) + 1), float(a))
                     for i, a in zip(k, f, strict=True)])
    v0, v1 = cycle.qvel[k], cycle.qvel[(k + 1) % n]
    qvel = ((1.0 - f[:, None]) * v0 + f[:, None] * v1) * rate[k][:, None]
    return replace(cycle, qpos=qpos, qvel=qvel)


def left_right_shift(model: mujoco.MjModel, cycle: ReferenceCycle,
                     joints: tuple[str, ...] = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion"),
                     ) -> dict[str, dict[str, float]]:
    """How the cycle's left and right legs relate, per sagittal joint: the circular shift (fraction
    of the cycle) that best aligns the left curve onto the right (about 0.5 in symmetric walking)
    and the RMS left-right difference (deg) at a shift of exactly half a cycle."""
    angles = joint_angles(model, cycle.qpos)
    n = len(cycle.phase)
    out = {}
    for j in joints:
        right, left = angles[f"{j}_right"], angles[f"{j}_left"]
        errs = [np.sqrt(np.mean((np.roll(left, -k) - right) ** 2)) for k in range(n)]
        out[j] = {"best_shift": round(int(np.argmin(errs)) / n, 3),
                  "rms_at_half_cycle_deg": round(float(errs[n // 2]), 3)}
    return out


def cycle_from_trials(model: mujoco.MjModel, trials: list[RetargetedTrial], strides: pd.DataFrame,
                      p: ReferenceParams) -> tuple[ReferenceCycle, pd.DataFrame]:
    """The periodic cycle from the kept `p.cycle_side` strides (ingest stride table, all trials)
    that lie within the retargeted `trials` whose condition is the first of `p.conditions`; also
    returns the strides used."""
    by_id = {t.trial: t for t in trials if t.condition == p.conditions[0]}
    used = strides[strides["kept"] & (strides["side"] == p.cycle_side) & strides["trial"].isin(by_id)]
    covered = [by_id[r.trial].time_s[0] <= r.t_start_s and r.t_end_s <= by_id[r.trial].time_s[-1]
               for r in used.itertuples()]
    used = used[np.array(covered, bool)]
    segments = [(by_id[r.trial].time_s, by_id[r.trial].qpos, float(r.t_start_s), float(r.t_end_s))
                for r in used.itertuples()]
    cycle = periodic_cycle(model, segments, p.cycle_samples, p.cycle_side)
    return (floor_aligned(model, cycle) if p.floor_align else cycle), used



# -- fit metrics: the retargeted motion against the recording --------------------------------------

def angle_errors(model: mujoco.MjModel, trial: RetargetedTrial,
                 real: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-frame retargeted-minus-real sagittal angles (deg) for hip, knee, ankle of both sides."""
    sim = joint_angles(model, trial.qpos)
    return {f"{j}_{s}": sim[f"{j}_{s}"] - real[f"{j}_{s}"]
            for j in JOINTS for s in SIDES if f"{j}_{s}" in sim and f"{j}_{s}" in real}


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


def angle_summary(errors: dict[str, list[np.ndarray]]) -> dict[str, dict[str, float]]:
    """Per joint: RMS of the raw difference, the constant offset (mean difference, e.g. differing
    neutral-pose definitions) and the RMS once that offset is removed."""
    out = {}
    for name, parts in errors.items():
        e = np.concatenate(parts)
        offset = float(np.nanmean(e))
        out[name] = {"rms_deg": round(_rms(e), 3), "offset_deg": round(offset, 3),
                     "rms_offset_removed_deg": round(_rms(e - offset), 3)}
    return out


def fit_metrics(subject_id: str, model: mujoco.MjModel, trials: list[RetargetedTrial],
                real: dict[str, dict[str, np.ndarray]], main_condition: str) -> dict:
    """Marker and angle fit per trial and pooled over the trials of `main_condition`; `real` holds
    each trial's recorded angles by trial id."""
    per_trial, pooled_err, pooled_rms = {}, {}, []
    n_frames = sum(len(t.time_s) for t in trials)
    for t in trials:
        errs = angle_errors(model, t, real[t.trial])
        per_trial[t.trial] = {
            "condition": t.condition, "n_frames": len(t.time_s),
            "marker_rms_m": round(t.fit.overall_rms_m, 5),
            "marker_rms_max_frame_m": round(float(np.nanmax(t.fit.rms_m)), 5),
            "markers_rms_m": {n: round(float(v), 5) for n, v in zip(t.fit.marker_names, t.fit.marker_rms_m,
                                                                  strict=True)},
            "angles": angle_summary({k: [v] for k, v in errs.items()}),
        }
        if t.condition == main_condition:
            pooled_rms.append(t.fit.rms_m)
            for k, v in errs.items():
                pooled_err.setdefault(k, []).append(v)
    ik_s = sum(t.ik_s for t in trials)
    rms = np.concatenate(pooled_rms)
    return {
        "subject": subject_id, "condition": main_condition, "n_frames": n_frames,
        "ik_frames_per_s": round(n_frames / ik_s, 1),
        "marker_rms_m": round(float(np.sqrt(np.nanmean(rms ** 2))), 5),
        "angles": angle_summary(pooled_err),
        "trials": per_trial,
    }


def cycle_summary(cycle: ReferenceCycle, used: pd.DataFrame) -> dict:
    """The periodic cycle's stride length and speed against the real strides it was built from."""
    real_length = float(used["stride_length_m"].mean())
    real_speed = float(used["gait_speed_mps"].mean())
    return {
        "n_strides": cycle.n_strides, "side": cycle.side, "period_s": round(cycle.period_s, 4),
        "floor_shift_m": round(cycle.floor_shift_m, 4),
        "stride_length_m": round(cycle.stride_length_m, 4), "speed_mps": round(cycle.speed_mps, 4),
        "real_stride_length_m": round(real_length, 4), "real_speed_mps": round(real_speed, 4),
        "stride_length_rel_error": round(cycle.stride_length_m / real_length - 1, 4),
        "speed_rel_error": round(cycle.speed_mps / real_speed - 1, 4),
    }

@dataclass(frozen=True)
class Reference:
    """What `reference.npz` holds: every retargeted frame (trials stacked, `trial` names each
    frame's trial) and the periodic cycle."""

    time_s: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    phase: np.ndarray
    trial: np.ndarray
    condition: np.ndarray
    marker_rms_m: np.ndarray
    cycle: ReferenceCycle

    @classmethod
    def from_trials(cls, trials: list[RetargetedTrial], cycle: ReferenceCycle) -> Reference:
        cat = np.concatenate
        return cls(cat([t.time_s for t in trials]), cat([t.qpos for t in trials]),
                   cat([t.qvel for t in trials]), cat([t.phase for t in trials]),
                   cat([np.full(len(t.time_s), t.trial) for t in trials]),
                   cat([np.full(len(t.time_s), t.condition) for t in trials]),
                   cat([t.fit.rms_m for t in trials]), cycle)

    def arrays(self) -> dict[str, np.ndarray]:
        """Flat arrays for `np.savez` (cycle fields prefixed `cycle_`)."""
        out = {f.name: np.asarray(getattr(self, f.name)) for f in fields(self) if f.name != "cycle"}
        for f in fields(ReferenceCycle):
            out[f"cycle_{f.name}"] = np.asarray(getattr(self.cycle, f.name))
        return out

    def rate_hz(self, trial: str) -> float:
        """Sampling rate of one retargeted trial (its median sample period), snapped to 0.01 Hz when the
        file's time column is rounded (kgc6 writes 120 Hz as 0.008333 s steps: 120.0048 Hz, whose
        common period with the control rate, `sim.rollout.world.step_grid`, is a 1e-7 s physics step)."""
        time_s, _ = self.motion(trial)
        rate = float(1.0 / np.median(np.diff(time_s)))
        snapped = round(rate, 2)
        return rate if abs(rate - snapped) < 1e-6 else snapped

    def motion(self, trial: str) -> tuple[np.ndarray, np.ndarray]:
        """(time_s, qpos) of one retargeted trial."""
        rows = self.trial == trial
        if not rows.any():
            raise SimulationError("reference", f"no trial {trial!r} (has: {sorted(set(self.trial))})")
        return self.time_s[rows], self.qpos[rows]


def save_reference(path: str | Path, ref: Reference) -> None:
    """Write `ref` as an uncompressed npz to `path` (a file object or path; callers make it atomic)."""
    np.savez(path, **ref.arrays())


def load_reference(path: str | Path) -> Reference:
    """Read a `reference.npz` written by `save_reference`."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise SimulationError(path, f"cannot read reference motion ({exc})") from None
    try:
        cycle = ReferenceCycle(**{f.name: _scalar(arrays[f"cycle_{f.name}"]) for f in fields(ReferenceCycle)
                                  if f"cycle_{f.name}" in arrays or f.default is MISSING})
        return Reference(**{f.name: arrays[f.name] for f in fields(Reference) if f.name != "cycle"},
                         cycle=cycle)
    except KeyError as exc:
        raise SimulationError(path, f"reference motion lacks array {exc.args[0]!r}") from None


def _scalar(a: np.ndarray):
    if a.ndim:
        return a
    return a.item()
