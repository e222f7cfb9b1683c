"""A goal run's task-space outcome (TASKSPACE §3.4): the frame's error to its goal over the
run, when it entered the goal's band for good, and the status of a goal run.

Statuses of a goal run (never ``converged``: that is a joint set point's):

* ``reached``: the task error ends inside the goal's tolerance, at rest;
* ``unreachable``: at rest away from the goal, which the preflight found out of reach;
* ``stalled`` with ``stall_kind``: at rest away from a goal the preflight did not rule out:
  ``singular`` (σ_min of the point's Jacobian below the preflight's threshold: the error
  produces no torque), ``barrier:<name>`` (a constraint's margin shrank below a small share
  of its start value: it holds the arm off), or ``local_minimum`` (neither);
* ``held`` (the safeguard held the arm), ``not_settled``, ``constraint_violated`` and
  ``diverged`` as for joint runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.model.robot_model import RobotModel
from cpbc.simulation.trajectory import Trajectory
from cpbc.taskspace.goal import FrameGoal
from cpbc.taskspace.ik import ACTIVE_SHARE, SINGULAR

# judge_status's "at rest, no progress" statuses, which a goal run refines
_AT_REST = ("converged", "stalled")


@dataclass(frozen=True)
class TaskOutcome:
    """What a goal run adds to its summary (m and rad)."""

    status: str
    stall_kind: str | None
    task_error_final: dict[str, float]
    task_error_rms: dict[str, float]
    task_error_max: dict[str, float]
    reach_time: float | None


def task_errors(model: RobotModel, goal: FrameGoal, positions: Array) -> Array:
    """(position m, angle rad) at every sample, shape (N, 2)."""
    out = np.empty((len(positions), 2))
    for k, x in enumerate(positions):
        p, rot = model.frame_placement(goal.frame, x)
        if goal.offset is not None:
            p = p + rot @ goal.offset
        out[k] = float(np.linalg.norm(p - goal.position)), goal.angle(rot)
    return out


def _pair(values: Array) -> dict[str, float]:
    return {"position": float(values[0]), "angle": float(values[1])}


def reach_time(times: Array, inside: Array) -> float | None:
    """The first time from which every sample is inside the band; None if the last is not."""
    if not inside.size or not inside[-1]:
        return None
    outside = np.flatnonzero(np.logical_not(inside))
    return float(times[0] if not outside.size else times[outside[-1] + 1])


def stall_kind(model: RobotModel, goal: FrameGoal, x: Array, names: Sequence[str],
               margins: Array) -> str:
    """Why an arm rests away from a reachable goal (module docstring); ``margins`` is the
    run's margin history (N, m) in the order of ``names``."""
    model.point_position(goal.frame, x, goal.offset)
    jv = model.point_jacobian(goal.frame, x, goal.offset)
    if np.linalg.svd(jv, compute_uv=False)[-1] < SINGULAR:
        return "singular"
    if margins.size:
        start, end = margins[0], margins[-1]
        share = np.where(start > 0, end / np.where(start > 0, start, 1.0), np.inf)
        j = int(np.argmin(share))
        if share[j] < ACTIVE_SHARE:
            return f"barrier:{names[j]}"
    return "local_minimum"


def task_outcome(model: RobotModel, goal: FrameGoal, verdict: str, traj: Trajectory,
                 joint_status: str, names: Sequence[str], margins: Array,
                 velocity_tolerance: float, errors: Array | None = None) -> TaskOutcome:
    """The goal run's outcome from its trajectory, the preflight's ``verdict`` and the joint
    status judge_status gave it (against the posture); ``errors``: :func:`task_errors` of
    the run, when already computed."""
    errors = task_errors(model, goal, traj.position) if errors is None else errors
    finite = errors[np.all(np.isfinite(errors), axis=1)]
    final = finite[-1] if len(finite) else np.full(2, np.nan)
    tol = np.array(goal.tolerance)
    inside = np.all(errors <= tol, axis=1)
    at_rest = bool(np.max(np.abs(traj.velocity[-1])) < velocity_tolerance)
    status, kind = joint_status, None
    if joint_status not in ("constraint_violated", "diverged", "held"):
        if inside[-1] and at_rest:
            status = "reached"
        elif joint_status in _AT_REST:
            if verdict == "unreachable":
                status = "unreachable"
            else:
                x = traj.position[-1]
                status, kind = "stalled", stall_kind(model, goal, x, names, margins)
        else:
            status = "not_settled"
    rms = np.sqrt(np.mean(finite**2, axis=0)) if len(finite) else np.full(2, np.nan)
    peak = finite.max(axis=0) if len(finite) else np.full(2, np.nan)
    return TaskOutcome(status, kind, _pair(final), _pair(rms), _pair(peak),
                       reach_time(traj.time, inside))
