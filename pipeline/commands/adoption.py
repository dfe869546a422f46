"""The adoption rule of the universal walking policy, as a procedure (docs/policies.md, "Adoption rule").

A checkpoint of the universal run (`data/universal`) is exported to every bundled subject's body
(`sim.learn.universal.export_subject`) and judged by evaluate-policy with the transfer gate:
`transfer.gate_seeds` walks per check, the scenario checks that the run's source policy
(`universal.init_from`, camargo's committed policy) passes in its own evaluation being required
(`pipeline.runs.gate.universal_required`, as the transfer stage requires of a universal export). A subject
without a committed policy adopts the checkpoint when its gate passes; a subject with one
(`train.subjects`) only when the checkpoint passes at least as many of evaluate-policy's checks as
its committed policy does. A checkpoint the 2-walk rule would adopt is confirmed with evaluate-policy's
own walks (`evaluate_policy.n_seeds`; the amendment of 2026-11-28): the same rule again on that
evaluation. `decide` is that rule; `evaluate_checkpoint` runs it; the command
`python -m pipeline adopt-universal` appends the result to `data/universal/adoption.json`.
Nothing is copied into `data/policies/`: a subject that adopts is listed in `transfer.adopted` and
gets the checkpoint's export through the transfer command (zero-shot), committed by the frozen stage
`adopted@<subject>`; a committed one is replaced by hand.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from pathlib import Path

from pipeline import paths
from pipeline.params import Params
from pipeline.paths import ADOPTION_FILE
from pipeline.runs.evaluation import EvalParams
from pipeline.runs.gate import run_gate, universal_required
from pipeline.runs.gate_record import source_evaluation
from pipeline.runs.setup import train_params


def passed_checks(evaluation: dict) -> list[str]:
    """evaluate-policy's checks that passed, sorted."""
    return sorted(k for k, ok in evaluation.get("checks", {}).items() if ok is True)


def gate_rule(verdict: dict, evaluation: dict, committed: dict | None) -> dict:
    """The 2-walk rule for one subject. `verdict`: the gate's (`pipeline.runs.gate.judge`);
    `evaluation`: the checkpoint's evaluate-policy result on the subject; `committed`: the subject's
    committed policy's evaluation (None: it has none). Returns the record: checks passed, walks per
    check, the gate, the committed policy's count and whether the rule adopts (`adopt`, `why`)."""
    passed = passed_checks(evaluation)
    out = {"checks_passed": len(passed), "checks": len(evaluation.get("checks", {})),
           "walks": evaluation.get("free", {}).get("rollouts"), "gate_pass": bool(verdict["pass"]),
           "failed_required": list(verdict["failed"]), "passed": passed}
    if committed is None:
        return {**out, "adopt": out["gate_pass"], "why": "gate" if out["gate_pass"] else "gate failed"}
    theirs = len(passed_checks(committed))
    return {**out, "committed_checks_passed": theirs, "adopt": out["checks_passed"] >= theirs,
            "why": f"{out['checks_passed']} checks against the committed policy's {theirs}"}


def decide(verdict: dict, evaluation: dict, committed: dict | None,
           confirmation: tuple[dict, dict] | None = None) -> dict:
    """The amended rule (module docstring): `gate_rule` on the gate's walks, and where that adopts,
    `gate_rule` again on `confirmation` (evaluate-policy's result with its own walks, its verdict;
    None: not run, so not adopted). The record keeps the confirmation's under `confirmation`."""
    first = gate_rule(verdict, evaluation, committed)
    if not first["adopt"]:
        return first
    if confirmation is None:
        return {**first, "adopt": False, "why": f"{first['why']}; not confirmed (not run at its own walks)"}
    conf = gate_rule(confirmation[1], confirmation[0], committed)
    return {**first, "confirmation": conf, "adopt": conf["adopt"],
            "why": f"{first['why']}; at {conf['walks']} walks {conf['why']}"}


def evaluate_checkpoint(params: Params, universal_dir: Path, subjects: list[str], *,
                        root: Path = paths.PROCESSED_ROOT, policy_root: Path = paths.POLICIES_ROOT,
                        progress: bool = False) -> dict:
    """The rule over `subjects` for the checkpoint in `universal_dir` (module docstring): one
    evaluation record (checkpoint steps, gate seeds, required checks, per subject `decide`'s record,
    seconds spent)."""
    from pipeline.stages.train import train_inputs
    from sim.learn.pool import Source
    from sim.learn.train import NORM_FILE, POLICY_FILE, PROGRESS_FILE
    from sim.learn.transfer import TransferSection
    from sim.learn.universal import export_subject

    t = params.section("transfer", TransferSection)
    required = universal_required(params, policy_root)
    env = train_params(params).env
    walks = params.section("evaluate_policy", EvalParams).n_seeds
    start, judged = time.perf_counter(), {}
    with tempfile.TemporaryDirectory(prefix="adoption-") as tmp:
        work, snapshot = Path(tmp), Path(tmp) / ".checkpoint"  # a running training rewrites its folder
        snapshot.mkdir()
        for name in (POLICY_FILE, NORM_FILE, PROGRESS_FILE):
            shutil.copyfile(Path(universal_dir) / name, snapshot / name)
        steps = int(json.loads((snapshot / PROGRESS_FILE).read_text())["steps"])
        for subject in subjects:
            xml, npz = train_inputs(subject, root)
            export_subject(snapshot, Source(subject, str(xml), str(npz)), env,
                           paths.policy_dir(work, subject), label=f"universal@{steps}")
            doc, verdict = run_gate(subject, params, work, required, root=root, reports=work / "reports",
                                    progress=progress)
            committed = source_evaluation(paths.policy_dir(policy_root, subject))
            confirm = None
            if gate_rule(verdict, doc, committed)["adopt"]:
                confirm = run_gate(subject, params, work, required, root=root, reports=work / "reports",
                                   progress=progress, seeds=walks)
            judged[subject] = decide(verdict, doc, committed, confirm)
    return {"universal_steps": steps, "gate_seeds": t.gate_seeds, "confirm_seeds": walks,
            "required": sorted(required) if required is not None else "every scenario check",
            "subjects": judged, "adopted": sorted(s for s, r in judged.items() if r["adopt"]),
            "wall_s": round(time.perf_counter() - start, 1)}


def append_record(universal_dir: Path, evaluation: dict, how: str) -> Path:
    """`evaluation` appended to `<universal_dir>/adoption.json` (created when missing)."""
    path = Path(universal_dir) / ADOPTION_FILE
    doc = json.loads(path.read_text()) if path.exists() else {
        "rule": "docs/policies.md, 'Adoption rule' (written before these evaluations)", "evaluations": []}
    doc["evaluations"].append({"how": how, **evaluation})
    doc["adopted"] = evaluation["adopted"]
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return path


__all__ = ["append_record", "decide", "evaluate_checkpoint", "gate_rule", "passed_checks"]
