"""A scenario's ``goal:`` (cpbc.taskspace): the goal checked against the robot and the scene
(errors name ``goal.frame``, ``goal.position``, ...), the IK preflight and the posture x_n,
and the laws with their task potential, task damping and task gains."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.geometry import Obstacle, point_rounded_box, quat_to_matrix, rpy_matrix
from cpbc.constraints.point_outside_sphere import PointOutsideSphere
from cpbc.controllers.law_kind import Slopes
from cpbc.errors import CpbcError, ParameterError, ScenarioError
from cpbc.model.robot_model import RobotModel
from cpbc.scenario import schema as s
from cpbc.taskspace.gains import TaskGains, TaskGainSpec, linear_terms, task_gains
from cpbc.taskspace.goal import AxisGoal, FrameGoal
from cpbc.taskspace.ik import Preflight, preflight
from cpbc.taskspace.posture import admissible_turns
from cpbc.taskspace.task_terms import Saturation, task_terms


def _vector3(value: list[float] | None, field: str) -> Array:
    a = np.asarray(value, dtype=float)
    if a.shape != (3,):
        raise ScenarioError(field, f"needs 3 numbers [x, y, z], got {len(value or [])}")
    return a


def _unit3(value: list[float], field: str) -> Array:
    a = _vector3(value, field)
    norm = float(np.linalg.norm(a))
    if norm <= 1e-12:
        raise ScenarioError(field, "must be a nonzero direction")
    return a / norm


def _rotation(spec: s.OrientationSpec | None) -> Array | AxisGoal | None:
    if spec is None:
        return None
    given = [k for k in ("rpy", "quat", "axis") if getattr(spec, k) is not None]
    if len(given) != 1:
        raise ScenarioError("goal.orientation", "give exactly one of rpy, quat or axis, got "
                            f"{given or 'none'}")
    if spec.axis is not None:
        return AxisGoal(_unit3(spec.axis.tool, "goal.orientation.axis.tool"),
                        _unit3(spec.axis.world, "goal.orientation.axis.world"))
    if spec.rpy is not None:
        return rpy_matrix(_vector3(spec.rpy, "goal.orientation.rpy"))
    return quat_to_matrix(_unit_quaternion(spec.quat, "goal.orientation.quat"))


#: How far a quaternion's norm may be from 1: what numbers written to four digits leave
#: (0.7071 for √½); farther, the numbers are not the rotation the user meant.
QUAT_NORM_TOLERANCE = 1e-3


def _unit_quaternion(values: object, field: str) -> Array:
    """[w, x, y, z] of unit norm (within QUAT_NORM_TOLERANCE, then made exact)."""
    q = np.asarray(values, dtype=float)
    if q.shape != (4,):
        raise ScenarioError(field, f"needs 4 numbers [w, x, y, z], got {q.size}")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
        fix = ("the identity is [1, 0, 0, 0]" if norm < 1e-12 else
               f"divide each number by {norm:.6g}")
        raise ScenarioError(field, f"has norm {norm:.6g}, not 1: a rotation's quaternion "
                            f"is a unit one ({fix})")
    return q / norm


def _check_free(goal: Array, scene: Mapping[str, Obstacle], monitor: ConstraintSet,
                frame: int) -> None:
    """Refuse a goal point inside an obstacle, or inside the sphere a point-outside-sphere
    constraint keeps this frame out of."""
    for name, ob in scene.items():
        core = ob.core()
        u = (core.rotation.T @ (goal - core.centre))[None, :]
        depth = -float(point_rounded_box(u, core.half_extents[None, :],
                                         np.array([core.rounding]))[0][0])
        if depth >= 0:
            raise ScenarioError("goal.position", f"the goal point is {depth:.4g} m inside "
                                f"obstacle '{name}'; move it outside")
    for c in monitor.configuration:
        if isinstance(c, PointOutsideSphere) and c.frame_id == frame and c.offset is None:
            depth = c.radius - float(np.linalg.norm(goal - c.centre))
            if depth >= 0:
                raise ScenarioError("goal.position", f"the goal point is {depth:.4g} m inside "
                                    f"the sphere of constraint '{c.names[0]}'; move it out")


def goal_of(spec: s.GoalSpec, model: RobotModel, scene: Mapping[str, Obstacle],
            monitor: ConstraintSet) -> FrameGoal:
    """The goal of the scenario, checked."""
    try:
        frame = model.frame_id(spec.frame)
    except CpbcError as exc:
        raise ScenarioError("goal.frame", str(exc)) from None
    position = _vector3(spec.position, "goal.position")
    offset = None if spec.offset is None else _vector3(spec.offset, "goal.offset")
    _check_free(position, scene, monitor, frame)
    return FrameGoal(frame, spec.frame, position, offset, _rotation(spec.orientation),
                     (spec.tolerance.position, spec.tolerance.angle))


@dataclass(frozen=True)
class GoalPlan:
    """The goal, the preflight's prediction and the posture x_n the laws take."""

    goal: FrameGoal
    preflight: Preflight
    posture: Array


def plan(spec: s.GoalSpec, goal: FrameGoal, model: RobotModel, monitor: ConstraintSet,
         start: Array, seeds: list[Array], check: Callable[[Array, str], None],
         periodic: Array | None = None) -> GoalPlan:
    """Run the preflight from ``start`` (then ``seeds``) and choose x_n: the preflight's
    posture (``ik``), the start (``start``) or the given one, checked by ``check``. The
    preflight's posture is turned on the ``periodic`` (continuous) joints to the equivalent
    nearest ``start`` (cpbc.taskspace.posture): a seed's branch may lie a turn away."""
    config = ConstraintSet(model.n, monitor.configuration)
    found = preflight(model, config, goal, start, seeds)
    found = replace(found, posture=admissible_turns(found.posture, start, periodic, config))
    if spec.posture == "ik":
        posture = found.posture
    elif spec.posture == "start":
        posture = start
    else:
        posture = np.asarray(spec.posture, dtype=float)
        if posture.shape != (model.n,):
            raise ScenarioError("goal.posture", f"needs {model.n} numbers, got {posture.size}")
    check(posture, "goal.posture")
    return GoalPlan(goal, found, posture)


def law_terms(spec: s.LawSpec, model: RobotModel, goal: GoalPlan, field: str, slopes: Slopes
              ) -> tuple[dict[str, object], TaskGains]:
    """The keyword arguments (kp, kd, potential, task_damping) of a law for the goal, and its
    gains (linear at the posture, for the zero-order-hold check). A law whose slopes saturate
    (its kind's declaration) gets the bounded task terms, saturating beyond 1/``task.xi`` and
    1/``task.gamma``, and its posture spring and joint damping divided by its slopes."""
    if spec.task is None and spec.posture is None:
        raise ScenarioError(f"{field}.kp", "with goal:, give task: {omega_n, zeta} and "
                            "posture: {omega_n, zeta} in place of kp, kd (or omega_n, zeta)")
    task, posture = spec.task or s.TaskGainsSpec(), spec.posture or s.PostureGainsSpec()
    try:
        gains = task_gains(model, goal.goal, goal.posture, TaskGainSpec(
            task.omega_n, task.zeta, task.rotation_omega_n, posture.omega_n, posture.zeta))
    except ParameterError as exc:
        raise ScenarioError(f"{field}.task", f"{exc}; raise task.omega_n (or zeta, "
                            "rotation_omega_n) or lower posture.omega_n") from None
    bounded = Saturation(task.xi, task.gamma, slopes.spring) if slopes.saturates else None
    kd = gains.joint_damping
    if bounded is not None:  # the bounded laws' springs and damping take the diagonals
        gains = replace(gains, position=np.diag(np.diag(gains.position)),
                        position_damping=np.diag(np.diag(gains.position_damping)))
        kd = kd / slopes.damping
    potential, damping = task_terms(model, goal.goal, goal.posture, gains, bounded)
    kp = gains.posture if bounded is None else gains.posture / bounded.joint_xi
    return {"kp": kp, "kd": kd, "potential": potential, "task_damping": damping}, gains


def linear_gains(model: RobotModel, goal: GoalPlan, gains: TaskGains, x: Array
                 ) -> tuple[Array, Array]:
    """The law's linear stiffness and damping (n × n) with the Jacobians at ``x``, for the
    ZOH check: the task springs reach the joints through J(x), so at a start far from the
    posture they load other joints than at the posture."""
    state = model.state(x, np.zeros(model.n), frames=[goal.goal.frame])
    return linear_terms(goal.goal, gains, state.frames[goal.goal.frame])
