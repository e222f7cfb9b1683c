"""The IK preflight (TASKSPACE §3.3): before a run, where will the law rest?

Damped least squares with the constraints' log barriers: from a seed inside S, minimise

    F(x) = ½ ‖r(x)‖² − μ Σ ln φ_i(x)            r = [p(x) − p_d ; w·e_R(x)]

(e_R = ½ vee(R R_dᵀ − R_d Rᵀ) for a full orientation, a_w × R a_b for an axis goal; w [m/rad]
weighs angle against distance) by Levenberg–Marquardt steps

    Δx = −(J_rᵀJ_r + μ b bᵀ + λ I)⁻¹ (J_rᵀ r − μ b),   b = Σ ∇φ_i/φ_i

each accepted only inside S and when F decreases. Its rest points are those of the law's own
V(·, 0) = U/s(Φ) in kind (∇U balanced by the barrier sum), so it predicts whether the arm
reaches the goal, is held off it by a constraint, or cannot reach it at all:

* ``reachable``: the task error is within the goal's tolerance; the result is the posture x_n
  (``posture: ik``), consistent with the goal and strictly inside S;
* ``blocked``: a constraint's margin shrank to a small share of its value at the seed while
  the error stays above tolerance; that constraint is named;
* ``unreachable``: neither; the closest approach is reported. A goal beyond the arm's reach
  (cpbc.taskspace.reach) is ``unreachable`` whatever the descent ran into on its way.

Several seeds (the start first, then others the caller gives) guard against local minima:
the first one that reaches the goal wins. When none does, the descent from the start is the
prediction, because that is where the law, which descends from the start, comes to rest: a
closer miss on another branch would send the posture spring across the workspace toward a
configuration that does not reach the goal either.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.errors import ConstraintViolation
from cpbc.model.frames import FrameKinematics
from cpbc.model.robot_model import RobotModel
from cpbc.taskspace.goal import AxisGoal, FrameGoal, TaskError
from cpbc.taskspace.reach import reach

BARRIER_WEIGHT = 1e-7  # μ [m²]
ANGLE_LENGTH = 0.3  # w [m/rad]
ACTIVE_SHARE = 0.05  # a margin below this share of its seed value is active
SINGULAR = 1e-3  # σ_min(J_v) [m/rad] below which a configuration is singular for the goal


@dataclass(frozen=True)
class Preflight:
    """The preflight's prediction.

    Attributes:
        verdict: ``reachable``, ``blocked`` or ``unreachable``.
        posture: the rest configuration found (x_n for ``posture: ik``).
        error: its task error.
        blocked_by: the active constraint (``blocked``), else None.
        nearest: (name, margin) of the smallest margin at the posture; None without
            configuration constraints.
        singular_start: σ_min(J_v) at the start is below ``SINGULAR``.
        beyond_reach: how far the goal lies beyond the arm's reach [m], when it does (no
            posture reaches it); None when it is within reach.
    """

    verdict: str
    posture: Array
    error: TaskError
    blocked_by: str | None
    nearest: tuple[str, float] | None
    singular_start: bool
    beyond_reach: float | None = None

    def describe(self) -> str:
        """One line for the console."""
        err = f"{self.error.position * 1000:.3g} mm, {self.error.angle:.3g} rad"
        if self.verdict == "reachable":
            text = f"reachable (IK error {err}); posture {np.round(self.posture, 3).tolist()}"
        elif self.verdict == "blocked":
            text = f"blocked_by: {self.blocked_by} (closest {err})"
        elif self.beyond_reach is not None:
            text = (f"unreachable: {self.beyond_reach:.3g} m beyond the arm's reach "
                    f"(closest {err})")
        else:
            text = f"unreachable (distance {err})"
        if self.singular_start:
            text += "; the start is singular for this goal (slow start expected)"
        return text


def _residual(goal: FrameGoal, kin: FrameKinematics) -> tuple[Array, Array]:
    """r and ∂r/∂x of the module docstring."""
    p, jv = kin.point(goal.offset)
    rows, jac = [p - goal.position], [jv]
    if isinstance(goal.rotation, AxisGoal):
        axis = kin.rotation @ goal.rotation.tool
        rows.append(ANGLE_LENGTH * np.cross(goal.rotation.world, axis))
        skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        w = goal.rotation.world
        wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        jac.append(ANGLE_LENGTH * (-wx @ skew @ kin.angular))
    elif goal.rotation is not None:
        m = kin.rotation @ goal.rotation.T
        skew = m - m.T
        rows.append(ANGLE_LENGTH * 0.5 * np.array([skew[2, 1], skew[0, 2], skew[1, 0]]))
        jac.append(ANGLE_LENGTH * 0.5 * (np.trace(m) * np.eye(3) - m) @ kin.angular)
    return np.concatenate(rows), np.vstack(jac)


@dataclass(frozen=True)
class _Point:
    x: Array
    cost: float
    residual: Array
    jacobian: Array
    barrier: Array
    margins: Array
    kin: FrameKinematics


class _Flow:
    """One descent from a seed."""

    def __init__(self, model: RobotModel, constraints: ConstraintSet, goal: FrameGoal) -> None:
        self.model, self.constraints, self.goal = model, constraints, goal
        self.zero = np.zeros(model.n)

    def at(self, x: Array) -> _Point | None:
        state = self.constraints.state(self.model, x, self.zero, [self.goal.frame])
        kin = state.frames[self.goal.frame]
        r, jac = _residual(self.goal, kin)
        if self.constraints.empty:
            return _Point(x, 0.5 * float(r @ r), r, jac, self.zero, np.zeros(0), kin)
        try:
            bar = self.constraints.barrier(state, margins=True)
        except ConstraintViolation:
            return None
        if bar.margins is None or not np.all(bar.margins > 0):
            return None
        grad = self.zero if bar.gradient is None else bar.gradient
        cost = 0.5 * float(r @ r) - BARRIER_WEIGHT * bar.log_phi
        return _Point(x, cost, r, jac, grad, bar.margins, kin)

    def descend(self, seed: Array, iterations: int) -> _Point | None:
        point = self.at(seed)
        if point is None:
            return None
        damping = 1e-3
        for _ in range(iterations):
            g = point.jacobian.T @ point.residual - BARRIER_WEIGHT * point.barrier
            h = point.jacobian.T @ point.jacobian + BARRIER_WEIGHT * np.outer(
                point.barrier, point.barrier)
            step = -np.linalg.solve(h + damping * np.eye(self.model.n), g)
            trial = self.at(point.x + step)
            if trial is not None and trial.cost < point.cost:
                done = point.cost - trial.cost < 1e-14 + 1e-10 * point.cost
                point, damping = trial, max(damping / 3.0, 1e-9)
                if done:
                    break
            else:
                damping *= 4.0
                if damping > 1e6:
                    break
        return point


#: How far a singular start is moved off its singularity before the descent [rad or m].
OFF_SINGULAR = 1e-3


def _off_singular(model: RobotModel, goal: FrameGoal, x: Array) -> tuple[bool, Array]:
    """Whether ``x`` is singular for the goal (σ_min(J_v) < ``SINGULAR``), and where the
    descent starts: at x, or at a singular x ``OFF_SINGULAR`` along the joint direction J_v
    moves least (its right singular vector), signed so that its first largest entry is
    positive. At the singularity the descent's step along that direction is roundoff alone,
    so the branch taken was the host's BLAS's: the outstretched thesis arm went to the
    elbow (π, 2π/3) on the project's earlier hosts and to (2π/3, π) on an AVX-512 one."""
    state = model.state(x, np.zeros(model.n), frames=[goal.frame])
    jv = state.frames[goal.frame].point(goal.offset)[1]
    _, sigma, vt = np.linalg.svd(jv)
    rank = min(jv.shape[0], jv.shape[1])
    least = (min(rank, 2) if model.n < 3 else rank) - 1
    if not sigma[least] < SINGULAR:
        return False, x
    away = vt[least]
    first = int(np.argmax(np.abs(away) >= (1.0 - 1e-9) * np.abs(away).max()))
    return True, x + OFF_SINGULAR * np.sign(away[first]) * away


def preflight(model: RobotModel, constraints: ConstraintSet, goal: FrameGoal, start: Array,
              seeds: Sequence[Array] = (), iterations: int = 200) -> Preflight:
    """The verdict of the module docstring; ``constraints`` are the configuration
    constraints (velocity ones are slack at rest)."""
    flow = _Flow(model, constraints, goal)
    start = np.asarray(start, dtype=float)
    seed_point = flow.at(start)
    singular, begin = _off_singular(model, goal, start)
    best = flow.descend(begin, iterations)
    if best is None and singular:  # moved off it, the start left S: from the start itself
        best = flow.descend(start, iterations)
    if best is None or not goal.reached(goal.error(best.kin)):
        for seed in seeds:  # another branch may reach the goal; a miss there is no better
            found = flow.descend(np.asarray(seed, dtype=float), iterations)
            if found is not None and goal.reached(goal.error(found.kin)):
                best = found
                break
    if best is None:
        best = seed_point if seed_point is not None else flow.at(start)
    assert best is not None, "the start is inside S (checked by the caller)"
    error = goal.error(best.kin)
    names = constraints.names[: constraints.n_configuration]
    nearest = None
    blocked = None
    if best.margins.size:
        k = int(np.argmin(best.margins))
        nearest = (names[k], float(best.margins[k]))
        if seed_point is not None:
            share = best.margins / np.maximum(seed_point.margins, 1e-300)
            j = int(np.argmin(share))
            blocked = names[j] if share[j] < ACTIVE_SHARE else None
    beyond = reach(model, goal).beyond(goal.position) - goal.tolerance[0]
    if goal.reached(error):
        verdict, blocked = "reachable", None
    elif beyond > 0:  # no posture reaches it: no constraint is to blame
        verdict, blocked = "unreachable", None
    else:
        verdict = "blocked" if blocked is not None else "unreachable"
    return Preflight(verdict, best.x, error, blocked, nearest, singular,
                     beyond if beyond > 0 else None)
