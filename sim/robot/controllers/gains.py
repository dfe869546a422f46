"""The gains a follow-me controller declares: one `Gain` per name, written once in its class
(`Controller.declared_gains`), read by everything that handles gains.

A declaration says what a gain means and in which unit, its default (None: required, no value the
controller can run on), the closed interval a value must lie in, and how a tuner searches it
(`search`: ``"log"`` multiplies a positive gain, ``"linear"`` adds to one stored as a log10 already;
None: a design constant, never searched). From it:

- the robot params section checks `robot.controllers.<name>.gains` and the tuned-gains file
  (`sim.robot.controllers.specs.merge_specs`, `sim.robot.section.RobotSection.merged_specs`): an
  unknown gain, a value out of bounds, or a required gain that neither gives fails there, naming the
  key path;
- a controller's `gains` are its declared defaults overlaid with what it was given (`with_defaults`),
  so its code reads ``self.gains[k]`` and a misspelt key cannot be silently ignored;
- the tuners (`sim.rollout.tuning`, `pipeline.runs.tune`) search the gains with a `search` scale,
  and params `tune.search` boxes are checked against the declared gains and bounds.

A plug-in controller that declares nothing (`declared_gains` None) takes any gains, with no defaults.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from sim.robot.controllers.base import Controller

POSITIVE = (0.0, math.inf)
ANY = (-math.inf, math.inf)


@dataclass(frozen=True)
class Gain:
    """One gain of a controller: meaning, unit, default (None: required), bounds (closed), search scale."""

    meaning: str
    unit: str = "1"
    default: float | None = None
    bounds: tuple[float, float] = ANY
    search: Literal["log", "linear"] | None = None  # how the tuners move it; None: a design constant

    def problem(self, value: float) -> str | None:
        """Why `value` is not a valid value of this gain, or None."""
        lo, hi = self.bounds
        if not isinstance(value, int | float) or isinstance(value, bool) or math.isnan(value):
            return f"expected a number (got {value!r})"
        if not lo <= value <= hi:
            return f"{value!r} outside [{lo:g}, {hi:g}] ({self.meaning}, {self.unit})"
        return None


def declared(cls: type[Controller]) -> Mapping[str, Gain] | None:
    """The gains `cls` declares (None: a plug-in that declares none and takes any)."""
    return cls.declared_gains


def searched(cls: type[Controller]) -> dict[str, Gain]:
    """The gains of `cls` a tuner searches (those with a `search` scale), in declaration order."""
    return {k: g for k, g in (declared(cls) or {}).items() if g.search is not None}


def gain_problems(cls: type[Controller], gains: Mapping[str, float], complete: bool = True) -> dict[str, str]:
    """gain name -> what is wrong with it in `gains` for `cls`: unknown, out of bounds, and (when
    `complete`) a required gain missing. Empty when all is well."""
    decl = declared(cls)
    if decl is None:
        return {}
    out: dict[str, str] = {}
    for name, value in gains.items():
        if name not in decl:
            out[name] = f"unknown gain of {cls.__name__} (it takes {', '.join(decl)})"
        elif (p := decl[name].problem(value)) is not None:
            out[name] = p
    if complete:
        for name, g in decl.items():
            if g.default is None and name not in gains:
                out[name] = f"missing: required gain of {cls.__name__} ({g.meaning}, {g.unit})"
    return out


def with_defaults(cls: type[Controller], gains: Mapping[str, float]) -> dict[str, float]:
    """`gains` over the declared defaults of `cls` (only `gains` for a class that declares none)."""
    decl = declared(cls) or {}
    return {**{k: float(g.default) for k, g in decl.items() if g.default is not None}, **gains}


def describe(cls: type[Controller]) -> list[dict]:
    """The declaration as rows (name, meaning, unit, default, low, high, search): docs and reports."""
    return [{"name": k, "meaning": g.meaning, "unit": g.unit, "default": g.default, "low": g.bounds[0],
             "high": g.bounds[1], "search": g.search} for k, g in (declared(cls) or {}).items()]


__all__ = ["ANY", "POSITIVE", "Gain", "declared", "describe", "gain_problems", "searched", "with_defaults"]
