"""The `rollout` section of params.yaml (sim/rollout/loop.py, sim/rollout/batch.py): the physics step, the
seeded trials per condition and bout, the replayed pelvis servo and the scripted fall test."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sim.motion.replay import ReplayParams


class Schema(BaseModel):
    """A block of params.yaml: no unknown key, values type-checked."""

    model_config = ConfigDict(extra="forbid", frozen=True, coerce_numbers_to_str=True)


class FallTestSchema(Schema):
    drop_m: float
    duration_s: float


class RolloutSection(Schema):
    """The `rollout` section of params.yaml: how the simulated trials of `simulate` and the policy
    rollouts are run (physics step in s, seeds, conditions, lead-in, motor noise)."""

    max_physics_dt_s: Annotated[float, Field(gt=0.0)]
    start_offset_m: Annotated[float, Field(ge=0.0)]
    n_seeds: Annotated[int, Field(ge=1)]
    conditions: tuple[str, ...]
    bout_margin_s: float
    bout_join_gap_s: float
    workers: int
    lead_in_s: float
    lead_in_ramp_s: float
    policy_sample_rate_hz: Annotated[float, Field(gt=0.0)]
    policy_motor_noise: Annotated[float, Field(ge=0.0)] = 0.0
    stop_after_fall_s: Annotated[float, Field(ge=0.0)] | None
    replay: ReplayParams
    fall_test: FallTestSchema
