"""A policy folder's transfer-gate record (`GATE_FILE`) and evaluate-policy result (`EVALUATION_FILE`),
as the stages that only read them need them (simulate: is the policy usable; store: its checks). The
gate itself is `pipeline.runs.gate`."""

from __future__ import annotations

from pathlib import Path

from pipeline.stages.outputs import read_json

GATE_FILE = "transfer.json"          # in the policy folder: the gate record
EVALUATION_FILE = "evaluation.json"  # in the policy folder: its evaluate-policy result


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
    keys = ("source", "universal_steps", "distance", "pass", "failed", "checks", "steps", "wall_s", "gate",
            "gate_seeds")
    return {k: gate[k] for k in keys if k in gate}


def source_evaluation(folder: Path) -> dict | None:
    """A policy folder's evaluate-policy result (`EVALUATION_FILE`), None when it has none."""
    return read_json(folder / EVALUATION_FILE)
