"""Stride selection, spatiotemporal parameters and cycles on the real example subjects."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ingest.manifest import Manifest
from ingest.process import process_subject
from ingest.subject import load_subject

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def camargo(ingest_params):
    return process_subject(load_subject("camargo"), Manifest.load(), ingest_params)


@pytest.fixture(scope="module")
def opencap4(ingest_params):
    return process_subject(load_subject("opencap4"), Manifest.load(), ingest_params)


def _pelvis_speed(subject_id: str):
    """Pelvis horizontal speed straight from the raw file (Y-up), independent of ingest.bouts."""
    from ingest.readers import read_trc

    subject = load_subject(subject_id)
    trc = read_trc(Manifest.load().resolve(subject.trials[0].markers))
    names = list(trc.names)
    idx = [names.index(subject.markerset[r]) for r in ("asis_left", "asis_right", "psis_left",
                                                       "psis_right")]
    xz = np.nanmean(trc.xyz_m[:, idx][..., [0, 2]], axis=1)
    lag = int(0.25 * trc.rate_hz)
    speed = np.full(len(xz), np.nan)
    speed[lag:-lag] = np.linalg.norm(xz[2 * lag:] - xz[:-2 * lag], axis=1) / 0.5
    heading = np.full(len(xz), np.nan)
    d = xz[2 * lag:] - xz[:-2 * lag]
    heading[lag:-lag] = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return trc.time_s, speed, heading


def test_camargo_keeps_at_least_four_steady_strides_per_side(camargo):
    kept = camargo.strides[camargo.strides["kept"]]
    assert kept.groupby("side").size().min() >= 4


def test_camargo_kept_strides_avoid_start_turn_and_stop(camargo):
    time, speed, heading = _pelvis_speed("camargo")
    walking = time[np.nan_to_num(speed) > 1.0]
    start, stop = walking[0], walking[-1]  # quiet standing before, stopping after
    kept = camargo.strides[camargo.strides["kept"]]
    # the 180-degree turn: where the travel direction is more than 45 degrees off both straights
    outbound = np.nanmedian(heading[(time > start) & (time < start + 2.0)])
    off_axis = np.mod(heading - outbound, np.pi)
    turn = (np.minimum(off_axis, np.pi - off_axis) > np.radians(45)) & (time > start) & (time < stop)
    assert 1.0 < (turn.sum() / 200.0) < 3.0  # the turn itself lasts about 2 s
    for row in kept.itertuples():
        inside = (time >= row.t_start_s) & (time <= row.t_end_s)
        assert row.t_start_s > start and row.t_end_s < stop
        assert not (turn & inside).any(), f"stride {row.side} {row.stride} overlaps the turn"
        assert speed[inside].min() > 1.0
    assert set(camargo.strides.loc[~camargo.strides["kept"], "reason"]) >= {"standing", "turn"}


def test_camargo_spatiotemporal_is_fast_walking(camargo):
    kept = camargo.strides[camargo.strides["kept"]]
    assert kept["stride_length_m"].between(1.3, 2.0).all()
    assert kept["gait_speed_mps"].between(1.5, 2.3).all()  # fast walking, 1.80 m tall
    assert kept["stride_time_s"].between(0.75, 1.1).all()
    assert np.allclose(kept["cadence_spm"], 120.0 / kept["stride_time_s"])
    assert np.allclose(kept["gait_speed_mps"], kept["stride_length_m"] / kept["stride_time_s"])
    assert kept["step_width_m"].between(0.0, 0.35).all()


def test_knee_flexion_sign_and_units_on_camargo(camargo):
    """Source file: radians, knee flexion negative. Canonical: degrees, flexion positive."""
    knee = camargo.cycles.query("joint == 'knee_flexion'")
    peaks = knee.groupby(["side", "stride"])["angle_deg"].max()
    assert peaks.between(50, 75).all(), peaks
    swing = knee[knee["pct"].between(60, 80)].groupby(["side", "stride"])["angle_deg"].max()
    assert (swing == peaks).all()  # the peak is in swing, not in stance


def test_cycles_have_101_points_and_four_joints(camargo):
    counts = camargo.cycles.groupby(["side", "stride", "joint"]).size()
    assert (counts == 101).all()
    assert set(camargo.cycles["joint"]) == {"hip_flexion", "knee_flexion", "ankle_dorsiflexion",
                                            "pelvis_tilt"}
    n_kept = int(camargo.strides["kept"].sum())
    assert len(counts) == 4 * n_kept


def test_opencap4_pools_complete_cycles_across_short_walks(opencap4):
    """Each walk is 1.3-1.45 s: a complete heel-strike-to-heel-strike cycle exists only where the
    window happens to hold two heel strikes of one side."""
    strides = opencap4.strides
    assert set(strides["condition"]) <= {"free", "trunk_sway", "toe_in", "toe_out"}
    complete = strides.groupby("trial").size()
    assert 5 <= len(complete) <= 12
    kept = strides[strides["kept"]]
    assert len(kept) >= 5
    knee = opencap4.cycles.query("joint == 'knee_flexion'").groupby(["trial", "side", "stride"])
    assert knee["angle_deg"].max().between(50, 75).all()
    assert kept["gait_speed_mps"].between(0.9, 1.6).all()
    assert opencap4.events["trial"].nunique() == 12


@pytest.fixture(scope="module")
def camargo_signals(ingest_params):
    """Camargo's walk cleaned as `process_trial` does: the inputs of `segment_strides` and its
    kinematic and force-plate events (6 plates: some heel strikes of the walk are on a plate, others
    not)."""
    from ingest.bouts import straight_bouts
    from ingest.canonical import load_trial
    from ingest.events import force_plate_events, kinematic_events
    from ingest.process import PELVIS_ROLES, as_overground, clean_markers, landmarks, trial_path

    subject, p = load_subject("camargo"), ingest_params
    clean, _ = as_overground(clean_markers(load_trial(subject, subject.trials[0], Manifest.load()),
                                           subject.markerset, p), subject.markerset, p)
    lm = landmarks(clean, subject.markerset)
    pelvis = np.mean([lm[r] for r in PELVIS_ROLES], axis=0)
    path = trial_path(lm, clean.rate_hz, p)
    heel = {s: lm[f"heel_{s}"] for s in ("left", "right")}
    toe = {s: lm[f"toe_{s}"] for s in ("left", "right")}
    kin = kinematic_events(heel, toe, pelvis, path.heading_rad, clean.time_s, clean.rate_hz, p.events)
    feet = {s: (heel[s][:, :2] + toe[s][:, :2]) / 2 for s in ("left", "right")}
    force = force_plate_events(clean.plates, feet, clean.time_s, p.events)
    bouts = straight_bouts(path, int(p.bouts.min_bout_s * clean.rate_hz))
    inputs = (clean.time_s, heel, toe, pelvis, path, bouts, p.strides)
    return inputs, kin, force


def _strike_methods(events, strides):
    """The event method at each stride's start and end (None where no heel strike lies there)."""
    hs = events[events["event"] == "heel_strike"]
    out = []
    for side, t0, t1 in zip(strides["side"], strides["t_start_s"], strides["t_end_s"], strict=True):
        at = hs[hs["side"] == side].set_index("time_s")["method"]
        out.append(tuple(at.get(t) for t in (t0, t1)))
    return out


def test_a_stride_mixing_plate_and_kinematic_strikes_is_flagged(camargo_signals, ingest_params):
    """Issue 34 case 5: camargo's real walk has strides from a plate heel strike to a kinematic one.
    Without kinematic strikes to time them on one source they are rejected as mixed; the strides
    whose two strikes share a source are the same row either way."""
    from ingest.events import merge_events
    from ingest.strides import segment_strides

    inputs, kin, force = camargo_signals
    merged = merge_events(kin, force, ingest_params.events.force_window_s)
    flagged = segment_strides(merged, *inputs)
    methods = _strike_methods(merged, flagged)
    mixed = np.array([len(set(m)) > 1 for m in methods])
    assert mixed.sum() >= 3 and (~mixed).sum() >= 3  # both kinds occur in the real walk
    reasons = flagged.loc[mixed, "reason"]  # `events missing` is checked first (module docstring)
    assert set(reasons) == {"mixed event sources (force, kinematic)", "events missing"}
    assert (reasons != "events missing").sum() >= 3 and not flagged.loc[mixed, "kept"].any()
    assert not flagged.loc[~mixed, "reason"].str.startswith("mixed").any()
    retimed = segment_strides(merged, *inputs, kinematic=kin, window_s=ingest_params.events.force_window_s)
    pd.testing.assert_frame_equal(retimed[~mixed], flagged[~mixed])


def test_a_mixed_stride_is_timed_from_the_kinematic_strikes_at_both_ends(camargo_signals, ingest_params):
    """Where the plate strike replaced a kinematic one, the mixed stride takes both kinematic
    strikes: the same row as the kinematic-only stride, so no plate-vs-markers bias enters it (11-28
    ms on camargo). One camargo stride has no kinematic pair within the window and stays flagged."""
    from ingest.events import merge_events
    from ingest.strides import segment_strides

    inputs, kin, force = camargo_signals
    window = ingest_params.events.force_window_s
    merged = merge_events(kin, force, window)
    strides = segment_strides(merged, *inputs, kinematic=kin, window_s=window)
    methods = _strike_methods(merged, strides)
    left = np.array([None not in m and len(set(m)) > 1 for m in methods])  # no kinematic pair found
    assert set(strides.loc[left, "reason"]) <= {"mixed event sources (force, kinematic)", "events missing"}
    assert not strides.loc[left, "kept"].any() and strides["reason"].str.startswith("mixed").sum() <= 1
    retimed = strides[[None in m for m in methods]]  # an end off the merged events: a kinematic strike
    assert len(retimed) >= 3
    kinematic_only = segment_strides(kin, *inputs).set_index(["side", "t_start_s", "t_end_s"])
    for _, row in retimed.iterrows():
        same = kinematic_only.loc[(row["side"], row["t_start_s"], row["t_end_s"])]
        assert same["stride_time_s"] == pytest.approx(row["stride_time_s"])
        assert same["stride_length_m"] == pytest.approx(row["stride_length_m"])
        assert same["kept"] == row["kept"]
