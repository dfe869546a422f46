"""A subject with one kept stride per side (issue 34, case 1), built from camargo's real tables:
its replayed seeds repeat that stride, so it is one stride, not three; statistics that need
variance say n/a and the paper's findings are not judged on it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from metrics.findings import NO_INTERVAL, compare, speed_findings
from metrics.gait import gait_table
from metrics.spm import SpmParams, spm_tables
from metrics.stability import stability_table


@pytest.fixture(scope="module")
def one_stride(camargo_model):
    real = camargo_model.parent / "real"
    strides, cycles = pd.read_parquet(real / "strides.parquet"), pd.read_parquet(real / "cycles.parquet")
    kept = strides[strides["kept"]]
    first = kept.groupby("side").head(1)[["trial", "side", "stride"]]  # one kept stride per side
    strides = strides.merge(first, on=["trial", "side", "stride"])
    cycles = cycles.merge(first, on=["trial", "side", "stride"])
    replay = {"source": "sim", "human_mode": "replay", "condition": "pid"}
    sim_strides = pd.concat([strides.assign(**replay, seed=s) for s in range(3)], ignore_index=True)
    sim_cycles = pd.concat([cycles.assign(**replay, seed=s) for s in range(3)], ignore_index=True)
    return strides, cycles, sim_strides, sim_cycles


def test_replayed_seeds_of_one_stride_count_once(one_stride):
    _, cycles, sim_strides, sim_cycles = one_stride
    sd = stability_table(sim_cycles, pool_sides=False)
    assert (sd["n_cycles"] == 1).all()
    assert sd["intercycle_sd_deg"].isna().all() and sd["note"].str.contains("at least 2").all()
    gait = gait_table(sim_strides).iloc[0]
    assert gait["n_strides"] == 2 and np.isfinite(gait["gait_speed_mps_sd"])  # one stride per side
    one_side = gait_table(sim_strides[sim_strides["side"] == "left"]).iloc[0]
    assert one_side["n_strides"] == 1 and np.isnan(one_side["gait_speed_mps_sd"])


def test_spm_against_one_stride_is_skipped(one_stride):
    _, cycles, _, sim_cycles = one_stride
    tests = spm_tables(pd.concat([cycles, sim_cycles], ignore_index=True),
                       SpmParams(pool_sides=False)).tests
    real_vs_sim = tests[tests["comparison"] == "real_vs_sim"]
    assert len(real_vs_sim) and (real_vs_sim["status"] == "skipped").all()
    assert real_vs_sim["reason"].str.contains("too few cycles").all()


def test_a_finding_without_an_interval_is_not_judged(one_stride):
    _, _, sim_strides, _ = one_stride
    left = sim_strides[sim_strides["side"] == "left"]
    rows = []
    for condition in ("free", "pid", "adaptive"):
        g = gait_table(left.assign(condition=condition)).iloc[0]
        rows.append({"condition": condition, "sim_gait_speed_mps_mean": g["gait_speed_mps_mean"],
                     "sim_gait_speed_mps_sd": g["gait_speed_mps_sd"], "sim_n_strides": g["n_strides"]})
    findings = speed_findings(pd.DataFrame(rows), {}, controllers=("pid", "adaptive"))
    assert all(f.result == NO_INTERVAL and f.verdict.startswith("n/a") for f in findings)
    assert compare(1.0, np.nan, 2.0, 0.1) == NO_INTERVAL and compare(1.0, 0.0, 2.0, 0.0) == "lower"
