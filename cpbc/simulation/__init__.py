"""Simulation layer: the one MuJoCo closed loop (arms and Part I systems) and the
continuous-time reference backend."""

from cpbc.simulation.continuous import run_reference, run_system_reference
from cpbc.simulation.loop import LoopSettings, run_mujoco, run_system_mujoco, substeps_per_control
from cpbc.simulation.plant import INTEGRATORS, MujocoPlant, PlantSettings
from cpbc.simulation.trajectory import SystemTrajectory, Trajectory

__all__ = [
    "INTEGRATORS",
    "LoopSettings",
    "MujocoPlant",
    "PlantSettings",
    "SystemTrajectory",
    "Trajectory",
    "run_mujoco",
    "run_reference",
    "run_system_mujoco",
    "run_system_reference",
    "substeps_per_control",
]
