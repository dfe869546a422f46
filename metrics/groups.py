"""Identity of a result row: which subject, source, human mode and condition it describes.

Every metric groups its input by `GROUP` = subject, source, human_mode, condition. Real tables
carry no `human_mode` (the person walked; nothing drove them), so it reads `none` there; simulated
tables say `replay` or `policy`. A cycle is identified by `CYCLE` = trial, seed, side, stride;
real tables have no `seed` and get 0. The seeds of a replayed human replay the same recorded strides
(the same joint angles), so only one seed of them is an observation (`independent_rows`): counted
once each, a subject with one kept stride is one stride, not three.
"""

from __future__ import annotations

import pandas as pd

from metrics.errors import MetricsError

GROUP = ["subject", "source", "human_mode", "condition"]
CYCLE = ["trial", "seed", "side", "stride"]
REAL_HUMAN_MODE = "none"
REPLAY_HUMAN_MODE = "replay"
JOINTS = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")


def with_identity(table: pd.DataFrame, name: str, required: tuple[str, ...] = ()) -> pd.DataFrame:
    """`table` with `human_mode` and `seed` filled in where absent (real data), after checking that
    it has the identity columns and `required`; raises `MetricsError` naming `name` otherwise."""
    missing = [c for c in ("subject", "source", "condition", *required) if c not in table.columns]
    if missing:
        raise MetricsError(name, f"missing columns {missing} (has {list(table.columns)})")
    out = table.copy()
    if "human_mode" not in out.columns:
        out["human_mode"] = REAL_HUMAN_MODE
    out["human_mode"] = out["human_mode"].fillna(REAL_HUMAN_MODE).astype(str)
    if "seed" not in out.columns:
        out["seed"] = 0
    out["seed"] = out["seed"].fillna(0).astype("int64")
    for col in ("subject", "source", "condition"):
        out[col] = out[col].astype(str)
    return out


def independent_rows(table: pd.DataFrame) -> pd.DataFrame:
    """The rows that are independent observations (module docstring): every row of real data and of
    the policy human (each seed is its own walk), the lowest seed of each replayed stride (trial,
    side, stride)."""
    if "human_mode" not in table.columns or not (table["human_mode"] == REPLAY_HUMAN_MODE).any():
        return table
    first = table.groupby([*GROUP, "trial", "side", "stride"], sort=False)["seed"].transform("min")
    return table[(table["human_mode"] != REPLAY_HUMAN_MODE) | (table["seed"] == first)]
