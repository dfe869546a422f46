"""Sagittal joint angles from markers, for trials that come without joint coordinates.

Segments are projected on the vertical plane of progression (heading per frame):
thigh = hip joint centre -> knee, shank = knee -> ankle, foot = heel -> toe, pelvis =
PSIS midpoint -> ASIS midpoint. The hip joint centre is placed by the Harrington et al. (2007,
J Biomech 40:595) regression from pelvis width and depth. Angles (degrees, canonical signs):
pelvis anterior tilt = downward pitch of the pelvis axis; hip flexion = thigh angle from vertical
+ pelvis tilt; knee flexion = thigh angle - shank angle; ankle dorsiflexion = foot pitch - shank angle
pitch. Without a static calibration they carry the constant offsets of the marker placement.
"""

from __future__ import annotations

import numpy as np

SIDES_SIGN = {"left": 1.0, "right": -1.0}  # +Y is left in the canonical frame


def _pitch(vec: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Angle (deg) of `vec` above the horizontal, in the plane of `direction`."""
    fwd = np.einsum("ij,ij->i", vec[:, :2], direction)
    return np.degrees(np.arctan2(vec[:, 2], fwd))


def _from_vertical(vec: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Angle (deg) of a downward segment from the vertical, positive when its end is forward."""
    fwd = np.einsum("ij,ij->i", vec[:, :2], direction)
    return np.degrees(np.arctan2(fwd, -vec[:, 2]))


def hip_joint_centres(asis_l, asis_r, psis_l, psis_r) -> dict[str, np.ndarray]:
    """Harrington (2007) hip joint centres: in the pelvis frame (origin mid-ASIS, x anterior,
    z right, y up), x = -0.24 PD - 9.9 mm, y = -0.30 PW - 10.9 mm, z = +/-(0.33 PW + 7.3 mm)."""
    origin = (asis_l + asis_r) / 2
    mid_psis = (psis_l + psis_r) / 2
    right = asis_r - asis_l
    pw = np.linalg.norm(right, axis=1, keepdims=True)
    z = right / pw
    x = origin - mid_psis
    x -= np.sum(x * z, axis=1, keepdims=True) * z
    pd_ = np.linalg.norm(x, axis=1, keepdims=True)
    x /= pd_
    y = np.cross(z, x)
    base = origin + x * (-0.24 * pd_ - 0.0099) + y * (-0.30 * pw - 0.0109)
    lateral = z * (0.33 * pw + 0.0073)
    return {"right": base + lateral, "left": base - lateral}


def marker_angles(lm: dict[str, np.ndarray], heading_rad: np.ndarray) -> dict[str, np.ndarray]:
    """Canonical sagittal angles from landmark trajectories keyed by role (``heel_left`` ...)."""
    direction = np.column_stack([np.cos(heading_rad), np.sin(heading_rad)])
    hjc = hip_joint_centres(lm["asis_left"], lm["asis_right"], lm["psis_left"], lm["psis_right"])
    mid_asis = (lm["asis_left"] + lm["asis_right"]) / 2
    mid_psis = (lm["psis_left"] + lm["psis_right"]) / 2
    tilt = -_pitch(mid_asis - mid_psis, direction)
    angles = {"pelvis_tilt": tilt}
    for side in ("left", "right"):
        thigh = _from_vertical(lm[f"knee_{side}"] - hjc[side], direction)
        shank = _from_vertical(lm[f"ankle_{side}"] - lm[f"knee_{side}"], direction)
        foot = _pitch(lm[f"toe_{side}"] - lm[f"heel_{side}"], direction)
        angles[f"hip_flexion_{side}"] = thigh + tilt
        angles[f"knee_flexion_{side}"] = thigh - shank
        angles[f"ankle_dorsiflexion_{side}"] = foot - shank
    return angles
