"""Anthropometric tables: segment mass fractions, centre-of-mass positions and radii of gyration
(de Leva 1996), and stature ratios for landmarks a marker set does not have (de Leva 1996 segment
lengths; Drillis & Contini 1966 as drawn in Winter 2009, Fig. 4.1).

de Leva P. (1996) Adjustments to Zatsiorsky-Seluyanov's segment inertia parameters.
J Biomech 29(9):1223-1230, Table 4 (mass, CoM, radii) and Tables 1-2 (segment lengths, stature
1741 mm male, 1735 mm female). CoM is a fraction of the segment length from its proximal end point
(head: from the vertex; trunk parts: from the upper end point). Radii of gyration are fractions of
the segment length about the sagittal (antero-posterior, x), transverse (medio-lateral, y) and
longitudinal (z) axes through the segment's CoM.
Winter D.A. (2009) Biomechanics and Motor Control of Human Movement, 4th ed., Fig. 4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Segment:
    """One de Leva segment: mass fraction of body mass, CoM fraction of length from the proximal
    end point, radii of gyration (x, y, z) as fractions of length, length in mm at the table's
    reference stature."""

    mass_fraction: float
    com_fraction: float
    gyration: tuple[float, float, float]
    length_mm: float


@dataclass(frozen=True)
class Table:
    stature_mm: float
    segments: dict[str, Segment]

    def length_ratio(self, name: str) -> float:
        """Segment length as a fraction of stature."""
        return self.segments[name].length_mm / self.stature_mm


# de Leva (1996) Table 4. Head: VERT-CERV; upper trunk CERV-XYPH; mid trunk XYPH-OMPH; lower trunk
# OMPH-MIDH; upper arm SJC-EJC; forearm EJC-WJC; hand WJC-MET3; thigh HJC-KJC; shank KJC-LMAL
# (ankle joint centre here); foot HEEL-TTIP.
DE_LEVA_MALE = Table(1741.0, {
    "head": Segment(0.0694, 0.5002, (0.303, 0.315, 0.261), 242.9),
    "upper_trunk": Segment(0.1596, 0.5066, (0.505, 0.320, 0.465), 242.1),
    "mid_trunk": Segment(0.1633, 0.4502, (0.482, 0.383, 0.468), 215.5),
    "lower_trunk": Segment(0.1117, 0.6115, (0.615, 0.551, 0.587), 145.7),
    "upper_arm": Segment(0.0271, 0.5772, (0.285, 0.269, 0.158), 281.7),
    "forearm": Segment(0.0162, 0.4574, (0.276, 0.265, 0.121), 268.9),
    "hand": Segment(0.0061, 0.7900, (0.628, 0.513, 0.401), 86.2),
    "thigh": Segment(0.1416, 0.4095, (0.329, 0.329, 0.149), 422.2),
    "shank": Segment(0.0433, 0.4459, (0.255, 0.249, 0.103), 434.0),
    "foot": Segment(0.0137, 0.4415, (0.257, 0.245, 0.124), 258.1),
})
DE_LEVA_FEMALE = Table(1735.0, {
    "head": Segment(0.0668, 0.4841, (0.271, 0.295, 0.261), 243.7),
    "upper_trunk": Segment(0.1545, 0.5050, (0.466, 0.314, 0.449), 228.0),
    "mid_trunk": Segment(0.1465, 0.4512, (0.433, 0.354, 0.415), 205.3),
    "lower_trunk": Segment(0.1247, 0.4920, (0.433, 0.402, 0.444), 181.5),
    "upper_arm": Segment(0.0255, 0.5754, (0.278, 0.260, 0.148), 275.1),
    "forearm": Segment(0.0138, 0.4559, (0.261, 0.257, 0.094), 264.3),
    "hand": Segment(0.0056, 0.7474, (0.531, 0.454, 0.335), 78.0),
    "thigh": Segment(0.1478, 0.3612, (0.369, 0.364, 0.162), 368.5),
    "shank": Segment(0.0481, 0.4416, (0.271, 0.267, 0.093), 432.3),
    "foot": Segment(0.0129, 0.4014, (0.299, 0.279, 0.139), 228.3),
})
TABLES = {"de_leva_male": DE_LEVA_MALE, "de_leva_female": DE_LEVA_FEMALE}

# Drillis & Contini (1966) via Winter (2009) Fig. 4.1, fractions of stature H.
WINTER_RATIOS = {
    "shoulder_height": 0.818,   # acromion above the floor
    "shoulder_width": 0.259,    # between the shoulders
    "hip_width": 0.191,
    "foot_width": 0.055,
    "ankle_height": 0.039,
}

SEGMENTS_PER_SIDE = ("upper_arm", "forearm", "hand", "thigh", "shank", "foot")


def total_mass_fraction(table: Table) -> float:
    """Sum of the table's mass fractions with both sides counted (1.0 for de Leva)."""
    return sum(s.mass_fraction * (2 if n in SEGMENTS_PER_SIDE else 1) for n, s in table.segments.items())


@dataclass(frozen=True)
class Inertial:
    """Mass (kg), CoM (m) and inertia tensor (kg m^2, about the CoM) of a rigid part in some frame."""

    mass_kg: float
    com_m: np.ndarray
    inertia: np.ndarray


def segment_inertial(seg: Segment, body_mass_kg: float, proximal: np.ndarray, distal: np.ndarray,
                     frame: np.ndarray) -> Inertial:
    """Inertial of a segment running from `proximal` to `distal` (points in some body frame);
    `frame` is a 3x3 whose columns are the segment's x (AP), y (ML), z (long) axes in that body
    frame. The principal axes are the segment's; the tensor is returned in the body frame."""
    length = float(np.linalg.norm(distal - proximal))
    mass = seg.mass_fraction * body_mass_kg
    com = proximal + seg.com_fraction * (distal - proximal)
    principal = np.diag([mass * (r * length) ** 2 for r in seg.gyration])
    return Inertial(mass, com, frame @ principal @ frame.T)


def combine(parts: list[Inertial]) -> Inertial:
    """One rigid body from parts (parallel-axis theorem)."""
    mass = sum(p.mass_kg for p in parts)
    com = sum(p.mass_kg * p.com_m for p in parts) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com_m - com
        inertia += p.inertia + p.mass_kg * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return Inertial(mass, com, inertia)
