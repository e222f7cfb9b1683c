"""What the safeguard holds when the law's torque fails its test (step 4 of the package
docstring): the law less its push into the boundaries (the slide), the brakes b − λ D ẋ/h and
the search of λ, the rescue's brakes (cpbc.controllers.rescue), and, when nothing passes, the
calmest brake or the escape."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.controllers.rescue import Rescue
from cpbc.controllers.safeguard.acceptance import Acceptance, Slack, StepSlack
from cpbc.controllers.safeguard.predicted_margins import BrakingTest, Sample
from cpbc.controllers.safeguard.prediction import Frozen, Predictor
from cpbc.controllers.safeguard.settings import SafeguardSettings
from cpbc.controllers.safeguard.step_box import StepBox
from cpbc.kernels.sampled_guard import project_halfspaces
from cpbc.kernels.slide import slide_acceleration
from cpbc.model.robot_model import ArmState


class Reaches(NamedTuple):
    """The calmest brake b − λ₀ D ẋ/h of one step reached into its box, with F of (S1) and
    (S2) of each (or its sign, exact where < 0: StepSlack.sign): by its nearest
    acceleration, and under a torque-rate limit along the line from the held torque (None
    where it was not made).

    Attributes:
        nearest, f_nearest: the brake reached by its nearest acceleration (Brakes.brake), F.
        line, f_line: reached along the line (Brakes.brake_along_line), F; or None, −∞.
        kept_nearest, kept_line: (S0) of each over the first prediction as F's test told
            it (StepSlack.with_positivity: its sign is the sign of (S0)'s own test), or NaN
            where it did not.
    """

    nearest: Array
    f_nearest: float
    line: Array | None = None
    f_line: float = -math.inf
    kept_nearest: float = math.nan
    kept_line: float = math.nan

    def first_passing(self) -> tuple[Array, float]:
        """The nearest reach where it passes, else the line where it passes, else the
        nearest: the guard's brake among its candidates (Safeguard._choose)."""
        if self.f_nearest < 0.0 and self.line is not None and self.f_line >= 0.0:
            return self.line, self.f_line
        return self.nearest, self.f_nearest

    def by_f(self) -> tuple[Array, ...]:
        """The reaches made, the one whose F comes nearer to passing first."""
        return tuple(tau for tau, _ in self.told())

    def told(self) -> tuple[tuple[Array, float], ...]:
        """:meth:`by_f`, each reach with its (S0) as F's test told it (NaN: not told)."""
        nearest = self.nearest, self.kept_nearest
        if self.line is None:
            return (nearest,)
        line = self.line, self.kept_line
        return (line, nearest) if self.f_line > self.f_nearest else (nearest, line)


class Brakes:
    """The replacement torques, tested by the guard's acceptance.

    Args:
        guarded: the constraints the guard keeps (configuration ones first).
        settings: λ₀, the search's steps.
        acceptance: the test a replacement must pass.
        box: the step's input bounds (every replacement is put in them).
        rescue: the rescue's brakes, or None (no torque box).
        cushion: δ_i per guarded margin.
        keep: e^{−κh}, the share of a margin (S1) keeps over a period (keep_half: at mid-period).
        travel: c of the predicted end x + hẋ + c h² a.

    Attributes:
        rescues: steps at which a rescue brake was held.
    """

    def __init__(self, guarded: ConstraintSet, settings: SafeguardSettings,
                 acceptance: Acceptance, box: StepBox, rescue: Rescue | None, cushion: Array,
                 keep: float, keep_half: float, travel: float, period: float) -> None:
        self.guarded, self.settings, self.acceptance = guarded, settings, acceptance
        self.box, self.rescue, self.cushion = box, rescue, cushion
        self.keep, self.keep_half, self.travel, self.period = keep, keep_half, travel, period
        self.n_config = guarded.n_configuration
        self.rescues = 0

    def brake(self, bias: Array, stop: Array, lam: float) -> Array:
        """The braking torque b − λ D ẋ/h, put in the step's box (StepBox.fit)."""
        return self.box.fit(bias, bias - lam * stop, brake=True)

    def calmest(self, bias: Array, stop: Array, slack: Slack) -> Reaches:
        """The calmest brake b − λ₀ D ẋ/h reached by its nearest acceleration and F there;
        under a torque-rate limit, where it fails, reached along the line too: a joint
        riding its rate bound, sped up through D by the nearest acceleration
        (panda_goal_pose_rate seed 100, docs/reliability.md), the line slows."""
        box, brake = self.box, bias - self.settings.braking * stop
        nearest = box.fit(bias, brake, brake=True)  # as self.brake, self.brake_along_line
        f = slack(nearest)
        if not box.rate_limited or f >= 0.0:
            return Reaches(nearest, f)
        line = box.fit(bias, brake)
        return Reaches(nearest, f, line, slack(line))

    def reaches(self, bias: Array, stop: Array,
                test: Callable[[Array], tuple[float, float]]) -> Reaches:
        """Under a torque-rate limit, both of :meth:`calmest`'s reaches whatever the first's
        F (what a spent step holds, made ahead: Safeguard._reaches), ``test`` telling F and
        (S0) of each (StepSlack.with_positivity)."""
        box, brake = self.box, bias - self.settings.braking * stop
        nearest = box.fit(bias, brake, brake=True)
        f, kept = test(nearest)
        line = box.fit(bias, brake)
        f_line, kept_line = test(line)
        return Reaches(nearest, f, line, f_line, kept, kept_line)

    def brake_along_line(self, bias: Array, stop: Array, lam: float) -> Array:
        """The braking torque b − λ D ẋ/h reached from the held torque along the straight
        line, as far as the step's rate box allows (StepBox.fit of a law's torque): its
        acceleration is a blend of the held torque's and the brake's, so a joint that both
        slow is slowed, where the nearest acceleration (:meth:`brake`) may speed it up
        through the coupling in D to give the others their share."""
        return self.box.fit(bias, bias - lam * stop)

    def search_braking(
        self, bias: Array, stop: Array, slack: Slack, f_stop: float, f_reverse: float,
    ) -> tuple[float, float]:
        """Golden-section search of λ ∈ (λ₀, 2) for the braking torque bias − λ D ẋ / h with
        the largest F, stopping at the first λ with F ≥ 0. Between stopping (excursion ½hẋ)
        and reversing (excursion ¼hẋ, speed kept) lies a λ whose excursion h ẋ / (2λ) fits
        the configuration margin while the end speed |1 − λ|·|ẋ| keeps the velocity ones."""
        a, b = self.settings.braking, 2.0
        best = max((f_stop, a), (f_reverse, b))
        budget = self.settings.brake_search if a < b else 0
        ratio = 0.5 * (math.sqrt(5.0) - 1.0)
        c, d = b - ratio * (b - a), a + ratio * (b - a)
        fc = fd = -math.inf
        for i in range(budget):
            at_c = i == 0 or (i > 1 and fc > fd)
            if at_c:  # a new point c: the larger F lies in [a, d]
                if i > 1:
                    b, d, fd = d, c, fc
                    c = b - ratio * (b - a)
                lam = c
            else:  # a new point d: the larger F lies in [c, b]
                if i > 1:
                    a, c, fc = c, d, fd
                    d = a + ratio * (b - a)
                lam = d
            f = slack(self.brake(bias, stop, lam))
            if at_c:
                fc = f
            else:
                fd = f
            best = max(best, (f, lam))
            if f >= 0.0:
                break
        return best[1], best[0]

    def rescued(self, state: ArmState, bias: Array, predict: Predictor, now: Array,
                step: int) -> Array | None:
        """The rescue's brake (rescue.py) when it finds one that stops the arm inside S in
        the model; a committed one is held again, in the period right after the one it was
        held in (``step``: the guard's count of control steps), while its one-period
        prediction keeps every margin above the floor it was found with."""
        if self.rescue is None:
            return None
        tau = self.rescue.torque(state, bias, now, self._holds(predict, Sample(state.x, now)),
                                 step, self.box.holding)
        return self._counted(None if tau is None else self._reach(bias)(tau))

    def holding(self, step: int) -> bool:
        """Under a rescue budget, whether a committed brake is live at ``step``
        (Rescue.live): :meth:`committed` would make and test it."""
        rescue = self.rescue
        return rescue is not None and rescue.budget is not None and rescue.live(step)

    def committed(self, state: ArmState, bias: Array, predict: Predictor, now: Array,
                  step: int) -> Array | None:
        """Under a rescue budget, the rescue's committed brake while it is live
        (Rescue.held_brake) and its one-period prediction keeps every margin above the floor
        it was found with (``now``: the margins at the sample), else None; nothing is
        searched. Without a budget, None: the
        committed brake is checked again from each state (Rescue.torque), after the guard's
        own candidates.

        Under a torque-rate limit the one-period test leaves out the velocity lookahead
        (Acceptance.check's ``lookahead``: the rates while the torque ramps back from the
        period's acceleration): the brake's check held it, ramped as the motors allow, to
        rest, and holds it on until then — the search that committed it never asks the
        lookahead either, and the unbounded rescue, whose test asks it, searches again where
        it fails and commits to the same brake. With it, on the xArm7 at 250 Hz (500 N·m/s,
        6 tests, B = 8) the aimed brake found at a start inside V failed its second period's
        lookahead (F = −996, 3.2 without), no brake stopped the arm within 8 periods, and the
        uniform brake, untested, let link 7 cross the pole's clearance by 2.9 µm.

        The test sees the brake as the step holds it (:meth:`_reach`): the prediction clips
        a torque to the step's rate box joint by joint, and a brake tested so was held
        reached nearest in acceleration, another torque (2 N·m away on a joint of the FR3).
        Where that reach fails, the brake clipped into the step's box joint by joint — the
        torque the unbounded rescue holds — is tested too: on the figure eight's seed 127 (a
        start outside V, joint 7 1.3 mrad from its limit at 0.82 rad/s) the nearest reach
        failed at the second step where the clipped one passed, and the uniform brake held
        instead took joint 7 0.33 mrad past its limit under the robot's budgets."""
        if not self.holding(step):  # none, or refused already at this step
            return None
        rescue = self.rescue
        assert rescue is not None
        reach = self._reach(bias)
        reaches = (reach,) if not self.box.rate_limited else (reach, self.box.end_clip)
        holds = self._holds(predict, Sample(state.x, now), lookahead=False)
        return self._counted(rescue.held_brake(state, bias, reaches, holds, step))

    def _reach(self, bias: Array) -> Callable[[Array], Array]:
        """τ ↦ the torque the step holds for a rescue brake τ: under a rate limit reached as
        the rescue's search held it (brakes.ramped, StepBox.fit) — a brake clipped joint by
        joint kicked the Panda's light wrist through its rate bound —, else τ."""
        if not self.box.rate_limited:
            return lambda tau: tau
        return lambda tau: self.box.fit(bias, tau, brake=True)

    def _counted(self, tau: Array | None) -> Array | None:
        """A rescue brake the step holds, counted (None: none held)."""
        if tau is not None:
            self.rescues += 1
        return tau

    def _holds(self, predict: Predictor, sample: Sample,
               lookahead: bool = True) -> Callable[[Array, Array], bool]:
        """holds(τ, floor): τ's one-period prediction keeps every margin above ``floor``
        (``lookahead``: and under a torque-rate limit the velocity margins while the torque
        ramps back, Acceptance.check). F's sign is all it asks: from the ``sample``'s bounds
        where they settle a clearance (StepSlack.sign; fewer joint placements), the check
        made once for the floor asked last (a committed brake's two reaches share it)."""
        nc, check = self.n_config, self.acceptance.check
        made: list[tuple[Array, Slack]] = []

        def holds(t: Array, floor: Array) -> bool:
            if not made or made[0][0] is not floor:
                made[:] = [(floor, check(predict, np.maximum(floor, 1e-300),
                                         np.maximum(floor[:nc], 1e-300) if nc else None,
                                         sample=sample, lookahead=lookahead).sign)]
            return made[0][1](t) >= 0.0

        return holds

    def infeasible(self, state: ArmState, bias: Array, stop: Array, predict: Predictor,
                    now: Array, floor: Array, floor_mid: Array | None) -> Array:
        """When no brake satisfies (S1): the fallback, with the escape where there are
        configuration constraints, judged on the first (frozen) prediction alone: asking
        the fallback to satisfy both predictions left it choosing among torques that all
        fail, and worse ones (a Panda joint limit broken at 100 Hz)."""
        delta, nc, check = self.cushion, self.n_config, self.acceptance.check
        frozen = _first_prediction(predict)
        positivity = self.positivity(frozen)
        if floor_mid is None:
            return self.fallback(bias, stop, positivity)
        # (S−), for the escape: configuration margins recover as (S1) asks at the end but,
        # below their cushion, may shrink at mid-period by the decay share; velocity
        # margins may be spent down to their cushion.
        hold_end = np.minimum(delta, self.keep * now)
        hold_end[:nc] = floor[:nc]
        hold_mid = np.minimum(floor_mid, self.keep_half * now[:nc])
        escape = self._escape(state, now, hold_end, hold_mid)
        return self.fallback(bias, stop, positivity, escape, check(frozen, hold_end, hold_mid))

    def positivity(self, frozen: Predictor, sample: Sample | None = None) -> StepSlack:
        """(S0), every margin above its cushion, m ≥ δ, over ``frozen``, the first (frozen)
        prediction alone (:func:`_first_prediction`): the fallback's test (:meth:`infeasible`).
        With ``sample`` (where the step starts) its ``sign`` leaves the sphere clearances that
        the sample's margins bound uncomputed (PredictedMargins.slack)."""
        nc = self.n_config
        return self.acceptance.check(frozen, self.cushion, self.cushion[:nc] if nc else None,
                                     sample=sample)

    def spent(self, bias: Array, stop: Array | None, predict: Predictor, sample: Sample,
              reaches: Reaches | None,
              floors: tuple[Array, Array | None] | None = None) -> Array:
        """What a step whose budget of tests is spent holds where no candidate passed
        (Safeguard._out_of_tests): the calmest brake b − λ₀ D ẋ/h in the step's box,
        untested; under a torque-rate limit its ``reaches`` — by its nearest acceleration
        within ±ρh and along the line from the held torque, F of (S1) and (S2) made for
        each — the one nearer to passing first, then the other, then b reached along the
        line (the held acceleration taken back, as :meth:`_held_back`): the first that keeps
        (S0), else the nearest.

        Reached by its nearest acceleration the brake can spin a joint riding its rate
        bound up through the coupling in D: held untested, it let joint 2 of
        panda_goal_pose_rate's seed 35, a start inside V, through its rate bound by 5.2
        mrad/s at 8 ms under the robot's budgets (6 tests, 8 model periods), where the
        unbounded guard's fallback kept it — hence (S0). And it bends the path (S2) tested:
        on the figure eight (seed 19, inside V) it stopped the wrist within 15–30 ms while
        the shoulder and elbow ran on and carried the hand 0.15–0.75 mm through the table,
        where the line, whose path is (S2)'s (the held acceleration fading as the brake
        builds), passed F at the chain's first step. The line alone is no answer either: it
        takes the held acceleration back at the pace of the joint with the most to change,
        and held from every spent step it let the figure eight's seed 53 through its
        kinetic-energy bound by 0.12 J at 500 Hz (docs/reliability.md).

        (S0) of a reach is read from its F's test where that tells it (Reaches.told), else
        tested. ``floors``: (S1)'s floors at the end and mid-period the reaches' F held them
        to (None where some margin is broken already). Where each is at or above its cushion,
        F ≥ 0 says (S0) holds already (its rows are the first prediction's of F's, its
        floors no higher), and the reach nearer to passing is held without a test where F's
        did not tell its (S0)."""
        if reaches is None:
            assert stop is not None  # D ẋ/h, read only here
            return self.brake(bias, stop, self.settings.braking)
        told = reaches.told()
        first, kept = told[0]
        if kept != kept and max(reaches.f_nearest, reaches.f_line) >= 0.0 and self._covered(
                floors):
            return first
        keeps: Slack | None = None  # (S0)'s own test, made where F's did not tell it
        for tau, kept in told:
            if kept != kept:
                keeps = keeps or self.positivity(_first_prediction(predict), sample).sign
                kept = keeps(tau)  # a sign: all it asks
            if kept >= 0.0:
                return tau
        keeps = keeps or self.positivity(_first_prediction(predict), sample).sign
        back = self._taken_back(bias)  # made only here: five spent steps in six need not
        return back if keeps(back) >= 0.0 else reaches.nearest

    def _covered(self, floors: tuple[Array, Array | None] | None) -> bool:
        """Whether ``floors`` (end, mid-period) are at or above the cushions δ at every
        margin, as (S0) holds them."""
        if floors is None:
            return False
        end, mid = floors
        cushion = self.cushion
        return bool((end >= cushion).all()) and (
            mid is None or bool((mid >= cushion[:self.n_config]).all()))

    def _first_kept(self, bias: Array, stop: Array, positivity: Slack
                    ) -> tuple[Array | None, Array, float]:
        """The fallback's first answers, in its order: the calmest brake b − λ₀ D ẋ/h where
        it keeps (S0) (``positivity`` ≥ 0), else under a torque-rate limit the brake along the
        line or the taken-back acceleration that keeps it (:meth:`_held_back`), else None;
        with the calmest brake and its F."""
        lam0 = self.settings.braking
        calmest = self.brake(bias, stop, lam0)
        f_stop = positivity(calmest)
        if f_stop >= 0.0:
            return calmest, calmest, f_stop
        held = self._held_back(bias, stop, lam0, positivity) if self.box.rate_limited else None
        return held, calmest, f_stop

    def fallback(self, bias: Array, stop: Array, positivity: Slack,
                 escape: Array | None = None, holding: Slack | None = None) -> Array:
        """When no torque satisfies (S1): the calmest braking torque that keeps every margin
        above its cushion (S0) — the smallest λ ≥ λ₀, so that the arm is not bounced off
        the boundary period after period; under a torque-rate limit, where that brake
        fails (S0), the same brake reached along the line from the held torque, else the
        torque that takes back the held acceleration (b reached along the line); else the
        first escape torque C ẋ + g + f − D ẋ/h + s·D v/h, s = 1, 1.5, 2, that holds (S−)
        (the larger s for the curvature of φ that the first-order escape misses); else the
        λ that comes closest to (S0)."""
        lam0 = self.settings.braking
        kept, _, f_stop = self._first_kept(bias, stop, positivity)
        if kept is not None:
            return kept
        lam, f_lam = self.search_braking(bias, stop, positivity, f_stop,
                                         positivity(self.brake(bias, stop, 2.0)))
        if f_lam >= 0.0:  # bisect down towards the smallest λ that keeps (S0)
            lo = lam0
            for _ in range(self.settings.brake_search):
                mid = 0.5 * (lo + lam)
                if positivity(self.brake(bias, stop, mid)) >= 0.0:
                    lam = mid
                else:
                    lo = mid
        elif escape is not None and holding is not None:
            start = bias - stop  # ends the period at rest ...
            for s in (1.0, 1.5, 2.0):  # ... plus the push to the end velocity s·v
                push = self.box.fit(bias, start + s * escape, brake=True)
                if holding(push) >= 0.0:
                    return push
        return self.brake(bias, stop, lam)

    def _held_back(self, bias: Array, stop: Array, lam: float,
                   positivity: Slack) -> Array | None:
        """Under a torque-rate limit, where the brake reached by its nearest acceleration
        fails (S0): the brake reached along the line from the held torque, else b reached
        along the line — the held acceleration a taken back as the ramp test (RampTest)
        assumed it would be when it let the arm get here, every rate moving on along a, by
        less than that test's peak — whichever first keeps (S0), or None. Reached by its
        nearest acceleration within ±ρh, the brake can spin a joint riding its rate bound
        up through the coupling in D: from panda_goal_pose_rate's seed 35 (joint 2 on its
        bound at −1 rad/s², joint 6 pushed off its lower limit at 74 rad/s²) it took joint 2
        to +4.3 rad/s² and through its bound the period after. With these two (the line
        held 5 periods, the taken-back acceleration 1) the run keeps every constraint."""
        line = self.brake_along_line(bias, stop, lam)
        if positivity(line) >= 0.0:
            return line
        coast = self._taken_back(bias)
        return coast if positivity(coast) >= 0.0 else None

    def _taken_back(self, bias: Array) -> Array:
        """b reached along the line from the held torque: the held acceleration taken back
        as far as one step allows (:meth:`_held_back`, :meth:`spent`)."""
        return self.box.fit(bias, bias)

    def _escape(self, state: ArmState, now: Array, end_floor: Array, mid_floor: Array
                ) -> Array:
        """The push D v/h of a braking torque that ends the period at a velocity v pushing
        off the nearby configuration boundaries — for when one factor λ for every joint
        cannot both keep one joint off its limit and let another move away from its own.

        Under τ = C ẋ + g + f + D (v − ẋ)/h the frozen prediction ends at
        x + h((1 − c)ẋ + c v) (c of its end, ``travel``: ½ in continuous time, where it is
        x + ½h(ẋ + v)) and passes x + ⅛h(3ẋ + v) at mid-period, so to first order a floor
        φ̲ at the end and φ̲ᵐ at mid-period ask of each configuration margin φ_i

            ∇φ_i · v ≥ r_i = max(((φ̲_i − φ_i)/h − (1 − c)∇φ_i·ẋ)/c,
                                 8(φ̲ᵐ_i − φ_i)/h − 3∇φ_i·ẋ).

        v starts at rest and is projected onto the most violated of these half-spaces, at
        most twice per constraint (joint limits are orthogonal to each other, so one
        projection meets each): a closed-form construction, not an optimisation. A joint
        heading away from its limit just stops. The caller adds the push to the stopping
        torque C ẋ + g + f − D ẋ/h and checks the sum with the full prediction.
        """
        h = self.period
        nc = self.n_config
        grads = self.guarded.configuration_gradients(state)
        rate = grads @ state.dx
        c = self.travel
        need = np.maximum(((end_floor[:nc] - now[:nc]) / h - (1.0 - c) * rate) / c,
                          8.0 * (mid_floor - now[:nc]) / h - 3.0 * rate)
        return state.inertia @ _project(grads, need, np.zeros_like(state.dx)) / h

    def slide(self, state: ArmState, bias: Array, tau: Array, now: Array, end_floor: Array,
              mid_floor: Array, stop: BrakingTest | None) -> Array:
        """The law's torque less what drives the arm into the configuration boundaries:
        its acceleration a = D⁻¹(τ − b) projected onto the half-spaces that (S1) asks of
        each configuration margin to first order,

            ∇φ_i · a ≥ r_i = max((φ̲_i − φ_i − h∇φ_i·ẋ)/(c h²),  8(φ̲ᵐ_i − φ_i − ½h∇φ_i·ẋ)/h²),

        (φ(h) ≈ φ + h∇φ·ẋ + c h²∇φ·a, c of the prediction's end (``travel``: ½ in continuous
        time), and at mid-period ⅛h²∇φ·a), in one compiled call
        (cpbc.kernels.slide.slide_acceleration), then b + D a scaled into the torque box.
        Blending toward it, not toward a brake, lets the law go on along a boundary it
        presses against: a law that does not know of a joint limit and whose acceleration,
        through D, pushes that joint into it would otherwise be braked to rest there for
        good. Where the result would leave a braking margin σ_i below its floor (``stop``),
        the arm must also stop approaching that boundary by the end of the period,
        ∇φ_i · (ẋ + h a) ≥ 0, and a is projected again with that half-space added."""
        h, nc, n = self.period, self.n_config, len(state.dx)
        grads = np.ascontiguousarray(self.guarded.configuration_gradients(state), dtype=float)
        rate, need, law, acc = np.empty(nc), np.empty(nc), np.empty(n), np.empty(n)
        slide_acceleration(grads, state.dx, now[:nc], end_floor[:nc], mid_floor, h,
                           self.travel, state.inertia, tau - bias, np.empty((n, n)), rate,
                           need, law, acc)
        if stop is not None:  # the braking margins where the uniform brake would stop
            short = self.acceptance.along.stopping_point_margins(
                state.x, state.dx, acc, h, self.travel, stop[0]) < stop[1]
            if short.any():
                need = np.where(short, np.maximum(need, -rate / h), need)
                acc = _project(grads, need, law)
        return self.box.fit(bias, bias + state.inertia.dot(acc))


def _first_prediction(predict: Predictor) -> Predictor:
    """``predict`` cut to its first (frozen) prediction: the fallback judges on it alone
    (a closed-form one stays a Frozen, whose test is compiled: Frozen.first)."""
    if isinstance(predict, Frozen):
        return predict.first()

    def frozen(t: Array) -> tuple[Array, Array, Array, Array, Array]:
        mids, ends, speeds, inner_x, inner_v = predict(t)
        inner = len(inner_x) // len(ends)  # rows per prediction
        return mids[:1], ends[:1], speeds[:1], inner_x[:inner], inner_v[:inner]

    return frozen


def _project(grads: Array, need: Array, start: Array) -> Array:
    """``start`` moved onto the half-spaces {v : ∇φ_i · v ≥ r_i}: one orthogonal projection
    at a time onto the most violated, at most twice per constraint (joint limits are
    orthogonal to each other, so one projection meets each): a closed-form construction,
    not an optimisation (cpbc.kernels.sampled_guard.project_halfspaces)."""
    out = np.empty(len(start))
    project_halfspaces(np.ascontiguousarray(grads, dtype=float), np.asarray(need, dtype=float),
                       np.asarray(start, dtype=float), out)
    return out
