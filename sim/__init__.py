"""Simulation: the subject-scaled human (scaling, anthropometry, MjSpec model, virtual markers,
rendering), the MRBA robot, harness, controllers and rollouts."""

from sim.body.human import build_human, load_human_model, pose_hold_ctrl, pose_hold_gains, static_qpos
from sim.body.human_params import HumanParams
from sim.body.scaling import ScaledBody, scale_subject
from sim.errors import ScalingError, SimulationError

__all__ = ["HumanParams", "ScaledBody", "ScalingError", "SimulationError", "build_human",
           "load_human_model", "pose_hold_ctrl", "pose_hold_gains", "scale_subject", "static_qpos"]
