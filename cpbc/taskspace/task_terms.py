"""The task potential and task damping a law takes for a goal (TASKSPACE §2.2):

    U = ½ eᵀK_p e + orientation spring + ½ (x − x_n)ᵀK_n(x − x_n)      (CPBC, CPBC-KE, PD + g)
    U = Σ (K_i/ξ_i) ln cosh(ξ_i e_i) + orientation spring + joint ln cosh spring
                                                                        (BPBC, BPBC-KE)

with the trace spring k(3 − tr R_dᵀR) (stiffness 2k) for a full orientation and the axis
spring k(1 − a_wᵀRa_b) (stiffness k) for an axis goal, both bounded; the posture spring is
never off (it keeps U > 0 on ∂S). The bounded laws take the diagonal of K_p and D_x as the
slopes at zero of their ln cosh spring and tanh damping.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.potentials import (
    FrameAxisSpring,
    FrameOrientationSpring,
    FramePositionLogCosh,
    FramePositionSpring,
    JointLogCoshSpring,
    JointSpring,
    Potential,
    total,
)
from cpbc.controllers.task_damping import TaskDamping, TaskTanhDamping
from cpbc.controllers.terms import StateDamping
from cpbc.model.frames import jacobian_bounds
from cpbc.model.robot_model import RobotModel
from cpbc.taskspace.gains import TaskGains
from cpbc.taskspace.goal import AxisGoal, FrameGoal


@dataclass(frozen=True)
class Saturation:
    """The bounded laws' ξ of the task spring [1/m], Γ_x of the task damping [s/m] and ξ of
    the joint (posture) spring [1/rad], per joint."""

    task_xi: float
    task_gamma: float
    joint_xi: Array


def _orientation(model: RobotModel, goal: FrameGoal, gains: TaskGains) -> list[Potential]:
    if goal.rotation is None or gains.rotation <= 0:
        return []
    reach = jacobian_bounds(model.model, model.coordinates.inverse, goal.frame)[1]
    if isinstance(goal.rotation, AxisGoal):
        return [FrameAxisSpring(goal.frame, goal.rotation.tool, goal.rotation.world,
                                gains.rotation, reach)]
    return [FrameOrientationSpring(goal.frame, goal.rotation, 0.5 * gains.rotation, reach)]


def _across(goal: FrameGoal) -> Array:
    """The rotations an orientation goal fixes: all (I), or those across an axis goal's axis
    (I − a aᵀ); its yaw about the axis is left to the posture spring."""
    if isinstance(goal.rotation, AxisGoal):
        a = goal.rotation.world
        return np.eye(3) - np.outer(a, a)
    return np.eye(3)


def task_terms(model: RobotModel, goal: FrameGoal, posture: Array, gains: TaskGains,
               bounded: Saturation | None = None) -> tuple[Potential, StateDamping]:
    """U and F of the module docstring toward ``goal`` with the posture x_n."""
    rotation = _orientation(model, goal, gains)
    if bounded is None:
        position: Potential = FramePositionSpring(goal.frame, goal.position, gains.position,
                                                  goal.offset)
        spring: Potential = JointSpring(posture, gains.posture)
        damping: StateDamping = TaskDamping(goal.frame, gains.position_damping, goal.offset,
                                            angular=gains.angular_damping * _across(goal))
        return total(position, *rotation, spring), damping
    reach = jacobian_bounds(model.model, model.coordinates.inverse, goal.frame, goal.offset)[0]
    slope = np.maximum(np.diag(gains.position), 1e-9)
    position = FramePositionLogCosh(goal.frame, goal.position, slope / bounded.task_xi,
                                    np.full(3, bounded.task_xi), reach, goal.offset)
    spring = JointLogCoshSpring(posture, gains.posture / bounded.joint_xi, bounded.joint_xi)
    tanh = TaskTanhDamping(goal.frame, np.maximum(np.diag(gains.position_damping), 1e-9)
                           / bounded.task_gamma, np.full(3, bounded.task_gamma), reach,
                           goal.offset)
    return total(position, *rotation, spring), tanh
