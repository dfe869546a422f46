"""Seeds of a walk from quiet standing: without motor noise every seed is the same rollout (the seed
sets only the start phase, which standing resets), so `rollout.policy_motor_noise` exists to make
them distinct walks; the same seed and noise give the same walk again."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.params import parse_params
from pipeline.runs.jobs import policy_setup, scenario_jobs
from sim.rollout.batch import run_batch

SCENARIO = "short_start"


def _walks(params, camargo_model, policies_root, noise: float, seeds: int) -> list[np.ndarray]:
    doc = params.document()
    doc["rollout"]["policy_motor_noise"] = noise
    doc["scenarios"]["commands"][SCENARIO] = [{"stand_s": 0.5}, {"walk_s": 2.0, "speed": 1.0}]
    p = parse_params(doc)
    setup = policy_setup("camargo", p, camargo_model.parents[1], policies_root)
    outcomes = run_batch(setup, scenario_jobs(p, ("free",), seeds, (SCENARIO,)), 1, "", False)
    return [o.pelvis_xy for o in outcomes]


@pytest.fixture
def committed(policies_root):
    if not (policies_root / "camargo" / "policy.zip").exists():
        pytest.skip("camargo's committed policy is missing")


def test_motor_noise_makes_seeds_distinct_walks(params, camargo_model, policies_root, committed):
    quiet = _walks(params, camargo_model, policies_root, 0.0, 2)
    assert np.array_equal(quiet[0], quiet[1])  # why the noise exists
    noisy = _walks(params, camargo_model, policies_root, 0.1, 2)
    assert not np.array_equal(noisy[0], noisy[1])
    assert np.abs(noisy[0] - quiet[0]).max() > 1e-3  # the noise acts on the walk
    again = _walks(params, camargo_model, policies_root, 0.1, 1)
    assert np.array_equal(again[0], noisy[0])  # a rollout stays a pure function of its job
