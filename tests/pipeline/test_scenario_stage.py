"""The scenario stage of a subject without a trained policy: empty tables and a summary that says
why, and the metrics stage still runs (a new subject from another lab has no policy yet)."""

from __future__ import annotations

import shutil

import pandas as pd

from pipeline.stages.metrics import run_metrics
from pipeline.stages.simulate import run_simulate_policy


def test_subject_without_a_policy_gets_empty_scenario_tables(params, camargo_model, tmp_path):
    root = tmp_path / "processed"
    shutil.copytree(camargo_model.parents[1] / "camargo", root / "camargo")
    summary = run_simulate_policy("camargo", params, root, tmp_path / "no_policies", progress=False)
    assert summary["rollouts"] == 0 and "no trained policy" in summary["note"]
    assert pd.read_parquet(root / "camargo" / "sim_policy" / "robot.parquet").empty
    folder = run_metrics("camargo", params, root, tmp_path / "metrics")
    assert pd.read_parquet(folder / "tables" / "phases.parquet").empty
    gait = pd.read_parquet(folder / "tables" / "gait.parquet")
    assert set(gait["human_mode"]) == {"none"}  # real only: no policy rows appear from nowhere
