"""Transparency: harness (pHRI) force and torque per condition, RMS and peak.

A transparent follow-me controller moves the robot so the harness spring barely loads; the
interaction wrench is therefore measured directly: RMS and peak absolute value of each component
and of the force and torque magnitudes, over the following samples (see `metrics.compliance`).
A real robot-assisted trial has them only when its robot logged a load cell; a quantity that was not
measured (all NaN) gets no row.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.compliance import following
from metrics.groups import GROUP, with_identity
from metrics.table import GROUP_COLUMNS, MetricTable

COMPONENTS = {
    "fx": ("harness_fx_n", "N"), "fy": ("harness_fy_n", "N"), "fz": ("harness_fz_n", "N"),
    "tx": ("harness_tx_nm", "N m"), "ty": ("harness_ty_nm", "N m"), "tz": ("harness_tz_nm", "N m"),
}
SCHEMA = {**GROUP_COLUMNS, "quantity": "VARCHAR", "unit": "VARCHAR", "n_samples": "BIGINT", "rms": "DOUBLE",
          "peak": "DOUBLE", "mean": "DOUBLE"}
COLUMNS = list(SCHEMA)


def harness_table(robot: pd.DataFrame, exclude_locked: bool = True) -> pd.DataFrame:
    """Rows per group and quantity (fx..tz, |f|, |t|): RMS, peak |value| and mean of the wrench."""
    robot = with_identity(robot, "robot table", tuple(c for c, _ in COMPONENTS.values()) + ("locked",))
    rows = []
    for key, g in robot.groupby(GROUP, sort=True):
        f = following(g, exclude_locked)
        series = {q: (f[c].to_numpy(float), unit) for q, (c, unit) in COMPONENTS.items()}
        for name, parts, unit in (("f_norm", ("fx", "fy", "fz"), "N"), ("t_norm", ("tx", "ty", "tz"), "N m")):
            series[name] = (np.linalg.norm(np.stack([series[q][0] for q in parts]), axis=0), unit)
        for q, (x, unit) in series.items():
            if len(x) and not np.isfinite(x).any():
                continue  # not measured: a real robot without a load cell logs no wrench
            x = x[np.isfinite(x)]
            if len(x) == 0:
                rows.append((*key, q, unit, 0, np.nan, np.nan, np.nan))
                continue
            rows.append((*key, q, unit, len(x), float(np.sqrt(np.mean(x**2))), float(np.max(np.abs(x))),
                         float(np.mean(x))))
    return pd.DataFrame(rows, columns=COLUMNS)


TABLE = MetricTable("harness", SCHEMA, lambda inputs, p: harness_table(inputs.robot, p.exclude_locked)
                    if inputs.has_robot else pd.DataFrame(columns=COLUMNS))
