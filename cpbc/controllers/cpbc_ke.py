"""CPBC with the velocity constraint a kinetic-energy bound (Corollary 6.11)."""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import BarrierTerms, ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.controllers.controller import Controller, Evaluation, positive_vector
from cpbc.controllers.cpbc import CPBC
from cpbc.controllers.law_kind import LINEAR, LawInputs, LawKind, shaping
from cpbc.controllers.law_specs import ShapedLawSpec
from cpbc.controllers.packed_law import PackedLaw, PacksItsLaw, law_terms, writable
from cpbc.controllers.potentials import JointSpring, Potential, require_posture
from cpbc.controllers.shaping import Identity, Shaping
from cpbc.controllers.terms import Damping, LinearDamping, StateDamping
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.kernels.energy import kinetic_energy
from cpbc.kernels.laws import (
    cpbc_ke_step,
    cpbc_ke_torque,
    shaped_value,
    zero_terms,
)
from cpbc.model.robot_model import ArmState, RobotModel


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


class CPBCKineticEnergy(PacksItsLaw):
    """Corollary 6.11 (eq. 6.67) with shaping s, in log-barrier form:

        τ = g + [−(∂U/∂x + K_D ẋ) + ρ b_φ] / (1 + ρ/ψ),   ρ = r(ΦΨ)·L

    with ∂U/∂x = K_P x̃ for the default potential (``potential``: any U with a posture
    spring, as in CPBC). No C, no D⁻¹: only D (inside ψ and L) and g.
    V̇ = −[ẋᵀK_Dẋ + (1 + ρ/ψ)ẋᵀf]/s ≤ 0; with ``task_damping`` F, K_D ẋ becomes K_D ẋ + F.

    When the configuration constraints and every term pack, a step is one kernel call
    (cpbc.kernels.laws.cpbc_ke_step), packed as CPBC packs (cpbc.controllers.cpbc.CPBC).
    """

    type_name = "cpbc_ke"
    _packed_from = frozenset({"constraints", "energy", "potential", "damping",
                              "task_damping", "shaping", "_config"})

    def __init__(
        self,
        model: RobotModel,
        target: Array,
        constraints: ConstraintSet,
        kp: object,
        kd: object,
        shaping: Shaping | None = None,
        potential: Potential | None = None,
        task_damping: StateDamping | None = None,
    ) -> None:
        super().__init__(model, target, constraints)
        self.task_damping = task_damping
        self.energy = single_energy_limit(constraints, self.type_name)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self.shaping: Shaping = shaping or Identity()
        self.potential: Potential = JointSpring(self.target, self.kp) if potential is None else (
            require_posture(potential, self.type_name))
        self.damping: Damping = LinearDamping(self.kd)
        self._config = ConstraintSet(model.n, constraints.configuration)
        self._no_barrier = zero_terms(model.n)

    def state(self, x: Array, dx: Array) -> ArmState:
        """The per-step state of the configuration constraints and the potential: the law
        reads the energy limit through D alone (no C, which the limit's own barrier terms
        would need)."""
        packed = self._packed_law
        if packed is None or packed.law is not type(self):
            packed = self.packed_law()
        produce = packed.produce
        if produce is None:
            return self._config.state(self.model, x, dx, self.frames)
        return produce(x, dx)

    def _pack(self) -> PackedLaw:
        parts = law_terms(self, CPBCKineticEnergy, ("_law", "task_damping_force"))
        return PackedLaw.build(type(self), parts, self._config, self.frames,
                               self.model)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        packed = self._packed_law
        if packed is None or packed.law is not type(self):
            packed = self.packed_law()
        if packed.terms is not None:
            return self._packed_step(packed, state, margins)
        kinetic = kinetic_energy(state.inertia, state.dx)
        psi = self.energy.limit - kinetic
        if not psi > 0:
            raise ConstraintViolation(self.energy.names[0], psi)
        bar = self._config.barrier(state, margins)
        potential, grad = self.potential.evaluate(state)
        lag = kinetic + potential
        log_x = bar.log_phi + math.log(psi)
        value = shaped_value(lag, self.shaping.log_s(log_x))
        found = None if bar.margins is None else np.append(bar.margins, psi)
        return Evaluation(self._law(state, bar, grad, lag, psi), value, found)

    def _packed_step(self, packed: PackedLaw, state: ArmState, margins: bool) -> Evaluation:
        """τ, V and the margins from one kernel call (cpbc.kernels.laws.cpbc_ke_step)."""
        args = packed.arguments(state, margins)  # ends with [φ̃ | the margins] and τ
        try:
            found = cpbc_ke_step(self.energy.limit, *args)
        except TypeError:  # a read-only or integer state (``writable``)
            args = writable(args)
            found = cpbc_ke_step(self.energy.limit, *args)
        lyapunov = self._checked(found, args[-2][:packed.margins])
        shown = np.append(args[-2][packed.margins:], found[2]) if margins else None
        return Evaluation(args[-1], lyapunov, shown)

    def _checked(self, found: tuple[float, float, float], phi: Array) -> float:
        """V from a step kernel's (V, log Φ, ψ); raises outside S (ψ ≤ 0, or a NaN log Φ:
        naming the margin from the barrier values ``phi``)."""
        lyapunov, log_phi, psi = found
        if not psi > 0:
            raise ConstraintViolation(self.energy.names[0], psi)
        if log_phi != log_phi:  # outside S
            raise self._config.violation(log_phi, phi)
        return lyapunov

    def _law(self, state: ArmState, bar: BarrierTerms, grad: Array, lag: float, psi: float
             ) -> Array:
        """The law of the class docstring, from ∂U/∂x (``grad``)
        (cpbc.kernels.laws.cpbc_ke_torque)."""
        rho = self.shaping.ratio(bar.log_phi + math.log(psi)) * lag
        damping = self.damping.force(state.dx)
        if self.task_damping is not None:
            damping = damping + self.task_damping_force(state)
        tau = np.empty(grad.shape[0])
        gradient = self._no_barrier[0] if bar.gradient is None else bar.gradient
        cpbc_ke_torque(state.gravity, grad, damping, gradient, rho, psi, tau)
        return tau


# -- the scenario's ``type: cpbc`` and ``cpbc_ke``: CPBC (cpbc.controllers.cpbc, Theorem 6.9)
# and this law (cpbc.controllers.law_kind) -------------------------------------------------
class CPBCSpec(ShapedLawSpec):
    type: Literal["cpbc", "cpbc_ke"] = Field(
        description=(
            "cpbc: Theorem 6.9, any configuration and velocity constraints; cpbc_ke: "
            "Corollary 6.11, configuration constraints and one kinetic_energy_limit"))


def build_cpbc(spec: CPBCSpec, given: LawInputs) -> Controller:
    law = CPBC if spec.type == "cpbc" else CPBCKineticEnergy
    gains: dict[str, Any] = dict(given.gains)
    return law(given.model, given.target, given.constraint_set(spec.constraints),
               shaping=shaping(spec.shaping), **gains)


KINDS = (LawKind(
    CPBCSpec, build_cpbc, slopes=LINEAR,
    examples={"cpbc": {"constraints": ["limits", "rates"]},
              "cpbc_ke": {"constraints": ["limits", "energy"]}},
    goal_types=("cpbc", "cpbc_ke")),)
