"""The `robot` section of params.yaml: the MRBA (`sim.robot.mrba.RobotParams`, its parts' defaults
and units there), the controllers with their gains (`robot.controllers`: name -> {class, gains}) and the
synthetic-walk gain tuning (`robot.tuning`)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

from sim.motion.synthetic import WalkParams
from sim.robot.harness import HarnessParams
from sim.robot.mrba import ArmParams, BaseParams, FallParams, RobotParams, SensorParams
from sim.rollout.tuning import TuningParams


class Schema(BaseModel):
    """A block of params.yaml: no unknown key, values type-checked."""

    model_config = ConfigDict(extra="forbid", frozen=True, coerce_numbers_to_str=True)


class TuningSchema(Schema):
    method: str
    max_evaluations: int
    seed: int
    force_weight_m_per_n: float
    limit_weight_m: float
    sample_rate_hz: float
    walks: Annotated[tuple[WalkParams, ...], Field(min_length=1)]
    initial: dict[str, dict[str, float]]  # controller name -> starting gains of the search

    def build(self) -> TuningParams:
        return TuningParams(self.method, self.max_evaluations, self.seed, self.force_weight_m_per_n,
                            self.limit_weight_m, self.sample_rate_hz, self.walks)


class ControllerSchema(Schema):
    class_: str = Field(alias="class")  # registry name or package.module:Class
    gains: dict[str, float]

    @model_validator(mode="after")
    def _gains_fit_the_class(self) -> ControllerSchema:
        """The gains its class needs and reads (`Controller.gain_problems`); a class that does not
        resolve here (registered later) is left to `make_controller`."""
        from sim.errors import SimulationError
        from sim.robot.controllers import resolve

        try:
            cls = resolve(self.class_)
        except SimulationError:
            return self
        problem = cls.gain_problems(self.gains)
        if problem:
            raise ValueError(f"gains: {problem}")
        return self

    def spec(self) -> dict:
        """The {class, gains} dict `sim.robot.controllers.make_controller` takes."""
        return {"class": self.class_, "gains": dict(self.gains)}


class RobotSection(Schema):
    """The `robot` section of params.yaml: the MRBA's parts (`RobotParams`), its controllers and how
    their gains are tuned (`python -m pipeline tune-controllers`)."""

    base: BaseParams = BaseParams()
    arm: ArmParams = ArmParams()
    harness: HarnessParams = HarnessParams()
    fall: FallParams = FallParams()
    sensors: SensorParams = SensorParams()
    tuning: TuningSchema
    controllers: dict[str, ControllerSchema]

    def build(self) -> RobotParams:
        return RobotParams(self.base, self.arm, self.harness, self.fall, self.sensors)

    def controller_specs(self) -> dict[str, dict]:
        """`robot.controllers`: name -> {class, gains}."""
        return {name: c.spec() for name, c in self.controllers.items()}
