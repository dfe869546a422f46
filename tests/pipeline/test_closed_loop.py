"""The closed loop discriminates: with the same steerable policy human, a sluggish PID follows worse
than the tuned one and the human's walking changes beyond seed noise, or the human falls (issue 11;
the sluggish gains are the ones that drove the harness to 690 N RMS in the sanity check quoted
there). The comparison needs the human to walk with the tuned PID, in `steady` (already walking) and
in the paper's protocol `walk_10m`. Only the walk itself counts (`metrics.outcomes.walk_window`):
the quiet standing before and after it says nothing about the following gains (the adaptive
controller's behaviour there has its own test below)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from metrics.outcomes import walk_window
from metrics.scenario_checks import stride_speed
from pipeline.runs.jobs import policy_setup, scenario_jobs, scenario_profiles
from sim.learn.train import load_body
from sim.rollout.batch import RolloutOutcome, run_batch

SLUGGISH_GAINS = {"kp_x": 1.0, "ki_x": 0.5}
WALKS = 3


def _mean_se(x: list[float]) -> tuple[float, float]:
    a = np.asarray(x, float)
    return float(a.mean()), float(a.std(ddof=1) / np.sqrt(len(a)))


def _fell_walking(o: RolloutOutcome, walk_end_s: float) -> bool:
    """The human fell, or the arm locked on a fall, before the walk's final standing (or the
    simulation went unstable)."""
    return not o.stable or (o.first_fall_s is not None and o.first_fall_s <= walk_end_s)


@pytest.mark.parametrize("scenario", ["steady", "walk_10m"])
def test_sluggish_pid_is_told_apart_from_the_tuned_one(params, camargo_model, policies_root, scenario):
    setup = policy_setup("camargo", params, camargo_model.parents[1], policies_root)
    src = setup.drivers
    cycle = load_body(src.policy_dir)[1]
    commands = scenario_profiles(params, src.env.variant.preferred_speed(cycle.speed_mps), src.sample_rate_hz)
    start_s, end_s = walk_window(commands[scenario].spans())
    pid = setup.controllers["pid"]
    sluggish = {**pid, "gains": {**pid["gains"], **SLUGGISH_GAINS}}
    setup = replace(setup, controllers={**setup.controllers, "sluggish": sluggish})
    outcomes = run_batch(setup, scenario_jobs(params, ("pid", "sluggish"), WALKS, (scenario,)), 1, "", False)
    by = {c: [o for o in outcomes if o.job.condition == c] for c in ("pid", "sluggish")}
    assert not any(_fell_walking(o, end_s) for o in by["pid"]), "the human must walk with the tuned PID"
    lo = max(start_s, 2.0)  # the walk itself, never the first 2 s (the robot's start)
    walking = {c: [o.robot[(o.robot["time_s"] > lo) & (o.robot["time_s"] <= end_s)] for o in runs]
               for c, runs in by.items()}
    e_x = {c: [float(np.abs(r["e_x_m"]).mean() * 100) for r in rs] for c, rs in walking.items()}
    assert min(e_x["sluggish"]) > max(e_x["pid"]), e_x

    falls = sum(_fell_walking(o, end_s) for o in by["sluggish"])
    stride_s = 1.0
    speed = {c: [float(np.median(stride_speed(o.pelvis_xy, o.sample_rate_hz, stride_s)[
        int(4.0 * o.sample_rate_hz):int(8.0 * o.sample_rate_hz)])) for o in runs
        if not _fell_walking(o, end_s)] for c, runs in by.items()}
    changed = False
    if len(speed["sluggish"]) >= 2 and len(speed["pid"]) >= 2:
        (m_s, se_s), (m_t, se_t) = _mean_se(speed["sluggish"]), _mean_se(speed["pid"])
        changed = abs(m_s - m_t) > 2 * np.hypot(se_s, se_t)
    assert falls > 0 or changed, (speed, falls)


def test_adaptive_base_keeps_still_while_the_human_stands(params, camargo_model, policies_root):
    """After walk_10m's stop the person stands; the adaptive controller's heading must not follow the
    deceleration or the sway of a standing user (sim/robot/controllers/adaptive.py): before that was
    fixed its base spun at up to 1.45 rad/s, backed up at 0.45 m/s and drove the arm to its lateral
    stop (0.20 m, 330 N on the pelvis) behind the standing human."""
    setup = policy_setup("camargo", params, camargo_model.parents[1], policies_root)
    src = setup.drivers
    cycle = load_body(src.policy_dir)[1]
    commands = scenario_profiles(params, src.env.variant.preferred_speed(cycle.speed_mps), src.sample_rate_hz)
    stand_s = [a for phase, a, _ in commands["walk_10m"].spans() if phase == "standing"][-1]
    outcomes = run_batch(setup, scenario_jobs(params, ("adaptive",), 2, ("walk_10m",)), 1, "", False)
    for o in outcomes:
        r = o.robot[o.robot["time_s"] >= stand_s]
        if o.first_fall_s is not None:
            r = r[r["time_s"] < o.first_fall_s]
        assert len(r) > 50, "the human must stand a while after the stop"
        assert np.abs(r["base_yaw_rate_rps"]).max() < 1.0       # no spin
        assert r["base_speed_mps"].min() > -0.25                # no backing away
        assert np.abs(r["e_y_m"]).max() < 0.5 * params.robot.arm.range_m[1]  # the arm far from its stop
