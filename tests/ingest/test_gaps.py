"""Gap filling on real marker trajectories: gaps cut out of complete data are refilled close to the
truth; long and edge gaps stay missing."""

import numpy as np
import pytest

from ingest.gaps import fill_rigid, fill_short
from ingest.manifest import Manifest
from ingest.readers import read_trc

CAMARGO_TRC = "camargo2021_levelground/MarkerData/levelground_ccw_fast_01_01.trc"


@pytest.fixture(scope="module")
def trc():
    return read_trc(Manifest.load().resolve(CAMARGO_TRC))


def _marker(trc, name):
    return trc.xyz_m[:, list(trc.names).index(name)]


@pytest.mark.parametrize("t0", [5.6, 6.1, 10.5])  # heel in swing, at heel strike, in stance
def test_short_gap_is_refilled_within_a_few_millimetres(trc, t0):
    heel = _marker(trc, "L_Heel")
    i0 = int(np.searchsorted(trc.time_s, t0))
    rows = slice(i0, i0 + 10)  # 50 ms at 200 Hz
    assert np.isfinite(heel[i0 - 2:i0 + 12]).all()
    cut = heel.copy()
    cut[rows] = np.nan
    filled = fill_short(cut, trc.rate_hz, max_gap_s=0.1)
    err = np.linalg.norm(filled[rows] - heel[rows], axis=1)
    assert err.max() < 0.01, err  # < 1 cm over a 50-ms dropout of a heel moving up to ~5 m/s
    assert np.array_equal(filled[~np.isnan(cut).any(axis=1)], heel[~np.isnan(cut).any(axis=1)])


def test_long_and_edge_gaps_stay_missing(trc):
    heel = _marker(trc, "L_Heel").copy()
    heel[1000:1030] = np.nan  # 150 ms > 100 ms limit
    heel[:5] = np.nan  # no sample before: nothing to bridge from
    filled = fill_short(heel, trc.rate_hz, max_gap_s=0.1)
    assert np.isnan(filled[1000:1030]).all() and np.isnan(filled[:5]).all()


def test_rigid_pelvis_fill_rebuilds_a_dropped_marker(trc):
    names = ["L_ASIS", "R_ASIS", "L_PSIS", "R_PSIS"]
    cluster = np.stack([_marker(trc, n) for n in names], axis=1)
    ok = np.flatnonzero(np.isfinite(cluster).all(axis=(1, 2)))
    rows = ok[1500:1540]
    cut = cluster.copy()
    cut[rows, 2] = np.nan
    filled = fill_rigid(cut)
    assert np.linalg.norm(filled[rows, 2] - cluster[rows, 2], axis=1).max() < 0.01
