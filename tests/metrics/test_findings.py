"""The paper's findings are decided from means and 95 % CIs: overlap is no difference, a missing
condition is not measured, and a finding agrees only when the direction matches the paper's."""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.findings import Pair, compare, compliance_findings, speed_findings, variability_findings

PAIR = Pair("adaptive", "pid")  # the paper's finding: adaptive below pid (the caller names the controllers)


def test_compare_needs_separated_intervals():
    assert compare(1.0, 0.1, 2.0, 0.1) == "lower"
    assert compare(2.0, 0.1, 1.0, 0.1) == "higher"
    assert compare(1.0, 0.6, 2.0, 0.6) == "no difference"
    assert compare(np.nan, 0.1, 2.0, 0.1) == "not measured"
    assert compare(1.0, np.nan, 1.5, np.nan) == "no interval"  # one stride or walk: not judged
    assert compare(1.0, 0.0, 1.5, 0.0) == "lower"  # zero-width intervals: the means decide


def _phase(condition: str, ex: float, ex_ci: float, ey: float, ey_ci: float) -> dict:
    return {"scenario": "walk_10m", "phase": "steady", "condition": condition, "abs_ex_cm_mean": ex,
            "abs_ex_cm_ci95": ex_ci, "abs_ey_cm_mean": ey, "abs_ey_cm_ci95": ey_ci}


def test_compliance_findings_follow_the_measured_direction():
    phases = pd.DataFrame([_phase("pid", 0.78, 0.06, 1.74, 0.09), _phase("adaptive", 1.53, 0.09, 1.80, 0.50)])
    paper = {"pid": (7.65, 7.73), "adaptive": (0.70, 0.53)}
    ex, ey = compliance_findings(phases, "walk_10m", ("steady",), paper, pair=PAIR)
    assert ex.result == "higher" and ex.verdict == "disagrees"  # adaptive above pid: not the paper's finding
    assert ey.result == "no difference" and "no difference" in ey.verdict
    assert "0.70 vs 7.65" in ex.paper and "1.53 ± 0.09 vs 0.78 ± 0.06" in ex.measured
    assert not any("|" in text for f in (ex, ey) for text in (f.claim, f.paper, f.measured, f.verdict))
    missing = compliance_findings(phases, "walk_10m", ("stop",), {}, pair=PAIR)
    assert all(f.verdict == "not measured" for f in missing)


def test_speed_and_variability_findings():
    t2 = pd.DataFrame({"condition": ["free", "pid", "adaptive"],
                       "sim_gait_speed_mps_mean": [1.70, 1.90, 1.71],
                       "sim_gait_speed_mps_sd": [0.05, 0.05, 0.05], "sim_n_strides": [25, 25, 25]})
    pid, adaptive = speed_findings(t2, {"free": 1.12, "pid": 1.28, "adaptive": 1.47},
                                   controllers=("pid", "adaptive"))
    assert pid.verdict == "agrees" and adaptive.result == "no difference"
    t3 = pd.DataFrame({"condition": ["pid", "pid", "adaptive", "adaptive"], "side": ["left", "right"] * 2,
                       "joint": ["knee_flexion"] * 4, "sim_intercycle_sd_deg": [2.0, 2.2, 1.5, 1.7]})
    (knee,) = variability_findings(t3, {"pid": {"knee_flexion": 4.43}, "adaptive": {"knee_flexion": 2.11}},
                                   pair=PAIR)
    assert knee.result == "lower" and knee.verdict == "agrees (means only, no CI)"


def test_findings_name_the_controllers_they_are_given():
    """metrics/ knows no controller: the pair compared comes from the caller."""
    phases = pd.DataFrame([_phase("lqr", 0.5, 0.05, 1.0, 0.05), _phase("pd", 1.5, 0.05, 2.0, 0.05)])
    ex, _ = compliance_findings(phases, "walk_10m", ("steady",), {}, pair=Pair("lqr", "pd"))
    assert ex.claim == "lqr below pd: mean abs e_x, walk_10m steady" and ex.verdict == "agrees"
