"""Constrained passivity-based control (Theorem 6.9) in log-barrier form (sums of ∇φ/φ)."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import BarrierTerms, ConstraintSet
from cpbc.controllers.controller import Evaluation, positive_vector
from cpbc.controllers.packed_law import PackedLaw, PacksItsLaw, law_terms, writable
from cpbc.controllers.potentials import JointSpring, Potential, require_posture
from cpbc.controllers.shaping import Identity, Shaping
from cpbc.controllers.terms import Damping, LinearDamping, StateDamping
from cpbc.kernels.energy import kinetic_energy
from cpbc.kernels.laws import (
    cpbc_step,
    cpbc_torque,
    shaped_value,
    zero_terms,
)
from cpbc.model.robot_model import ArmState, RobotModel


class CPBC(PacksItsLaw):
    """Constrained PBC for configuration and velocity constraints (Theorem 6.9, eq. 6.24/6.70).

    With V = L / s(ΦΨ), L = ½ẋᵀDẋ + U(x̃), dividing (6.24) by s gives the equivalent

        ρ = r(ΦΨ)·L,   b_φ = Σ ∇φ_i/φ_i,   b_ψ = Σ ∂_xψ_j/ψ_j,   Π = Σ Q_j/ψ_j
        a = −∂U/∂x − K_D ẋ + ρ(b_φ + b_ψ),   c = C ẋ + f
        τ = g + c + D (D + ρΠ)⁻¹ (a − c)

    which is (6.24) rearranged so that one linear solve suffices and the products Φ, Ψ are
    never formed. Along the closed loop V̇ = −ẋᵀ(K_D ẋ + f)/s ≤ 0 (eq. 6.32). The proof uses
    U only through U ≥ 0 and ∂U/∂x, so U may be any potential with a posture spring (a task
    potential: frame springs plus a joint spring toward x_n inside S; TASKSPACE §2.2).

    Args:
        model: the controller's robot model.
        target: x_d, inside S (the posture x_n with a task potential).
        constraints: the enforced constraints.
        kp: the diagonal stiffness K_P (a number or a list of n), > 0.
        kd: the diagonal damping K_D (a number or a list of n), > 0.
        shaping: s(x); Identity (Theorem 6.9) when omitted.
        potential: U; the joint spring ½x̃ᵀK_P x̃ toward ``target`` (eq. 6.7) when omitted.
        task_damping: F(x, ẋ) with ẋᵀF ≥ 0 added to K_D ẋ (cpbc.controllers.task_damping);
            then V̇ = −ẋᵀ(K_D ẋ + F + f)/s.

    When the constraint set and every term pack (cpbc.controllers.packed_law) a step is one
    kernel call (cpbc.kernels.laws.cpbc_step) over the same formulas; the packing is made
    at the first step and again after any of its inputs (``constraints``, ``potential``,
    ``damping``, ``task_damping``, ``shaping``) is set or the object's class changes.
    """

    type_name = "cpbc"
    _packed_from = frozenset({"constraints", "potential", "damping", "task_damping",
                              "shaping"})

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
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self.shaping: Shaping = shaping or Identity()
        self.potential: Potential = JointSpring(self.target, self.kp) if potential is None else (
            require_posture(potential, self.type_name))
        self.damping: Damping = LinearDamping(self.kd)
        self._no_barrier = zero_terms(model.n)

    def state(self, x: Array, dx: Array) -> ArmState:
        packed = self._packed_law
        if packed is None or packed.law is not type(self):
            packed = self.packed_law()
        produce = packed.produce
        if produce is None:
            return super().state(x, dx)
        return produce(x, dx)

    def _pack(self) -> PackedLaw:
        parts = law_terms(self, CPBC, ("_law", "_shaped_value", "task_damping_force"))
        return PackedLaw.build(type(self), parts, self.constraints, self.frames,
                               self.model)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        packed = self._packed_law
        if packed is None or packed.law is not type(self):
            packed = self.packed_law()
        if packed.terms is None:
            return self._general_step(state, margins)
        # τ, V and the margins from one kernel call (cpbc.kernels.laws.cpbc_step), written
        # here rather than in a method of its own: a call costs about 50 ns a step
        args = packed.arguments(state, margins)  # ends with [φ̃ | the margins] and τ
        try:
            lyapunov, log_phi, log_psi = cpbc_step(*args)
        except TypeError:  # a read-only or integer state (``writable``)
            args = writable(args)
            lyapunov, log_phi, log_psi = cpbc_step(*args)
        if log_phi != log_phi or log_psi != log_psi:  # outside S: named from φ̃
            raise self.constraints.violation(log_phi, args[-2][:packed.margins])
        return Evaluation(args[-1], lyapunov, args[-2][packed.margins:] if margins else None)

    def _general_step(self, state: ArmState, margins: bool) -> Evaluation:
        """τ, V and the margins method by method (a term or the class without a kernel)."""
        bar = self.constraints.barrier(state, margins)  # raises outside S
        potential, grad = self.potential.evaluate(state)
        lag = kinetic_energy(state.inertia, state.dx) + potential
        tau = self._law(state, bar, grad, lag)
        return Evaluation(tau, self._shaped_value(bar, lag), bar.margins)

    def _shaped_value(self, bar: BarrierTerms, lag: float) -> float:
        """V = L / s(ΦΨ), evaluated in logs."""
        return shaped_value(lag, self.shaping.log_s(bar.log_phi + bar.log_psi))

    def _law(self, state: ArmState, bar: BarrierTerms, grad: Array, lag: float) -> Array:
        """The law of the class docstring: τ from ∂U/∂x (``grad``), L and the barrier sums
        (cpbc.kernels.laws.cpbc_torque)."""
        damping = self.damping.force(state.dx)
        if self.task_damping is not None:
            damping = damping + self.task_damping_force(state)
        rho = self.shaping.ratio(bar.log_phi + bar.log_psi) * lag
        c = state.coriolis_force + state.dissipation if self.model.has_friction else (
            state.coriolis_force
        )
        tau = np.empty(grad.shape[0])
        zero_gradient, zero_weight = self._no_barrier
        cpbc_torque(state.inertia, state.gravity, c, grad, damping,
                    zero_gradient if bar.gradient is None else bar.gradient,
                    zero_weight if bar.weight is None else bar.weight,
                    bar.weight is not None, rho, tau)
        return tau
