"""The transfer gate: may a fine-tuned policy walk the subject's policy human?

The gate is evaluate-policy (`pipeline.runs.evaluate_policy`) with `transfer.gate_seeds` walks per
check (`gate_params`), judged on its scenario checks (metrics/scenario_checks.py; `judge`).
`transfer.gate: source` requires every scenario check the source policy passes in its own
`evaluation.json` (`required_checks`: a transfer must not be worse than where it started), `all`
every scenario check. It passes when at least one check is required and all required ones pass.
The transfer stage (`pipeline.stages.transfer`) writes the record (`GATE_FILE`) and the gate's
evaluate-policy result (`EVALUATION_FILE`) into the policy folder; the simulate stage reads them
(`read_gate`, `usable_policy`): a policy whose gate failed is not used.
"""

from __future__ import annotations

from pathlib import Path

from pipeline import paths
from pipeline.params import Params
from pipeline.stages.outputs import read_json

GATE_FILE = "transfer.json"          # in the policy folder: the gate record
EVALUATION_FILE = "evaluation.json"  # in the policy folder: its evaluate-policy result
SCENARIO_PREFIX = "scenario_"        # evaluate-policy's names of the scenario checks


def read_gate(folder: Path) -> dict | None:
    """The transfer gate record of a policy folder (None: no transfer, e.g. a committed policy)."""
    return read_json(Path(folder) / GATE_FILE)


def gate_failed(gate: dict | None) -> bool:
    """A transfer gate record that did not pass (None, no transfer: False)."""
    return gate is not None and not gate.get("pass")


def usable_policy(folder: Path) -> bool:
    """A policy the policy human may use: trained, and not one whose transfer gate failed."""
    from sim.learn.train import POLICY_FILE

    return (Path(folder) / POLICY_FILE).is_file() and not gate_failed(read_gate(folder))


def gate_summary(gate: dict) -> dict:
    """What the rollouts' summary (and so the quality rows) carries of a gate record."""
    keys = ("source", "distance", "pass", "failed", "checks", "steps", "wall_s", "gate")
    return {k: gate[k] for k in keys if k in gate}


def gate_params(params: Params, seeds: int) -> Params:
    """`params` with `seeds` walks per evaluate-policy check (free, controllers, push and scenarios)."""
    ev = params.evaluate_policy
    ev = ev.model_copy(update={"n_seeds": seeds,
                               "scenario_checks": ev.scenario_checks.model_copy(update={"seeds": seeds})})
    return params.model_copy(update={"evaluate_policy": ev})


def required_checks(params: Params, source_evaluation: dict | None) -> set[str] | None:
    """The scenario checks the gate requires: those the source passes (`transfer.gate: source`, when
    its evaluation is known), else None (every scenario check)."""
    if params.transfer.gate == "all" or source_evaluation is None:
        return None
    checks = source_evaluation.get("checks", {})
    return {k for k, ok in checks.items() if k.startswith(SCENARIO_PREFIX) and ok}


def judge(checks: dict[str, bool | None], required: set[str] | None) -> dict:
    """The gate over evaluate-policy's `checks`: each scenario check with its result and whether it
    is required; `failed` the required ones that did not pass; `pass` when at least one check is
    required and none failed."""
    judged = {name: {"pass": ok, "required": required is None or name in required}
              for name, ok in checks.items() if name.startswith(SCENARIO_PREFIX)}
    needed = [n for n, c in judged.items() if c["required"]]
    failed = [n for n in needed if judged[n]["pass"] is not True]
    return {"pass": bool(needed) and not failed, "failed": failed, "checks": judged,
            "not_evaluated": sorted((required or set()) - set(judged))}


def run_gate(subject: str, params: Params, policy_root: Path, required: set[str] | None, *,
             root: Path = paths.PROCESSED_ROOT, reports: Path = paths.REPORTS_ROOT,
             progress: bool = True) -> tuple[dict, dict]:
    """(evaluate-policy's result with `transfer.gate_seeds` walks per check, the gate's verdict)."""
    from pipeline.runs.evaluate_policy import evaluate_policy  # torch: only when a gate runs

    doc = evaluate_policy(subject, gate_params(params, params.transfer.gate_seeds), root, policy_root,
                          reports, progress)
    return doc, judge(doc["checks"], required)


def source_evaluation(folder: Path) -> dict | None:
    """A policy folder's evaluate-policy result (`EVALUATION_FILE`), None when it has none."""
    return read_json(folder / EVALUATION_FILE)


__all__ = ["EVALUATION_FILE", "GATE_FILE", "SCENARIO_PREFIX", "gate_failed", "gate_params", "gate_summary",
           "judge", "read_gate", "required_checks", "run_gate", "source_evaluation", "usable_policy"]
