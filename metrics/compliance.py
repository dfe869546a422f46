"""Compliance (paper Table I): how closely the robot keeps the pelvis at the arm's neutral point.

Wang, Chan et al. (ICRA 2025) report the mean absolute forward and lateral offset, |e_x| and
|e_y|, in centimetres, per follow-me controller. Here the mean runs over every sample of every
trial of a condition while the robot follows: samples after a fall locked the arm are left out
(`exclude_locked`), since the controller is no longer following then.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.groups import GROUP, with_identity
from metrics.table import GROUP_COLUMNS, MetricTable

# the columns used here, of the robot table a rollout writes (ingest.robot.ROBOT_COLUMNS)
NEEDED_ROBOT_COLUMNS = ("trial", "time_s", "e_x_m", "e_y_m", "fall", "locked")
SCHEMA = {**GROUP_COLUMNS, "n_trials": "BIGINT", "n_samples": "BIGINT", "mean_abs_ex_cm": "DOUBLE",
          "sd_abs_ex_cm": "DOUBLE", "mean_abs_ey_cm": "DOUBLE", "sd_abs_ey_cm": "DOUBLE",
          "max_abs_ex_cm": "DOUBLE", "max_abs_ey_cm": "DOUBLE", "fall_rate": "DOUBLE"}
COLUMNS = list(SCHEMA)


FORCE = ["harness_fx_n", "harness_fy_n", "harness_fz_n"]


def following(robot: pd.DataFrame, exclude_locked: bool = True) -> pd.DataFrame:
    """Rows of a robot table where the robot is following (not locked after a fall)."""
    return robot[~robot["locked"].astype(bool)] if exclude_locked else robot


def run_means(f: pd.DataFrame) -> tuple[float, float, float]:
    """Mean |e_x|, |e_y| (cm) and harness |f| RMS (N) of one run's following samples `f` (NaN
    without any): what a run contributes per phase (`metrics.phases`) or as a sweep row
    (`metrics.outcomes`)."""
    if not len(f):
        return np.nan, np.nan, np.nan
    force = np.linalg.norm(f[FORCE].to_numpy(float), axis=1)
    return (float(np.abs(f["e_x_m"]).mean() * 100), float(np.abs(f["e_y_m"]).mean() * 100),
            float(np.sqrt(np.mean(force ** 2))))


def compliance_table(robot: pd.DataFrame, exclude_locked: bool = True) -> pd.DataFrame:
    """One row per subject/source/human_mode/condition: mean and SD of |e_x|, |e_y| (cm) over the
    following samples, their maxima, and the share of trials (trial, seed) with a fall."""
    robot = with_identity(robot, "robot table", NEEDED_ROBOT_COLUMNS)
    rows = []
    for key, g in robot.groupby(GROUP, sort=True):
        runs = g.groupby(["trial", "seed"])["fall"].any()
        f = following(g, exclude_locked)
        ex, ey = np.abs(f["e_x_m"].to_numpy(float)) * 100, np.abs(f["e_y_m"].to_numpy(float)) * 100
        rows.append((*key, len(runs), len(f), *_stats(ex), *_stats(ey),
                     float(ex.max()) if len(ex) else np.nan, float(ey.max()) if len(ey) else np.nan,
                     float(runs.mean())))
    out = pd.DataFrame(rows, columns=[*GROUP, "n_trials", "n_samples", "mean_abs_ex_cm", "sd_abs_ex_cm",
                                      "mean_abs_ey_cm", "sd_abs_ey_cm", "max_abs_ex_cm", "max_abs_ey_cm",
                                      "fall_rate"])
    return out[COLUMNS]


def _stats(x: np.ndarray) -> tuple[float, float]:
    if len(x) == 0:
        return np.nan, np.nan
    return float(x.mean()), float(x.std(ddof=1)) if len(x) > 1 else np.nan


TABLE = MetricTable("compliance", SCHEMA, lambda inputs, p: compliance_table(inputs.robot, p.exclude_locked)
                    if inputs.has_robot else pd.DataFrame(columns=COLUMNS),
                    title="Table I: compliance, mean absolute offset of the pelvis from the arm's neutral "
                          "point (mean ± SD over samples)")
