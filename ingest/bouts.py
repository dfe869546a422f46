"""Walking bouts: where the subject walks in a straight line, and in which direction.

The pelvis path (mean of the pelvis markers) is low-passed at about one stride (`smooth_hz`) so
the within-stride sway does not show; its speed separates standing from walking, the angle between
the direction of travel and the way the pelvis faces (ASIS midpoint ahead of the PSIS midpoint)
separates walking from side-stepping and shuffling into place, and its heading rate separates
turns from straight walking. The progression direction of each straight bout is
the mean heading over it: stride lengths and event detection are measured along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ingest.filtering import finite_frames, finite_runs, lowpass


@dataclass(frozen=True)
class PelvisPath:
    """Per-frame pelvis kinematics on the horizontal plane."""

    xy_m: np.ndarray         # (n, 2) smoothed position
    speed_mps: np.ndarray    # (n,)
    heading_rad: np.ndarray  # (n,) unwrapped direction of travel
    yaw_rate_deg_s: np.ndarray
    walking: np.ndarray      # (n,) bool
    turning: np.ndarray      # (n,) bool


@dataclass(frozen=True)
class Bout:
    start: int
    stop: int  # exclusive
    heading_rad: float


def _bridged(xy: np.ndarray) -> np.ndarray:
    ok = finite_frames(xy)
    if ok.all() or not ok.any():
        return xy
    idx = np.arange(len(xy))
    return np.column_stack([np.interp(idx, idx[ok], xy[ok, k]) for k in range(xy.shape[1])])


def pelvis_path(pelvis: np.ndarray, facing: np.ndarray, rate_hz: float, smooth_hz: float,
                min_walk_speed_mps: float, max_yaw_rate_deg_s: float,
                max_facing_angle_deg: float) -> PelvisPath:
    """Pelvis path from the pelvis centre and its facing vector ((n, 3) each, canonical frame)."""
    xy = _bridged(pelvis[:, :2].copy())
    face = _bridged(facing[:, :2].copy())
    if len(xy) > 9:  # in one call: each channel is filtered on its own
        both = lowpass(np.column_stack([xy, face]), rate_hz, smooth_hz)
        xy, face = both[:, :2], both[:, 2:]
    vel = np.gradient(xy, 1.0 / rate_hz, axis=0)
    speed = np.linalg.norm(vel, axis=1)
    heading = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    yaw = np.degrees(np.gradient(heading, 1.0 / rate_hz))
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_facing = np.einsum("ij,ij->i", vel, face) / (speed * np.linalg.norm(face, axis=1))
    walking = (speed >= min_walk_speed_mps) & (cos_facing >= np.cos(np.radians(max_facing_angle_deg)))
    yaw[~walking] = 0.0
    return PelvisPath(xy, speed, heading, yaw, walking, np.abs(yaw) > max_yaw_rate_deg_s)


def straight_bouts(path: PelvisPath, min_frames: int) -> list[Bout]:
    """Runs of walking without turning, at least `min_frames` long."""
    bouts = []
    for start, stop in finite_runs(path.walking & ~path.turning):
        if stop - start >= min_frames:
            h = path.heading_rad[start:stop]
            bouts.append(Bout(int(start), int(stop), float(np.arctan2(np.sin(h).mean(), np.cos(h).mean()))))
    return bouts
