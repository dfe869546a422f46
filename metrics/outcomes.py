"""One rollout's headline numbers, and the objective a controller is tuned and compared by.

A sweep stores one row per rollout job (`run_row`): how closely the robot followed (mean |e_x|,
|e_y| over the following samples, as Table I), how hard the harness pulled (|f| RMS), whether the
human fell, and how it walked (mean speed and stride length of its kept strides). `objective`
scores a controller on such rows against the same person walking free, with one procedure for
every controller (the issue's "same budget and procedure"): the cost of Wang, Chan et al. (ICRA
2025) Table I (|e_x| + |e_y|), plus the harness force (transparency), plus the gait change versus
walking free (the paper's Tables II-III question), plus a penalty per fall. `compliance_headline` is a
simulation run's headline per condition: Table I (`metrics.compliance`) and the harness |f| RMS
(`metrics.harness`) together, so it lives above both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from metrics.compliance import compliance_table, following, run_means
from metrics.groups import GROUP
from metrics.harness import harness_table

ROW_COLUMNS = ["mean_abs_ex_cm", "mean_abs_ey_cm", "force_rms_n", "fell", "gait_speed_mps", "stride_length_m",
               "n_strides", "n_samples"]


def walk_window(spans: list[tuple[str, float, float]]) -> tuple[float, float]:
    """(start, end) s of a scenario's walk itself, from its commanded phase spans
    (`sim.rollout.scenarios.CommandProfile.spans`): after the quiet standing it starts with and before
    the one it ends with, as Table I's compliance is taken (`metrics.sampling`); open where it
    neither starts nor ends standing."""
    start = spans[0][2] if spans and spans[0][0] == "standing" else -np.inf
    end = spans[-1][1] if len(spans) > 1 and spans[-1][0] == "standing" else np.inf
    return float(start), float(end)


def run_row(robot: pd.DataFrame, strides: pd.DataFrame, fell: bool, exclude_locked: bool = True,
            window_s: tuple[float, float] = (-np.inf, np.inf)) -> dict:
    """Headline numbers of one rollout: its robot table (empty when walking free) and strides, both
    within `window_s` (robot samples by time, strides by their end; default: all)."""
    lo, hi = window_s
    if not robot.empty:
        robot = robot[(robot["time_s"] >= lo) & (robot["time_s"] <= hi)]
    if not strides.empty:
        strides = strides[(strides["t_start_s"] >= lo) & (strides["t_end_s"] <= hi)]
    kept = strides[strides["kept"].astype(bool)] if not strides.empty else strides
    out = {"mean_abs_ex_cm": np.nan, "mean_abs_ey_cm": np.nan, "force_rms_n": np.nan, "fell": bool(fell),
           "gait_speed_mps": float(kept["gait_speed_mps"].mean()) if len(kept) else np.nan,
           "stride_length_m": float(kept["stride_length_m"].mean()) if len(kept) else np.nan,
           "n_strides": int(len(kept)), "n_samples": 0}
    if not robot.empty:
        f = following(robot, exclude_locked)
        ex, ey, force = run_means(f)
        out.update(mean_abs_ex_cm=ex, mean_abs_ey_cm=ey, force_rms_n=force, n_samples=len(f))
    return out


@dataclass(frozen=True)
class ObjectiveWeights:
    """Weights of the controller objective (params `tune`), in metres of tracking error."""

    force_weight_m_per_n: float = 0.001   # 10 N harness force RMS costs as much as 1 cm of mean |e|
    gait_weight_m: float = 0.05           # a 100 % change of gait speed versus free walking costs 5 cm
    fall_penalty_m: float = 0.5           # a fall costs 50 cm


def costs(rows: pd.DataFrame, free_speed_mps: float, w: ObjectiveWeights = ObjectiveWeights()) -> np.ndarray:
    """Per rollout: |e_x| + |e_y| (m) + w_f |f|_rms + w_g |speed / free speed - 1|, or the fall penalty
    for a rollout that fell (or has no following samples or kept strides). A fall costs the same
    whenever it happens: its partial terms are left out, so a controller cannot lower its cost by
    making the human fall before the costly part of a walk."""
    ex, ey = rows["mean_abs_ex_cm"].to_numpy(float) / 100, rows["mean_abs_ey_cm"].to_numpy(float) / 100
    force = rows["force_rms_n"].to_numpy(float)
    gait = np.abs(rows["gait_speed_mps"].to_numpy(float) / free_speed_mps - 1.0)
    terms = ex + ey + w.force_weight_m_per_n * force + w.gait_weight_m * gait
    fell = rows["fell"].to_numpy(bool) | ~np.isfinite(terms)
    return np.where(fell, w.fall_penalty_m, np.nan_to_num(terms))


def objective(rows: pd.DataFrame, free_speed_mps: float, w: ObjectiveWeights = ObjectiveWeights()) -> float:
    """Mean of `costs` over the rollouts."""
    return float(costs(rows, free_speed_mps, w).mean())


def compliance_headline(robot: pd.DataFrame, exclude_locked: bool = True) -> dict[str, dict]:
    """Per condition, the numbers a simulation run reports first: mean |e_x|, |e_y| (cm) and
    harness force RMS (N) over the following samples, and the number of runs with a fall. The same
    computation as Table I (`compliance_table`) and the harness table (`harness_table`, |f|)."""
    if robot.empty:
        return {}
    comp = compliance_table(robot, exclude_locked)
    harness = harness_table(robot, exclude_locked)
    force = harness[harness["quantity"] == "f_norm"].set_index(GROUP)["rms"]
    out = {}
    for row in comp.itertuples(index=False):
        rms = float(force[tuple(getattr(row, g) for g in GROUP)])
        out[str(row.condition)] = {"mean_abs_e_x_cm": round(float(row.mean_abs_ex_cm), 3),
                                   "mean_abs_e_y_cm": round(float(row.mean_abs_ey_cm), 3),
                                   "harness_force_rms_n": round(rms, 3),
                                   "falls": int(round(row.fall_rate * row.n_trials))}
    return out


__all__ = ["ROW_COLUMNS", "ObjectiveWeights", "compliance_headline", "costs", "objective", "run_row",
           "walk_window"]
