"""Metrics against hand-computed values on small known inputs (the stage on the real example
subjects: tests/pipeline/test_metrics_stage.py)."""

import numpy as np
import pandas as pd
import pytest

from metrics.compliance import compliance_table
from metrics.curves import bands_table
from metrics.errors import MetricsError
from metrics.gait import gait_table
from metrics.harness import harness_table
from metrics.rom import rom_table
from metrics.stability import intercycle_sd, stability_table
from metrics.tracking import tracking_table

ID = {"subject": "s1", "source": "sim", "condition": "pid"}


def robot_table(ex_m, ey_m, locked=None, trial="t1", fx=0.0, fy=0.0) -> pd.DataFrame:
    n = len(ex_m)
    df = pd.DataFrame(
        {
            **ID,
            "human_mode": "replay",
            "trial": trial,
            "seed": 0,
            "time_s": np.arange(n) / 100,
            "e_x_m": ex_m,
            "e_y_m": ey_m,
            "fall": False,
            "locked": locked if locked is not None else [False] * n,
        }
    )
    for c in ("harness_fz_n", "harness_tx_nm", "harness_ty_nm", "harness_tz_nm"):
        df[c] = 0.0
    df["harness_fx_n"], df["harness_fy_n"] = fx, fy
    return df


def cycles_table(
    curves: np.ndarray, side: str = "right", joint: str = "knee_flexion", **ident
) -> pd.DataFrame:
    rows = []
    for k, curve in enumerate(curves):
        for pct, value in enumerate(curve):
            rows.append(
                {
                    **ID,
                    "condition": "free",
                    "source": "real",
                    **ident,
                    "trial": "t1",
                    "side": side,
                    "stride": k,
                    "pct": float(pct),
                    "joint": joint,
                    "angle_deg": float(value),
                }
            )
    return pd.DataFrame(rows)


def test_compliance_mean_abs_offsets_in_cm_without_locked_samples():
    robot = robot_table(
        [0.01, -0.03, 0.02, 0.50], [0.0, 0.01, -0.02, 0.50], locked=[False, False, False, True]
    )
    row = compliance_table(robot).iloc[0]
    assert row["mean_abs_ex_cm"] == pytest.approx(2.0)  # (1 + 3 + 2) / 3
    assert row["mean_abs_ey_cm"] == pytest.approx(1.0)  # (0 + 1 + 2) / 3
    assert row["max_abs_ex_cm"] == pytest.approx(3.0)
    assert row["n_samples"] == 3 and row["human_mode"] == "replay"
    assert compliance_table(robot, exclude_locked=False).iloc[0]["mean_abs_ex_cm"] == pytest.approx(14.0)


def test_compliance_groups_conditions_and_counts_falls():
    a = robot_table([0.01, 0.01], [0.0, 0.0])
    b = robot_table([0.04, 0.02], [0.0, 0.0], trial="t2").assign(condition="adaptive", fall=[False, True])
    out = compliance_table(pd.concat([a, b])).set_index("condition")
    assert out.loc["pid", "mean_abs_ex_cm"] == pytest.approx(1.0)
    assert out.loc["adaptive", "mean_abs_ex_cm"] == pytest.approx(3.0)
    assert out.loc["adaptive", "fall_rate"] == 1.0 and out.loc["pid", "fall_rate"] == 0.0


def test_harness_rms_and_peak_of_components_and_magnitude():
    robot = robot_table([0.0] * 4, [0.0] * 4, fx=[3.0, -3.0, 3.0, -3.0], fy=[4.0, 4.0, -4.0, 4.0])
    out = harness_table(robot).set_index("quantity")
    assert out.loc["fx", "rms"] == pytest.approx(3.0) and out.loc["fx", "mean"] == pytest.approx(0.0)
    assert out.loc["f_norm", "rms"] == pytest.approx(5.0) and out.loc["f_norm", "peak"] == pytest.approx(5.0)
    assert out.loc["t_norm", "peak"] == 0.0 and out.loc["tx", "unit"] == "N m"


def test_gait_mean_sd_over_kept_strides_only():
    strides = pd.DataFrame(
        {
            **ID,
            "trial": "t1",
            "side": ["left", "right", "left", "right"],
            "kept": [True, True, True, False],
            "stride_length_m": [1.0, 1.2, 1.4, 9.0],
            "gait_speed_mps": [1.0, 1.1, 1.2, 9.0],
            "stride_time_s": 1.0,
            "cadence_spm": 120.0,
        }
    )
    row = gait_table(strides).iloc[0]
    assert row["n_strides"] == 3
    assert row["stride_length_m_mean"] == pytest.approx(1.2)
    assert row["stride_length_m_sd"] == pytest.approx(0.2)  # sample SD of 1.0, 1.2, 1.4
    assert row["gait_speed_mps_sd"] == pytest.approx(0.1)
    assert row["human_mode"] == "none"  # a real-style table without the column


def test_intercycle_sd_is_the_mean_pointwise_sd():
    base = np.sin(np.linspace(0, 2 * np.pi, 101)) * 30
    assert intercycle_sd(np.stack([base, base + 1, base + 2])) == pytest.approx(1.0)
    # two cycles apart by d have SD d / sqrt(2): 0 in the first half, 2 / sqrt(2) in the second
    half = np.r_[np.zeros(51), np.full(50, 2.0)]
    assert intercycle_sd(np.stack([base, base + half])) == pytest.approx(np.mean(half / np.sqrt(2)))
    assert np.isnan(intercycle_sd(base[None, :]))


def test_stability_pooled_and_per_side():
    base = np.linspace(0, 50, 101)
    cycles = pd.concat(
        [
            cycles_table(np.stack([base, base + 2]), side="right"),
            cycles_table(np.stack([base + 4, base + 6]), side="left"),
        ]
    )
    pooled = stability_table(cycles, pool_sides=True).iloc[0]
    assert pooled["side"] == "both" and pooled["n_cycles"] == 4
    assert pooled["intercycle_sd_deg"] == pytest.approx(np.std([0, 2, 4, 6], ddof=1))
    per_side = stability_table(cycles, pool_sides=False).set_index("side")
    assert per_side.loc["left", "intercycle_sd_deg"] == pytest.approx(np.sqrt(2))
    one = stability_table(cycles_table(base[None, :])).iloc[0]
    assert np.isnan(one["intercycle_sd_deg"]) and "at least 2" in one["note"]


def test_rom_and_bands():
    t = np.linspace(0, 2 * np.pi, 101)
    curves = np.stack([10 + 20 * np.sin(t), 10 + 30 * np.sin(t)])
    row = rom_table(cycles_table(curves)).iloc[0]
    assert row["rom_deg_mean"] == pytest.approx(50.0, abs=0.1)  # (40 + 60) / 2
    assert row["rom_deg_sd"] == pytest.approx(np.std([40, 60], ddof=1), abs=0.1)
    bands = bands_table(cycles_table(curves))
    assert len(bands) == 101 and bands["n_cycles"].eq(2).all()
    assert bands["mean_deg"].to_numpy() == pytest.approx(10 + 25 * np.sin(t))


def test_missing_columns_name_the_table():
    with pytest.raises(MetricsError, match=r"robot table: missing columns \['e_x_m'"):
        compliance_table(robot_table([0.0], [0.0]).drop(columns="e_x_m"))


def test_tracking_trace_takes_the_first_run_at_the_plot_rate():
    n = 201
    robot = pd.concat(
        [
            robot_table(np.linspace(0, 0.1, n), np.zeros(n), fx=3.0, fy=4.0),
            robot_table(np.ones(n), np.ones(n), trial="t0"),
        ]
    )
    robot["time_s"] = np.tile(np.arange(n) / 100, 2)  # 2 s at 100 Hz
    out = tracking_table(robot, rate_hz=10.0)
    assert set(out["trial"]) == {"t0"} and len(out) == 21
    assert out["e_x_cm"].to_numpy() == pytest.approx(np.full(21, 100.0))
    one = tracking_table(robot[robot["trial"] == "t1"], rate_hz=10.0)
    assert one["e_x_cm"].to_numpy() == pytest.approx(np.linspace(0, 10, 21))
    assert one["force_n"].to_numpy() == pytest.approx(np.full(21, 5.0))
