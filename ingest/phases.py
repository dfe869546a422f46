"""Phases of a walk read from the pelvis motion: standing, start, steady, speed change, turn, stop.

The same labels as the commands of a simulated scenario (`sim.rollout.scenarios`), measured, so a
recording and a simulation are cut the same way and a simulation can be checked against what it
was asked. Per sample of the pelvis path (`ingest.bouts.PelvisPath`, already low-passed):

- `standing`: horizontal pelvis speed below `standing_speed_mps`;
- each run of moving samples has a steady speed, the median speed of its straight samples;
  `start` runs from the run's first sample until the speed first reaches `steady_fraction` of it,
  `stop` from the last sample at that speed to the run's end;
- `turn`: the path turns faster than `turn_rate_deg_s`;
- `speed_change`: |acceleration| above `speed_change_mps2` for at least `min_speed_change_s`
  elsewhere (shorter excursions are the stride-to-stride pace, steady); the rest is `steady`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import with_config

from ingest.bouts import PelvisPath
from ingest.filtering import finite_runs


@with_config(extra="forbid")
@dataclass(frozen=True)
class PhaseParams:
    """The `ingest.phases` section of params.yaml."""

    standing_speed_mps: float = 0.1
    steady_fraction: float = 0.9
    turn_rate_deg_s: float = 20.0
    speed_change_mps2: float = 0.4
    min_speed_change_s: float = 0.3


def motion_phases(path: PelvisPath, rate_hz: float, p: PhaseParams = PhaseParams()) -> np.ndarray:
    """One phase label per sample of `path` (see the module docstring)."""
    speed = np.asarray(path.speed_mps, float)
    heading_rate = np.degrees(np.gradient(path.heading_rad, 1.0 / rate_hz))
    accel = np.gradient(speed, 1.0 / rate_hz)
    moving = speed >= p.standing_speed_mps
    turning = moving & (np.abs(heading_rate) > p.turn_rate_deg_s)
    phase = np.full(len(speed), "standing", dtype=object)
    for a, b in finite_runs(moving):
        seg = slice(a, b)
        straight = ~turning[seg]
        v = speed[seg]
        steady = float(np.median(v[straight])) if straight.any() else float(np.median(v))
        fast = np.flatnonzero(v >= p.steady_fraction * steady)
        changing = np.abs(accel[seg]) > p.speed_change_mps2
        for c0, c1 in finite_runs(changing):
            if (c1 - c0) / rate_hz < p.min_speed_change_s:
                changing[c0:c1] = False
        labels = np.where(changing, "speed_change", "steady").astype(object)
        labels[turning[seg]] = "turn"
        if len(fast):
            labels[:fast[0]] = "start"
            labels[fast[-1] + 1:] = "stop"
        phase[seg] = labels
    return phase.astype(str)


__all__ = ["PhaseParams", "motion_phases"]
