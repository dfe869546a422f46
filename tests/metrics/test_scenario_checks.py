"""Scenario checks on hand-built pelvis paths whose answers are known, and the paper sampling of
simulated strides."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from metrics.phases import mean_ci95, phase_table
from metrics.sampling import paper_strides, repeated_walks, restrict_cycles
from metrics.scenario_checks import (
    motion_onset_s,
    path_turn_deg,
    speed_changes,
    standing_at_end,
    start_time_s,
    stop_time_s,
    stride_speed,
)

RATE = 100.0


def profile(speeds: list[tuple[str, float, float]]):
    """(phase, seconds, speed at its end) pieces -> command time, speed (linear ramps), phase."""
    t, v, ph = [0.0], [0.0], ["standing"]
    for phase, dur, end in speeds:
        n = int(round(dur * RATE))
        t += list(t[-1] + np.arange(1, n + 1) / RATE)
        v += list(np.linspace(v[-1], end, n + 1)[1:])
        ph += [phase] * n
    return np.array(t), np.array(v), np.array(ph)


def test_start_stop_and_standing_times_on_a_known_path():
    t, v, ph = profile([("standing", 2.0, 0.0), ("start", 1.0, 1.5), ("steady", 4.0, 1.5),
                        ("stop", 1.0, 0.0), ("standing", 2.0, 0.0)])
    delayed = np.interp(t - 0.5, t, v)  # the body follows its command 0.5 s late
    xy = np.column_stack([np.cumsum(delayed) / RATE, np.zeros_like(t)])
    speed = stride_speed(xy, RATE, 0.02)
    assert speed[500] == pytest.approx(1.5, rel=0.02)
    # 90 % of 1.5 m/s: 0.9 s into the linear ramp, plus the 0.5 s delay
    assert start_time_s(t, speed, t, v, ph) == pytest.approx(1.4, abs=0.03)
    # a walk 15 % slower than its command never reaches 90 % of the command, but its own start
    # (to 90 % of its own steady speed, as a recording's is measured) has the same length
    slow = 0.85 * speed
    assert start_time_s(t, slow, t, v, ph) is None
    assert start_time_s(t, slow, t, v, ph, steady_mps=float(np.median(slow[400:700]))) == pytest.approx(
        1.4, abs=0.03)
    # leaving standing (0.1 m/s): 0.1 / 1.5 of the ramp up, plus the delay; the start from there on
    onset = motion_onset_s(t, speed, t, ph)
    assert onset == pytest.approx(0.5 + 0.1 / 1.5, abs=0.03)
    assert start_time_s(t, speed, t, v, ph) - onset == pytest.approx(0.9 - 0.1 / 1.5, abs=0.03)
    # below 0.1 m/s: 1 - 0.1 / 1.5 of the ramp down, plus the delay
    assert stop_time_s(t, speed, t, ph) == pytest.approx(0.5 + 1 - 0.1 / 1.5, abs=0.03)
    assert standing_at_end(t, speed) and not standing_at_end(t[:600], speed[:600])


def test_speed_change_times_and_a_change_never_reached():
    t, v, ph = profile([("steady", 2.0, 1.0), ("speed_change", 1.0, 0.7), ("steady", 3.0, 0.7),
                        ("speed_change", 1.0, 1.2), ("steady", 3.0, 1.2)])
    v[0] = 1.0
    out = speed_changes(t, v, t, v, ph, 0.1)
    assert [c["speed_mps"] for c in out] == [0.7, 1.2]
    assert out[0]["reached_after_s"] == pytest.approx((1.0 - 0.77) / 0.3, abs=0.02)  # 1.0 -> 0.7 in 1 s
    capped = np.minimum(v, 1.0)  # never speeds up to 1.2
    assert speed_changes(t, capped, t, v, ph, 0.1)[1]["reached_after_s"] is None


def test_path_turn_is_the_change_of_walking_direction_between_steady_phases():
    """A walk that turns left by 90 deg (and one that turns around) between its steady phases; one
    that turned only half as far; and a walk that stopped moving (fell) before its last steady phase."""
    t = np.arange(0.0, 9.0, 1 / RATE)
    ph = np.where(t < 3.0, "steady", np.where(t < 5.0, "turn", "steady"))

    def path(turn_deg: float) -> np.ndarray:
        heading = np.radians(turn_deg) * np.clip((t - 3.0) / 2.0, 0.0, 1.0)
        return np.column_stack([np.cumsum(np.cos(heading)), np.cumsum(np.sin(heading))]) * 1.2 / RATE

    assert path_turn_deg(path(90.0), t, t, ph) == pytest.approx(90.0, abs=0.5)
    assert path_turn_deg(path(-45.0), t, t, ph) == pytest.approx(-45.0, abs=0.5)
    assert abs(path_turn_deg(path(180.0), t, t, ph)) == pytest.approx(180.0, abs=0.5)
    stopped = path(90.0)
    stopped[t >= 4.0] = stopped[int(4.0 * RATE)]
    assert path_turn_deg(stopped, t, t, ph) is None
    assert path_turn_deg(path(90.0), t, t, np.full(len(t), "steady")) is None


def test_stride_speed_cancels_the_intra_stride_surge():
    t = np.arange(0, 10, 1 / RATE)
    x = 1.4 * t + 0.05 * np.sin(2 * np.pi * t / 1.1)  # 1.1-s stride surge
    speed = stride_speed(np.column_stack([x, 0 * x]), RATE, 1.1)
    assert np.abs(speed[100:-100] - 1.4).max() < 0.005


def test_phase_table_means_runs_with_a_seed_interval():
    rows = []
    for seed, ex in enumerate([0.01, 0.02, 0.03]):
        for k in range(10):
            rows.append({"subject": "s", "source": "sim", "human_mode": "policy", "condition": "pid",
                         "scenario": "walk_10m", "phase": "start" if k < 5 else "steady",
                         "trial": f"walk_10m_pid_seed{seed}", "seed": seed, "time_s": k / 10,
                         "e_x_m": ex if k < 5 else -ex, "e_y_m": 0.0, "harness_fx_n": 3.0,
                         "harness_fy_n": 4.0, "harness_fz_n": 0.0, "fall": False, "locked": False})
    table = phase_table(pd.DataFrame(rows)).set_index("phase")
    assert table.loc["start", "abs_ex_cm_mean"] == pytest.approx(2.0)
    assert table.loc["start", "abs_ex_cm_ci95"] == pytest.approx(4.303 * 1.0 / np.sqrt(3), rel=1e-3)
    assert table.loc["steady", "force_rms_n_mean"] == pytest.approx(5.0)
    assert table.loc["steady", "n_runs"] == 3 and table.loc["steady", "falls"] == 0
    assert np.isnan(mean_ci95(np.array([1.0]))[1])


def test_paper_sampling_takes_the_middle_of_the_steady_phase():
    rows = [{"condition": "pid", "trial": "w", "seed": 0, "side": "right", "stride": i, "kept": True,
             "phase": "steady" if 1 <= i <= 7 else "start", "t_start_s": float(i), "t_end_s": i + 1.0}
            for i in range(9)]
    strides = pd.DataFrame(rows)
    chosen = paper_strides(strides, 4)
    assert chosen["stride"].tolist() == [2, 3, 4, 5]  # nearest the middle (4.5 s); ties to the earlier
    cycles = strides.assign(pct=0.0)[["condition", "trial", "seed", "side", "stride", "pct"]]
    assert sorted(restrict_cycles(cycles, chosen)["stride"]) == sorted(chosen["stride"])


def _walk(condition: str, seed: int, lengths: list[float]) -> list[dict]:
    return [{"condition": condition, "trial": f"w_{condition}_seed{seed}", "seed": seed, "side": "right",
             "stride": i, "kept": True, "phase": "steady", "t_start_s": float(i), "t_end_s": i + 1.0,
             "stride_length_m": length, "stride_time_s": 1.0} for i, length in enumerate(lengths)]


def test_a_walk_repeated_by_another_seed_enters_the_tables_once():
    same = [1.50, 1.52, 1.51, 1.49]
    strides = pd.DataFrame(_walk("free", 0, same) + _walk("free", 1, same) + _walk("free", 2, [1.5] * 4)
                           + _walk("pid", 0, same) + _walk("pid", 1, same[::-1]))
    walks = repeated_walks(strides).set_index(["condition", "seed"])["repeats"]
    assert walks[("free", 1)] == "w_free_seed0"  # the same strides as seed 0
    # pid's seed 0 walks free's seed 0 again, in another condition: not a copy
    assert walks[[("free", 0), ("free", 2), ("pid", 0), ("pid", 1)]].isna().all()
    chosen = paper_strides(strides, 4)
    assert chosen.groupby("condition")["seed"].unique().map(list).to_dict() == {"free": [0, 2], "pid": [0, 1]}
    assert len(chosen) == 16
