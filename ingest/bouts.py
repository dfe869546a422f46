"""Walking bouts: where the subject walks in a straight line, and in which direction.

The pelvis path (mean of the pelvis markers) is low-passed at about one stride (`smooth_hz`) so
the within-stride sway does not show; its speed separates standing from walking and its heading
rate separates turns from straight walking. The progression direction of each straight bout is
the mean heading over it: stride lengths and event detection are measured along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ingest.filtering import finite_runs, lowpass


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


def pelvis_path(pelvis: np.ndarray, rate_hz: float, smooth_hz: float, min_walk_speed_mps: float,
                max_yaw_rate_deg_s: float) -> PelvisPath:
    xy = pelvis[:, :2].copy()
    ok = np.isfinite(xy).all(axis=1)
    if not ok.all() and ok.any():
        idx = np.arange(len(xy))
        xy = np.column_stack([np.interp(idx, idx[ok], xy[ok, k]) for k in range(2)])
    xy = lowpass(xy, rate_hz, smooth_hz) if len(xy) > 9 else xy
    vel = np.gradient(xy, 1.0 / rate_hz, axis=0)
    speed = np.linalg.norm(vel, axis=1)
    heading = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    yaw = np.degrees(np.gradient(heading, 1.0 / rate_hz))
    walking = speed >= min_walk_speed_mps
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
