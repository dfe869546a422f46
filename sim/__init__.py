"""Simulation: the subject-scaled human (scaling, anthropometry, MjSpec model, virtual markers,
rendering), the MRBA robot, harness, controllers and rollouts."""

from sim.errors import ScalingError, SimulationError
from sim.human import build_human, load_human_model, pose_hold_ctrl, pose_hold_gains, static_qpos
from sim.human_params import HumanParams
from sim.scaling import ScaledBody, scale_subject

__all__ = ["HumanParams", "ScaledBody", "ScalingError", "SimulationError", "build_human",
           "load_human_model", "pose_hold_ctrl", "pose_hold_gains", "scale_subject", "static_qpos"]
