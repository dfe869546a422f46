"""SPM wrapper against spm1d's own results on its bundled datasets, skips, and real opencap4 data."""

import numpy as np
import pandas as pd
import pytest
import spm1d

from ingest.manifest import Manifest
from ingest.process import process_subject
from ingest.subject import load_subject
from metrics.errors import MetricsError
from metrics.spm import SpmParams, spm_tables, spm_test


def test_anova1_matches_spm1d_on_weather_dataset():
    y, groups = spm1d.data.uv1d.anova1.Weather().get_data()
    a, b = y[groups == 0], y[groups == 2]
    ref = spm1d.stats.anova1(np.vstack([a, b]), np.r_[np.zeros(len(a)), np.ones(len(b))], equal_var=True)
    ref = ref.inference(0.05)
    res = spm_test(a, b, "anova1", 0.05)
    assert res.statistic == "F" and (res.n_a, res.n_b) == (len(a), len(b))
    assert res.z == pytest.approx(np.asarray(ref.z))
    assert res.zstar == pytest.approx(ref.zstar)
    assert res.df == pytest.approx(tuple(float(d) for d in ref.df))
    assert len(res.clusters) == len(ref.clusters) > 0
    q = y.shape[1]
    for mine, theirs in zip(res.clusters, ref.clusters, strict=True):
        assert mine.p == pytest.approx(theirs.P)
        assert mine.start_pct == pytest.approx(theirs.endpoints[0] * 100 / (q - 1))
        assert mine.end_pct == pytest.approx(theirs.endpoints[1] * 100 / (q - 1))


def test_ttest2_matches_spm1d_on_plantar_arch_dataset():
    ya, yb = spm1d.data.uv1d.t2.PlantarArchAngle().get_data()
    ref = spm1d.stats.ttest2(yb, ya, equal_var=False).inference(0.05, two_tailed=True)
    res = spm_test(ya, yb, "ttest2", 0.05)
    assert res.statistic == "t" and res.z == pytest.approx(np.asarray(ref.z))
    assert res.zstar == pytest.approx(ref.zstar)
    assert [c.p for c in res.clusters] == pytest.approx([c.P for c in ref.clusters])
    assert res.h0_rejected == (len(ref.clusters) > 0)


def test_too_few_cycles_and_identical_curves_are_skipped_not_raised():
    curve = np.sin(np.linspace(0, np.pi, 101))[None, :]
    few = spm_test(np.vstack([curve, curve + 0.1]), curve, "anova1")
    assert few.skipped == "too few cycles: 2 vs 1, need at least 2 each" and few.z is None
    same = spm_test(np.vstack([curve, curve]), np.vstack([curve, curve]), "anova1")
    assert same.skipped and same.z is None and not same.h0_rejected
    gaps = spm_test(np.vstack([curve, curve + 1]), np.vstack([curve, np.full_like(curve, np.nan)]))
    assert gaps.skipped == "curves contain missing values"
    with pytest.raises(MetricsError, match="test must be one of"):
        SpmParams(test="kruskal")


@pytest.fixture(scope="module")
def opencap4_cycles(params) -> pd.DataFrame:
    t = process_subject(
        load_subject("opencap4"), Manifest.load(), params.ingest, progress=False
    )
    return t.cycles


def test_opencap4_free_vs_gait_modifications(opencap4_cycles):
    """Real data: free walking against toe-in, toe-out and trunk sway, per joint (sides pooled)."""
    out = spm_tables(opencap4_cycles, SpmParams())
    tests = out.tests
    assert set(tests["comparison"]) == {"within_source"}  # no simulation yet: nothing real vs sim
    assert set(tests["condition_b"]) == {"toe_in", "toe_out", "trunk_sway"}
    assert set(tests["joint"]) == {"hip_flexion", "knee_flexion", "ankle_dorsiflexion"}
    n = opencap4_cycles.drop_duplicates(["condition", "trial", "side", "stride"]).groupby("condition").size()
    for _, row in tests.iterrows():
        enough = min(n["free"], n[row["condition_b"]]) >= 2
        assert row["status"] == ("ok" if enough else "skipped"), row["reason"]
        if enough:
            curve = out.curves[out.curves["test_id"] == row["test_id"]]
            assert len(curve) == 101 and np.isfinite(curve["value"]).all() and (curve["value"] >= 0).all()
            assert row["df1"] == 1.0 and row["df2"] == n["free"] + n[row["condition_b"]] - 2
        else:
            assert row["reason"].startswith("too few cycles")
    clusters = out.clusters.merge(tests, on="test_id")
    assert (clusters["p"] < 0.05).all() and clusters["h0_rejected"].all()
    assert ((clusters["start_pct"] >= 0) & (clusters["end_pct"] <= 100)).all()


def test_real_vs_sim_pairs_sim_conditions_with_real_reference():
    base = np.sin(np.linspace(0, 2 * np.pi, 101)) * 20
    rng = np.random.default_rng(0)
    rows = []
    for source, mode, cond, shift in [
        ("real", "none", "free", 0),
        ("sim", "replay", "free", 0),
        ("sim", "replay", "pid", 8),
    ]:
        for k in range(6):
            curve = base + shift + rng.normal(0, 1, 101).cumsum() * 0.3
            rows += [
                {
                    "subject": "s",
                    "source": source,
                    "human_mode": mode,
                    "condition": cond,
                    "trial": "t",
                    "seed": k,
                    "side": "right",
                    "stride": k,
                    "pct": float(i),
                    "joint": "knee_flexion",
                    "angle_deg": float(v),
                }
                for i, v in enumerate(curve)
            ]
    out = spm_tables(pd.DataFrame(rows), SpmParams(joints=("knee_flexion",)))
    pairs = set(
        zip(
            out.tests["comparison"],
            out.tests["condition_a"],
            out.tests["source_a"],
            out.tests["condition_b"],
            strict=True,
        )
    )
    assert pairs == {
        ("real_vs_sim", "free", "real", "free"),
        ("real_vs_sim", "free", "real", "pid"),
        ("within_source", "free", "sim", "pid"),
    }
    shifted = out.tests[(out.tests["comparison"] == "within_source")].iloc[0]
    assert shifted["h0_rejected"]  # an 8 deg offset over the whole cycle is found
