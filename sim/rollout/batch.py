"""The one batch runner: many rollouts of one subject's human, in this process or on Ray.

A `RolloutJob` names a condition (`free` or a controller of `BatchSetup.controllers`), a seed, the
simulated trial's id and the human driver's own description of the job. Each worker opens the
subject's world once (`Worker`): the MuJoCo spec, the human model for virtual markers, and the
driver source (`DriverSource.open`: the replay reference or the trained policy). Per job it builds
the driver and the controller, runs `sim.rollout.loop.rollout`, and turns the human's motion into a
canonical sim `Trial` through the virtual markers, processed by `ingest.process.process_trial`
exactly like a real trial. Parallel jobs run as Ray tasks through `dispatch`, the one Ray dispatch of
the project (`BatchRunner` here, the sweep, the per-subject tuning; `sim.rollout.cluster`).
Simulate (replay human), policy rollouts, render, sweeps and the rollout bench all run here, so
every rollout of the project is set up one way.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np
import pandas as pd
import ray
from tqdm import tqdm

from ingest.errors import IngestError
from ingest.process import IngestParams, ProcessedTrial, process_trial
from ingest.robot import ROBOT_COLUMNS
from sim.body.markers import trial_from_qpos
from sim.errors import SimulationError
from sim.motion.driver import HumanDriver
from sim.motion.reference import Reference
from sim.robot.controllers import make_controller
from sim.robot.controllers.base import Controller
from sim.robot.controllers.warm_start import WarmStarted
from sim.robot.mrba import RobotParams
from sim.rollout.cluster import cached_worker, completed, connect
from sim.rollout.loop import RolloutParams, RolloutResult, rollout
from sim.rollout.world import build_world, robot_info

TABLES = ("events", "strides", "cycles")


@dataclass(frozen=True)
class HumanRun:
    """A driver source's answer for one job: the driver and how its samples are timed."""

    driver: HumanDriver
    sample_rate_hz: float
    discard_s: float = 0.0                # lead-in simulated but not recorded
    t0_s: float = 0.0                     # the first recorded sample's time in the trial's own clock
    warm_speed_mps: float | None = None   # controller warm start: the human is already walking


class DriverSource(Protocol):
    """Picklable description of a kind of human; `open` runs once per worker and returns the
    function that makes one job's `HumanRun` from (the job's `human` field, its seed)."""

    def open(self, world: mujoco.MjSpec) -> Callable[[Any, int], HumanRun]: ...


@dataclass(frozen=True)
class RolloutJob:
    condition: str        # "free" (no robot) or a name in `BatchSetup.controllers`
    seed: int
    trial: str            # id of the simulated trial
    human: Any            # the driver source's own job description (picklable)


@dataclass(frozen=True)
class BatchSetup:
    """Everything a worker needs, picklable: the subject's world and how to run and process it."""

    human_xml: str
    subject: str
    markerset: dict[str, str]
    robot: RobotParams
    controllers: dict[str, dict]
    ingest: IngestParams
    max_physics_dt_s: float
    start_offset_m: float
    drivers: DriverSource
    process: bool = True  # False: no virtual-marker processing (benchmarks, worlds without markers)
    stop_after_fall_s: float | None = None  # `RolloutParams.stop_after_fall_s`


@dataclass
class RolloutOutcome:
    """One job's results: the robot table, the processed sim tables (or why they were skipped)."""

    job: RolloutJob
    human_mode: str
    stable: bool
    warnings: dict[str, int]
    robot_fall_s: float | None
    human_fall_s: float | None
    wall_s: float
    sim_s: float
    distance_m: float
    robot: pd.DataFrame
    pelvis_xy: np.ndarray | None = None   # (n, 2) the human's root position per recorded sample
    pelvis_z: np.ndarray | None = None    # (n,) its height
    sample_rate_hz: float = 0.0
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    skipped: str | None = None
    result: RolloutResult | None = None  # kept only when asked (render): world qpos is large
    world: mujoco.MjModel | None = None  # the compiled world of `result`, kept with it
    human: HumanRun | None = None        # the driver that ran, kept with it
    probe: Any = None                    # what `Worker.run(..., probe=)` recorded

    @property
    def fell(self) -> bool:
        """The human fell, the robot detected a fall, or the simulation went unstable."""
        return self.human_fall_s is not None or self.robot_fall_s is not None or not self.stable

    @property
    def first_fall_s(self) -> float | None:
        """When the human fell or the robot detected a fall, whichever came first (None: neither)."""
        return min((t for t in (self.human_fall_s, self.robot_fall_s) if t is not None), default=None)


class Worker:
    """One process's open world: runs jobs one after the other."""

    def __init__(self, setup: BatchSetup) -> None:
        self.setup = setup
        self.spec = mujoco.MjSpec.from_file(setup.human_xml)
        self.human_model = mujoco.MjModel.from_xml_path(setup.human_xml)
        self.make_run = setup.drivers.open(self.spec)

    def with_setup(self, setup: BatchSetup) -> Worker:
        """This open world (spec, human model, driver source) under another setup of the same human: another
        robot or other controller gains (a sweep's robot variations: `dataclasses.replace(worker.setup, ...)`,
        the same driver source object), without reopening the world."""
        if setup.human_xml != self.setup.human_xml or setup.drivers is not self.setup.drivers:
            raise SimulationError(setup.human_xml, "with_setup: another human needs its own Worker")
        other = copy.copy(self)
        other.setup = setup
        return other

    def prepare(self, job: RolloutJob) -> tuple[HumanRun, Controller | None, RolloutParams]:
        """The job's driver, controller (None for free walking) and rollout params."""
        s = self.setup
        run = self.make_run(job.human, job.seed)
        with_robot = job.condition != "free"
        ctrl = None
        if with_robot:
            if job.condition not in s.controllers:
                raise SimulationError(f"condition {job.condition}", "neither free nor in robot.controllers")
            ctrl = make_controller(s.controllers[job.condition], robot_info(s.robot))
            if run.warm_speed_mps is not None:
                ctrl = WarmStarted(ctrl, run.warm_speed_mps)
        p = RolloutParams(robot=s.robot, sample_rate_hz=run.sample_rate_hz,
                          max_physics_dt_s=s.max_physics_dt_s, start_offset_m=s.start_offset_m,
                          with_robot=with_robot, subject=s.subject,
                          condition=job.condition, trial=job.trial, discard_s=run.discard_s,
                          stop_after_fall_s=s.stop_after_fall_s)
        return run, ctrl, p

    def run(self, job: RolloutJob, keep_result: bool = False,
            probe: Callable[[mujoco.MjModel], Any] | None = None) -> RolloutOutcome:
        """One job. `probe`: made from the compiled world, called at every sample (see `rollout`) and
        kept in the outcome (e.g. `sim.body.ground_reaction.GroundReactionProbe`)."""
        run, ctrl, p = self.prepare(job)
        human = run.driver
        world = build_world(self.spec, human, p)
        probing = probe(world) if probe is not None else None
        result = rollout(self.spec, human, ctrl, p, job.seed, model=world, probe=probing)
        human_fall = getattr(human, "fall_time_s", None)
        out = RolloutOutcome(
            job=job, human_mode=human.mode, stable=result.stable, warnings=result.warnings,
            robot_fall_s=result.fall_time_s, human_fall_s=human_fall, wall_s=result.wall_s,
            sim_s=result.n_physics_steps * result.physics_dt_s,
            distance_m=float(result.human_qpos[-1, 0] - result.human_qpos[0, 0]), robot=result.robot,
            pelvis_xy=result.human_qpos[:, :2].copy(), pelvis_z=result.human_qpos[:, 2].copy(),
            sample_rate_hz=run.sample_rate_hz,
            result=result if keep_result else None, world=world if keep_result else None,
            human=run if keep_result else None, probe=probing)
        if not self.setup.process:
            return out
        qpos = result.human_qpos
        if human_fall is not None:  # gait analysis of the walking before the fall only
            qpos = qpos[result.time_s < human_fall]
        try:
            processed = process_motion(self.human_model, qpos, run.sample_rate_hz, self.setup.subject,
                                       job.condition, job.trial, self.setup.markerset, self.setup.ingest,
                                       t0_s=run.t0_s)
            extra = {"human_mode": human.mode, "seed": job.seed}
            out.tables = {k: getattr(processed, k).assign(**extra) for k in TABLES}
        except (IngestError, SimulationError) as exc:
            out.skipped = str(exc)
        return out


def process_motion(model: mujoco.MjModel, qpos: np.ndarray, rate_hz: float, subject: str, condition: str,
                   trial: str, markerset: dict[str, str], ingest: IngestParams, t0_s: float = 0.0
                   ) -> ProcessedTrial:
    """A motion of `model` as a canonical sim `Trial` (virtual markers, joint angles), processed by
    `ingest.process.process_trial` exactly like a real recording."""
    sim_trial = trial_from_qpos(model, qpos, rate_hz, subject, condition, trial, t0_s=t0_s)
    return process_trial(sim_trial, markerset, ingest)


def reference_cycles(model: mujoco.MjModel, reference: Reference, subject: str, markerset: dict[str, str],
                     ingest: IngestParams, condition: str = "free") -> pd.DataFrame:
    """Cycles of the subject's recorded `condition` trials as retargeted onto `model` and processed
    like a simulation: the real gait in the model's joint definitions and event detection (the
    reference a policy human is held to)."""
    parts = []
    for trial in sorted(set(reference.trial[reference.condition == condition].tolist())):
        t, q = reference.motion(trial)
        parts.append(process_motion(model, q, reference.rate_hz(trial), subject, condition, trial, markerset,
                                    ingest, t0_s=float(t[0])).cycles)
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


@ray.remote(num_cpus=1)
def _call(setup: BatchSetup, fn: Callable[..., Any], job: Any, args: tuple) -> Any:
    """`fn(worker, job, *args)` in a Ray worker, on the worker's cached open world of `setup`."""
    return fn(cached_worker(setup, Worker), job, *args)


def dispatch(tasks: Iterable[tuple[Any, Any, tuple]], fn: Callable[..., Any], max_retries: int = 1,
             retry_exceptions: bool = False, desc: str = "rollouts", progress: bool = False
             ) -> Iterator[tuple[int, ray.ObjectRef]]:
    """The one Ray dispatch of the project's rollouts: ``fn(worker, job, *args)`` for each task
    ``(setup, job, args)`` as a Ray task on that worker process's open world of `setup`
    (`cached_worker`; each distinct setup object is put in Ray's object store once, an `ObjectRef`
    is taken as is). Yields (index of the task, its result's reference) as each task finishes, with a
    progress bar: `ray.get` of the reference returns the result or raises the task's error. A task
    whose worker died is retried `max_retries` times; with `retry_exceptions` so is one that raised.
    Connect first (`sim.rollout.cluster.connect`). `fn` must be importable (a module-level function)."""
    refs_of: dict[int, tuple[Any, Any]] = {}
    task = _call.options(max_retries=int(max_retries), retry_exceptions=bool(retry_exceptions))
    refs = []
    for setup, job, args in tasks:
        if not isinstance(setup, ray.ObjectRef):
            if id(setup) not in refs_of:
                refs_of[id(setup)] = (setup, ray.put(setup))  # the setup kept: its id stays its own
            setup = refs_of[id(setup)][1]
        refs.append(task.remote(setup, fn, job, tuple(args)))
    index = {ref: i for i, ref in enumerate(refs)}
    for ref in completed(refs, desc, progress):
        yield index[ref], ref


def dispatch_all(tasks: Iterable[tuple[Any, Any, tuple]], fn: Callable[..., Any], max_retries: int = 1,
                 retry_exceptions: bool = False, desc: str = "rollouts", progress: bool = False) -> list:
    """`dispatch`'s results in task order (the first failed task's error raises)."""
    refs = [ref for _, ref in sorted(dispatch(tasks, fn, max_retries, retry_exceptions, desc, progress),
                                     key=lambda pair: pair[0])]
    return ray.get(refs)


class BatchRunner:
    """Runs jobs of one `BatchSetup`: in this process with `workers <= 1`, else as Ray tasks on
    `workers` CPUs of a local Ray instance (or the cluster of `RAY_ADDRESS`; `sim.rollout.cluster`),
    through `dispatch`. A task whose worker died is retried `max_retries` times (a job is a pure
    function of its inputs); an exception a job raises is not retried and propagates."""

    def __init__(self, setup: BatchSetup, workers: int = 1, max_retries: int = 1) -> None:
        self.setup, self.workers, self.max_retries = setup, max(1, int(workers)), int(max_retries)
        self._local: Worker | None = None
        self._setup_ref = None

    def __enter__(self) -> BatchRunner:
        if self.workers > 1:
            connect(self.workers)
            self._setup_ref = ray.put(self.setup)
        else:
            self._local = Worker(self.setup)
        return self

    def __exit__(self, *exc: object) -> None:
        self._local = self._setup_ref = None

    def map(self, jobs: Iterable[RolloutJob], desc: str = "rollouts", progress: bool = False
            ) -> list[RolloutOutcome]:
        """Outcomes in job order, with a progress bar when `progress`."""
        jobs = list(jobs)
        if self._setup_ref is None:
            return [self._local.run(job) for job in tqdm(jobs, desc=desc, disable=not progress)]
        return dispatch_all([(self._setup_ref, job, ()) for job in jobs], Worker.run, self.max_retries,
                            desc=desc, progress=progress)


def run_batch(setup: BatchSetup, jobs: Iterable[RolloutJob], workers: int = 1, desc: str = "rollouts",
              progress: bool = False) -> list[RolloutOutcome]:
    """Every job of `setup`, outcomes in job order (see `BatchRunner`)."""
    with BatchRunner(setup, workers) as runner:
        return runner.map(jobs, desc, progress)


def batch_tables(outcomes: Iterable[RolloutOutcome]) -> dict[str, pd.DataFrame]:
    """events, strides, cycles and robot tables of all outcomes, each concatenated in job order."""
    outcomes = list(outcomes)
    tables = {}
    for name in TABLES:
        parts = [o.tables[name] for o in outcomes if name in o.tables]
        tables[name] = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
    robot = [o.robot for o in outcomes if not o.robot.empty]
    tables["robot"] = (pd.concat(robot, ignore_index=True)[ROBOT_COLUMNS] if robot
                       else pd.DataFrame(columns=ROBOT_COLUMNS))
    return tables


__all__ = ["BatchRunner", "BatchSetup", "DriverSource", "HumanRun", "RolloutJob", "RolloutOutcome", "Worker",
           "batch_tables", "dispatch", "dispatch_all", "process_motion", "reference_cycles", "run_batch"]
