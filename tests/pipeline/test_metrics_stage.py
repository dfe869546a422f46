"""Stage `metrics` (pipeline/stages/metrics.py): every metric table and the headline computed from the
real example subjects' ingested tables, and the params hash that versions stored results."""

import hashlib
import json

import pandas as pd
import pytest
import yaml

from ingest.manifest import Manifest
from ingest.process import IngestParams, process_subject
from ingest.subject import load_subject
from metrics.section import MetricsParams
from pipeline.params import PARAMS_FILE, load_params, parse_params
from pipeline.paths import TUNED_GAINS
from pipeline.runs.setup import controller_specs
from pipeline.runs.tuned_gains import read_tuned, write_tuned
from pipeline.stages.metrics import NON_RESULT_SECTIONS, compute, headline, params_hash


@pytest.fixture(scope="module")
def real_tables():
    p = load_params().section("ingest", IngestParams)
    out = {}
    for sid in ("camargo", "opencap4"):
        t = process_subject(load_subject(sid), Manifest.load(), p, progress=False)
        out[sid] = {"strides": t.strides, "cycles": t.cycles, "robot": pd.DataFrame()}
    return out


def test_real_subjects_metrics(real_tables):
    mp = load_params().section("metrics", MetricsParams)
    for inputs in real_tables.values():
        tables = compute(inputs, mp)
        gait = tables["gait"]
        assert set(gait["source"]) == {"real"} and set(gait["human_mode"]) == {"none"}
        assert gait["gait_speed_mps_mean"].between(0.5, 2.5).all()
        stab = tables["stability"].dropna(subset=["intercycle_sd_deg"])
        assert not stab.empty and stab["intercycle_sd_deg"].between(0.05, 15).all()
        kept = inputs["strides"]["kept"].sum()
        assert gait["n_strides"].sum() == kept
        assert tables["compliance"].empty and tables["harness"].empty  # no robot without simulation
        doc = headline(tables)
        assert doc["real_none"]["free"]["n_strides"] == int(
            gait.set_index("condition").loc["free", "n_strides"]
        )
    assert set(compute(real_tables["opencap4"], mp)["gait"]["condition"]) == {
        "free",
        "toe_in",
        "toe_out",
        "trunk_sway",
    }


def test_params_hash_ignores_only_non_result_sections(tmp_path):
    params = load_params()
    base = params_hash(params)
    # the hash of the params.yaml document as written, its controllers' gains with the tuned-gains file's
    # on top: stored versions keep matching the same files
    raw = yaml.safe_load(PARAMS_FILE.read_text())
    tuned = read_tuned(TUNED_GAINS)
    for name, entry in raw["robot"]["controllers"].items():
        entry["gains"] = {**entry["gains"], **tuned.get(name, {})}
    raw = {k: raw[k] for k in sorted(raw) if k not in NON_RESULT_SECTIONS}
    assert base == hashlib.sha256(json.dumps(raw, sort_keys=True, default=str).encode()).hexdigest()[:16]
    doc = params.document()
    report = {**doc["report"], "dpi": 1}
    assert params_hash(parse_params({**doc, "report": report, "subjects": ["x"]})) == base
    changed = {**doc, "metrics": {**doc["metrics"], "pool_sides": not doc["metrics"]["pool_sides"]}}
    assert params_hash(parse_params(changed)) != base
    # a new controller counts without editing NON_RESULT_SECTIONS
    doc["robot"]["controllers"]["pid2"] = controller_specs(params)["pid"]
    assert params_hash(parse_params(doc)) != base
    # so do other tuned gains (they live in the tuned-gains file, not in params.yaml)
    tuned["pid"] = {**tuned["pid"], "kp_x": 2 * tuned["pid"]["kp_x"]}
    write_tuned(tmp_path / "controllers.yaml", tuned)
    assert params_hash(parse_params(params.document(), tuned=tmp_path / "controllers.yaml")) != base
