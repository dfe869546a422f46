"""The paper's qualitative findings checked against the simulation (Wang, Chan et al. ICRA 2025).

The paper reports, for its one participant: the speed-adaptive controller kept the pelvis closer to
the arm's neutral point than PID (mean |e_x| and |e_y|, Table I, real and simulated); in simulation
both controllers raised the gait speed above free walking (Table II); the inter-cycle SD of the
sagittal joint angles was smaller with the adaptive controller (Table III). Each finding here is a
comparison of two conditions decided from means and 95 % confidence intervals: `lower`, `higher`,
or `no difference` when the intervals overlap; a comparison without intervals (Table III has one
SD per condition) is decided on the means and says so. Which controller wins is reported as
measured: nothing here is a target.

The responsiveness study (`sensitivity` view: the twin's drive lag, command latency and PID gains moved one
at a time) says where each tracking finding holds: `responsiveness_comparisons` compares the pair's `a`
against its `b` at each level, `region_text` names the twin's own point and the levels where `a` is below.

No controller is named here: which two conditions a finding compares (`Pair`: the paper's speed-adaptive
controller against its PID baseline) and which controllers a table holds are passed in by the caller
(the report stage), as the condition names the tables hold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

NO_INTERVAL = "no interval"  # `compare`: a mean without a confidence interval is not judged
Z95 = 1.96  # normal 95 % quantile, for a mean over many strides (Table II's SD / sqrt(n))


@dataclass(frozen=True)
class Pair:
    """The two conditions (controllers) a finding compares: `a` against `b`."""

    a: str
    b: str

    @property
    def below(self) -> str:
        return f"{self.a} below {self.b}"


def compare(a: float, a_ci: float, b: float, b_ci: float) -> str:
    """`lower` / `higher` when `a` +- `a_ci` and `b` +- `b_ci` do not overlap, else `no difference`;
    `not measured` when a mean is missing; `no interval` when an interval is (a single stride or walk
    has no variance: nothing can be judged; pass 0.0 to decide on the means alone)."""
    if not (np.isfinite(a) and np.isfinite(b)):
        return "not measured"
    if not (np.isfinite(a_ci) and np.isfinite(b_ci)):
        return NO_INTERVAL
    if a + a_ci < b - b_ci:
        return "lower"
    if a - a_ci > b + b_ci:
        return "higher"
    return "no difference"


@dataclass(frozen=True)
class Finding:
    """One of the paper's findings beside what the simulation gives (plain text: no `|`, it goes in a
    markdown table cell)."""

    claim: str       # the paper's finding, e.g. "<a> below <b>: mean abs e_x, walk_10m steady"
    expected: str    # the direction the paper found for `a` against `b` (`lower` / `higher`)
    paper: str       # the paper's numbers behind it
    measured: str    # ours: mean +- 95 % CI (or +- nothing) of `a` vs `b`
    result: str      # `compare`'s answer for ours
    ci: bool = True  # False: decided on the means alone
    region: str = "not in the responsiveness study"  # where on the twin's responsiveness it holds

    @property
    def verdict(self) -> str:
        if self.result == "not measured":
            return "not measured"
        if self.result == NO_INTERVAL:
            return "n/a: no 95 % CI (fewer than 2 independent strides or walks)"
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
                        paper_sim: dict[str, tuple[float, float]],
                        regions: dict[str, str] | None = None, *, pair: Pair) -> list[Finding]:
    """`pair.a` below `pair.b` in mean |e_x| and |e_y|, per phase of `scenario` (rows of the
    `phase_compliance` view of one subject and human mode: mean and 95 % CI over walks);
    `paper_sim`: condition -> the paper's simulated (|e_x|, |e_y|) in cm; `regions`: axis (`e_x`,
    `e_y`) -> `region_text` of the responsiveness study."""
    regions = regions or {}
    out = []
    for phase in phases_shown:
        rows = phases[(phases["scenario"] == scenario) & (phases["phase"] == phase)]
        by = {r.condition: r for r in rows.itertuples(index=False)}
        for i, (axis, col) in enumerate((("e_x", "abs_ex_cm"), ("e_y", "abs_ey_cm"))):
            a, b = _mean_ci(by.get(pair.a), col), _mean_ci(by.get(pair.b), col)
            paper = (f"{paper_sim[pair.a][i]:.2f} vs {paper_sim[pair.b][i]:.2f} cm (whole walks)"
                     if pair.a in paper_sim and pair.b in paper_sim else "–")
            out.append(Finding(f"{pair.below}: mean abs {axis}, {scenario} {phase}", "lower", paper,
                               _pair(a, b, 2, "cm"), compare(*a, *b),
                               region=regions.get(axis, "not in the responsiveness study")))
    return out


# factor -> (label, unit, multiplier to that unit) of the responsiveness study (sim.robot.responsiveness)
FACTOR_UNITS = {"drive_tau_s": ("drive tau", "ms", 1000.0), "latency_s": ("latency", "ms", 1000.0),
                "pid_gain_scale": ("PID gains", "x", 1.0)}
def comparison_columns(pair: Pair) -> list[str]:
    """The columns of `responsiveness_comparisons` (`<a>_mean`, ..., `falls_<b>`)."""
    return ["factor", "level", "twin", f"{pair.a}_mean", f"{pair.a}_ci95", f"{pair.b}_mean", f"{pair.b}_ci95",
            f"falls_{pair.a}", f"falls_{pair.b}", "n", "result"]


def responsiveness_comparisons(sens: pd.DataFrame, col: str, pair: Pair) -> pd.DataFrame:
    """`pair.a` against `pair.b` at each (factor, level) of the responsiveness study (rows of the
    `sensitivity` view of one subject, variant and scenario; `col`: `mean_abs_ex_cm` or
    `mean_abs_ey_cm`, with its `_ci95`): both means and CIs, falls, the smaller n of the two and
    `compare(a, b)` (`lower`: a below b; columns `comparison_columns`). A level without both
    controllers is left out; `twin` is b's (the controller that reads every factor)."""
    rows = []
    for (factor, level), g in sens.groupby(["factor", "level"], sort=True):
        by = {r.condition: r for r in g.itertuples(index=False)}
        if pair.a not in by or pair.b not in by:
            continue
        a, b = by[pair.a], by[pair.b]
        am, ac = float(getattr(a, col)), float(getattr(a, f"{col}_ci95"))
        pm, pc = float(getattr(b, col)), float(getattr(b, f"{col}_ci95"))
        rows.append([factor, float(level), bool(b.twin), am, ac, pm, pc, int(a.falls), int(b.falls),
                     int(min(a.n, b.n)), compare(am, ac, pm, pc)])
    return pd.DataFrame(rows, columns=comparison_columns(pair))


def level_text(factor: str, level: float) -> str:
    """`200 ms`, `0.25x` (`FACTOR_UNITS`)."""
    _, unit, k = FACTOR_UNITS.get(factor, (factor, "", 1.0))
    return f"{level * k:g}x" if unit == "x" else f"{level * k:g} {unit}"


def region_text(comparisons: pd.DataFrame, pair: Pair) -> str:
    """Where on the twin's responsiveness `pair.a` is below `pair.b` (`responsiveness_comparisons` of
    one axis): the twin's point, then per factor the levels where a is lower (95 % CIs apart), or
    that there are none; plain text for a markdown cell."""
    if comparisons.empty:
        return "not in the responsiveness study"
    twin = comparisons[comparisons["twin"]].drop_duplicates("factor")
    point = ", ".join(f"{FACTOR_UNITS.get(r.factor, (r.factor,))[0]} {level_text(r.factor, r.level)}"
                      for r in twin.itertuples(index=False))
    words = {"lower": pair.below, "higher": f"{pair.a} above {pair.b}",
             "no difference": "no difference", "not measured": "not measured"}
    head = f"twin ({point}): {words[twin['result'].iloc[0]]}" if not twin.empty else "twin: not measured"
    parts = []
    for factor, g in comparisons.groupby("factor", sort=True):
        label = FACTOR_UNITS.get(factor, (factor, "", 1.0))[0]
        below = [level_text(factor, v) for v in g.loc[g["result"] == "lower", "level"]]
        span = f"{level_text(factor, g['level'].min())}-{level_text(factor, g['level'].max())}"
        parts.append(f"{label} {', '.join(below)}" if below else f"{label} never ({span})")
    return f"{head}; {pair.below} at " + "; ".join(parts)



def speed_findings(table2: pd.DataFrame, paper_sim_speed: dict[str, float], *,
                   controllers: tuple[str, ...]) -> list[Finding]:
    """Each of `controllers` above free walking in simulated gait speed (Table II rows of one subject and
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
    for c in controllers:
        paper = (f"{paper_sim_speed[c]:.2f} vs {paper_sim_speed['free']:.2f} m/s"
                 if c in paper_sim_speed and "free" in paper_sim_speed else "–")
        out.append(Finding(f"{c} above free walking: gait speed (kept strides)", "higher", paper,
                           _pair(of(c), free, 3, "m/s"), compare(*of(c), *free)))
    return out


def variability_findings(table3: pd.DataFrame, paper_sim_sd: dict[str, dict[str, float]], *,
                         pair: Pair) -> list[Finding]:
    """`pair.a` below `pair.b` in the inter-cycle SD of each sagittal angle (Table III rows of one subject
    and human mode, sides averaged; one SD per condition, so decided on the means alone)."""
    out = []
    for joint, rows in table3.groupby("joint", sort=True):
        mean = rows.groupby("condition")["sim_intercycle_sd_deg"].mean()
        a, b = float(mean.get(pair.a, np.nan)), float(mean.get(pair.b, np.nan))
        pa, pp = paper_sim_sd.get(pair.a, {}).get(joint), paper_sim_sd.get(pair.b, {}).get(joint)
        paper = f"{pa:.2f} vs {pp:.2f} deg" if pa is not None and pp is not None else "–"
        out.append(Finding(f"{pair.below}: inter-cycle SD, {joint}", "lower", paper,
                           _pair((a, np.nan), (b, np.nan), 2, "deg"), compare(a, 0.0, b, 0.0), ci=False))
    return out


__all__ = ["FACTOR_UNITS", "NO_INTERVAL", "Finding", "Pair", "compare", "comparison_columns",
           "compliance_findings", "level_text", "region_text", "responsiveness_comparisons", "speed_findings",
           "variability_findings"]
