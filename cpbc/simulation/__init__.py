"""Simulation layer: the MuJoCo closed loop and a continuous-time reference backend."""

from cpbc.simulation.loop import LoopSettings, run_mujoco, substeps_per_control
from cpbc.simulation.plant import INTEGRATORS, MujocoPlant, PlantSettings
from cpbc.simulation.reference import run_reference
from cpbc.simulation.trajectory import Trajectory

__all__ = [
    "INTEGRATORS",
    "LoopSettings",
    "MujocoPlant",
    "PlantSettings",
    "Trajectory",
    "run_mujoco",
    "run_reference",
    "substeps_per_control",
]
