"""Stage `transfer <subject>`: a walking policy for a subject without a committed one.

Two sources (`transfer.source`). `universal`: the body-conditioned policy of `data/universal`
(`sim.learn.universal`) on the subject's own body, gated zero-shot first (`export_subject`), then,
while the gate fails, fine-tuned on that body alone (`fine_tune_body`). `nearest` (also when the
universal policy is missing): the committed policy (`train.subjects`) whose body and gait are
nearest the subject's (`sim.learn.transfer`: height, mass, leg length, preferred speed; weighted RMS
of log ratios), fine-tuned on the subject's scaled human and reference cycle (`sim.learn.train.train`
with `init_from`). Either way the fine-tune runs in chunks of `transfer.chunk_steps`, gated after
each, until the gate passes or `transfer.steps` / `transfer.max_wall_s` are spent (one loop for both,
`tune_until_gate`, given the source's chunk of fine-tuning).

The gate is `evaluate-policy` (pipeline/runs/evaluate_policy.py) with `transfer.gate_seeds` walks per
check, judged on its scenario checks (metrics/scenario_checks.py). `transfer.gate: source` requires
every scenario check the source policy passes in its own `evaluation.json` (a transfer must not be
worse than where it started; for the universal policy, its run's source, `universal.init_from`:
`pipeline.runs.gate.universal_required`, the set the adoption rule requires too), `all` every
scenario check. It passes when at least one check is required and all required ones pass.

Outputs, all-or-nothing (built in a temporary folder beside it, then moved into place):
`data/policies/<subject>/` as `train` (or `export_subject`) writes it, plus `evaluation.json` (the
gate's evaluate-policy result) and `transfer.json` (the gate record, `GATE_FILE`). A failed gate keeps
the policy for inspection, but `simulate --human policy` does not use it (`usable_policy`; the gate
and its records are `pipeline.runs.gate`): the subject keeps replay rows only, and the metrics stage
turns the gate into `policy` quality rows.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pipeline import paths
from pipeline.params import Params
from pipeline.runs.gate import (
    EVALUATION_FILE,
    GATE_FILE,
    required_checks,
    run_gate,
    source_evaluation,
    universal_required,
)
from pipeline.runs.setup import train_params
from sim.learn.transfer import TransferSection

if TYPE_CHECKING:
    from sim.learn.transfer import BodyFeatures, NearestPolicy


# -- choosing the source ----------------------------------------------------------------------------

def subject_features(subject: str, root: Path) -> BodyFeatures:
    """The subject's scaled human (`scale`) at its reference cycle's speed (`reference`)."""
    from pipeline.stages.train import train_inputs
    from sim.learn.transfer import body_features
    from sim.motion.reference import load_reference

    xml, npz = train_inputs(subject, root)
    return body_features(xml, load_reference(npz).cycle.speed_mps)


def policy_features(folder: Path) -> BodyFeatures:
    """A trained policy's body and reference cycle (the ones it was trained on)."""
    from sim.learn.train import load_body
    from sim.learn.transfer import body_features

    xml, cycle = load_body(folder)
    return body_features(xml, cycle.speed_mps)


def choose_source(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                  policy_root: Path = paths.POLICIES_ROOT) -> tuple[NearestPolicy, dict[str, BodyFeatures]]:
    """The nearest committed policy (`train.subjects` with a policy in `policy_root`) and the features
    of the subject (key `subject`) and of every candidate."""
    from sim.errors import SimulationError
    from sim.learn.train import POLICY_FILE, TrainParams
    from sim.learn.transfer import nearest_policy

    train_subjects = params.section("train", TrainParams).subjects
    committed = [s for s in train_subjects
                 if s != subject and (paths.policy_dir(policy_root, s) / POLICY_FILE).is_file()]
    if not committed:
        raise SimulationError(policy_root, f"no committed policy of {', '.join(train_subjects)} to "
                              f"start {subject}'s from")
    features = {s: policy_features(paths.policy_dir(policy_root, s)) for s in committed}
    target = subject_features(subject, root)
    weights = params.section("transfer", TransferSection).weights
    return nearest_policy(target, features, weights), {subject: target, **features}


# -- fine-tuning and the gate -----------------------------------------------------------------------

def fine_tune(subject: str, params: Params, out_dir: Path, *, steps: int, max_wall_s: float | None,
              init_from: Path | None, root: Path = paths.PROCESSED_ROOT, progress: bool = True) -> dict:
    """Fine-tune into `out_dir`: from the policy in `init_from`, or (None) on from `out_dir`'s own
    (resume; `steps` then counts the total). Returns `sim.learn.train.train`'s progress record."""
    from pipeline.stages.train import train_inputs
    from sim.learn.train import train
    from sim.motion.reference import load_reference

    xml, npz = train_inputs(subject, root)
    command = f"python -m pipeline transfer {subject}"
    return train(xml, load_reference(npz).cycle, train_params(params), out_dir, total_steps=steps,
                 max_wall_s=max_wall_s, resume=init_from is None, init_from=init_from, progress=progress,
                 command=command)


@dataclass(frozen=True)
class Tuned:
    """What a fine-tune-and-gate loop (`tune_until_gate`) did: env steps in all (as its chunks count
    them), gates run (rounds), seconds spent training and gating, the last gate's evaluate-policy
    result and verdict (`judge`)."""

    steps: int
    rounds: int
    train_wall_s: float
    gate_wall_s: float
    evaluation: dict
    verdict: dict


Chunk = Callable[[int, float], int]
"""One chunk of a fine-tune: `chunk(total_steps, max_wall_s)` fine-tunes on until `total_steps` env
steps of this fine-tune are done in all or `max_wall_s` seconds are spent, leaves the policy the gate
walks in `<work_root>/<subject>`, and returns the env steps done in all."""


def tune_until_gate(subject: str, params: Params, work_root: Path, required: set[str] | None, chunk: Chunk,
                    *, gate_first: bool, max_wall_s: float, root: Path = paths.PROCESSED_ROOT,
                    reports: Path = paths.REPORTS_ROOT, progress: bool = True) -> Tuned:
    """Fine-tune `subject`'s policy in `<work_root>/<subject>` in chunks of `transfer.chunk_steps`
    (`chunk`), gating after each (`required` checks: `run_gate`), until the gate passes,
    `transfer.steps` are done or `max_wall_s` (s) is spent (the chunk running then stops; its gate
    still runs). `gate_first`: gate the policy already there before the first chunk (zero-shot)."""
    t = params.section("transfer", TransferSection)
    start = time.perf_counter()
    steps, rounds, train_s, gate_s = 0, 0, 0.0, 0.0
    while True:
        if rounds > 0 or not gate_first:  # zero-shot: the first gate comes before any chunk
            t0 = time.perf_counter()
            steps = chunk(min(steps + t.chunk_steps, t.steps), max(max_wall_s - (t0 - start), 1.0))
            train_s += time.perf_counter() - t0
        t1 = time.perf_counter()
        doc, verdict = run_gate(subject, params, work_root, required, root=root, reports=reports,
                                progress=progress)
        gate_s, rounds = gate_s + time.perf_counter() - t1, rounds + 1
        if verdict["pass"] or steps >= t.steps or time.perf_counter() - start >= max_wall_s:
            return Tuned(steps, rounds, round(train_s, 1), round(gate_s, 1), doc, verdict)


def fine_tune_until_gate(subject: str, params: Params, work_root: Path, source_dir: Path,
                         required: set[str] | None, *, max_wall_s: float, root: Path = paths.PROCESSED_ROOT,
                         reports: Path = paths.REPORTS_ROOT, progress: bool = True) -> Tuned:
    """`subject`'s policy in `<work_root>/<subject>` fine-tuned from the committed one in
    `source_dir` (`tune_until_gate`: no zero-shot gate, as the source was trained on another body)."""
    from sim.learn.train import PROGRESS_FILE

    dest = paths.policy_dir(work_root, subject)

    def chunk(total_steps: int, wall_s: float) -> int:
        started = (dest / PROGRESS_FILE).is_file()  # a chunk ran: resume it, else start from the source
        rec = fine_tune(subject, params, dest, steps=total_steps, max_wall_s=wall_s,
                        init_from=None if started else source_dir, root=root, progress=progress)
        return int(rec["steps"])

    return tune_until_gate(subject, params, work_root, required, chunk, gate_first=False,
                           max_wall_s=max_wall_s, root=root, reports=reports, progress=progress)


def universal_until_gate(subject: str, params: Params, work_root: Path, universal_dir: Path,
                         required: set[str] | None, *, max_wall_s: float, root: Path = paths.PROCESSED_ROOT,
                         reports: Path = paths.REPORTS_ROOT, progress: bool = True) -> Tuned:
    """`subject`'s policy in `<work_root>/<subject>` from the universal policy in `universal_dir`:
    exported to the subject's body and gated zero-shot, then fine-tuned on that body alone (in
    `<work_root>/.fine_tune`, exported after each chunk) by `tune_until_gate`; the gate requires the
    `required` checks (`pipeline.runs.gate.universal_required`)."""
    from pipeline.stages.train import train_inputs
    from sim.learn.pool import Source, UniversalParams
    from sim.learn.train import PROGRESS_FILE
    from sim.learn.universal import export_subject, fine_tune_body

    xml, npz = train_inputs(subject, root)
    src, p = Source(subject, str(xml), str(npz)), train_params(params)
    up = params.section("universal", UniversalParams)
    dest, tune_dir = paths.policy_dir(work_root, subject), work_root / ".fine_tune"

    def export(folder: Path, record: dict) -> None:
        """The policy in `folder` on the subject's body into `dest`, `record` its progress record."""
        export_subject(folder, src, p.env, dest, label="universal")
        (dest / PROGRESS_FILE).write_text(json.dumps(record, indent=1) + "\n")

    def chunk(total_steps: int, wall_s: float) -> int:
        record = fine_tune_body(universal_dir, src, p, up, tune_dir, steps=total_steps, max_wall_s=wall_s,
                                command=f"python -m pipeline transfer {subject}", progress=progress)
        export(tune_dir, record)
        return int(record["fine_tuned_steps"])

    start = int(json.loads((universal_dir / PROGRESS_FILE).read_text())["steps"])
    export(universal_dir, {"steps": start, "initialised_from": "universal", "initial_steps": start,
                           "fine_tuned_steps": 0})
    return tune_until_gate(subject, params, work_root, required, chunk, gate_first=True,
                           max_wall_s=max_wall_s, root=root, reports=reports, progress=progress)


def universal_source(params: Params, universal_dir: Path | None) -> Path | None:
    """The universal policy's folder when `transfer.source` is `universal` and it has a policy."""
    from sim.learn.train import POLICY_FILE

    if params.section("transfer", TransferSection).source != "universal" or universal_dir is None:
        return None
    return universal_dir if (universal_dir / POLICY_FILE).is_file() else None


def tune_from_source(subject: str, params: Params, work_root: Path, *, max_wall_s: float,
                     root: Path = paths.PROCESSED_ROOT, policy_root: Path = paths.POLICIES_ROOT,
                     reports: Path = paths.REPORTS_ROOT, universal_dir: Path | None = paths.UNIVERSAL_DIR,
                     progress: bool = True) -> tuple[Tuned, dict]:
    """The stage's procedure into `<work_root>/<subject>` (module docstring): from the universal
    policy when `universal_source` gives one, else from the nearest committed policy. Returns what
    the loop did and the route's record (source, gate, and for the nearest its distances)."""
    t = params.section("transfer", TransferSection)
    universal = universal_source(params, universal_dir)
    if universal is not None:
        required = universal_required(params, policy_root)
        from sim.learn.universal import UNIVERSAL_FILE

        tuned = universal_until_gate(subject, params, work_root, universal, required, max_wall_s=max_wall_s,
                                     root=root, reports=reports, progress=progress)
        origin = json.loads((paths.policy_dir(work_root, subject) / UNIVERSAL_FILE).read_text())
        steps = origin["steps"] - origin["fine_tuned_steps"]  # the checkpoint's, as exported
        return tuned, {"source": "universal", "universal_steps": steps, "gate": t.gate}
    choice, features = choose_source(subject, params, root, policy_root)
    source_dir = paths.policy_dir(policy_root, choice.source)
    tuned = fine_tune_until_gate(subject, params, work_root, source_dir,
                                 required_checks(params, source_evaluation(source_dir)),
                                 max_wall_s=max_wall_s, root=root, reports=reports, progress=progress)
    return tuned, {"source": choice.source, "distance": round(choice.distance, 4),
                   "distances": {k: round(v, 4) for k, v in choice.distances.items()},
                   "features": {"subject": asdict(features[subject]),
                                "source": asdict(features[choice.source])}, "gate": t.gate}


def run_transfer(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                 policy_root: Path = paths.POLICIES_ROOT, reports: Path = paths.REPORTS_ROOT, *,
                 steps: int | None = None, max_wall_s: float | None = None, progress: bool = True,
                 universal_dir: Path | None = paths.UNIVERSAL_DIR) -> dict:
    """Choose, fine-tune and gate, write `<policy_root>/<subject>/` (module docstring); returns the
    gate record. `steps`, `max_wall_s`: override `transfer.steps` / `transfer.max_wall_s`."""
    from sim.learn.train import AMP_FILE

    if steps is not None:
        t = params.section("transfer", TransferSection)
        params = params.replaced("transfer", TransferSection, t.model_copy(update={"steps": steps}))
    t = params.section("transfer", TransferSection)
    start = time.perf_counter()
    dest = paths.policy_dir(policy_root, subject)
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest.parent, prefix=f".{subject}.transfer-") as tmp:
        tuned, chosen = tune_from_source(subject, params, Path(tmp), max_wall_s=max_wall_s or t.max_wall_s,
                                         root=root, policy_root=policy_root, reports=reports,
                                         universal_dir=universal_dir, progress=progress)
        record = {"subject": subject, **chosen, "gate_seeds": t.gate_seeds, "steps": tuned.steps,
                  "rounds": tuned.rounds, "train_wall_s": tuned.train_wall_s,
                  "gate_wall_s": tuned.gate_wall_s,
                  "wall_s": round(time.perf_counter() - start, 1), **tuned.verdict}
        work = paths.policy_dir(Path(tmp), subject)
        (work / AMP_FILE).unlink(missing_ok=True)  # the discriminator: no rollout needs it
        (work / EVALUATION_FILE).write_text(json.dumps(tuned.evaluation, indent=2) + "\n")
        (work / GATE_FILE).write_text(json.dumps(record, indent=2) + "\n")
        if dest.exists():
            shutil.rmtree(dest)
        os.replace(work, dest)
    return record


__all__ = ["Chunk", "Tuned", "choose_source", "fine_tune", "fine_tune_until_gate", "policy_features",
           "run_transfer", "subject_features", "tune_from_source", "tune_until_gate", "universal_source",
           "universal_until_gate"]
