"""The subject-scaled 27-DoF human built with `mujoco.MjSpec` from a `ScaledBody`.

Conventions (shared with retargeting, the robot harness and rollouts):
- Z up, gravity -Z, a plane `floor`; timestep from params, implicitfast integrator.
- At qpos0 every body frame is aligned with the world (x forward, y left, z up): the human
  stands upright facing +X with the lowest foot contact on the floor. Keyframe `static` holds the
  subject's static pose (exactly the static trial's joint centres and markers).
- Bodies: pelvis (free joint `root`), torso (ball `lumbar`), head (welded to torso), thigh_l/r
  (ball `hip_l/r`), shank_l/r (hinge `knee_l/r`), foot_l/r (hinge `ankle_l/r`), upper_arm_l/r
  (ball `shoulder_l/r`), forearm_l/r with the hand (hinge `elbow_l/r`). nv = 27, nu = 21.
- Hinge axes: knee +y, ankle -y, elbow -y, so that positive = knee flexion, ankle dorsiflexion,
  elbow flexion. Ball joints rotate the child from the parent frame (hip flexion is about -y).
- Motors: `<joint>` on hinges, `<joint>_x/_y/_z` on ball joints (torque about that axis of the
  joint frame), ctrl in [-1, 1], gear = the joint's torque limit (params, N m/kg x body mass).
- Sites: one per static-trial marker, named as in the marker file, on the body it rides on
  (site group `MARKER_SITE_GROUP`).
- Collisions: bit 1 = feet (4 contact spheres each: heel medial/lateral, toe medial/lateral,
  giving heel-to-toe roll-over), bit 2 = every other geom. The floor collides with both; feet
  collide with each other; body geoms collide with the floor only (no self-collision).
- Inertia: de Leva (1996) masses, CoM and radii of gyration on the segment axes; geoms carry none.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from sim.body.anthropometry import TABLES, Inertial, combine, segment_inertial
from sim.body.human_params import BALL_JOINTS, HINGE_JOINTS, HumanParams, joint_kind
from sim.body.scaling import SIDE_NAME_OF_SUFFIX, ScaledBody, frame_from_zy
from sim.errors import SimulationError

MARKER_SITE_GROUP = 4
FOOT_BIT, BODY_BIT = 1, 2
HINGE_AXES = {"knee": (0.0, 1.0, 0.0), "ankle": (0.0, -1.0, 0.0), "elbow": (0.0, -1.0, 0.0)}
SKIN = (0.85, 0.7, 0.6, 1.0)


def _quat(rot: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot).ravel())
    return q


def _tree(body: ScaledBody) -> list[tuple[str, str | None, str, str | None]]:
    """(body, parent, origin joint centre, joint name) in build order."""
    rows = [("pelvis", None, "mid_hip", "root"), ("torso", "pelvis", "lumbar", "lumbar"),
            ("head", "torso", "neck", None)]
    for s in SIDE_NAME_OF_SUFFIX:
        rows += [(f"upper_arm_{s}", "torso", f"shoulder_{s}", f"shoulder_{s}"),
                 (f"forearm_{s}", f"upper_arm_{s}", f"elbow_{s}", f"elbow_{s}")]
    for s in SIDE_NAME_OF_SUFFIX:
        rows += [(f"thigh_{s}", "pelvis", f"hip_{s}", f"hip_{s}"),
                 (f"shank_{s}", f"thigh_{s}", f"knee_{s}", f"knee_{s}"),
                 (f"foot_{s}", f"shank_{s}", f"ankle_{s}", f"ankle_{s}")]
    return rows


def _local(body: ScaledBody, name: str, point: np.ndarray) -> np.ndarray:
    """A static-frame point in body `name`'s frame."""
    origin = body.joint_centres[dict((b, o) for b, _, o, _ in _tree(body))[name]]
    return body.frames[name].T @ (point - origin)


def _segment(body: ScaledBody, name: str, seg: str, prox: str | np.ndarray, dist: str | np.ndarray,
             scale: float) -> Inertial:
    """de Leva segment `seg` from joint centre (or point) `prox` to `dist`, in body `name`'s frame."""
    jc = body.joint_centres
    a = _local(body, name, jc[prox] if isinstance(prox, str) else prox)
    b = _local(body, name, jc[dist] if isinstance(dist, str) else dist)
    axes = frame_from_zy(b - a, np.array([0.0, 1.0, 0.0]))
    return segment_inertial(body.table.segments[seg], body.mass_kg * scale, a, b, axes)


def body_inertials(body: ScaledBody) -> dict[str, Inertial]:
    """Mass, CoM and inertia of every model body in its own frame (de Leva 1996)."""
    table = TABLES[body.anthropometry]
    scale = 1.0 / sum(s.mass_fraction * (2 if n in ("upper_arm", "forearm", "hand", "thigh", "shank", "foot")
                                         else 1) for n, s in table.segments.items())
    jc = body.joint_centres
    trunk = [table.segments[n].length_mm for n in ("upper_trunk", "mid_trunk")]
    xyph = jc["neck"] + (jc["lumbar"] - jc["neck"]) * trunk[0] / sum(trunk)
    out = {"pelvis": _segment(body, "pelvis", "lower_trunk", "lumbar", "mid_hip", scale),
           "torso": combine([_segment(body, "torso", "upper_trunk", "neck", xyph, scale),
                             _segment(body, "torso", "mid_trunk", xyph, "lumbar", scale)]),
           "head": _segment(body, "head", "head", "vertex", "neck", scale)}
    for s in SIDE_NAME_OF_SUFFIX:
        out[f"thigh_{s}"] = _segment(body, f"thigh_{s}", "thigh", f"hip_{s}", f"knee_{s}", scale)
        out[f"shank_{s}"] = _segment(body, f"shank_{s}", "shank", f"knee_{s}", f"ankle_{s}", scale)
        out[f"foot_{s}"] = _segment(body, f"foot_{s}", "foot", f"heel_{s}", f"toe_{s}", scale)
        out[f"upper_arm_{s}"] = _segment(body, f"upper_arm_{s}", "upper_arm", f"shoulder_{s}", f"elbow_{s}",
                                         scale)
        out[f"forearm_{s}"] = combine([
            _segment(body, f"forearm_{s}", "forearm", f"elbow_{s}", f"wrist_{s}", scale),
            _segment(body, f"forearm_{s}", "hand", f"wrist_{s}", f"hand_{s}", scale)])
    return out


def _capsule(b: mujoco.MjsBody, name: str, a: np.ndarray, c: np.ndarray, radius: float) -> None:
    g = b.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[radius, 0, 0],
                   fromto=np.concatenate([a, c]), rgba=SKIN, contype=BODY_BIT, conaffinity=0, group=1)
    g.mass = 0.0


def build_human(body: ScaledBody, p: HumanParams) -> mujoco.MjSpec:
    """The human model of `body` (see module docstring for its conventions)."""
    spec = mujoco.MjSpec()
    spec.modelname = f"human_{body.subject}"
    spec.compiler.degree = False
    spec.option.timestep = p.timestep_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.05],
                            contype=FOOT_BIT, conaffinity=FOOT_BIT | BODY_BIT,
                            friction=[p.friction, 0.005, 1e-4], rgba=[0.8, 0.8, 0.8, 1], group=0)
    spec.worldbody.add_light(name="sun", pos=[0, 0, 4], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    jc = body.joint_centres
    origins = {n: o for n, _, o, _ in _tree(body)}
    inert = body_inertials(body)
    built: dict[str, mujoco.MjsBody] = {}
    for name, parent, origin, joint in _tree(body):
        if parent is None:
            b = spec.worldbody.add_body(name=name, pos=[0.0, 0.0, 1.0])
            b.add_freejoint(name="root")
        else:
            pos = body.frames[parent].T @ (jc[origin] - jc[origins[parent]])
            b = built[parent].add_body(name=name, pos=pos)
            if joint is not None:
                kind = joint_kind(joint)
                if joint in BALL_JOINTS:
                    b.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_BALL,
                                range=[0.0, np.radians(p.range_deg[kind])],
                                limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                                damping=p.joint_damping_nms_per_rad, armature=p.armature_kg_m2)
                else:
                    axis = body.hinge_axes.get(joint, HINGE_AXES[kind])
                    b.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                                range=np.radians(p.range_deg[kind]),
                                limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                                damping=p.joint_damping_nms_per_rad, armature=p.armature_kg_m2)
        i = inert[name]
        b.explicitinertial = True
        b.mass = i.mass_kg
        b.ipos = i.com_m
        b.fullinertia = [i.inertia[0, 0], i.inertia[1, 1], i.inertia[2, 2], i.inertia[0, 1],
                         i.inertia[0, 2], i.inertia[1, 2]]
        built[name] = b
        _add_geoms(body, name, b, p)
        if name.startswith("foot_"):
            for k, c in enumerate(body.contact_points[name]):
                g = b.add_geom(name=f"{name}_contact{k}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                               size=[p.contact_radius_m, 0, 0], pos=_local(body, name, c),
                               contype=FOOT_BIT, conaffinity=FOOT_BIT, condim=3,
                               friction=[p.friction, 0.005, 1e-4], solref=list(p.contact_solref),
                               rgba=[0.3, 0.3, 0.3, 1], group=1)
                g.mass = 0.0
    for marker, bname in sorted(body.marker_bodies.items()):
        built[bname].add_site(name=marker, pos=_local(body, bname, body.markers[marker]),
                              size=[0.008, 0, 0], rgba=[0.1, 0.3, 1.0, 1], group=MARKER_SITE_GROUP)
    for joint in BALL_JOINTS + HINGE_JOINTS:
        gear = p.torque_limit_nm_per_kg[joint_kind(joint)] * body.mass_kg
        axes = ("x", "y", "z") if joint in BALL_JOINTS else ("",)
        for k, ax in enumerate(axes):
            vec = [0.0] * 6
            vec[k] = gear
            spec.add_actuator(name=f"{joint}_{ax}" if ax else joint, target=joint,
                              trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=vec, ctrlrange=[-1.0, 1.0],
                              ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE)
    _stand_on_floor(spec, p)
    spec.add_key(name="static", qpos=static_qpos(spec.compile(), body))
    return spec


def _add_geoms(body: ScaledBody, name: str, b: mujoco.MjsBody, p: HumanParams) -> None:
    """Capsules along the bones (shape only: no mass), a sphere for the head touching the vertex."""
    jc, r, H = body.joint_centres, p.geom_radius_per_height, body.height_m
    loc = lambda point: _local(body, name, jc[point])  # noqa: E731
    if name == "pelvis":
        _capsule(b, "pelvis_geom", loc("hip_l"), loc("hip_r"), r["pelvis"] * H)
    elif name == "torso":
        _capsule(b, "torso_geom", loc("lumbar") + [0, 0, r["torso"] * H], loc("neck"), r["torso"] * H)
        _capsule(b, "shoulders_geom", loc("shoulder_l"), loc("shoulder_r"), r["upper_arm"] * H)
    elif name == "head":
        radius = p.head_radius_per_height * H
        centre = loc("vertex") - np.array([0.0, 0.0, radius])
        g = b.add_geom(name="head_geom", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0],
                       pos=centre, rgba=SKIN, contype=BODY_BIT, conaffinity=0, group=1)
        g.mass = 0.0
        _capsule(b, "neck_geom", loc("neck"), centre, 0.4 * radius)
        nose = b.add_geom(name="nose_geom", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.25 * radius, 0, 0],
                          pos=centre + np.array([radius, 0.0, 0.0]), rgba=SKIN, contype=0, conaffinity=0,
                          group=1)  # shows which way the model faces (+X) in pictures
        nose.mass = 0.0
    else:
        seg, s = name.rsplit("_", 1)
        ends = {"thigh": ("knee",), "shank": ("ankle",), "upper_arm": ("elbow",), "forearm": ("wrist",),
                "foot": ("heel", "toe")}[seg]
        if seg == "foot":
            _capsule(b, f"{name}_geom", loc(f"heel_{s}"), loc(f"toe_{s}"), r["foot"] * H)
        else:
            _capsule(b, f"{name}_geom", np.zeros(3), loc(f"{ends[0]}_{s}"), r[seg] * H)
        if seg == "forearm":
            _capsule(b, f"hand_{s}_geom", loc(f"wrist_{s}"), loc(f"hand_{s}"), r["hand"] * H)


def _stand_on_floor(spec: mujoco.MjSpec, p: HumanParams) -> None:
    """Put the pelvis at the height where the lowest foot contact touches the floor at qpos0."""
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    feet = [g for g in range(model.ngeom) if model.geom_contype[g] == FOOT_BIT and model.geom_bodyid[g] > 0]
    low = min(data.geom_xpos[g, 2] - model.geom_size[g, 0] for g in feet)
    pelvis = spec.body("pelvis")
    pelvis.pos = [0.0, 0.0, pelvis.pos[2] - low]


def static_qpos(model: mujoco.MjModel, body: ScaledBody) -> np.ndarray:
    """qpos of the subject's static pose: root at the static mid-hip, ball joints from the static
    segment frames, hinges at the static hinge angles."""
    qpos = model.qpos0.copy()
    f = body.frames

    def put(joint: str, value: np.ndarray | float) -> None:
        j = model.joint(joint)
        n = {0: 7, 1: 4, 2: 1, 3: 1}[int(j.type[0])]
        qpos[j.qposadr[0]:j.qposadr[0] + n] = value

    put("root", np.concatenate([body.joint_centres["mid_hip"], _quat(f["pelvis"])]))
    put("lumbar", _quat(f["pelvis"].T @ f["torso"]))
    for s in SIDE_NAME_OF_SUFFIX:
        put(f"hip_{s}", _quat(f["pelvis"].T @ f[f"thigh_{s}"]))
        put(f"shoulder_{s}", _quat(f["torso"].T @ f[f"upper_arm_{s}"]))
        for hinge in ("knee", "ankle", "elbow"):
            put(f"{hinge}_{s}", body.static_angles_rad[f"{hinge}_{s}"])
    return qpos


def load_human_model(path: str | Path) -> mujoco.MjModel:
    """Compile a saved human MJCF; raises `SimulationError` naming the file when it cannot."""
    path = Path(path)
    if not path.is_file():
        raise SimulationError(path, "no human model here: run `python -m pipeline scale <subject>`")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise SimulationError(path, f"MuJoCo cannot compile the model ({exc})") from None


def actuator_dofs(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(dof index, gear) of each joint motor: the dof it drives and its torque scale (N m per ctrl)."""
    dofs, gears = [], []
    for a in range(model.nu):
        j = model.actuator_trnid[a, 0]
        g = model.actuator_gear[a]
        axis = int(np.argmax(np.abs(g[:3]))) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL else 0
        dofs.append(model.jnt_dofadr[j] + axis)
        gears.append(g[axis])
    return np.array(dofs), np.array(gears)


def pose_hold_gains(model: mujoco.MjModel, p: HumanParams) -> tuple[np.ndarray, np.ndarray]:
    """Per-actuator PD gains (kp N m/rad, kd N m s/rad) from params, by joint kind."""
    kinds = [joint_kind(model.joint(model.actuator_trnid[a, 0]).name) for a in range(model.nu)]
    return (np.array([p.pd_kp_nm_per_rad[k] for k in kinds]),
            np.array([p.pd_kd_nms_per_rad[k] for k in kinds]))


def pose_hold_ctrl(model: mujoco.MjModel, data: mujoco.MjData, qpos_ref: np.ndarray, kp: np.ndarray,
                   kd: np.ndarray) -> np.ndarray:
    """Joint PD toward `qpos_ref` (ball joints by their rotation error) as motor controls in [-1, 1]."""
    err = np.zeros(model.nv)
    mujoco.mj_differentiatePos(model, err, 1.0, data.qpos, qpos_ref)
    dofs, gears = actuator_dofs(model)
    torque = kp * err[dofs] - kd * data.qvel[dofs]
    return np.clip(torque / gears, -1.0, 1.0)


def standing_height(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Top of the highest geom (sphere or capsule end) above the floor, for `data`'s pose."""
    top = -np.inf
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0:
            continue
        r = model.geom_size[g, 0]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g, 1]
            z = max(data.geom_xpos[g, 2] + axis[2], data.geom_xpos[g, 2] - axis[2])
        else:
            z = data.geom_xpos[g, 2]
        top = max(top, z + r)
    return float(top)


def model_checks(model: mujoco.MjModel, body: ScaledBody) -> dict:
    """Numbers to hold the model to: DoF and motor counts, total mass vs the subject's, standing
    height (static pose and qpos0) vs height_m, and thigh / shank lengths in the model vs the
    joint-centre distances of the static markers."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("static").id)
    mujoco.mj_kinematics(model, data)
    out = {"nq": int(model.nq), "nv": int(model.nv), "nu": int(model.nu),
           "total_mass_kg": round(float(model.body_mass.sum()), 4),
           "mass_error_pct": round(100 * (model.body_mass.sum() / body.mass_kg - 1), 4),
           "standing_height_static_m": round(standing_height(model, data), 4)}
    out["height_error_pct"] = round(100 * (out["standing_height_static_m"] / body.height_m - 1), 3)
    lengths = {}
    for s in SIDE_NAME_OF_SUFFIX:
        for seg, a, b in (("thigh", f"thigh_{s}", f"shank_{s}"), ("shank", f"shank_{s}", f"foot_{s}")):
            model_len = float(np.linalg.norm(data.xpos[model.body(b).id] - data.xpos[model.body(a).id]))
            lengths[f"{seg}_{s}"] = {"model_m": round(model_len, 4),
                                     "markers_m": round(body.segment_lengths_m[f"{seg}_{s}"], 4)}
    out["segment_lengths"] = lengths
    mujoco.mj_resetData(model, data)
    mujoco.mj_kinematics(model, data)
    out["standing_height_qpos0_m"] = round(standing_height(model, data), 4)
    return out
