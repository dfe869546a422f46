"""Does the simulated person do what its scenario asked? Checks on the pelvis path of a rollout.

Pure functions of a run's pelvis positions and its command profile (`sim.rollout.scenarios`):
the pelvis speed averaged over one stride (the intra-stride surge cancels), the time from the start
command to 90 % of the walk's steady speed (its own, as for a recording: a walk slower than its
command fails the steady-speed check, not this one), from the stop command to standing (below 0.1 m/s, the
standing threshold of `ingest.phases`), whether it stands still at the end, and the time to reach
each newly commanded speed within a tolerance, and how far the walking direction turned between the
first and the last steady phase. `evaluate-policy` applies them with the thresholds of
`evaluate_policy.scenario_checks`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field, with_config


@with_config(extra="forbid")
@dataclass(frozen=True)
class ScenarioChecks:
    """Pass rules of `evaluate_policy.scenario_checks` in params.yaml (issue 11)."""

    seeds: Annotated[int, Field(ge=1)] = 10                         # walks per scenario and condition
    no_fall_fraction: Annotated[float, Field(ge=0.0, le=1.0)] = 1.0  # 10 of 10 walks without a human fall
    start_tolerance_pct: float = 30.0       # start time vs the subject's own
    start_range_s: tuple[float, float] = (1.0, 3.0)  # when the subject's recordings have no start
    steady_speed_tolerance_pct: float = 10.0  # steady speed vs real free walking
    stop_within_s: float = 2.5              # stop command to standing
    standing_mps: float = 0.1               # ingest.phases' standing threshold
    end_standing_s: float = 1.0             # standing still over the walk's last second
    speed_change_tolerance_pct: float = 10.0
    speed_change_within_s: float = 3.0


def stride_speed(xy: np.ndarray, rate_hz: float, window_s: float) -> np.ndarray:
    """Horizontal pelvis speed (m/s) over a centred window of `window_s` (one stride), per sample;
    the ends use the window that fits."""
    xy = np.asarray(xy, float)
    n = len(xy)
    h = max(1, int(round(window_s * rate_hz / 2)))
    a, b = np.clip(np.arange(n) - h, 0, n - 1), np.clip(np.arange(n) + h, 0, n - 1)
    span = np.maximum(b - a, 1) / rate_hz
    return np.linalg.norm(xy[b] - xy[a], axis=1) / span


def first_time(time_s: np.ndarray, mask: np.ndarray, after_s: float) -> float | None:
    """First time at or after `after_s` where `mask` holds, or None."""
    k = np.flatnonzero(mask & (time_s >= after_s - 1e-9))
    return float(time_s[k[0]]) if len(k) else None


def phase_start(command_time_s: np.ndarray, command_phase: np.ndarray, phase: str,
                nth: int = 0) -> float | None:
    """Start time of the `nth` run of `phase` in a command profile."""
    inside = command_phase == phase
    starts = np.flatnonzero(inside & ~np.r_[False, inside[:-1]])
    return float(command_time_s[starts[nth]]) if len(starts) > nth else None


def start_time_s(time_s: np.ndarray, speed: np.ndarray, command_time_s: np.ndarray,
                 command_speed: np.ndarray, command_phase: np.ndarray, fraction: float = 0.9,
                 steady_mps: float | None = None) -> float | None:
    """Seconds from the start command to `fraction` of the steady speed (None: never): the walk's
    own `steady_mps` when given, as a recording's start is measured (`ingest.phases`: to 0.9 of its
    run's steady speed), else the commanded one."""
    t0 = phase_start(command_time_s, command_phase, "start")
    if t0 is None:
        return None
    v = steady_mps if steady_mps is not None else float(np.max(command_speed[command_phase == "steady"],
                                                                initial=0.0))
    t = first_time(time_s, speed >= fraction * v, t0)
    return None if t is None else t - t0


def motion_onset_s(time_s: np.ndarray, speed: np.ndarray, command_time_s: np.ndarray,
                   command_phase: np.ndarray, standing_mps: float = 0.1) -> float | None:
    """Seconds from the start command until the pelvis leaves standing (speed at or above
    `standing_mps`, the threshold `ingest.phases` starts a recording's start phase at; None: never).
    A recording has no command: its start is measured from this onset, so `start_time_s` minus
    this is the part of a simulated start comparable with a recorded one."""
    t0 = phase_start(command_time_s, command_phase, "start")
    if t0 is None:
        return None
    t = first_time(time_s, speed >= standing_mps, t0)
    return None if t is None else t - t0


def stop_time_s(time_s: np.ndarray, speed: np.ndarray, command_time_s: np.ndarray,
                command_phase: np.ndarray, standing_mps: float = 0.1) -> float | None:
    """Seconds from the stop command to a pelvis speed below `standing_mps` (None: never)."""
    t0 = phase_start(command_time_s, command_phase, "stop")
    if t0 is None:
        return None
    t = first_time(time_s, speed < standing_mps, t0)
    return None if t is None else t - t0


def standing_at_end(time_s: np.ndarray, speed: np.ndarray, last_s: float = 1.0,
                    standing_mps: float = 0.1) -> bool:
    """The pelvis stays below `standing_mps` over the last `last_s` of the run."""
    return bool(np.all(speed[time_s >= time_s[-1] - last_s] < standing_mps))


def speed_changes(time_s: np.ndarray, speed: np.ndarray, command_time_s: np.ndarray,
                  command_speed: np.ndarray, command_phase: np.ndarray, tolerance: float = 0.1
                  ) -> list[dict]:
    """For every `speed_change` command: the new commanded speed and the seconds from the change
    command until the pelvis speed is within `tolerance` of it (None: never)."""
    out = []
    inside = command_phase == "speed_change"
    starts = np.flatnonzero(inside & ~np.r_[False, inside[:-1]])
    ends = np.flatnonzero(inside & ~np.r_[inside[1:], False])
    for a, b in zip(starts, ends, strict=True):
        t0, target = float(command_time_s[a]), float(command_speed[min(b + 1, len(command_speed) - 1)])
        t = first_time(time_s, np.abs(speed - target) <= tolerance * target, t0)
        out.append({"at_s": round(t0, 2), "speed_mps": round(target, 3),
                    "reached_after_s": None if t is None else round(t - t0, 2)})
    return out


def path_turn_deg(xy: np.ndarray, time_s: np.ndarray, command_time_s: np.ndarray,
                  command_phase: np.ndarray, min_travel_m: float = 0.5) -> float | None:
    """How far the walk turned (deg, + left, in (-180, 180]): the direction of the pelvis displacement
    over the last commanded steady phase minus that over the first (None: fewer than two steady
    phases, or one with less than `min_travel_m` of travel, as in a walk that fell)."""
    steady = command_phase == "steady"
    starts = np.flatnonzero(steady & ~np.r_[False, steady[:-1]])
    ends = np.flatnonzero(steady & ~np.r_[steady[1:], False])
    if len(starts) < 2:
        return None
    directions = []
    for a, b in ((starts[0], ends[0]), (starts[-1], ends[-1])):
        i, j = np.searchsorted(time_s, [command_time_s[a], command_time_s[b]])
        d = xy[min(j, len(xy) - 1)] - xy[min(i, len(xy) - 1)]
        if math.hypot(d[0], d[1]) < min_travel_m:
            return None
        directions.append(math.atan2(d[1], d[0]))
    turn = math.degrees(directions[1] - directions[0])
    return turn - 360.0 * math.ceil((turn - 180.0) / 360.0)


__all__ = ["ScenarioChecks", "first_time", "path_turn_deg", "phase_start", "speed_changes", "standing_at_end",
           "start_time_s", "stop_time_s", "stride_speed"]
