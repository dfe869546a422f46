"""Stage `sweep`: a study of subjects x variants x conditions x scenarios x balance-loss events x
seeds on Ray (params `sweep`, or `fall_intervention` with `--study fall_intervention`); and the
responsiveness study (params `sensitivity`, `--study responsiveness`): subjects x controllers x the
robot twin's responsiveness (`sim.robot.responsiveness`), one factor at a time around the twin's point.

Each job is one policy-human rollout, a pure function of (subject, variant and its policy file,
condition and its gains, scenario, event and its definition, seed, params hash); its key is the hash
of exactly those, so a job that ran (or was retried after its worker died) gives the same row, a
rerun with nothing changed runs nothing, and a retrained policy reruns its jobs. Jobs run as Ray
tasks (`sim.rollout.batch.dispatch`, the one Ray dispatch; `sim.rollout.cluster`: local, or the cluster
of `RAY_ADDRESS`) on the batch runner's worker (`sim.rollout.batch.Worker`); a task is retried
`ray.max_retries` times, whether its worker died or it raised, and a job that still fails is reported
with its error while the rest completes.

Outputs in `<root>/<study>/` (root: data/sweeps): `jobs/<key>.parquet` (one row per finished job,
written as results come back: an interrupted study resumes where it stopped), `results.parquet`
(the rows of the current jobs: identity, `metrics.outcomes.run_row`, the event's
`metrics.fall_intervention.event_metrics` and `metrics.gait_symmetry.symmetry_row`; in the responsiveness
study one row per job and design cell it belongs to, `DESIGN_COLUMNS`) and `summary.json`. The store stage
adds the rows to `sweep_results`, once per (study, job key), and the design to `sensitivity_design`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import ray
from ray.exceptions import RayTaskError

from metrics.fall_intervention import FallRuleParams, event_metrics
from metrics.gait_symmetry import symmetry_row
from metrics.outcomes import run_row
from pipeline import paths
from pipeline.params import Params
from pipeline.runs.jobs import policy_digest, policy_setup
from pipeline.runs.setup import controller_specs
from pipeline.runs.studies import (
    NO_EVENT,
    FallInterventionSection,
    RaySection,
    SensitivitySection,
    SweepSection,
)
from pipeline.stages.outputs import write_outputs
from pipeline.store.records import DESIGN_COLUMNS, SWEEP_COLUMNS
from sim.body.balance_loss import BalanceLoss
from sim.errors import SimulationError
from sim.learn.policy_human import PolicyWalk
from sim.robot.responsiveness import Responsiveness, for_controller, twin_responsiveness, with_responsiveness
from sim.robot.section import RobotSection
from sim.rollout.batch import RolloutJob, Worker, dispatch
from sim.rollout.cluster import connect

ROLLOUT_SECTIONS = ("ingest", "metrics", "robot", "rollout", "human", "train", "evaluate_policy", "scenarios",
                    "cohort")


@dataclass(frozen=True)
class SweepJob:
    """One rollout of a study; `key` names it (and its row) for good."""

    study: str
    subject: str
    variant: str
    condition: str
    gains: dict
    scenario: str
    seed: int
    params_hash: str
    event: BalanceLoss | None = None  # None: normal walking
    onset_jitter_s: float = 0.0
    policy_hash: str = ""             # sha256 (16 hex) of the policy file the job runs
    responsiveness: Responsiveness | None = None  # None: the robot as params `robot` has it
    code_hash: str = ""               # `rollout_code_hash`: the code that runs the job and makes its row

    @property
    def event_name(self) -> str:
        return NO_EVENT if self.event is None else self.event.kind

    @property
    def gains_hash(self) -> str:
        return hashlib.sha256(json.dumps(self.gains, sort_keys=True).encode()).hexdigest()[:12]

    @property
    def key(self) -> str:
        doc = [self.subject, self.variant, self.condition, self.gains, self.scenario, self.seed,
               self.params_hash, self.policy_hash]
        if self.event is not None:  # normal-walking keys stay as they were before events existed
            doc += [dataclasses.asdict(self.event), self.onset_jitter_s]
        if self.responsiveness is not None:  # the twin's own point keeps the key of a plain job
            doc += [dataclasses.asdict(self.responsiveness)]
        if self.code_hash:
            doc += [self.code_hash]
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:20]

    def rollout_job(self) -> RolloutJob:
        tag = "" if self.event is None else f"_{self.event.kind}"
        walk = PolicyWalk(scenario=self.scenario, event=self.event, event_jitter_s=self.onset_jitter_s)
        trial = f"{self.scenario}{tag}_{self.condition}_seed{self.seed}"
        return RolloutJob(self.condition, self.seed, trial, walk)


CODE_PACKAGES = ("ingest", "sim", "metrics", "pipeline")


def rollout_code_hash(root: Path = paths.REPO_ROOT, packages: tuple[str, ...] = CODE_PACKAGES) -> str:
    """sha256 (16 hex) of every module of the project's packages (path and contents): part of each
    job's key, so that a row made by other code is not resumed as this code's (`dvc repro` reruns the
    stage when its code changes, and the finished jobs of before must then run again; an interrupted
    study of the same code still resumes)."""
    h = hashlib.sha256()
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            if "__pycache__" not in path.parts:
                h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def rollout_params_hash(params: Params) -> str:
    """sha256 (16 hex) of the params sections that shape a rollout and its row (`ROLLOUT_SECTIONS`;
    the controllers' gains are part of each job's key instead): adding seeds or subjects to a study
    adds jobs, it does not rename the finished ones."""
    doc = {k: params.document()[k] for k in ROLLOUT_SECTIONS}
    doc["robot"] = {k: v for k, v in doc["robot"].items() if k not in ("controllers", "tuning")}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]


def study_params(params: Params, study: str | None = None) -> SweepSection:
    """The study named `study`: params `sweep` (default), `fall_intervention` or `sensitivity`."""
    sweep, fall = params.section("sweep", SweepSection), params.section("fall_intervention",
                                                                        FallInterventionSection)
    sensitivity = params.section("sensitivity", SensitivitySection)
    if study is None or study == sweep.study:
        return sweep
    for sw in (fall, sensitivity):
        if study == sw.study:
            return sw
    raise params.fail(f"no study {study!r} (sweep.study {sweep.study!r}, fall_intervention.study "
                      f"{fall.study!r} or sensitivity.study {sensitivity.study!r})")


def _policies(sw: SweepSection, policy_root: Path, notes: list[str]) -> list[tuple[str, str, str]]:
    """(subject, variant, policy digest) of the study's subjects and variants that have a policy; a note
    in `notes` for each left out (a subject without a trained policy, a variant without its own)."""
    out = []
    for subject in sw.subjects:
        if not (paths.policy_dir(policy_root, subject) / "policy.zip").is_file():
            notes.append(f"{subject}: no trained policy in {paths.policy_dir(policy_root, subject)}")
            continue
        for variant in sw.variants:
            folder = paths.policy_dir(policy_root, subject, variant)
            if not (folder / "policy.zip").is_file():
                notes.append(f"{subject}/{variant}: no fine-tuned policy in {folder} "
                             f"(`python -m pipeline train {subject} --variant {variant}`)")
                continue
            out.append((subject, variant, policy_digest(folder)))
    return out


def sweep_jobs(params: Params, policy_root: Path = paths.POLICIES_ROOT,
               sw: SweepSection | None = None) -> tuple[list[SweepJob], list[str]]:
    """The study's jobs (default params `sweep`), grouped by subject; and notes on what was left out
    (a subject without a trained policy, a variant without its fine-tuned policy)."""
    sw = sw or params.section("sweep", SweepSection)
    controllers = controller_specs(params)
    if isinstance(sw, SensitivitySection):
        jobs, _, notes = sensitivity_jobs(params, policy_root, sw)
        return jobs, notes
    events = params.section("fall_intervention", FallInterventionSection).events_of(sw.events)
    digest, code = rollout_params_hash(params), rollout_code_hash()
    jobs, notes = [], []
    for subject, variant, policy in _policies(sw, policy_root, notes):
        for condition in sw.conditions:
            gains = {} if condition == "free" else dict(controllers[condition].get("gains", {}))
            jobs += [SweepJob(sw.study, subject, variant, condition, gains, scenario, seed, digest, event,
                              sw.onset_jitter_s if event is not None else 0.0, policy, code_hash=code)
                     for scenario in sw.scenarios for event in events for seed in range(sw.seeds)]
    return jobs, notes


def sensitivity_jobs(params: Params, policy_root: Path = paths.POLICIES_ROOT,
                     sw: SensitivitySection | None = None) -> tuple[list[SweepJob], pd.DataFrame, list[str]]:
    """The responsiveness study's jobs (default params `sensitivity`), its design and notes.

    One factor at a time: each level of each factor (`sim.robot.responsiveness.FACTORS`) with the other
    two at the twin's values (`twin_responsiveness` of params `robot`), the twin's own value of each
    factor included, x subject x variant x controller x scenario x seed. A controller that does not read a
    factor (adaptive: PID gains) runs the twin's robot at every level of it, and the twin's point is one job
    whatever factor it is a level of. The design (`DESIGN_COLUMNS` but the study) has one row per job and
    (factor, level) cell it belongs to; `twin`: the job's robot is the twin's.
    """
    sw = sw or params.section("sensitivity", SensitivitySection)
    robot, controllers = params.section("robot", RobotSection).build(), controller_specs(params)
    twin = twin_responsiveness(robot)
    digest, code = rollout_params_hash(params), rollout_code_hash()
    cells: list[tuple[str, float, Responsiveness]] = []
    for factor, levels in sw.levels().items():
        values = sorted({*levels, getattr(twin, factor)})
        values = [v for i, v in enumerate(values) if i == 0 or not math.isclose(v, values[i - 1])]
        cells += [(factor, float(v), twin.moved(factor, v)) for v in values]
    jobs: dict[str, SweepJob] = {}
    design, notes = [], []
    for subject, variant, policy in _policies(sw, policy_root, notes):
        for condition in sw.conditions:
            for factor, level, point in cells:
                point = for_controller(point, controllers[condition])
                at_twin = point.same(twin)
                _, moved = with_responsiveness(robot, {condition: controllers[condition]}, point)
                gains = dict(moved[condition].get("gains", {}))
                for scenario in sw.scenarios:
                    for seed in range(sw.seeds):
                        job = SweepJob(sw.study, subject, variant, condition, gains, scenario, seed, digest,
                                       policy_hash=policy, responsiveness=None if at_twin else point,
                                       code_hash=code)
                        jobs.setdefault(job.key, job)
                        design.append({"job_key": job.key, "factor": factor, "level": level, "twin": at_twin})
    frame = pd.DataFrame(design, columns=DESIGN_COLUMNS[1:]).drop_duplicates(["job_key", "factor", "level"])
    return list(jobs.values()), frame.reset_index(drop=True), notes


def job_row(worker: Worker, job: SweepJob, exclude_locked: bool,
            fall_rule: FallRuleParams | None = None) -> dict:
    """Run one job on an open world and return its row (`pipeline.store.SWEEP_COLUMNS`; a plain dict:
    cheaper for Ray to ship than a one-row frame)."""
    start = time.perf_counter()
    if job.responsiveness is not None:  # the same open world, the job's robot and gains
        setup = worker.setup
        robot, controllers = with_responsiveness(setup.robot, setup.controllers, job.responsiveness)
        worker = worker.with_setup(dataclasses.replace(setup, robot=robot, controllers=controllers))
    o = worker.run(job.rollout_job(), keep_result=job.event is not None)
    strides = o.tables.get("strides", pd.DataFrame(columns=["kept", "gait_speed_mps", "stride_length_m"]))
    events = o.tables.get("events", pd.DataFrame())
    onset = o.human.driver.event.onset_s if job.event is not None else None
    t = np.arange(len(o.pelvis_z)) / o.sample_rate_hz
    row = {"study": job.study, "job_key": job.key, "subject": job.subject, "variant": job.variant,
           "condition": job.condition, "gains_hash": job.gains_hash, "scenario": job.scenario,
           "seed": job.seed, "params_hash": job.params_hash,
           **run_row(o.robot, strides, o.fell, exclude_locked),
           **event_metrics(job.event_name, onset, t, o.pelvis_z, o.robot, o.robot_fall_s, o.human_fall_s,
                           fall_rule or FallRuleParams()),
           **symmetry_row(strides, events), "wall_s": time.perf_counter() - start}
    return {c: row[c] for c in SWEEP_COLUMNS}


def job_label(failed: dict) -> str:
    """`subject/variant condition scenario event seed N` of a failed job (a `summary["failed"]` entry)."""
    return (f"{failed['subject']}/{failed['variant']} {failed['condition']} {failed['scenario']} "
            f"{failed['event']} seed {failed['seed']}")


def check_failed(summary: dict, root: Path = paths.SWEEPS_ROOT) -> None:
    """Raise `SimulationError` naming the study's failed jobs, if any (after `run_sweep` wrote its outputs:
    the finished jobs are kept, a rerun retries only the failed ones). A sweep with failed jobs is not
    done: under `dvc repro` it must not be recorded as such."""
    failed = summary["failed"]
    if not failed:
        return
    shown = "; ".join(f"{job_label(f)} ({f['error']})" for f in failed[:5])
    more = f"; and {len(failed) - 5} more" if len(failed) > 5 else ""
    listed = paths.sweep_dir(root, summary["study"]) / "summary.json"
    raise SimulationError(f"sweep {summary['study']}",
                          f"{len(failed)} of {summary['jobs']} jobs failed after their retries: "
                          f"{shown}{more} (all in {listed}; the finished jobs are kept: rerun to retry "
                          f"only the failed ones)")


def error_text(exc: BaseException) -> str:
    """`Type: first line of the message` of a failed job, as the summary reports it. An exception the
    job raised comes wrapped in a `RayTaskError` whose text starts with the task's name and pid, not
    the error: it is unwrapped to the job's own exception."""
    if isinstance(exc, RayTaskError) and exc.cause is not None:
        exc = exc.cause
    message = next(iter(str(exc).splitlines()), "")
    return f"{type(exc).__name__}: {message[:300]}"


def run_sweep(params: Params, root: Path = paths.SWEEPS_ROOT, policy_root: Path = paths.POLICIES_ROOT,
              progress: bool = True, on_result: Callable[[SweepJob], None] | None = None,
              study: str | None = None) -> dict:
    """Run the study's missing jobs on Ray and write its outputs; returns the summary. `on_result`:
    called after each finished job (tests use it to kill a worker mid-sweep); `study`: default the
    params' `sweep` study (`study_params`)."""
    sw = study_params(params, study)
    design = None
    if isinstance(sw, SensitivitySection):
        jobs, design, notes = sensitivity_jobs(params, policy_root, sw)
    else:
        jobs, notes = sweep_jobs(params, policy_root, sw)
    fall_rule = params.section("fall_intervention", FallInterventionSection).rule(
        params.section("robot", RobotSection).fall.drop_m)
    ray_params, exclude = params.section("ray", RaySection), params.section("metrics.exclude_locked", bool)
    folder = paths.sweep_dir(root, sw.study)
    job_dir = folder / "jobs"
    job_dir.mkdir(parents=True, exist_ok=True)
    todo = [j for j in jobs if not (job_dir / f"{j.key}.parquet").is_file()]
    failed: list[dict] = []
    if todo:
        connect(ray_params.num_cpus)
        bodies = dict.fromkeys((j.subject, j.variant) for j in todo)
        setups = {(s, v): policy_setup(s, params, policy_root=policy_root, variant=v) for s, v in bodies}
        tasks = [(setups[j.subject, j.variant], j, (exclude, fall_rule)) for j in todo]
        for i, ref in dispatch(tasks, job_row, ray_params.max_retries, retry_exceptions=True,
                               desc=f"sweep {sw.study}", progress=progress):
            job = todo[i]
            try:
                write_outputs(job_dir, {job.key: pd.DataFrame([ray.get(ref)])}, {})
            except Exception as exc:  # retried already: report it, finish the rest
                failed.append({"job_key": job.key, "subject": job.subject, "variant": job.variant,
                               "condition": job.condition, "scenario": job.scenario, "event": job.event_name,
                               "seed": job.seed, "error": error_text(exc)})
            if on_result is not None:
                on_result(job)
    keys = {j.key for j in jobs}
    files = [job_dir / f"{k}.parquet" for k in sorted(keys)]
    rows = [pd.read_parquet(f) for f in files if f.is_file()]
    results = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=SWEEP_COLUMNS)
    if design is not None:  # one row per job and design cell (the twin's jobs are in several)
        results = results.merge(design, on="job_key", how="inner", validate="one_to_many")
    summary = {"study": sw.study, "jobs": len(jobs), "ran": len(todo) - len(failed),
               "resumed": len(jobs) - len(todo), "failed": failed, "notes": notes}
    ran = results[results["job_key"].isin({j.key for j in todo})]
    if len(ran):
        summary["job_wall_s_mean"] = round(float(ran["wall_s"].mean()), 3)
    write_outputs(folder, {"results": results}, {"summary": summary})
    return summary


__all__ = ["CODE_PACKAGES", "SweepJob", "check_failed", "error_text", "job_label", "job_row",
           "rollout_code_hash", "run_sweep", "sensitivity_jobs", "study_params", "sweep_jobs"]
