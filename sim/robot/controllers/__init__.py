"""Follow-me controllers: the interface (`base`), the gains each declares (`gains`), the registry by
short name or import path ``package.module:Class`` (`registry`), and a run's specs with the tuned
gains on top (`specs`)."""

from __future__ import annotations

from sim.robot.controllers.adaptive import Adaptive
from sim.robot.controllers.base import BaseCommand, Controller, RobotInfo, RobotSensors
from sim.robot.controllers.gains import Gain
from sim.robot.controllers.pid import PID
from sim.robot.controllers.registry import REGISTRY, make_controller, register, resolve

__all__ = ["REGISTRY", "PID", "Adaptive", "BaseCommand", "Controller", "Gain", "RobotInfo", "RobotSensors",
           "make_controller", "register", "resolve"]
