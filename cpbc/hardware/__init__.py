"""Drive a torque-controlled robot with a scenario's controller (``python -m cpbc.hardware``).

Low layer (beside cpbc.simulation; model and controllers below): the robot protocol
(:mod:`~cpbc.hardware.backend`), its backends (:mod:`~cpbc.hardware.franka` over
pylibfranka, :mod:`~cpbc.hardware.lockstep` over MuJoCo), one motion
(:mod:`~cpbc.hardware.motion`) and the robot's rules checked on its log
(:mod:`~cpbc.hardware.rules`). Top layer (beside cpbc.run: the scenario builder and the
results below): :mod:`~cpbc.hardware.robot_run` and :mod:`~cpbc.hardware.dry_run`.
"""

from cpbc.hardware.backend import (
    MeasuredState,
    RobotBackend,
    RobotDynamics,
    RobotFault,
    RobotLimits,
)
from cpbc.hardware.lockstep import LockstepBackend
from cpbc.hardware.motion import ENDINGS, MotionLog, MotionSettings, run_motion
from cpbc.hardware.rules import RuleReport, check_rules

__all__ = [
    "ENDINGS",
    "LockstepBackend",
    "MeasuredState",
    "MotionLog",
    "MotionSettings",
    "RobotBackend",
    "RobotDynamics",
    "RobotFault",
    "RobotLimits",
    "RuleReport",
    "check_rules",
    "run_motion",
]
