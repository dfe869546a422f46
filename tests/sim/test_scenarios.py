"""Scenario command profiles (params `scenarios`) and their phases, checked against a motion that
follows them."""

import numpy as np
import pytest

from ingest.bouts import PelvisPath
from ingest.phases import motion_phases
from sim.errors import SimulationError
from sim.rollout.scenarios import Segment, command_profile, measured_phases, phase_agreement

RATE = 100.0
V = 1.5  # preferred speed, m/s


@pytest.fixture(scope="module")
def profiles(params):
    p = params.scenarios.profile
    return {name: command_profile(name, segs, V, RATE, p) for name, segs in params.scenarios.build().items()}


def test_every_named_scenario_exists(profiles):
    assert set(profiles) >= {"walk_10m", "speed_change", "turn_90", "turnaround_180", "steady"}


def test_walk_10m_is_the_papers_protocol(profiles, params):
    c = profiles["walk_10m"]
    spans = c.spans()
    assert [s[0] for s in spans] == ["standing", "start", "steady", "stop", "standing"]
    assert spans[0][2] == pytest.approx(2.0) and spans[-1][2] - spans[-1][1] == pytest.approx(2.0, abs=0.02)
    steady = c.phase == "steady"
    assert np.sum(c.speed_mps[steady]) / RATE == pytest.approx(10.0, abs=V / RATE + 1e-9)
    assert c.speed_mps[0] == 0.0 and c.speed_mps[-1] == 0.0
    start = [s for s in spans if s[0] == "start"][0]
    assert start[2] - start[1] == pytest.approx(params.scenarios.profile.start_s, abs=0.02)


def test_turns_speed_changes_and_steady(profiles):
    assert profiles["turn_90"].heading_rad[-1] == pytest.approx(np.pi / 2, abs=0.02)
    assert profiles["turnaround_180"].heading_rad[-1] == pytest.approx(np.pi, abs=0.02)
    sc = profiles["speed_change"]
    speeds = [float(np.median(sc.speed_mps[(sc.phase == "steady") & (sc.time_s > a) & (sc.time_s < b)]))
              for a, b in [(s[1], s[2]) for s in sc.spans() if s[0] == "steady"]]
    assert speeds == pytest.approx([V, 0.7 * V, 1.2 * V])
    steady = profiles["steady"]
    assert set(steady.phase) == {"steady"} and np.all(steady.speed_mps == V)


def test_a_lagging_follower_is_labelled_like_its_commands(profiles, params):
    """A pelvis path that follows the commands 0.2 s late with a stride-rate speed oscillation: the
    phases read from its motion agree with the commanded ones."""
    for name, c in profiles.items():
        lag = 20
        speed = np.r_[np.full(lag, c.speed_mps[0]), c.speed_mps[:-lag]] * (1 + 0.03 * np.sin(2 * np.pi * 1.8 *
                                                                                             c.time_s))
        heading = np.r_[np.zeros(lag), c.heading_rad[:-lag]]
        path = PelvisPath(np.zeros((len(speed), 2)), speed, heading, np.zeros(len(speed)), speed > 0.3,
                          np.zeros(len(speed), bool))
        agreement = phase_agreement(c.phase, motion_phases(path, RATE, params.ingest.phases), 30)
        for phase, share in agreement.items():
            assert share >= (0.8 if phase in ("standing", "steady", "turn") else 0.4), (name, agreement)


def test_phases_read_from_a_simulated_pelvis_path(profiles, params):
    """`measured_phases` reads positions (what a rollout records), smoothing them as ingest does: a
    path that follows walk_10m and turn_90 exactly is labelled like its commands."""
    for name in ("walk_10m", "turn_90"):
        c = profiles[name]
        step = c.speed_mps / RATE
        xy = np.cumsum(np.column_stack([step * np.cos(c.heading_rad), step * np.sin(c.heading_rad)]), axis=0)
        agreement = phase_agreement(c.phase, measured_phases(xy, RATE, params.ingest), 50)
        for phase, share in agreement.items():
            assert share >= (0.8 if phase in ("standing", "steady", "turn") else 0.4), (name, agreement)


def test_bad_scenarios_are_refused():
    with pytest.raises(SimulationError, match="exactly one"):
        command_profile("x", [Segment(stand_s=1.0, walk_s=2.0)], V, RATE)
    with pytest.raises(SimulationError, match="stop first"):
        command_profile("x", [Segment(walk_s=2.0), Segment(stand_s=1.0)], V, RATE)
    with pytest.raises(SimulationError, match="walk first"):
        command_profile("x", [Segment(turn_deg=90.0)], V, RATE)
