"""Stage `metrics <subject>`: a subject's real and simulated tables -> metric tables.

Inputs: `<root>/<subject>/real/{strides,cycles}.parquet` (and the processed trials' file time columns
for the quality gates, `trial_spans`) and, once simulated,
`<root>/<subject>/sim/{strides,cycles,robot}.parquet` (replay human) and `sim_policy/` (policy human
in every scenario; root: data/processed). The policy human enters the paper's tables as the paper
sampled its walks (`metrics.sampling.paper_inputs`: `scenarios.paper`), and every scenario's robot
rows give the per-phase table and the traces around the commanded events (`metrics.phases`). Outputs in
`<out_root>/<subject>/` (data/metrics): `tables/` with one parquet per metric table of
`metrics.tables.REGISTRY` (replaced as a set: a DVC folder output, so a new table changes no dvc.yaml),
`quality.parquet` (the quality gates), `metrics.json` (headline numbers, a DVC metrics file) and
`provenance.json` (params hash and input hashes, read by the store stage). They live outside
data/processed so that the store stage can depend on `data/metrics` alone rather than on every
stage's outputs under data/processed.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import pandas as pd

from ingest.errors import GaitloopError
from ingest.manifest import sha256_of
from ingest.subject import load_subject
from metrics.errors import MetricsError
from metrics.quality import (
    QualityParams,
    TrialSpan,
    ingest_checks,
    policy_body_checks,
    quality_table,
    scale_checks,
    sim_checks,
    transfer_checks,
)
from metrics.sampling import paper_inputs, paper_strides, repeated_walks
from metrics.section import MetricsParams
from metrics.table import MetricInputs, MetricTable
from metrics.tables import REGISTRY
from pipeline.params import Params
from pipeline.paths import (
    METRICS_ROOT,
    PROCESSED_ROOT,
    metric_tables_dir,
    metrics_dir,
    model_dir,
    real_dir,
    sim_dir,
    sim_policy_dir,
    subject_dir,
)
from pipeline.runs.tuned_gains import tuned_document
from pipeline.stages.ingest import read_ingested
from pipeline.stages.outputs import read_json, write_outputs

SOURCES = ("real", "sim", "sim_policy")
SOURCE_DIRS = {"real": real_dir, "sim": sim_dir, "sim_policy": sim_policy_dir}  # under <root>/<subject>/
# Sections that do not shape the results; the hash of all others identifies a params version
# (so a section added later, e.g. for a new controller, counts without editing this list).
NON_RESULT_SECTIONS = ("subjects", "quality", "store", "report", "ray", "sweep", "tune")


def params_hash(params: Params) -> str:
    """sha256 (16 hex) of the result-shaping params sections, in a canonical JSON form (that of the
    params.yaml document, its controllers' gains with the tuned-gains file's on top: the same files
    give the same hash, and other tuned gains another)."""
    document = tuned_document(params)
    doc = {k: document[k] for k in sorted(document) if k not in NON_RESULT_SECTIONS}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]


def read_inputs(subject: str, root: Path, paper: tuple[str, int] | None = None) -> dict[str, pd.DataFrame]:
    """strides, cycles and robot tables of every source, concatenated (robot may be empty), plus
    `scenario_robot`: the policy human's robot rows of every scenario. `paper`: (scenario, cycles per
    walk) the policy human's rows are sampled with for the paper's tables (`paper_inputs`)."""
    found: dict[str, list[pd.DataFrame]] = {name: [] for name in ("strides", "cycles", "robot")}
    scenario_robot = pd.DataFrame()
    for source in SOURCES:
        tables = {}
        for name in found:
            path = SOURCE_DIRS[source](root, subject) / f"{name}.parquet"
            if path.is_file():
                tables[name] = pd.read_parquet(path)
        if source == "sim_policy" and tables:
            scenario_robot = tables.get("robot", pd.DataFrame())
            if paper is not None and not tables.get("strides", pd.DataFrame()).empty:
                tables = paper_inputs(tables, *paper)
            tables = {k: v.drop(columns=["scenario", "phase"], errors="ignore") for k, v in tables.items()}
        for name, df in tables.items():
            if not df.empty:
                found[name].append(df)
    if not found["cycles"]:
        raise MetricsError(str(subject_dir(root, subject)),
                           "no real/ or sim/ cycles.parquet: run ingest first")
    out = {name: pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
           for name, frames in found.items()}
    out["scenario_robot"] = scenario_robot
    return out


def compute(inputs: dict[str, pd.DataFrame], p: MetricsParams,
            registry: tuple[MetricTable, ...] = REGISTRY) -> dict[str, pd.DataFrame]:
    """Every metric table of `registry` for one subject (`inputs`: strides, cycles, robot and
    optionally scenario_robot)."""
    given = MetricInputs(inputs["strides"], inputs["cycles"], inputs["robot"],
                         inputs.get("scenario_robot", pd.DataFrame()))
    return {table.name: table.compute(given, p) for table in registry}


def headline(tables: dict[str, pd.DataFrame]) -> dict:
    """Small nested dict for `dvc metrics show`: per source/human mode/condition."""
    out: dict = {}

    def put(row, *keys_values):
        node = out.setdefault(f"{row['source']}_{row['human_mode']}", {}).setdefault(row["condition"], {})
        for k, v in keys_values:
            v = float(v)
            node[k] = None if math.isnan(v) else (int(v) if k.startswith("n_") else round(v, 4))

    for _, r in tables["gait"].iterrows():
        put(r, ("n_strides", r["n_strides"]), ("stride_length_m", r["stride_length_m_mean"]),
            ("gait_speed_mps", r["gait_speed_mps_mean"]))
    for _, r in tables["stability"].iterrows():
        side = "" if r["side"] == "both" else f"_{r['side']}"
        put(r, (f"sd_{r['joint']}{side}_deg", r["intercycle_sd_deg"]))
    for _, r in tables["compliance"].iterrows():
        put(r, ("mean_abs_ex_cm", r["mean_abs_ex_cm"]), ("mean_abs_ey_cm", r["mean_abs_ey_cm"]))
    tests = tables["spm_tests"]
    ok = tests["status"] == "ok"
    out["spm"] = {"n_tests": int(ok.sum()), "n_skipped": int((~ok).sum()),
                  "n_significant": int(tests["h0_rejected"].astype(bool).sum())}
    return out


def input_hashes(subject: str, root: Path) -> dict[str, str]:
    files = [p for source in SOURCES for p in sorted(SOURCE_DIRS[source](root, subject).glob("*.parquet"))]
    model = model_dir(root, subject)
    files += [p for p in (model / "model.json", model / "reference.json") if p.is_file()]
    return {str(p.relative_to(root)): sha256_of(p) for p in files}


def _read_table(path: Path) -> pd.DataFrame:
    return pd.read_parquet(path) if path.is_file() else pd.DataFrame()


def trial_spans(subject: str, root: Path = PROCESSED_ROOT) -> list[TrialSpan] | None:
    """The time columns of each trial's marker, angles and GRF files, as the ingest stage read them
    (`ingest.trial.Trial.file_time_s` of its processed trials); None without the ingest outputs."""
    try:
        trials = read_ingested(subject, root).trials
    except (GaitloopError, OSError):
        return None
    kinds = ("markers", "angles", "grf")
    return [TrialSpan(p.trial.trial, *(p.trial.file_time_s.get(kind) for kind in kinds)) for p in trials]


def paper_sampling(params: Params) -> tuple[str, int]:
    """(scenario, complete cycles per walk) the paper's tables sample the policy human with (params
    `scenarios.paper`, `sim.rollout.scenarios.PaperSampling`)."""
    paper = "scenarios.paper"
    return params.section(f"{paper}.scenario", str), params.section(f"{paper}.cycles_per_walk", int)


def quality_checks(subject: str, params: Params, root: Path = PROCESSED_ROOT,
                   spans: list[TrialSpan] | None = None) -> pd.DataFrame:
    """The subject's quality gates (`QUALITY_COLUMNS`) from what the earlier stages wrote
    (`spans`: the trial files' time columns, `trial_spans` when None); a transferred
    policy's gate comes from the policy rollouts' summary (`sim_policy/summary.json`)."""
    q, p = params.section("quality", QualityParams), params.section("metrics", MetricsParams)
    model = read_json(model_dir(root, subject) / "model.json")
    reference = read_json(model_dir(root, subject) / "reference.json")
    real = {n: _read_table(real_dir(root, subject) / f"{n}.parquet") for n in ("strides", "events", "cycles")}
    sims = {"replay": _read_table(sim_dir(root, subject) / "strides.parquet")}
    policy = _read_table(sim_policy_dir(root, subject) / "strides.parquet")
    table_strides = walks = None
    if not policy.empty:
        scenario, per_walk = paper_sampling(params)
        scenario = policy[policy["scenario"] == scenario]
        walks = repeated_walks(scenario) if not scenario.empty else None
        table_strides = paper_strides(scenario, per_walk, walks=walks)
    sims["policy"] = table_strides if table_strides is not None else policy
    policy_summary = read_json(sim_policy_dir(root, subject) / "summary.json") or {}
    replay_summary = read_json(sim_dir(root, subject) / "summary.json") or {}
    rollouts = {"replay": replay_summary.get("rollouts"), "policy": policy_summary.get("rollouts")}
    checks = [*scale_checks(subject, model, reference, q),
              *ingest_checks(subject, real["events"], real["cycles"],
                             spans if spans is not None else trial_spans(subject, root),
                             p.spm.min_cycles, q),
              *sim_checks(subject, real["strides"], sims, table_strides, q, walks, rollouts),
              *transfer_checks(subject, policy_summary.get("transfer")),
              *policy_body_checks(subject, policy_summary.get("policy_body"))]
    return quality_table(checks)


def run_metrics(subject: str, params: Params, root: Path = PROCESSED_ROOT,
                out_root: Path = METRICS_ROOT, registry: tuple[MetricTable, ...] = REGISTRY) -> Path:
    """Compute and write a subject's metric tables (those of `registry`); returns the output folder."""
    p = params.section("metrics", MetricsParams)
    root = Path(root)
    try:
        tables = compute(read_inputs(subject, root, paper_sampling(params)), p, registry)
    except (KeyError, ValueError) as exc:
        raise MetricsError(str(subject_dir(root, subject)), f"cannot compute metrics ({exc})") from None
    quality = quality_checks(subject, params, root)
    folder = metrics_dir(out_root, subject)
    provenance = {"subject": subject, "params_hash": params_hash(params),
                  "inputs": input_hashes(subject, root),
                  "round_trip_of": load_subject(subject).round_trip_of}
    write_outputs(folder, {"quality": quality}, {"metrics": headline(tables), "provenance": provenance},
                  (metric_tables_dir(out_root, subject), tables))
    return folder
