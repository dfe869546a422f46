"""The controller registry: a class by short name (``pid``, ``adaptive``, what `register` added) or by
import path ``package.module:Class``; `make_controller` builds one from a params entry."""

from __future__ import annotations

import importlib

from sim.errors import SimulationError
from sim.robot.controllers.adaptive import Adaptive
from sim.robot.controllers.base import Controller, RobotInfo
from sim.robot.controllers.pid import PID

REGISTRY: dict[str, type[Controller]] = {"pid": PID, "adaptive": Adaptive}


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
    """A controller from a params entry ``{class: <name or module:Class>, gains: {...}}`` (its gains
    checked against the class's declaration: `Controller.__init__`)."""
    if "class" not in spec:
        raise SimulationError("robot.controllers", f"entry {spec!r} lacks 'class'")
    return resolve(str(spec["class"]))(spec.get("gains", {}), robot)


__all__ = ["REGISTRY", "make_controller", "register", "resolve"]
