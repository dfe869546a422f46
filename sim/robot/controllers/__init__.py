"""Follow-me controllers and their registry: by short name or by import path ``package.module:Class``."""

from __future__ import annotations

import importlib

from sim.errors import SimulationError
from sim.robot.controllers.adaptive import Adaptive
from sim.robot.controllers.base import BaseCommand, Controller, RobotInfo, RobotSensors
from sim.robot.controllers.pid import PID

REGISTRY: dict[str, type[Controller]] = {"pid": PID, "adaptive": Adaptive}

__all__ = ["REGISTRY", "Adaptive", "BaseCommand", "Controller", "PID", "RobotInfo", "RobotSensors",
           "make_controller", "register", "resolve"]


def register(name: str, cls: type[Controller]) -> None:
    """Make `cls` available under `name` (e.g. in params: ``class: name``)."""
    if not (isinstance(cls, type) and issubclass(cls, Controller)):
        raise SimulationError(f"controller {name!r}", f"{cls!r} is not a Controller subclass")
    REGISTRY[name] = cls


def resolve(name: str) -> type[Controller]:
    """The controller class registered as `name`, or imported from ``package.module:Class``."""
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            cls = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise SimulationError(f"controller {name!r}", f"cannot import it ({exc})") from None
        if not (isinstance(cls, type) and issubclass(cls, Controller)):
            raise SimulationError(f"controller {name!r}", "is not a Controller subclass")
        return cls
    try:
        return REGISTRY[name]
    except KeyError:
        raise SimulationError(f"controller {name!r}",
                              f"unknown (registered: {', '.join(sorted(REGISTRY))})") from None


def make_controller(spec: dict, robot: RobotInfo) -> Controller:
    """A controller from a params entry ``{class: <name or module:Class>, gains: {...}}``."""
    if "class" not in spec:
        raise SimulationError("robot.controllers", f"entry {spec!r} lacks 'class'")
    return resolve(str(spec["class"]))(spec.get("gains", {}), robot)
