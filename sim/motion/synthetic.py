"""A synthetic constant-speed walk on a minimal world, for controller tuning and tests.

The world is one free-floating capsule body ``pelvis`` (free joint ``root``) carrying the subject's
mass; the walk starts from rest, ramps to `speed_mps` and adds the intra-stride pelvis oscillation
of level walking: forward speed +-`surge_mps` at step frequency (two per stride) plus +-`asym_mps`
at stride frequency (left/right step asymmetry, present in every real gait), lateral sway
+-`sway_m` at stride frequency, vertical +-`bounce_m` at step frequency (Winter 2009: about 2-5 cm
sway and bounce), and optionally a slow pace fluctuation (`drift_mps`: walkers change pace from
stride to stride). Optionally the path curves gently (`turn_rate_rps`), from the start or from
`turn_onset_s` on, the heading rate rising over `turn_ramp_s` and the pace dropping by
`turn_slowdown` (a walk that ends entering a turn): real "straight" bouts drift in heading and end
in turns, and a controller tuned on a perfectly straight line alone is never asked to correct a
lateral offset. It is not the evaluation data: the controllers are tuned on it and evaluated on the
subjects' replayed recordings.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from pydantic import with_config

from sim.motion.replay import Motion


@with_config(extra="forbid")
@dataclass(frozen=True)
class WalkParams:
    """Synthetic walk (params `robot.tuning.walks`)."""

    speed_mps: float = 1.2
    stride_s: float = 1.1
    surge_mps: float = 0.05
    asym_mps: float = 0.0
    sway_m: float = 0.03
    bounce_m: float = 0.02
    ramp_s: float = 1.5
    rest_s: float = 0.5
    duration_s: float = 10.0
    pelvis_height_m: float = 0.95
    mass_kg: float = 75.0
    rate_hz: float = 100.0
    turn_rate_rps: float = 0.0  # heading rate once at speed (scaled by the ramp): a gently curving path
    drift_mps: float = 0.0      # slow pace fluctuation, +- this, one cycle per drift_period_s
    drift_period_s: float = 3.0
    turn_onset_s: float = 0.0   # > 0: the heading rate rises from 0 at this time ...
    turn_ramp_s: float = 1.0    # ... to turn_rate_rps over this long (a bout that ends entering a turn)
    turn_slowdown: float = 0.0  # ... while the walk's envelope (pace, sway, bounce and the turn rate
                                # itself) shrinks by this fraction over the same ramp


def capsule_world(mass_kg: float = 75.0, height_m: float = 0.95) -> mujoco.MjSpec:
    """A floor and a free capsule ``pelvis`` (joint ``root``) at `height_m`, facing +X."""
    spec = mujoco.MjSpec()
    spec.modelname = "capsule_walker"
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1], rgba=[0.8, 0.8, 0.8, 1])
    body = spec.worldbody.add_body(name="pelvis", pos=[0, 0, height_m])
    body.add_freejoint(name="root")
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, -0.12, 0, 0, 0.12, 0], size=[0.1, 0, 0],
                  mass=mass_kg, rgba=[0.7, 0.5, 0.4, 1])
    return spec


def synthetic_walk(p: WalkParams, phase_rad: float = 0.0) -> Motion:
    """Root qpos (n, 7) of the walk: rest, smooth ramp to speed, steady walking with oscillation."""
    t = np.arange(0.0, p.duration_s, 1.0 / p.rate_hz)
    u = np.clip((t - p.rest_s) / p.ramp_s, 0, 1)
    envelope = 3 * u**2 - 2 * u**3
    f = 1.0 / p.stride_s
    if p.turn_onset_s > 0 and p.turn_slowdown:  # walkers slow down as they enter a turn
        w = np.clip((t - p.turn_onset_s) / p.turn_ramp_s, 0, 1)
        envelope = envelope * (1 - p.turn_slowdown * (3 * w**2 - 2 * w**3))
    # forward position: integral of envelope * (v + surge sin(2 w t)), integrated numerically
    vx = envelope * (p.speed_mps + p.surge_mps * np.sin(4 * np.pi * f * t + phase_rad)
                     + p.asym_mps * np.sin(2 * np.pi * f * t + phase_rad)
                     + p.drift_mps * np.sin(2 * np.pi * t / p.drift_period_s))
    x = np.concatenate([[0.0], np.cumsum((vx[1:] + vx[:-1]) / 2 * np.diff(t))])
    y = envelope * p.sway_m * np.sin(2 * np.pi * f * t + phase_rad)
    z = p.pelvis_height_m - envelope * p.bounce_m * (1 - np.cos(4 * np.pi * f * t + phase_rad)) / 2
    quat = np.tile([1.0, 0, 0, 0], (len(t), 1))
    if p.turn_rate_rps:
        # along a curving path: heading integrates turn_rate x envelope; progression and sway are
        # expressed in the path frame, the pelvis yaws with the path
        rate = envelope * p.turn_rate_rps
        if p.turn_onset_s > 0:
            rate = rate * np.clip((t - p.turn_onset_s) / p.turn_ramp_s, 0, 1)
        heading = np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) / 2 * np.diff(t))])
        c, s = np.cos(heading), np.sin(heading)
        dx = np.diff(x)
        px = np.concatenate([[0.0], np.cumsum(dx * (c[1:] + c[:-1]) / 2)]) - s * y
        py = np.concatenate([[0.0], np.cumsum(dx * (s[1:] + s[:-1]) / 2)]) + c * y
        x, y = px, py
        quat = np.column_stack([np.cos(heading / 2), np.zeros_like(t), np.zeros_like(t), np.sin(heading / 2)])
    return Motion(t, np.column_stack([x, y, z, quat]))
