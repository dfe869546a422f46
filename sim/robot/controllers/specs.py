"""A run's controllers: params entries ``{class, gains}`` with the tuned gains on top, checked against
each class's declared gains (`sim.robot.controllers.gains`).

Where a gain's value comes from, highest first:

1. the tuned-gains file (`data/tuning/controllers.yaml`, written by `tune-controllers`): controller
   name -> {gain: value}, the gains a tuner searched;
2. params.yaml `robot.controllers.<name>.gains`: the design constants (and any gain of a controller
   that was never tuned);
3. the class's declared default.

A gain set in both files is an error, so that neither silently overrides the other (edit the tuned file,
or rerun tuning, to change a searched gain). A gain that none of them gives and that has no default, an
unknown gain, a value outside its declared bounds, or a tuned controller that `robot.controllers` lacks
is reported with its key path
(`merge_specs`). The params section holds the entries (`sim.robot.section.RobotSection.merged_specs`);
the pipeline reads the tuned-gains file (`pipeline.runs.tuned_gains`) and raises the problems naming
their file (`pipeline.runs.setup.controller_specs`, run by `check-params` too).
"""

from __future__ import annotations

from collections.abc import Mapping

from sim.errors import SimulationError
from sim.robot.controllers.gains import gain_problems, searched
from sim.robot.controllers.registry import resolve

PARAMS, TUNED = "params", "tuned"  # the source a problem is in


def merge_specs(entries: Mapping[str, Mapping], tuned: Mapping[str, Mapping[str, float]]
                ) -> tuple[dict[str, dict], list[tuple[str, str]]]:
    """name -> {class, gains} with `tuned` on top of each entry's gains; and the problems, each
    (source: `PARAMS` or `TUNED`, ``key.path: problem``). A class that does not resolve (a plug-in
    registered later) is not checked here: `make_controller` is."""
    problems: list[tuple[str, str]] = []
    for name in tuned:
        if name not in entries:
            problems.append((TUNED, f"{name}: no controller {name!r} in robot.controllers"))
    specs = {}
    for name, entry in entries.items():
        given, top = dict(entry.get("gains", {})), dict(tuned.get(name, {}))
        specs[name] = {"class": entry["class"], "gains": {**given, **top}}
        try:
            cls = resolve(str(entry["class"]))
        except SimulationError:
            continue
        if cls.declared_gains is not None:  # in declaration order
            merged = specs[name]["gains"]
            specs[name]["gains"] = {**{k: merged[k] for k in cls.declared_gains if k in merged}, **merged}
        for gain in sorted(given.keys() & top.keys()):
            said = (f"also set in the tuned-gains file ({top[gain]!r} there, {given[gain]!r} here): a gain "
                    "is set in one place (the tuned file holds the searched gains); remove one")
            problems.append((PARAMS, f"robot.controllers.{name}.gains.{gain}: {said}"))
        for gain, problem in gain_problems(cls, given, complete=False).items():
            problems.append((PARAMS, f"robot.controllers.{name}.gains.{gain}: {problem}"))
        for gain, problem in gain_problems(cls, top, complete=False).items():
            problems.append((TUNED, f"{name}.{gain}: {problem}"))
        for gain, problem in gain_problems(cls, specs[name]["gains"]).items():
            if problem.startswith("missing"):
                problems.append((PARAMS, f"robot.controllers.{name}.gains.{gain}: {problem}, given neither "
                                         "there nor in the tuned-gains file"))
    return specs, problems


def search_problems(cls_name: str, space: Mapping[str, object], key: str,
                    boxes: bool = True) -> list[str]:
    """`key.gain: problem` of each gain of `space` (a tuner's start values, or with `boxes` its
    (low, high) search boxes) that `cls_name` does not declare as searched, or whose box leaves the
    declared bounds."""
    try:
        cls = resolve(cls_name)
    except SimulationError:
        return []
    tunable = searched(cls)
    if cls.declared_gains is None:
        return []
    out = []
    for gain, value in space.items():
        if gain not in tunable:
            out.append(f"{key}.{gain}: not a searched gain of {cls.__name__} "
                       f"(searched: {', '.join(tunable) or 'none'})")
            continue
        lo, hi = tunable[gain].bounds
        values = value if boxes else (value,)
        if any(not lo <= float(v) <= hi for v in values):
            out.append(f"{key}.{gain}: {list(values) if boxes else value} outside the declared bounds "
                       f"[{lo:g}, {hi:g}]")
    return out


def controller_specs(entries: Mapping[str, Mapping], tuned: Mapping[str, Mapping[str, float]],
                     initial: Mapping[str, Mapping[str, float]], search: Mapping[str, Mapping[str, object]]
                     ) -> tuple[dict[str, dict], list[tuple[str, str]]]:
    """`merge_specs`, and the tuners' inputs checked against the declarations: `initial` (params
    `robot.tuning.initial`: controller -> start values) and `search` (params `tune.search`: controller
    -> gain -> (low, high)); their problems are params.yaml's (`PARAMS`)."""
    specs, problems = merge_specs(entries, tuned)
    for key, given, boxes in (("robot.tuning.initial", initial, False), ("tune.search", search, True)):
        for name, space in given.items():
            if name in specs:  # an unknown controller name is the params schema's to report
                found = search_problems(specs[name]["class"], space, f"{key}.{name}", boxes)
                problems += [(PARAMS, p) for p in found]
    return specs, problems


__all__ = ["PARAMS", "TUNED", "controller_specs", "merge_specs", "search_problems"]
