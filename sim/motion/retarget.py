"""Retarget recorded marker trajectories onto a MuJoCo model: per-frame marker inverse kinematics.

Each frame solves the weighted least-squares problem

    min_dq  sum_i w_i |m_i - p_i(q (+) dq)|^2  +  sum_k c_k |(q (+) dq) (-) q_rest|_k^2

over all `nv` degrees of freedom with a Levenberg-Marquardt iteration of our own: `p_i` are the
model's sites named like the real markers `m_i`, `(+)`/`(-)` are MuJoCo's `mj_integratePos` /
`mj_differentiatePos` (so quaternion joints move in their tangent space), `c_k` is a small posture
prior that keeps unobserved degrees of freedom (e.g. arms of a lower-body marker set) at the rest
pose, and joint ranges are enforced by projection after each step (hinges clipped, ball joints
clipped to their cone). Frames are solved in order and each starts from the previous solution
(warm start), so a few iterations per frame suffice; the first frame starts from a rigid fit of
the pelvis sites to the pelvis markers (Kabsch 1976). Markers missing (NaN) in a frame are left
out of that frame's problem.

Site Jacobians are assembled for all sites at once from MuJoCo's `cdof` (motion subspaces in the
centre-of-mass frame, `mj_comPos`): for a point p on a body with ancestor degree of freedom j,
J_p[:, j] = cdof_lin_j + cdof_ang_j x (p - subtree_com[root]), exactly what `mj_jacSite` computes
one site at a time.

`joint_angles` turns model configurations into the canonical sagittal (and other) joint angles of
`ingest.trial.Trial` so simulated motion is compared with the recorded `.mot` angles by name.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field

import mujoco
import numpy as np
from pydantic import with_config
from scipy.spatial.transform import Rotation

from sim.errors import SimulationError

ROOT_JOINT = "root"
SUFFIX_OF_SIDE = {"left": "l", "right": "r"}  # canonical side names -> the model's suffixes


@with_config(extra="forbid")
@dataclass(frozen=True)
class RetargetParams:
    """The `retarget.ik` block of params.yaml (see the module docstring for the problem solved)."""

    iterations: int = 4                  # LM iterations per warm-started frame
    first_frame_iterations: int = 80     # LM iterations for the first frame (cold start)
    step_tolerance: float = 1e-4         # stop when |dq| (rad or m) falls below this
    damping: float = 1e-4                # initial Levenberg damping (m^2 per unit dq^2)
    posture_weight: float = 1e-4         # prior toward the rest pose, m^2 per rad^2 of joint motion
    default_marker_weight: float = 1.0
    marker_weights: dict[str, float] = field(default_factory=dict)  # fnmatch pattern -> weight
    min_markers: int = 4                 # frames with fewer present markers keep the previous pose

    def weight(self, name: str) -> float:
        """Weight of marker `name`: the first matching pattern in `marker_weights`, else the default."""
        for pattern, w in self.marker_weights.items():
            if fnmatch.fnmatchcase(name, pattern):
                return w
        return self.default_marker_weight


@dataclass(frozen=True)
class MarkerFit:
    """Result of `retarget`: one configuration per frame and how well it fits the markers.

    `rms_m` is the per-frame RMS distance (m) between the weighted (w > 0) present markers and
    their model sites; `marker_rms_m` the per-marker RMS over the frames where it is present.
    """

    qpos: np.ndarray
    rms_m: np.ndarray
    marker_names: tuple[str, ...]
    marker_rms_m: np.ndarray
    iterations: np.ndarray

    @property
    def overall_rms_m(self) -> float:
        """RMS over every present (marker, frame) pair."""
        return float(np.sqrt(np.nanmean(self.rms_m ** 2)))


class MarkerIK:
    """Per-frame marker IK on `model` for the markers in `names` that the model has as sites."""

    def __init__(self, model: mujoco.MjModel, names: list[str], p: RetargetParams) -> None:
        self.model, self.p = model, p
        self.data = mujoco.MjData(model)
        site_ids = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in names}
        self.names = tuple(n for n in names if site_ids[n] >= 0 and p.weight(n) > 0)
        if not self.names:
            raise SimulationError("retarget", f"none of the markers {sorted(names)[:8]} is a site of "
                                  "the model (or all have weight 0)")
        self.site_ids = np.array([site_ids[n] for n in self.names])
        self.weights = np.array([p.weight(n) for n in self.names])
        self.root = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, ROOT_JOINT)
        if self.root < 0 or model.jnt_type[self.root] != mujoco.mjtJoint.mjJNT_FREE:
            raise SimulationError("retarget", f"the model has no free joint named {ROOT_JOINT!r}")
        # ancestor mask: site s moves with dof j when j's body is the site's body or an ancestor of it
        nb = model.nbody
        anc = np.zeros((nb, nb), bool)
        for b in range(nb):
            a = b
            while True:
                anc[b, a] = True
                if a == 0:
                    break
                a = model.body_parentid[a]
        self.mask = anc[model.site_bodyid[self.site_ids]][:, model.dof_bodyid].astype(float)
        self.tree_root = int(model.body_rootid[model.jnt_bodyid[self.root]])
        # posture prior on every non-root dof
        root_dofs = np.arange(model.jnt_dofadr[self.root], model.jnt_dofadr[self.root] + 6)
        self.prior = np.full(model.nv, p.posture_weight)
        self.prior[root_dofs] = 0.0
        self.q_rest = model.qpos0.copy()
        self._joint_limits()
        self._diag = np.diag_indices(model.nv)

    def _joint_limits(self) -> None:
        """Index arrays of the limited hinges / slides (qpos address, range) and ball joints
        (qpos address, cone angle) for the vectorised projection in `clamp`."""
        m = self.model
        hinge = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        lim = [j for j in range(m.njnt) if m.jnt_limited[j]]
        h = [j for j in lim if int(m.jnt_type[j]) in hinge]
        ball = int(mujoco.mjtJoint.mjJNT_BALL)
        b = [j for j in lim if int(m.jnt_type[j]) == ball and m.jnt_range[j, 1] > 0]
        self._hinge_adr = m.jnt_qposadr[h].astype(int)
        self._hinge_lo, self._hinge_hi = m.jnt_range[h, 0], m.jnt_range[h, 1]
        self._ball_adr = (m.jnt_qposadr[b][:, None] + np.arange(4)).astype(int)
        self._ball_max = m.jnt_range[b, 1]

    def clamp(self, q: np.ndarray) -> np.ndarray:
        """Project `q` into the joint ranges: hinges clipped, ball rotations clipped to their cone
        (rotation angle at most the range, about the same axis)."""
        q[self._hinge_adr] = np.clip(q[self._hinge_adr], self._hinge_lo, self._hinge_hi)
        if len(self._ball_adr):
            quat = q[self._ball_adr]
            quat *= np.where(quat[:, :1] < 0, -1.0, 1.0)
            s = np.sqrt(np.sum(quat[:, 1:] ** 2, axis=1))
            over = (2 * np.arctan2(s, quat[:, 0]) > self._ball_max) & (s > 0)
            if over.any():
                half = self._ball_max[over] / 2
                quat[over, 0] = np.cos(half)
                quat[over, 1:] *= (np.sin(half) / s[over])[:, None]
                q[self._ball_adr[over]] = quat[over]
        return q

    def sites(self, q: np.ndarray) -> np.ndarray:
        """Site positions (n_markers, 3) at configuration `q` (also leaves `cdof` in `self.data`)."""
        d = self.data
        d.qpos[:] = q
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        return d.site_xpos[self.site_ids].copy()

    def jacobian(self, pos: np.ndarray) -> np.ndarray:
        """Translational Jacobians (n_markers, 3, nv) of the sites at `pos`, from the last `sites` call."""
        d = self.data
        ang, lin = d.cdof[:, :3].T, d.cdof[:, 3:].T  # (3, nv)
        r = (pos - d.subtree_com[self.tree_root])[:, :, None]  # (n_markers, 3, 1)
        jac = np.empty((len(pos), 3, self.model.nv))
        jac[:, 0] = lin[0] + ang[1] * r[:, 2] - ang[2] * r[:, 1]
        jac[:, 1] = lin[1] + ang[2] * r[:, 0] - ang[0] * r[:, 2]
        jac[:, 2] = lin[2] + ang[0] * r[:, 1] - ang[1] * r[:, 0]
        jac *= self.mask[:, None, :]
        return jac

    def _cost(self, err: np.ndarray, w: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray]:
        dev = np.empty(self.model.nv)
        mujoco.mj_differentiatePos(self.model, dev, 1.0, self.q_rest, q)
        return float(np.sum(w[:, None] * err ** 2) + np.sum(self.prior * dev ** 2)), dev

    def solve(self, q: np.ndarray, target: np.ndarray, iterations: int) -> tuple[np.ndarray, float, int]:
        """Levenberg-Marquardt from `q` toward marker positions `target` (n_markers, 3; NaN =
        missing). Returns the configuration, the RMS marker error (m) and the iterations used."""
        m = self.model
        present = np.isfinite(target).all(axis=1)
        w = np.where(present, self.weights, 0.0)
        tgt = np.where(present[:, None], target, 0.0)
        q = q.copy()
        pos = self.sites(q)
        cost, dev = self._cost(tgt - pos, w, q)
        mu = self.p.damping
        used = 0
        for _ in range(iterations):
            used += 1
            err = tgt - pos
            jac = self.jacobian(pos).reshape(-1, m.nv)
            jw = jac.T * np.repeat(w, 3)
            lhs = jw @ jac
            rhs = jw @ err.ravel() - self.prior * dev
            diag = lhs.diagonal().copy()
            lhs[self._diag] += self.prior
            improved = False
            for _ in range(6):
                a = lhs.copy()
                a[self._diag] += mu * (1.0 + diag)
                dq = np.linalg.solve(a, rhs)
                q_new = q.copy()
                mujoco.mj_integratePos(m, q_new, dq, 1.0)
                self.clamp(q_new)
                pos_new = self.sites(q_new)
                cost_new, dev_new = self._cost(tgt - pos_new, w, q_new)
                if cost_new <= cost:
                    q, pos, cost, dev = q_new, pos_new, cost_new, dev_new
                    mu = max(mu / 3.0, 1e-9)
                    improved = True
                    break
                mu *= 10.0
            if not improved or float(np.sqrt(dq @ dq)) < self.p.step_tolerance:
                break
        self.sites(q)
        n = max(int(present.sum()), 1)
        rms = float(np.sqrt(np.sum(present[:, None] * (tgt - pos) ** 2) / n))
        return q, rms, used

    def initial_pose(self, target: np.ndarray) -> np.ndarray:
        """Rest pose with the root placed by a rigid (Kabsch) fit of the root body's sites to their
        markers; with fewer than 3 of them, the root is moved to the centroid of all markers."""
        m = self.model
        q = self.q_rest.copy()
        rest = self.sites(q)
        present = np.isfinite(target).all(axis=1)
        root_body = m.jnt_bodyid[self.root]
        on_root = present & (m.site_bodyid[self.site_ids] == root_body)
        adr = m.jnt_qposadr[self.root]
        if on_root.sum() >= 3:
            a, b = rest[on_root], target[on_root]
            ca, cb = a.mean(0), b.mean(0)
            u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
            sign = np.sign(np.linalg.det(vt.T @ u.T))
            rot = vt.T @ np.diag([1.0, 1.0, sign]) @ u.T
            body_pos = self.data.xpos[root_body]
            quat_rest = q[adr + 3:adr + 7].copy()
            rquat = np.empty(4)
            mujoco.mju_mat2Quat(rquat, rot.ravel())
            new_quat = np.empty(4)
            mujoco.mju_mulQuat(new_quat, rquat, quat_rest)
            q[adr:adr + 3] = rot @ (body_pos - ca) + cb
            q[adr + 3:adr + 7] = new_quat
        elif present.any():
            q[adr:adr + 3] += target[present].mean(0) - rest[present].mean(0)
        return q


def retarget(model: mujoco.MjModel, markers: dict[str, np.ndarray], p: RetargetParams,
             q_init: np.ndarray | None = None, progress: bool = False) -> MarkerFit:
    """Per-frame marker IK of a whole recording (`markers`: name -> (n, 3) m, NaN = missing).

    Frames are solved in order with a warm start from the previous frame; a frame with fewer than
    `p.min_markers` present markers keeps the previous configuration (its RMS is NaN).
    """
    names = sorted(markers)
    ik = MarkerIK(model, names, p)
    target = np.stack([np.asarray(markers[n], float) for n in ik.names], axis=1)
    n = target.shape[0]
    qpos = np.empty((n, model.nq))
    rms = np.full(n, np.nan)
    iters = np.zeros(n, int)
    q = None if q_init is None else np.asarray(q_init, float).copy()
    frames = range(n)
    if progress:
        from tqdm import tqdm
        frames = tqdm(frames, desc="retarget", unit="frame")
    for k in frames:
        present = np.isfinite(target[k]).all(axis=1)
        if present.sum() < p.min_markers:
            qpos[k] = q if q is not None else ik.q_rest
            continue
        if q is None:
            q, rms[k], iters[k] = ik.solve(ik.initial_pose(target[k]), target[k], p.first_frame_iterations)
        else:
            q, rms[k], iters[k] = ik.solve(q, target[k], p.iterations)
        qpos[k] = q
    residual = _marker_residuals(ik, qpos, target)
    return MarkerFit(qpos, rms, ik.names, residual, iters)


def _marker_residuals(ik: MarkerIK, qpos: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Per-marker RMS distance over the frames where the marker is present."""
    err = np.stack([ik.sites(q) for q in qpos]) - target
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.nanmean(np.sum(err ** 2, axis=2), axis=0))


def site_positions(model: mujoco.MjModel, qpos: np.ndarray, names: list[str]) -> dict[str, np.ndarray]:
    """World positions (n, 3) of the named sites along a trajectory of configurations."""
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in names]
    missing = [n for n, i in zip(names, ids, strict=True) if i < 0]
    if missing:
        raise SimulationError("site_positions", f"the model has no sites {missing}")
    out = np.empty((len(qpos), len(ids), 3))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[k] = data.site_xpos[ids]
    return {n: out[:, j] for j, n in enumerate(names)}


# --------------------------------------------------------------------------- joint angles

def _joint_child_parent(model: mujoco.MjModel, joint: str) -> tuple[int, int, int] | None:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if j < 0:
        return None
    child = int(model.jnt_bodyid[j])
    return j, child, int(model.body_parentid[child])


def joint_angles(model: mujoco.MjModel, qpos: np.ndarray) -> dict[str, np.ndarray]:
    """Canonical joint angles (degrees) of configurations `qpos` (n, nq), named as in
    `ingest.trial.Trial.angles` (``hip_flexion_left``, ``knee_flexion_right``, ``pelvis_tilt``...).

    Definitions (frames: X forward, Y left, Z up, as the model stands at `qpos0`):
    - Ball joints (hips, lumbar, shoulders): the child's rotation relative to the parent, measured
      from the rest pose and expressed in the parent's axes, R = R_rel(q) R_rel(q0)^T, decomposed
      as intrinsic Y-X-Z, R = Ry(a) Rx(b) Rz(c). This is OpenSim's hip sequence (flexion about the
      lateral axis, then adduction, then long-axis rotation; Delp et al. 1990 / gait2392) written in
      our axes, so ``hip_flexion = -a`` (knee forward +), ``hip_adduction = -b`` left / ``+b``
      right (toward the midline +), ``hip_rotation = -c`` left / ``+c`` right (internal +). Lumbar
      gives ``lumbar_extension = a`` (trunk backward +), ``lumbar_bending = b``, ``lumbar_rotation =
      c``; shoulders ``shoulder_flexion = -a`` (arm forward +), ``shoulder_adduction``,
      ``shoulder_rotation`` with the hip's side signs.
    - Hinges (knees, ankles, elbows): the joint coordinate, whose positive sense is flexion /
      dorsiflexion by the model's convention; zero is the model's rest pose.
    - Pelvis: orientation of the pelvis body relative to its rest orientation, decomposed as yaw
      about world Z, then pitch, then roll (Z-Y-X): ``pelvis_rotation`` = yaw (heading, left +),
      ``pelvis_tilt`` = pitch (anterior +), ``pelvis_list`` = roll about the forward axis (left
      side up +). Yaw first keeps tilt and list meaningful whatever the walking direction.
    Joints the model lacks are left out.
    """
    qpos = np.atleast_2d(np.asarray(qpos, float))
    data = mujoco.MjData(model)
    joints = {f"{kind}_{s}": f"{kind}_{s}" for kind in ("hip", "shoulder") for s in SUFFIX_OF_SIDE.values()}
    joints["lumbar"] = "lumbar"
    found = {k: jb for k, v in joints.items() if (jb := _joint_child_parent(model, v)) is not None}
    root = _joint_child_parent(model, ROOT_JOINT)
    bodies = sorted({b for _, c, p in found.values() for b in (c, p)}
                    | ({root[1]} if root else set()))
    n = len(qpos)
    xmat = {b: np.empty((n, 3, 3)) for b in bodies}

    def frames(q: np.ndarray) -> dict[int, np.ndarray]:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        return {b: data.xmat[b].reshape(3, 3).copy() for b in bodies}

    rest = frames(model.qpos0)
    for k, q in enumerate(qpos):
        for b, mat in frames(q).items():
            xmat[b][k] = mat
    out: dict[str, np.ndarray] = {}
    for key, (_, child, parent) in found.items():
        rel = np.einsum("nji,njk->nik", xmat[parent], xmat[child])
        rel0 = rest[parent].T @ rest[child]
        a, b, c = np.degrees(Rotation.from_matrix(rel @ rel0.T).as_euler("YXZ")).T.copy()  # Ry(a) Rx(b) Rz(c)
        if key == "lumbar":
            out.update(lumbar_extension=a, lumbar_bending=b, lumbar_rotation=c)
            continue
        kind, s = key.split("_")
        side = "left" if s == "l" else "right"
        sign = -1.0 if s == "l" else 1.0
        out[f"{kind}_flexion_{side}"] = -a
        out[f"{kind}_adduction_{side}"] = sign * b
        out[f"{kind}_rotation_{side}"] = sign * c
    for kind, name in (("knee", "knee_flexion"), ("ankle", "ankle_dorsiflexion"), ("elbow", "elbow_flexion")):
        for side, s in SUFFIX_OF_SIDE.items():
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{kind}_{s}")
            if j >= 0:
                adr = model.jnt_qposadr[j]
                out[f"{name}_{side}"] = np.degrees(qpos[:, adr] - model.qpos0[adr])
    if root is not None:
        r = np.einsum("nij,kj->nik", xmat[root[1]], rest[root[1]])
        yaw, pitch, roll = np.degrees(Rotation.from_matrix(r).as_euler("ZYX")).T.copy()
        out.update(pelvis_tilt=pitch, pelvis_list=roll, pelvis_rotation=yaw)
    return out
