"""Which simulated cycles enter the paper's tables: sampled like the paper.

Wang, Chan et al. (ICRA 2025) walk 10 m from standing, several walks per condition, and analyse a
fixed number of complete gait cycles from each walk. `paper_strides` keeps, per walk (trial, seed)
and side, the `cycles_per_walk` kept strides nearest the middle of the walk's steady phase (start
and stop transitions left out), so every condition contributes the same number of cycles from the
same part of the walk.

A deterministic human repeats itself: the policy human walking free from quiet standing starts in
the same state whatever the seed (the seed sets the start phase of a walk that starts walking, and
the robot's sensor noise), so without motor noise (`rollout.policy_motor_noise`) its free walks
from standing are one walk several times. Copies would
count as independent samples in the SDs and the SPM tests; `distinct_walks` keeps each walk once
(and `metrics.quality.sim_checks` warns that the condition has fewer walks than asked).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.errors import MetricsError

WALK_KEYS = ["condition", "trial", "seed"]
# what makes two walks the same walk: every stride of it, bit for bit
WALK_SIGNATURE = ["side", "stride", "t_start_s", "t_end_s", "kept", "stride_length_m", "stride_time_s"]


def repeated_walks(strides: pd.DataFrame) -> pd.DataFrame:
    """One row per walk (condition, trial, seed) of `strides` with `repeats`: the trial of an earlier
    walk of the same condition it repeats stride for stride, or None. Walks are taken in (trial,
    seed) order."""
    rows, seen = [], {}
    signature = [c for c in WALK_SIGNATURE if c in strides.columns]
    for (condition, trial, seed), g in strides.groupby(WALK_KEYS, sort=True):
        key = (condition, tuple(g.sort_values(["side", "t_start_s"])[signature].itertuples(index=False)))
        rows.append((condition, trial, seed, seen.get(key)))
        seen.setdefault(key, trial)
    return pd.DataFrame(rows, columns=[*WALK_KEYS, "repeats"])


def distinct_walks(strides: pd.DataFrame, walks: pd.DataFrame | None = None) -> pd.DataFrame:
    """`strides` without the walks that repeat an earlier walk of their condition (module docstring);
    `walks`: their `repeated_walks`, when the caller has it already."""
    walks = repeated_walks(strides) if walks is None else walks
    copies = walks[walks["repeats"].notna()][WALK_KEYS]
    if copies.empty:
        return strides
    marked = strides.merge(copies.assign(_copy=True), on=WALK_KEYS, how="left")
    return strides[~marked["_copy"].fillna(False).to_numpy(bool)]


def paper_strides(strides: pd.DataFrame, cycles_per_walk: int, phase: str = "steady",
                  walks: pd.DataFrame | None = None) -> pd.DataFrame:
    """Rows of `strides` (with `kept`, `phase`, `t_start_s`, `t_end_s`) chosen as in the paper:
    per trial, seed and side, the `cycles_per_walk` kept strides in `phase` around its middle; a
    walk that repeats an earlier one of its condition is left out (`distinct_walks`; `walks`: the
    strides' `repeated_walks` when the caller has it already)."""
    missing = [c for c in ("condition", "trial", "seed", "side", "kept", "phase", "t_start_s", "t_end_s")
               if c not in strides.columns]
    if missing:
        raise MetricsError("strides table", f"cannot sample like the paper: missing columns {missing}")
    strides = distinct_walks(strides, walks)
    pool = strides[strides["kept"].astype(bool) & (strides["phase"] == phase)]
    chosen = []
    for _, g in pool.groupby(["condition", "trial", "seed", "side"], sort=True):
        mid = 0.5 * (g["t_start_s"].min() + g["t_end_s"].max())
        centre = 0.5 * (g["t_start_s"] + g["t_end_s"])
        order = np.argsort(np.abs(centre.to_numpy(float) - mid), kind="stable")[:cycles_per_walk]
        chosen.append(g.iloc[np.sort(order)])
    return pd.concat(chosen) if chosen else strides.iloc[0:0]


def restrict_cycles(cycles: pd.DataFrame, strides: pd.DataFrame) -> pd.DataFrame:
    """The cycles of `strides` (matched on trial, seed, side, stride)."""
    keys = ["condition", "trial", "seed", "side", "stride"]
    return cycles.merge(strides[keys].drop_duplicates(), on=keys, how="inner")



def paper_inputs(tables: dict[str, pd.DataFrame], scenario: str, cycles_per_walk: int
                 ) -> dict[str, pd.DataFrame]:
    """Policy-human tables (strides, cycles, robot with `scenario` and `phase`) reduced to what the
    paper's tables read: the walks of `scenario`; strides and cycles sampled by `paper_strides`;
    robot samples of the walk itself (quiet standing before and after left out)."""
    strides, cycles, robot = tables["strides"], tables["cycles"], tables["robot"]
    if strides.empty:
        return {"strides": strides, "cycles": cycles, "robot": robot}
    chosen = paper_strides(strides[strides["scenario"] == scenario], cycles_per_walk)
    if not robot.empty:
        robot = robot[(robot["scenario"] == scenario) & (robot["phase"] != "standing")]
    return {"strides": chosen, "cycles": restrict_cycles(cycles, chosen), "robot": robot}


__all__ = ["distinct_walks", "paper_inputs", "paper_strides", "repeated_walks", "restrict_cycles"]
