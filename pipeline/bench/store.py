"""Benchmark of the results half of the pipeline: metrics per subject, store runs, a query.

On the example subjects' real tables (ingested once into a temp folder, untimed): `compute` of
every metric table per subject, a first store run into an empty DuckDB file, an unchanged rerun
(hashing only, no new versions) and `select * from paper_table2` on a read-only connection; best
of `repeat` runs each (`time.perf_counter`)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from metrics.section import MetricsParams
from pipeline.params import Params
from pipeline.stages.ingest import run_ingest
from pipeline.stages.metrics import compute, params_hash, read_inputs
from pipeline.store.connection import StoreParams
from pipeline.store.read import query
from pipeline.store.write import SubjectResults, store_results

SUBJECTS = ("camargo", "opencap4")
STORE_TARGETS = {"store_unchanged_rerun_s": 2.0, "metrics_all_subjects_s": 10.0}


def _best(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(max(repeat, 1)):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def time_store(params: Params, repeat: int = 3) -> dict:
    mp = params.section("metrics", MetricsParams)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for sid in SUBJECTS:
            run_ingest(sid, params, root / "processed", progress=False)
        inputs = {sid: read_inputs(sid, root / "processed") for sid in SUBJECTS}
        tables = {}

        def metrics_all() -> None:
            tables.update({sid: compute(inputs[sid], mp) for sid in SUBJECTS})

        metrics_s = _best(metrics_all, repeat)
        results = [SubjectResults(sid, tables[sid], params_hash(params)) for sid in SUBJECTS]
        first = float("inf")
        for k in range(max(repeat, 1)):
            db = root / f"first{k}.duckdb"
            start = time.perf_counter()
            store_results(db, results, StoreParams(), rev="bench")
            first = min(first, time.perf_counter() - start)
        rerun = _best(lambda: store_results(db, results, StoreParams(), rev="bench"), repeat)
        q = _best(lambda: query(db, "select * from paper_table2"), repeat)
        size = db.stat().st_size
    return {"metrics_all_subjects_s": round(metrics_s, 3), "store_first_run_s": round(first, 3),
            "store_unchanged_rerun_s": round(rerun, 3), "query_paper_table2_s": round(q, 4),
            "store_file_bytes": size}
