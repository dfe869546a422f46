"""Issue 35: a metric table is one module plus one line in `metrics.tables.REGISTRY`. A table registered
here (`kept_strides`, built from a subject's real strides) becomes an output of the metrics stage
inside an output dvc.yaml already declares, a `result_<name>` table with its typed columns and a
`latest_<name>` view in the store; registered no more, the metrics stage's table set drops it."""

from pathlib import Path

import pandas as pd
import pytest
import yaml

import pipeline.stages.metrics as metrics_stage
from ingest.manifest import Manifest
from ingest.process import process_subject
from ingest.subject import load_subject
from metrics.groups import GROUP, with_identity
from metrics.quality import QUALITY_COLUMNS
from metrics.table import GROUP_COLUMNS, MetricTable
from metrics.tables import REGISTRY, checked
from pipeline.params import check_params, load_params
from pipeline.paths import METRICS_ROOT, REPO_ROOT
from pipeline.stages.metrics import run_metrics
from pipeline.stages.store import load_results
from pipeline.store.connection import StoreParams
from pipeline.store.read import query
from pipeline.store.write import store_results

SUBJECT = "camargo"


def kept_strides(inputs, p) -> pd.DataFrame:
    strides = with_identity(inputs.strides, "strides table", ("kept",))
    out = strides.groupby(GROUP, sort=True)["kept"].agg(n_kept="sum", share_kept="mean").reset_index()
    return out.astype({"n_kept": "int64", "share_kept": float})


TINY = MetricTable("kept_strides", {**GROUP_COLUMNS, "n_kept": "BIGINT", "share_kept": "DOUBLE"},
                   kept_strides)


@pytest.fixture(scope="module")
def real_inputs() -> dict[str, pd.DataFrame]:
    t = process_subject(load_subject(SUBJECT), Manifest.load(), check_params().ingest, progress=False)
    return {"strides": t.strides, "cycles": t.cycles, "robot": pd.DataFrame(),
            "scenario_robot": pd.DataFrame()}


def declared_outputs(subject: str) -> list[Path]:
    """The metrics stage's outs and metrics in dvc.yaml, relative to data/metrics."""
    do = yaml.safe_load((REPO_ROOT / "dvc.yaml").read_text())["stages"]["metrics"]["do"]
    entries = [*do.get("outs", []), *do.get("metrics", [])]
    paths = [(e if isinstance(e, str) else next(iter(e))).replace("${item}", subject) for e in entries]
    return [(REPO_ROOT / p).relative_to(METRICS_ROOT) for p in paths]


def test_a_registered_table_is_written_and_stored(real_inputs, tmp_path, monkeypatch):
    registry = checked([*REGISTRY, TINY])
    monkeypatch.setattr(metrics_stage, "read_inputs", lambda subject, root, paper=None: real_inputs)
    monkeypatch.setattr(metrics_stage, "quality_checks",
                        lambda subject, params, root: pd.DataFrame(columns=QUALITY_COLUMNS))
    out_root = tmp_path / "metrics"
    folder = run_metrics(SUBJECT, load_params(), tmp_path / "processed", out_root, registry)

    written = pd.read_parquet(folder / "tables" / "kept_strides.parquet")
    assert written.columns.tolist() == TINY.column_names and written["n_kept"].sum() > 0
    outs = declared_outputs(SUBJECT)
    files = [p.relative_to(out_root) for p in out_root.rglob("*") if p.is_file()]
    assert Path(SUBJECT, "tables", "kept_strides.parquet") in files
    assert [f for f in files if not any(f == o or o in f.parents for o in outs)] == []  # no dvc.yaml edit

    db = tmp_path / "results.duckdb"
    store_results(db, [load_results(SUBJECT, out_root, registry)], StoreParams(busy_timeout_s=1.0),
                  rev="test", registry=registry)
    columns = query(db, "SELECT column_name, data_type FROM information_schema.columns "
                        "WHERE table_name = 'result_kept_strides' ORDER BY ordinal_position")
    assert list(columns.itertuples(index=False, name=None)) == [("version_id", "BIGINT"),
                                                                 *TINY.columns.items()]
    stored = query(db, f"SELECT {', '.join(TINY.columns)} FROM latest_kept_strides "
                       f"ORDER BY {', '.join(GROUP)}")
    expected = written.sort_values(GROUP).reset_index(drop=True)
    pd.testing.assert_frame_equal(stored, expected, check_dtype=False)
    groups = query(db, "SELECT count(DISTINCT version_id) FROM latest_kept_strides").iloc[0, 0]
    assert groups == len(written)  # one version per group, shared with the subject's other tables
    assert query(db, "SELECT count(*) FROM latest_gait").iloc[0, 0] > 0

    run_metrics(SUBJECT, load_params(), tmp_path / "processed", out_root)  # the registry without it
    assert not (folder / "tables" / "kept_strides.parquet").exists()
    assert sorted(p.stem for p in (folder / "tables").iterdir()) == sorted(t.name for t in REGISTRY)
