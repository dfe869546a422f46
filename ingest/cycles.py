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
    kept = strides["kept"].to_numpy(bool)
    # the kept strides' rows as Python values, column by column (selecting and iterating rows costs more)
    columns = (strides[c].to_numpy()[kept].tolist() for c in ("side", "stride", "t_start_s", "t_end_s"))
    cycles = []  # (side, stride, joint, angle_deg over the cycle)
    for side, stride, t0, t1 in zip(*columns, strict=True):
        t = np.linspace(t0, t1, n_points)
        for joint in CYCLE_JOINTS:
            values = angles.get(angle_name(joint, side))
            if values is not None:
                cycles.append((side, stride, joint, np.interp(t, time_s, values)))
    if not cycles:
        return pd.DataFrame({c: pd.Series(dtype=float if c in ("pct", "angle_deg") else object)
                             for c in CYCLE_COLUMNS})
    side, stride, joint, angle = zip(*cycles, strict=True)
    return pd.DataFrame({"side": np.repeat(np.array(side, dtype=object), n_points),
                         "stride": np.repeat(np.array(stride), n_points),
                         "pct": np.tile(pct, len(cycles)),
                         "joint": np.repeat(np.array(joint, dtype=object), n_points),
                         "angle_deg": np.concatenate(angle)})
