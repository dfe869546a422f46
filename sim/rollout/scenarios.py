"""Scenarios: what the simulated person is asked to do, as a command profile over time.

A scenario (params `scenarios`) is a list of segments: stand for a while, walk a time or a
distance at a fraction of the subject's preferred speed, turn by an angle, stop. `command_profile`
turns it into per-sample commands (speed, heading) and a phase per sample, the label every
simulated trial carries so compliance and harness forces can be read per phase:

- `standing`: commanded speed 0;
- `start`: from rest to the commanded speed over `start_s` (Camargo et al. 2021's level-ground
  trial reaches 1.75 m/s about 1.7 s after leaving quiet standing);
- `steady`: constant speed and heading;
- `speed_change`: from one commanded speed to the next over `speed_change_s`;
- `turn`: heading changing at `turn_rate_deg_s`, at `turn_speed_fraction` of the preferred speed
  (Camargo's 180 deg turn: about 1.4 of 1.9 m/s), entered and left through speed changes;
- `stop`: to rest over `stop_s` (Camargo: 1.86 m/s to standing in about 1.4 s).

Speed transitions follow a raised cosine (zero acceleration at both ends). The phases come from the
commands; `ingest.phases.motion_phases` labels a recorded or simulated motion the same way, so a
simulation can be checked against what it was asked (`phase_agreement`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator, with_config

from ingest.bouts import pelvis_path
from ingest.phases import motion_phases
from ingest.process import IngestParams
from sim.errors import SimulationError

Positive = Annotated[float, Field(gt=0.0)]
PHASES = ("standing", "start", "steady", "speed_change", "turn", "stop")


@with_config(extra="forbid")
@dataclass(frozen=True)
class Segment:
    """One step of a scenario; exactly one of `stand_s`, `walk_s`, `walk_m`, `turn_deg`, `stop`."""

    stand_s: Annotated[float, Field(ge=0.0)] | None = None
    walk_s: Annotated[float, Field(gt=0.0)] | None = None
    walk_m: Annotated[float, Field(gt=0.0)] | None = None  # the steady part's length (m)
    speed: Annotated[float, Field(gt=0.0)] = 1.0  # walking speed, x the subject's preferred speed
    turn_deg: float | None = None  # + left (counter-clockwise), - right
    stop: bool = False

    @property
    def kind(self) -> str:
        kinds = [k for k, v in (("stand", self.stand_s), ("walk", self.walk_s), ("walk", self.walk_m),
                                ("turn", self.turn_deg)) if v is not None] + (["stop"] if self.stop else [])
        if len(kinds) != 1:
            raise SimulationError("scenario segment", f"needs exactly one of stand_s, walk_s, walk_m, "
                                  f"turn_deg, stop (got {self})")
        return kinds[0]


@with_config(extra="forbid")
@dataclass(frozen=True)
class ProfileParams:
    """Transition timing of every scenario (params `scenarios.profile`)."""

    start_s: Positive = 1.7  # rest to the commanded speed (s)
    stop_s: Positive = 1.4  # speed to rest (s)
    speed_change_s: Positive = 1.0  # one commanded speed to the next (s)
    turn_rate_deg_s: Positive = 90.0  # heading rate while turning
    turn_speed_fraction: Positive = 0.75  # speed while turning, x preferred


SCENARIO_NAMES = ("walk_10m", "speed_change", "turn_90", "turnaround_180", "steady")


def _one_kind(segment: Segment) -> Segment:
    try:
        segment.kind  # noqa: B018 (the segment's own check)
    except SimulationError as exc:
        raise ValueError(str(exc)) from None
    return segment


class PaperSampling(BaseModel):
    """How the paper's tables sample the policy human (Wang, Chan et al. ICRA 2025)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    scenario: str  # the scenario the tables come from
    walks: Annotated[int, Field(ge=1)]  # walks (seeds) per condition
    cycles_per_walk: Annotated[int, Field(ge=1)]  # complete cycles per walk and side


class ScenariosSection(BaseModel):
    """The `scenarios` section of params.yaml: each scenario's segments, their shared transition
    timing and how many walks `dvc repro` runs of each."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    paper: PaperSampling
    seeds: Annotated[int, Field(ge=1)]  # walks per condition of every other scenario
    phase_tolerance_s: Annotated[float, Field(ge=0.0)]  # the motion may lag its command this long (s)
    profile: ProfileParams = ProfileParams()
    commands: dict[str, list[Annotated[Segment, AfterValidator(_one_kind)]]]

    @model_validator(mode="after")
    def _named(self) -> ScenariosSection:
        missing = [n for n in SCENARIO_NAMES if n not in self.commands]
        if missing:
            raise ValueError(f"missing scenario(s) {', '.join(missing)} (every subject walks "
                             f"{', '.join(SCENARIO_NAMES)})")
        if self.paper.scenario not in self.commands:
            raise ValueError(f"paper.scenario: no scenario {self.paper.scenario!r} in commands")
        return self

    def walks(self, name: str) -> int:
        """Walks per condition of scenario `name` in `dvc repro`."""
        return self.paper.walks if name == self.paper.scenario else self.seeds

    def build(self) -> dict[str, list[Segment]]:
        """Scenario name -> its segments."""
        return {name: list(segments) for name, segments in self.commands.items()}


@dataclass(frozen=True)
class CommandProfile:
    """Per-sample commands of one scenario: speed (m/s), heading (rad, world yaw), phase label."""

    name: str
    time_s: np.ndarray
    speed_mps: np.ndarray
    heading_rad: np.ndarray
    phase: np.ndarray  # str labels from PHASES

    def spans(self) -> list[tuple[str, float, float]]:
        """(phase, start, end) of each run of one phase, in time order."""
        change = np.flatnonzero(self.phase[1:] != self.phase[:-1]) + 1
        starts, ends = np.r_[0, change], np.r_[change, len(self.phase)] - 1
        return [(str(self.phase[a]), float(self.time_s[a]), float(self.time_s[b])) for a, b in
                zip(starts, ends, strict=True)]


def _ramp(n: int) -> np.ndarray:
    """Raised-cosine 0 -> 1 over n samples (excluding 0, including 1)."""
    x = np.arange(1, n + 1) / n
    return 0.5 - 0.5 * np.cos(np.pi * x)


class _Builder:
    def __init__(self, rate_hz: float) -> None:
        self.dt = 1.0 / rate_hz
        self.speed: list[float] = [0.0]
        self.heading: list[float] = [0.0]
        self.phase: list[str] = ["standing"]

    def add(self, speed: np.ndarray, yaw_rate: np.ndarray, phase: str) -> None:
        heading = self.heading[-1] + np.cumsum(yaw_rate) * self.dt
        self.speed += list(speed)
        self.heading += list(heading)
        self.phase += [phase] * len(speed)

    def change_speed(self, target: float, duration_s: float, phase: str, yaw_rate: float = 0.0) -> None:
        v0 = self.speed[-1]
        n = max(int(round(duration_s / self.dt)), 1)
        self.add(v0 + (target - v0) * _ramp(n), np.full(n, yaw_rate), phase)

    def hold(self, n: int, yaw_rate: float, phase: str) -> None:
        if n > 0:
            self.add(np.full(n, self.speed[-1]), np.full(n, yaw_rate), phase)


def command_profile(name: str, segments: list[Segment], preferred_speed_mps: float, rate_hz: float,
                    p: ProfileParams = ProfileParams()) -> CommandProfile:
    """Per-sample commands of `segments` for a person whose preferred speed is `preferred_speed_mps`,
    heading 0 at t = 0: at rest, or already walking when the first segment is a walk."""
    if preferred_speed_mps <= 0:
        raise SimulationError(name, f"preferred speed must be positive, got {preferred_speed_mps}")
    b = _Builder(rate_hz)
    if segments and segments[0].kind == "walk":  # no standing first: already walking at its speed
        b.speed[0], b.phase[0] = segments[0].speed * preferred_speed_mps, "steady"
    for seg in segments:
        kind = seg.kind
        if kind == "stand":
            if b.speed[-1] != 0.0:
                raise SimulationError(name, "stand_s while walking: stop first")
            b.hold(int(round(seg.stand_s / b.dt)), 0.0, "standing")
        elif kind == "stop":
            b.change_speed(0.0, p.stop_s, "stop")
            b.speed[-1] = 0.0
        elif kind == "walk":
            v = seg.speed * preferred_speed_mps
            if abs(b.speed[-1] - v) > 1e-9:
                b.change_speed(v, p.start_s if b.speed[-1] == 0.0 else p.speed_change_s,
                               "start" if b.speed[-1] == 0.0 else "speed_change")
            if seg.walk_s is not None:
                b.hold(int(round(seg.walk_s / b.dt)), 0.0, "steady")
            else:
                b.hold(int(round(seg.walk_m / v / b.dt)), 0.0, "steady")
        else:  # turn: slow to the turning speed, turn at a constant rate, speed up again
            if b.speed[-1] == 0.0:
                raise SimulationError(name, "turn_deg from standing: walk first")
            rate = np.sign(seg.turn_deg) * np.radians(p.turn_rate_deg_s)
            v_before = b.speed[-1]
            b.change_speed(p.turn_speed_fraction * preferred_speed_mps, p.speed_change_s, "speed_change")
            b.hold(int(round(np.radians(abs(seg.turn_deg)) / abs(rate) / b.dt)), rate, "turn")
            b.change_speed(v_before, p.speed_change_s, "speed_change")
    time = np.arange(len(b.speed)) * b.dt
    return CommandProfile(name, time, np.asarray(b.speed), np.asarray(b.heading), np.asarray(b.phase))


def phase_at(profile: CommandProfile, times_s: np.ndarray) -> np.ndarray:
    """The commanded phase label at each of `times_s` (the last command sample at or before it;
    times past the profile keep its last label)."""
    k = np.searchsorted(profile.time_s, np.asarray(times_s, float) + 1e-9, side="right") - 1
    return profile.phase[np.clip(k, 0, len(profile.phase) - 1)]


def measured_phases(xy: np.ndarray, rate_hz: float, p: IngestParams) -> np.ndarray:
    """Phase labels of a simulated pelvis path (n, 2), read as `ingest.phases` reads a recording
    (the same smoothing and thresholds); the facing is the direction of travel."""
    pelvis = np.column_stack([xy, np.zeros(len(xy))])
    b = p.bouts
    path = pelvis_path(pelvis, np.gradient(pelvis, axis=0), rate_hz, b.smooth_hz, b.min_walk_speed_mps,
                       b.max_yaw_rate_deg_s, b.max_facing_angle_deg)
    return motion_phases(path, rate_hz, p.phases)


def phase_agreement(commanded: np.ndarray, measured: np.ndarray, tolerance_samples: int = 0) -> dict:
    """Per commanded phase, the share of its samples whose measured phase (`ingest.phases`) agrees;
    a transition's label may be off by `tolerance_samples` (the motion lags its command)."""
    commanded, measured = np.asarray(commanded), np.asarray(measured)
    n = min(len(commanded), len(measured))
    commanded, measured = commanded[:n], measured[:n]
    ok = commanded == measured
    if tolerance_samples:
        for shift in range(1, tolerance_samples + 1):
            ok[shift:] |= commanded[:-shift] == measured[shift:]
            ok[:-shift] |= commanded[shift:] == measured[:-shift]
    return {ph: round(float(ok[commanded == ph].mean()), 3) for ph in PHASES if (commanded == ph).any()}


__all__ = ["PHASES", "CommandProfile", "ProfileParams", "Segment", "command_profile", "measured_phases",
           "phase_agreement", "phase_at"]
