"""`HumanParams`: the `human` section of params.yaml (scaling, model, contact, standing PD)."""

from __future__ import annotations

from dataclasses import dataclass, field

BALL_JOINTS = ("lumbar", "hip_l", "hip_r", "shoulder_l", "shoulder_r")
HINGE_JOINTS = ("knee_l", "knee_r", "ankle_l", "ankle_r", "elbow_l", "elbow_r")


def joint_kind(joint: str) -> str:
    """`lumbar`, `hip`, `knee`, ... : the per-joint key of the params for `hip_l` etc."""
    return joint.rsplit("_", 1)[0] if joint.endswith(("_l", "_r")) else joint


@dataclass(frozen=True)
class HumanParams:
    """Every tunable number of the human model; units in the names."""

    anthropometry: str = "de_leva_male"
    neutral: str = "static_ik"        # joint zeros: static_ik | static_upright | asis_psis (sim.body.scaling)
    ankle_axis: str = "knee"          # ankle hinge axis with static_ik: knee | malleoli
    # OpenSim foot axes (Delp et al. 1990; gait2392, Rajagopal 2015): right side, x fwd, y up, z right
    talocrural_axis: tuple[float, float, float] = (-0.10501355, -0.17402245, 0.97912632)
    subtalar_axis: tuple[float, float, float] = (0.78717961, 0.60474746, -0.12094949)
    timestep_s: float = 0.002
    knee_width_per_height: float = 0.071
    ankle_width_per_height: float = 0.049
    sjc_below_acromion_fraction: float = 0.17
    head_radius_per_height: float = 0.05
    floor_tolerance_m: float = 0.02
    marker_bone_distance_max_m: float = 0.17  # a marker without role or segment farther is left out
    contact_radius_m: float = 0.02
    friction: float = 1.0
    contact_solref: tuple[float, float] = (0.02, 1.0)
    joint_damping_nms_per_rad: float = 2.0
    armature_kg_m2: float = 0.01
    ball_range_deg: dict[str, float] = field(default_factory=lambda: {
        "lumbar": 60.0, "hip": 120.0, "shoulder": 170.0})
    hinge_range_deg: dict[str, tuple[float, float]] = field(default_factory=lambda: {
        "knee": (-10.0, 140.0), "ankle": (-50.0, 30.0), "elbow": (-5.0, 150.0)})
    torque_limit_nm_per_kg: dict[str, float] = field(default_factory=lambda: {
        "lumbar": 3.0, "hip": 3.0, "knee": 3.2, "ankle": 2.2, "shoulder": 1.0, "elbow": 0.9})
    pd_kp_nm_per_rad: dict[str, float] = field(default_factory=lambda: {
        "lumbar": 2500.0, "hip": 2500.0, "knee": 2500.0, "ankle": 2500.0, "shoulder": 60.0, "elbow": 30.0})
    pd_kd_nms_per_rad: dict[str, float] = field(default_factory=lambda: {
        "lumbar": 20.0, "hip": 20.0, "knee": 10.0, "ankle": 4.0, "shoulder": 2.0, "elbow": 1.0})
    geom_radius_per_height: dict[str, float] = field(default_factory=lambda: {
        "pelvis": 0.045, "torso": 0.06, "thigh": 0.033, "shank": 0.024, "foot": 0.012, "upper_arm": 0.021,
        "forearm": 0.017, "hand": 0.013})

    @property
    def widths_per_height(self) -> tuple[float, float]:
        """(knee, ankle) width / body height: a joint centre lies half a width medial of its lateral
        marker (scaling; `static: none` stands the legs on those centres)."""
        return self.knee_width_per_height, self.ankle_width_per_height

    @classmethod
    def from_dict(cls, d: dict) -> HumanParams:
        """From the `human` section of params.yaml (missing keys keep their defaults)."""
        d = dict(d)
        ranges = d.pop("range_deg", {}) or {}
        out = {}
        for key in ("anthropometry", "neutral", "ankle_axis"):
            if key in d:
                out[key] = str(d.pop(key))
        for key in ("talocrural_axis", "subtalar_axis"):
            if key in d:
                out[key] = tuple(float(v) for v in d.pop(key))
        if "contact_solref" in d:
            out["contact_solref"] = tuple(float(v) for v in d.pop("contact_solref"))
        for key in ("torque_limit_nm_per_kg", "pd_kp_nm_per_rad", "pd_kd_nms_per_rad",
                    "geom_radius_per_height"):
            if key in d:
                out[key] = {str(k): float(v) for k, v in d.pop(key).items()}
        ball = {k: float(v) for k, v in ranges.items() if not isinstance(v, list | tuple)}
        hinge = {k: (float(v[0]), float(v[1])) for k, v in ranges.items() if isinstance(v, list | tuple)}
        if ball:
            out["ball_range_deg"] = ball
        if hinge:
            out["hinge_range_deg"] = hinge
        known = {f for f in cls.__dataclass_fields__}
        unknown = set(d) - known
        if unknown:
            raise KeyError(sorted(unknown)[0])
        out.update({k: float(v) for k, v in d.items()})
        return cls(**out)
