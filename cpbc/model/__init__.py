"""Model layer: Pinocchio dynamics and kinematics, coordinates, model-derived bounds."""

from cpbc.model.coordinates import LinearCoordinates
from cpbc.model.robot_model import DynamicsTerms, RobotModel

__all__ = ["DynamicsTerms", "LinearCoordinates", "RobotModel"]
