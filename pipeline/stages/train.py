"""Stage `train <subject>`: PPO + AMP on the subject's scaled human and reference cycle
(`sim.learn.train`); the policy goes to `data/policies/<subject>/` (policy.zip, vecnormalize.pkl,
amp.pt, progress.json with the exact commands, steps and wall time of every run; metrics via
dvclive or metrics.csv). The DVC stage is frozen: the committed policy is its output.
"""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline import paths
from pipeline.params import Params
from pipeline.runs.setup import fine_tune_steps, train_params
from sim.body.variant import HEALTHY, CohortSection
from sim.errors import SimulationError
from sim.learn.train import POLICY_FILE, train
from sim.learn.train_ray import train_on_ray
from sim.motion.reference import load_reference


def train_inputs(subject: str, root: Path) -> tuple[Path, Path]:
    """The scaled human and reference motion a policy of `subject` trains on (checked to exist)."""
    xml, npz = paths.human_xml(root, subject), paths.reference_npz(root, subject)
    for f in (xml, npz):
        if not f.exists():
            raise SimulationError(f, f"missing input of the policy stages for {subject} (run `python -m "
                                  f"pipeline scale {subject}` and `reference {subject}`)")
    return xml, npz


def run_train(subject: str, params: Params, *, n_envs: int | None, threads: int | None, steps: int | None,
              resume: bool, root: Path = paths.PROCESSED_ROOT, out_root: Path = paths.POLICIES_ROOT,
              max_wall_s: float | None = None, subprocess: bool | None = None,
              init_from: str | None = None, on_ray: bool = False, variant: str = HEALTHY) -> dict:
    """Train `subject`'s policy; `init_from`: another subject whose committed policy is the start;
    `on_ray`: as one Ray job (`sim.learn.train_ray.train_on_ray`: locally, or on a node of the
    `RAY_ADDRESS` cluster) of as many CPUs as it uses (its environment processes, else its threads).
    `variant`: fine-tune cohort variant `variant` from the subject's own policy (params `cohort`:
    its body and goals, its `fine_tune_steps` unless `steps`; the body and speed ramp in over
    `curriculum_fraction` x `cohort.fine_tune_steps`) into `data/policies/<subject>/cohort/<variant>`."""
    p = train_params(params, variant)
    start = None
    if variant != HEALTHY:
        if init_from is not None:
            raise SimulationError(f"train {subject} --variant {variant}",
                                  "a variant starts from the subject's own policy: drop --init-from")
        init_from, steps = subject, steps or fine_tune_steps(params, variant)
        cohort = params.section("cohort", CohortSection)
        curriculum = int(cohort.curriculum_fraction * cohort.fine_tune_steps)
    else:
        curriculum = 0
    if init_from is not None and not resume:
        start = paths.policy_dir(out_root, init_from)
        if not (start / POLICY_FILE).exists():
            raise SimulationError(start, f"no trained policy of {init_from!r} to start {subject}'s from")
    xml, npz = train_inputs(subject, root)
    reference = load_reference(npz)
    cycle = reference.cycle
    command = "python -m pipeline train " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["train"] else ""
    kwargs = {"n_envs": n_envs, "threads": threads, "total_steps": steps, "resume": resume,
              "max_wall_s": max_wall_s, "subprocess": subprocess, "command": command,
              "curriculum_steps": curriculum,
              # the recorded motion is the healthy subject's own: a variant's changed body keeps its cycle
              "motion": reference if variant == HEALTHY else None}
    if on_ray:
        in_processes = p.subprocess if subprocess is None else subprocess
        cpus = (n_envs or p.n_envs) if in_processes else (threads or p.threads)
        return train_on_ray(xml, cycle, p, paths.policy_dir(out_root, subject, variant), cpus=cpus,
                            init_from=start, **kwargs)
    return train(xml, cycle, p, paths.policy_dir(out_root, subject, variant), init_from=start, **kwargs)
