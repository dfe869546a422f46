"""Tracking traces for the report: one run per condition, resampled to a plotting rate.

The compliance table summarises every sample; the tracking figure shows how the offsets and the
harness force evolve over one run (the first trial and seed of each condition), sampled at
`rate_hz` by taking the nearest recorded sample (no smoothing: what is drawn was recorded).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.groups import GROUP, with_identity
from metrics.table import GROUP_COLUMNS, MetricTable

SCHEMA = {**GROUP_COLUMNS, "trial": "VARCHAR", "seed": "BIGINT", "time_s": "DOUBLE", "e_x_cm": "DOUBLE",
          "e_y_cm": "DOUBLE", "force_n": "DOUBLE", "locked": "BOOLEAN"}
TRACKING_COLUMNS = list(SCHEMA)


def tracking_table(robot: pd.DataFrame, rate_hz: float = 20.0) -> pd.DataFrame:
    """Per group, the first (trial, seed) run at about `rate_hz`: offsets in cm and |F| in N."""
    robot = with_identity(robot, "robot table", ("trial", "time_s", "e_x_m", "e_y_m", "harness_fx_n",
                                                  "harness_fy_n", "harness_fz_n", "locked"))
    frames = []
    for key, g in robot.groupby(GROUP, sort=True):
        trial, seed = min(zip(g["trial"].astype(str), g["seed"], strict=True))
        run = g[(g["trial"].astype(str) == trial) & (g["seed"] == seed)].sort_values("time_s")
        t = run["time_s"].to_numpy(float)
        grid = np.arange(t[0], t[-1] + 1e-9, 1.0 / rate_hz)
        idx = np.clip(np.searchsorted(t, grid), 1, max(len(t) - 1, 1))
        idx = np.where(np.abs(t[idx - 1] - grid) <= np.abs(t[np.minimum(idx, len(t) - 1)] - grid), idx - 1,
                       np.minimum(idx, len(t) - 1))
        r = run.iloc[idx]
        force = np.linalg.norm(r[["harness_fx_n", "harness_fy_n", "harness_fz_n"]].to_numpy(float), axis=1)
        frame = pd.DataFrame({"trial": trial, "seed": int(seed), "time_s": r["time_s"].to_numpy(float),
                              "e_x_cm": r["e_x_m"].to_numpy(float) * 100,
                              "e_y_cm": r["e_y_m"].to_numpy(float) * 100,
                              "force_n": force, "locked": r["locked"].astype(bool).to_numpy()})
        for col, value in zip(GROUP, key, strict=True):
            frame[col] = value
        frames.append(frame[TRACKING_COLUMNS])
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=TRACKING_COLUMNS)


TABLE = MetricTable("tracking", SCHEMA, lambda inputs, p: tracking_table(inputs.robot, p.tracking_rate_hz)
                    if inputs.has_robot else pd.DataFrame(columns=TRACKING_COLUMNS))
