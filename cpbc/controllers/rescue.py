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
tens of milliseconds, and a 1 kHz loop must answer within its period. With a *budget* of B
model periods per control period (``SafeguardSettings.rescue_budget``; none by default in
simulation, 8 on a robot) the rescue is decided before it is needed where it can be, and
bounded after that:

- the search from a motion's first state (the guard's first step) runs until rest whatever
  B: it is made before the arm has moved under the guard. On a robot it is not asked there —
  a motion starts at rest, inside V (the scenario builder checks it) — and in simulation its
  time is the first step's;
- a brake committed to is held, at the steps after, as soon as the law's own torque fails
  its test — before the guard's other candidates: one brake and one test a step — while its
  one-period prediction keeps every margin above its floor (under a torque-rate limit
  without the guard's velocity lookahead, which its check's ramped braking answers:
  cpbc.controllers.safeguard.braking.Brakes.committed), until the step its check came
  to rest at (:meth:`Rescue.held_brake`);
- a later search spends at most B model periods over all its candidates and commits only
  to a brake whose check brought the arm to rest within them; where none did, the guard's
  fallback answers.

No brake is held before its check has seen the arm to rest. Until 2026-11-29 a budgeted
check that had not ended was committed to and went on B periods ahead of the arm while its
brake was held: on the Panda rate campaign (tools/campaigns/panda_sphere_rate.yaml, 300
states, 1 kHz, 1000 N·m/s) 4 of 166 stoppable runs crossed a bound at B = 4, 2 at B = 25, 1
unbounded, and on the rate campaigns as a robot runs them (6 tests a step, B = 8) the starts
outside V that the first steps decide crossed 28 times in 168 runs (docs/reliability.md has
what crosses now). What a budget still gives up: a state mid-run from which a brake needs
longer than B periods to stop the arm gets the fallback, not the brake — the UR10 held under
a ball (tests/test_reference_stall.py), which the unbounded rescue holds at rest, rides the
clearance in stick-slip at 0.05 rad/s under B = 8. So simulation keeps no bound, where every
search runs until rest and a committed brake's check runs again from each state measured
(the UR5 above) in the period it is asked; on a robot the rescue's time is the robot's
(there a search of 30–70 ms left franky-sim holding the last command and two runs crossed a
bound, and the budget kept every run, docs/hardware.md), so ``python -m cpbc.hardware``
bounds it to 8 periods unless the scenario says otherwise (cpbc.hardware.robot_run.on_robot).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import FRICTION_LEFT, Rollout, TorqueBox, brakes, model_advance
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import ArmState, RobotModel

# tried in this order (the uniform brake last: the guard's own chain has tried it already)
ORDER = ("least_squares", "aimed", "uniform")


def first_step(step: int) -> bool:
    """Whether the guard's count of control steps ``step`` is the motion's first (1; 0 for
    a warm-up): the rescue's search from there runs until rest, whatever its budget."""
    return step <= 1


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
        budget: the periods of the model a search may hold brakes for, all candidates
            together, or None for no bound. With a budget only a brake whose check ended
            at rest within it is committed to, the search from the motion's first state
            (step 1) has no bound, and a committed brake is held without a check again
            until the step its check came to rest at (the module docstring).
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
        # the step by which its check had the arm at rest in the model (None: not yet known)
        self.rest_at: int | None = None
        self.searches = 0
        # where the committed brake stands in the order of candidates (two rounds of the
        # order: cushioned floor, then none)
        self._candidate = 0
        self._floors: tuple[Array, Array] = (cushion, np.zeros_like(cushion))

    def torque(self, state: ArmState, bias: Array, now: Array,
               holds: Callable[[Array, Array], bool], step: int,
               held: Array | None = None) -> Array | None:
        """Without a budget, the committed brake's torque if it is :meth:`live` at ``step``
        (the guard's count of control steps), ``holds(τ, floor)`` accepts it (its one-period
        prediction keeps every margin above the floor of the search that committed it) and
        its check, run again from here, still brings the arm to rest; else the first brake
        whose model braking keeps every margin above its floor until rest (:meth:`_search`;
        then committed), else None. Under a budget the guard asks :meth:`held_brake` for a
        committed brake before it asks this, which then searches. ``now``: the margins m_i at
        the sample; ``held``: the torque the actuators hold (under a torque-rate limit)."""
        # the motion's first state: its search runs until rest, whatever the budget
        budget = None if first_step(step) else self.budget
        if self.budget is None and self.live(step):
            assert self.committed is not None and self.floor is not None
            tau = self.table[self.committed](state, bias, self.period)
            if holds(tau, self.floor):
                # checked again from here (the module docstring)
                again = self._rollout(state, self.committed, self.floor, held).run()
                if again is not None and again.stopped:
                    self.held_at, self.rest_at = step, step + again.periods
                    return tau
                # its check failed from here: the next candidate
                return self._search(state, bias, now, step, held, self._candidate + 1,
                                    budget)
        return self._search(state, bias, now, step, held, 0, budget)

    def live(self, step: int) -> bool:
        """A brake is committed to and was held at the step before ``step``; under a budget,
        also the arm is not yet at rest by its check (``step`` is not past the step its
        check came to rest at): a brake held on past it held the Panda of the tail bench at
        rest 0.13 mrad from a joint limit for good, every step failing (S2) there. Without a
        budget its check runs again from each state instead (:meth:`torque`)."""
        if self.committed is None or self.floor is None or self.held_at != step - 1:
            return False
        return self.budget is None or (self.rest_at is not None and step <= self.rest_at)

    def held_brake(self, state: ArmState, bias: Array,
                   reaches: Sequence[Callable[[Array], Array]],
                   holds: Callable[[Array, Array], bool], step: int) -> Array | None:
        """While :meth:`live`, the committed brake's torque as the step holds it — the first
        of ``reaches`` of the brake clipped to the box (the step's own fits into its rate
        box) that ``holds(τ, floor)`` accepts (held then) —, else None — the commitment then
        ends, so that the step does not make and test the brake twice —, searching nothing:
        under a budget the guard holds it as soon as the law's own torque fails its test,
        before its other candidates."""
        if not self.live(step):
            return None
        assert self.committed is not None and self.floor is not None
        brake = self.box.clip(self.table[self.committed](state, bias, self.period))
        for reach in reaches:
            tau = reach(brake)
            if holds(tau, self.floor):
                self.held_at = step
                return tau
        self.forget()
        return None

    def _search(self, state: ArmState, bias: Array, now: Array, step: int,
                held: Array | None, first: int, budget: int | None) -> Array | None:
        """The first candidate from ``first`` on (the order with the cushioned floor, then with
        none) whose check brings the arm to rest in the model with every margin above its
        floor — under a budget, within ``budget`` model periods for all candidates together:
        a check the budget ends before it decides is not committed to, and no candidate
        follows it."""
        self.committed = None
        if first == 0:
            self.searches += 1
            # first with a cushion: a margin keeps δ_i, or half of itself where it is below
            # δ_i already; then with none (every margin positive in the model)
            cushioned = np.minimum(self.cushion, 0.5 * np.maximum(now, 0.0))
            self._floors = (cushioned, np.zeros_like(cushioned))
        left = budget
        order = self.order
        for k in range(first, 2 * len(order)):
            if left is not None and left <= 0:
                break
            name, floor = order[k % len(order)], self._floors[k // len(order)]
            check = self._rollout(state, name, floor, held)
            stop = check.run(left)
            if stop is not None and stop.stopped:
                self.committed, self.floor, self.held_at = name, floor, step
                self.rest_at, self._candidate = step + stop.periods, k
                return self.box.clip(self.table[name](state, bias, self.period))
            if left is not None:
                left -= check.held
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
        self.committed = self.floor = self.held_at = self.rest_at = None
