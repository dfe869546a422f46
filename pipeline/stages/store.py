"""Stage `store`: every subject's metric tables -> new versions in the results store.

Reads `<root>/<subject>/<table>.parquet` (root: data/metrics) and `provenance.json` for each subject in
params.yaml and adds them to `data/results.duckdb` in one transaction (`pipeline.store`).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from pipeline.params import ParamsError
from pipeline.stages.metrics import DEFAULT_OUT_ROOT
from pipeline.store import TABLES, StoreError, StoreParams, StoreReport, SubjectResults, store_results


def store_params(params: dict, path: str | Path = "params.yaml") -> StoreParams:
    section = params.get("store")
    if not isinstance(section, dict):
        raise ParamsError(path, "no 'store' section")
    try:
        return StoreParams.from_dict(section)
    except KeyError as exc:
        raise ParamsError(path, f"store section lacks key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise ParamsError(path, f"invalid store section ({exc})") from None


def load_results(subject: str, root: Path = DEFAULT_OUT_ROOT) -> SubjectResults:
    """A subject's metric tables as written by the metrics stage."""
    folder = Path(root) / subject
    prov = folder / "provenance.json"
    if not prov.is_file():
        raise StoreError(folder, f"no metrics for subject {subject!r}: "
                         f"run `python -m pipeline metrics {subject}`")
    files = {t: folder / f"{t}.parquet" for t in TABLES}
    tables = {t: pd.read_parquet(f) for t, f in files.items() if f.is_file()}
    return SubjectResults(subject, tables, str(json.loads(prov.read_text())["params_hash"]))


def run_store(params: dict, root: Path = DEFAULT_OUT_ROOT, db: Path | None = None,
              params_path: str | Path = "params.yaml", progress: bool = True) -> StoreReport:
    """Store the metrics of every subject in `params['subjects']`."""
    p = store_params(params, params_path)
    subjects = [str(s) for s in params.get("subjects") or []]
    results = [load_results(s, root) for s in subjects]
    bar = tqdm(desc="store", unit="table", disable=not progress, leave=False)
    try:
        return store_results(db or p.path, results, p, progress=lambda _: bar.update())
    finally:
        bar.close()
