"""`HumanParams`: the `human` section of params.yaml (scaling, model, contact, standing PD)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import Field, with_config

BALL_JOINTS = ("lumbar", "hip_l", "hip_r", "shoulder_l", "shoulder_r")
HINGE_JOINTS = ("knee_l", "knee_r", "ankle_l", "ankle_r", "elbow_l", "elbow_r")


def joint_kind(joint: str) -> str:
    """`lumbar`, `hip`, `knee`, ... : the per-joint key of the params for `hip_l` etc."""
    return joint.rsplit("_", 1)[0] if joint.endswith(("_l", "_r")) else joint


class ByName:
    """Values read by key, as `p.torque_limit_nm_per_kg["knee"]`."""

    def __getitem__(self, key: str):
        return getattr(self, key)


@with_config(extra="forbid")
@dataclass(frozen=True)
class JointValues(ByName):
    """One value per joint kind (`joint_kind`)."""

    lumbar: float
    hip: float
    knee: float
    ankle: float
    shoulder: float
    elbow: float


@with_config(extra="forbid")
@dataclass(frozen=True)
class RangeDeg(ByName):
    """Ranges of motion (deg): ball joints the total rotation from upright, hinges [min, max] in
    canonical signs."""

    lumbar: float = 60.0
    hip: float = 120.0
    shoulder: float = 170.0
    knee: tuple[float, float] = (-10.0, 140.0)
    ankle: tuple[float, float] = (-50.0, 30.0)
    elbow: tuple[float, float] = (-5.0, 150.0)


@with_config(extra="forbid")
@dataclass(frozen=True)
class GeomRadius(ByName):
    """Capsule radius of each segment (shape only), per metre of stature."""

    pelvis: float = 0.045
    torso: float = 0.06
    thigh: float = 0.033
    shank: float = 0.024
    foot: float = 0.012
    upper_arm: float = 0.021
    forearm: float = 0.017
    hand: float = 0.013


@with_config(extra="forbid")
@dataclass(frozen=True)
class HumanParams:
    """The `human` section of params.yaml: every tunable number of the human model; units in the names."""

    anthropometry: Literal["de_leva_male", "de_leva_female"] = "de_leva_male"  # de Leva (1996) Table 4
    neutral: Literal["static_ik", "static_upright", "asis_psis"] = "static_ik"  # joint zeros (scaling)
    ankle_axis: Literal["knee", "malleoli"] = "knee"  # ankle hinge axis with static_ik
    # OpenSim foot axes (Delp et al. 1990; gait2392, Rajagopal 2015): right side, x fwd, y up, z right
    talocrural_axis: tuple[float, float, float] = (-0.10501355, -0.17402245, 0.97912632)
    subtalar_axis: tuple[float, float, float] = (0.78717961, 0.60474746, -0.12094949)
    timestep_s: float = 0.002
    knee_width_per_height: float = 0.071  # knee / ankle centre half a width medial of the lateral marker
    ankle_width_per_height: float = 0.049
    sjc_below_acromion_fraction: float = 0.17  # shoulder centre below the acromion, x acromion-elbow
    head_radius_per_height: float = 0.05
    floor_tolerance_m: float = 0.02  # foot markers may sit this far below the lab floor z = 0
    marker_bone_distance_max_m: Annotated[float, Field(gt=0.0)] = 0.17  # a marker without role or segment
    #                                                                      farther is left out
    contact_radius_m: float = 0.02
    friction: float = 1.0
    contact_solref: tuple[float, float] = (0.02, 1.0)
    joint_damping_nms_per_rad: float = 2.0
    armature_kg_m2: float = 0.01
    range_deg: RangeDeg = RangeDeg()
    torque_limit_nm_per_kg: JointValues = JointValues(lumbar=3.0, hip=3.0, knee=3.2, ankle=2.2, shoulder=1.0,
                                                      elbow=0.9)  # motor gear = this x body mass
    pd_kp_nm_per_rad: JointValues = JointValues(lumbar=2500.0, hip=2500.0, knee=2500.0, ankle=2500.0,
                                                shoulder=60.0, elbow=30.0)  # pose-holding PD
    pd_kd_nms_per_rad: JointValues = JointValues(lumbar=20.0, hip=20.0, knee=10.0, ankle=4.0, shoulder=2.0,
                                                 elbow=1.0)
    geom_radius_per_height: GeomRadius = GeomRadius()

    @property
    def widths_per_height(self) -> tuple[float, float]:
        """(knee, ankle) width / body height: a joint centre lies half a width medial of its lateral
        marker (scaling; `static: none` stands the legs on those centres)."""
        return self.knee_width_per_height, self.ankle_width_per_height

