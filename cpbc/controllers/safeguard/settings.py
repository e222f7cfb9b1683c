"""The safeguard's parameters, and the one-period viability test of a state (the package
docstring, :mod:`cpbc.controllers.safeguard`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.errors import ParameterError

# the rescue's default budget [model periods per control period]: none. A budget bounds the
# guard's worst step, but a state mid-run whose brake needs longer than it to stop the arm
# gets the fallback instead (the UR10 held under a ball rides its clearance in stick-slip
# under a budget of 8, held at rest without one: cpbc.controllers.rescue)
RESCUE_BUDGET: int | None = None


@dataclass(frozen=True)
class SafeguardSettings:
    """Parameters of the sampled-data safeguard.

    Attributes:
        decay_rate: κ [1/s] of (S1): over one period h a tightened margin keeps at least
            e^{−κh} of its value. Larger is more permissive.
        cushion: η, the cushion as a fraction of each margin's value at the target at rest,
            for a 10 ms period (it scales linearly with the period).
        braking: λ > 0 of the braking torque (λ = 1 stops the model's motion in one period).
        substeps: 1 for the closed-form prediction with the dynamics frozen at the sample;
            k > 1 for k semi-implicit Euler steps of the model's forward dynamics.
        max_step: the longest prediction step [s]: a period longer than this is predicted
            in ⌈h / max_step⌉ sub-steps whatever ``substeps`` says (over 10 ms a 7-joint
            arm's acceleration changes too much for the frozen prediction).
        backoffs: Illinois steps on β when the law's torque fails (S1) (≥ 1).
        brake_search: predictions spent searching the braking factor λ between stopping
            and reversing when neither satisfies (S1) (0: none).
        velocity_cushion: η for the velocity margins (rates, kinetic energy), None: the same
            as ``cushion``. A thicker one keeps a law riding a velocity bound further from
            it, where its inertia shaping D + ρΠ leaves it more authority; the hold correction
            is what keeps such a law's margin from being worn down (README, "A law that rides
            a rate bound").
        hold_correction: test and hold τ − ½ D Δa instead of the law's τ
            (:func:`cpbc.controllers.hold.hold_corrected`):
            the law's acceleration of the sample kept on average over the period, to first
            order, as the continuous-time law asks. Without it a law that rides a rate bound
            loses its margin to the hold error (README, "A law that rides a rate bound").
        plant_step: the step [s] of a plant integrated by a one-stage (semi-implicit Euler)
            integrator (MuJoCo's Euler, implicit, implicitfast), None for an arm in
            continuous time or an RK4 plant. It sets s of the hold correction τ − s D Δa,
            the share of the period's drift Δa the plant's acceleration has on average
            (:func:`cpbc.controllers.hold.hold_share`): ½ in continuous time, 0 for a plant
            stepped once per period, which holds the sample's acceleration exactly; and c
            of the closed-form prediction's end x + hẋ + c h² a, where that plant's steps
            land (:func:`cpbc.controllers.safeguard.prediction.travel_share`): ½ in
            continuous time, 1 for a plant stepped once per period.
        corrector: with the closed-form prediction, also predict to second order in
            continuous time (the model's acceleration evaluated once more at the predicted
            end, taken as linear over the period, Heun's) and hold every margin under both
            predictions. The frozen one is what the semi-implicit Euler steps of the plant
            do (given ``plant_step``); the corrected one is nearer continuous time (a real
            arm, RK4): on a 7-joint arm near its rate bounds the acceleration changes
            enough within 1 ms (Coriolis terms of fast joints) that the frozen one alone
            misses a rate margin by more than its cushion.
        rescue_budget: the periods of the model the rescue may hold its brakes for in one
            control period (cpbc.controllers.rescue.Rescue's ``budget``), None for no bound:
            a bound on the guard's worst step, save the search from the motion's first
            state, which runs until rest; a later search commits only to a brake whose
            check ended within it, so a brake that needs longer gives way to the fallback.
        test_budget: K, the most candidate torques one step tests (each a prediction of the
            period and every margin along it), None for no bound: with ``rescue_budget``, a
            bound on the step's time (at most K + 3 tests). Past it the step holds the last
            torque that passed, else a rescue brake whose check came to rest within
            ``rescue_budget``, else the uniform brake
            (:mod:`cpbc.controllers.safeguard.step_budget`).
        time_budget: the longest one guard step (its ``filter``) may test torques for [s],
            None for no bound: past it the step stops testing as past ``test_budget``. It
            reads the clock (a run under it is not reproducible): for a robot's deadline.
    """

    decay_rate: float = 50.0
    cushion: float = 1e-3
    braking: float = 1.0
    substeps: int = 1
    max_step: float = 0.001
    backoffs: int = 6
    brake_search: int = 5
    corrector: bool = True
    velocity_cushion: float | None = None
    hold_correction: bool = True
    plant_step: float | None = None
    rescue_budget: int | None = RESCUE_BUDGET
    test_budget: int | None = None
    time_budget: float | None = None

    def __post_init__(self) -> None:
        for name in ("decay_rate", "braking"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                _refuse(name, "> 0", v)
        for name in ("cushion", "velocity_cushion"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and 0 <= v < 1):
                _refuse(name, "in [0, 1)", v)
        for name in ("plant_step", "time_budget", "max_step"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                _refuse(name, "> 0 [s]", v)
        for name in ("substeps", "backoffs", "rescue_budget", "test_budget"):
            v = getattr(self, name)
            if v is not None and v < 1:
                _refuse(name, "≥ 1", v)
        if self.brake_search < 0:
            _refuse("brake_search", "≥ 0", self.brake_search)

    def steps_for(self, period: float) -> int:
        """Prediction sub-steps for a control period."""
        return max(self.substeps, math.ceil(period / self.max_step - 1e-9))

    def keep_fraction(self, period: float) -> float:
        """e^{−κh}: the share of each tightened margin (S1) requires after one period."""
        return math.exp(-self.decay_rate * period)


def viable(constraints: ConstraintSet, x: Array, dx: Array, period: float) -> bool:
    """Whether some held torque that keeps every speed can keep (x, ẋ) inside S over one
    period, to first order: the configuration margins at x + ¼hẋ — the least excursion
    towards ∂S of a constant deceleration that ends at speed |ẋ| (reversal, λ = 2) — are > 0.

    A state that fails this is in S but cannot be kept in S by sampled-data control at
    period h; the reliability campaigns count such states apart.
    """
    if not constraints.configuration:
        return True
    probe = x + 0.25 * period * dx
    return bool(np.all(constraints.configuration_margins(probe) > 0))


def _refuse(name: str, rule: str, value: object) -> None:
    """A ParameterError (a ValueError) naming the setting."""
    raise ParameterError(name, f"safeguard {name} must be {rule}, got {value}")
