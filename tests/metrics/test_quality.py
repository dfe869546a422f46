"""Quality gates (metrics/quality.py): grading, the worst status and each check on small inputs."""

import math

import numpy as np
import pandas as pd
import pytest

from metrics.quality import (
    QUALITY_COLUMNS,
    QualityParams,
    TrialSpan,
    edge_strike_share,
    grade,
    ingest_checks,
    knee_alignment_check,
    missing_sides,
    non_steady_share,
    quality_table,
    scale_checks,
    segment_asymmetry_pct,
    sim_checks,
    speed_gap_pct,
    uncovered_samples,
    worst,
    worst_check,
)
from sim.body.scaling import knee_valgus_deg

P = QualityParams()


def strides(speeds, sides=("left", "right"), condition="free", **extra) -> pd.DataFrame:
    rows = [{"condition": condition, "side": sides[i % len(sides)], "kept": True, "gait_speed_mps": v,
             **extra} for i, v in enumerate(speeds)]
    return pd.DataFrame(rows)


def test_grade_and_worst():
    assert grade(0.01, 0.02, 0.04) == "ok"
    assert grade(0.03, 0.02, 0.04) == "warn"
    assert grade(0.05, 0.02, 0.04) == "fail"
    assert grade(0.02, 0.02, 0.04) == "ok"  # at the threshold is still within it
    assert grade(float("nan"), 0.02, 0.04) == "n/a" and grade(None, 1, 2) == "n/a"
    assert grade(1, 2, 2, higher_is_worse=False) == "fail" and grade(2, 2, 2, higher_is_worse=False) == "ok"
    assert worst(["ok", "warn", "ok"]) == "warn" and worst(["warn", "fail"]) == "fail"
    assert worst(["ok"]) == "ok" and worst([]) == "unknown"
    assert worst(["ok", "n/a"]) == "ok" and worst(["n/a"]) == "unknown"  # n/a is not graded


def test_knee_alignment_is_the_frontal_angle_between_thigh_and_shank():
    """Straight legs read 0; a knee 2 cm medial of the hip-ankle line reads valgus on either side
    (mirrored), lateral reads varus; the gate grades the side furthest from straight."""
    straight = {"hip_l": [0, 0.09, 0.9], "knee_l": [0, 0.09, 0.5], "ankle_l": [0, 0.09, 0.1]}
    assert knee_valgus_deg({k: np.array(v) for k, v in straight.items()}, "l") == pytest.approx(0.0, abs=1e-9)
    jc = {"hip_l": [0, 0.09, 0.9], "knee_l": [0, 0.07, 0.5], "ankle_l": [0, 0.09, 0.1],
          "hip_r": [0, -0.09, 0.9], "knee_r": [0, -0.07, 0.5], "ankle_r": [0, -0.09, 0.1]}
    jc = {k: np.array(v, float) for k, v in jc.items()}
    expected = 2 * np.degrees(np.arctan2(0.02, 0.4))
    assert knee_valgus_deg(jc, "l") == pytest.approx(expected)
    assert knee_valgus_deg(jc, "r") == pytest.approx(expected)
    jc["knee_r"] = np.array([0, -0.11, 0.5])
    assert knee_valgus_deg(jc, "r") == pytest.approx(-expected)  # varus
    row = knee_alignment_check("s", {"l": 3.0, "r": -11.0}, P)
    assert (row.status, row.value) == ("fail", 11.0) and "varus 11.0 deg (r)" in row.note
    assert knee_alignment_check("s", {"l": 6.0, "r": 1.0}, P).status == "warn"
    assert knee_alignment_check("s", None, P).status == "n/a"  # an older model.json without it


def test_scale_checks_grade_marker_rms_and_asymmetry():
    lengths = {"thigh_l": 0.40, "thigh_r": 0.44, "shank_l": 0.40, "shank_r": 0.40}
    pct, seg = segment_asymmetry_pct(lengths)
    assert seg == "thigh" and math.isclose(pct, 200 * 0.04 / 0.84)
    rows = quality_table(scale_checks("s", {"segment_lengths_m": lengths},
                                      {"marker_rms_m": 0.05, "angles": {"knee": {"rms_deg": 3.0}}}, P))
    assert list(rows.columns) == QUALITY_COLUMNS
    status = rows.set_index("check")["status"]
    assert status["segment_asymmetry_pct"] == "warn"  # 9.5 %
    assert status["retarget_marker_rms_m"] == "fail" and status["ik_angle_rms_deg"] == "ok"
    missing = quality_table(scale_checks("s", None, None, P))
    assert set(missing["status"]) == {"n/a"}
    assert missing["cause"].str.startswith("cannot be computed: no ").all()


def test_ingest_checks_edges_spans_and_cycles():
    events = pd.DataFrame({"trial": ["t"] * 4, "event": ["heel_strike"] * 3 + ["toe_off"],
                           "time_s": [0.02, 1.0, 1.97, 0.0]})
    assert math.isclose(edge_strike_share(events, {"t": (0.0, 2.0)}, 0.05), 2 / 3)
    marker_t = np.arange(0, 2.0001, 0.01)
    assert uncovered_samples(marker_t, marker_t) == 0.0
    assert math.isclose(uncovered_samples(marker_t, marker_t[5:]), 5.0)
    cycles = pd.DataFrame({"condition": "free", "trial": "t", "side": ["left"] * 3 + ["right"] * 3,
                           "stride": [0, 0, 1, 0, 0, 0], "pct": [0, 1, 0, 0, 1, 2]})
    spans = [TrialSpan("t", marker_t, marker_t[20:], marker_t)]
    rows = quality_table(ingest_checks("s", events, cycles, spans, 2, P)).set_index("check")
    assert rows.loc["edge_heel_strike_share", "status"] == "fail"
    assert rows.loc["angles_span_samples:t", "status"] == "fail"
    assert rows.loc["grf_span_samples:t", "value"] == 0
    assert tuple(rows.loc["spm_cycles:free:left", ["value", "status"]]) == (2, "ok")
    assert tuple(rows.loc["spm_cycles:free:right", ["value", "status"]]) == (1, "n/a")
    no_raw = quality_table(ingest_checks("s", events, cycles, None, 2, P)).set_index("check")
    assert no_raw.loc["edge_heel_strike_share", "status"] == "n/a"


def test_sim_checks_speed_sides_and_phases():
    real = strides([1.0, 1.0, 1.2, 1.2])  # mean 1.1
    assert math.isclose(speed_gap_pct(real, strides([1.21, 1.21])), 10.0)
    assert missing_sides(real, strides([1.1], sides=("left",))) == 1
    policy = strides([0.77, 0.77], scenario="walk_10m", phase="steady")  # 30 % slow
    assert non_steady_share(policy) == 0.0
    assert non_steady_share(policy.assign(phase=["steady", "start"])) == 0.5
    rows = quality_table(sim_checks("s", real, {"replay": strides([1.1, 1.1]), "policy": policy}, policy, P))
    status = rows.set_index("check")["status"]
    assert status["speed_gap_pct:replay"] == "ok" and status["speed_gap_pct:policy"] == "fail"
    assert status["missing_sides:policy"] == "ok" and status["non_steady_share:policy"] == "ok"
    walks = pd.DataFrame({"condition": ["free"] * 4 + ["pid"] * 4, "trial": [f"w{i}" for i in range(8)],
                          "seed": [0, 1, 2, 3] * 2, "repeats": [None, "w0", "w0", "w0"] + [None] * 4})
    rows = quality_table(sim_checks("s", real, {"policy": policy}, policy, P, walks)).set_index("check")
    assert tuple(rows.loc["repeated_walks:policy", ["value", "status"]]) == (3 / 8, "warn")
    assert "free: 1 of 4, pid: 4 of 4" in rows.loc["repeated_walks:policy", "note"]
    empty = quality_table(sim_checks("s", real, {"replay": pd.DataFrame()}, None, P)).set_index("check")
    assert empty.loc["speed_gap_pct:replay", "status"] == "n/a"
    assert empty.loc["speed_gap_pct:replay", "cause"] == "cannot be computed: no replay simulation"
    ran = quality_table(sim_checks("s", real, {"replay": pd.DataFrame()}, None, P, rollouts={"replay": 27}))
    assert set(ran["cause"]) == {"cannot be computed: its 27 replay rollouts kept no stride"}


def test_every_status_has_its_cause_and_cannot_be_computed_is_not_a_failure():
    """A 4.9 cm marker RMS fails naming its value, the limit and the worst markers; too few cycles for
    SPM and a missing IK file are `n/a` with that reason, not `fail`; `worst_check` names the failure."""
    reference = {"marker_rms_m": 0.049, "angles": {},
                 "trials": {"t1": {"markers_rms_m": {"LTHI": 0.12, "RTHI": 0.11, "LASI": 0.01, "C7": 0.005}},
                            "t2": {"markers_rms_m": {"LTHI": 0.10, "RASI": 0.2}}}}
    model = {"segment_lengths_m": {"thigh_l": 0.40, "thigh_r": 0.40}}
    cycles = pd.DataFrame({"condition": "free", "trial": "t", "side": ["left", "right", "right"],
                           "stride": [0, 0, 1], "pct": 0})
    events = pd.DataFrame({"trial": ["t"], "event": ["heel_strike"], "time_s": [1.0]})
    q = quality_table([*scale_checks("s", model, reference, P),
                       *ingest_checks("s", events, cycles, None, 2, P)]).set_index("check")
    assert q["cause"].str.len().gt(0).all()
    rms = q.loc["retarget_marker_rms_m"]
    assert rms["status"] == "fail" and rms["cause"] == "0.049 above the fail limit 0.04"
    assert rms["note"].endswith("largest: RASI 20.0 cm, LTHI 12.0 cm, RTHI 11.0 cm")
    assert q.loc["ik_angle_rms_deg", "status"] == "n/a"
    assert q.loc["ik_angle_rms_deg", "cause"] == "cannot be computed: no dataset IK angles to compare with"
    left = q.loc["spm_cycles:free:left"]
    assert (left["value"], left["status"]) == (1.0, "n/a")
    assert left["cause"].startswith("too few cycles for SPM: 1 kept, 2 needed")
    assert q.loc["spm_cycles:free:right", "status"] == "ok"
    assert q.loc["segment_asymmetry_pct", "cause"] == "0 at or below the warn limit 5"
    top = worst_check(q.reset_index())
    assert (top["check"], top["status"]) == ("retarget_marker_rms_m", "fail")
    assert worst_check(q.reset_index().query("status == 'n/a'")) is None
