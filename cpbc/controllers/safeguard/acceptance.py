"""The safeguard's acceptance test (step 3 of the package docstring): F(τ) of (S1) and (S2)
over a prediction, the law's torque as the guard holds it (corrected for the hold), and the
Illinois blend toward a replacement torque for the smallest share that passes."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.stopping import Braking
from cpbc.controllers.hold import hold_corrected
from cpbc.controllers.safeguard.error_floors import Refine
from cpbc.controllers.safeguard.predicted_margins import (
    SEGMENT_POINTS,
    BrakingTest,
    PredictedMargins,
    RampTest,
    Sample,
)
from cpbc.controllers.safeguard.prediction import Frozen, Predictor
from cpbc.controllers.safeguard.step_box import StepBox
from cpbc.controllers.safeguard.step_budget import StepBudget
from cpbc.model.robot_model import ArmState, RobotModel

Slack = Callable[[Array], float]  # F(τ): ≥ 0 when τ passes


class StepSlack:
    """F(τ) of one step (:meth:`Acceptance.check`): a call gives F; :meth:`sign` gives F
    where it is < 0 and a value in [0, F] where it is not — all the step's first test
    needs (the torque is held where F ≥ 0, and F goes on to the blend only where it is
    not), and with fewer joint placements computed (PredictedMargins.slack's
    ``enough``). Both count against the step's budget alike; :meth:`plain_sign` is the
    sign uncounted, for what the guard makes outside the budget (its brakes made ahead,
    Safeguard._reaches; Safeguard.prime), which the budget wraps there as it needs;
    :meth:`with_positivity` is that sign with (S0) read from the same test. ``signs``:
    (t, cushions or None) ↦ (the sign, (S0) or NaN), uncounted."""

    __slots__ = ("_exact", "_sign", "_signs")

    def __init__(self, exact: Slack, sign: Slack,
                 signs: Callable[[Array, Array | None], tuple[float, float]]) -> None:
        self._exact, self._sign, self._signs = exact, sign, signs

    def __call__(self, t: Array) -> float:
        return self._exact(t)

    def sign(self, t: Array) -> float:
        """F(t) where it is < 0, else a value in [0, F(t)]."""
        return self._sign(t)

    def plain_sign(self, t: Array) -> float:
        """:meth:`sign` uncounted."""
        return self._signs(t, None)[0]

    def with_positivity(self, cushion: Array) -> Callable[[Array], tuple[float, float]]:
        """t ↦ (:meth:`plain_sign` of t, P): P (S0) of t over the first prediction, the
        margins above their cushions ``cushion`` — with the sign (S0)'s own test gives
        (Brakes.positivity) — where F's compiled test tells it, else NaN
        (PredictedMargins.frozen_positivity). Uncounted, as :meth:`plain_sign`."""
        signs = self._signs
        return lambda t: signs(t, cushion)


class Acceptance:
    """(S1), (S2) and the blend: the safeguard's test of a torque.

    Args:
        model: the controller's model.
        along: the guarded margins along a prediction (compiled).
        box: the step's input bounds (the law's torque is put in them).
        braking: the uniform brake whose margins σ (S2) holds, or None.
        sigma_floor: the floors of σ_i (their cushions δ_i).
        period: h [s].
        hold_share: s of the hold correction (0: none).
        backoffs: Illinois steps of the blend.
        budget: the tests a step may make (every F that :meth:`check` returns counts), or
            None for no bound.

    Attributes:
        ramp: this step's velocity lookahead under a torque-rate limit (set by the guard).
        scaled: steps at which the law's torque was scaled into the torque box.
        uncorrected: steps at which the law's own torque kept (S1) where its hold-corrected
            one failed it.
    """

    def __init__(self, model: RobotModel, along: PredictedMargins, box: StepBox,
                 braking: Braking | None, sigma_floor: Array, period: float,
                 hold_share: float, backoffs: int, budget: StepBudget | None = None) -> None:
        self.model, self.along, self.box, self.braking = model, along, box, braking
        self.sigma_floor, self.period, self.hold_share = sigma_floor, period, hold_share
        self.backoffs = backoffs
        self.budget = budget or StepBudget(None)
        self.ramp: RampTest | None = None
        self.scaled = 0
        self.uncorrected = 0

    def check(self, predict: Predictor, end_floor: Array, mid_floor: Array | None,
               stop: BrakingTest | None = None, past: np.ndarray | None = None,
               sample: Sample | None = None, refine: Refine | None = None,
               lookahead: bool = True) -> StepSlack:
        """F(τ) = min_i m_i/floor_i − 1 over the predicted end (and mid-period
        configuration) margins of every prediction, and with ``stop`` = (1/(2θA), floors)
        the braking margins σ_i at the predicted ends: ≥ 0 when τ keeps every margin above
        its floor (``PredictedMargins.slack``, compiled). The velocity margins count inside
        the period too, held to their end floor: under a held torque whose acceleration
        turns within the period a rate can cross its bound and be back by the end (seen at
        100 Hz once the torque was corrected for the hold). ``past`` marks the margins
        already ≤ 0 (only the extra constraints can be): their floor is their present value,
        compared by difference, and their braking margin is not held (Safeguard._guard).
        ``sample``: where the step starts, whose margins bound the sphere clearances along
        the prediction (PredictedMargins.slack), or None. ``refine``: the floors are raised
        by bounds of the errors' losses (cpbc.controllers.safeguard.error_floors), and this
        makes them exact in place: before any F but a sign ≥ 0, which the exact floors only
        raise (F falls as a floor rises), or None. ``lookahead``: under a torque-rate limit,
        also the velocity margins where the rates peak while the torque ramps back from the
        period's acceleration (:attr:`ramp`); False for a brake whose check held it, ramped
        as the motors allow, until rest (Brakes.committed)."""
        along = self.along
        ramp = self.ramp if along.nv and lookahead else None
        frozen = predict if (isinstance(predict, Frozen) and along.fuses
                             and past is None) else None

        def f(t: Array, given: Sample | None, enough: float = 1.0,
              cushion: Array | None = None) -> tuple[float, float]:
            if frozen is not None:  # the same F in compiled calls (PredictedMargins.frozen_slack)
                acc, after = frozen.start(t)
                return along.frozen_positivity(frozen, acc, after, end_floor, mid_floor, stop,
                                               given, enough, ramp, cushion)
            rows = predict(t)
            end = along.slack(rows, end_floor, mid_floor, stop, past, given, enough)
            return (end if ramp is None else min(end, along.ramp_slack(rows, ramp))), math.nan

        pending = [] if refine is None else [refine]  # emptied once the floors are exact
        # F's value: exact from the sample's bounds too (``enough`` ∞) where they settle
        # clearances one by one (the compiled test); the rows' path computes a row whole
        exact_from = sample if frozen is not None else None

        def value(t: Array) -> float:
            if pending:
                pending.pop()()
            return f(t, exact_from, math.inf)[0]

        def signs(t: Array, cushion: Array | None = None) -> tuple[float, float]:
            # one test, taken again under the exact floors if < 0
            found = f(t, sample, 1.0, cushion)
            if found[0] < 0.0 and pending:
                pending.pop()()
                found = f(t, sample, 1.0, cushion)
            return found

        def sign(t: Array) -> float:
            return signs(t)[0]

        exact = self.budget.counted(value)
        if sample is None and refine is None:  # the sign is F: no bound, no floor to refine
            return StepSlack(exact, exact, signs)
        # Where F's value counts (the blend's, the brakes') the guard acts, near a boundary,
        # where a bound settles no row whole: the rows' path then only pays for the bounds,
        # while the compiled test still skips the clearances they settle. A sign's test,
        # shorter, is not what a time budget takes a later (exact) test's time to be
        # (StepBudget.counted).
        return StepSlack(exact, self.budget.counted(sign, exact=False), signs)

    def braking_floor(self, state: ArmState, bias: Array,
                       held: Array | None = None) -> BrakingTest | None:
        """(1/(2θA), the floors of the braking margins σ_i: their cushions δ_i, and under a
        torque-rate limit the brake's ramp time from the torque ``held``), or None without a
        torque box, at rest, or where the box leaves no deceleration (then no torque can
        help and σ is not held). σ is held above its cushion, not by the decay rule (S1):
        that would cost a second evaluation of every constraint per step, at the stopping
        point of the sample, and φ itself is held by (S1) already. The ramp is taken from
        the held torque plus one period: a candidate lies within ρh of it."""
        braking = self.braking
        if braking is None:
            return None
        per_speed = braking.per_speed(state.inertia, bias, state.dx)
        if per_speed == 0.0 or per_speed == math.inf:
            return None
        if braking.rate is None:
            return BrakingTest(per_speed, self.sigma_floor)
        ramp = braking.ramp(state.inertia, bias, state.dx,
                            state.gravity if held is None else held, per_speed)
        return BrakingTest(per_speed, self.sigma_floor, ramp + self.period, state.dx,
                           self.period, SEGMENT_POINTS)

    def held(self, state: ArmState, bias: Array, law: Array,
             slack: StepSlack) -> tuple[Array, float]:
        """The law's torque as the guard would hold it, and F of (S1) there: corrected for
        the hold (:func:`hold_corrected`, by the plant's share ``hold_share``) and scaled
        into the torque box. If that fails (S1) while the law's own torque keeps it, the
        blend of the two with as much of the correction as (S1) lets through (F ≥ 0): the
        correction, not the law, is what fails then. It is right for a plant whose
        acceleration drifts within the period (the corrected prediction), while the frozen
        prediction sees the correction and none of the drift, and finds the margin moved
        by s h Δa against the law's own torque; near a velocity bound that is more than
        (S1) allows, and braking there fought the law on every other step."""
        share = self.hold_share
        tau = hold_corrected(self.model, state, bias, law, self.period, share) if share else law
        boxed = self.box.fit(bias, tau)
        if boxed is not tau:
            self.scaled += 1
            tau = boxed
        f0 = slack.sign(tau)  # F only where < 0: the torque is held where it passes
        if f0 >= 0.0 or not share:
            return tau, f0
        plain = self.box.fit(bias, law)
        f_plain = slack(plain)
        if f_plain < 0.0:
            return tau, f0
        self.uncorrected += 1
        return self.blend(tau, plain, f0, f_plain, slack), 0.0

    def blend(self, tau: Array, brake: Array, f0: float, f1: float, slack: Slack) -> Array:
        """Illinois steps for the smallest β with F(β) ≥ 0, bracketed by F(0) < 0 ≤ F(1)."""
        lo, f_lo, hi, f_hi = 0.0, f0, 1.0, f1
        side = 0
        for _ in range(self.backoffs):
            beta = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not lo < beta < hi:
                beta = 0.5 * (lo + hi)
            f = slack((1.0 - beta) * tau + beta * brake)
            if f >= 0.0:
                hi, f_hi = beta, f
                if side == 1:
                    f_lo *= 0.5
                side = 1
            else:
                lo, f_lo = beta, f
                if side == -1:
                    f_hi *= 0.5
                side = -1
        return (1.0 - hi) * tau + hi * brake

