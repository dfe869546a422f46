"""All-or-nothing stage outputs: a failure keeps what was stored and leaves no temp file."""

import pandas as pd
import pytest

from pipeline.stages.outputs import replacing, write_outputs


def test_outputs_replace_previous_ones(tmp_path):
    write_outputs(tmp_path, {"t": pd.DataFrame({"a": [1]})}, {"m": {"n": 1}})
    write_outputs(tmp_path, {"t": pd.DataFrame({"a": [2]})}, {"m": {"n": 2}})
    assert pd.read_parquet(tmp_path / "t.parquet")["a"].tolist() == [2]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "t.parquet"]


def test_failure_keeps_stored_outputs(tmp_path):
    kept = tmp_path / "a.json"
    kept.write_text("old")
    with pytest.raises(RuntimeError), replacing(kept, tmp_path / "b.json") as (a, b):
        a.write_text("new")
        raise RuntimeError("writing b failed")
    assert kept.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]
