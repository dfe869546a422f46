"""A plug-in follow-me controller (params `class: tests.pipeline.failing_controller:Failing`) that raises
at its first control tick: a deterministic job failure inside a Ray task, for the sweep's retry test.
Each attempt appends a line to the file `ATTEMPTS_ENV` names (when set), so the test counts attempts."""

from __future__ import annotations

import os

from sim.robot.controllers.base import BaseCommand, Controller, RobotSensors

ATTEMPTS_ENV = "GAITLOOP_TEST_CONTROLLER_ATTEMPTS"
MESSAGE = "failing controller: deliberate failure at the first control tick"


class Failing(Controller):
    """Records the attempt, then raises `RuntimeError(MESSAGE)` from `step`."""

    def reset(self) -> None:
        pass

    def step(self, sensors: RobotSensors) -> BaseCommand:
        path = os.environ.get(ATTEMPTS_ENV)
        if path:
            with open(path, "a", encoding="utf-8") as f:
                f.write(f"{os.getpid()}\n")
        raise RuntimeError(MESSAGE)
