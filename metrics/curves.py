"""Gait cycles as curves: one row per cycle, one column per % of the cycle, and their mean ± SD.

The cycles table is long (one row per cycle, joint and point); the metrics and SPM want matrices
(n_cycles x n_points). `pool_sides` treats a left and a right cycle as two observations of the
same joint; otherwise each side is its own group (`side` column 'left'/'right', 'both' if pooled).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.groups import CYCLE, GROUP, independent_rows, with_identity
from metrics.table import GROUP_COLUMNS, MetricTable

CYCLE_COLUMNS = ("trial", "side", "stride", "pct", "joint", "angle_deg")
BOTH = "both"
BAND_SCHEMA = {**GROUP_COLUMNS, "side": "VARCHAR", "joint": "VARCHAR", "pct": "DOUBLE", "n_cycles": "BIGINT",
               "mean_deg": "DOUBLE", "sd_deg": "DOUBLE"}
BAND_COLUMNS = list(BAND_SCHEMA)


def tidy_cycles(cycles: pd.DataFrame) -> pd.DataFrame:
    """Checked cycles table with `human_mode` and `seed` filled in, independent cycles only (a
    replayed human's other seeds repeat its recorded strides: `metrics.groups.independent_rows`)."""
    return independent_rows(with_identity(cycles, "cycles table", CYCLE_COLUMNS))


def curve_groups(cycles: pd.DataFrame, pool_sides: bool) -> dict[tuple, pd.DataFrame]:
    """Cycles split by (subject, source, human_mode, condition, side, joint); side is 'both' when
    pooling. Each value is a matrix DataFrame: index = cycle (trial, seed, side, stride), columns =
    pct, rows with any missing point dropped."""
    cycles = tidy_cycles(cycles)
    if pool_sides:
        cycles = cycles.assign(side_group=BOTH)
    else:
        cycles = cycles.assign(side_group=cycles["side"])
    out = {}
    for key, g in cycles.groupby([*GROUP, "side_group", "joint"], sort=True):
        out[key] = g.pivot_table(index=CYCLE, columns="pct", values="angle_deg", aggfunc="first").dropna()
    return out


def bands_table(cycles: pd.DataFrame, pool_sides: bool = True) -> pd.DataFrame:
    """Mean and SD (ddof 1) across cycles at each % point: the kinematics figure's bands."""
    frames = []
    for key, m in curve_groups(cycles, pool_sides).items():
        if m.empty:
            continue
        y = m.to_numpy(float)
        sd = y.std(axis=0, ddof=1) if len(y) > 1 else np.full(y.shape[1], np.nan)
        frame = pd.DataFrame({"pct": m.columns.to_numpy(float), "n_cycles": len(y),
                              "mean_deg": y.mean(axis=0), "sd_deg": sd})
        for col, value in zip([*GROUP, "side", "joint"], key, strict=True):
            frame[col] = value
        frames.append(frame[BAND_COLUMNS])
    if not frames:
        return pd.DataFrame(columns=BAND_COLUMNS)
    return pd.concat(frames, ignore_index=True)


# the kinematics figure's bands
TABLE = MetricTable("kinematics", BAND_SCHEMA, lambda inputs, p: bands_table(inputs.cycles, p.pool_sides))
