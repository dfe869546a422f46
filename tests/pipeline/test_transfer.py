"""transfer@<subject> (pipeline/stages/transfer.py): every subject without a committed policy gets one
fine-tuned from the nearest committed policy, gated by evaluate-policy's scenario checks; a failed
gate leaves replay rows only and `policy` fail rows in the quality table. Real files and MuJoCo,
tiny budgets."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest
import yaml

from metrics.quality import policy_body_checks, transfer_checks
from pipeline.params import PARAMS_FILE, ParamsError, check_params
from pipeline.report import sections
from pipeline.report.render import section_markdown
from pipeline.runs.gate import (
    EVALUATION_FILE,
    GATE_FILE,
    judge,
    read_gate,
    required_checks,
    universal_required,
    usable_policy,
)
from pipeline.runs.report_params import ReportParams
from pipeline.stages.metrics import quality_checks, run_metrics
from pipeline.stages.report import run_report
from pipeline.stages.simulate import run_simulate_policy
from pipeline.stages.store import load_results
from pipeline.stages.transfer import choose_source, policy_features, run_transfer, subject_features
from pipeline.store.connection import StoreParams
from pipeline.store.read import query
from pipeline.store.write import store_results
from sim.learn.pool import UNIVERSAL_OBS_SIZE
from sim.learn.train import (
    BODY_FILE,
    CYCLE_FILE,
    NORM_FILE,
    POLICY_FILE,
    PROGRESS_FILE,
    load_norm,
    policy_env,
)
from sim.learn.transfer import BodyFeatures, FeatureWeights, TransferSection, feature_distance, nearest_policy
from sim.learn.universal import UNIVERSAL_FILE
from sim.rollout.section import RolloutSection

REPO = Path(__file__).resolve().parents[2]
TARGETS = ("lenhart2015", "moissenet_np1023")
POLICY_FILES = (POLICY_FILE, NORM_FILE, BODY_FILE, CYCLE_FILE, PROGRESS_FILE, EVALUATION_FILE)


@pytest.fixture(scope="module")
def processed(tmp_path_factory, params) -> Path:
    """ingest, scale and reference of two bundled subjects that transfer here (into a temporary
    policies root: what data/policies holds for them does not matter) and camargo, as `dvc repro`
    makes them, in a temporary root."""
    from pipeline.stages.ingest import run_ingest
    from pipeline.stages.reference import run_reference
    from pipeline.stages.scale import run_scale

    root, reports = tmp_path_factory.mktemp("processed"), tmp_path_factory.mktemp("reports")
    for s in (*TARGETS, "camargo"):
        run_ingest(s, params, root, progress=False)
        run_scale(s, params, root, reports)
        run_reference(s, params, root, reports, progress=False)
    return root


@pytest.fixture()
def policies(tmp_path, policies_root) -> Path:
    """A copy of the committed policies (the files a transfer reads) in a temporary root."""
    root = tmp_path / "policies"
    for s in ("camargo", "opencap4"):
        (root / s).mkdir(parents=True)
        for f in POLICY_FILES:
            if (policies_root / s / f).is_file():
                shutil.copy(policies_root / s / f, root / s / f)
    return root


# -- params ------------------------------------------------------------------------------------------

def test_transfer_subjects_are_subjects_without_a_committed_policy(params):
    assert set(params.transfer.subjects) <= set(params.subjects) - set(params.train.subjects)
    assert len(set(params.transfer.subjects)) == len(params.transfer.subjects)


def test_adopted_subjects_are_bundled_subjects_without_another_policy(params):
    others = set(params.train.subjects) | set(params.transfer.subjects)
    assert set(params.transfer.adopted) <= set(params.subjects) - others
    assert len(set(params.transfer.adopted)) == len(params.transfer.adopted)


def test_adopted_stage_is_the_transfer_stage_frozen_with_its_outputs_committed():
    """`adopted@<subject>` runs transfer@'s command with its deps and params, but `dvc repro` never
    reruns it (a later checkpoint of the universal run would make another policy) and a fresh clone
    finds its outputs in git."""
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    adopted, transfer = stages["adopted"], stages["transfer"]
    assert adopted["foreach"] == "${transfer.adopted}" and adopted["do"]["frozen"] is True
    assert {k: adopted["do"][k] for k in ("cmd", "deps", "params")} == {
        k: transfer["do"][k] for k in ("cmd", "deps", "params")}
    outs = [*adopted["do"]["outs"], *adopted["do"]["metrics"]]
    assert all(next(iter(o.values())) == {"cache": False} for o in outs)
    assert {next(iter(o)).rsplit("/", 1)[1] for o in outs} >= {*POLICY_FILES, GATE_FILE, UNIVERSAL_FILE}


ADOPTED = yaml.safe_load(PARAMS_FILE.read_text())["transfer"].get("adopted", [])


@pytest.mark.parametrize("subject", ADOPTED)
def test_an_adopted_policy_is_the_export_the_adoption_rule_adopted(subject, policies_root):
    """The committed policy of an adopted subject is the zero-shot export of a universal checkpoint
    that `adopt-universal` judged and adopted (data/universal/adoption.json), and its gate's walks
    are the ones the rule judged: the same checks pass."""
    from pipeline.commands.adoption import passed_checks
    from pipeline.paths import ADOPTION_FILE, UNIVERSAL_DIR

    folder = policies_root / subject
    gate = json.loads((folder / GATE_FILE).read_text())
    assert gate["pass"] and gate["source"] == "universal" and gate["steps"] == 0  # zero-shot
    steps = json.loads((folder / UNIVERSAL_FILE).read_text())["steps"]
    record = json.loads((UNIVERSAL_DIR / ADOPTION_FILE).read_text())
    judged = [e["subjects"][subject] for e in record["evaluations"]
              if e["universal_steps"] == steps and subject in e["adopted"]]
    assert judged, f"no adoption of {subject} at {steps} steps in {ADOPTION_FILE}"
    evaluation = json.loads((folder / EVALUATION_FILE).read_text())
    assert passed_checks(evaluation) == judged[-1]["passed"]


def test_transfer_stage_depends_on_every_committed_policy(params):
    stage = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]["transfer"]
    assert stage["foreach"] == "${transfer.subjects}"
    assert {f"data/policies/{s}" for s in params.train.subjects} <= set(stage["do"]["deps"])


@pytest.mark.parametrize("subject", ["camargo", "opencap4"])
def test_fine_tunes_train_under_the_law_their_source_learned(train_params, policies_root, subject):
    """Transfers and cohort variants fine-tune a committed policy under params' `train` steering law
    (`sim.learn.train.train` records it in the new policy's steering.json, and its rollouts read it
    back); a law other than the one the source was trained under changes the reference under the
    policy's feet (with the law of before, lenhart2015's transfer from opencap4 fell in steady walking)."""
    env = train_params().env
    source = policy_env(policies_root / subject, env)
    fields = ("stride_speed_exponent", "full_gait_fraction", "min_cadence", "turn_lean", "heading_lead_deg")
    assert {f: getattr(source.commands, f) for f in fields} == {f: getattr(env.commands, f) for f in fields}


def test_params_schema_accepts_the_transfer_section(params):
    assert params.transfer.weights == FeatureWeights()
    assert params.transfer.gate in ("source", "all") and params.transfer.gate_seeds >= 1


@pytest.mark.parametrize(("edit", "message"), [
    (lambda t: t.update(gate_seeds=0),
     r"params\.yaml: transfer\.gate_seeds: Input should be greater than or equal to 1 \(got 0\)$"),
    (lambda t: t.update(max_wall_s="long"),
     r"params\.yaml: transfer\.max_wall_s: Input should be a valid number"),
    (lambda t: t.update(gate="some"), r"params\.yaml: transfer\.gate: Input should be 'source' or 'all'"),
    (lambda t: t["weights"].update(sped=1.0), r"params\.yaml: transfer\.weights: unknown key 'sped'$"),
    (lambda t: t.update(weights={"height": 0.0, "mass": 0.0, "leg_length": 0.0, "speed": 0.0}),
     r"params\.yaml: transfer\.weights: at least one weight must be positive"),
    (lambda t: t.update(subjects=["camargo"]),
     r"params\.yaml: transfer\.subjects: 'camargo' has a committed policy \(train\.subjects\)$"),
    (lambda t: t.update(adopted=["camargo"]),
     r"params\.yaml: transfer\.adopted: 'camargo' is also in train\.subjects$"),
    (lambda t: t.update(adopted=["lenhart2015"], subjects=["lenhart2015"]),
     r"params\.yaml: transfer\.adopted: 'lenhart2015' is also in transfer\.subjects$"),
])
def test_bad_transfer_params_name_params_yaml(tmp_path, edit, message):
    document = yaml.safe_load(PARAMS_FILE.read_text())
    edit(document["transfer"])
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    with pytest.raises(ParamsError, match=message):
        check_params(path)


# -- the nearest policy -------------------------------------------------------------------------------

def test_distance_is_the_rms_of_log_ratios():
    a = BodyFeatures(1.7, 70.0, 0.85, 1.3)
    assert feature_distance(a, a) == 0.0
    scaled = BodyFeatures(1.7 * 1.1, 70.0 * 1.1, 0.85 * 1.1, 1.3 * 1.1)
    assert feature_distance(scaled, a) == pytest.approx(math.log(1.1))
    faster = replace(a, speed_mps=1.3 * 1.2)
    assert feature_distance(faster, a) == pytest.approx(math.log(1.2) / 2)  # one of four features
    assert feature_distance(faster, a, FeatureWeights(0.0, 0.0, 0.0, 1.0)) == pytest.approx(math.log(1.2))
    near = nearest_policy(a, {"far": scaled, "near": faster})
    assert near.source == "near" and list(near.distances) == ["near", "far"]


def test_nearest_policy_of_the_bundled_subjects(processed, policies_root, params):
    chosen = {s: choose_source(s, params, processed, policies_root) for s in TARGETS}
    for s, (choice, features) in chosen.items():
        assert set(choice.distances) == {"camargo", "opencap4"}
        assert features[s].height_m == pytest.approx(yaml.safe_load(
            (REPO / "data" / "subjects" / f"{s}.yaml").read_text())["height_m"], rel=0.03)
        # opencap4 (1.68 m, 63 kg, 1.28 m/s) is nearer each of them than camargo (1.80 m, 75 kg, 1.84 m/s)
        assert choice.source == "opencap4", (s, choice.distances)
        assert choice.distances["camargo"] > 2 * choice.distance
    # a subject's own scaled model and the body its committed policy was trained on agree
    own = subject_features("camargo", processed)
    assert feature_distance(own, policy_features(policies_root / "camargo")) < 0.02


# -- the gate -----------------------------------------------------------------------------------------

def test_gate_requires_what_the_source_passes(params):
    source = {"checks": {"free_speed": True, "scenario_steady_free_no_fall": True,
                         "scenario_walk_10m_free_no_fall": False}}
    required = required_checks(params, source)
    assert required == {"scenario_steady_free_no_fall"}
    verdict = judge({"free_speed": False, "scenario_steady_free_no_fall": True,
                     "scenario_walk_10m_free_no_fall": False}, required)
    assert verdict["pass"] and verdict["failed"] == []
    assert verdict["checks"]["scenario_walk_10m_free_no_fall"] == {"pass": False, "required": False}
    assert "free_speed" not in verdict["checks"]  # the gate is the scenario checks
    every = judge({"scenario_steady_free_no_fall": True, "scenario_walk_10m_free_no_fall": None}, None)
    assert not every["pass"] and every["failed"] == ["scenario_walk_10m_free_no_fall"]
    assert not judge({"scenario_steady_free_no_fall": False}, set())["pass"]  # nothing required: no pass


@pytest.mark.parametrize(("gate_first", "verdicts", "budget_s", "totals", "rounds"), [
    (False, [False, False, True], 60.0, [100, 200, 300], 3),        # a pass ends it
    (True, [False, False, True], 60.0, [100, 200], 3),              # zero-shot gate first
    (False, [False] * 9, 60.0, [100, 200, 250], 3),                 # transfer.steps end it
    (True, [False] * 9, 0.0, [], 1),                                # the budget ends it
])
def test_one_loop_chunks_and_gates_until_pass_steps_or_wall(monkeypatch, params, gate_first, verdicts,
                                                             budget_s, totals, rounds):
    """`tune_until_gate`, both routes' loop, with a stand-in chunk and gate: what it asks each chunk
    for and when it stops."""
    from pipeline.stages import transfer as stage

    gates = iter(verdicts)
    monkeypatch.setattr(stage, "run_gate", lambda *a, **k: ({"gate": "doc"}, {"pass": next(gates)}))
    asked: list[tuple[int, float]] = []

    def chunk(total_steps: int, wall_s: float) -> int:
        asked.append((total_steps, wall_s))
        return total_steps

    t = params.transfer.model_copy(update={"steps": 250 if not any(verdicts) else 1000, "chunk_steps": 100})
    p = params.replaced("transfer", TransferSection, t)
    tuned = stage.tune_until_gate("s", p, Path("work"), None, chunk, gate_first=gate_first,
                                  max_wall_s=budget_s)
    assert [a for a, _ in asked] == totals and all(0 < w <= max(budget_s, 1.0) for _, w in asked)
    assert (tuned.rounds, tuned.steps) == (rounds, totals[-1] if totals else 0)
    assert tuned.evaluation == {"gate": "doc"} and tuned.verdict["pass"] == any(verdicts[:rounds])


def test_transfer_stage_writes_the_policy_and_the_gate_record(processed, policies, tmp_path, params):
    subject = "lenhart2015"
    free_only = params.rollout.model_copy(update={"conditions": ("free",)})
    near = params.transfer.model_copy(update={"source": "nearest"})
    fast = params.replaced("rollout", RolloutSection, free_only).replaced("transfer", TransferSection, near)
    rec = run_transfer(subject, fast, processed, policies, tmp_path / "reports", steps=2048, progress=False)
    folder = policies / subject
    for f in (*POLICY_FILES, GATE_FILE):
        assert (folder / f).is_file(), f
    assert not (folder / "amp.pt").exists()  # the discriminator stays out of a subject's folder
    assert [p.name for p in policies.iterdir() if p.name.startswith(".")] == []  # the work folder is gone
    gate = json.loads((folder / GATE_FILE).read_text())
    assert gate == rec == read_gate(folder)
    assert gate["source"] == "opencap4" and gate["distance"] == pytest.approx(gate["distances"]["opencap4"])
    assert gate["steps"] >= 2048 and gate["rounds"] == 1 and gate["wall_s"] + 0.1 >= gate["train_wall_s"] > 0
    assert gate["gate_seeds"] == params.transfer.gate_seeds
    assert isinstance(gate["pass"], bool) and set(gate["failed"]) <= set(gate["checks"])
    assert gate["checks"] and all(k.startswith("scenario_") for k in gate["checks"])
    progress = json.loads((folder / PROGRESS_FILE).read_text())
    assert progress["initialised_from"].endswith("opencap4")
    evaluation = json.loads((folder / EVALUATION_FILE).read_text())
    assert {f"scenario_{k}" for k in evaluation["scenarios"]["checks"]} == set(gate["checks"])
    assert usable_policy(folder) == gate["pass"]

    # a passed gate: simulate_policy uses the policy and its rows go on to the metrics
    (folder / GATE_FILE).write_text(json.dumps({**gate, "pass": True, "failed": []}))
    pid_only = params.rollout.model_copy(update={"conditions": ("pid",)})
    with_pid = params.replaced("rollout", RolloutSection, pid_only)
    summary = run_simulate_policy(subject, with_pid, processed, policies, progress=False)
    assert summary["rollouts"] > 0 and summary["transfer"]["pass"] is True
    assert summary["policy_body"] == {"file": str(folder / "human.xml"), "current_model": True}
    robot = pd.read_parquet(processed / subject / "sim_policy" / "robot.parquet")
    assert not robot.empty and set(robot["human_mode"]) == {"policy"}


def test_universal_source_is_gated_zero_shot_then_fine_tuned_on_the_body(processed, policies, tmp_path,
                                                                          params):
    universal = tmp_path / "universal"
    universal.mkdir()
    for f in (POLICY_FILE, NORM_FILE, "amp.pt", PROGRESS_FILE):
        shutil.copy(REPO / "data" / "universal" / f, universal / f)
    subject = "moissenet_np1023"
    free_only = params.rollout.model_copy(update={"conditions": ("free",)})
    chunks = params.transfer.model_copy(update={"chunk_steps": 2048})
    fast = params.replaced("rollout", RolloutSection, free_only).replaced("transfer", TransferSection, chunks)
    rec = run_transfer(subject, fast, processed, policies, tmp_path / "reports", steps=2048, progress=False,
                       universal_dir=universal)
    folder = policies / subject
    assert rec["source"] == "universal" and rec["gate"] == params.transfer.gate and read_gate(folder) == rec
    required = universal_required(params, policies)  # what the run's source (camargo's policy) passes
    assert required and rec["checks"]
    assert all(c["required"] == (name in required) for name, c in rec["checks"].items())
    # zero-shot first: a pass stops there, a failure fine-tunes one chunk on the body and gates again
    assert (rec["rounds"], rec["steps"] >= 2048) == ((1, False) if rec["pass"] else (2, True))
    progress = json.loads((folder / PROGRESS_FILE).read_text())
    start = json.loads((universal / PROGRESS_FILE).read_text())["steps"]
    assert progress["initialised_from"] == "universal" and progress["initial_steps"] == start
    assert progress["fine_tuned_steps"] == rec["steps"] == progress["steps"] - start
    assert json.loads((folder / UNIVERSAL_FILE).read_text())["universal"] == "universal"
    assert [p.name for p in policies.iterdir() if p.name.startswith(".")] == []  # work folders are gone
    assert usable_policy(folder) == rec["pass"]
    assert load_norm(folder).observation_space.shape == (UNIVERSAL_OBS_SIZE,)


def test_failed_gate_gives_fail_quality_rows_and_no_policy_rows(processed, policies, params, tmp_path):
    subject = "lenhart2015"
    folder = policies / subject
    shutil.copytree(policies / "opencap4", folder)  # a trained policy ...
    checks = {"scenario_steady_free_no_fall": {"pass": False, "required": True},
              "scenario_walk_10m_free_no_fall": {"pass": False, "required": False},
              "scenario_steady_pid_no_fall": {"pass": True, "required": True}}
    gate = {"subject": subject, "source": "opencap4", "distance": 0.025, "steps": 4096, "wall_s": 30.0,
            "gate": "source", "pass": False, "failed": ["scenario_steady_free_no_fall"], "checks": checks}
    (folder / GATE_FILE).write_text(json.dumps(gate))  # ... whose transfer gate failed
    assert not usable_policy(folder) and usable_policy(policies / "opencap4")

    root = processed
    summary = run_simulate_policy(subject, params, root, policies, progress=False)
    assert summary["rollouts"] == 0 and summary["transfer"]["failed"] == gate["failed"]
    assert "failed its transfer gate" in summary["note"]
    for name in ("events", "strides", "cycles", "robot"):
        assert pd.read_parquet(root / subject / "sim_policy" / f"{name}.parquet").empty  # no policy rows

    q = quality_checks(subject, params, root)
    rows = q[q["stage"] == "policy"].set_index("check")
    assert rows.loc["scenario_steady_free_no_fall", "status"] == "fail"
    assert rows.loc["scenario_walk_10m_free_no_fall", "status"] == "warn"  # its source fails it too
    assert rows.loc["scenario_steady_pid_no_fall", "status"] == "ok"
    assert set(rows[rows["status"] == "fail"].index) == set(gate["failed"])
    assert "fine-tuned from opencap4" in rows.loc["scenario_steady_free_no_fall", "note"]
    (line, _) = section_markdown("transfer", sections.transfer(q)).splitlines()
    assert "transfer gate FAILED" in line and "scenario_steady_free_no_fall" in line
    assert "replay rows only" in line

    # through the metrics, store and report stages: fail rows stored, no policy rows, the report says so
    run_metrics(subject, params, root, tmp_path / "metrics")
    db = tmp_path / "results.duckdb"
    store_results(db, [load_results(subject, tmp_path / "metrics")], StoreParams())
    stored = query(db, "SELECT \"check\" FROM quality_latest WHERE stage = 'policy' AND status = 'fail'")
    assert stored["check"].tolist() == gate["failed"]
    modes = query(db, "SELECT DISTINCT human_mode FROM latest_versions")["human_mode"].tolist()
    assert "policy" not in modes
    (report,) = run_report([subject], [subject], db, tmp_path / "reports", False, ReportParams(dpi=40))
    head = report.read_text().split("## Quality gates")[0]
    assert "transfer gate FAILED" in head and "replay rows only" in head


def test_a_universal_gate_row_names_the_checkpoint_and_its_sample():
    gate = {"source": "universal", "universal_steps": 60931328, "steps": 0, "gate_seeds": 2, "pass": True,
            "checks": {"scenario_steady_free_no_fall": {"pass": True, "required": True}}}
    (row,) = transfer_checks("kgc6", gate)
    assert row.status == "ok" and "universal policy at 60931328 steps" in row.note
    assert "2 walks per check" in row.note and "distance" not in row.note


def test_a_policy_on_an_older_body_warns_and_says_so():
    """The policy rolls out on the body it was trained on: when scaling has changed since, its
    rows describe that body, and the quality row says so (warn); on the current model, ok."""
    (stale,) = policy_body_checks("opencap4", {"file": "data/policies/opencap4/human.xml",
                                               "current_model": False})
    assert stale.status == "warn" and stale.value == 0.0
    assert "not the subject's current model" in stale.note and "data/policies/opencap4" in stale.note
    (fresh,) = policy_body_checks("camargo", {"file": "x.xml", "current_model": True})
    assert fresh.status == "ok" and "current model" in fresh.note
    assert policy_body_checks("kgc6", None) == []


def test_no_gate_no_policy_rows():
    assert transfer_checks("camargo", None) == []
    assert sections.transfer(pd.DataFrame(columns=["stage", "check", "status", "note"])) is None


def test_bench_body_is_the_subject_scaled_geometrically(processed, params, tmp_path):
    """The bench's unseen body, made by the stages' own code from the scaled recordings: standing
    height, leg length and speed x k, mass x k^3."""
    from pipeline.bench.transfer import unseen_subject
    from pipeline.stages.ingest import read_ingested

    b = params.transfer.bench
    unseen_subject(b.subject, b.scale, params, processed, tmp_path / "processed", tmp_path / "reports")
    own, scaled = subject_features(b.subject, processed), subject_features(b.subject, tmp_path / "processed")
    k = b.scale
    assert scaled.height_m == pytest.approx(k * own.height_m, rel=0.01)
    assert scaled.mass_kg == pytest.approx(k**3 * own.mass_kg, rel=1e-4)
    assert scaled.leg_length_m == pytest.approx(k * own.leg_length_m, rel=0.01)
    assert scaled.speed_mps == pytest.approx(k * own.speed_mps, rel=0.02)
    real = read_ingested(b.subject, tmp_path / "processed").strides
    assert real["stride_length_m"].to_numpy() == pytest.approx(
        k * read_ingested(b.subject, processed).strides["stride_length_m"].to_numpy())


@pytest.mark.parametrize("route", ["universal", "nearest"])
def test_bench_section_reports_steps_wall_time_and_the_gate(processed, policies, params, tmp_path, route):
    from pipeline.bench.transfer import TRANSFER_TARGETS, time_transfer

    universal = REPO / "data" / "universal" if route == "universal" else tmp_path / "no_universal"
    t = params.transfer.model_copy(update={"steps": 2048, "chunk_steps": 2048})
    tiny = params.replaced("transfer", TransferSection, t).replaced(
        "rollout", RolloutSection, params.rollout.model_copy(update={"conditions": ("free",)}))
    section = time_transfer(tiny, processed, policies, universal, max_wall_s=60.0)
    b = params.transfer.bench
    assert (section["subject"], section["scale"]) == (b.subject, b.scale)
    assert section["body"] == f"{b.subject}_x{b.scale:g}" and section["prepare_wall_s"] > 0
    if route == "universal":
        start = json.loads((universal / PROGRESS_FILE).read_text())["steps"]
        assert (section["source"], section["universal_steps"]) == ("universal", start)
        # zero-shot first: a pass stops there, a failure fine-tunes one chunk and gates again
        assert (section["rounds"], section["steps"] >= 2048) == ((1, False) if section["gate_passed"]
                                                                 else (2, True))
    else:
        assert section["source"] in {"camargo", "opencap4"} and section["gate"] == params.transfer.gate
        assert "no universal policy" in section["note"] and section["universal_steps"] is None
        assert section["rounds"] == 1 and section["steps"] >= 2048  # transfer.steps ends it
    # three times each rounded to 0.1 s: their sum may exceed the total by up to 0.15 s
    assert section["wall_s"] + 0.15 >= section["train_wall_s"] + section["gate_wall_s"] > 0
    assert section["gate_passed"] == (section["failed_checks"] == [])
    assert set(TRANSFER_TARGETS) <= set(section)
