"""Video frames of a rollout: the full human model (limbs from its own qpos) with the robot's
simulated joints, rendered offscreen by MuJoCo (EGL or OSMesa when there is no display)."""

from __future__ import annotations

import mujoco
import numpy as np

from sim.robot.mrba import RobotParams, attach_robot


def rollout_frames(physics: mujoco.MjModel, world_qpos: np.ndarray, human_spec: mujoco.MjSpec,
                   human_qpos: np.ndarray, rate_hz: float, robot: RobotParams | None,
                   neutral_height_m: float, size_px: tuple[int, int] = (640, 480), fps: float = 30.0
                   ) -> list[np.ndarray]:
    """RGB frames at `fps` of the full human (its own joints, `human_qpos`) plus the robot joints of
    the rollout world `physics` (`world_qpos`); `robot` None: free walking, no robot drawn."""
    width, height = size_px
    spec = human_spec.copy()
    if robot is not None:
        attach_robot(spec, robot, neutral_height_m=neutral_height_m)
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
    renderer = mujoco.Renderer(model, height, width)
    cam = mujoco.MjvCamera()
    cam.distance, cam.azimuth, cam.elevation = 3.5, 125.0, -15.0
    frames = []
    for k in np.arange(0, len(human_qpos), max(int(round(rate_hz / fps)), 1)):
        data.qpos[:nh] = human_qpos[k]
        data.qpos[dst] = world_qpos[k, src]
        mujoco.mj_kinematics(model, data)
        cam.lookat[:] = data.xpos[pelvis] * np.array([1, 1, 0]) + np.array([0, 0, 0.8])
        renderer.update_scene(data, cam)
        frames.append(renderer.render().copy())
    renderer.close()
    return frames
