"""Model layer: Pinocchio dynamics and kinematics, coordinates, model-derived bounds."""

from cpbc.model.coordinates import LinearCoordinates
from cpbc.model.input_bounds import InputBounds
from cpbc.model.robot_model import ArmState, RobotModel

__all__ = ["ArmState", "InputBounds", "LinearCoordinates", "RobotModel"]
