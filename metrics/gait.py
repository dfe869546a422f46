"""Gait (paper Table II): stride length and gait speed, mean ± SD over the kept strides.

Only strides the ingest stage kept (steady, straight walking) count; both sides are pooled, as
each stride is one observation of the person's gait; a replayed human's seeds repeat its recorded
strides and count once (`metrics.groups.independent_rows`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.groups import GROUP, independent_rows, with_identity
from metrics.table import GROUP_COLUMNS, MetricTable

STRIDE_COLUMNS = ("kept", "stride_length_m", "gait_speed_mps", "stride_time_s", "cadence_spm")
SCHEMA = {**GROUP_COLUMNS, "n_strides": "BIGINT", "stride_length_m_mean": "DOUBLE",
          "stride_length_m_sd": "DOUBLE", "gait_speed_mps_mean": "DOUBLE", "gait_speed_mps_sd": "DOUBLE",
          "stride_time_s_mean": "DOUBLE", "cadence_spm_mean": "DOUBLE"}
COLUMNS = list(SCHEMA)


def gait_table(strides: pd.DataFrame) -> pd.DataFrame:
    """One row per subject/source/human_mode/condition with at least one kept stride; SD is the
    sample SD (ddof 1), NaN for a single stride."""
    strides = with_identity(strides, "strides table", STRIDE_COLUMNS)
    kept = independent_rows(strides[strides["kept"].astype(bool)])
    rows = []
    for key, g in kept.groupby(GROUP, sort=True):
        rows.append((*key, len(g), *_mean_sd(g["stride_length_m"]), *_mean_sd(g["gait_speed_mps"]),
                     float(g["stride_time_s"].mean()), float(g["cadence_spm"].mean())))
    return pd.DataFrame(rows, columns=COLUMNS)


def _mean_sd(x: pd.Series) -> tuple[float, float]:
    x = x.to_numpy(float)
    return float(x.mean()), float(x.std(ddof=1)) if len(x) > 1 else np.nan


TABLE = MetricTable("gait", SCHEMA, lambda inputs, p: gait_table(inputs.strides),
                    title="Table II: stride length and gait speed (mean ± SD over kept strides, n strides)")
