"""The traces around the commanded events and the seed interval (metrics/phases.py), on small
hand-built robot logs whose expected values are worked out by hand in the comments (the per-phase
table: tests/metrics/test_scenario_checks.py)."""

import numpy as np
import pandas as pd
import pytest

from metrics.phases import EventWindow, event_traces, mean_ci95

T_975_1 = 12.706204736174698  # Student t, 97.5 % quantile, 1 degree of freedom (two runs)
T_975_2 = 4.302652729911275   # 2 degrees of freedom (three values)


def run(condition: str, seed: int, ex_offset_m: float = 0.0, locked_from_s: float = np.inf,
        scenario: str = "walk_10m", first_phase: str = "standing") -> pd.DataFrame:
    """10 Hz log 0 .. 3.9 s: `first_phase` below 1 s, start 1-2 s, steady 2-3 s, stop from 3 s;
    e_x = t + offset (m), e_y = 1 cm, harness force (3, 4, 0) N so |f| = 5 N."""
    t = np.round(np.arange(40) * 0.1, 10)
    phase = np.select([t < 1.0, t < 2.0, t < 3.0], [first_phase, "start", "steady"], "stop")
    return pd.DataFrame({"subject": "s1", "source": "sim", "human_mode": "policy", "condition": condition,
                         "trial": f"{scenario}_{condition}_seed{seed}", "seed": seed, "time_s": t,
                         "e_x_m": t + ex_offset_m, "e_y_m": 0.01, "harness_fx_n": 3.0, "harness_fy_n": 4.0,
                         "harness_fz_n": 0.0, "fall": t >= locked_from_s, "locked": t >= locked_from_s,
                         "scenario": scenario, "phase": phase})


W = EventWindow(names=("start", "turn", "stop"), window_s=(-0.5, 1.0), step_s=0.25)


def test_mean_ci95_student_t_over_finite_values():
    mean, half = mean_ci95(np.array([1.0, 2.0, 3.0]))
    assert float(mean) == 2.0 and float(half) == pytest.approx(T_975_2 * 1.0 / np.sqrt(3))  # SD 1
    mean, half = mean_ci95(np.array([[1.0, 5.0], [np.nan, 7.0], [np.nan, np.nan]]))  # per column
    assert mean.tolist() == [1.0, 6.0] and np.isnan(half[0])  # one value: no interval
    assert half[1] == pytest.approx(T_975_1 * np.sqrt(2) / np.sqrt(2))  # SD of {5, 7} = sqrt(2)
    assert all(np.isnan(v) for v in mean_ci95(np.array([np.nan])))


def test_event_traces_align_runs_on_the_commanded_onset():
    robot = pd.concat([run("pid", 0), run("pid", 1, ex_offset_m=0.02)])
    out = event_traces(robot, W)
    assert W.grid().tolist() == [-0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0]
    # start at 1.0 s and stop at 3.0 s in walk_10m; no turn was commanded, so no turn rows
    assert sorted(set(out["event"])) == ["start", "stop"] and len(out) == 2 * 7
    start = out[out["event"] == "start"].set_index("t_s")
    # e_x at 1.0 + tau s: (100 (1 + tau) + 0) and (+ 2) cm -> mean 100 (1 + tau) + 1, SD sqrt(2)
    for tau in W.grid():
        assert start.loc[tau, "ex_cm_mean"] == pytest.approx(100 * (1 + tau) + 1)
        assert start.loc[tau, "ex_cm_ci95"] == pytest.approx(T_975_1)
    assert start["ey_cm_mean"].tolist() == pytest.approx([1.0] * 7)
    assert start["force_n_mean"].tolist() == pytest.approx([5.0] * 7)
    assert start["force_n_ci95"].tolist() == pytest.approx([0.0] * 7) and (start["n_runs"] == 2).all()
    stop = out[out["event"] == "stop"].set_index("t_s")
    # 3.0 + 1.0 s lies past the last sample (3.9 s): no value there
    assert stop.loc[1.0, "n_runs"] == 0 and np.isnan(stop.loc[1.0, "ex_cm_mean"])
    assert stop.loc[0.75, "ex_cm_mean"] == pytest.approx(376.0)  # 100 x 3.75 + 1


def test_event_traces_leave_out_locked_samples_and_runs_without_an_onset():
    robot = pd.concat([run("adaptive", 0, locked_from_s=3.45),
                       run("adaptive", 1, scenario="steady", first_phase="start")])
    out = event_traces(robot, W)
    # the steady-scenario run begins in `start`: no start onset, but its stop at 3.0 s counts
    assert set(zip(out["scenario"], out["event"], strict=True)) == {
        ("walk_10m", "start"), ("walk_10m", "stop"), ("steady", "stop")}
    stop = out[(out["scenario"] == "walk_10m") & (out["event"] == "stop")].set_index("t_s")
    assert stop.loc[0.25, "ex_cm_mean"] == pytest.approx(325.0) and np.isnan(stop.loc[0.25, "ex_cm_ci95"])
    assert stop.loc[0.5, "n_runs"] == 0  # 3.5 s lies between 3.4 s and the locked 3.5 s sample
    unlocked = event_traces(robot, W, exclude_locked=False)
    assert unlocked.set_index(["scenario", "event", "t_s"]).loc[("walk_10m", "stop", 0.5), "ex_cm_mean"] == (
        pytest.approx(350.0))
    assert event_traces(robot.iloc[0:0], W).empty

