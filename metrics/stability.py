"""Stability (paper Table III): inter-cycle variability of the sagittal joint angles.

For each joint the SD across cycles is taken at each of the 101 points of the normalised cycle
(ddof 1) and then averaged over the cycle (degrees), as in Wang, Chan et al. (ICRA 2025), Table
III. Lower means more repeatable gait. With `pool_sides` the left and right cycles are pooled
(side 'both'); otherwise each side is reported on its own. Fewer than 2 cycles give NaN with the
reason in `note`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.curves import curve_groups
from metrics.groups import JOINTS
from metrics.table import GROUP_COLUMNS, MetricTable

SCHEMA = {**GROUP_COLUMNS, "side": "VARCHAR", "joint": "VARCHAR", "n_cycles": "BIGINT",
          "intercycle_sd_deg": "DOUBLE", "note": "VARCHAR"}
COLUMNS = list(SCHEMA)


def intercycle_sd(curves: np.ndarray) -> float:
    """Mean over the cycle of the across-cycle SD; `curves` is (n_cycles, n_points)."""
    curves = np.asarray(curves, float)
    if curves.ndim != 2 or curves.shape[0] < 2:
        return float("nan")
    return float(curves.std(axis=0, ddof=1).mean())


def stability_table(cycles: pd.DataFrame, pool_sides: bool = True,
                    joints: tuple[str, ...] = JOINTS) -> pd.DataFrame:
    """One row per group, side and joint in `joints`."""
    rows = []
    for key, m in curve_groups(cycles, pool_sides).items():
        if key[-1] not in joints:
            continue
        n = len(m)
        note = "" if n >= 2 else f"only {n} cycle(s): SD needs at least 2"
        rows.append((*key, n, intercycle_sd(m.to_numpy(float)), note))
    return pd.DataFrame(rows, columns=COLUMNS)


TABLE = MetricTable("stability", SCHEMA,
                    lambda inputs, p: stability_table(inputs.cycles, p.pool_sides, p.joints),
                    title="Table III: inter-cycle SD of the sagittal joint angles, averaged over the cycle "
                          "(n cycles)")
