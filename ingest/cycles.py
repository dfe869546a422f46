"""Gait cycles: each kept stride's joint angles resampled to `n_points` (0-100 % of the cycle).

Joints: hip flexion, knee flexion, ankle dorsiflexion of the stride's side and pelvis anterior
tilt (degrees, canonical signs). Linear interpolation in time between the two heel strikes.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

CYCLE_JOINTS = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion", "pelvis_tilt")
CYCLE_COLUMNS = ["side", "stride", "pct", "joint", "angle_deg"]


def angle_name(joint: str, side: str) -> str:
    return joint if joint == "pelvis_tilt" else f"{joint}_{side}"


def normalise_cycles(strides: pd.DataFrame, time_s: np.ndarray, angles: dict[str, np.ndarray],
                     n_points: int = 101) -> pd.DataFrame:
    """Long table (side, stride, pct, joint, angle_deg) of the kept strides."""
    pct = np.linspace(0.0, 100.0, n_points)
    frames = []
    for row in strides[strides["kept"]].itertuples(index=False):
        t = np.linspace(row.t_start_s, row.t_end_s, n_points)
        for joint in CYCLE_JOINTS:
            values = angles.get(angle_name(joint, row.side))
            if values is None:
                continue
            frames.append(pd.DataFrame({
                "side": row.side, "stride": row.stride, "pct": pct, "joint": joint,
                "angle_deg": np.interp(t, time_s, values),
            }))
    if not frames:
        return pd.DataFrame(columns=CYCLE_COLUMNS)
    return pd.concat(frames, ignore_index=True)
