"""A reference run's outcome (TASKSPACE §3.4): the frame's error to the requested reference
r(t) and to the applied one, the path lag t − s_v, the governor's slowed and blocked time,
and the status of a reference run.

Statuses of a reference run (never ``converged``: that is a joint set point's):

* ``tracked``: the governor completed the path (s_v reached its end) and the frame ends
  within the tolerance of the path's last point;
* ``blocked`` with ``blocked_by`` (the constraint) and ``blocked_at`` ({time, path_time}
  of the block): the governor stopped before an inadmissible stretch and the run ended
  there (``stop``, or a stretch to the path's end);
* ``stalled`` with ``stall_kind``: the reference rests — the path completed, or the
  governor moved the applied point less than the position tolerance over the run's last
  stall window without completing the path (its budget spent while the arm is held) — and
  the arm rests away from where it rests, or creeps there without progress, as a goal
  run's rest is judged against its goal (cpbc.results.task_metrics: ``creeping`` on the
  error to that point, and ``stall_kind`` with the law, steered to that point, and the
  monitor's constraints, so a barrier holding the arm with margin to spare is named, not
  called a local minimum);
* ``held``, ``not_settled`` (the reference still moving at the run's end, or the arm still
  moving and closing in on it), ``constraint_violated`` and ``diverged`` as for joint
  runs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import RobotModel
from cpbc.reference.tracker import ReferenceTracker
from cpbc.results.metrics import RunSummary, SettleCriteria
from cpbc.results.task_metrics import creeping, stall_kind, stall_window_start, task_errors
from cpbc.simulation.trajectory import Trajectory
from cpbc.taskspace.goal import FrameGoal

_KEPT = ("constraint_violated", "diverged", "held")


@dataclass(frozen=True)
class ReferenceLog:
    """Per trajectory sample: s_v, the applied point (N, 3), the blocked flag, the requested
    point r(t) (N, 3), the task error (position m, angle rad) to r(t), (N, 2), and the lag
    min(t, T) − s_v [s] (T the path's duration)."""

    path_time: Array
    applied: Array
    blocked: Array
    requested: Array
    task_error: Array
    path_lag: Array


@dataclass(frozen=True)
class ReferenceOutcome:
    """What a reference run adds to its summary (m, rad, s)."""

    status: str
    stall_kind: str | None
    task_error_final: dict[str, float]
    task_error_rms: dict[str, float]
    task_error_max: dict[str, float]
    tracking_error_applied_rms: float
    path_lag_final: float
    path_lag_max: float
    governor: dict[str, float]
    blocked_by: str | None
    blocked_at: dict[str, float] | None


def reference_log(model: RobotModel, goal: FrameGoal, tracker: ReferenceTracker,
                  traj: Trajectory) -> ReferenceLog:
    """The tracker's per-step log on the trajectory's samples, with r(t) and the errors."""
    plan = tracker.plan
    assert plan is not None and tracker.log_s
    k = np.clip(np.rint(traj.time / tracker.h).astype(int), 0, len(tracker.log_s) - 1)
    s_v = np.asarray(tracker.log_s)[k]
    applied = np.asarray(tracker.log_applied)[k]
    blocked = np.asarray(tracker.log_blocked, dtype=bool)[k]
    requested = plan.path.sample(np.asarray(traj.time, dtype=float))[0]
    errors = np.empty((len(traj.time), 2))
    for i, x in enumerate(traj.position):
        p, rot = model.frame_placement(goal.frame, x)
        if goal.offset is not None:
            p = p + rot @ goal.offset
        errors[i] = float(np.linalg.norm(p - requested[i])), goal.angle(rot)
    lag = np.clip(np.minimum(traj.time, plan.path.duration) - s_v, 0.0, None)
    return ReferenceLog(s_v, applied, blocked, requested, errors, lag)


def _pair(values: Array) -> dict[str, float]:
    return {"position": float(values[0]), "angle": float(values[1])}


def _status(joint_status: str, finished: bool, stopped: bool, inside: bool) -> str:
    """The status before the stall rule: kept, blocked, tracked, or not_settled."""
    if joint_status in _KEPT:
        return joint_status
    if stopped:
        return "blocked"
    if finished and inside:
        return "tracked"
    return "not_settled"


def _resting_at(log: ReferenceLog, time: Array, finished: bool, blocked: bool,
                end_point: Array, criteria: SettleCriteria, tolerance: float
                ) -> Array | None:
    """Where the applied reference rests at the run's end: the path's last point when the
    governor finished it; the applied point when, without finishing and without a block,
    the governor moved it less than the position ``tolerance`` over the last stall window
    (its budget spent while the arm is held: s_v creeps toward a standstill); else None
    (still moving, or waiting out a blocked stretch)."""
    if finished:
        return end_point
    if blocked:
        return None
    start = stall_window_start(time, criteria)
    moved = float(np.linalg.norm(log.applied[-1] - log.applied[start]))
    return log.applied[-1] if start < len(time) - 1 and moved < tolerance else None


def reference_outcome(model: RobotModel, goal: FrameGoal, tracker: ReferenceTracker,
                      traj: Trajectory, log: ReferenceLog, joint_status: str,
                      monitor: ConstraintSet, margins: Array,
                      criteria: SettleCriteria) -> ReferenceOutcome:
    """The run's outcome (module docstring) from its log and the joint status; ``monitor``
    and ``margins`` (N, m): the run's constraints and margin history, to name a barrier
    that holds the arm."""
    gov, plan = tracker.governor, tracker.plan
    assert gov is not None and plan is not None
    h = tracker.h
    finite = log.task_error[np.all(np.isfinite(log.task_error), axis=1)]
    final = finite[-1] if len(finite) else np.full(2, np.nan)
    end_point = plan.path.sample(np.array([plan.path.duration]))[0][0]
    final_gap = float(np.linalg.norm(log.requested[-1] - end_point))
    inside = bool(final[0] + final_gap <= goal.tolerance[0] and final[1] <= goal.tolerance[1])
    finished = gov.s >= plan.path.duration - 0.5 * h
    stopped = gov.blocked_now and (gov.settings.on_infeasible == "stop"
                                   or not np.isfinite(gov.blocked[1] if gov.blocked else 0))
    at_rest = bool(np.max(np.abs(traj.velocity[-1])) < criteria.velocity_tolerance)
    status, kind = _status(joint_status, finished, stopped, inside), None
    resting = _resting_at(log, traj.time, finished, gov.blocked_now, end_point, criteria,
                          goal.tolerance[0])
    if status == "not_settled" and resting is not None:
        # the law's springs are steered to where the reference rests (the target stays)
        aim = replace(goal, position=resting)
        errors = task_errors(model, aim, traj.position)
        away = bool(np.any(errors[-1] > np.asarray(goal.tolerance)))
        if away and (at_rest or creeping(model, aim, traj, errors, criteria)):
            status = "stalled"
            kind = stall_kind(model, aim, traj.position[-1], monitor.names, margins,
                              tracker.law, monitor)
    lag = log.path_lag
    applied_gap = [_gap(model, goal, x, a) for x, a in zip(traj.position, log.applied,
                                                           strict=True)]
    block = gov.blocks[0] if gov.blocks else None
    return ReferenceOutcome(
        status, kind, _pair(final),
        _pair(np.sqrt(np.mean(finite**2, axis=0)) if len(finite) else np.full(2, np.nan)),
        _pair(finite.max(axis=0) if len(finite) else np.full(2, np.nan)),
        float(np.sqrt(np.nanmean(np.square(applied_gap)))),
        float(lag[-1]), float(lag.max()),
        {"time_slowed": gov.steps_slowed * h, "time_blocked": gov.steps_blocked * h},
        None if block is None else block.constraint,
        None if block is None else {"time": block.time, "path_time": block.path_time})


def _gap(model: RobotModel, goal: FrameGoal, x: Array, applied: Array) -> float:
    return float(np.linalg.norm(model.point_position(goal.frame, x, goal.offset) - applied))


def judged_reference(model: RobotModel, goal: FrameGoal, tracker: ReferenceTracker,
                     traj: Trajectory, summary: RunSummary, monitor: ConstraintSet,
                     margins: Array, criteria: SettleCriteria
                     ) -> tuple[RunSummary, ReferenceLog]:
    """A reference run's summary judged from its log (:func:`reference_log`,
    :func:`reference_outcome`: tracked, blocked, stalled, …; no settle time), and the log,
    as ``cpbc.run`` and ``cpbc.hardware`` judge one."""
    log = reference_log(model, goal, tracker, traj)
    found = reference_outcome(model, goal, tracker, traj, log, summary.status, monitor,
                              margins, criteria)
    return replace(summary, **found.__dict__, settle_time=None), log
