"""The Butterworth convention stated in ingest/filtering.py, checked on its frequency response
and against a peer's output (Pose2Sim's 'order 4, 6 Hz' filter on its demo trial)."""

from pathlib import Path

import numpy as np
import pytest

from ingest.filtering import lowpass, magnitude_response
from ingest.readers import read_trc

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data"
RATE_HZ = 200.0


def _gain(freq_hz: float, cutoff_hz: float = 12.0, order: int = 4) -> float:
    """Measured amplitude ratio of a long sinusoid through the filter (centre half only)."""
    t = np.arange(0, 20.0, 1 / RATE_HZ)
    x = np.sin(2 * np.pi * freq_hz * t)
    y = lowpass(x, RATE_HZ, cutoff_hz, order)
    mid = slice(len(t) // 4, 3 * len(t) // 4)
    return float(np.sqrt(np.mean(y[mid] ** 2) / np.mean(x[mid] ** 2)))


def test_gain_is_one_half_at_cutoff_for_order_4():
    assert _gain(12.0) == pytest.approx(0.5, abs=2e-3)
    assert magnitude_response(12.0, 4, 12.0, RATE_HZ) == pytest.approx(0.5)


@pytest.mark.parametrize("freq_hz", [1.0, 5.0, 9.6, 12.0, 15.0, 24.0, 40.0])
def test_measured_response_matches_stated_formula(freq_hz):
    expected = magnitude_response(freq_hz, 4, 12.0, RATE_HZ)
    assert _gain(freq_hz) == pytest.approx(expected, abs=3e-3)


def test_minus_3db_point_and_rolloff():
    # -3 dB of a twice-applied 2nd-order filter sits near 0.80 fc (Winter's correction factor)
    freqs = np.linspace(5, 12, 2000)
    f3db = freqs[np.argmin(np.abs(magnitude_response(freqs, 4, 12.0, RATE_HZ) - 1 / np.sqrt(2)))]
    assert f3db / 12.0 == pytest.approx(0.802, abs=0.005)
    assert _gain(1.0) == pytest.approx(1.0, abs=1e-3)
    # 4th order overall: about -80 dB/decade well above the cutoff (bilinear warping aside)
    assert 20 * np.log10(magnitude_response(48.0, 4, 12.0, 1000.0) / magnitude_response(24.0, 4, 12.0, 1000.0)) == pytest.approx(-24.1, abs=1.0)  # noqa: E501


def test_zero_phase():
    t = np.arange(0, 10.0, 1 / RATE_HZ)
    x = np.sin(2 * np.pi * 3.0 * t)
    y = lowpass(x, RATE_HZ, 12.0)
    lag = np.argmax(np.correlate(y[500:1500], x[500:1500], "full")) - 999
    assert lag == 0


def test_reproduces_pose2sim_order4_6hz_output():
    raw = read_trc(SHARED / "pose2sim_demo_markerless/S00_P00_T01_BalancingTrial_0-100.trc")
    ref = read_trc(
        SHARED / "pose2sim_demo_markerless/S00_P00_T01_BalancingTrial_0-100_filt_butterworth.trc"
    )
    ours = lowpass(raw.xyz_m.reshape(raw.xyz_m.shape[0], -1), raw.rate_hz, 6.0, order=4)
    assert np.nanmax(np.abs(ours - ref.xyz_m.reshape(ours.shape))) < 1e-9


def test_nan_runs_stay_and_finite_runs_are_filtered():
    t = np.arange(0, 4.0, 1 / RATE_HZ)
    x = np.sin(2 * np.pi * 2 * t) + 0.2 * np.sin(2 * np.pi * 40 * t)
    x[300:400] = np.nan
    y = lowpass(x, RATE_HZ, 12.0)
    assert np.isnan(y[300:400]).all()
    assert np.isfinite(y[:300]).all() and np.isfinite(y[400:]).all()
    clean = np.sin(2 * np.pi * 2 * t)
    assert np.max(np.abs(y[50:250] - clean[50:250])) < 0.02


def test_bad_order_or_cutoff_is_refused():
    with pytest.raises(ValueError, match="even"):
        lowpass(np.zeros(100), RATE_HZ, 12.0, order=3)
    with pytest.raises(ValueError, match="Nyquist"):
        lowpass(np.zeros(100), RATE_HZ, 120.0)
