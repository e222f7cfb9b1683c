"""Constrained passivity-based control (Theorem 6.9) in the log-barrier form of DESIGN §3."""

from __future__ import annotations

import math

from cpbc.constraints.base import Array
from cpbc.constraints.constraint_set import BarrierTerms, ConstraintSet
from cpbc.controllers.base import Controller, positive_vector
from cpbc.controllers.linalg import solve_spd
from cpbc.controllers.shaping import Identity, Shaping
from cpbc.controllers.terms import LinearDamping, QuadraticPotential
from cpbc.controllers.unrolled import Unrolled
from cpbc.model.robot_model import DynamicsTerms, RobotModel


class CPBC(Unrolled, Controller):
    """Constrained PBC for configuration and velocity constraints (Theorem 6.9, eq. 6.24/6.70).

    With V = L / s(ΦΨ), L = ½ẋᵀDẋ + U(x̃), dividing (6.24) by s gives the equivalent

        ρ = r(ΦΨ)·L,   b_φ = Σ ∇φ_i/φ_i,   b_ψ = Σ ∂_xψ_j/ψ_j,   Π = Σ Q_j/ψ_j
        a = −∂U/∂x̃ − K_D ẋ + ρ(b_φ + b_ψ),   c = C ẋ + f
        τ = g + c + D (D + ρΠ)⁻¹ (a − c)

    which is (6.24) rearranged so that one linear solve suffices and the products Φ, Ψ are
    never formed. Along the closed loop V̇ = −ẋᵀ(K_D ẋ + f)/s ≤ 0 (eq. 6.32).

    Args:
        model: the controller's robot model.
        target: x_d, inside S.
        constraints: the enforced constraints.
        kp, kd: diagonal gains (number or list of n), > 0.
        shaping: s(x); Identity (Theorem 6.9) when omitted.
    """

    type_name = "cpbc"

    def __init__(
        self,
        model: RobotModel,
        target: Array,
        constraints: ConstraintSet,
        kp: object,
        kd: object,
        shaping: Shaping | None = None,
    ) -> None:
        super().__init__(model, target, constraints)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self.shaping: Shaping = shaping or Identity()
        self.potential: QuadraticPotential = QuadraticPotential(self.kp)
        self.damping: object = LinearDamping(self.kd)
        self._uses_velocity = bool(constraints.velocity)

    def _shaped_terms(
        self, x: Array, dx: Array
    ) -> tuple[DynamicsTerms, BarrierTerms, Array, float]:
        """Dynamics, barrier sums, −∂U/∂x̃ and L at one state."""
        dyn = self.model.dynamics(x, dx)
        bar = self.constraints.barrier(x, dx, dyn)
        potential, grad = self.potential.evaluate(x - self.target)
        lag = 0.5 * float(dx.dot(dyn.inertia.dot(dx))) + potential
        return dyn, bar, grad, lag

    def torque_arrays(self, x: Array, dx: Array) -> Array:
        """τ from the array code (the reference for the unrolled one)."""
        return self._law(dx, *self._shaped_terms(x, dx))

    def evaluate_arrays(self, x: Array, dx: Array) -> tuple[Array, float]:
        """τ and V from the array code (the reference for the unrolled one)."""
        terms = self._shaped_terms(x, dx)
        return self._law(dx, *terms), self._shaped_value(terms[1], terms[3])

    def _shaped_value(self, bar: BarrierTerms, lag: float) -> float:
        if lag <= 0.0:
            return 0.0
        return math.exp(math.log(lag) - self.shaping.log_s(bar.log_phi + bar.log_psi))

    def _law(
        self, dx: Array, dyn: DynamicsTerms, bar: BarrierTerms, grad: Array, lag: float
    ) -> Array:
        """The law of the class docstring from precomputed terms."""
        a = -grad - self.damping.force(dx)  # type: ignore[attr-defined]
        rho = self.shaping.ratio(bar.log_phi + bar.log_psi) * lag
        if bar.gradient is not None:
            a += rho * bar.gradient
        if bar.weight is None:
            return dyn.gravity + a
        c = dyn.coriolis_force + dyn.dissipation if self.model.has_friction else (
            dyn.coriolis_force
        )
        y = solve_spd(dyn.inertia + rho * bar.weight, a - c)
        return dyn.gravity + c + dyn.inertia.dot(y)

    def lyapunov(self, x: Array, dx: Array) -> float:
        """V = L / s(ΦΨ), evaluated in logs."""
        _, bar, _, lag = self._shaped_terms(x, dx)
        return self._shaped_value(bar, lag)

