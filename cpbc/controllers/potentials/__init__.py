"""Potentials U(x) ≥ 0 of the laws, evaluated on the per-step state: joint springs (the set
point, the posture), frame position and orientation springs, and their sum."""

from cpbc.controllers.potentials.frame_orientation import FrameAxisSpring, FrameOrientationSpring
from cpbc.controllers.potentials.frame_position import FramePositionLogCosh, FramePositionSpring
from cpbc.controllers.potentials.joint import JointLogCoshSpring, JointSpring
from cpbc.controllers.potentials.potential import (
    Configuration,
    GradientBound,
    Placed,
    Potential,
    require_bounded,
    require_posture,
)
from cpbc.controllers.potentials.total import PotentialSum, total

__all__ = [
    "Configuration",
    "FrameAxisSpring",
    "FrameOrientationSpring",
    "FramePositionLogCosh",
    "FramePositionSpring",
    "GradientBound",
    "JointLogCoshSpring",
    "JointSpring",
    "Placed",
    "Potential",
    "PotentialSum",
    "require_bounded",
    "require_posture",
    "total",
]
