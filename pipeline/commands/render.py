"""Command `render <subject> <condition>`: an mp4 of one replay rollout (straight bout, seed).

The rollout runs exactly as in `simulate`; the frames show the full human model (limbs from the
reference, pelvis from the simulation) with the robot's simulated joints, rendered offscreen by
MuJoCo (EGL when no display: set MUJOCO_GL=egl) and written by OpenCV to
`reports/<subject>/rollout_<condition>.mp4`.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd

from pipeline.params import Params
from pipeline.paths import PROCESSED_ROOT, REPORTS_ROOT, human_xml, real_dir, reference_npz, report_dir
from pipeline.stages.outputs import replacing
from pipeline.stages.simulate import straight_bouts
from sim.errors import SimulationError
from sim.motion.reference import load_reference
from sim.motion.replay import Motion, ReplayHuman
from sim.robot.controllers import make_controller
from sim.robot.mrba import attach_robot
from sim.rollout.loop import RolloutParams, rollout
from sim.rollout.world import build_world, robot_info

WIDTH, HEIGHT, FPS = 640, 480, 30


def render_frames(physics: mujoco.MjModel, world_qpos: np.ndarray, human_spec: mujoco.MjSpec,
                  human_qpos: np.ndarray, rate_hz: float, with_robot: bool, robot_section,
                  neutral_height_m: float) -> list[np.ndarray]:
    """RGB frames at `FPS` of the full human (its own joints) plus the robot joints of `physics`."""
    spec = human_spec.copy()
    if with_robot:
        attach_robot(spec, robot_section, neutral_height_m=neutral_height_m)
    model = spec.compile()
    data = mujoco.MjData(model)
    nh = human_qpos.shape[1]
    pairs = []
    for j in range(physics.njnt):
        name = physics.joint(j).name
        if name.startswith("mrba_"):
            k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            pairs.append((model.jnt_qposadr[k], physics.jnt_qposadr[j]))
    dst, src = (np.array(a, int) for a in zip(*pairs, strict=True)) if pairs else (np.zeros(0, int),) * 2
    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    renderer = mujoco.Renderer(model, HEIGHT, WIDTH)
    cam = mujoco.MjvCamera()
    cam.distance, cam.azimuth, cam.elevation = 3.5, 125.0, -15.0
    frames = []
    for k in np.arange(0, len(human_qpos), max(int(round(rate_hz / FPS)), 1)):
        data.qpos[:nh] = human_qpos[k]
        data.qpos[dst] = world_qpos[k, src]
        mujoco.mj_kinematics(model, data)
        cam.lookat[:] = data.xpos[pelvis] * np.array([1, 1, 0]) + np.array([0, 0, 0.8])
        renderer.update_scene(data, cam)
        frames.append(renderer.render().copy())
    renderer.close()
    return frames


def run_render(subject_id: str, condition: str, params: Params, root: Path = PROCESSED_ROOT,
               reports: Path = REPORTS_ROOT, seed: int = 0, bout: int = 0) -> Path:
    os.environ.setdefault("MUJOCO_GL", "egl")
    import cv2

    section = params.simulate_section()
    spec = mujoco.MjSpec.from_file(str(human_xml(root, subject_id)))
    ref = load_reference(reference_npz(root, subject_id))
    strides = pd.read_parquet(real_dir(root, subject_id) / "strides.parquet")
    bouts = [(tr, b) for tr in sorted(set(ref.trial.tolist()))
             for b in straight_bouts(strides, tr, section.bout_margin_s)]
    if not 0 <= bout < len(bouts):
        raise SimulationError(subject_id, f"bout {bout} does not exist ({len(bouts)} straight bouts)")
    trial, (t0, t1) = bouts[bout]
    time_s, qpos = ref.motion(trial)
    rows = (time_s >= t0) & (time_s <= t1)
    rate = float(1.0 / np.median(np.diff(time_s)))
    human = ReplayHuman(Motion(time_s[rows] - time_s[rows][0], qpos[rows]), params.rollout.replay.build())
    with_robot = condition != "free"
    p = RolloutParams(robot=section.robot, sample_rate_hz=rate, max_physics_dt_s=section.max_physics_dt_s,
                      start_offset_m=section.start_offset_m, with_robot=with_robot, subject=subject_id,
                      condition=condition, trial=trial)
    ctrl = None
    if with_robot:
        if condition not in section.controllers:
            raise SimulationError(subject_id, f"condition {condition!r} is neither free nor in "
                                  "robot.controllers")
        ctrl = make_controller(section.controllers[condition], robot_info(section.robot))
    physics = build_world(spec, human, p)
    result = rollout(spec, human, ctrl, p, seed, model=physics)
    frames = render_frames(physics, result.world_qpos, spec, result.human_qpos, rate, with_robot,
                           section.robot, float(human.start_pose()[0][2]))
    out = report_dir(reports, subject_id) / f"rollout_{condition}.mp4"
    with replacing(out) as (tmp,):
        video = tmp.with_suffix(".mp4")
        writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (WIDTH, HEIGHT))
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        writer.release()
        video.replace(tmp)
    return out
