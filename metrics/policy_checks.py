"""Checks of a trained walking policy against its subject (`python -m pipeline evaluate-policy`).

A policy human is accepted when it walks without falling, at the subject's speed and stride length,
with the subject's knee swing, and when SPM finds no long cluster between its hip and knee curves
and the subject's. The thresholds are params (`evaluate_policy.checks`); the functions here are
pure over the gait tables of `ingest.process`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from metrics.spm import spm_test


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


def enough(n_ok: int, n: int, fraction: float) -> bool:
    """At least `fraction` of `n` runs were ok (9 of 10 for 0.9)."""
    return n > 0 and n_ok >= fraction * n - 1e-9


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


def spm_check(a: np.ndarray, b: np.ndarray, p: PolicyChecks = PolicyChecks(), min_a: int = 2) -> dict:
    """SPM anova1 of curves `a` vs `b`: clusters (% of cycle), the longest, pass. With fewer than
    `min_a` curves in `a` the test is still run and reported but not judged (pass None): the mean
    of so few real cycles is not a reference to hold a simulation to."""
    if not (a.size and b.size) or a.shape[1] != b.shape[1]:
        return {"n_a": int(len(a)), "n_b": int(len(b)), "skipped": "no curves", "pass": False}
    res = spm_test(a, b, "anova1", p.spm_alpha, 2)
    spans = [(round(c.start_pct, 1), round(c.end_pct, 1)) for c in res.clusters]
    longest = round(float(max((e - s for s, e in spans), default=0.0)), 1)
    diff = np.abs(a.mean(0) - b.mean(0))
    out = {"n_a": int(len(a)), "n_b": int(len(b)), "clusters_pct": spans, "longest_cluster_pct": longest,
           "skipped": res.skipped, "pass": not res.skipped and longest <= p.max_spm_cluster_pct,
           "mean_abs_difference_deg": round(float(diff.mean()), 2),
           "max_abs_difference_deg": round(float(diff.max()), 2)}
    if len(a) < min_a:
        out.update({"pass": None, "not_judged": f"{len(a)} real cycles < {min_a}"})
    return out


def gait_check(real_kept: pd.DataFrame, sim_kept: pd.DataFrame, real_cycles: pd.DataFrame,
               sim_cycles: pd.DataFrame, p: PolicyChecks = PolicyChecks()) -> dict:
    """Gait speed, stride length (kept strides) and knee swing peak of the policy vs the subject."""
    real_v, real_l = float(real_kept["gait_speed_mps"].mean()), float(real_kept["stride_length_m"].mean())
    sim_v = float(sim_kept["gait_speed_mps"].mean()) if len(sim_kept) else float("nan")
    sim_l = float(sim_kept["stride_length_m"].mean()) if len(sim_kept) else float("nan")
    real_knee = swing_knee_peaks(real_cycles, p.swing_start_pct)
    sim_knee = swing_knee_peaks(sim_cycles, p.swing_start_pct) if len(sim_cycles) else np.array([])
    knee_diff = float(np.mean(sim_knee) - np.mean(real_knee)) if len(sim_knee) else float("nan")
    v_err, l_err = relative_error_pct(sim_v, real_v), relative_error_pct(sim_l, real_l)
    return {
        "kept_strides_sim": int(len(sim_kept)), "kept_strides_real": int(len(real_kept)),
        "gait_speed_mps": {"real": round(real_v, 3), "sim": round(sim_v, 3), "error_pct": round(v_err, 2)},
        "stride_length_m": {"real": round(real_l, 3), "sim": round(sim_l, 3), "error_pct": round(l_err, 2)},
        "knee_swing_peak_deg": {"real": round(float(np.mean(real_knee)), 2),
                                "sim": round(float(np.mean(sim_knee)), 2) if len(sim_knee) else None,
                                "difference": round(knee_diff, 2)},
        "pass_speed": bool(abs(round(v_err, 2)) <= p.max_speed_error_pct),
        "pass_stride_length": bool(abs(round(l_err, 2)) <= p.max_stride_error_pct),
        "pass_knee_peak": bool(abs(knee_diff) <= p.max_knee_peak_difference_deg),
    }
