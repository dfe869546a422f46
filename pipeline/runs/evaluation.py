"""`EvalParams`: the `evaluate_policy` section of params.yaml, the protocol of
`python -m pipeline evaluate-policy` (pipeline/runs/evaluate_policy.py) and its pass rules."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated

from pydantic import Field, with_config

from metrics.policy_checks import PolicyChecks
from metrics.scenario_checks import ScenarioChecks


@with_config(extra="forbid")
@dataclass(frozen=True)
class EvalParams:
    """Walks of the evaluation (seeds, durations in s, the lateral push) and its pass rules."""

    n_seeds: Annotated[int, Field(ge=1)] = 10  # walks per check
    free_s: float = 20.0  # free walking
    robot_s: float = 15.0  # walking with each controller
    push_n: float = 200.0  # lateral push at the pelvis during free walking (N)
    push_duration_s: float = 0.2
    push_time_s: float = 5.0
    fall_height_fraction: float = 0.7  # a fall: pelvis below this x its standing height
    spm_min_real_cycles: int = 5  # fewer real cycles: SPM reported but not judged (too few to test)
    push_recovery_s: float = 5.0  # the pushed walk goes on this long after the push
    checks: PolicyChecks = field(default_factory=PolicyChecks)
    scenario_checks: ScenarioChecks = field(default_factory=ScenarioChecks)
