"""The universal policy's adoption rule (pipeline/commands/adoption.py): `decide` on hand-made gate
results, and `adopt-universal` on the committed checkpoint and one real body (MuJoCo rollouts)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from pipeline.cli import main
from pipeline.commands.adoption import decide, gate_rule
from pipeline.paths import ADOPTION_FILE, policy_dir
from pipeline.runs.gate import SCENARIO_PREFIX, universal_required
from pipeline.runs.gate_record import EVALUATION_FILE, source_evaluation
from sim.learn.train import NORM_FILE, POLICY_FILE, PROGRESS_FILE

REPO = Path(__file__).resolve().parents[2]
SUBJECT = "lenhart2015"   # judged against a policies folder without its policy: adopts on its gate alone


def verdict(passed: bool, failed: list[str] | None = None) -> dict:
    return {"pass": passed, "failed": failed or []}


def evaluation(n_passed: int, n_checks: int = 29, walks: int = 10) -> dict:
    return {"checks": {f"check_{i}": i < n_passed for i in range(n_checks)}, "free": {"rollouts": walks}}


def test_a_subject_without_a_committed_policy_adopts_on_its_gate():
    assert gate_rule(verdict(True), evaluation(5), None)["adopt"] is True  # few checks, but the gate passed
    rec = gate_rule(verdict(False, ["scenario_turn_90_free_no_fall"]), evaluation(28), None)
    assert rec["adopt"] is False and rec["failed_required"] == ["scenario_turn_90_free_no_fall"]
    assert rec["checks_passed"] == 28 and rec["checks"] == 29


def test_a_committed_policy_is_replaced_only_by_as_many_checks():
    assert gate_rule(verdict(True), evaluation(21), evaluation(22))["adopt"] is False  # gate passed, 1 fewer
    rec = gate_rule(verdict(False), evaluation(22), evaluation(22))
    assert rec["adopt"] is True and rec["committed_checks_passed"] == 22


def test_an_adoption_is_confirmed_with_evaluate_policys_own_walks():
    """The amendment of 2026-11-28: a 2-walk pass adopts only when 10 walks pass it too (kgc6's
    case: its gate passed at 2 walks, and 10 walks found required checks failing)."""
    two, ten = evaluation(26, walks=2), evaluation(10, walks=10)
    assert decide(verdict(True), two, None)["adopt"] is False  # no confirmation run: not adopted
    rec = decide(verdict(True), two, None, (ten, verdict(False, ["scenario_push_free_recovered"])))
    assert rec["adopt"] is False and rec["confirmation"]["walks"] == 10 and rec["walks"] == 2
    assert rec["confirmation"]["failed_required"] == ["scenario_push_free_recovered"]
    assert decide(verdict(True), two, None, (ten, verdict(True)))["adopt"] is True
    committed, no = evaluation(22), verdict(False)  # a committed policy: counted at 10 walks on both sides
    assert decide(no, evaluation(23), committed, (evaluation(21), no))["adopt"] is False
    assert decide(no, evaluation(23), committed, (evaluation(22), no))["adopt"] is True
    assert "confirmation" not in decide(verdict(True), evaluation(3), committed, (ten, verdict(True)))


def test_the_gate_requires_what_the_runs_source_passes(params, policies_root):
    required = universal_required(params, policies_root)
    checks = source_evaluation(policy_dir(policies_root, params.universal.init_from))["checks"]
    assert required == {k for k, ok in checks.items() if k.startswith(SCENARIO_PREFIX) and ok}
    assert required and not any(k.startswith("scenario_turnaround") for k in required)  # camargo fails those


@pytest.fixture(scope="module")
def processed(tmp_path_factory, params) -> Path:
    """ingest, scale and reference of SUBJECT, as `dvc repro` makes them, in a temporary root."""
    from pipeline.stages.ingest import run_ingest
    from pipeline.stages.reference import run_reference
    from pipeline.stages.scale import run_scale

    root, reports = tmp_path_factory.mktemp("processed"), tmp_path_factory.mktemp("reports")
    run_ingest(SUBJECT, params, root, progress=False)
    run_scale(SUBJECT, params, root, reports)
    run_reference(SUBJECT, params, root, reports, progress=False)
    return root


def test_adopt_universal_judges_the_checkpoint_and_records_it(processed, tmp_path, capsys, params,
                                                             policies_root):
    universal, policies = tmp_path / "universal", tmp_path / "policies"
    universal.mkdir()
    for f in (POLICY_FILE, NORM_FILE, PROGRESS_FILE):
        shutil.copy(REPO / "data" / "universal" / f, universal / f)
    source = params.universal.init_from  # the run's source: its evaluation gives the required checks
    policy_dir(policies, source).mkdir(parents=True)
    shutil.copy(policy_dir(policies_root, source) / EVALUATION_FILE, policy_dir(policies, source))
    assert main(["adopt-universal", SUBJECT, "--universal", str(universal), "--root", str(processed),
                 "--policy-root", str(policies), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    rec = doc["subjects"][SUBJECT]
    assert doc["universal_steps"] == json.loads((universal / PROGRESS_FILE).read_text())["steps"]
    assert rec["checks"] >= 20 and rec["checks_passed"] == len(rec["passed"])
    assert (SUBJECT in doc["adopted"]) == rec["adopt"] and rec["walks"] == doc["gate_seeds"]
    assert rec["gate_pass"] == (not rec["failed_required"]) and "committed_checks_passed" not in rec
    assert doc["required"] == sorted(universal_required(params, policies_root))
    if rec["gate_pass"]:  # confirmed with evaluate-policy's own walks before it adopts
        assert rec["confirmation"]["walks"] == doc["confirm_seeds"]
        assert rec["adopt"] == rec["confirmation"]["gate_pass"]
    else:
        assert not rec["adopt"] and "confirmation" not in rec
    assert set(rec["failed_required"]) <= set(doc["required"])
    record = json.loads((universal / ADOPTION_FILE).read_text())
    assert record["evaluations"][-1]["subjects"] == doc["subjects"] and record["adopted"] == doc["adopted"]
    how = record["evaluations"][-1]["how"]
    assert str(tmp_path) not in how and "--policy-root <outside>/policies" in how  # no path of this machine
