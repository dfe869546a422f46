"""Statistical parametric mapping (SPM1D) of joint-angle curves with `spm1d`.

Wang, Chan et al. (ICRA 2025) compare real and simulated kinematics with a one-way ANOVA in
SPM1D (`spm1d.stats.anova1`, alpha 0.05): the F statistic is computed at every point of the
gait cycle, its critical threshold comes from random field theory, and each supra-threshold
cluster gets a p-value. Two comparisons are made per joint:

- `real_vs_sim`: a simulated condition against the real recordings of the same condition, or of
  `reference_condition` (free walking) when the real subject did not walk in that condition;
- `within_source`: `reference_condition` against every other condition of one source and human
  mode (free vs pid, free vs adaptive; free vs toe_in for real gait modifications).

`test` is `anova1` (F, as in the paper) or `ttest2` (two-tailed t; t > 0 where b lies above a).
A comparison with fewer than `min_cycles` cycles in a group, or whose statistic is not finite
(e.g. identical curves), is skipped with the reason recorded, never raised.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Annotated, Literal

import numpy as np
import pandas as pd
from pydantic import Field, with_config

from metrics.curves import curve_groups
from metrics.errors import MetricsError
from metrics.groups import GROUP, JOINTS
from metrics.table import MetricInputs, MetricTable

TESTS = ("anova1", "ttest2")
TEST_SCHEMA = {"test_id": "VARCHAR", "subject": "VARCHAR", "comparison": "VARCHAR", "side": "VARCHAR",
               "joint": "VARCHAR", "source_a": "VARCHAR", "human_mode_a": "VARCHAR", "condition_a": "VARCHAR",
               "source_b": "VARCHAR", "human_mode_b": "VARCHAR", "condition_b": "VARCHAR", "test": "VARCHAR",
               "statistic": "VARCHAR", "n_a": "BIGINT", "n_b": "BIGINT", "alpha": "DOUBLE", "zstar": "DOUBLE",
               "df1": "DOUBLE", "df2": "DOUBLE", "h0_rejected": "BOOLEAN", "n_clusters": "BIGINT",
               "min_p": "DOUBLE", "status": "VARCHAR", "reason": "VARCHAR"}
CURVE_SCHEMA = {"test_id": "VARCHAR", "pct": "DOUBLE", "value": "DOUBLE"}
CLUSTER_SCHEMA = {"test_id": "VARCHAR", "cluster": "BIGINT", "start_pct": "DOUBLE", "end_pct": "DOUBLE",
                  "extent_pct": "DOUBLE", "p": "DOUBLE"}
TEST_COLUMNS, CURVE_COLUMNS, CLUSTER_COLUMNS = list(TEST_SCHEMA), list(CURVE_SCHEMA), list(CLUSTER_SCHEMA)


@with_config(extra="forbid")
@dataclass(frozen=True)
class SpmParams:
    """The `metrics.spm` section of params.yaml (`pool_sides` and `joints` are the `metrics` section's:
    `metrics.section.MetricsParams` sets them)."""

    alpha: Annotated[float, Field(gt=0.0, lt=1.0)] = 0.05  # Wang, Chan et al. ICRA 2025
    test: Literal["anova1", "ttest2"] = "anova1"  # the paper's one-way ANOVA; or ttest2
    min_cycles: Annotated[int, Field(ge=2)] = 2  # per group; spm1d needs residual degrees of freedom
    reference_condition: str = "free"
    pool_sides: bool = True
    joints: tuple[str, ...] = JOINTS

    def __post_init__(self) -> None:
        if self.test not in TESTS:
            raise MetricsError("params metrics.spm", f"test must be one of {TESTS}, got {self.test!r}")
        if not 0 < self.alpha < 1:
            raise MetricsError("params metrics.spm", f"alpha must be in (0, 1), got {self.alpha}")
        if self.min_cycles < 2:
            raise MetricsError("params metrics.spm", f"min_cycles must be at least 2, got {self.min_cycles}")


@dataclass(frozen=True)
class SpmCluster:
    start_pct: float
    end_pct: float
    p: float

    @property
    def extent_pct(self) -> float:
        return self.end_pct - self.start_pct


@dataclass(frozen=True)
class SpmResult:
    """One SPM test: the statistic curve `z` over `pct`, its threshold `zstar`, clusters."""

    test: str
    n_a: int
    n_b: int
    alpha: float
    pct: np.ndarray
    z: np.ndarray | None = None
    zstar: float = float("nan")
    df: tuple[float, float] = (float("nan"), float("nan"))
    clusters: tuple[SpmCluster, ...] = field(default_factory=tuple)
    skipped: str = ""

    @property
    def statistic(self) -> str:
        return "F" if self.test == "anova1" else "t"

    @property
    def h0_rejected(self) -> bool:
        return bool(self.clusters)


def spm_test(a: np.ndarray, b: np.ndarray, test: str = "anova1", alpha: float = 0.05,
             min_cycles: int = 2, pct: np.ndarray | None = None) -> SpmResult:
    """Compare two sets of curves, (n_a, Q) and (n_b, Q), point by point.

    `anova1` runs `spm1d.stats.anova1(Y, A, equal_var=True)` with groups 0 (a) and 1 (b);
    `ttest2` runs `spm1d.stats.ttest2(b, a)` two-tailed. Cluster endpoints (node indices,
    interpolated by spm1d) are mapped onto `pct` (default 0..100 over Q points).
    """
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    q = a.shape[1]
    pct = np.linspace(0, 100, q) if pct is None else np.asarray(pct, float)
    base = SpmResult(test, int(a.shape[0]) if a.size else 0, int(b.shape[0]) if b.size else 0, alpha, pct)
    if test not in TESTS:
        raise MetricsError("spm", f"unknown test {test!r} (known: {', '.join(TESTS)})")
    if a.size == 0 or b.size == 0 or min(a.shape[0], b.shape[0]) < min_cycles:
        return _skip(base, f"too few cycles: {base.n_a} vs {base.n_b}, need at least {min_cycles} each")
    if b.shape[1] != q or len(pct) != q:
        return _skip(base, f"curves differ in length: {q} vs {b.shape[1]} points")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        return _skip(base, "curves contain missing values")
    import spm1d  # here, not at the top: it imports matplotlib (~1 s), which most stages never need

    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            if test == "anova1":
                y = np.vstack([a, b])
                groups = np.r_[np.zeros(len(a), int), np.ones(len(b), int)]
                spmi = spm1d.stats.anova1(y, groups, equal_var=True).inference(alpha)
            else:
                spmi = spm1d.stats.ttest2(b, a, equal_var=False).inference(alpha, two_tailed=True)
    except Exception as exc:  # spm1d raises plain errors on degenerate input
        return _skip(base, f"spm1d could not run the test ({type(exc).__name__}: {exc})")
    z = np.asarray(spmi.z, float)
    if not np.isfinite(z).all() or not np.isfinite(spmi.zstar):
        return _skip(base, "statistic not finite (curves without variance, e.g. identical)")
    nodes = np.arange(q)
    clusters = tuple(
        SpmCluster(float(np.interp(c.endpoints[0], nodes, pct)), float(np.interp(c.endpoints[1], nodes, pct)),
                   float(c.P))
        for c in spmi.clusters
    )
    return SpmResult(test, base.n_a, base.n_b, alpha, pct, z, float(spmi.zstar),
                     (float(spmi.df[0]), float(spmi.df[1])), clusters)


def _skip(base: SpmResult, reason: str) -> SpmResult:
    return SpmResult(base.test, base.n_a, base.n_b, base.alpha, base.pct, skipped=reason)


@dataclass(frozen=True)
class SpmTables:
    """Tidy SPM results: one row per test, its statistic curve, and its clusters."""

    tests: pd.DataFrame
    curves: pd.DataFrame
    clusters: pd.DataFrame


def comparisons(groups: list[tuple[str, str, str]], reference: str) -> list[tuple[str, tuple, tuple]]:
    """(comparison, group a, group b) pairs among (source, human_mode, condition) groups."""
    present = set(groups)
    pairs = []
    real = {g for g in groups if g[0] == "real"}
    for g in sorted(x for x in groups if x[0] == "sim"):
        same = ("real", next(iter(real))[1] if real else "none", g[2])
        ref = ("real", same[1], reference)
        partner = same if same in present else (ref if ref in present else None)
        if partner:
            pairs.append(("real_vs_sim", partner, g))
    for g in sorted(groups):
        ref = (g[0], g[1], reference)
        if g[2] != reference and ref in present:
            pairs.append(("within_source", ref, g))
    return pairs


def spm_tables(cycles: pd.DataFrame, params: SpmParams = SpmParams()) -> SpmTables:
    """Every real-vs-sim and within-source comparison of one subject's cycles, per joint."""
    matrices = curve_groups(cycles, params.pool_sides)
    tests, curves, clusters = [], [], []
    by_subject: dict[str, dict[tuple, dict[tuple, pd.DataFrame]]] = {}
    for (subject, source, mode, condition, side, joint), m in matrices.items():
        if joint in params.joints:
            by_subject.setdefault(subject, {}).setdefault((side, joint), {})[(source, mode, condition)] = m
    for subject, per_joint in sorted(by_subject.items()):
        for (side, joint), per_group in sorted(per_joint.items()):
            for comparison, ga, gb in comparisons(list(per_group), params.reference_condition):
                ma, mb = per_group[ga], per_group[gb]
                res = spm_test(ma.to_numpy(float), mb.to_numpy(float), params.test, params.alpha,
                               params.min_cycles, ma.columns.to_numpy(float))
                test_id = f"{subject}|{comparison}|{side}|{joint}|{'/'.join(ga)}|{'/'.join(gb)}"
                tests.append((test_id, subject, comparison, side, joint, *ga, *gb, res.test, res.statistic,
                              res.n_a, res.n_b, res.alpha, res.zstar, *res.df, res.h0_rejected,
                              len(res.clusters), min((c.p for c in res.clusters), default=np.nan),
                              "skipped" if res.skipped else "ok", res.skipped))
                if res.z is not None:
                    curves.append(pd.DataFrame({"test_id": test_id, "pct": res.pct, "value": res.z}))
                clusters += [(test_id, i, c.start_pct, c.end_pct, c.extent_pct, c.p)
                             for i, c in enumerate(res.clusters)]
    return SpmTables(
        pd.DataFrame(tests, columns=TEST_COLUMNS),
        pd.concat(curves, ignore_index=True) if curves else pd.DataFrame(columns=CURVE_COLUMNS),
        pd.DataFrame(clusters, columns=CLUSTER_COLUMNS),
    )


def _shared_tables(inputs: MetricInputs, p) -> SpmTables:
    """The three SPM tables of `inputs` (`p`: the `metrics` params section), computed once for all three."""
    return inputs.shared("spm", lambda: spm_tables(inputs.cycles, p.spm))


# a test belongs to the group of its second sample (`*_b`); its curve and clusters to the test's
TEST_TABLE = MetricTable("spm_tests", TEST_SCHEMA, lambda inputs, p: _shared_tables(inputs, p).tests,
                         group=("subject", *(f"{c}_b" for c in GROUP[1:])))
CURVE_TABLE = MetricTable("spm_curves", CURVE_SCHEMA, lambda inputs, p: _shared_tables(inputs, p).curves,
                          linked=("spm_tests", "test_id"))
CLUSTER_TABLE = MetricTable("spm_clusters", CLUSTER_SCHEMA,
                            lambda inputs, p: _shared_tables(inputs, p).clusters,
                            linked=("spm_tests", "test_id"))
