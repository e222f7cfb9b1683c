"""The safeguard's rescue: a brake better than the uniform one, for states outside its V.

The safeguard keeps the braking set V of the uniform brake (cpbc.constraints.stopping.Braking)
invariant. That brake slows every coordinate in proportion to its speed, so the joint with
the least torque to spare sets the deceleration of all of them; a state it cannot stop may
still be stopped by a brake that lets each joint decelerate as hard as the box allows
(cpbc.constraints.brakes: the least-squares and the aimed brake). When no torque of the
guard's own satisfies its conditions — the state is outside V, or about to leave it — the
rescue holds each brake in turn in the controller's model, period after period at the control
rate (prediction sub-steps of at most ``max_step``), until the arm rests, and takes the first
that keeps every guarded margin m_i above min(δ_i, ½ m_i(now)) at every predicted step (its
cushion δ_i, or half its present value where that is below the cushion already); failing
that, the first that keeps every margin positive: the torque it
holds is that brake's at the sample. The brake found is *committed*: while the guard keeps
failing, the next periods hold it again as long as its one-period prediction keeps every margin
above its cushion (S0), and search again otherwise. The commitment lasts only as long as the
brake is held in unbroken succession: a period in which the guard's own torque passed ends it.
The search showed that the brake, held from *that* state on, stops the arm; once the law has
moved the arm on, the same brake may lead into a boundary while its next period still looks
safe (on the Panda figure-8 a brake committed 300 periods earlier was held again and carried
the hand 4 mm through the table's clearance, where the uniform brake would have stopped it).
That is the whole promise: from a state where the model says one of these brakes stops the
arm inside S, the guard holds that brake. The search runs only on the guard's infeasible path;
the accept path does not change.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import TorqueBox, brakes, brings_to_rest, model_advance
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import ArmState, RobotModel

# tried in this order (the uniform brake last: the guard's own chain has tried it already)
ORDER = ("least_squares", "aimed", "uniform")


class Rescue:
    """The brakes of the rescue, and the one committed to.

    Args:
        model: the controller's model (the plant the brakes are held in).
        guarded: the constraints the safeguard keeps.
        box: the torque box.
        cushion: δ_i, one per margin of ``guarded`` (the floor of every predicted margin).
        period: the control period h [s].
        steps: prediction sub-steps per period.
        horizon: the longest braking predicted [s].
        rate_step: ρh, how far the joint torques can move in one period under a torque-rate
            limit, or None: each brake is then held as the motors would let it ramp from
            the torque held at the sample (model_advance).
    """

    def __init__(self, model: RobotModel, guarded: ConstraintSet, box: TorqueBox,
                 cushion: Array, period: float, steps: int, horizon: float = 2.0,
                 rate_step: Array | None = None) -> None:
        self.model, self.guarded, self.box = model, guarded, box
        self.rate_step = rate_step
        self.cushion, self.period, self.steps, self.horizon = cushion, period, steps, horizon
        self.table = brakes(box, guarded, model)
        self.committed: str | None = None
        self.floor: Array | None = None  # the floor of the search that committed the brake
        self.held_at: int | None = None  # the control step at which it was last held
        self.searches = 0

    def torque(self, state: ArmState, bias: Array, now: Array,
               holds: Callable[[Array, Array], bool], step: int,
               held: Array | None = None) -> Array | None:
        """The committed brake's torque if it was held at the step before ``step`` (the
        guard's count of control steps) and ``holds(τ, floor)`` accepts it (its one-period
        prediction keeps every margin above the floor of the search that committed it), else
        the first brake whose model braking keeps every margin above its floor until rest
        (the module docstring; then committed), else None. ``now``: the margins m_i at the
        sample; ``held``: the torque the actuators hold (under a torque-rate limit)."""
        if (self.committed is not None and self.floor is not None
                and self.held_at == step - 1):
            tau = self.table[self.committed](state, bias, self.period)
            if holds(tau, self.floor):
                self.held_at = step
                return tau
        self.committed = None
        self.searches += 1
        # first with a cushion: a margin keeps δ_i, or half of itself where it is below δ_i
        # already; then with none (every margin positive in the model)
        cushioned = np.minimum(self.cushion, 0.5 * np.maximum(now, 0.0))
        for floor in (cushioned, np.zeros_like(cushioned)):
            name = self._search(state, floor, held)
            if name is not None:
                self.committed, self.floor, self.held_at = name, floor, step
                return self.box.clip(self.table[name](state, bias, self.period))
        return None

    def _search(self, state: ArmState, floor: Array, held: Array | None) -> str | None:
        """The first brake of ORDER that, held in the model until rest (ramped from ``held``
        under a torque-rate limit), keeps every margin above ``floor``."""

        def margins(xs: Array, dxs: Array) -> Array:
            return self.guarded.margins_along(xs, dxs) - floor

        for name in ORDER:
            advance = model_advance(self.model, self.box, state.x, state.dx, self.period,
                                    self.steps, self.rate_step,
                                    state.gravity if held is None else held)
            stop = brings_to_rest(self.table[name], self.model, margins, advance, state.x,
                                  state.dx, self.period, horizon=self.horizon)
            if stop.stopped:
                return name
        return None

    def forget(self) -> None:
        self.committed = self.floor = self.held_at = None

