"""`evaluate-policy` (pipeline/runs/evaluate_policy.py) on a cohort variant: its own policy on its
own body at its own preferred speed, one walk per check (the transfer gate's reduced form)."""

from __future__ import annotations

import re

import numpy as np
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
    # one row per check, with the same pass flag, in the same order
    assert [(r["check"], r["passed"]) for r in doc["check_rows"]] == list(doc["checks"].items())
    by = {r["check"]: r for r in doc["check_rows"]}
    assert by["free_no_fall"]["bound"] == [params.evaluate_policy.checks.free_no_fall_fraction, 1.0]
    assert by["free_speed"]["value"] == doc["free"]["gait_speed_mps"]["error_pct"]


def test_a_missing_recording_fails_before_any_rollout(params, policies_root, tmp_path):
    """Without the subject's ingest outputs the command stops at once, naming the file and the command
    that makes it, instead of after minutes of rollouts."""
    from ingest.errors import IngestError

    file = tmp_path / "camargo" / "real" / "events.parquet"
    message = f"{file}: missing: run `python -m pipeline ingest camargo --out-root {tmp_path}` first"
    with pytest.raises(IngestError, match=re.escape(message)):
        evaluate_policy("camargo", gate_params(params, 1), tmp_path, policies_root, tmp_path, progress=False)


def _walk(profile, lag_s: float, scenario: str, condition: str, fall_s: float | None = None):
    """A pelvis that follows the commanded velocity through a first-order lag of `lag_s`, as an
    outcome of the batch runner (the fields `scenario_report` reads)."""
    from types import SimpleNamespace

    dt = float(profile.time_s[1] - profile.time_s[0])
    v = np.zeros(len(profile.time_s))
    for i in range(1, len(v)):
        v[i] = v[i - 1] + (profile.speed_mps[i] - v[i - 1]) * dt / lag_s
    step = np.c_[v * np.cos(profile.heading_rad), v * np.sin(profile.heading_rad)] * dt
    job = SimpleNamespace(condition=condition, human=SimpleNamespace(scenario=scenario))
    return SimpleNamespace(job=job, pelvis_xy=np.cumsum(step, axis=0), sample_rate_hz=1 / dt, stable=True,
                           human_fall_s=fall_s, robot_fall_s=None)


@pytest.mark.parametrize("fallen", [None, "walk_10m", "speed_change"])
def test_scenario_check_rows_are_the_checks(params, fallen):
    """Every scenario's pass flag is its row's comparison: a value inside its bound passes, the
    walk furthest from a bound is the value, and a scenario with a fallen walk has its checks
    unmeasured (value None) and failed. Synthetic pelvis paths, no simulation."""
    from pipeline.runs.evaluate_policy import scenario_report
    from pipeline.runs.jobs import scenario_profiles

    sc = params.evaluate_policy.scenario_checks
    profiles = scenario_profiles(params, 1.3, 100.0)
    outcomes = [_walk(prof, lag, name, cond, 3.0 if (name, cond, lag) == (fallen, "free", 0.5) else None)
                for name, prof in profiles.items() for cond in ("free", "pid") for lag in (0.2, 0.5)]
    doc, rows = scenario_report(outcomes, profiles, 1.1, 1.54, 1.3, sc)
    assert doc["checks"] == {r.check: r.passed for r in rows}
    assert len(rows) == len(doc["checks"]) == 2 * len(profiles) + 5
    for r in rows:
        if r.value is None:
            assert r.passed is False
        else:
            inside = (r.low is None or r.value >= r.low) and (r.high is None or r.value <= r.high)
            assert r.passed == inside, r
    by = {r.check: r for r in rows}
    walk = doc["walk_10m free"]
    lo, hi = 1.54 * 0.7, 1.54 * 1.3
    assert (by["walk_10m_start_time"].low, by["walk_10m_start_time"].high) == pytest.approx((lo, hi))
    assert by["walk_10m_stop_time"].high == sc.stop_within_s
    if fallen == "walk_10m":
        assert by["walk_10m_free_no_fall"].value == 0.5 and not by["walk_10m_free_no_fall"].passed
        assert all(by[c].value is None and by[c].passed is False for c in
                   ("walk_10m_start_time", "walk_10m_stop_time", "walk_10m_steady_speed",
                    "walk_10m_standing_at_end"))
    else:
        assert by["walk_10m_stop_time"].value == pytest.approx(max(walk["stop_s"]), abs=0.006)
        far = max(walk["start_s"], key=lambda x: max(lo - x, x - hi))
        assert by["walk_10m_start_time"].value == pytest.approx(far, abs=0.006)
        assert by["walk_10m_steady_speed"].value == pytest.approx(walk["steady_speed_error_pct"], abs=0.006)
        assert by["walk_10m_standing_at_end"].value == 1.0 and by["walk_10m_standing_at_end"].passed
    reached = by["speed_change_reached"]
    if fallen == "speed_change":
        assert reached.value is None and reached.passed is False
    else:
        after = [c["reached_after_s"] for run in doc["speed_change free"]["speed_changes"] for c in run]
        assert reached.value == max(after) and reached.passed
