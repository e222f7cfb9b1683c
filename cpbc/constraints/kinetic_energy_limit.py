"""A bound on the arm's kinetic energy (eq. 6.66, 7.33)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_kind import ConstraintEntrySpec, ConstraintInputs, ConstraintKind
from cpbc.constraints.constraint_types import VelocityConstraint
from cpbc.constraints.margins import ENERGY
from cpbc.constraints.packing import Packed
from cpbc.errors import CpbcError, ParameterError
from cpbc.kernels.barriers import kinetic_energy_terms, pack_kinetic_energy_limit
from cpbc.model.robot_model import ArmState, RobotModel
from cpbc.spec.fields import Positive


class KineticEnergyLimit(VelocityConstraint):
    """ψ = Ω − ½ ẋᵀ D(x) ẋ > 0, so Q = D(x) and ∂ψ/∂x = −Cᵀ ẋ (C in Christoffel form).

    Args:
        model: the controller's robot model (for D and C when no dynamics terms are given).
        limit: Ω > 0 [J].
        name: label of the constraint.
    """

    margin_type = ENERGY  # ψ is in J already
    needs_dynamics = True
    needs_coriolis = True

    def __init__(self, model: RobotModel, limit: float, name: str = "kinetic_energy") -> None:
        if not (np.isfinite(limit) and limit > 0):
            raise ParameterError("limit", f"kinetic energy limit must be finite and > 0, got "
                                          f"{limit}")
        self.model = model
        self.limit = float(limit)
        self.names = (name,)

    def value(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        d = state.inertia if state is not None else self.model.inertia(x)
        return np.array([self.limit - 0.5 * dx @ d @ dx])

    def weights(self, x: Array, state: ArmState | None = None) -> Array:
        d = state.inertia if state is not None else self.model.inertia(x)
        return d[None, :, :]

    def gradient(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        c = state.coriolis_matrix if state is not None else None
        return -((self.model.coriolis(x, dx) if c is None else c).T @ dx)[None, :]

    def barrier_terms(self, state: ArmState) -> tuple[Array, Array, Array]:
        """ψ, Π = D/ψ and b = −Cᵀẋ/ψ, with C the state's (``coriolis=True``)
        (cpbc.kernels.barriers.kinetic_energy_terms)."""
        d, dx, c = state.inertia, state.dx, state.coriolis_matrix
        if c is None:
            raise CpbcError("the kinetic-energy limit reads C from the state: build it with "
                            "coriolis=True (a law's state(x, dx) does)")
        pi, b = np.empty_like(d), np.empty_like(dx)
        psi = kinetic_energy_terms(self.limit, d, c, dx, pi, b)
        return np.array([psi]), pi, b

    def packed(self) -> Packed | None:
        """Ω for the kernel, unless a subclass overrides ``barrier_terms``."""
        if type(self).barrier_terms is not KineticEnergyLimit.barrier_terms:
            return None
        return pack_kinetic_energy_limit(self.limit)


# -- the scenario's ``type: kinetic_energy_limit`` -------------------------------------------
class KineticEnergyLimitSpec(ConstraintEntrySpec):
    type: Literal["kinetic_energy_limit"] = Field(description="½ẋᵀDẋ < Ω")
    name: str = Field(
        default="kinetic_energy", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    limit: Positive = Field(description="Ω [J]")


def build(spec: KineticEnergyLimitSpec, given: ConstraintInputs) -> KineticEnergyLimit:
    return KineticEnergyLimit(given.model, spec.limit, spec.name)


KINDS = (ConstraintKind(KineticEnergyLimitSpec, build, KineticEnergyLimit,
                        {"kinetic_energy_limit": {"limit": 10}}),)
