"""The studies on Ray (params `sweep`, `fall_intervention`, `sensitivity`), the gain search (`tune`) and
the Ray resources they share (`ray`): what runs, on which subjects, variants, conditions, scenarios,
balance-loss events and seeds. Their rollouts take the other sections' settings."""

from __future__ import annotations

from dataclasses import replace
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from metrics.fall_intervention import FallRuleParams
from metrics.outcomes import ObjectiveWeights
from pipeline.params import NO_EVENT, Params
from pipeline.runs.report_params import ReportParams
from sim.body.balance_loss import BalanceLoss
from sim.robot.mrba import FallParams
from sim.rollout.scenarios import ScenariosSection


class Schema(BaseModel):
    """A block of params.yaml: no unknown key, values type-checked."""

    model_config = ConfigDict(extra="forbid", frozen=True, coerce_numbers_to_str=True)




class RaySection(Schema):
    num_cpus: Annotated[int, Field(ge=1)]
    max_retries: Annotated[int, Field(ge=0)]


class SweepSection(Schema):
    study: Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9_-]*$")]
    subjects: tuple[str, ...]
    variants: tuple[str, ...]
    conditions: tuple[str, ...]
    scenarios: tuple[str, ...]
    seeds: Annotated[int, Field(ge=1)]
    events: tuple[str, ...] = (NO_EVENT,)   # balance-loss events (fall_intervention.balance_loss) or none
    onset_jitter_s: Annotated[float, Field(ge=0.0)] = 0.3


class BalanceLossSpec(Schema):
    duration_s: Annotated[float, Field(gt=0.0)]
    magnitude: float


class FallInterventionSection(SweepSection):
    balance_loss: dict[Literal["trip", "slip", "collapse", "push"], BalanceLossSpec]
    detection_window_s: Annotated[float, Field(gt=0.0)]
    confirm_s: Annotated[float, Field(gt=0.0)]
    baseline_s: Annotated[float, Field(gt=0.0)]
    caught_margin_m: Annotated[float, Field(ge=0.0)]

    def events_of(self, names: tuple[str, ...]) -> list[BalanceLoss | None]:
        """The named events as `BalanceLoss` (no onset: placed per walk), `none` as None."""
        return [None if n == NO_EVENT else BalanceLoss(n, **self.balance_loss[n].model_dump()) for n in names]

    def rule(self, fall_drop_m: float) -> FallRuleParams:
        """The rule given the robot's fall-detection drop threshold (`robot.fall.drop_m`)."""
        return FallRuleParams(self.detection_window_s, self.confirm_s, self.baseline_s,
                              fall_drop_m + self.caught_margin_m)


class SensitivitySection(SweepSection):
    """The responsiveness study (`sim.robot.responsiveness`): each factor's levels, one factor at a time
    around the twin's point (the others at the twin's values)."""

    pid_gain_scale: tuple[Annotated[float, Field(gt=0.0)], ...]
    drive_tau_s: tuple[Annotated[float, Field(gt=0.0)], ...]
    latency_s: tuple[Annotated[float, Field(ge=0.0)], ...]

    def levels(self) -> dict[str, tuple[float, ...]]:
        """factor -> its levels (`sim.robot.responsiveness.FACTORS`)."""
        return {"pid_gain_scale": self.pid_gain_scale, "drive_tau_s": self.drive_tau_s,
                "latency_s": self.latency_s}


class TuneSection(Schema):
    method: Literal["tpe", "cmaes"]
    n_trials: Annotated[int, Field(ge=2)]
    seed: int
    scenarios: tuple[str, ...]
    seeds: tuple[int, ...]
    heldout_seeds: tuple[int, ...]
    force_weight_m_per_n: Annotated[float, Field(ge=0.0)]
    gait_weight_m: Annotated[float, Field(ge=0.0)]
    fall_penalty_m: Annotated[float, Field(ge=0.0)]
    search: dict[str, dict[str, tuple[float, float]]]

    @model_validator(mode="after")
    def _disjoint(self) -> TuneSection:
        if set(self.seeds) & set(self.heldout_seeds):
            raise ValueError("heldout_seeds must differ from seeds (held-back evaluation)")
        for name, space in self.search.items():
            for gain, (lo, hi) in space.items():
                if not lo < hi:
                    raise ValueError(f"search.{name}.{gain}: low {lo} must be below high {hi}")
        return self

    def weights(self) -> ObjectiveWeights:
        return ObjectiveWeights(self.force_weight_m_per_n, self.gait_weight_m, self.fall_penalty_m)


def report_params(params: Params) -> ReportParams:
    """`report`, with the fall-intervention caught threshold and detection window
    (`FallInterventionSection.rule`) and the paper's scenario (`scenarios.paper`)."""
    rule = params.section("fall_intervention", FallInterventionSection).rule(
        params.section("robot.fall", FallParams).drop_m)
    return replace(params.section("report", ReportParams), caught_drop_m=rule.caught_drop_m,
                   detection_window_s=rule.detection_window_s,
                   paper_scenario=params.section("scenarios", ScenariosSection).paper.scenario)
