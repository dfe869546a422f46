"""`python -m pipeline tune`: a tiny real search on camargo's policy human, and the clear errors."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import pytest

from ingest.errors import GaitloopError
from pipeline import paths
from pipeline.params import Params, checked, load_params, parse_params
from pipeline.runs.tune import run_tune
from pipeline.store.records import TUNING_COLUMNS

N_TRIALS = 3


@pytest.fixture(scope="module")
def tiny() -> Params:
    """One short steady walk per trial (seed 0) and one held back (seed 100)."""
    doc = load_params().document()
    doc["tune"].update(scenarios=["steady"], seeds=[0], heldout_seeds=[100])
    doc["scenarios"]["commands"]["steady"] = [{"walk_s": 4.0, "speed": 1.0}]
    return checked(parse_params(doc))


def _has_policy(subject: str) -> bool:
    return (paths.policy_dir(paths.POLICIES_ROOT, subject) / "policy.zip").is_file()


@pytest.mark.skipif(not _has_policy("camargo"), reason="camargo's trained policy is not here")
def test_tune_writes_a_bounded_result(tiny: Params, tmp_path: Path) -> None:
    path = run_tune("camargo", "pid", tiny, n_trials=N_TRIALS, out_root=tmp_path, progress=False)
    assert path == paths.tuning_file(tmp_path, "camargo", "healthy", "pid")
    doc = json.loads(path.read_text())
    extra = ["scenarios", "seeds", "heldout_seeds", "history", "wall_s", "free_speed_mps"]
    assert set(TUNING_COLUMNS + extra) <= set(doc)
    head = (doc["subject"], doc["variant"], doc["controller"], doc["n_trials"])
    assert head == ("camargo", "healthy", "pid", N_TRIALS)
    assert [h["trial"] for h in doc["history"]] == list(range(N_TRIALS))
    assert doc["history"][0]["gains"] == {g: doc["generic_gains"][g] for g in tiny.tune.search["pid"]}
    space = tiny.tune.search["pid"]
    assert set(doc["tuned_gains"]) == set(doc["generic_gains"])  # unsearched constants (i_max) kept
    assert doc["tuned_gains"]["i_max"] == doc["generic_gains"]["i_max"]
    for gain, (lo, hi) in space.items():
        assert lo <= doc["tuned_gains"][gain] <= hi
    assert doc["search_best_objective"] == min(h["objective"] for h in doc["history"])
    assert doc["n_heldout"] == 1
    for key in ("generic_mean", "tuned_mean", "search_best_objective", "free_speed_mps"):
        assert math.isfinite(doc[key])
    assert doc["generic_ci95"] is None and doc["tuned_ci95"] is None  # one held-back rollout: no CI
    assert doc["generic_falls"] in (0, 1) and doc["tuned_falls"] in (0, 1)
    # which policy the gains were tuned on: a tuning of an earlier policy can be told apart
    policy = paths.policy_dir(paths.POLICIES_ROOT, "camargo") / "policy.zip"
    assert doc["policy_sha256_16"] == hashlib.sha256(policy.read_bytes()).hexdigest()[:16]


def test_controller_without_search_space(tiny: Params, tmp_path: Path) -> None:
    with pytest.raises(GaitloopError, match="no search space for controller 'bang_bang'.*adaptive, pid"):
        run_tune("camargo", "bang_bang", tiny, out_root=tmp_path, progress=False)


def test_unknown_variant(tiny: Params, tmp_path: Path) -> None:
    with pytest.raises(GaitloopError, match="cohort.variants: no variant 'stroke' \\(healthy, weak"):
        run_tune("camargo", "pid", tiny, variant="stroke", out_root=tmp_path, progress=False)


def test_unknown_subject(tiny: Params, tmp_path: Path) -> None:
    with pytest.raises(GaitloopError, match="no trained policy"):
        run_tune("nobody", "pid", tiny, out_root=tmp_path, progress=False)
