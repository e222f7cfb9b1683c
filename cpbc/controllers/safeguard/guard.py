"""The safeguard itself: the wrapper a law runs in (the package docstring), its state and
counts, and one control instant — accept the law's torque (acceptance.py) or replace it
(braking.py)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.stopping import Braking
from cpbc.controllers.controller import Controller, Evaluation, SafetyFilter
from cpbc.controllers.hold import hold_share
from cpbc.controllers.rescue import Rescue, first_step
from cpbc.controllers.safeguard.acceptance import Acceptance, StepSlack
from cpbc.controllers.safeguard.braking import Brakes, Reaches
from cpbc.controllers.safeguard.error_floors import ErrorFloors
from cpbc.controllers.safeguard.model_error import DeclaredError, acceleration_bound
from cpbc.controllers.safeguard.predicted_margins import (
    BrakingTest,
    PredictedMargins,
    RampTest,
    Sample,
)
from cpbc.controllers.safeguard.prediction import Predictor, predictor, travel_share
from cpbc.controllers.safeguard.settings import SafeguardSettings
from cpbc.controllers.safeguard.step_box import StepBox
from cpbc.controllers.safeguard.step_budget import OutOfTests, StepBudget
from cpbc.kernels.sampled_guard import floors
from cpbc.model.input_bounds import InputBounds
from cpbc.model.measured_state import finite_vector, refuse_non_finite
from cpbc.model.robot_model import ArmState


class StepTests(NamedTuple):
    """What one step tests its candidate torques with (Safeguard.step_tests)."""

    state: ArmState
    bias: Array  # C ẋ + g (+ f)
    predict: Predictor
    now: Array  # every guarded margin at the sample
    floor: Array  # (S1)'s floors at the period's end
    floor_mid: Array | None  # and at mid-period (configuration margins), None without any
    stop: BrakingTest | None  # (S2)
    past: np.ndarray | None  # the margins broken already (only the extra constraints')
    slack: StepSlack  # F(τ) ≥ 0 when τ passes


def guarded(
    law: Controller,
    bounds: InputBounds,
    settings: SafeguardSettings | None,
    also_keep: Sequence[ConfigurationConstraint] = (),
    model_error: Array | float | None = None,
    declared: DeclaredError | None = None,
) -> Controller:
    """The law as a sampled-data loop at the period of ``bounds`` should run it: wrapped in a
    Safeguard with ``settings`` when it enforces constraints, else the law itself (also with
    no settings).

    ``bounds`` are the control period and the plant's joint torque and torque-rate limits;
    ``model_error`` the declared bound on the model's acceleration error [per coordinate,
    rad/s² or m/s²] (a number or one per joint); ``declared`` the declared inertia, joint
    and measurement errors (model_error.DeclaredError)."""
    if isinstance(law, SafetyFilter):  # a filter already (a peer): fresh counts, no wrap
        return law.restarted()
    if settings is None or law.constraints.empty:
        return law
    return Safeguard(law, bounds, settings, also_keep, model_error, declared)


class Safeguard(SafetyFilter):
    """Wraps a constrained law so that (S1) holds under zero-order hold at period h.

    Args:
        law: the constrained law (its ``constraints`` and ``model`` are used).
        bounds: the control period h and the actuators' limits (cpbc.model.input_bounds).
            Torque |τ_q| ≤ L per joint: every torque the safeguard returns or predicts with
            lies in this box; the law's torque, the brakes and the escape are scaled toward
            C ẋ + g + f until they fit (StepBox.fit), which keeps the direction of the
            acceleration they ask for. Torque rate |τ̇_q| ≤ ρ per joint [N·m/s]: each step
            the guard chooses only among torques within ρh of the one the actuators hold
            (:meth:`holding`; its own last torque, or the gravity torque at its first
            state) and inside the torque box, tests every candidate as clipped there, and
            keeps the braking margins σ with the time the brake takes to ramp up
            (stopping.Braking.ramp): nothing after the guard need change its torque.
        settings: κ, λ, prediction sub-steps, back-off steps.
        also_keep: configuration constraints the law does not enforce (obstacles it does
            not know of, the plant's joint ranges) that the safeguard keeps as well: (S1)
            on them makes it brake before the arm reaches them. Those the law enforces
            already are skipped.
        model_error: ā, the declared bound on the model's acceleration error |a − â| ≤ ā
            per coordinate, shape (n,): every floor of (S1) is raised by what such an error
            can take off its margin in one period, and the braking set's deceleration is
            lowered by it (:mod:`cpbc.controllers.safeguard.model_error`).
        declared: a declared relative inertia error, held at each step as the acceleration
            error it makes at the law's acceleration (model_error.InertiaError), and
            measurement errors, whose reach is added to the floors too
            (model_error.measurement_losses); or None.

    The guard is five parts and the step that joins them (:meth:`_guard`): ``box``, the
    input bounds at this step (:class:`StepBox`); ``errors``, the floors the errors it holds
    raise (:class:`ErrorFloors`); ``acceptance``, the test (S1), (S2) and the blend
    (:class:`Acceptance`); ``brakes``, the replacement torques and the rescue
    (:class:`Brakes`); ``budget``, how many torques a step may test (:class:`StepBudget`).

    Attributes:
        calls: control instants seen.
        acted: instants at which the law's torque was replaced (β > 0).
        infeasible: instants at which even the braking torque failed (S1).
        scaled: instants at which the law's torque was outside the torque box and was scaled
            into it (it is then tested as scaled).
        uncorrected: instants at which the hold-corrected torque failed (S1) and the law's
            own torque kept it: the guard held a blend of the two, with as much of the
            correction as (S1) allows (not counted as acting: the torque is the law's).
        rescues: instants at which a rescue brake was held.
        out_of_tests: instants that spent the budget of tests (``test_budget``).
    """

    type_name = "safeguard"

    def __init__(
        self,
        law: Controller,
        bounds: InputBounds,
        settings: SafeguardSettings | None = None,
        also_keep: Sequence[ConfigurationConstraint] = (),
        model_error: Array | float | None = None,
        declared: DeclaredError | None = None,
    ) -> None:
        super().__init__(law.model, law.target, law.constraints)
        self.law = law
        self.bounds = bounds
        self.period = float(bounds.period)
        self.settings = settings = settings or SafeguardSettings()
        self.keep = settings.keep_fraction(self.period)
        self.keep_half = math.sqrt(self.keep)
        self.substeps = settings.steps_for(self.period)
        # s of the hold correction τ − s D Δa: the drift the plant's hold has (hold.py)
        hold = hold_share(self.period, settings.plant_step) if settings.hold_correction else 0.0
        # c of the predicted end x + hẋ + c h² a: where the plant's own steps land
        self.travel = travel_share(self.period, settings.plant_step)
        own = law.constraints
        seen = set(own.names)  # a constraint the law enforces already, or a repeat, is skipped
        extra = []
        for c in also_keep:
            if seen.isdisjoint(c.names):
                extra.append(c)
                seen.update(c.names)
        # the constraints the guard keeps: the law's own, and the extra configuration ones
        self.guarded = own if not extra or own.empty else ConstraintSet(
            own.n, (*own.configuration, *extra), own.velocity)
        self._extra = ConstraintSet(own.n, extra) if extra and not own.empty else None
        at_target = self.guarded.margins(law.target, np.zeros(law.model.n))
        scale = settings.cushion * self.period / 0.01
        # δ_i; a constraint only the guard keeps may have the target beyond it (a joint limit
        # the law does not know of between it and its target): the size of its margin there
        self.cushion = scale * np.abs(at_target)
        nc = self._n_config = self.guarded.n_configuration
        if settings.velocity_cushion is not None:
            self.cushion[nc:] = (settings.velocity_cushion * self.period / 0.01
                                 * np.abs(at_target[nc:]))
        self._n_own_config = own.n_configuration
        self.box = StepBox(law.model, bounds)
        torque_limit, self.rate_limit = self.box.torque_limit, self.box.rate_limit
        self.model_error = None if model_error is None else acceleration_bound(
            model_error, law.model.n)
        self.declared = declared
        self.errors = ErrorFloors(self.guarded, law.model, self.box, self.model_error,
                                  declared, self.period, self.travel, self.cushion)
        self._velocity_floor = np.maximum(self.cushion[nc:], 1e-300)
        # under bounded torque the guard also keeps the braking margins σ (stopping.Braking)
        braking = None if torque_limit is None or not nc else Braking.of(
            law.model, torque_limit, rate=self.rate_limit, disturbance=self.model_error)
        self.budget = StepBudget(settings.test_budget, settings.time_budget)
        self.acceptance = Acceptance(
            law.model, PredictedMargins(self.guarded, law.model), self.box, braking,
            np.maximum(self.cushion[:nc], 1e-300), self.period, hold, settings.backoffs,
            self.budget)
        # where no torque of its own will do: brakes better than the uniform one (rescue.py)
        torque_box = self.box.torque_box
        rescue = None if braking is None or torque_box is None else Rescue(
            law.model, self.guarded, torque_box, self.cushion, self.period, self.substeps,
            rate_step=self.box.rate_step, budget=settings.rescue_budget,
            margins=self.acceptance.along.margins_along)
        self.brakes = Brakes(self.guarded, settings, self.acceptance, self.box, rescue,
                             self.cushion, self.keep, self.keep_half, self.travel, self.period)
        self.calls = 0
        self.acted = 0
        self.infeasible = 0

    @property
    def scaled(self) -> int:
        """Steps at which the law's torque was scaled into the torque box."""
        return self.acceptance.scaled

    @property
    def uncorrected(self) -> int:
        """Steps at which the law's own torque kept (S1) where its hold-corrected one failed."""
        return self.acceptance.uncorrected

    @property
    def out_of_tests(self) -> int:  # type: ignore[override]
        """Steps that spent their budget of tests (step_budget.py)."""
        return self.budget.spent

    @property
    def rescues(self) -> int:  # type: ignore[override]
        """Steps at which a rescue brake was held."""
        return self.brakes.rescues

    # -- the Controller interface ------------------------------------------------------------

    def state(self, x: Array, dx: Array) -> ArmState:
        return self.law.state(x, dx)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        """The guarded torque and the law's V at the per-step state; ConstraintViolation
        outside S (NonFiniteState at a state that is not finite), the guard as it was."""
        out = self.law.evaluate_state(state, margins=True)  # raises outside S
        refuse_non_finite(out.torque, state.x, state.dx)  # before the guard moves
        self.calls += 1
        if self.constraints.empty:
            return out
        assert out.margins is not None  # asked for
        tau = self.filter(state, out.torque, out.margins)
        return Evaluation(tau, out.lyapunov, out.margins if margins else None)

    def filter(self, state: ArmState, law: Array, law_margins: Array) -> Array:
        """The guarded torque for the law's torque ``law`` and margins at the per-step state
        (one control instant; the counts move). A time budget counts from here."""
        self.budget.start()
        if not self.box.rate_limited:
            return self._guard(state, law, law_margins)
        return self._rate_limited(state, law, law_margins)

    def holding(self, tau: Array, added: Array | None = None) -> None:
        """Tell the guard the torque the actuators hold now (controller coordinates): the
        next step's torque lies within ρh of it. The guard's own last torque is assumed
        otherwise, and at its first step the gravity torque of its first state (an arm held
        at rest; a Franka's own gravity compensation). ``added``: the torque the robot adds
        to every command itself at this state (a Franka's gravity compensation), whose box
        then bounds the command, τ − added, not τ: the guard's box moves by it. A ParameterError
        names either when it is not n finite numbers (the guard as it was)."""
        n = self.model.n
        held = finite_vector(tau, n, "tau", "the torque held, one per coordinate")
        self.box.hold(held, None if added is None else finite_vector(
            added, n, "added", "the torque the robot adds, one per coordinate"))

    def _rate_limited(self, state: ArmState, law: Array, law_margins: Array) -> Array:
        """The guard's step inside the box one step can reach from the held torque: every
        candidate is tested as clipped there (the predictor saturates into the step's box)
        and the torque returned lies in it."""
        self._begin(state)
        return self.box.end(self._guard(state, law, law_margins))

    def _begin(self, state: ArmState) -> None:
        """The step's box and velocity lookahead under a torque-rate limit."""
        assert self.rate_limit is not None
        self.box.begin(state)
        self.acceptance.ramp = RampTest(state.dx, self.period, state.inertia,
                                        self.box.to_joint, self.rate_limit,
                                        self._velocity_floor)

    def lyapunov(self, x: Array, dx: Array) -> float:
        """The law's V: the law alone is asked, no count moves (the loop asks for the true
        state's V beside every guarded call when the measurement is noisy)."""
        return self.law.lyapunov(x, dx)

    # -- the guard ---------------------------------------------------------------------------

    def _guard(self, state: ArmState, tau: Array, law_margins: Array) -> Array:
        """τ if it satisfies (S1), else the smallest blend toward braking that does."""
        step = self._tests(state, tau, law_margins)
        self.budget.begin()
        acted = self.acted
        try:
            return self._choose(step, tau)
        except OutOfTests:  # the step's budget of tests is spent (step_budget.py)
            self.budget.spent += 1
            self.acted = acted + 1  # the law's torque, as held, did not pass
            if self.budget.passed is not None:
                return self.budget.passed
            return self._out_of_tests(step)

    def _out_of_tests(self, step: StepTests) -> Array:
        """A step whose budget of tests is spent before any torque passed: the rescue's
        committed brake while it holds it (one test), or at the motion's first step its
        search, until rest; then under a time budget the uniform brake, which the step
        before's torque was tested with ((S2)), at once (under a rate limit made ahead,
        StepBudget.ready: a search's stopping points, ~200 µs for the aimed brake on the
        Panda, no test's time foretells); else the rescue's bounded search, else the uniform
        brake (:meth:`_spent`) — not the first of the rescue's brakes to pass one period's
        test, which (S2) did not promise (figure eight, seed 58, reliability.md)."""
        state, bias, brakes = step.state, step.bias, self.brakes
        with self.budget.lifted():
            held = brakes.committed(state, bias, step.predict, step.now, self.calls)
            if held is None and first_step(self.calls):
                held = brakes.rescued(state, bias, step.predict, step.now, self.calls)
        if held is not None:
            return held
        if self.budget.timed:
            ready = self.budget.ready
            return ready if ready is not None else self._spent(step)
        if not first_step(self.calls):
            with self.budget.lifted():
                held = brakes.rescued(state, bias, step.predict, step.now, self.calls)
        return held if held is not None else self._spent(step)

    def _spent(self, step: StepTests, reaches: Reaches | None = None) -> Array:
        """The uniform brake, untested; rate-limited its reach that keeps (S0) (Brakes.spent)."""
        if reaches is None and self.box.rate_limited:
            reaches = self._reaches(step)
        floors = None if step.past is not None else (step.floor, step.floor_mid)
        stop = None if reaches is not None else step.state.inertia.dot(step.state.dx) / self.period
        with self.budget.lifted():
            return self.brakes.spent(step.bias, stop, step.predict,
                                     Sample(step.state.x, step.now), reaches, floors)

    def _reaches(self, step: StepTests) -> Reaches:
        """The calmest brake's two reaches, F's sign (exact where < 0) and (S0) where F's test
        tells it: the step's own test uncounted (StepSlack.with_positivity), timed ahead."""
        with self.budget.lifted():
            test = self.budget.uncounted(step.slack.with_positivity(self.brakes.cushion))
            return self.brakes.reaches(step.bias, step.state.inertia.dot(step.state.dx) /
                                       self.period, test)

    def step_tests(self, state: ArmState, law: Array, law_margins: Array) -> StepTests:
        """What a step at ``state`` tests a torque with, as :meth:`filter` makes it for the
        law's torque ``law`` and margins ``law_margins``: the prediction, the margins now, the
        floors and F (``slack``: F(τ) ≥ 0 when τ passes). Under a torque-rate limit the step's
        box is set around the held torque first, as a step begins. No count moves and no
        budget applies: for reading F of any torque at a state."""
        if self.box.rate_limited:
            self._begin(state)
        with self.budget.lifted():  # F made here is not counted against a step's tests
            return self._tests(state, law, law_margins)

    def _tests(self, state: ArmState, tau: Array, law_margins: Array) -> StepTests:
        """What this step tests a torque with: the prediction, the margins now, the floors
        of (S1) raised by the declared errors, (S2)'s floors, and F."""
        bias = state.coriolis_force + state.gravity
        if self.model.has_friction:
            bias = bias + state.dissipation
        predict = self.predictor(state, bias)
        now, floor, mid = self.sample_floors(state.x, law_margins)  # (S1)
        nc = self._n_config
        refine = self.errors.raise_floors(state, bias, tau, floor, mid)
        floor_mid = None
        past = None
        if nc:
            floor_mid = mid
            if self._extra is not None and not now[now.argmin()] > 0.0:
                # An extra constraint (one only the guard keeps) is broken already, from a
                # state nothing could stop the arm from: its margin must merely not shrink,
                # so a law that leads back is let through (asking for a positive margin at
                # the period's end made every step fail and held the arm there for good).
                past = now <= 0.0
                if refine is not None:  # the floors copied below: exact before
                    refine()
                    refine = None
                floor = np.where(past, now, floor)
                floor_mid = np.where(past[:nc], now[:nc], floor_mid)
        stop = self.acceptance.braking_floor(state, bias, self.box.holding)
        slack = self.acceptance.check(predict, floor, floor_mid, stop, past,
                                      Sample(state.x, now), refine)  # (S1)
        return StepTests(state, bias, predict, now, floor, floor_mid, stop, past, slack)

    def _before_candidates(self, step: StepTests) -> tuple[Array | None, Reaches | None]:
        """Once the law's torque fails: the rescue's committed brake where it holds one that
        passes, else None — having made, under a time budget, what a step out of time holds
        (and under a rate limit the brake's reaches, tested, which the candidates take up)."""
        # a brake whose check saw the arm to rest (Rescue.held_brake): tested whatever the
        # budget, as a step out of tests would (cut off, made twice: 300 µs on the Panda)
        brakes = self.brakes
        if brakes.holding(self.calls):
            with self.budget.uncut():
                held = brakes.committed(step.state, step.bias, step.predict, step.now, self.calls)
            if held is not None:
                return held, None
        if not self.budget.timed or first_step(self.calls):
            return None, None
        with self.budget.ahead():  # made after the budget ran out, it ran past it: up to
            # 95 µs (the reaches' tests), 10-20 µs without a rate limit (the uniform brake)
            reaches = self._reaches(step) if self.box.rate_limited else None
            self.budget.ready = self._spent(step, reaches)
        return None, reaches

    def _choose(self, step: StepTests, tau: Array) -> Array:
        """The chain of candidates (the package docstring, steps 3 and 4): the law's torque
        as held, the slide, the brakes and their search, the rescue, the fallback."""
        accept, brakes = self.acceptance, self.brakes
        state, bias, slack = step.state, step.bias, step.slack
        tau, f0 = accept.held(state, bias, tau, slack)
        if f0 >= 0.0:
            return tau
        self.acted += 1
        held, reaches = self._before_candidates(step)
        if held is not None:
            return held
        if step.floor_mid is not None:  # first the law less its push into the boundaries
            with self.budget.making("slide"):
                slid = brakes.slide(state, bias, tau, step.now, step.floor, step.floor_mid,
                                    step.stop)
            f_slid = slack(slid)
            if f_slid >= 0.0:
                return accept.blend(tau, slid, f0, f_slid, slack)
        to_rest = state.inertia.dot(state.dx) / self.period
        brake, f1 = (brakes.calmest(bias, to_rest, slack) if reaches is None
                     else reaches).first_passing()
        if f1 >= 0.0 and reaches is not None:  # tested ahead: the step's, as if tested now
            self.budget.passed = brake
        if f1 < 0.0:
            # Reverse instead of stop: x⁺ = x, ẋ⁺ = −ẋ, the least excursion at this speed.
            reverse = brakes.brake(bias, to_rest, 2.0)
            f_rev = slack(reverse)
            if f_rev < 0.0:
                # Stopping goes too far and reversing at full speed breaks a velocity
                # margin: search the deceleration λ in between.
                lam, f_lam = brakes.search_braking(bias, to_rest, slack, f1, f_rev)
                if f_lam < 0.0:
                    self.infeasible += 1
                    rescued = brakes.rescued(state, bias, step.predict, step.now, self.calls)
                    if rescued is not None:
                        return rescued
                    return brakes.infeasible(state, bias, to_rest, step.predict, step.now,
                                             step.floor, step.floor_mid)
                reverse, f_rev = brakes.brake(bias, to_rest, lam), f_lam
            brake, f1 = reverse, f_rev
        return accept.blend(tau, brake, f0, f1, slack)

    def warm(self, x: Array, dx: Array) -> None:
        """Take every path of a step once at (x, ẋ), whatever the law's torque does there
        (the test, the slide, the brakes, the search of λ, the blend, the rescue's search,
        the fallback, a spent step's brake), as a real-time loop must before its first
        cycle, where a first call costs milliseconds. The counts and the rescue's
        commitment move: warm a spare guard, not the one that drives."""
        state = self.law.state(x, dx)
        out = self.law.evaluate_state(state, margins=True)
        assert out.margins is not None  # asked for
        if self.box.rate_limited:
            self._begin(state)
        with self.budget.lifted():  # every path, not the first K tests
            step = self._tests(state, out.torque, out.margins)
            accept, brakes, slack = self.acceptance, self.brakes, step.slack
            tau, _ = accept.held(state, step.bias, out.torque, slack)
            to_rest = state.inertia.dot(state.dx) / self.period
            brake = brakes.calmest(step.bias, to_rest, slack).nearest
            if step.floor_mid is not None:
                brakes.slide(state, step.bias, tau, step.now, step.floor, step.floor_mid,
                             step.stop)
            accept.blend(tau, brake, -1.0, 1.0, slack)
            brakes.search_braking(step.bias, to_rest, slack, -1.0, -1.0)
            brakes.rescued(state, step.bias, step.predict, step.now, self.calls)
            brakes.infeasible(state, step.bias, to_rest, step.predict, step.now, step.floor,
                              step.floor_mid)
            self._out_of_tests(step)  # a spent first step: the rescue's search again
            self._spent(step)  # a spent later step's (rate-limited: its reaches, their (S0))
        if self.box.rate_limited:
            self.box.end(tau)

    def prime(self, x: Array, dx: Array) -> None:
        """What a step at (x, ẋ) reads — the law, the step's box, prediction, floors and the
        law's test — touched with no count moved and the held torque kept: the driving
        guard's own data before its first cycle (:meth:`warm` takes the paths on a spare)."""
        state = self.law.state(x, dx)
        out = self.law.evaluate_state(state, margins=True)  # raises outside S
        if self.constraints.empty or out.margins is None:  # (margins: asked for)
            return
        held = self.box.holding
        try:
            self.step_tests(state, out.torque, out.margins).slack.plain_sign(out.torque)
        finally:
            self.box.holding = held

    def sample_floors(self, x: Array, law_margins: Array) -> tuple[Array, Array, Array]:
        """Every guarded margin at the sample — the law's, with the extra configuration
        constraints' after its own configuration margins; NaN counted as −∞ — and the
        floors of (S1) from them: at the period's end, and for the configuration margins at
        mid-period (cpbc.kernels.sampled_guard.floors), before the declared errors raise
        them (ErrorFloors.raise_floors)."""
        margins = law_margins
        if self._extra is not None:
            k = self._n_own_config
            margins = np.concatenate(
                (law_margins[:k], self._extra.configuration_margins(x), law_margins[k:]))
        n = len(margins)
        now, floor, mid = np.empty(n), np.empty(n), np.empty(self._n_config)
        floors(margins, self.cushion, self.keep, self.keep_half, now, floor, mid)
        return now, floor, mid

    def predictor(self, state: ArmState, bias: Array) -> Predictor:
        """The period's prediction under a held τ (:func:`prediction.predictor`)."""
        return predictor(self.model, state, bias, self.period, self.substeps, self.box.reachable,
                         self.settings.corrector, self.travel)
