"""`HumanDriver`: what a rollout needs from the human side.

A driver adapts the human part of the world before the robot is attached (`prepare`), sets the
human's initial state (`reset`), acts once per output sample before the physics steps
(`before_sample`), records what it needs after them (`record`), and returns the human's joint
positions per sample in the human model's own qpos layout (`qpos_samples`, what the virtual markers
need). The kinematic `sim.motion.replay.ReplayHuman` and the torque-driven
`sim.learn.policy_human.PolicyHuman` implement the same methods; the rollout and robot code do not
change.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import mujoco
import numpy as np


class HumanDriver(ABC):
    """What a rollout needs from the human side; see the module docstring."""

    mode: str
    duration_s: float

    @abstractmethod
    def prepare(self, spec: mujoco.MjSpec) -> None: ...

    @abstractmethod
    def start_pose(self) -> tuple[np.ndarray, float]:
        """Pelvis world position (3,) and heading (rad) at t = 0."""

    @abstractmethod
    def reset(self, model: mujoco.MjModel, data: mujoco.MjData, sample_times_s: np.ndarray) -> None: ...

    @abstractmethod
    def before_sample(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None: ...

    @abstractmethod
    def record(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None: ...

    @abstractmethod
    def qpos_samples(self) -> np.ndarray: ...

    def sample_controls(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Optional, after `reset`: (a view into `data.ctrl`, values (n_samples, width)) when all that
        `before_sample(k)` does is write row k into that view; the rollout then writes it itself
        and does not call `before_sample` (one Python call per sample less)."""
        return None

    def from_world_qpos(self, world_qpos: np.ndarray) -> None:
        """Optional: take the per-sample state from the world qpos (n, nq_world) the rollout recorded
        at the output samples. A driver that overrides this is not called through `record` (one
        Python call per sample less)."""
        return None
