"""evaluate-policy's check rows (metrics/policy_checks.py): each pass flag is its row's comparison of
the measured value with its bound, on hand-built tables whose answers are known."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from metrics.policy_checks import PolicyChecks, bounded, furthest, gait_check, share_row, spm_check, spm_row


def test_bounded_passes_inside_its_closed_interval_and_fails_unmeasured():
    assert bounded("a", 15.0, -15.0, 15.0, "%").passed
    assert not bounded("a", 15.01, -15.0, 15.0, "%").passed
    assert not bounded("a", -15.01, -15.0, 15.0, "%").passed
    assert bounded("a", 1e9, -math.inf, None).passed  # None: open side
    for missing in (None, float("nan"), np.float64("nan")):
        row = bounded("a", missing, 0.0, 1.0)
        assert row.passed is False and row.value is None
    assert bounded("a", np.float64(0.5), 0.0, 1.0).as_dict() == {
        "check": "a", "passed": True, "value": 0.5, "bound": [0.0, 1.0], "unit": ""}


def test_furthest_is_the_walk_that_decides_the_check():
    assert furthest([1.5, 2.2, 1.0], 1.08, 2.0) == 2.2      # 0.2 above beats 0.08 below
    assert furthest([1.5, 2.05, 0.9], 1.08, 2.0) == 0.9     # 0.18 below beats 0.05 above
    assert furthest([1.5, 1.9, 1.2], 1.08, 2.0) == 1.9      # all inside: the one nearest a bound
    assert furthest([0.5, 2.4, 1.0], None, 2.5) == 2.4      # open below: the largest
    assert furthest([1.0, None], None, 2.5) is None and furthest([], None, 2.5) is None
    for values in ([1.5, 2.2, 1.0], [1.5, 1.9, 1.2], [0.9, 1.1]):
        assert bounded("x", furthest(values, 1.08, 2.0), 1.08, 2.0).passed == all(1.08 <= v <= 2.0
                                                                                   for v in values)


@pytest.mark.parametrize(("n_ok", "n", "fraction", "passed"), [
    (9, 10, 0.9, True), (8, 10, 0.9, False), (7, 10, 0.7, True), (10, 10, 1.0, True), (9, 10, 1.0, False),
    (1, 1, 0.9, True), (0, 0, 0.9, False)])
def test_share_row_is_the_share_of_walks_against_the_fraction(n_ok, n, fraction, passed):
    row = share_row("free_no_fall", n_ok, n, fraction)
    assert row.passed is passed and (row.low, row.high) == (fraction, 1.0)
    assert row.value == (n_ok / n if n else None)


def test_spm_check_pass_is_its_row():
    """Judged, not judged (too few real cycles: pass None, value and bound kept) and skipped."""
    base = np.sin(np.linspace(0, 2 * np.pi, 101))[None, :] * 30 + np.zeros((8, 1))
    noisy = base + np.random.default_rng(0).normal(0, 0.5, base.shape)
    shifted = noisy + 15.0
    p = PolicyChecks()
    for a, b, min_a in ((noisy, noisy[::-1] + 0.1, 2), (noisy, shifted, 2), (noisy[:3], shifted, 5),
                        (np.zeros((0, 0)), shifted, 2)):
        result = spm_check(a, b, p, min_a)
        row = spm_row("spm_knee_flexion", result, p)
        assert result["pass"] is row.passed and row.high == p.max_spm_cluster_pct
        if "not_judged" in result:
            assert row.passed is None and row.value == result["longest_cluster_pct"]
        elif result.get("skipped"):
            assert row.value is None and row.passed is False
        else:
            assert row.value == result["longest_cluster_pct"]
            assert row.passed == (row.value <= p.max_spm_cluster_pct)
    assert spm_check(noisy, shifted, p)["pass"] is False


def _strides(speed: float, length: float) -> pd.DataFrame:
    return pd.DataFrame({"gait_speed_mps": [speed] * 4, "stride_length_m": [length] * 4})


def _cycles(knee_peak: float) -> pd.DataFrame:
    pct = np.arange(101.0)
    angle = knee_peak * np.clip((pct - 60) / 15, 0, 1)
    return pd.DataFrame({"trial": "t", "side": "l", "stride": 0, "joint": "knee_flexion", "pct": pct,
                         "angle_deg": angle})


@pytest.mark.parametrize(("sim_speed", "sim_length", "sim_knee"), [
    (1.30, 1.40, 60.0), (1.60, 1.40, 60.0), (1.30, 1.00, 75.0), (1.30, 1.40, 45.0)])
def test_gait_check_flags_are_its_rows(sim_speed, sim_length, sim_knee):
    """Real: 1.3 m/s, 1.4 m, knee peak 60 deg; the rows carry the relative errors and the knee
    difference with +-15 %, +-15 %, +-10 deg."""
    doc, rows = gait_check(_strides(1.3, 1.4), _strides(sim_speed, sim_length), _cycles(60.0),
                           _cycles(sim_knee))
    by = {r.check: r for r in rows}
    assert list(by) == ["free_speed", "free_stride_length", "free_knee_peak"]
    assert [doc["pass_speed"], doc["pass_stride_length"], doc["pass_knee_peak"]] == [r.passed for r in rows]
    assert by["free_speed"].value == doc["gait_speed_mps"]["error_pct"]
    assert by["free_speed"].value == pytest.approx(100 * (sim_speed / 1.3 - 1), abs=0.005)
    assert by["free_knee_peak"].value == pytest.approx(sim_knee - 60.0)
    assert (by["free_stride_length"].low, by["free_stride_length"].high) == (-15.0, 15.0)
    for r in rows:
        assert r.passed == (r.low <= r.value <= r.high)
    no_strides, rows = gait_check(_strides(1.3, 1.4), _strides(1.3, 1.4).iloc[:0], _cycles(60.0),
                                  _cycles(60.0).iloc[:0])
    assert not any(r.passed for r in rows) and all(r.value is None for r in rows)
    assert not no_strides["pass_speed"]
