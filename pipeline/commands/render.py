"""Command `render <subject> <condition>`: an mp4 of one rollout.

Default: a replay rollout (straight bout, seed), run through the batch runner exactly as in
`simulate` (lead-in included, not shown), to `reports/<subject>/rollout_<condition>.mp4`. With
`--scenario NAME`: the steerable policy human walking that scenario (seed), as in `simulate --human
policy`, to `reports/<subject>/rollout_<scenario>_<condition>.mp4`. The frames (`sim.rollout.video`)
show the full human model with the robot's simulated joints, written by OpenCV.
"""

from __future__ import annotations

import os
from pathlib import Path

from pipeline import paths
from pipeline.params import Params
from pipeline.runs.jobs import policy_setup, replay_jobs, replay_setup, scenario_jobs
from pipeline.stages.outputs import replacing
from sim.errors import SimulationError
from sim.robot.section import RobotSection
from sim.rollout.batch import Worker
from sim.rollout.scenarios import ScenariosSection
from sim.rollout.video import rollout_frames

SIZE_PX, FPS = (640, 480), 30.0


def run_render(subject: str, condition: str, params: Params, root: Path = paths.PROCESSED_ROOT,
               reports: Path = paths.REPORTS_ROOT, seed: int = 0, bout: int = 0,
               scenario: str | None = None, policy_root: Path = paths.POLICIES_ROOT) -> Path:
    os.environ.setdefault("MUJOCO_GL", "egl")
    import cv2

    if scenario is None:
        jobs = replay_jobs(subject, params, root, conditions=(condition,), seeds=range(seed, seed + 1))
        if not 0 <= bout < len(jobs):
            raise SimulationError(subject, f"bout {bout} does not exist ({len(jobs)} straight bouts)")
        worker, job, name = Worker(replay_setup(subject, params, root)), jobs[bout], f"rollout_{condition}"
    else:
        commands = params.section("scenarios", ScenariosSection).commands
        if scenario not in commands:
            raise SimulationError(f"scenario {scenario!r}",
                                  f"not in params scenarios ({', '.join(commands)})")
        job = next(j for j in scenario_jobs(params, (condition,), seed + 1, (scenario,)) if j.seed == seed)
        worker = Worker(policy_setup(subject, params, root, policy_root))
        name = f"rollout_{scenario}_{condition}"
    outcome = worker.run(job, keep_result=True)
    robot = params.section("robot", RobotSection).build()
    result, human = outcome.result, outcome.human
    frames = rollout_frames(outcome.world, result.world_qpos, worker.spec, result.human_qpos,
                            human.sample_rate_hz, robot if condition != "free" else None,
                            float(human.driver.start_pose()[0][2]), SIZE_PX, FPS)
    out = paths.report_dir(reports, subject) / f"{name}.mp4"
    with replacing(out) as (tmp,):
        video = tmp.with_suffix(".mp4")
        writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE_PX)
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        writer.release()
        video.replace(tmp)
    return out
