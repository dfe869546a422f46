"""The robot twin's follow-me responsiveness: how fast its base answers a command and how hard its PID
pushes (issue 34's sensitivity study, `python -m pipeline sweep --study responsiveness`).

Three factors, each a number a robot's builder sets:

- `drive_tau_s`: the base's velocity-servo time constant, tau = base mass / drive gain (the twin: 100 kg
  / 4000 N s/m = 25 ms). Another tau sets the drive gain to mass / tau and scales the yaw servo's gain
  by the same ratio, so a heavier-answering base lags in heading as it lags in speed.
- `latency_s`: the command latency (`robot.base.latency_s`, rounded to control ticks by the drive).
- `pid_gain_scale`: every gain of a PID controller (kp, ki, kd, both axes) times this; `i_max` is kept.
  Controllers that are not PIDs do not read it.

A controller that models the robot (the adaptive one: `RobotInfo.drive_tau_s`) sees the changed drive
and latency, as it would on the robot it was designed for; the PID sees nothing of them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from sim.errors import SimulationError
from sim.robot.controllers import PID, resolve
from sim.robot.controllers.pid import GAINS as PID_GAINS
from sim.robot.mrba import RobotParams

FACTORS = ("pid_gain_scale", "drive_tau_s", "latency_s")


@dataclass(frozen=True)
class Responsiveness:
    """One point of the study: drive time constant (s), command latency (s), PID gain scale (x)."""

    drive_tau_s: float
    latency_s: float
    pid_gain_scale: float

    def __post_init__(self) -> None:
        for name in FACTORS:
            value = getattr(self, name)
            if not (math.isfinite(value) and (value > 0 if name != "latency_s" else value >= 0)):
                raise SimulationError("responsiveness", f"{name} must be a finite number "
                                      f"{'>= 0' if name == 'latency_s' else '> 0'}. Got {value!r}")

    def moved(self, factor: str, level: float) -> Responsiveness:
        """This point with `factor` (one of `FACTORS`) at `level`."""
        if factor not in FACTORS:
            raise SimulationError("responsiveness", f"no factor {factor!r} ({', '.join(FACTORS)})")
        return dataclasses.replace(self, **{factor: float(level)})

    def same(self, other: Responsiveness) -> bool:
        """Equal up to float rounding (the twin's tau is computed as mass / gain)."""
        return all(math.isclose(getattr(self, f), getattr(other, f), rel_tol=1e-9, abs_tol=1e-12)
                   for f in FACTORS)


def twin_responsiveness(robot: RobotParams) -> Responsiveness:
    """The point `robot` sits at: tau = base mass / drive gain, its latency, PID gains as they are."""
    b = robot.base
    return Responsiveness(b.mass_kg / b.drive_gain_n_per_mps, b.latency_s, 1.0)


def is_pid(spec: dict) -> bool:
    """Whether a controller entry (``{class, gains}``) is a PID (reads `pid_gain_scale`)."""
    return issubclass(resolve(str(spec["class"])), PID)


def for_controller(r: Responsiveness, spec: dict) -> Responsiveness:
    """`r` as a controller sees it: a controller that is not a PID has no PID gains to scale (1x)."""
    return r if is_pid(spec) else dataclasses.replace(r, pid_gain_scale=1.0)


def with_responsiveness(robot: RobotParams, controllers: dict[str, dict], r: Responsiveness
                        ) -> tuple[RobotParams, dict[str, dict]]:
    """`robot` and its controller entries moved to point `r` from the point `robot` sits at
    (`twin_responsiveness`): drive gain = base mass / tau, yaw gain scaled by the same ratio, latency,
    every PID's gains x `pid_gain_scale` (relative to their values in `controllers`)."""
    b = robot.base
    ratio = (b.mass_kg / b.drive_gain_n_per_mps) / r.drive_tau_s
    base = dataclasses.replace(b, drive_gain_n_per_mps=b.mass_kg / r.drive_tau_s,
                               yaw_gain_nm_per_radps=b.yaw_gain_nm_per_radps * ratio, latency_s=r.latency_s)
    out = {}
    for name, spec in controllers.items():
        spec = dict(spec)
        if is_pid(spec):
            gains = dict(spec.get("gains", {}))
            spec["gains"] = {k: (v * r.pid_gain_scale if k in PID_GAINS else v) for k, v in gains.items()}
        out[name] = spec
    return dataclasses.replace(robot, base=base), out


__all__ = ["FACTORS", "Responsiveness", "for_controller", "is_pid", "twin_responsiveness",
           "with_responsiveness"]
