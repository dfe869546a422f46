"""Checks of a trained walking policy against its subject (`python -m pipeline evaluate-policy`).

A policy human is accepted when it walks without falling, at the subject's speed and stride length,
with the subject's knee swing, and when SPM finds no long cluster between its hip and knee curves
and the subject's. The thresholds are params (`evaluate_policy.checks`); the functions here are
pure over the gait tables of `ingest.process`.

Every check is one `CheckRow`: the measured value, the interval it must lie in and whether it does,
from one comparison (`bounded`); `evaluate-policy`'s pass flags are the rows' `passed`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from pydantic import with_config

from metrics.spm import spm_test


@with_config(extra="forbid")
@dataclass(frozen=True)
class PolicyChecks:
    """Pass rules of `evaluate_policy.checks` in params.yaml."""

    free_no_fall_fraction: float = 0.9       # share of free walks without a fall
    robot_no_fall_fraction: float = 0.8      # share of walks with each controller without a fall
    push_recovered_fraction: float = 0.7     # share of pushed walks recovered
    max_speed_error_pct: float = 15.0        # gait speed, sim vs real kept strides
    max_stride_error_pct: float = 15.0       # stride length, sim vs real kept strides
    max_knee_peak_difference_deg: float = 10.0  # mean knee flexion peak in swing, sim - real
    swing_start_pct: float = 60.0            # swing: this share of the cycle to its end
    spm_alpha: float = 0.05
    max_spm_cluster_pct: float = 20.0        # longest supra-threshold cluster allowed (% of cycle)


@dataclass(frozen=True)
class CheckRow:
    """One check of `evaluate-policy`: its measured `value` (in `unit`), the closed interval
    [`low`, `high`] it must lie in (None: open on that side) and whether it does. `value` None: not
    measured (e.g. a walk of the scenario fell), which fails; `passed` None: measured, not judged."""

    check: str
    passed: bool | None
    value: float | None
    low: float | None
    high: float | None
    unit: str

    def as_dict(self) -> dict:
        """The row as `evaluation.json`'s `check_rows` hold it: `bound` is [low, high]."""
        return {"check": self.check, "passed": self.passed, "value": self.value,
                "bound": [self.low, self.high], "unit": self.unit}


def bounded(check: str, value: float | None, low: float | None = None, high: float | None = None,
            unit: str = "") -> CheckRow:
    """The check that `value` lies in [`low`, `high`] (None: open side); an unmeasured value (None,
    NaN) fails."""
    x = None if value is None or math.isnan(value) else float(value)
    passed = x is not None and (low is None or x >= low) and (high is None or x <= high)
    return CheckRow(check, passed, x, low, high, unit)


def share_row(check: str, n_ok: int, n: int, fraction: float, unit: str = "share of walks") -> CheckRow:
    """At least `fraction` of `n` runs were ok (9 of 10 for 0.9): value `n_ok / n` (None without
    runs), bound [`fraction`, 1]."""
    return bounded(check, n_ok / n if n else None, fraction, 1.0, unit)


def furthest(values: list[float | None], low: float | None, high: float | None) -> float | None:
    """The value furthest outside [`low`, `high`] (None: open side), or when all lie inside the one
    nearest a bound: all lie inside exactly when it does (one value for a check over several walks).
    None when any is None (a walk that never got there) or there is none."""
    if not values or any(v is None for v in values):
        return None
    return max(values, key=lambda v: max(-math.inf if low is None else low - v,
                                         -math.inf if high is None else v - high))


def swing_knee_peaks(cycles: pd.DataFrame, swing_start_pct: float = 60.0) -> np.ndarray:
    """Knee flexion maximum (deg) in swing (`swing_start_pct`-100 % of the cycle) of each cycle."""
    k = cycles[(cycles["joint"] == "knee_flexion") & (cycles["pct"] >= swing_start_pct)]
    return k.groupby(["trial", "side", "stride"])["angle_deg"].max().to_numpy()


def curves(cycles: pd.DataFrame, joint: str,
           per: tuple[str, ...] = ("trial", "side", "stride")) -> np.ndarray:
    """(n, n_points) of one joint, sides pooled: one curve per cycle, or with `per=("trial",)` one
    mean curve per trial (a simulated rollout)."""
    c = cycles[cycles["joint"] == joint] if len(cycles) else cycles
    if c.empty:
        return np.zeros((0, 0))
    return c.pivot_table(index=list(per), columns="pct", values="angle_deg").to_numpy()


def relative_error_pct(sim: float, real: float) -> float:
    return 100 * (sim / real - 1)


def spm_row(check: str, result: dict, p: PolicyChecks = PolicyChecks()) -> CheckRow:
    """The check of an `spm_check` result: its longest cluster (% of cycle; None when the test was
    skipped) at most `max_spm_cluster_pct`; not judged (passed None) when `result` says so."""
    longest = None if result.get("skipped") else result.get("longest_cluster_pct")
    row = bounded(check, longest, None, p.max_spm_cluster_pct, "% of cycle")
    return CheckRow(check, None, row.value, row.low, row.high, row.unit) if "not_judged" in result else row


def spm_check(a: np.ndarray, b: np.ndarray, p: PolicyChecks = PolicyChecks(), min_a: int = 2) -> dict:
    """SPM anova1 of curves `a` vs `b`: clusters (% of cycle), the longest, pass (`spm_row`). With
    fewer than `min_a` curves in `a` the test is still run and reported but not judged (pass None):
    the mean of so few real cycles is not a reference to hold a simulation to."""
    if not (a.size and b.size) or a.shape[1] != b.shape[1]:
        out: dict = {"n_a": int(len(a)), "n_b": int(len(b)), "skipped": "no curves"}
        return out | {"pass": spm_row("spm", out, p).passed}
    res = spm_test(a, b, "anova1", p.spm_alpha, 2)
    spans = [(round(c.start_pct, 1), round(c.end_pct, 1)) for c in res.clusters]
    longest = round(float(max((e - s for s, e in spans), default=0.0)), 1)
    diff = np.abs(a.mean(0) - b.mean(0))
    out = {"n_a": int(len(a)), "n_b": int(len(b)), "clusters_pct": spans, "longest_cluster_pct": longest,
           "skipped": res.skipped, "mean_abs_difference_deg": round(float(diff.mean()), 2),
           "max_abs_difference_deg": round(float(diff.max()), 2)}
    if len(a) < min_a:
        out["not_judged"] = f"{len(a)} real cycles < {min_a}"
    out["pass"] = spm_row("spm", out, p).passed
    return out


def gait_check(real_kept: pd.DataFrame, sim_kept: pd.DataFrame, real_cycles: pd.DataFrame,
               sim_cycles: pd.DataFrame, p: PolicyChecks = PolicyChecks()) -> tuple[dict, list[CheckRow]]:
    """Gait speed, stride length (kept strides) and knee swing peak of the policy's free walking vs
    the subject's: the report (with `pass_*` flags) and the checks `free_speed`, `free_stride_length`
    (relative error, %), `free_knee_peak` (sim - real, deg)."""
    real_v, real_l = float(real_kept["gait_speed_mps"].mean()), float(real_kept["stride_length_m"].mean())
    sim_v = float(sim_kept["gait_speed_mps"].mean()) if len(sim_kept) else float("nan")
    sim_l = float(sim_kept["stride_length_m"].mean()) if len(sim_kept) else float("nan")
    real_knee = swing_knee_peaks(real_cycles, p.swing_start_pct)
    sim_knee = swing_knee_peaks(sim_cycles, p.swing_start_pct) if len(sim_cycles) else np.array([])
    knee_diff = float(np.mean(sim_knee) - np.mean(real_knee)) if len(sim_knee) else float("nan")
    v_err, l_err = relative_error_pct(sim_v, real_v), relative_error_pct(sim_l, real_l)
    v_tol, l_tol = p.max_speed_error_pct, p.max_stride_error_pct
    rows = [bounded("free_speed", round(v_err, 2), -v_tol, v_tol, "%"),
            bounded("free_stride_length", round(l_err, 2), -l_tol, l_tol, "%"),
            bounded("free_knee_peak", knee_diff, -p.max_knee_peak_difference_deg,
                    p.max_knee_peak_difference_deg, "deg")]
    return {
        "kept_strides_sim": int(len(sim_kept)), "kept_strides_real": int(len(real_kept)),
        "gait_speed_mps": {"real": round(real_v, 3), "sim": round(sim_v, 3), "error_pct": round(v_err, 2)},
        "stride_length_m": {"real": round(real_l, 3), "sim": round(sim_l, 3), "error_pct": round(l_err, 2)},
        "knee_swing_peak_deg": {"real": round(float(np.mean(real_knee)), 2),
                                "sim": round(float(np.mean(sim_knee)), 2) if len(sim_knee) else None,
                                "difference": round(knee_diff, 2)},
        "pass_speed": rows[0].passed, "pass_stride_length": rows[1].passed, "pass_knee_peak": rows[2].passed,
    }, rows
