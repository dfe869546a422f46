"""The `robot` section of params.yaml: the MRBA (`sim.robot.mrba.RobotParams`, its parts' defaults
and units there), the controllers with their design-constant gains (`robot.controllers`: name -> {class,
gains}; the searched gains are in the tuned-gains file, merged on top and checked against each class's
declared gains by `RobotSection.merged_specs`) and the synthetic-walk gain tuning (`robot.tuning`)."""

from __future__ import annotations

from collections.abc import Mapping

from pydantic import BaseModel, ConfigDict, Field

from sim.robot.controllers.specs import controller_specs
from sim.robot.harness import HarnessParams
from sim.robot.mrba import ArmParams, BaseParams, FallParams, RobotParams, SensorParams
from sim.rollout.tuning import TuningParams


class Schema(BaseModel):
    """A block of params.yaml: no unknown key, values type-checked."""

    model_config = ConfigDict(extra="forbid", frozen=True, coerce_numbers_to_str=True)


class ControllerSchema(Schema):
    """A `robot.controllers` entry: its class and the gains params.yaml sets (the design constants; the
    searched gains are in the tuned-gains file), checked against the class's declared gains with the
    tuned gains on top by `RobotSection.merged_specs`."""

    class_: str = Field(alias="class")  # registry name or package.module:Class
    gains: dict[str, float]

    def spec(self) -> dict:
        """The {class, gains} entry as params.yaml has it (`merged_specs`: with the tuned gains)."""
        return {"class": self.class_, "gains": dict(self.gains)}


class RobotSection(Schema):
    """The `robot` section of params.yaml: the MRBA's parts (`RobotParams`), its controllers and how
    their gains are tuned (`python -m pipeline tune-controllers`)."""

    base: BaseParams = BaseParams()
    arm: ArmParams = ArmParams()
    harness: HarnessParams = HarnessParams()
    fall: FallParams = FallParams()
    sensors: SensorParams = SensorParams()
    tuning: TuningParams
    controllers: dict[str, ControllerSchema]

    def build(self) -> RobotParams:
        return RobotParams(self.base, self.arm, self.harness, self.fall, self.sensors)

    def merged_specs(self, tuned: Mapping[str, Mapping[str, float]],
                     search: Mapping[str, Mapping[str, object]] | None = None
                     ) -> tuple[dict[str, dict], list[tuple[str, str]]]:
        """name -> {class, gains}: `controllers` with `tuned` (the tuned-gains file's gains: controller
        -> {gain: value}) on top; and the problems of checking every controller's gains, the tuning's
        start values (`tuning.initial`) and `search` (params `tune.search`: controller -> gain -> box)
        against its class's declared gains, each (source: `PARAMS` or `TUNED`, ``key.path: problem``),
        the key path from params.yaml's root (``robot.controllers.pid.gains.kp_x``) or the tuned
        file's (``pid.kp_x``): `sim.robot.controllers.specs.controller_specs`."""
        entries = {name: c.spec() for name, c in self.controllers.items()}
        return controller_specs(entries, tuned, self.tuning.initial, search or {})
