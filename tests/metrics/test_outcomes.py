"""A rollout's row over the walk itself: `walk_window` from a scenario's real command profile, and
`run_row` leaving out the samples and strides outside it (the tuning objective's window)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from metrics.outcomes import run_row, walk_window
from sim.rollout.scenarios import command_profile

RATE_HZ = 100.0


def _profile(params, name: str):
    return command_profile(name, list(params.scenarios.build()[name]), 1.5, RATE_HZ,
                           params.scenarios.profile)


def test_walk_window_is_between_the_standing_at_either_end(params):
    spans = _profile(params, "walk_10m").spans()
    start, end = walk_window(spans)
    assert spans[0][0] == "standing" and spans[-1][0] == "standing"
    assert start == spans[0][2] and end == spans[-1][1]
    assert 0.0 < start < end < spans[-1][2]
    assert walk_window(_profile(params, "steady").spans()) == (-np.inf, np.inf)  # starts and ends walking


def test_run_row_keeps_only_the_window(params):
    t = np.arange(0.0, 12.0, 1.0 / RATE_HZ)
    locked = t > 11.0  # the arm locks in the final standing
    e_x = np.where(t > 10.0, 0.5, 0.01)  # a large error only after the walk
    robot = pd.DataFrame({"trial": "w", "time_s": t, "e_x_m": e_x, "e_y_m": 0.0, "fall": locked,
                          "locked": locked, "harness_fx_n": 0.0, "harness_fy_n": 0.0, "harness_fz_n": 0.0})
    strides = pd.DataFrame({"kept": [True, True], "t_start_s": [3.0, 9.5], "t_end_s": [4.0, 10.5],
                            "gait_speed_mps": [1.5, 0.2], "stride_length_m": [1.4, 0.3]})
    whole = run_row(robot, strides, fell=False)
    walk = run_row(robot, strides, fell=False, window_s=(2.0, 10.0))
    assert whole["mean_abs_ex_cm"] > 5 * walk["mean_abs_ex_cm"]
    assert np.isclose(walk["mean_abs_ex_cm"], 1.0)
    assert walk["n_samples"] == int(np.sum((t >= 2.0) & (t <= 10.0)))
    assert (walk["n_strides"], walk["gait_speed_mps"]) == (1, 1.5)
