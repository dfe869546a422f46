"""Per-subject tuning (command `tune`, pipeline/cli.py): one subject's controller gains, searched on its
policy human, then compared with the generic gains on walks the search never saw.

The search is Optuna (TPE or CMA-ES, params `tune.method`) through Ray Tune over params
`tune.search.<controller>` (gain -> box; each gain one the class declares as searched, each box within
its declared bounds, checked by `check-params`; each gain on the scale its class declares: `log` ->
log-uniform, `linear` -> uniform, `sim.robot.controllers.gains`): every trial runs the
controller with the trial's gains on `tune.scenarios` x `tune.seeds` and scores the rollouts with
`metrics.outcomes.objective` (tracking |e_x| + |e_y|, harness force, gait speed versus the same
person walking free, falls). The budget (`tune.n_trials`) and procedure are the same for every
controller: the first trial is the controller's generic gains (`pipeline.runs.setup.controller_specs`:
the tuned-gains file on top of params `robot.controllers`, clipped to the search box), the rest come
from the sampler seeded with `tune.seed`. The best trial's gains
and the generic ones then run on `tune.heldout_seeds` x `tune.scenarios`; each rollout's cost is
the objective of that one rollout, reported as mean and Student-t 95 % CI half-width across
rollouts, with the falls, and the tuned minus generic cost of each held-back walk (paired: the same
scenario and seed) as mean and 95 % CI half-width. The result goes to
`data/tuning/<subject>/<variant>/<controller>.json` (committed; the store's `tuned_gains` table and
`tuning_comparison` view read it).

Each Ray process opens the subject's world once (`sim.rollout.cluster.cached_worker`, keyed by the
setup with its generic gains) and swaps in each trial's gains (`trial_worker`); the held-back and
free-walking rollouts go through the batch runner's `sim.rollout.batch.dispatch`.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from metrics.outcomes import ObjectiveWeights, costs, objective, run_row, walk_window
from metrics.phases import mean_ci95
from pipeline import paths
from pipeline.params import Params, ParamsError
from pipeline.runs.jobs import policy_digest, policy_setup, scenario_jobs
from pipeline.stages.outputs import write_json
from sim.body.variant import HEALTHY
from sim.errors import SimulationError
from sim.robot.controllers import resolve
from sim.robot.controllers.gains import searched
from sim.rollout.batch import BatchSetup, RolloutJob, Worker, dispatch_all
from sim.rollout.cluster import cached_worker, connect

METRIC = "objective"
STUDY = "tune"


@dataclasses.dataclass(frozen=True)
class SearchContext:
    """What every trial needs besides its gains (picklable; shipped once through Ray's object store)."""

    base: BatchSetup                 # the subject's setup with the generic gains (the world cache key)
    controller: str
    jobs: tuple[RolloutJob, ...]     # tune.scenarios x tune.seeds
    free_speed_mps: float
    exclude_locked: bool
    weights: ObjectiveWeights


def search_space(params: Params, controller: str) -> dict[str, tuple[float, float]]:
    """`tune.search.<controller>`: gain -> (low, high); a clear error for a controller without one."""
    space = params.tune.search.get(controller)
    if not space:
        raise ParamsError(params.path, f"tune.search has no search space for controller {controller!r}; "
                                       f"controllers with one: {', '.join(sorted(params.tune.search))}")
    return dict(space)


def optuna_space(space: dict[str, tuple[float, float]], controller_class: str) -> dict:
    """Optuna distributions of `space`: log-uniform for a gain its class declares on a `log` scale,
    uniform for a `linear` one (a plug-in that declares no gains: log-uniform when low > 0)."""
    from optuna.distributions import FloatDistribution

    scale = {g: d.search for g, d in searched(resolve(controller_class)).items()}
    return {g: FloatDistribution(lo, hi, log=scale[g] == "log" and lo > 0 if g in scale else lo > 0)
            for g, (lo, hi) in space.items()}


def sampler(params: Params):
    """The Optuna sampler of `tune.method`, seeded with `tune.seed`."""
    import optuna

    t = params.tune
    if t.method == "tpe":
        return optuna.samplers.TPESampler(seed=t.seed)
    try:
        return optuna.samplers.CmaEsSampler(seed=t.seed)
    except ImportError:
        raise ParamsError(params.path, "tune.method cmaes needs the `cmaes` package (pip install cmaes)") \
            from None


def seeded_jobs(params: Params, condition: str, seeds: tuple[int, ...]) -> list[RolloutJob]:
    """One policy-human job per `tune.scenarios` x `seeds`; trial id `<scenario>_<condition>_seed<k>`."""
    first = scenario_jobs(params, conditions=(condition,), walks=1, scenarios=params.tune.scenarios)
    return [dataclasses.replace(job, seed=s, trial=f"{job.human.scenario}_{condition}_seed{s}")
            for job in first for s in seeds]


def with_gains(setup: BatchSetup, controller: str, gains: dict[str, float]) -> BatchSetup:
    """`setup` with `gains` replacing those of `controller` (the others kept)."""
    spec = setup.controllers[controller]
    return dataclasses.replace(setup, controllers={**setup.controllers,
                                                   controller: {**spec, "gains": {**spec["gains"], **gains}}})


def trial_worker(base: BatchSetup, setup: BatchSetup) -> Worker:
    """This process's open world of `base`, running jobs with `setup`'s controllers: the world does not
    depend on the gains (`Worker.prepare` reads `setup.controllers` per job), so a search opens it
    once per process, not once per trial."""
    worker = cached_worker(base, Worker)
    worker.setup = setup
    return worker


def rollout_row(worker: Worker, job: RolloutJob, exclude_locked: bool) -> dict:
    """`metrics.outcomes.run_row` of one job on `worker` over the walk itself (`walk_window` of its
    scenario's commands), with the job's trial id and seed. A fall, or the arm's lock on one, counts
    when it happens before the walk's final quiet standing; one after it (`late_fall`) is counted apart
    and not scored: there the policy human topples whatever the controller (docs/robot.md, "Per-subject
    controller tuning"), so scoring it would score the human, not the gains."""
    o = worker.run(job, keep_result=True)
    commands = getattr(o.human.driver, "commands", None)
    window = walk_window(commands.spans()) if commands is not None else (-np.inf, np.inf)
    late = o.stable and o.first_fall_s is not None and o.first_fall_s > window[1]
    strides = o.tables.get("strides", pd.DataFrame())
    row = run_row(o.robot, strides, o.fell and not late, exclude_locked, window)
    return {"trial": job.trial, "scenario": job.human.scenario, "seed": job.seed, **row, "late_fall": late}


def _row_with(worker: Worker, job: RolloutJob, setup: BatchSetup, exclude_locked: bool) -> dict:
    """`rollout_row` on a dispatched worker (the open world of the base setup) under `setup`'s gains."""
    worker.setup = setup
    return rollout_row(worker, job, exclude_locked)


def parallel_rows(base: BatchSetup, runs: list[tuple[BatchSetup, RolloutJob]], exclude_locked: bool,
                  desc: str, progress: bool, max_retries: int = 1) -> pd.DataFrame:
    """`rollout_row` of each (setup, job) as Ray tasks on open worlds of `base`, rows in the order given."""
    return pd.DataFrame(dispatch_all([(base, job, (setup, exclude_locked)) for setup, job in runs], _row_with,
                                     max_retries, desc=desc, progress=progress))


def free_speed(rows: pd.DataFrame, subject: str) -> float:
    """Mean gait speed of the free-walking rows (the objective's reference speed)."""
    speed = rows["gait_speed_mps"].to_numpy(float)
    if not np.isfinite(speed).any():
        raise SimulationError(f"{subject} free walking", "no kept strides in any tune scenario and seed: "
                                                         "no reference gait speed for the objective")
    return float(np.nanmean(speed))


def heldout_summary(rows: pd.DataFrame, free_speed_mps: float, w: ObjectiveWeights) -> dict:
    """Per-rollout cost (the objective of that one rollout): mean, 95 % CI half-width (Student t
    across rollouts; None with one rollout) and the falls."""
    each = costs(rows, free_speed_mps, w)
    mean, half = mean_ci95(each)
    return {"mean": float(mean), "ci95": float(half) if len(each) > 1 else None,
            "falls": int(rows["fell"].astype(bool).sum()),
            "late_falls": int(rows["late_fall"].astype(bool).sum()),
            "costs": each.tolist()}


def trial_objective(config: dict, ctx: SearchContext) -> None:
    """A Ray Tune trial: the controller with the trial's gains on the search jobs, one after the other
    in this trial's process; reports `objective`."""
    from ray import tune

    setup = with_gains(ctx.base, ctx.controller, config)
    rows = pd.DataFrame([rollout_row(trial_worker(ctx.base, setup), job, ctx.exclude_locked)
                         for job in ctx.jobs])
    tune.report({METRIC: objective(rows, ctx.free_speed_mps, ctx.weights),
                 "falls": int(rows["fell"].astype(bool).sum())})


@contextmanager
def _environ(**values: str) -> Iterator[None]:
    """Environment variables set for the duration (Ray Tune reads its switches from there)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def search(ctx: SearchContext, params: Params, n_trials: int, generic: dict[str, float],
           progress: bool) -> list[dict]:
    """`n_trials` Optuna trials through Ray Tune (at most `ray.num_cpus` at once); the first is the
    generic gains clipped to the search box. History in trial order: {trial, gains, objective}."""
    import optuna
    from ray import tune
    from ray.tune.search.optuna import OptunaSearch

    optuna.logging.set_verbosity(optuna.logging.WARNING)  # the progress bar says what the study does
    space = search_space(params, ctx.controller)
    start = {g: float(min(max(generic[g], lo), hi)) for g, (lo, hi) in space.items()}
    storage = optuna.storages.InMemoryStorage()  # the study's own record: trials numbered as suggested
    cls = ctx.base.controllers[ctx.controller]["class"]
    alg = OptunaSearch(optuna_space(space, cls), metric=METRIC, mode="min", points_to_evaluate=[start],
                       sampler=sampler(params), study_name=STUDY, storage=storage)
    bar = tqdm(total=n_trials, desc=f"tune {ctx.base.subject} {ctx.controller}", disable=not progress)

    class _Progress(tune.Callback):
        def on_trial_result(self, iteration, trials, trial, result, **info) -> None:
            bar.update()
            bar.set_postfix(objective=f"{result[METRIC]:.4f}")

    with tempfile.TemporaryDirectory(prefix="gaitloop-tune-") as tmp, \
            _environ(TUNE_DISABLE_AUTO_CALLBACK_LOGGERS="1", RAY_AIR_NEW_OUTPUT="0"):
        tuner = tune.Tuner(
            tune.with_parameters(trial_objective, ctx=ctx),
            tune_config=tune.TuneConfig(search_alg=alg, num_samples=n_trials, reuse_actors=True,
                                        max_concurrent_trials=params.ray.num_cpus),
            run_config=tune.RunConfig(name="tune", storage_path=tmp, verbose=0, callbacks=[_Progress()],
                                      failure_config=tune.FailureConfig(max_failures=params.ray.max_retries)))
        grid = tuner.fit()
        bar.close()
    errors = [r.error for r in grid if r.error is not None]
    if errors:
        raise SimulationError(f"tune {ctx.base.subject} {ctx.controller}",
                              f"{len(errors)} of {n_trials} trials failed; the first: {errors[0]}")
    falls = {tuple(float(r.config[g]) for g in space): int(r.metrics["falls"]) for r in grid}
    trials = sorted(optuna.load_study(study_name=STUDY, storage=storage).trials, key=lambda t: t.number)
    return [{"trial": t.number, "gains": {g: float(t.params[g]) for g in space}, METRIC: float(t.value),
             "falls": falls.get(tuple(float(t.params[g]) for g in space))} for t in trials]


def search_falls(history: list[dict], rollouts_per_trial: int) -> dict[str, int]:
    """Rollouts of the search and how many fell. When every one fell the objective is the same
    for every trial (the fall penalty), the search has no signal, and the "tuned" gains are the
    first trial's, the generic ones: the store's `tuning_comparison` says so (`search_status`)."""
    return {"search_rollouts": len(history) * rollouts_per_trial,
            "search_falls": int(sum(h["falls"] or 0 for h in history))}


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def run_tune(subject: str, controller: str, params: Params, variant: str = HEALTHY,
             n_trials: int | None = None, out_root: Path = paths.TUNING_ROOT, progress: bool = True) -> Path:
    """Tune `controller`'s gains for `subject`'s policy human (variant `healthy`: its own policy),
    compare with the generic gains on held-back walks; returns the written JSON's path."""
    params.variant(variant)  # a declared one (ParamsError lists them)
    space = search_space(params, controller)
    n_trials = params.tune.n_trials if n_trials is None else int(n_trials)
    if n_trials < 1:
        raise ParamsError(params.path, f"--n-trials {n_trials}: at least one trial")
    t0 = time.perf_counter()
    base = policy_setup(subject, params, variant=variant)
    t, exclude, w = params.tune, params.metrics.exclude_locked, params.tune.weights()
    connect(params.ray.num_cpus)

    retries = params.ray.max_retries
    free_rows = parallel_rows(base, [(base, j) for j in seeded_jobs(params, "free", t.seeds)], exclude,
                              f"free walking {subject}", progress, retries)
    speed = free_speed(free_rows, subject)
    ctx = SearchContext(base, controller, tuple(seeded_jobs(params, controller, t.seeds)), speed, exclude, w)
    generic = dict(base.controllers[controller]["gains"])
    history = search(ctx, params, n_trials, generic, progress)
    best = min(history, key=lambda h: h[METRIC])
    tuned = {**generic, **best["gains"]}

    heldout = seeded_jobs(params, controller, t.heldout_seeds)
    tuned_setup = with_gains(base, controller, tuned)
    rows = parallel_rows(base, [(base, j) for j in heldout] + [(tuned_setup, j) for j in heldout], exclude,
                         f"held-back {subject} {controller}", progress, retries)
    gen, tun = (heldout_summary(rows.iloc[k * len(heldout):(k + 1) * len(heldout)], speed, w) for k in (0, 1))
    diff_mean, diff_half = mean_ci95(np.subtract(tun["costs"], gen["costs"]))  # the same walks, paired
    doc = {"subject": subject, "variant": variant, "controller": controller, "method": t.method,
           "n_trials": n_trials, "seed": t.seed, "generic_gains": generic, "tuned_gains": tuned,
           "search_best_objective": best[METRIC], **search_falls(history, len(ctx.jobs)),
           "generic_mean": gen["mean"], "generic_ci95": _finite(gen["ci95"]), "generic_falls": gen["falls"],
           "tuned_mean": tun["mean"], "tuned_ci95": _finite(tun["ci95"]), "tuned_falls": tun["falls"],
           "generic_late_falls": gen["late_falls"], "tuned_late_falls": tun["late_falls"],
           "paired_difference_mean": _finite(diff_mean), "paired_difference_ci95": _finite(diff_half),
           "n_heldout": len(heldout), "scenarios": list(t.scenarios), "seeds": list(t.seeds),
           "heldout_seeds": list(t.heldout_seeds), "search_space": {g: list(b) for g, b in space.items()},
           "free_speed_mps": speed, "history": history,
           "policy_sha256_16": policy_digest(paths.policy_dir(paths.POLICIES_ROOT, subject, variant)),
           "heldout_costs": {"generic": gen["costs"], "tuned": tun["costs"],
                             "trials": [j.trial for j in heldout]},
           "wall_s": round(time.perf_counter() - t0, 1)}
    path = paths.tuning_file(out_root, subject, variant, controller)
    write_json(path, doc)
    return path


__all__ = ["SearchContext", "heldout_summary", "optuna_space", "parallel_rows", "rollout_row", "run_tune",
           "search", "search_falls", "search_space", "seeded_jobs", "trial_worker", "with_gains"]
