"""Bench section `policy_rollout`: the policy-human rollout loop against raw `mj_step`.

One worker of the batch runner (`sim.rollout.batch.Worker`) runs camargo's committed policy human
walking with the `adaptive` controller for `duration_s`; the loop time (policy inference, PD
servos, robot control and recording included) is compared with raw `mj_step` of the same compiled
world for the same number of steps from the rollout's initial state, timed in adjacent pairs (median
of the pair ratios). Target >= 0.8 (the closed-loop scenarios issue). The policy's forward pass is
plain numpy (`sim.learn.policy_human.ActorMlp`, ~25 us) and the human's samples are taken from the
world qpos after the loop; what remains per 10 s is the policy step's features and reference
(~0.3 ms x 333) and the controller's 1000 Python ticks. Batching the forward pass across a
worker's rollouts would need the rollouts to run in lockstep; not done.
"""

from __future__ import annotations

import numpy as np

from ingest.subject import load_subject
from pipeline import paths
from pipeline.bench.rollout import raw_step_s
from pipeline.params import Params
from sim.rollout.batch import RolloutJob, Worker

POLICY_ROLLOUT_TARGETS = {"ratio_to_mj_step": 0.8}
SUBJECT = "camargo"


def time_policy_rollout(params: Params, repeat: int = 3, duration_s: float = 10.0,
                        rate_hz: float = 100.0) -> dict:
    from sim.learn.policy_human import PolicySource, PolicyWalk
    from sim.learn.train import BODY_FILE

    folder = paths.policy_dir(paths.POLICIES_ROOT, SUBJECT)
    source = PolicySource(str(folder), params.train_params().env, rate_hz,
                          params.evaluate_policy.fall_height_fraction)
    setup = params.batch_setup(SUBJECT, load_subject(SUBJECT).markerset, folder / BODY_FILE, source,
                               process=False)
    worker = Worker(setup)
    walls, raws = [], []
    for seed in range(repeat):
        out = worker.run(RolloutJob("adaptive", seed, f"bench_seed{seed}", PolicyWalk(duration_s)),
                         keep_result=True)
        result = out.result
        raws.append(raw_step_s(out.world, result))
        walls.append(result.wall_s)
    walls_a, raws_a = np.array(walls), np.array(raws)
    return {"subject": SUBJECT, "controller": "adaptive", "duration_s": duration_s, "sample_rate_hz": rate_hz,
            "physics_steps": result.n_physics_steps, "rollout_loop_s": round(float(walls_a.min()), 4),
            "raw_mj_step_s": round(float(raws_a.min()), 4),
            "ratio_to_mj_step": round(float(np.median(raws_a / walls_a)), 3),
            "realtime_factor": round(duration_s / float(walls_a.min()), 1)}
