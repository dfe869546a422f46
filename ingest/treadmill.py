"""Treadmill walking: detect it, and turn it into the equivalent overground walk.

On a treadmill the pelvis hardly travels while the feet step back and forth, so the overground
pipeline (pelvis path -> bouts -> strides) would call every stride "standing". The approach here
is the simplest correct one: add the belt's displacement back to every marker
(x += belt_speed * t along the progression direction). The trial then is the overground walk the
belt stands for, and the normal pipeline runs on it unchanged: gait events are relative to the
pelvis (unchanged by a uniform shift), and stride length becomes belt speed x stride time + pelvis
drift over the stride, which is the treadmill's definition.

- Progression direction: the way the pelvis faces (ASIS midpoint ahead of the PSIS midpoint), mean
  over the trial; the path of a pelvis that hardly moves has no direction.
- Belt speed: declared in the subject file (`belt_speed_mps`), or the backward speed of the stance
  foot: median horizontal velocity along the progression direction of the heel-toe midpoint over
  the frames where it stands within `stance_height_m` of its lowest level (foot flat on the belt).
  Overground that speed is ~0 (the stance foot stands still). On the kgc6 treadmill trial the
  midpoint within 1 cm covers 43 % of the frames, all on the stance plateau (10-90 %: 1.15-1.21 m/s);
  within 3 cm swing frames come in.
- Detection (when the subject file does not declare it): the mean forward pelvis speed (along
  its facing, over the trial) is below `max_pelvis_speed_mps`, both feet move back and forth relative
  to the pelvis by more than `min_foot_excursion_m` (5th-95th percentile along the progression
  direction) and the stance foot moves backwards faster than `min_belt_speed_mps`. Overground walking
  at 1 m/s has a pelvis at ~1 m/s; standing and stepping in place have feet that barely leave the
  pelvis (< 0.1 m) and a still stance foot; walking strides move the foot ~0.6-0.9 m relative to the
  pelvis (half a stride length forward and back: Perry & Burnfield 2010, stride 1.2-1.6 m).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field, with_config

from ingest.canonical import rotate_z
from ingest.trial import SIDES, Trial

log = logging.getLogger(__name__)


@with_config(extra="forbid")
@dataclass(frozen=True)
class TreadmillParams:
    """Detection thresholds (module docstring gives the reasons)."""

    max_pelvis_speed_mps: Annotated[float, Field(gt=0.0)] = 0.2
    min_foot_excursion_m: Annotated[float, Field(gt=0.0)] = 0.3
    min_belt_speed_mps: Annotated[float, Field(gt=0.0)] = 0.2
    stance_height_m: Annotated[float, Field(gt=0.0)] = 0.01


@dataclass(frozen=True)
class TreadmillCheck:
    """What the trial looks like: the measures detection compares with its thresholds."""

    pelvis_speed_mps: float      # mean forward pelvis speed (along the facing), absolute
    foot_excursion_m: float      # smaller of the two feet's 5-95 % range relative to the pelvis
    stance_speed_mps: float      # backward speed of the flat stance foot (the belt's, on a treadmill)
    progression_rad: float       # pelvis facing (ASIS ahead of PSIS), canonical frame

    def is_treadmill(self, p: TreadmillParams) -> bool:
        return bool(self.pelvis_speed_mps < p.max_pelvis_speed_mps
                    and self.foot_excursion_m > p.min_foot_excursion_m
                    and self.stance_speed_mps > p.min_belt_speed_mps)


@dataclass(frozen=True)
class Treadmill:
    """A trial walked on a treadmill: how it was recognised and the belt displacement added back."""

    declared: bool               # the subject file says so (else detected)
    belt_speed_mps: float
    belt_speed_declared: bool    # else estimated from the stance foot
    progression_rad: float       # in the canonical frame before the trial was turned onto +X
    check: TreadmillCheck

    @property
    def note(self) -> str:
        how = "declared" if self.declared else "detected"
        speed = "declared" if self.belt_speed_declared else "estimated from the stance foot"
        return (f"treadmill ({how}): belt {self.belt_speed_mps:.3f} m/s ({speed}) added back along the "
                f"pelvis facing; pelvis {self.check.pelvis_speed_mps:.2f} m/s, feet excursion "
                f"{self.check.foot_excursion_m:.2f} m")


def facing_direction(lm: dict[str, np.ndarray]) -> float:
    """Mean pelvis facing over the trial (rad, canonical frame): ASIS midpoint minus PSIS midpoint."""
    face = (lm["asis_left"] + lm["asis_right"] - lm["psis_left"] - lm["psis_right"])[:, :2] / 2
    with np.errstate(all="ignore"):
        unit = face / np.linalg.norm(face, axis=1, keepdims=True)
    mean = np.nanmean(unit, axis=0)
    return float(np.arctan2(mean[1], mean[0]))


def stance_speed(heel: np.ndarray, toe: np.ndarray, direction: np.ndarray, rate_hz: float,
                 stance_height_m: float) -> float:
    """Backward speed (m/s, positive backwards) of one flat foot along `direction` (unit (2,)):
    median horizontal velocity of the heel-toe midpoint over the frames where the midpoint's height
    is within `stance_height_m` of its lowest level (5th percentile). NaN when no frame qualifies."""
    mid = (heel + toe) / 2
    if not np.isfinite(mid[:, 2]).any():
        return float("nan")
    with np.errstate(invalid="ignore"):
        flat = mid[:, 2] <= np.nanpercentile(mid[:, 2], 5) + stance_height_m
    v = np.gradient(mid[:, :2], 1.0 / rate_hz, axis=0) @ direction
    v = v[flat & np.isfinite(v)]
    return float(-np.median(v)) if len(v) else float("nan")


def check_treadmill(lm: dict[str, np.ndarray], time_s: np.ndarray, rate_hz: float,
                    p: TreadmillParams) -> TreadmillCheck:
    """The measures of `TreadmillParams` for one trial's landmarks (canonical frame)."""
    heading = facing_direction(lm)
    direction = np.array([np.cos(heading), np.sin(heading)])
    pelvis = np.mean([lm[r] for r in ("asis_left", "asis_right", "psis_left", "psis_right")], axis=0)
    excursion, speeds = [], []
    for side in SIDES:
        rel = (lm[f"heel_{side}"][:, :2] - pelvis[:, :2]) @ direction
        lo, hi = np.nanpercentile(rel, [5, 95]) if np.isfinite(rel).any() else (0.0, 0.0)
        excursion.append(hi - lo)
        speeds.append(stance_speed(lm[f"heel_{side}"], lm[f"toe_{side}"], direction, rate_hz,
                                   p.stance_height_m))
    forward = np.gradient(pelvis[:, :2], time_s, axis=0) @ direction
    speed = float(abs(np.nanmean(forward))) if np.isfinite(forward).any() else 0.0
    stance = float(np.nanmedian(speeds)) if np.isfinite(speeds).any() else 0.0
    return TreadmillCheck(speed, float(min(excursion)), stance, heading)


def decide(check: TreadmillCheck, p: TreadmillParams, declared: bool | None,
           belt_speed_mps: float | None, origin: str) -> Treadmill | None:
    """The treadmill of a trial, or None when it is overground: `declared` True/False from the subject
    file wins, None detects; a declared belt speed (which alone declares a treadmill) wins over the
    stance-foot estimate."""
    if declared is None and belt_speed_mps is not None:
        declared = True
    if declared is False or (declared is None and not check.is_treadmill(p)):
        return None
    speed = belt_speed_mps if belt_speed_mps is not None else check.stance_speed_mps
    result = Treadmill(bool(declared), float(speed), belt_speed_mps is not None, check.progression_rad,
                       check)
    log.log(logging.INFO if declared else logging.WARNING, "%s: %s", origin, result.note)
    return result


def overground_equivalent(trial: Trial, treadmill: Treadmill) -> Trial:
    """The trial turned so the pelvis faces +X, with the belt displacement added to every marker
    (x += belt speed x (t - t0)) and to the plates' centres of pressure."""
    t0 = trial.time_s[0]
    shift = treadmill.belt_speed_mps * (trial.time_s - t0)
    markers = {}
    for name, xyz in trial.markers.items():
        out = rotate_z(xyz, treadmill.progression_rad)
        out[:, 0] += shift
        markers[name] = out
    plates = trial.plates
    if plates is not None:
        cop = rotate_z(plates.cop_m, treadmill.progression_rad)
        cop[..., 0] += (treadmill.belt_speed_mps * (plates.time_s - t0))[:, None]
        plates = type(plates)(plates.rate_hz, plates.t0_s, plates.fz_n, cop)
    return trial.with_(markers=markers, plates=plates)
