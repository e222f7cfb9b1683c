"""A law that follows a moving reference: :class:`ReferenceTracker` wraps a law built for a
goal, steers its springs and damping to a :class:`~cpbc.reference.target.MovingTarget`, and
each control step (one ``evaluate`` call) moves the target, either along a planned path
under the :class:`~cpbc.reference.governor.PathGovernor`, or toward a streamed target set
with :meth:`ReferenceTracker.set_target` (teleoperation, a learned policy), by the classical
ERG attraction

    v ← v + h · min(κ Δ, 1) · v_max · (r − v)/max(|r − v|, v_max h),   Δ = max(0, Γ − V̄)/Γ

with V̄ normalised at the law's posture x_n, which a streamed target leaves where it is
(no path to continue it along: far targets leave a posture-spring compromise).

It is a Controller like any law, so cpbc.simulation.loop.run_mujoco runs it unchanged; it
knows nothing of the simulator (its clock is its own count of control steps).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller, Evaluation, SafetyFilter
from cpbc.model.robot_model import ArmState
from cpbc.reference.governor import GovernorSettings, PathGovernor
from cpbc.reference.plan import ReferencePlan, log_norm
from cpbc.reference.target import Follower, MovingTarget, steer


class ReferenceTracker(Controller):
    """``law`` with a moving target (module docstring).

    Args:
        law: a law built for a goal (a task potential with a posture spring).
        period: the control period h [s].
        plan: a planned path (cpbc.reference.plan.plan_reference), or None for a streamed
            target starting at the law's goal.
        settings: the governor's settings.
        feedforward: pass ṗ_ff = ṡ_v dp/ds to the task damping (else ṗ_ff = 0).
        run: the controller that computes the torque, when not ``law`` itself: the law
            wrapped in its sampled-data safeguard (cpbc.controllers.safeguard.guarded), which
            holds the same, steered, law object. Use :func:`tracking` to get a tracker that
            reports such a safeguard's counts to the loop.

    Attributes (logged once per step): ``log_s`` s_v, ``log_blocked``, ``log_applied`` the
    applied point.
    """

    def __init__(self, law: Controller, period: float, plan: ReferencePlan | None = None,
                 settings: GovernorSettings | None = None, feedforward: bool = True,
                 run: Controller | None = None) -> None:
        super().__init__(law.model, law.target, law.constraints)
        self.run = law if run is None else run
        self.type_name = law.type_name  # type: ignore[misc]
        self.law, self.h, self.plan, self.feedforward = law, period, plan, feedforward
        self.settings = settings or GovernorSettings()
        start = plan.points[0] if plan is not None else _spring_goal(law)
        posture = plan.postures[0] if plan is not None else law.target
        self.moving = MovingTarget(start, posture)
        steer(law, self.moving)
        self.potential, self.task_damping = law.potential, law.task_damping
        self.torque_bound = law.torque_bound
        self.governor = None if plan is None else PathGovernor(
            self.settings, plan.path.duration, period, plan.postures_path.stretches,
            plan.blend_times)
        self.stream_norm = math.exp(log_norm(law, self.moving.posture))
        self.requested = self.moving.position.copy()
        self.requested_velocity = np.zeros(3)
        self.k = 0
        self.log_s: list[float] = []
        self.log_blocked: list[bool] = []
        self.log_applied: list[Array] = []

    @property
    def frames(self) -> tuple[int, ...]:
        """The frames the wrapped law reads (its potential's, or a peer nominal's)."""
        return self.law.frames

    @property
    def reads_motion(self) -> bool:
        """Whether the wrapped law reads the constraints' second-order terms (a peer's)."""
        return self.law.reads_motion

    def start_at(self, phase: float) -> None:
        """Begin the path at path time ``phase`` (outside its stretches) instead of 0: the
        governor's s_v and clock, and the target at the path's point and posture there."""
        assert self.plan is not None and self.governor is not None
        self.governor.start_at(phase)
        self.k = round(phase / self.h)
        h = self.plan.period
        self.moving.set(_between(self.plan.points, phase, h), None,
                        _between(self.plan.postures, phase, h))

    def set_target(self, position: Array, velocity: Array | None = None) -> None:
        """The streamed target r (and its velocity, for the feed-forward) for the next steps."""
        self.requested[:] = position
        self.requested_velocity[:] = 0.0 if velocity is None else velocity

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        out = self.run.evaluate_state(state, margins)
        if self.plan is not None:
            self._follow_path(self.plan, out.lyapunov)
        else:
            self._follow_stream(out.lyapunov)
        self.k += 1
        return out

    def _follow_path(self, plan: ReferencePlan, v: float) -> None:
        gov = self.governor
        assert gov is not None
        i = plan.index(gov.s)
        vbar = v * math.exp(plan.log_norm[i])
        # the fastest table segment a step (≤ ρ_max h) can reach: v_max holds across jumps
        k = min(int(gov.s / plan.period), len(plan.speeds) - 1)
        s = gov.advance(self.k * self.h, vbar, max(plan.speeds[k:k + 3]))
        j = plan.index(s)
        point, posture = _between(plan.points, s, plan.period), _between(plan.postures, s,
                                                                          plan.period)
        if gov.blend is not None:  # a rejoin carries the reference over a stretch
            end = plan.index(gov.blocked[1]) if gov.blocked else j
            w = gov.blend
            self.moving.set((1 - w) * point + w * plan.points[end], None,
                            (1 - w) * posture + w * plan.postures[end])
        else:
            rate = gov.rate if self.feedforward else 0.0
            self.moving.set(point, rate * plan.tangents[j], posture,
                            rate * plan.posture_tangents[j])
        self.log_s.append(s)
        self.log_blocked.append(gov.blocked_now)
        self.log_applied.append(self.moving.position.copy())

    def _follow_stream(self, v: float) -> None:
        st = self.settings
        vbar = v * self.stream_norm  # normalised at the (fixed) posture x_n
        delta = max(0.0, st.budget - vbar) / st.budget
        gap = self.requested - self.moving.position
        dist = float(np.linalg.norm(gap))
        step = self.h * min(st.gain * delta, 1.0) * st.max_speed
        moved = gap if dist <= step else gap * (step / dist)
        ff = self.requested_velocity if (self.feedforward and dist <= step) else np.zeros(3)
        self.moving.set(self.moving.position + moved, ff)
        self.log_applied.append(self.moving.position.copy())


class GuardedReferenceTracker(ReferenceTracker, SafetyFilter):
    """A tracker whose ``run`` is a safety filter: the loop reads the filter's counts."""

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        out = super().evaluate_state(state, margins)
        run = self.run
        assert isinstance(run, SafetyFilter)
        self.acted, self.infeasible = run.acted, run.infeasible
        self.rescues = run.rescues
        return out

    @property
    def row_active_steps(self) -> int:
        run = self.run
        assert isinstance(run, SafetyFilter)
        return run.row_active_steps

    def holding(self, tau: Array) -> None:
        run = self.run
        assert isinstance(run, SafetyFilter)
        run.holding(tau)


def tracking(law: Controller, period: float, plan: ReferencePlan | None = None,
             settings: GovernorSettings | None = None, feedforward: bool = True,
             run: Controller | None = None) -> ReferenceTracker:
    """A :class:`ReferenceTracker`, or a :class:`GuardedReferenceTracker` when ``run`` is a
    safety filter."""
    cls = GuardedReferenceTracker if isinstance(run, SafetyFilter) else ReferenceTracker
    return cls(law, period, plan, settings, feedforward, run)


def _between(table: Array, s: float, h: float) -> Array:
    """The table's row at path time s, linear between the control grid's rows (so that the
    applied point moves no faster than s does along a jump of the path)."""
    x = s / h
    i = min(int(x), len(table) - 2)
    w = min(max(x - i, 0.0), 1.0)
    return (1.0 - w) * table[i] + w * table[i + 1]


def _spring_goal(law: Controller) -> Array:
    """The goal of the law's frame position spring, or of a follower's operational-space
    nominal (the CBF-QP peer's ``osc``, cpbc.peers.osc): the streamed target's start."""
    from cpbc.controllers.potentials import PotentialSum

    nominal = getattr(law, "osc", None) if isinstance(law, Follower) else None
    if nominal is not None:
        return np.array(nominal.target.position, dtype=float)
    pot = law.potential
    for part in pot.parts if isinstance(pot, PotentialSum) else (pot,):
        goal = getattr(part, "goal", None)
        if goal is not None and np.shape(goal) == (3,):
            return np.asarray(goal, dtype=float)
    raise ValueError("the law has no frame position spring to stream a target to")
