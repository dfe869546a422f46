"""`evaluate-policy` (pipeline/runs/evaluate_policy.py) on a cohort variant: its own policy on its
own body at its own preferred speed, one walk per check (the transfer gate's reduced form)."""

from __future__ import annotations

import pytest

from pipeline.runs.evaluate_policy import evaluate_policy
from pipeline.runs.gate import gate_params


def test_a_cohort_variant_is_evaluated_at_its_own_speed(params, policies_root, camargo_model, tmp_path):
    """The slow variant (preferred 0.6 m/s, camargo 1.87 m/s): every scenario is commanded at its own
    speed and its figure does not overwrite the healthy twin's."""
    if not (policies_root / "camargo" / "cohort" / "slow" / "policy.zip").exists():
        pytest.skip("no committed slow variant")
    doc = evaluate_policy("camargo", gate_params(params, 1), camargo_model.parent.parent, policies_root,
                          tmp_path, progress=False, variant="slow")
    assert doc["variant"] == "slow" and doc["figure"].endswith("policy_spm_slow.png")
    steady = doc["scenarios"]["steady free"]
    assert steady["walks"] == 1
    # 20 s of steady walking: ~12 m at 0.6 m/s, ~37 m at the healthy twin's speed
    assert max(doc["free"]["distance_m"]) < 20.0
    assert set(doc["checks"]) >= {"free_no_fall", "scenario_walk_10m_free_no_fall"}


def test_a_missing_recording_fails_before_any_rollout(params, policies_root, tmp_path):
    """Without the subject's ingested strides the command stops at once, naming the file, instead of
    after minutes of rollouts."""
    from sim.errors import SimulationError

    with pytest.raises(SimulationError, match="strides.parquet"):
        evaluate_policy("camargo", gate_params(params, 1), tmp_path, policies_root, tmp_path, progress=False)
