"""Stage `store`: every subject's metric tables -> new versions in the results store.

Reads `<root>/<subject>/tables/<table>.parquet` for each metric table of `metrics.tables.REGISTRY`
(root: data/metrics), `quality.parquet` and `provenance.json` for each subject in params.yaml, the
rows of the sweep, fall-intervention and responsiveness studies (data/sweeps/<study>/results.parquet),
the tuning results (data/tuning) and `evaluate-policy`'s checks of each subject's policy and cohort
variant (`evaluation.json` in its policy folder, data/policies), and adds them to
`data/results.duckdb` in one transaction (`pipeline.store`).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from metrics.table import MetricTable
from metrics.tables import REGISTRY
from pipeline.params import Params
from pipeline.paths import (
    METRICS_ROOT,
    POLICIES_ROOT,
    SWEEPS_ROOT,
    TUNING_ROOT,
    metric_tables_dir,
    metrics_dir,
    policy_dir,
    sweep_dir,
)
from pipeline.runs.gate_record import EVALUATION_FILE, source_evaluation
from pipeline.store.connection import StoreError, StoreParams
from pipeline.store.records import POLICY_CHECK_COLUMNS, TUNING_COLUMNS
from pipeline.store.write import StoreReport, SubjectResults, store_results
from sim.body.variant import HEALTHY


def load_results(subject: str, root: Path = METRICS_ROOT,
                 registry: tuple[MetricTable, ...] = REGISTRY) -> SubjectResults:
    """A subject's metric tables (those of `registry` it has) as written by the metrics stage."""
    folder = metrics_dir(root, subject)
    prov = folder / "provenance.json"
    if not prov.is_file():
        raise StoreError(folder, f"no metrics for subject {subject!r}: "
                         f"run `python -m pipeline metrics {subject}`")
    files = {t.name: metric_tables_dir(root, subject) / f"{t.name}.parquet" for t in registry}
    tables = {t: pd.read_parquet(f) for t, f in files.items() if f.is_file()}
    doc = json.loads(prov.read_text())
    quality_file = folder / "quality.parquet"
    quality = pd.read_parquet(quality_file) if quality_file.is_file() else None
    return SubjectResults(subject, tables, str(doc["params_hash"]), doc.get("round_trip_of"), quality)


def load_sweep(study: str, root: Path = SWEEPS_ROOT) -> list[pd.DataFrame]:
    """The study's rows (`sweep` stage), or nothing when it has not run."""
    path = sweep_dir(root, study) / "results.parquet"
    return [pd.read_parquet(path)] if path.is_file() else []


def load_tunings(root: Path = TUNING_ROOT) -> list[dict]:
    """Every tuning result under `root` (`tune`: <subject>/<variant>/<controller>.json)."""
    out = []
    for path in sorted(root.glob("*/*/*.json")):
        try:
            doc = json.loads(path.read_text())
            out.append({c: doc[c] for c in TUNING_COLUMNS})
        except (ValueError, KeyError) as exc:
            raise StoreError(path, f"not a tuning result ({exc!r})") from None
    return out


def evaluation_rows(doc: dict, subject: str, variant: str) -> list[dict]:
    """One row per check of an `evaluate-policy` result (`POLICY_CHECK_COLUMNS`): its `check_rows`,
    or for an evaluation from before them its `checks` with value, bound and unit None; `walks` the
    evaluation's walks per condition (its free walks, `free.rollouts`: every condition ran as many)."""
    walks = (doc.get("free") or {}).get("rollouts")
    if "check_rows" in doc:
        return [{"subject": subject, "variant": variant, "check": r["check"], "passed": r["passed"],
                 "value": r["value"], "low": r["bound"][0], "high": r["bound"][1], "unit": r["unit"],
                 "walks": walks} for r in doc["check_rows"]]
    return [{"subject": subject, "variant": variant, "check": check, "passed": passed, "value": None,
             "low": None, "high": None, "unit": None, "walks": walks}
            for check, passed in doc["checks"].items()]


def load_policy_checks(subjects: list[str], root: Path = POLICIES_ROOT) -> pd.DataFrame:
    """The checks of every subject's policy (`<root>/<subject>/evaluation.json`) and cohort variant
    (`<root>/<subject>/cohort/<variant>/evaluation.json`) that has been evaluated."""
    rows = []
    for subject in subjects:
        own = policy_dir(root, subject)
        folders = [(HEALTHY, own), *((f.name, f) for f in sorted((own / "cohort").glob("*")) if f.is_dir())]
        for variant, folder in folders:
            try:
                doc = source_evaluation(folder)
                rows += [] if doc is None else evaluation_rows(doc, subject, variant)
            except (ValueError, KeyError, TypeError, IndexError) as exc:
                raise StoreError(folder / EVALUATION_FILE,
                                 f"not an evaluate-policy result ({exc!r})") from None
    return pd.DataFrame(rows, columns=POLICY_CHECK_COLUMNS)


def run_store(params: Params, root: Path = METRICS_ROOT, db: Path | None = None,
              progress: bool = True, sweeps_root: Path = SWEEPS_ROOT, tuning_root: Path = TUNING_ROOT,
              policies_root: Path = POLICIES_ROOT) -> StoreReport:
    """Store the metrics of every subject in params `subjects`, the rows of the params' studies (`sweep`,
    `fall_intervention`, `sensitivity`) and every tuning result, and the
    evaluate-policy checks of their policies."""
    p = params.section("store", StoreParams)
    subjects = list(params.subjects)
    results = [load_results(s, root) for s in subjects]
    bar = tqdm(desc="store", unit="table", disable=not progress, leave=False)
    try:
        return store_results(db or p.path, results, p, progress=lambda _: bar.update(),
                             sweeps=[*load_sweep(params.section("sweep.study", str), sweeps_root),
                                     *load_sweep(params.section("fall_intervention.study", str), sweeps_root),
                                     *load_sweep(params.section("sensitivity.study", str), sweeps_root)],
                             tunings=load_tunings(tuning_root),
                             policy_checks=load_policy_checks(subjects, policies_root))
    finally:
        bar.close()
