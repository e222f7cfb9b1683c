"""CPBC with the velocity constraint a kinetic-energy bound (Corollary 6.11)."""

from __future__ import annotations

import math

from cpbc.constraints.base import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.controllers.base import Controller, positive_vector
from cpbc.controllers.shaping import Identity, Shaping
from cpbc.controllers.terms import LinearDamping, QuadraticPotential
from cpbc.controllers.unrolled import Unrolled
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model.robot_model import RobotModel


def single_energy_limit(constraints: ConstraintSet, law: str) -> KineticEnergyLimit:
    """The one kinetic-energy limit a KE law needs, or a clear error."""
    ke = [c for c in constraints.velocity if isinstance(c, KineticEnergyLimit)]
    others = [c for c in constraints.velocity if not isinstance(c, KineticEnergyLimit)]
    if len(ke) != 1 or others:
        raise CpbcError(
            f"{law} enforces exactly one kinetic_energy_limit as its velocity constraint; "
            f"got {len(ke)} kinetic-energy limits and {len(others)} other velocity constraints"
        )
    return ke[0]


class CPBCKineticEnergy(Unrolled, Controller):
    """Corollary 6.11 (eq. 6.67) with shaping s, in log-barrier form:

        τ = g + [−(K_P x̃ + K_D ẋ) + ρ b_φ] / (1 + ρ/ψ),   ρ = r(ΦΨ)·L

    No C, no D⁻¹: only D (inside ψ and L) and g. V̇ = −[ẋᵀK_Dẋ + (1 + ρ/ψ)ẋᵀf]/s ≤ 0.
    """

    type_name = "cpbc_ke"

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
        self.energy = single_energy_limit(constraints, self.type_name)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self.shaping: Shaping = shaping or Identity()
        self.potential: QuadraticPotential = QuadraticPotential(self.kp)
        self.damping: object = LinearDamping(self.kd)
        self._config = ConstraintSet(model.n, constraints.configuration)

    def _terms(self, x: Array, dx: Array) -> tuple[float, float, float, Array | None, Array]:
        d = self.model.inertia(x)
        kinetic = 0.5 * float(dx @ d @ dx)
        psi = self.energy.limit - kinetic
        if not psi > 0:
            raise ConstraintViolation(self.energy.names[0], psi)
        bar = self._config.barrier(x, dx, None)  # type: ignore[arg-type]
        err = x - self.target
        lag = kinetic + self.potential.value(err)
        return lag, psi, bar.log_phi + math.log(psi), bar.gradient, err

    def torque_arrays(self, x: Array, dx: Array) -> Array:
        """τ from the array code (the reference for the unrolled one)."""
        return self._law(x, dx, *self._terms(x, dx))

    def evaluate_arrays(self, x: Array, dx: Array) -> tuple[Array, float]:
        """τ and V from the array code (the reference for the unrolled one)."""
        terms = self._terms(x, dx)
        lag, _, log_x = terms[:3]
        v = 0.0 if lag <= 0 else math.exp(math.log(lag) - self.shaping.log_s(log_x))
        return self._law(x, dx, *terms), v

    def _law(
        self, x: Array, dx: Array, lag: float, psi: float, log_x: float, b_phi: Array | None,
        err: Array,
    ) -> Array:
        rho = self.shaping.ratio(log_x) * lag
        shaped = -(self.potential.gradient(err) + self.damping.force(dx))  # type: ignore[attr-defined]
        if b_phi is not None:
            shaped += rho * b_phi
        return self.model.gravity(x) + shaped / (1.0 + rho / psi)

    def lyapunov(self, x: Array, dx: Array) -> float:
        lag, _, log_x, _, _ = self._terms(x, dx)
        return 0.0 if lag <= 0 else math.exp(math.log(lag) - self.shaping.log_s(log_x))
