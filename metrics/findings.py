"""The paper's qualitative findings checked against the simulation (Wang, Chan et al. ICRA 2025).

The paper reports, for its one participant: the speed-adaptive controller kept the pelvis closer to
the arm's neutral point than PID (mean |e_x| and |e_y|, Table I, real and simulated); in simulation
both controllers raised the gait speed above free walking (Table II); the inter-cycle SD of the
sagittal joint angles was smaller with the adaptive controller (Table III). Each finding here is a
comparison of two conditions decided from means and 95 % confidence intervals: `lower`, `higher`,
or `no difference` when the intervals overlap; a comparison without intervals (Table III has one
SD per condition) is decided on the means and says so. Which controller wins is reported as
measured: nothing here is a target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

Z95 = 1.96  # normal 95 % quantile, for a mean over many strides (Table II's SD / sqrt(n))


def compare(a: float, a_ci: float, b: float, b_ci: float) -> str:
    """`lower` / `higher` when `a` +- `a_ci` and `b` +- `b_ci` do not overlap, else `no difference`;
    `not measured` when a mean is missing; a missing interval counts as zero width."""
    if not (np.isfinite(a) and np.isfinite(b)):
        return "not measured"
    a_ci = a_ci if np.isfinite(a_ci) else 0.0
    b_ci = b_ci if np.isfinite(b_ci) else 0.0
    if a + a_ci < b - b_ci:
        return "lower"
    if a - a_ci > b + b_ci:
        return "higher"
    return "no difference"


@dataclass(frozen=True)
class Finding:
    """One of the paper's findings beside what the simulation gives (plain text: no `|`, it goes in a
    markdown table cell)."""

    claim: str       # the paper's finding, e.g. "adaptive below pid: mean abs e_x, walk_10m steady"
    expected: str    # the direction the paper found for `a` against `b` (`lower` / `higher`)
    paper: str       # the paper's numbers behind it
    measured: str    # ours: mean +- 95 % CI (or +- nothing) of `a` vs `b`
    result: str      # `compare`'s answer for ours
    ci: bool = True  # False: decided on the means alone

    @property
    def verdict(self) -> str:
        if self.result == "not measured":
            return "not measured"
        if self.result == "no difference":
            return "no difference within the 95 % CIs"
        agrees = "agrees" if self.result == self.expected else "disagrees"
        return agrees if self.ci else f"{agrees} (means only, no CI)"


def _cell(mean: float, ci: float, digits: int) -> str:
    if not np.isfinite(mean):
        return "–"
    return f"{mean:.{digits}f}" + (f" ± {ci:.{digits}f}" if np.isfinite(ci) else "")


def _pair(a: tuple[float, float], b: tuple[float, float], digits: int, unit: str) -> str:
    return f"{_cell(*a, digits)} vs {_cell(*b, digits)} {unit}"


def _mean_ci(row, col: str) -> tuple[float, float]:
    """(mean, 95 % CI half-width) of column `col` of a `phase_compliance` row (NaN without one)."""
    if row is None:
        return np.nan, np.nan
    return float(getattr(row, f"{col}_mean")), float(getattr(row, f"{col}_ci95"))


def compliance_findings(phases: pd.DataFrame, scenario: str, phases_shown: tuple[str, ...],
                        paper_sim: dict[str, tuple[float, float]]) -> list[Finding]:
    """Adaptive below PID in mean |e_x| and |e_y|, per phase of `scenario` (rows of the
    `phase_compliance` view of one subject and human mode: mean and 95 % CI over walks);
    `paper_sim`: condition -> the paper's simulated (|e_x|, |e_y|) in cm."""
    out = []
    for phase in phases_shown:
        rows = phases[(phases["scenario"] == scenario) & (phases["phase"] == phase)]
        by = {r.condition: r for r in rows.itertuples(index=False)}
        for i, (axis, col) in enumerate((("e_x", "abs_ex_cm"), ("e_y", "abs_ey_cm"))):
            a, b = _mean_ci(by.get("adaptive"), col), _mean_ci(by.get("pid"), col)
            paper = (f"{paper_sim['adaptive'][i]:.2f} vs {paper_sim['pid'][i]:.2f} cm (whole walks)"
                     if "adaptive" in paper_sim and "pid" in paper_sim else "–")
            out.append(Finding(f"adaptive below pid: mean abs {axis}, {scenario} {phase}", "lower", paper,
                               _pair(a, b, 2, "cm"), compare(*a, *b)))
    return out


def speed_findings(table2: pd.DataFrame, paper_sim_speed: dict[str, float]) -> list[Finding]:
    """Each controller above free walking in simulated gait speed (Table II rows of one subject and
    human mode: mean, SD and n over kept strides; the CI is Z95 x SD / sqrt(n), strides taken as
    independent, which narrows it)."""
    by = {r.condition: r for r in table2.itertuples(index=False)}

    def of(c: str) -> tuple[float, float]:
        r = by.get(c)
        if r is None or not np.isfinite(r.sim_gait_speed_mps_mean):
            return np.nan, np.nan
        n = float(r.sim_n_strides) if np.isfinite(r.sim_n_strides) else np.nan
        return float(r.sim_gait_speed_mps_mean), Z95 * float(r.sim_gait_speed_mps_sd) / np.sqrt(n)

    out = []
    free = of("free")
    for c in ("pid", "adaptive"):
        paper = (f"{paper_sim_speed[c]:.2f} vs {paper_sim_speed['free']:.2f} m/s"
                 if c in paper_sim_speed and "free" in paper_sim_speed else "–")
        out.append(Finding(f"{c} above free walking: gait speed (kept strides)", "higher", paper,
                           _pair(of(c), free, 3, "m/s"), compare(*of(c), *free)))
    return out


def variability_findings(table3: pd.DataFrame, paper_sim_sd: dict[str, dict[str, float]]) -> list[Finding]:
    """Adaptive below PID in the inter-cycle SD of each sagittal angle (Table III rows of one subject
    and human mode, sides averaged; one SD per condition, so decided on the means alone)."""
    out = []
    for joint, rows in table3.groupby("joint", sort=True):
        mean = rows.groupby("condition")["sim_intercycle_sd_deg"].mean()
        a, b = float(mean.get("adaptive", np.nan)), float(mean.get("pid", np.nan))
        pa, pp = paper_sim_sd.get("adaptive", {}).get(joint), paper_sim_sd.get("pid", {}).get(joint)
        paper = f"{pa:.2f} vs {pp:.2f} deg" if pa is not None and pp is not None else "–"
        out.append(Finding(f"adaptive below pid: inter-cycle SD, {joint}", "lower", paper,
                           _pair((a, np.nan), (b, np.nan), 2, "deg"), compare(a, 0.0, b, 0.0), ci=False))
    return out


__all__ = ["Finding", "compare", "compliance_findings", "speed_findings", "variability_findings"]
