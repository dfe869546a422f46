"""Subject scaling: a static trial + height and mass -> joint centres, segment frames, lengths
and masses of the subject's body in the static pose (`ScaledBody`), which `sim.body.human` turns into
a MuJoCo model.

The static trial comes read (`ingest.static.StaticTrial`: markers as the median over the static
window, the static IK angles, the landmark roles); scaling reads no file.

Static frame (canonical): Z up, X = the direction the subject faces (mid-PSIS -> mid-ASIS),
Y left, origin on the floor (lab floor, z = 0) midway between the feet (mean of heel and toe).

Joint centres: hip by the Harrington et al. (2007) regression (`ingest.kinematics`); knee and
ankle at the midpoint of the lateral and medial markers, or the lateral marker shifted medially
by half a knee / ankle width (a fraction of stature, params) when the set has no medial marker;
elbow and wrist at the midpoint of their two markers; shoulder below the acromion marker by a
fraction of the acromion-elbow distance (Rab et al. 2002, Gait Posture 15:113); neck (C7/T1)
joint in front of the C7 marker, placed from it and the sternum markers (`cervical_joint_centre`),
else over the mid-hip at the C7 marker's height; lumbar joint at the navel level (de Leva's OMPH,
by his trunk subsegment lengths). Landmarks a marker set lacks come from stature ratios (de Leva
1996 lengths, Winter 2009 Fig. 4.1 heights and widths) with the trunk upright and the arms hanging.

Segment frames (columns x forward, y left, z up along the segment) set the zeros of the model's
joints, which `human.neutral` chooses:
- `static_ik` (static calibration of joint zeros, as gait labs do): the frames are placed so that
  the model's joint angles in the static pose equal the dataset's own IK angles of that pose
  (`static.angles` of the subject file, median over the static window: `StaticTrial.angles_deg`):
  pelvis = upright facing the ASIS, then pelvis tilt and list; thigh = pelvis turned by the hip
  flexion, adduction and rotation (intrinsic Y-X-Z, as `sim.motion.retarget.joint_angles` reads
  them); shank = thigh turned by the knee angle about the knee axis, foot = shank turned about the
  ankle axis by the calcaneus' static rotation about the talocrural axis (ankle angle, then the
  subtalar angle the model lacks: `calcaneus_dorsiflexion_deg`, OpenSim foot axes from params). The
  hinge axes stay anatomical (knee: medial-lateral knee markers; ankle: `human.ankle_axis`), written
  in the child's frame (`ScaledBody.hinge_axes`). The model's angles then share the zeros of the
  OpenSim model that produced the subject's `.mot` files. A subject without static angles falls
  back to `static_upright`.
- `static_upright`: pelvis upright and facing the ASIS in the static pose (zero pelvis tilt);
  thigh along the hip-knee line, the knee axis its y; shank and foot turned about that y axis by
  the static hinge angles: knee zero = shank along the thigh's mechanical axis, ankle zero = the
  heel-toe line perpendicular to the shank's.
- `asis_psis`: as `static_upright` with the pelvis in the ASIS/PSIS plane (the marker-based tilt of
  `ingest.kinematics`).
Upper arm is fully 3-D (ball joint above it), forearm its parent's frame turned about y by the
static elbow angle; the torso stands upright. In every mode the static pose is reached exactly by
the model's own joints (keyframe `static`).

Markers ride on bodies (`assign_markers`, the model's sites, which the retarget fits): a marker with a
landmark role on the body its role names, a marker the set lists under `segments` on that body, any
other on the nearest bone only within `human.marker_bone_distance_max_m`; beyond it the marker is left
out of the model (`ScaledBody.markers_left_out`, with its distance).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ingest.canonical import rotate_z
from ingest.kinematics import hip_joint_centres
from ingest.static import StaticTrial
from ingest.subject import Subject
from sim.body.anthropometry import TABLES, WINTER_RATIOS, Table
from sim.body.human_params import HumanParams
from sim.errors import ScalingError

SIDE_NAME_OF_SUFFIX = {"l": "left", "r": "right"}  # the model's side suffixes -> canonical side names
NEUTRALS = ("static_ik", "static_upright", "asis_psis")
ANKLE_AXES = ("knee", "malleoli")
CALIBRATED_JOINTS = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_flexion", "ankle_dorsiflexion")
# body -> the landmark roles whose markers ride on it (side suffix added for sided bodies)
ROLE_BODIES = {
    "pelvis": ("asis", "psis"),
    "torso": ("c7", "shoulder", "sternum"),
    "thigh": ("knee", "knee_medial"),
    "shank": ("ankle", "ankle_medial"),
    "foot": ("heel", "toe", "toe_medial", "toe_lateral"),
    "upper_arm": ("elbow", "elbow_medial"),
    "forearm": ("wrist", "wrist_medial"),
}
# C7/T1 joint centre from C7 and the jugular notch (`cervical_joint_centre`): Reed et al. 1999's
# men's values (Dumas et al. 2007 give 14 deg and 0.53 for women; subject files carry no sex).
CJC_ANGLE_DEG = 8.0
CJC_FRACTION = 0.55
BODIES = ("pelvis", "torso", "head", "thigh_l", "thigh_r", "shank_l", "shank_r", "foot_l", "foot_r",
          "upper_arm_l", "upper_arm_r", "forearm_l", "forearm_r")


@dataclass(frozen=True)
class ScaledBody:
    """A subject's body in the static pose, in the canonical static frame (metres, kg).

    joint_centres: hip_l/r, knee_l/r, ankle_l/r, mid_hip, lumbar, neck (C7/T1), vertex, shoulder_l/r,
    elbow_l/r, wrist_l/r, hand_l/r (third metacarpal end of the hand).
    frames: body -> 3x3 rotation whose columns are the body's axes in the static frame.
    contact_points: foot_l/r -> (4, 3) contact sphere centres (heel medial/lateral, toe
    medial/lateral) resting on the floor.
    hinge_axes: knee_l/r, ankle_l/r -> unit hinge axis in the child body's frame (+ = flexion /
    dorsiflexion); hinges absent here use `sim.body.human.HINGE_AXES` (the frame's y axis).
    neutral: the joint-zero definition used (`human.neutral`, after any fallback); static_ik_deg:
    the static IK angles it was calibrated to (canonical names, degrees; empty when not static_ik).
    marker_bodies: marker -> body it rides on; markers_left_out: marker -> distance (m) to the
    nearest bone of the markers on no body (`assign_markers`).
    """

    subject: str
    height_m: float
    mass_kg: float
    anthropometry: str
    markers: dict[str, np.ndarray]
    joint_centres: dict[str, np.ndarray]
    frames: dict[str, np.ndarray]
    contact_points: dict[str, np.ndarray]
    segment_lengths_m: dict[str, float]
    segment_masses_kg: dict[str, float]
    length_sources: dict[str, str]
    marker_bodies: dict[str, str]
    static_angles_rad: dict[str, float] = field(default_factory=dict)
    hinge_axes: dict[str, np.ndarray] = field(default_factory=dict)
    neutral: str = "static_upright"
    static_ik_deg: dict[str, float] = field(default_factory=dict)
    markers_left_out: dict[str, float] = field(default_factory=dict)

    @property
    def table(self) -> Table:
        return TABLES[self.anthropometry]


def calcaneus_dorsiflexion_deg(ankle_deg: float, subtalar_deg: float, talocrural_axis: np.ndarray,
                               subtalar_axis: np.ndarray) -> float:
    """Rotation of the calcaneus about the talocrural axis (deg, + = dorsiflexion) for an OpenSim
    foot turned by `ankle_deg` about the talocrural axis, then `subtalar_deg` about the subtalar
    axis (both unit vectors in the same frame): the twist part of that composite rotation. The
    model's one-hinge foot carries the calcaneus' markers, so this is its hinge angle; to first
    order ankle + (subtalar axis . talocrural axis) x subtalar."""
    h, n = _unit(np.asarray(talocrural_axis, float)), _unit(np.asarray(subtalar_axis, float))
    rot = Rotation.from_rotvec(np.radians(ankle_deg) * h) * Rotation.from_rotvec(np.radians(subtalar_deg) * n)
    quat = rot.as_quat(canonical=True, scalar_first=True)
    return float(np.degrees(2.0 * np.arctan2(quat[1:] @ h, quat[0])))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def frame_from_zy(z: np.ndarray, y_ref: np.ndarray) -> np.ndarray:
    """Right-handed frame with z along `z` and y as close to `y_ref` as orthogonality allows."""
    z = _unit(z)
    x = _unit(np.cross(y_ref, z))
    return np.column_stack([x, np.cross(z, x), z])


def _sternal_notch(lm: Callable[[str], np.ndarray | None]) -> np.ndarray | None:
    """The jugular notch: the `sternum` marker, or the midpoint of `sternum_left` and
    `sternum_right` (markers on the sternal ends of the clavicles); None without them."""
    single, pair = lm("sternum"), [lm("sternum_left"), lm("sternum_right")]
    if single is not None:
        return single
    return (pair[0] + pair[1]) / 2 if all(m is not None for m in pair) else None


def cervical_joint_centre(c7: np.ndarray, notch: np.ndarray, below: np.ndarray) -> np.ndarray:
    """The C7/T1 joint centre (m) from the C7 spinous process and jugular notch markers, in the
    sagittal plane they span with `below` (a point down the trunk, e.g. the mid-hip): from C7,
    `CJC_FRACTION` of the C7-notch distance along the C7->notch line turned `CJC_ANGLE_DEG` upward.
    Why: the C7 marker sits on the skin of the back, ~7 cm behind the spine's axis; taking it as
    the joint leans the trunk segment (and its mass) backward. Source: Reed, Manary & Schneider
    1999 (SAE 1999-01-0959), as used by Dumas, Cheze & Verriest 2007 (J Biomech 40:543)."""
    x = _unit(notch - c7)
    up = c7 - below
    y = _unit(up - (up @ x) * x)
    a = np.radians(CJC_ANGLE_DEG)
    return c7 + CJC_FRACTION * np.linalg.norm(notch - c7) * (np.cos(a) * x + np.sin(a) * y)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def assign_markers(markers: dict[str, np.ndarray], roles: dict[str, str], jc: dict[str, np.ndarray],
                   arms_measured: bool, segments: Mapping[str, str] | None = None,
                   max_distance_m: float = math.inf, tie_m: float = 0.01,
                   origin: str = "static trial") -> tuple[dict[str, str], dict[str, float]]:
    """(marker -> body, marker -> distance (m) of the markers left out). A marker goes to the body
    its landmark role names; else to the body `segments` gives it (marker -> body, a name of
    `BODIES`); else to the body whose bone (segment between its joint centres) passes closest,
    within `tie_m` of the closest the more proximal body (a marker on the hip centre belongs to the
    pelvis), when that bone lies within `max_distance_m`; farther markers ride on no body and are
    returned with their distance. Arm bones placed by stature ratios are not candidates (they may
    hang over the thigh markers). `ScalingError` naming `origin` for a segment body the model lacks."""
    segments = dict(segments or {})
    unknown = sorted({b for b in segments.values() if b not in BODIES})
    if unknown:
        raise ScalingError(origin, f"segments: unknown bodies {', '.join(unknown)} "
                           f"(bodies: {', '.join(BODIES)})")
    by_role = {}
    for role, name in roles.items():
        side = "l" if role.endswith("_left") else "r" if role.endswith("_right") else None
        base = role.removesuffix("_left").removesuffix("_right")
        for body, bases in ROLE_BODIES.items():
            if base in bases:
                by_role[name] = f"{body}_{side}" if side and body != "pelvis" and body != "torso" else body
    bones = [("pelvis", "hip_l", "hip_r"), ("pelvis", "mid_hip", "lumbar"), ("torso", "lumbar", "neck"),
             ("torso", "shoulder_l", "shoulder_r"), ("head", "neck", "vertex")]
    for s in SIDE_NAME_OF_SUFFIX:
        bones += [(f"thigh_{s}", f"hip_{s}", f"knee_{s}"), (f"shank_{s}", f"knee_{s}", f"ankle_{s}"),
                  (f"foot_{s}", f"heel_{s}", f"toe_{s}")]
        if arms_measured:
            bones += [(f"upper_arm_{s}", f"shoulder_{s}", f"elbow_{s}"),
                      (f"forearm_{s}", f"elbow_{s}", f"hand_{s}")]
    out: dict[str, str] = {}
    left_out: dict[str, float] = {}
    for name, p in markers.items():
        if name in by_role or name in segments:
            out[name] = by_role.get(name) or segments[name]
            continue
        dist = np.array([_segment_distance(p, jc[a], jc[b]) for _, a, b in bones])
        if dist.min() > max_distance_m:
            left_out[name] = float(dist.min())
            continue
        out[name] = bones[int(np.flatnonzero(dist <= dist.min() + tie_m)[0])][0]
    return out, left_out


def _to_static_frame(markers: dict[str, np.ndarray], roles: dict[str, str], origin: str,
                     floor_tol_m: float) -> dict[str, np.ndarray]:
    """Rotate about Z so the pelvis faces +X and shift the origin between the feet."""
    need = [f"{r}_{s}" for r in ("asis", "psis", "heel", "toe") for s in ("left", "right")]
    missing = [f"{r} ({roles.get(r)})" for r in need if roles.get(r) not in markers]
    if missing:
        raise ScalingError(origin, f"static trial lacks landmark markers: {', '.join(missing)}")
    m = lambda r: markers[roles[r]]  # noqa: E731
    facing = (m("asis_left") + m("asis_right") - m("psis_left") - m("psis_right")) / 2
    heading = float(np.arctan2(facing[1], facing[0]))
    out = {n: rotate_z(p, heading) for n, p in markers.items()}
    feet = [out[roles[f"{r}_{s}"]] for r in ("heel", "toe") for s in ("left", "right")]
    centre = np.mean(feet, axis=0)
    low = min(p[2] for p in feet)
    if not -floor_tol_m <= low <= 0.15:
        raise ScalingError(origin, f"lowest foot marker is {low:.3f} m above the lab floor (z = 0); "
                           "expected 0-0.15 m: the static trial is not standing on the floor")
    shift = np.array([centre[0], centre[1], 0.0])
    return {n: p - shift for n, p in out.items()}


def _static_ik(static: StaticTrial) -> dict[str, float]:
    """The static IK angles `human.neutral: static_ik` calibrates to ({} without static angles)."""
    ik = static.angles_deg
    need = [f"{j}_{s}" for j in CALIBRATED_JOINTS for s in ("left", "right")] + ["pelvis_tilt", "pelvis_list"]
    missing = [k for k in need if not np.isfinite(ik.get(k, np.nan))]
    if ik and missing:
        raise ScalingError(static.angles_source, f"static IK lacks {', '.join(missing)} (needed by "
                           "human.neutral: static_ik)")
    return dict(ik)


def scale_subject(subject: Subject, static: StaticTrial, p: HumanParams) -> ScaledBody:
    """Joint centres, segment frames, lengths and masses of `subject` from its static trial."""
    origin, roles = static.source, static.roles
    markers = _to_static_frame(static.markers, roles, origin, p.floor_tolerance_m)
    table = TABLES.get(p.anthropometry)
    if table is None:
        raise ScalingError(origin, f"unknown anthropometry table {p.anthropometry!r} "
                           f"(known: {', '.join(TABLES)})")
    H, up = subject.height_m, np.array([0.0, 0.0, 1.0])

    def lm(role: str) -> np.ndarray | None:
        name = roles.get(role)
        return markers.get(name) if name else None

    jc: dict[str, np.ndarray] = {}
    sources: dict[str, str] = {}
    frames: dict[str, np.ndarray] = {}
    angles: dict[str, float] = {}
    asis_l, asis_r, psis_l, psis_r = (lm(r) for r in ("asis_left", "asis_right", "psis_left", "psis_right"))
    hjc = hip_joint_centres(asis_l[None], asis_r[None], psis_l[None], psis_r[None])
    jc["hip_l"], jc["hip_r"] = hjc["left"][0], hjc["right"][0]
    jc["mid_hip"] = (jc["hip_l"] + jc["hip_r"]) / 2
    pelvis_y = _unit(asis_l - asis_r)
    anatomical = frame_from_zy(np.cross(_unit((asis_l + asis_r - psis_l - psis_r) / 2), pelvis_y), pelvis_y)
    fwd = anatomical[:, 0].copy()
    fwd[2] = 0.0
    upright = np.column_stack([_unit(fwd), np.cross(up, _unit(fwd)), up])
    if p.neutral not in NEUTRALS or p.ankle_axis not in ANKLE_AXES:
        raise ScalingError(origin, f"unknown neutral {p.neutral!r} or ankle_axis {p.ankle_axis!r} "
                           f"(known: {', '.join(NEUTRALS)}; {', '.join(ANKLE_AXES)})")
    ik = _static_ik(static) if p.neutral == "static_ik" else {}
    neutral = "static_upright" if p.neutral == "static_ik" and not ik else p.neutral
    hinge_axes: dict[str, np.ndarray] = {}
    if neutral == "static_ik":
        tilt, pelvis_list = np.radians(ik["pelvis_tilt"]), np.radians(ik["pelvis_list"])
        # yaw, pitch, roll as joint_angles reads them
        frames["pelvis"] = upright @ Rotation.from_euler("YX", [tilt, pelvis_list]).as_matrix()
    else:
        frames["pelvis"] = upright if neutral == "static_upright" else anatomical
    # Torso upright in the static pose, facing the pelvis' heading.
    frames["torso"] = frames["head"] = upright
    torso_y = upright[:, 1]

    for s, side in SIDE_NAME_OF_SUFFIX.items():
        sign = 1.0 if s == "l" else -1.0  # +Y is left
        for joint, width in (("knee", p.knee_width_per_height), ("ankle", p.ankle_width_per_height)):
            lat, med = lm(f"{joint}_{side}"), lm(f"{joint}_medial_{side}")
            if lat is None:
                raise ScalingError(origin, f"static trial lacks the {joint}_{side} marker")
            if med is not None:
                jc[f"{joint}_{s}"], sources[f"{joint}_{s}"] = (lat + med) / 2, "markers"
                jc[f"{joint}_axis_{s}"] = _unit(sign * (lat - med))
            else:
                jc[f"{joint}_{s}"] = lat - sign * pelvis_y * width * H / 2
                sources[f"{joint}_{s}"] = "lateral marker + width ratio"
        heel, toe = lm(f"heel_{side}"), lm(f"toe_{side}")
        jc[f"heel_{s}"], jc[f"toe_{s}"] = heel, toe
        axis = jc.get(f"knee_axis_{s}", pelvis_y)
        if neutral == "static_ik":
            leg_ik = dict(ik)
            leg_ik[f"ankle_dorsiflexion_{side}"] = calcaneus_dorsiflexion_deg(
                ik[f"ankle_dorsiflexion_{side}"], ik.get(f"subtalar_{side}", 0.0),
                np.array(p.talocrural_axis), np.array(p.subtalar_axis))
            ankle_axis = jc.get(f"ankle_axis_{s}", axis) if p.ankle_axis == "malleoli" else axis
            thigh, shank, foot = _calibrated_leg(frames["pelvis"], leg_ik, s, axis, ankle_axis, angles,
                                                 hinge_axes)
            frames.update({f"thigh_{s}": thigh, f"shank_{s}": shank, f"foot_{s}": foot})
            continue
        thigh = frame_from_zy(jc[f"hip_{s}"] - jc[f"knee_{s}"], axis)
        v = thigh.T @ (jc[f"ankle_{s}"] - jc[f"knee_{s}"])
        angles[f"knee_{s}"] = float(np.arctan2(-v[0], -v[2]))
        shank = thigh @ Rotation.from_euler("y", angles[f"knee_{s}"]).as_matrix()
        u = shank.T @ np.array([*(toe - heel)[:2], 0.0])
        angles[f"ankle_{s}"] = float(np.arctan2(u[2], u[0]))
        foot = shank @ Rotation.from_euler("y", -angles[f"ankle_{s}"]).as_matrix()
        frames.update({f"thigh_{s}": thigh, f"shank_{s}": shank, f"foot_{s}": foot})

    # Trunk and head: the neck (C7/T1) joint centre from the C7 and sternum markers, else at the
    # C7 marker's or the head length's height over the mid-hip; vertex at the subject's height.
    c7, notch = lm("c7"), _sternal_notch(lm)
    if c7 is not None and notch is not None:
        neck, sources["neck"] = cervical_joint_centre(c7, notch, jc["mid_hip"]), "Reed 1999 (C7, sternum)"
    else:
        neck_z = c7[2] if c7 is not None else H - table.length_ratio("head") * H
        neck = np.array([*jc["mid_hip"][:2], neck_z])
        sources["neck"] = "C7 height over the mid-hip" if c7 is not None else "height ratio"
    jc["neck"] = neck
    jc["vertex"] = np.array([neck[0], neck[1], H])
    trunk_parts = [table.segments[n].length_mm for n in ("upper_trunk", "mid_trunk", "lower_trunk")]
    jc["lumbar"] = jc["mid_hip"] + (neck - jc["mid_hip"]) * trunk_parts[2] / sum(trunk_parts)

    for s, side in SIDE_NAME_OF_SUFFIX.items():
        sign = 1.0 if s == "l" else -1.0
        l_ua, l_fa, l_hand = (table.length_ratio(n) * H for n in ("upper_arm", "forearm", "hand"))
        acromion = lm(f"shoulder_{side}")
        elbow = [lm(f"elbow_{side}"), lm(f"elbow_medial_{side}")]
        wrist = [lm(f"wrist_{side}"), lm(f"wrist_medial_{side}")]
        if acromion is None:
            acromion = np.array([jc["mid_hip"][0], 0.0, WINTER_RATIOS["shoulder_height"] * H]) \
                + sign * torso_y * WINTER_RATIOS["shoulder_width"] * H / 2
        if all(e is not None for e in elbow):
            ejc = (elbow[0] + elbow[1]) / 2
            sjc = acromion - up * p.sjc_below_acromion_fraction * np.linalg.norm(acromion - ejc)
            sources[f"elbow_{s}"] = "markers"
        else:
            sjc = acromion - up * p.sjc_below_acromion_fraction * l_ua
            ejc = sjc - up * l_ua
            sources[f"elbow_{s}"] = "height ratio"
        if all(w is not None for w in wrist):
            wjc, sources[f"wrist_{s}"] = (wrist[0] + wrist[1]) / 2, "markers"
        else:
            wjc, sources[f"wrist_{s}"] = ejc - up * l_fa, "height ratio"
        jc[f"shoulder_{s}"], jc[f"elbow_{s}"], jc[f"wrist_{s}"] = sjc, ejc, wjc
        jc[f"hand_{s}"] = wjc + _unit(wjc - ejc) * l_hand
        axis = _unit(sign * (elbow[0] - elbow[1])) if all(e is not None for e in elbow) else torso_y
        upper = frame_from_zy(sjc - ejc, axis)
        v = upper.T @ (wjc - ejc)
        angles[f"elbow_{s}"] = float(np.arctan2(v[0], -v[2]))
        frames[f"upper_arm_{s}"] = upper
        frames[f"forearm_{s}"] = upper @ Rotation.from_euler("y", -angles[f"elbow_{s}"]).as_matrix()

    contact = {}
    for s, side in SIDE_NAME_OF_SUFFIX.items():
        contact[f"foot_{s}"] = _contact_points(jc, s, lm(f"toe_medial_{side}"), lm(f"toe_lateral_{side}"),
                                               1.0 if s == "l" else -1.0, WINTER_RATIOS["foot_width"] * H,
                                               p.contact_radius_m)

    lengths = {"pelvis_width": float(np.linalg.norm(jc["hip_l"] - jc["hip_r"])),
               "pelvis_height": float(np.linalg.norm(jc["lumbar"] - jc["mid_hip"])),
               "torso": float(np.linalg.norm(jc["neck"] - jc["lumbar"])),
               "head": float(np.linalg.norm(jc["vertex"] - jc["neck"]))}
    for s in SIDE_NAME_OF_SUFFIX:
        for seg, a, b in (("thigh", "hip", "knee"), ("shank", "knee", "ankle"),
                          ("upper_arm", "shoulder", "elbow"), ("forearm", "elbow", "wrist"),
                          ("hand", "wrist", "hand"), ("foot", "heel", "toe")):
            lengths[f"{seg}_{s}"] = float(np.linalg.norm(jc[f"{b}_{s}"] - jc[f"{a}_{s}"]))
    sources.update({"hip_l": "Harrington 2007", "hip_r": "Harrington 2007", "vertex": "height_m"})
    bodies, left_out = assign_markers(markers, roles, jc, sources.get("elbow_l") == "markers",
                                      static.segments, p.marker_bone_distance_max_m, origin=origin)
    return ScaledBody(subject.id, H, subject.mass_kg, p.anthropometry, markers, jc, frames, contact,
                      lengths, segment_masses(table, subject.mass_kg), sources, bodies, angles,
                      hinge_axes, neutral, ik, left_out)


def _calibrated_leg(pelvis: np.ndarray, ik: dict[str, float], s: str, knee_axis: np.ndarray,
                    ankle_axis: np.ndarray, angles: dict[str, float],
                    hinge_axes: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thigh, shank and foot frames of side `s` whose joint angles to the calibrated pelvis are the
    static IK angles `ik` (degrees): hip as intrinsic Y-X-Z (flexion about -y; adduction and
    internal rotation toward the midline, mirrored on the left, as `sim.motion.retarget.joint_angles`
    decomposes it); knee and ankle hinges about the anatomical axes `knee_axis` / `ankle_axis`
    (unit, static frame, pointing left). Fills the static hinge angles and the hinge axes (child
    frame, + = flexion / dorsiflexion)."""
    side = SIDE_NAME_OF_SUFFIX[s]
    sgn = -1.0 if s == "l" else 1.0
    rad = {k: np.radians(ik[f"{k}_{side}"]) for k in ("hip_flexion", "hip_adduction", "hip_rotation",
                                                      "knee_flexion", "ankle_dorsiflexion")}
    hip = [-rad["hip_flexion"], sgn * rad["hip_adduction"], sgn * rad["hip_rotation"]]
    thigh = pelvis @ Rotation.from_euler("YXZ", hip).as_matrix()
    knee = _unit(thigh.T @ knee_axis)
    shank = thigh @ Rotation.from_rotvec(rad["knee_flexion"] * knee).as_matrix()
    ankle = -_unit(shank.T @ ankle_axis)  # pointing right: + = dorsiflexion (toes up)
    foot = shank @ Rotation.from_rotvec(rad["ankle_dorsiflexion"] * ankle).as_matrix()
    angles[f"knee_{s}"], angles[f"ankle_{s}"] = float(rad["knee_flexion"]), float(rad["ankle_dorsiflexion"])
    hinge_axes[f"knee_{s}"], hinge_axes[f"ankle_{s}"] = knee, ankle
    return thigh, shank, foot


def _contact_points(jc: dict[str, np.ndarray], s: str, toe_med: np.ndarray | None,
                    toe_lat: np.ndarray | None, sign: float, width_ratio_m: float,
                    radius_m: float) -> np.ndarray:
    """Heel (medial, lateral) and toe (medial, lateral) sphere centres on the floor: heel spheres
    just in front of the heel marker, toe spheres behind the toe marker; toe width from the
    medial/lateral toe markers when present, else the foot-width ratio; heel half as wide."""
    heel, toe = jc[f"heel_{s}"], jc[f"toe_{s}"]
    u = np.array([*(toe - heel)[:2], 0.0])
    u /= np.linalg.norm(u)
    left = np.array([-u[1], u[0], 0.0])
    if toe_med is not None and toe_lat is not None:
        width = abs(float(np.dot(toe_med - toe_lat, left)))
    else:
        width = width_ratio_m
    half = max(width / 2 - radius_m, radius_m)
    heel_c = heel + u * radius_m
    toe_c = toe - u * radius_m
    pts = [heel_c + sign * left * half / 2, heel_c - sign * left * half / 2,
           toe_c + sign * left * half, toe_c - sign * left * half]  # medial: towards the midline
    pts = np.array(pts)
    pts[:, 2] = radius_m
    return pts


def knee_valgus_deg(joint_centres: Mapping[str, np.ndarray], side: str) -> float:
    """Frontal-plane angle at the knee between thigh (hip -> knee) and shank (knee -> ankle) of `side`
    ('l' or 'r') in the static frame (y left, z up), degrees: + valgus (knee medial of the hip-ankle
    line), - varus. The model keeps it as a lateral offset of the ankle in the shank (the knee is a
    hinge), so the zero pose stands with the feet that much apart. Healthy adults: mechanical axis
    1.3 +- 2 deg varus (Moreland, Bassett & Hanker 1987, J Bone Joint Surg Am 69:745)."""
    hip, knee, ankle = (np.asarray(joint_centres[f"{j}_{side}"], float) for j in ("hip", "knee", "ankle"))
    thigh, shank = knee - hip, ankle - knee
    turn = math.atan2(shank[1], -shank[2]) - math.atan2(thigh[1], -thigh[2])  # + toward the left
    return math.degrees(turn if side == "l" else -turn)


def segment_masses(table: Table, mass_kg: float) -> dict[str, float]:
    """Body masses (kg) of the model's bodies from the table, renormalised to sum to `mass_kg`:
    pelvis = lower trunk, torso = upper + mid trunk, forearm = forearm + hand."""
    seg = table.segments
    frac = {"pelvis": seg["lower_trunk"].mass_fraction,
            "torso": seg["upper_trunk"].mass_fraction + seg["mid_trunk"].mass_fraction,
            "head": seg["head"].mass_fraction}
    for s in SIDE_NAME_OF_SUFFIX:
        frac |= {f"thigh_{s}": seg["thigh"].mass_fraction, f"shank_{s}": seg["shank"].mass_fraction,
                 f"foot_{s}": seg["foot"].mass_fraction, f"upper_arm_{s}": seg["upper_arm"].mass_fraction,
                 f"forearm_{s}": seg["forearm"].mass_fraction + seg["hand"].mass_fraction}
    total = sum(frac.values())
    return {b: mass_kg * f / total for b, f in frac.items()}
