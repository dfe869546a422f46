"""Command `tune-controllers`: the fair tuning procedure of sim/rollout/tuning.py for every controller in
`robot.tuning.initial`. Results, not edits: the record goes to reports/controller_tuning.json and the
searched gains to the tuned-gains file (data/tuning/controllers.yaml, committed), which every run reads
on top of params.yaml `robot.controllers` (`pipeline.runs.setup.controller_specs`); params.yaml itself
is never written."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from tqdm import tqdm

from pipeline.params import CheckedParams
from pipeline.runs.setup import controller_specs
from pipeline.runs.tuned_gains import read_tuned, write_tuned
from pipeline.stages.outputs import write_json
from sim.robot.controllers import resolve
from sim.robot.controllers.gains import searched
from sim.rollout.tuning import tune

HEADER = """The follow-me controllers' tuned gains, written by `python -m pipeline tune-controllers`
(params robot.tuning: {procedure};
the whole record in reports/controller_tuning.json). Read on top of params.yaml
robot.controllers.<name>.gains and checked against each class's declared gains
(sim/robot/controllers/specs.py): a gain is set here or there, never in both."""


def run_tuning(params: CheckedParams, out: Path) -> dict:
    """Tune every controller named in `robot.tuning.initial` (each one of `robot.controllers`, checked
    when the params were loaded) from its gains there; the document is written to `out`."""
    robot, replay, p = params.robot.build(), params.rollout.replay, params.robot.tuning
    specs = controller_specs(params)
    initial = params.robot.tuning.initial
    doc = {"procedure": f"scipy.optimize.minimize {p.method}, {p.max_evaluations} rollouts each, "
                        f"seed {p.seed}, synthetic walks {[dataclasses.asdict(w) for w in p.walks]}",
           "force_weight_m_per_n": p.force_weight_m_per_n, "controllers": {}}
    for name in tqdm(list(initial), desc="tune-controllers"):
        spec = {"class": specs[name]["class"], "gains": {**specs[name]["gains"], **initial[name]}}
        res = tune(name, spec, robot, replay, p)
        doc["controllers"][name] = {"class": spec["class"],
                                    "gains": {k: round(v, 4) for k, v in res.gains.items()},
                                    "objective": round(res.objective, 5),
                                    "initial_objective": round(res.initial_objective, 5),
                                    "n_evaluations": res.n_evaluations, "wall_s": round(res.wall_s, 1),
                                    "metrics": res.metrics}
    write_json(out, doc)
    return doc


def write_gains(path: Path, doc: dict, params: CheckedParams) -> None:
    """The searched gains of each tuned controller of `doc` into the tuned-gains file `path` (other
    controllers' entries there kept); the unsearched ones stay where they are (params.yaml)."""
    tuned = read_tuned(path)
    for name, res in doc["controllers"].items():
        cls = resolve(res.get("class", params.robot.controllers[name].class_))
        tuned[name] = {g: res["gains"][g] for g in searched(cls)}
    procedure = f"{params.robot.tuning.method}, {params.robot.tuning.max_evaluations} rollouts x " \
                f"{len(params.robot.tuning.walks)} synthetic walks each, seed {params.robot.tuning.seed}"
    write_tuned(path, tuned, HEADER.format(procedure=procedure))
