"""The ingest stage's summary counts the strides that mix event sources (issue 34 case 5)."""

from __future__ import annotations

import json

import pandas as pd

from pipeline.stages.ingest import run_ingest


def test_the_ingest_summary_counts_the_mixed_source_strides(params, tmp_path):
    """Camargo's one stride left on a plate and a kinematic strike (no kinematic pair) is counted."""
    run_ingest("camargo", params, tmp_path, progress=False)
    real = tmp_path / "camargo" / "real"
    strides = pd.read_parquet(real / "strides.parquet")
    mixed = int((strides["reason"] == "mixed event sources (force, kinematic)").sum())
    assert json.loads((real / "summary.json").read_text())["n_mixed_event_sources"] == mixed == 1
