"""The safeguard's rescue: a brake better than the uniform one, for states outside its V.

The safeguard keeps the braking set V of the uniform brake (cpbc.constraints.stopping.Braking)
invariant. That brake slows every coordinate in proportion to its speed, so the joint with
the least torque to spare sets the deceleration of all of them; a state it cannot stop may
still be stopped by a brake that lets each joint decelerate as hard as the box allows
(cpbc.constraints.brakes: the least-squares and the aimed brake; where the model has dry
friction, also each brake held against b without it, after the others). When no torque of the
guard's own satisfies its conditions — the state is outside V, or about to leave it — the
rescue holds each brake in turn in the controller's model, period after period at the control
rate (prediction sub-steps of at most ``max_step``), until the arm rests, and takes the first
that keeps every guarded margin m_i above min(δ_i, ½ m_i(now)) at every predicted step (its
cushion δ_i, or half its present value where that is below the cushion already); failing
that, the first that keeps every margin positive: the torque it
holds is that brake's at the sample. The brake found is *committed*: while the guard keeps
failing, the next periods hold it again as long as its one-period prediction keeps every margin
above its cushion (S0) and — without a budget — its check, run again from the state measured
then, still passes; they search again otherwise. The plant is not the model: on the UR5 of the
rate campaign (tools/campaigns/ur5_bpbc_rate.yaml, seed 49) a brake whose check had passed was
held for 40 periods while the plant's friction (MuJoCo's, which opposes the rate 9.5 ms ahead:
cpbc.controllers.safeguard.model_error) took the wrist's floor clearance down 0.3 mm a period
below the rollout's, until no brake was left; checked again each period it is left as soon as
it no longer stops the arm from where the arm is. (Holding the friction's error over each
rollout instead, a drift ½t²|D⁻¹|F of the joints that rest or turn, rejected nearly every brake
on the Panda and the FR3 and broke runs there.) The commitment lasts only as long as the
brake is held in unbroken succession: a period in which the guard's own torque passed ends it.
The search showed that the brake, held from *that* state on, stops the arm; once the law has
moved the arm on, the same brake may lead into a boundary while its next period still looks
safe (on the Panda figure-8 a brake committed 300 periods earlier was held again and carried
the hand 4 mm through the table's clearance, where the uniform brake would have stopped it).
That is the whole promise: from a state where the model says one of these brakes stops the
arm inside S, the guard holds that brake. The search runs only on the guard's infeasible path;
the accept path does not change.

**A bounded step.** Holding a brake until rest in the model costs a period of model
(Pinocchio's passes, the brake, the margins: 30–100 µs on the Panda) per period of braking,
and a brake under a torque-rate limit takes 0.1–0.3 s to stop the arm: a search could take
tens of milliseconds, and a 1 kHz loop on a robot must answer within its period. With a
*budget* of B model periods per control period (``SafeguardSettings.rescue_budget``; none by
default, for the reason below) each check is a :class:`cpbc.constraints.brakes.Rollout` run
B periods at a time: a candidate whose check has not ended when the budget runs out is
committed and held, and its check goes on in the next periods, B model periods ahead of the
arm per period held (the brake the arm holds is the one the check holds, from the same
state). Should the check see a margin fall below its floor, the next candidate is checked
from the arm's state then, with the remaining candidates of the same order; when none is
left the guard's own fallback answers. What this gives up: a brake is held before its check
has seen the arm to rest, so a brake that fails late is left later than the unbounded search
would have left it (after 1/B of the time to the failure), and the next candidate starts
from a worse state. Measured on the Panda rate campaign
(tools/campaigns/panda_sphere_rate.yaml, 300 states, 1 kHz, 1000 N·m/s): 4 of 166 stoppable
runs crossed a bound at B = 4, 2 at B = 25, 1 unbounded; on the UR5's, 4 and 0 of 282. The
bound on the step is bought with the guarantee, so the default is the search that ends in
the period it starts; a hard deadline needs a rescue that is decided before it is needed,
which this is not. On a robot the rescue's time is the robot's: there a search of 30–70 ms
left franky-sim holding the last command and two runs crossed a bound, and the budget kept
every run (docs/hardware.md), so ``python -m cpbc.hardware`` bounds it to 8 periods unless the
scenario says otherwise (cpbc.hardware.robot_run.on_robot).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import FRICTION_LEFT, Rollout, TorqueBox, brakes, model_advance
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
        budget: the periods of the model the search may hold brakes for in one control
            period, all candidates together, or None for no bound (the search then ends in
            the period it starts). With a budget a check that has not ended when the budget
            runs out goes on in the next periods, B model periods ahead per period held,
            while the guard holds the brake under check (the module docstring).
        margins: every margin of ``guarded`` at rows (x, ẋ) (the guard's compiled
            PredictedMargins.margins_along), or None for ``guarded.margins_along``.
    """

    def __init__(self, model: RobotModel, guarded: ConstraintSet, box: TorqueBox,
                 cushion: Array, period: float, steps: int, horizon: float = 2.0,
                 rate_step: Array | None = None, budget: int | None = None,
                 margins: Callable[[Array, Array], Array] | None = None) -> None:
        if budget is not None and budget < 1:
            raise ValueError(f"rescue budget must be ≥ 1 period, got {budget}")
        self.model, self.guarded, self.box = model, guarded, box
        self.rate_step, self.budget = rate_step, budget
        self.cushion, self.period, self.steps, self.horizon = cushion, period, steps, horizon
        self.margins = guarded.margins_along if margins is None else margins
        self.table = brakes(box, guarded, model)
        # then, where the model has dry friction, the same brakes held against b without it
        # (brakes.holding_bias): the brakes cpbc.verify's classification tries too
        self.order = ORDER + tuple(name + FRICTION_LEFT for name in ORDER
                                   if name + FRICTION_LEFT in self.table)
        self.committed: str | None = None
        self.floor: Array | None = None  # the floor of the search that committed the brake
        self.held_at: int | None = None  # the control step at which it was last held
        self.searches = 0
        # the check of the committed brake while it goes on (a budget), and where in the
        # order of candidates (two rounds of the order: cushioned floor, then none) it stands
        self._check: Rollout | None = None
        self._candidate = 0
        self._floors: tuple[Array, Array] = (cushion, np.zeros_like(cushion))

    def torque(self, state: ArmState, bias: Array, now: Array,
               holds: Callable[[Array, Array], bool], step: int,
               held: Array | None = None) -> Array | None:
        """The committed brake's torque if it was held at the step before ``step`` (the
        guard's count of control steps), ``holds(τ, floor)`` accepts it (its one-period
        prediction keeps every margin above the floor of the search that committed it) and
        its check has not failed, else the first brake whose model braking keeps every
        margin above its floor until rest — or, under a budget, whose check has not failed
        when the budget runs out — (the module docstring; then committed), else None.
        ``now``: the margins m_i at the sample; ``held``: the torque the actuators hold
        (under a torque-rate limit)."""
        budget = self.budget
        if (self.committed is not None and self.floor is not None
                and self.held_at == step - 1):
            tau = self.table[self.committed](state, bias, self.period)
            if holds(tau, self.floor):
                if budget is None:  # checked again from here (the module docstring)
                    again = self._rollout(state, self.committed, self.floor, held).run()
                    if again is not None and again.stopped:
                        self.held_at = step
                        return tau
                    return self._search(state, bias, now, step, held, self._candidate + 1,
                                        budget)
                stop = None if self._check is None else self._check.run(budget)
                if self._check is None or stop is None or stop.stopped:
                    if stop is not None:
                        self._check = None  # passed: nothing left to check
                    self.held_at = step
                    return tau
                # its check failed ahead of the arm: the next candidate, from here
                return self._search(state, bias, now, step, held, self._candidate + 1,
                                    budget)
        return self._search(state, bias, now, step, held, 0, budget)

    def _search(self, state: ArmState, bias: Array, now: Array, step: int,
                held: Array | None, first: int, budget: int | None) -> Array | None:
        """The first candidate from ``first`` on (the order with the cushioned floor, then with
        none) whose check passes, or under a budget has not failed when it runs out."""
        self.committed, self._check = None, None
        if first == 0:
            self.searches += 1
            # first with a cushion: a margin keeps δ_i, or half of itself where it is below
            # δ_i already; then with none (every margin positive in the model)
            cushioned = np.minimum(self.cushion, 0.5 * np.maximum(now, 0.0))
            self._floors = (cushioned, np.zeros_like(cushioned))
        left = budget
        order = self.order
        for k in range(first, 2 * len(order)):
            name, floor = order[k % len(order)], self._floors[k // len(order)]
            check = self._rollout(state, name, floor, held)
            stop = check.run(left)
            if stop is None or stop.stopped:
                self.committed, self.floor, self.held_at = name, floor, step
                self._candidate, self._check = k, (check if stop is None else None)
                return self.box.clip(self.table[name](state, bias, self.period))
            if left is not None:
                left = max(left - check.held, 1)  # every candidate gets at least a period
        return None

    def _rollout(self, state: ArmState, name: str, floor: Array,
                 held: Array | None) -> Rollout:
        """The check of brake ``name`` from the state: held in the model until rest (ramped
        from ``held`` under a torque-rate limit), every margin above ``floor``."""

        def margins(xs: Array, dxs: Array) -> Array:
            return self.margins(xs, dxs) - floor

        advance = model_advance(self.model, self.box, state.x, state.dx, self.period,
                                self.steps, self.rate_step,
                                state.gravity if held is None else held)
        return Rollout(self.table[name], self.model, margins, advance, state.x, state.dx,
                       self.period, horizon=self.horizon)

    def forget(self) -> None:
        self.committed = self.floor = self.held_at = None
        self._check = None
