"""Range of motion: max - min of each joint angle within a gait cycle, mean ± SD over cycles."""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.curves import curve_groups
from metrics.groups import JOINTS
from metrics.table import GROUP_COLUMNS, MetricTable

SCHEMA = {**GROUP_COLUMNS, "side": "VARCHAR", "joint": "VARCHAR", "n_cycles": "BIGINT",
          "rom_deg_mean": "DOUBLE", "rom_deg_sd": "DOUBLE", "min_deg_mean": "DOUBLE",
          "max_deg_mean": "DOUBLE"}
COLUMNS = list(SCHEMA)


def cycle_rom(curves: np.ndarray) -> np.ndarray:
    """Per-cycle range of motion (deg) of an (n_cycles, n_points) matrix."""
    curves = np.asarray(curves, float)
    return curves.max(axis=1) - curves.min(axis=1)


def rom_table(cycles: pd.DataFrame, pool_sides: bool = True,
              joints: tuple[str, ...] = JOINTS) -> pd.DataFrame:
    """One row per group, side and joint; SD is NaN for a single cycle."""
    rows = []
    for key, m in curve_groups(cycles, pool_sides).items():
        if key[-1] not in joints or m.empty:
            continue
        y = m.to_numpy(float)
        rom = cycle_rom(y)
        rows.append((*key, len(y), float(rom.mean()), float(rom.std(ddof=1)) if len(rom) > 1 else np.nan,
                     float(y.min(axis=1).mean()), float(y.max(axis=1).mean())))
    return pd.DataFrame(rows, columns=COLUMNS)


TABLE = MetricTable("rom", SCHEMA, lambda inputs, p: rom_table(inputs.cycles, p.pool_sides, p.joints))
