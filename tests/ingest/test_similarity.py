"""A geometrically similar person (ingest/similarity.py): positions, lengths and speeds x k, mass x
k^3, height x k; times, angles, phases and events kept; nothing of the original changed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from ingest.errors import SubjectError
from ingest.process import ProcessedTrial, SubjectTables
from ingest.similarity import scaled_id, scaled_static, scaled_subject, scaled_table, scaled_tables
from ingest.static import StaticTrial
from ingest.subject import FileFormat, Subject
from ingest.treadmill import Treadmill, TreadmillCheck
from ingest.trial import Trial

K = 0.9


def _subject() -> Subject:
    return Subject("p1", 1.70, 70.0, "synthetic", {"heel_left": "LHEE"}, FileFormat(), None)


def _processed() -> ProcessedTrial:
    time_s = np.arange(4) / 100.0
    markers = {"LHEE": np.array([[1.0, 2.0, 0.05]] * 4), "LASI": np.array([[1.1, 2.1, 0.9]] * 4)}
    trial = Trial("p1", "free", "real", "walk1", 100.0, time_s, markers, {"knee_flexion_l": np.full(4, 12.0)})
    events = pd.DataFrame({"trial": ["walk1"], "event": ["heel_strike"], "time_s": [0.01]})
    strides = pd.DataFrame({"trial": ["walk1"], "kept": [True], "t_start_s": [0.0], "stride_length_m": [1.4],
                            "stride_time_s": [1.1], "cadence_spm": [109.0], "gait_speed_mps": [1.3],
                            "step_width_m": [0.12]})
    cycles = pd.DataFrame({"trial": ["walk1"], "pct": [0.0], "angle_deg": [30.0]})
    robot = pd.DataFrame({"trial": ["walk1"], "e_x_m": [0.02], "base_speed_mps": [1.2],
                          "harness_fx_n": [10.0], "harness_tx_nm": [1.0], "time_s": [0.0]})
    treadmill = Treadmill(True, 1.2, True, 0.1, TreadmillCheck(0.05, 0.5, 1.1, 0.1))
    return ProcessedTrial(trial, events, strides, cycles, robot, treadmill, np.array(["walk"] * 4))


def test_subject_height_times_k_mass_times_k_cubed():
    s = _subject()
    out = scaled_subject(s, K)
    assert (out.height_m, out.mass_kg) == pytest.approx((1.70 * K, 70.0 * K**3))
    assert (out.id, out.markerset, out.trials) == (s.id, s.markerset, s.trials)
    assert (s.height_m, s.mass_kg) == (1.70, 70.0)  # the original is not touched
    assert scaled_id("lenhart2015", K) == "lenhart2015_x0.9"


def test_static_markers_times_k_angles_kept():
    static = StaticTrial("p1", {"LHEE": np.array([0.1, 0.2, 0.03])}, {"heel_left": "LHEE"}, "static.trc",
                         {"knee_flexion_l": 5.0})
    out = scaled_static(static, K)
    np.testing.assert_allclose(out.markers["LHEE"], [0.09, 0.18, 0.027])
    assert out.angles_deg == static.angles_deg and out.roles == static.roles
    np.testing.assert_array_equal(static.markers["LHEE"], [0.1, 0.2, 0.03])


def test_trials_and_tables_lengths_and_speeds_times_k_the_rest_kept():
    p = _processed()
    tables = SubjectTables(p.events, p.strides, p.cycles, p.robot, (p,))
    out = scaled_tables(tables, K)
    (q,) = out.trials
    for name, xyz in p.trial.markers.items():
        np.testing.assert_allclose(q.trial.markers[name], xyz * K)
    np.testing.assert_array_equal(q.trial.time_s, p.trial.time_s)
    np.testing.assert_array_equal(q.trial.angles["knee_flexion_l"], p.trial.angles["knee_flexion_l"])
    np.testing.assert_array_equal(q.phases, p.phases)
    assert q.trial.rate_hz == p.trial.rate_hz
    for strides in (out.strides, q.strides):
        row = strides.iloc[0]
        assert (row.stride_length_m, row.gait_speed_mps, row.step_width_m) == pytest.approx(
            (1.4 * K, 1.3 * K, 0.12 * K))
        assert (row.stride_time_s, row.cadence_spm, row.t_start_s, bool(row.kept)) == (1.1, 109.0, 0.0, True)
    pd.testing.assert_frame_equal(out.events, p.events)
    pd.testing.assert_frame_equal(out.cycles, p.cycles)
    robot = out.robot.iloc[0]
    assert (robot.e_x_m, robot.base_speed_mps) == pytest.approx((0.02 * K, 1.2 * K))
    assert (robot.harness_fx_n, robot.harness_tx_nm, robot.time_s) == (10.0, 1.0, 0.0)
    assert q.treadmill.belt_speed_mps == pytest.approx(1.2 * K)
    assert q.treadmill.check.foot_excursion_m == pytest.approx(0.5 * K)
    assert q.treadmill.progression_rad == p.treadmill.progression_rad
    assert p.strides.iloc[0].stride_length_m == 1.4  # the original is not touched


def test_bad_factors_and_bodies_are_refused():
    for k in (0.0, -0.9, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="positive and finite"):
            scaled_table(pd.DataFrame({"x_m": [1.0]}), k)
    with pytest.raises(SubjectError, match="height_m"):
        scaled_subject(dataclasses.replace(_subject(), height_m=0.6), 0.5)  # 0.3 m: no human
