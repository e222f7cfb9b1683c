"""A goal run's task-space outcome (TASKSPACE §3.4): the frame's error to its goal over the
run, when it entered the goal's band for good, and the status of a goal run.

Statuses of a goal run (never ``converged``: that is a joint set point's):

* ``reached``: the task error ends inside the goal's tolerance, at rest, or stays inside it
  over the run's last stall window (the hand holds the goal while the joints still drift);
* ``unreachable``: at rest away from the goal, which the preflight found out of reach; or,
  for a goal beyond the arm's reach (cpbc.taskspace.reach), not reached, however the run
  ended (short, moving, creeping): no run could have reached it;
* ``stalled`` with ``stall_kind``: at rest away from a goal the preflight did not rule out:
  ``singular`` (σ_min of the point's Jacobian below the preflight's threshold: the error
  produces no torque), ``barrier:<name>`` (a constraint holds the arm off: its margin shrank
  below a small share of its start value, or the law's springs do not balance each other
  there and descending them would shrink its margin fastest), or ``local_minimum`` (the
  springs balance each other: the task against the posture);
* ``held`` (the safeguard held the arm), ``not_settled``, ``constraint_violated`` and
  ``diverged`` as for joint runs.

"At rest" for a goal run is the task's, not the posture's: over the run's last stall window
(SettleCriteria, at least ``MIN_WINDOW``) the task error shrank by less than
``stall_progress`` and stayed within a band of ``BAND`` of its value, and the frame's point
travelled less than ``BAND`` of its distance to the goal (it creeps; it does not swing, nor
set out on its way). An arm creeping along a barrier (the safeguard braking it to rest and
the law pushing it on, in turns), or drifting along its self-motion while the hand stays
put, makes no progress toward the goal; judged against the posture it read
``not_settled`` however long the run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.controllers.controller import Controller
from cpbc.controllers.potentials import PotentialSum
from cpbc.model.robot_model import RobotModel
from cpbc.results.metrics import SettleCriteria
from cpbc.simulation.trajectory import Trajectory
from cpbc.taskspace.goal import FrameGoal
from cpbc.taskspace.ik import ACTIVE_SHARE, ANGLE_LENGTH, SINGULAR

# judge_status's "at rest, no progress" statuses, which a goal run refines
_AT_REST = ("converged", "stalled")
#: Over the stall window a stalled run's task error stays within this share of its value.
BAND = 0.1
#: The shortest stall window of a goal run [s]: a fifth of a short run says nothing.
MIN_WINDOW = 1.0
#: The law's springs balance each other at a rest when their net gradient is below this
#: share of the sum of their gradients' norms; above it, something else holds the arm.
UNBALANCED = 0.1


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


def holding(law: Controller, monitor: ConstraintSet, x: Array) -> str | None:
    """The constraint that holds a law's arm at rest at ``x``, or None when the law's springs
    balance each other there (module docstring): at a rest of the law alone ∂U/∂x = ρ b_φ
    (Theorem 6.9 with ẋ = 0), so an unbalanced ∂U/∂x is the barriers' (or the safeguard's)
    doing, and the constraint whose log margin falls fastest along −∂U/∂x is the one that
    holds."""
    potential = law.potential
    if potential is None or not monitor.configuration:
        return None
    state = law.state(x, np.zeros(law.model.n))
    parts = potential.parts if isinstance(potential, PotentialSum) else (potential,)
    grads = [p.evaluate(state)[1] for p in parts]
    net = np.sum(grads, axis=0)
    size = float(np.linalg.norm(net))
    if size <= UNBALANCED * sum(float(np.linalg.norm(g)) for g in grads):
        return None
    rates = np.concatenate([_log_rate(c.value(x), c.gradient(x) @ (-net / size))
                            for c in monitor.configuration])
    j = int(np.argmin(rates))
    return monitor.names[j] if rates[j] < 0 else None


def _log_rate(phi: Array, slope: Array) -> Array:
    """d ln φ along a direction (slope = ∇φ · direction); −inf for a crossed margin (the arm
    rests against what the constraint stands for: a joint stop, an obstacle)."""
    inside = phi > 0
    return np.where(inside, slope / np.where(inside, phi, 1.0), -np.inf)


def stall_kind(model: RobotModel, goal: FrameGoal, x: Array, names: Sequence[str],
               margins: Array, law: Controller | None = None,
               monitor: ConstraintSet | None = None) -> str:
    """Why an arm rests away from a reachable goal (module docstring); ``margins`` is the
    run's margin history (N, m) in the order of ``names``; with the ``law`` and the
    ``monitor``'s constraints, also a barrier that holds the arm with a margin to spare."""
    jv = model.point_jacobian(goal.frame, x, goal.offset)
    if np.linalg.svd(jv, compute_uv=False)[-1] < SINGULAR:
        return "singular"
    if margins.size:
        start, end = margins[0], margins[-1]
        share = np.where(start > 0, end / np.where(start > 0, start, 1.0), np.inf)
        j = int(np.argmin(share))
        if share[j] < ACTIVE_SHARE:
            return f"barrier:{names[j]}"
    held_by = None if law is None or monitor is None else holding(law, monitor, x)
    return "local_minimum" if held_by is None else f"barrier:{held_by}"


def stall_window_start(time: Array, criteria: SettleCriteria) -> int:
    """The first sample of the run's last stall window: its ``stall_window`` share, at least
    MIN_WINDOW seconds."""
    span = max(criteria.stall_window * float(time[-1] - time[0]), MIN_WINDOW)
    return int(np.searchsorted(time, time[-1] - span))


def held_in_band(time: Array, inside: Array, criteria: SettleCriteria) -> bool:
    """The task error stayed within the goal's tolerance over the whole last stall window:
    the goal is held, though the joints may still drift along the arm's self-motion (a
    redundant arm whose posture spring pulls slower than the task's)."""
    return bool(np.all(inside[stall_window_start(time, criteria):]))


def creeping(model: RobotModel, goal: FrameGoal, traj: Trajectory, errors: Array,
             criteria: SettleCriteria) -> bool:
    """The task error made no progress over the last stall window, stayed in its band, and
    the frame's point hardly moved (module docstring); errors in metres and ANGLE_LENGTH
    metres a radian."""
    start = stall_window_start(traj.time, criteria)
    combined = errors[start:, 0] + ANGLE_LENGTH * errors[start:, 1]
    if len(combined) < 2 or not np.all(np.isfinite(combined)):
        return False
    first = float(combined[0])
    if float(combined.max() - combined.min()) > BAND * first or (
            first - float(combined[-1]) >= criteria.stall_progress * first):
        return False
    every = max(1, (len(combined) - 1) // 200)  # the point's path on ≤ 200 chords
    points = np.array([model.point_position(goal.frame, x, goal.offset)
                       for x in traj.position[start::every]])
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1))) < BAND * first


def task_outcome(model: RobotModel, goal: FrameGoal, verdict: str, traj: Trajectory,
                 joint_status: str, monitor: ConstraintSet, margins: Array,
                 criteria: SettleCriteria, errors: Array | None = None,
                 law: Controller | None = None, beyond_reach: bool = False) -> TaskOutcome:
    """The goal run's outcome from its trajectory, the preflight's ``verdict`` and the joint
    status judge_status gave it (against the posture); ``errors``: :func:`task_errors` of
    the run, when already computed; ``law``: the run's law, to tell a barrier holding the
    arm from springs balancing each other (:func:`stall_kind`)."""
    errors = task_errors(model, goal, traj.position) if errors is None else errors
    finite = errors[np.all(np.isfinite(errors), axis=1)]
    final = finite[-1] if len(finite) else np.full(2, np.nan)
    tol = np.array(goal.tolerance)
    inside = np.all(errors <= tol, axis=1)
    at_rest = bool(np.max(np.abs(traj.velocity[-1])) < criteria.velocity_tolerance)
    status, kind = joint_status, None
    if joint_status not in ("constraint_violated", "diverged", "held"):
        if inside[-1] and (at_rest or held_in_band(traj.time, inside, criteria)):
            status = "reached"
        elif not inside[-1] and beyond_reach:
            status = "unreachable"
        elif joint_status in _AT_REST or (
                not inside[-1] and creeping(model, goal, traj, errors, criteria)):
            if verdict == "unreachable":
                status = "unreachable"
            else:
                x = traj.position[-1]
                status, kind = "stalled", stall_kind(model, goal, x, monitor.names, margins,
                                                     law, monitor)
        else:
            status = "not_settled"
    rms = np.sqrt(np.mean(finite**2, axis=0)) if len(finite) else np.full(2, np.nan)
    peak = finite.max(axis=0) if len(finite) else np.full(2, np.nan)
    return TaskOutcome(status, kind, _pair(final), _pair(rms), _pair(peak),
                       reach_time(traj.time, inside))
