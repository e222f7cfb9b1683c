"""The safeguard itself: the wrapper a law runs in (the package docstring), its state and
counts, and one control instant — accept the law's torque (acceptance.py) or replace it
(braking.py)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import TorqueBox
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.stopping import Braking
from cpbc.controllers.controller import Controller, Evaluation, SafetyFilter
from cpbc.controllers.hold import hold_share
from cpbc.controllers.rescue import Rescue
from cpbc.controllers.safeguard.acceptance import Acceptance
from cpbc.controllers.safeguard.braking import Brakes
from cpbc.controllers.safeguard.model_error import (
    DeclaredError,
    friction_error,
    margin_losses,
    measurement_losses,
)
from cpbc.controllers.safeguard.predicted_margins import PredictedMargins, RampTest
from cpbc.controllers.safeguard.prediction import Predictor, predictor, travel_share
from cpbc.controllers.safeguard.settings import SafeguardSettings
from cpbc.errors import CpbcError
from cpbc.kernels.sampled_guard import floors
from cpbc.model.robot_model import ArmState


def guarded(
    law: Controller,
    period: float,
    settings: SafeguardSettings | None,
    torque_limit: Array | float | None = None,
    also_keep: Sequence[ConfigurationConstraint] = (),
    rate_limit: Array | float | None = None,
    model_error: Array | float | None = None,
    declared: DeclaredError | None = None,
) -> Controller:
    """The law as a sampled-data loop at period h should run it: wrapped in a Safeguard with
    ``settings`` when it enforces constraints, else the law itself (also with no settings).

    ``torque_limit`` is the plant's joint torque saturation, ``rate_limit`` its joint
    torque-rate limit [N·m/s] and ``model_error`` the declared bound on the model's
    acceleration error [per coordinate, rad/s² or m/s²] (each a number or one per joint);
    ``declared`` the declared inertia and measurement errors (model_error.DeclaredError)."""
    if isinstance(law, SafetyFilter):  # a filter already (a peer): fresh counts, no wrap
        return law.restarted()
    if settings is None or law.constraints.empty:
        return law
    n = law.model.n
    limit = None if torque_limit is None else np.broadcast_to(
        np.asarray(torque_limit, dtype=float), (n,))
    rate = None if rate_limit is None else np.broadcast_to(
        np.asarray(rate_limit, dtype=float), (n,))
    error = None if model_error is None else np.broadcast_to(
        np.asarray(model_error, dtype=float), (n,))
    return Safeguard(law, period, settings, limit, also_keep, rate, error, declared)


class Safeguard(Acceptance, Brakes, SafetyFilter):
    """Wraps a constrained law so that (S1) holds under zero-order hold at period h.

    Args:
        law: the constrained law (its ``constraints`` and ``model`` are used).
        period: control period h [s].
        settings: κ, λ, prediction sub-steps, back-off steps.
        torque_limit: joint torque limits |τ_q| ≤ limit (the actuators'), shape (n,). Every
            torque the safeguard returns or predicts with lies in this box: the law's torque,
            the brakes and the escape are scaled toward C ẋ + g + f until they fit
            (:meth:`_box`), which keeps the direction of the acceleration they ask for.
        also_keep: configuration constraints the law does not enforce (obstacles it does
            not know of, the plant's joint ranges) that the safeguard keeps as well: (S1)
            on them makes it brake before the arm reaches them. Those the law enforces
            already are skipped.
        rate_limit: joint torque-rate limits |τ̇_q| ≤ ρ (the motors'), shape (n,)
            [N·m/s]. Each step the guard chooses only among torques within ρh of the one
            the actuators hold (:meth:`holding`; its own last torque, or the gravity torque
            at its first state) and inside the torque box, tests every candidate as clipped
            there, and keeps the braking margins σ with the time the brake takes to ramp
            up (stopping.Braking.ramp): nothing after the guard need change its torque.
        model_error: ā, the declared bound on the model's acceleration error |a − â| ≤ ā
            per coordinate, shape (n,): every floor of (S1) is raised by what such an error
            can take off its margin in one period, and the braking set's deceleration is
            lowered by it (:mod:`cpbc.controllers.safeguard.model_error`).
        declared: a declared relative inertia error, held at each step as the acceleration
            error it makes at the law's acceleration (model_error.InertiaError), and
            measurement errors, whose reach is added to the floors too
            (model_error.measurement_losses); or None.

    Attributes:
        calls: control instants seen.
        acted: instants at which the law's torque was replaced (β > 0).
        infeasible: instants at which even the braking torque failed (S1).
        scaled: instants at which the law's torque was outside the torque box and was scaled
            into it (it is then tested as scaled).
        uncorrected: instants at which the hold-corrected torque failed (S1) and the law's
            own torque kept it: the guard held a blend of the two, with as much of the
            correction as (S1) allows (not counted as acting: the torque is the law's).
    """

    type_name = "safeguard"

    def __init__(
        self,
        law: Controller,
        period: float,
        settings: SafeguardSettings | None = None,
        torque_limit: Array | None = None,
        also_keep: Sequence[ConfigurationConstraint] = (),
        rate_limit: Array | None = None,
        model_error: Array | None = None,
        declared: DeclaredError | None = None,
    ) -> None:
        if not (math.isfinite(period) and period > 0):
            raise CpbcError(f"safeguard period must be > 0, got {period}")
        super().__init__(law.model, law.target, law.constraints)
        self.law = law
        self.period = float(period)
        self.settings = settings or SafeguardSettings()
        self.keep = self.settings.keep_fraction(self.period)
        self.keep_half = math.sqrt(self.keep)
        self.substeps = self.settings.steps_for(self.period)
        # s of the hold correction τ − s D Δa: the drift the plant's hold has (hold.py)
        self.hold_share = hold_share(self.period, self.settings.plant_step) \
            if self.settings.hold_correction else 0.0
        # c of the predicted end x + hẋ + c h² a: where the plant's own steps land
        self.travel = travel_share(self.period, self.settings.plant_step)
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
        self.along = PredictedMargins(self.guarded, law.model)
        at_target = self.guarded.margins(law.target, np.zeros(law.model.n))
        scale = self.settings.cushion * self.period / 0.01
        # δ_i; a constraint only the guard keeps may have the target beyond it (a joint limit
        # the law does not know of between it and its target): the size of its margin there
        self.cushion = scale * np.abs(at_target)
        nc = self.guarded.n_configuration
        if self.settings.velocity_cushion is not None:
            self.cushion[nc:] = (self.settings.velocity_cushion * self.period / 0.01
                                 * np.abs(at_target[nc:]))
        self._n_config = nc
        self._n_own_config = own.n_configuration
        self.torque_limit = None if torque_limit is None else np.asarray(torque_limit, float)
        self.rate_limit = None if rate_limit is None else np.asarray(rate_limit, float)
        self.model_error = None if model_error is None else np.asarray(model_error, float)
        self.declared = declared
        self._inertia_error = None if declared is None else declared.acceleration_bound(
            law.model)
        self._coulomb = bool(np.any(law.model.coulomb_friction))
        # ρh: how far one step can move each joint torque (None: as far as the box allows)
        self._rate_step: Array | None = None if self.rate_limit is None else (
            self.rate_limit * self.period)
        box_limit = torque_limit if torque_limit is not None else (
            None if rate_limit is None else np.full(law.model.n, math.inf))
        self._torque_box = None if box_limit is None else TorqueBox.of(law.model, box_limit)
        self._step_box = self._torque_box  # the box of this step (narrowed by the rate)
        self._holding: Array | None = None  # the torque the actuators hold (controller coords)
        self._added: Array | None = None  # the torque the robot adds itself (holding)
        self._static_box = self._torque_box  # the torque box of this step (moved by _added)
        self._ramp: RampTest | None = None  # this step's velocity lookahead (rate limit)
        self._inertia = np.zeros((0, 0))  # D at this step's state (rate limit: _box)
        nc_all = self.guarded.n_configuration
        self._velocity_floor = np.maximum(self.cushion[nc_all:], 1e-300)
        # under bounded torque the guard also keeps the braking margins σ (stopping.Braking)
        self.braking = None if torque_limit is None or not self._n_config else Braking.of(
            law.model, torque_limit, rate=self.rate_limit, disturbance=self.model_error)
        self._sigma_floor = np.maximum(self.cushion[: self._n_config], 1e-300)
        # where no torque of its own will do: brakes better than the uniform one (rescue.py)
        self.rescue = None if self.braking is None or self._torque_box is None else Rescue(
            law.model, self.guarded, self._torque_box, self.cushion,
            self.period, self.substeps, rate_step=self._rate_step,
            budget=self.settings.rescue_budget)
        self.calls = 0
        self.acted = 0
        self.infeasible = 0
        self.scaled = 0
        self.uncorrected = 0
        self.rescues = 0

    # -- the Controller interface ------------------------------------------------------------

    def state(self, x: Array, dx: Array) -> ArmState:
        return self.law.state(x, dx)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        """The guarded torque and the law's V at the per-step state; ConstraintViolation
        outside S."""
        out = self.law.evaluate_state(state, margins=True)  # raises outside S
        self.calls += 1
        if self.constraints.empty:
            return out
        assert out.margins is not None  # asked for
        if self._rate_step is None:
            tau = self._guard(state, out.torque, out.margins)
        else:
            tau = self._rate_limited(state, out.torque, out.margins)
        return Evaluation(tau, out.lyapunov, out.margins if margins else None)

    def holding(self, tau: Array, added: Array | None = None) -> None:
        """Tell the guard the torque the actuators hold now (controller coordinates): the
        next step's torque lies within ρh of it. The guard's own last torque is assumed
        otherwise, and at its first step the gravity torque of its first state (an arm held
        at rest; a Franka's own gravity compensation). ``added``: the torque the robot adds
        to every command itself at this state (a Franka's gravity compensation), whose box
        then bounds the command, τ − added, not τ: the guard's box moves by it."""
        self._holding = np.array(tau, dtype=float)
        self._added = None if added is None else np.array(added, dtype=float)

    def _rate_limited(self, state: ArmState, law: Array, law_margins: Array) -> Array:
        """The guard's step inside the box one step can reach from the held torque: every
        candidate is tested as clipped there (the predictor saturates into ``_step_box``)
        and the torque returned lies in it."""
        assert self._torque_box is not None and self._rate_step is not None
        box = self._torque_box
        if self._added is not None:  # the robot's box bounds the command, τ − added
            lower, upper = box.bounds
            shift = box.joint(self._added)
            box = TorqueBox(box.limit, box.to_joint, box.from_joint, lower + shift,
                            upper + shift)
        self._static_box = box
        held = state.gravity if self._holding is None else self._holding
        self._holding = held  # this step's anchor (_box)
        self._step_box = box.around(box.joint(held), self._rate_step)
        self._inertia = state.inertia  # what _box reaches a brake by
        assert self.rate_limit is not None
        self._ramp = RampTest(state.dx, self.period, state.inertia, box.to_joint,
                              self.rate_limit, self._velocity_floor)
        tau = self._step_box.clip(self._guard(state, law, law_margins))
        self._holding = tau
        return tau

    def lyapunov(self, x: Array, dx: Array) -> float:
        """The law's V, which the guard leaves as it is: the law alone is asked, no guard runs
        and no count moves (the loop asks for the true state's V beside every guarded call
        when the measurement is noisy)."""
        return self.law.lyapunov(x, dx)

    # -- the guard ---------------------------------------------------------------------------

    def _guard(self, state: ArmState, tau: Array, law_margins: Array) -> Array:
        """τ if it satisfies (S1), else the smallest blend toward braking that does."""
        bias = state.coriolis_force + state.gravity
        if self.model.has_friction:
            bias = bias + state.dissipation
        predict = self._predictor(state, bias)
        now = self._now(state.x, law_margins)
        delta, nc = self.cushion, self._n_config
        floor, mid = np.empty(len(now)), np.empty(nc)
        floors(now, delta, self.keep, self.keep_half, floor, mid)  # (S1)
        self._raise_floors(state, bias, tau, floor, mid)
        floor_mid = None
        past = None
        if nc:
            floor_mid = mid
            if self._extra is not None and not now[now.argmin()] > 0.0:
                # An extra constraint (one only the guard keeps) is broken already: the arm
                # went past a limit the law does not know of, from a state nothing could stop
                # it from. No torque brings its margin back within one period, so it must
                # merely not shrink: a law that leads back is let through, and the guard
                # never holds the arm at rest beyond the limit (it did, for good, once
                # asking for a positive margin at the period's end made every step fail).
                past = now <= 0.0
                floor = np.where(past, now, floor)
                floor_mid = np.where(past[:nc], now[:nc], floor_mid)
        stop = self._braking_floor(state, bias, self._holding)
        slack = self._check(predict, floor, floor_mid, stop, past)  # (S1)
        tau, f0 = self._held(state, bias, tau, slack)
        if f0 >= 0.0:
            return tau
        self.acted += 1
        if floor_mid is not None:  # first the law less its push into the boundaries
            slid = self._slide(state, bias, tau, now, floor, floor_mid, stop)
            f_slid = slack(slid)
            if f_slid >= 0.0:
                return self._blend(tau, slid, f0, f_slid, slack)
        stop = state.inertia.dot(state.dx) / self.period
        brake = self._brake(bias, stop, self.settings.braking)
        f1 = slack(brake)
        if f1 < 0.0:
            # Reverse instead of stop: x⁺ = x, ẋ⁺ = −ẋ, the least excursion at this speed.
            reverse = self._brake(bias, stop, 2.0)
            f_rev = slack(reverse)
            if f_rev < 0.0:
                # Stopping goes too far and reversing at full speed breaks a velocity
                # margin: search the deceleration λ in between.
                lam, f_lam = self._search_braking(bias, stop, slack, f1, f_rev)
                if f_lam < 0.0:
                    self.infeasible += 1
                    rescued = self._rescued(state, bias, predict, now)
                    if rescued is not None:
                        return rescued
                    return self._infeasible(state, bias, stop, predict, now, floor, floor_mid)
                reverse, f_rev = self._brake(bias, stop, lam), f_lam
            brake, f1 = reverse, f_rev
        return self._blend(tau, brake, f0, f1, slack)

    def _raise_floors(self, state: ArmState, bias: Array, tau: Array, floor: Array,
                      mid: Array) -> None:
        """The floors of (S1) raised, in place, by whatever the model's error can take off
        each margin in one period (model_error.margin_losses), and to at least what a
        measurement error can hide above the cushion (measurement_losses): the true margin
        then ends above its cushion too."""
        error = self._error_bound(state, bias, tau)
        if error is not None:
            end_loss, mid_loss = margin_losses(self.guarded, state, error, self.period,
                                               self.travel)
            floor += end_loss
            mid += mid_loss
        if self.declared is not None and self.declared.measured:
            end_loss, mid_loss = measurement_losses(self.guarded, state, self.declared,
                                                    self.period)
            np.maximum(floor, end_loss + self.cushion, out=floor)
            np.maximum(mid, mid_loss + self.cushion[: len(mid)], out=mid)

    def _error_bound(self, state: ArmState, bias: Array, tau: Array) -> Array | None:
        """The bound on the model's acceleration error at this state: the declared one plus
        its smooth Coulomb friction's (model_error.friction_error) plus a declared inertia
        error's at the law's acceleration D⁻¹(τ − b) (model_error.InertiaError), or None."""
        parts = [p for p in (self.model_error,
                             friction_error(self.model, state) if self._coulomb else None)
                 if p is not None]
        if self._inertia_error is not None:
            accel = np.asarray(np.linalg.solve(state.inertia, tau - bias), dtype=float)
            parts.append(self._inertia_error.bound(state, accel))
        return sum(parts[1:], parts[0]) if parts else None

    def _box(self, bias: Array, tau: Array, brake: bool = False) -> Array:
        """τ scaled toward the bias b = C ẋ + g + f until it fits the torque box
        (:meth:`TorqueBox.toward`): the acceleration D⁻¹(τ − b) keeps its direction and only
        shrinks, so no joint is spun up by the coupling through D, as clipping each joint
        would (τ itself when it fits, or when there is no limit). Under a torque-rate limit
        it is then reached from the held torque τ_h as far as one step allows: the law's
        torque and what follows it (the slide) along the straight line τ_h + s(τ − τ_h),
        which keeps the direction of the change of acceleration the law asks for (a reach
        that bent it took the FR3's hand 23 mm off a circle it tracked within 2 mm); a
        ``brake`` (the brakes, the escape, the rescue's) as the torque within ρh of τ_h
        whose acceleration is nearest to its own (:meth:`TorqueBox.nearest`), which gives
        every joint as much of its own interval as it needs: scaled along the straight
        line, the FR3's light last joint kept −11 N·m for 15 ms (0.14 of its 1 N·m a
        period) while its motion had to turn, and ran through its rate bound. (Clipped joint
        by joint, a brake far outside the rate box spun the Panda's base joint up through
        its rate bound: the coupling through D.)"""
        box = self._static_box
        if box is None:
            return tau
        boxed = box.toward(bias, tau)
        step, held = self._step_box, self._holding
        if self._rate_step is None or step is None or held is None:
            return boxed
        return step.nearest(self._inertia, boxed) if brake else step.toward(held, boxed)

    def _saturate(self, tau: Array) -> Array:
        return tau if self._step_box is None else self._step_box.clip(tau)

    @staticmethod
    def _no_nan(m: Array) -> Array:
        """NaN margins (a prediction gone wild) count as −∞; one sum tells if there are any."""
        total = m.sum()
        return np.where(np.isnan(m), -np.inf, m) if total != total else m

    def _now(self, x: Array, law_margins: Array) -> Array:
        """Every guarded margin at the sample: the law's, with the extra configuration
        constraints' after its own configuration margins."""
        if self._extra is None:
            return self._no_nan(law_margins)
        k = self._n_own_config
        return self._no_nan(np.concatenate(
            (law_margins[:k], self._extra.configuration_margins(x), law_margins[k:])))

    def _predictor(self, state: ArmState, bias: Array) -> Predictor:
        """The period's prediction under a held τ (:func:`prediction.predictor`)."""
        return predictor(self.model, state, bias, self.period, self.substeps, self._saturate,
                         self.settings.corrector, self.travel)
