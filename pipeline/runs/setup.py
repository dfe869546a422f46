"""Library settings that combine several params sections: a training recipe with the scenarios'
transition timing, the harness's yaw spring and a cohort variant's body (`train_params`), a cohort
variant (`variant`, `fine_tune_steps`), the controllers with their tuned gains (`controller_specs`:
params `robot.controllers` with the tuned-gains file on top) and the rollout batch runner's world
(`batch_setup`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ingest.process import IngestParams
from pipeline.params import Params, ParamsError
from pipeline.runs.tuned_gains import read_tuned
from sim.body.variant import HEALTHY, CohortSection, Variant
from sim.robot.controllers.specs import TUNED
from sim.robot.harness import HarnessParams
from sim.robot.section import RobotSection
from sim.rollout.batch import BatchSetup, DriverSource
from sim.rollout.scenarios import ScenariosSection
from sim.rollout.section import RolloutSection

if TYPE_CHECKING:
    from sim.learn.train import TrainParams

SearchBoxes = dict[str, dict[str, tuple[float, float]]]  # params `tune.search`: controller -> gain -> box


def variant(params: Params, name: str) -> Variant:
    """Cohort variant `name` (`healthy`: nothing changed); `ParamsError` lists the declared ones."""
    if name == HEALTHY:
        return Variant()
    try:
        return params.section("cohort", CohortSection).variant(name)
    except ValueError as exc:
        raise params.fail(str(exc)) from None


def fine_tune_steps(params: Params, name: str) -> int:
    """Env steps of cohort variant `name`'s fine-tuning: its own budget, else `cohort.fine_tune_steps`."""
    variant(params, name)
    return params.section("cohort", CohortSection).budget(name)


def train_params(params: Params, name: str = HEALTHY) -> TrainParams:
    """`train` with the scenarios' transition timing in its env (training commands and the evaluated
    scenarios share one profile), the harness's yaw spring (`robot.harness`, 6th DoF) and the body and
    goals of cohort variant `name`."""
    from sim.learn.train import TrainParams  # torch: imported by the commands that train or run policies

    p = params.section("train", TrainParams)
    h = params.section("robot.harness", HarnessParams)
    twist = replace(p.env.harness_twist, stiffness_nm_per_rad=h.stiffness[5],
                    damping_nms_per_rad=h.damping[5], range_rad=h.range[5])
    return replace(p, env=replace(p.env, profile=params.section("scenarios", ScenariosSection).profile,
                                  variant=variant(params, name), harness_twist=twist))


def batch_setup(params: Params, subject: str, markerset: dict[str, str], human_xml: str | Path,
                drivers: DriverSource, process: bool = True) -> BatchSetup:
    """What the rollout batch runner needs for `subject`'s world: robot, controllers, the rollout's
    physics step and start offset, and the ingest params that process its trials."""
    r, robot = params.section("rollout", RolloutSection), params.section("robot", RobotSection)
    return BatchSetup(str(human_xml), subject, dict(markerset), robot.build(), controller_specs(params),
                      params.section("ingest", IngestParams), r.max_physics_dt_s, r.start_offset_m, drivers,
                      process, r.stop_after_fall_s)


def controller_specs(params: Params, search: Mapping[str, Mapping[str, object]] | None = None
                     ) -> dict[str, dict]:
    """name -> {class, gains}: params `robot.controllers` with the tuned-gains file (`params.tuned_file`,
    data/tuning/controllers.yaml) on top, every controller's gains, `robot.tuning.initial` and `search`
    (params `tune.search`) checked against its class's declared gains (`RobotSection.merged_specs`). A
    problem raises `ParamsError` naming its file and key path, e.g. `params.yaml:
    robot.controllers.pid.gains.kp_xx: unknown gain of PID ...` (those of the first file with one)."""
    robot = params.section("robot", RobotSection)
    specs, problems = robot.merged_specs(read_tuned(params.tuned_file), search)
    if problems:
        source = problems[0][0]
        raise ParamsError(params.tuned_file if source == TUNED else params.path,
                          "; ".join(p for s, p in problems if s == source))
    return specs


def check_controllers(params: Params) -> None:
    """`controller_specs` with params `tune.search` checked too: run by `pipeline.params.checked`
    (`check-params`, `make run`), so a bad gain in either file fails before any stage runs."""
    controller_specs(params, params.section("tune.search", SearchBoxes))
