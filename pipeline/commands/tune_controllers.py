"""Command `tune-controllers`: the fair tuning procedure of sim/rollout/tuning.py for every controller in
`robot.tuning.initial`, results to reports/controller_tuning.json; `--write-params` puts the tuned
gains into params.yaml (`robot.controllers.<name>.gains`, one line each)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from tqdm import tqdm

from pipeline.params import Params, ParamsError
from pipeline.stages.outputs import write_json
from sim.rollout.tuning import tune


def run_tuning(params: Params, out: Path) -> dict:
    """Tune every controller named in `robot.tuning.initial` (each one of `robot.controllers`, checked
    when the params were loaded) from its gains there; the document is written to `out`."""
    robot, replay, p = params.robot.build(), params.rollout.replay.build(), params.robot.tuning.build()
    specs = params.robot.controller_specs()
    initial = params.robot.tuning.initial
    doc = {"procedure": f"scipy.optimize.minimize {p.method}, {p.max_evaluations} rollouts each, "
                        f"seed {p.seed}, synthetic walks {[dataclasses.asdict(w) for w in p.walks]}",
           "force_weight_m_per_n": p.force_weight_m_per_n, "controllers": {}}
    for name in tqdm(list(initial), desc="tune-controllers"):
        spec = {"class": specs[name]["class"], "gains": {**specs[name]["gains"], **initial[name]}}
        res = tune(name, spec, robot, replay, p)
        doc["controllers"][name] = {"gains": {k: round(v, 4) for k, v in res.gains.items()},
                                    "objective": round(res.objective, 5),
                                    "initial_objective": round(res.initial_objective, 5),
                                    "n_evaluations": res.n_evaluations, "wall_s": round(res.wall_s, 1),
                                    "metrics": res.metrics}
    write_json(out, doc)
    return doc


def write_gains(path: Path, doc: dict) -> None:
    """Replace the `gains:` line of each tuned controller in the params file (text edit, comments kept)."""
    text = path.read_text()
    for name, res in doc["controllers"].items():
        flow = ", ".join(f"{k}: {v}" for k, v in res["gains"].items())
        pattern = re.compile(rf"(\n    {re.escape(name)}:\n      class: [^\n]*\n      gains: )\{{[^\n]*\}}")
        text, n = pattern.subn(lambda m, flow=flow: m.group(1) + "{" + flow + "}", text)
        if n != 1:
            raise ParamsError(path, f"cannot find robot.controllers.{name}.gains to update")
    path.write_text(text)
