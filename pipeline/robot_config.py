"""The `robot` and `rollout` sections of params.yaml as the dataclasses sim/ takes."""

from __future__ import annotations

from pathlib import Path

from pipeline.params import PARAMS_FILE, ParamsError
from sim.motion.replay import ReplayParams
from sim.robot.mrba import RobotParams
from sim.rollout.tuning import TuningParams


def _section(params: dict, name: str, path: str | Path) -> dict:
    section = params.get(name)
    if not isinstance(section, dict):
        raise ParamsError(path, f"no {name!r} section")
    return section


def robot_params(params: dict, path: str | Path = PARAMS_FILE) -> RobotParams:
    try:
        return RobotParams.from_dict(_section(params, "robot", path))
    except KeyError as exc:
        raise ParamsError(path, f"robot section lacks key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise ParamsError(path, f"invalid robot section ({exc})") from None


def replay_params(params: dict, path: str | Path = PARAMS_FILE) -> ReplayParams:
    try:
        return ReplayParams(**{k: float(v) for k, v in _section(params, "rollout", path)["replay"].items()})
    except KeyError as exc:
        raise ParamsError(path, f"rollout section lacks key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise ParamsError(path, f"invalid rollout.replay section ({exc})") from None


def tuning_params(params: dict, path: str | Path = PARAMS_FILE) -> TuningParams:
    try:
        return TuningParams.from_dict(_section(params, "robot", path)["tuning"])
    except KeyError as exc:
        raise ParamsError(path, f"robot.tuning lacks key {exc.args[0]!r}") from None


def controller_specs(params: dict, path: str | Path = PARAMS_FILE) -> dict[str, dict]:
    """`robot.controllers`: name -> {class, gains}."""
    specs = _section(params, "robot", path).get("controllers")
    if not isinstance(specs, dict) or not all(isinstance(v, dict) and "class" in v for v in specs.values()):
        raise ParamsError(path, "robot.controllers must map names to {class: ..., gains: {...}}")
    return specs
