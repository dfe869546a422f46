"""The transfer gate: may a fine-tuned policy walk the subject's policy human?

The gate is evaluate-policy (`pipeline.runs.evaluate_policy`) with `transfer.gate_seeds` walks per
check (`gate_params`), judged on its scenario checks (metrics/scenario_checks.py; `judge`).
`transfer.gate: source` requires every scenario check the source policy passes in its own
`evaluation.json` (`required_checks`: a transfer must not be worse than where it started), `all`
every scenario check. It passes when at least one check is required and all required ones pass.
The transfer stage (`pipeline.stages.transfer`) writes the record (`GATE_FILE`) and the gate's
evaluate-policy result (`EVALUATION_FILE`) into the policy folder; the simulate stage reads them
(`pipeline.runs.gate_record`): a policy whose gate failed is not used.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from pipeline import paths
from pipeline.params import Params
from pipeline.runs.evaluation import EvalParams
from pipeline.runs.gate_record import (
    EVALUATION_FILE,
    GATE_FILE,
    gate_failed,
    gate_summary,
    read_gate,
    source_evaluation,
    usable_policy,
)
from sim.learn.transfer import TransferSection

SCENARIO_PREFIX = "scenario_"        # evaluate-policy's names of the scenario checks


def gate_params(params: Params, seeds: int) -> Params:
    """`params` with `seeds` walks per evaluate-policy check (free, controllers, push and scenarios)."""
    ev = params.section("evaluate_policy", EvalParams)
    ev = replace(ev, n_seeds=seeds, scenario_checks=replace(ev.scenario_checks, seeds=seeds))
    return params.replaced("evaluate_policy", EvalParams, ev)


def required_checks(params: Params, source_evaluation: dict | None) -> set[str] | None:
    """The scenario checks the gate requires: those the source passes (`transfer.gate: source`, when
    its evaluation is known), else None (every scenario check)."""
    if source_evaluation is None or params.section("transfer", TransferSection).gate == "all":
        return None
    checks = source_evaluation.get("checks", {})
    return {k for k, ok in checks.items() if k.startswith(SCENARIO_PREFIX) and ok}


def universal_required(params: Params, policy_root: Path = paths.POLICIES_ROOT) -> set[str] | None:
    """The scenario checks a universal export must pass: those its run's source policy
    (`universal.init_from`) passes in its `evaluation.json` (`transfer.gate: source`), else every one."""
    from sim.learn.pool import UniversalParams

    source = params.section("universal", UniversalParams).init_from
    return required_checks(params, source_evaluation(paths.policy_dir(policy_root, source)))


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
             progress: bool = True, seeds: int | None = None) -> tuple[dict, dict]:
    """(evaluate-policy's result with `seeds` walks per check, default `transfer.gate_seeds`, the
    gate's verdict)."""
    from pipeline.runs.evaluate_policy import evaluate_policy  # torch: only when a gate runs

    seeds = seeds or params.section("transfer", TransferSection).gate_seeds
    doc = evaluate_policy(subject, gate_params(params, seeds), root, policy_root, reports, progress)
    return doc, judge(doc["checks"], required)


__all__ = ["EVALUATION_FILE", "GATE_FILE", "SCENARIO_PREFIX", "gate_failed", "gate_params", "gate_summary",
           "judge", "read_gate", "required_checks", "run_gate", "source_evaluation", "universal_required",
           "usable_policy"]
