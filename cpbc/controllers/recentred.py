"""Re-centred barrier PBC for joint position limits (Cases 2–3 of §6.3.1, eqs. 6.53–6.65).

The one law of Chapter 6 with a unique minimum and hence guaranteed asymptotic stability.
Generalised from symmetric limits |x_i| < X_i to lower_i < x_i < upper_i by centring:
z = x − c, w = (upper − lower)/2, and each factor normalised to 1 at the centre,

    Φ(z) = Π (1 − z_i²/w_i²),   f(x) = zᵀK_P z / (2Φ)                          (6.54)
    ∇f  = [K_P z + (zᵀK_P z) z / (w² − z²)] / Φ      (elementwise division)      (6.55)

The thesis's factors ½(X_i² − z_i²) differ only by the constants X_i²/2, which rescale
K_P; normalising keeps K_P's meaning of a PD gain at the centre of the range.

    V = ½ẋᵀDẋ / Ψ + f(x) − f(x_d) − ∇f(x_d)ᵀ(x − x_d)                          (6.61)
    τ = g + c + D (D + KΠ)⁻¹ (a − c),  K = ½ẋᵀDẋ,  c = Cẋ + f,
    a = −K_D ẋ + K b_ψ − Ψ (∇f(x) − ∇f(x_d))                                   (6.63)

which reduces to τ = g − K_D ẋ − ∇f(x) + ∇f(x_d) (6.57) without velocity constraints.
V̇ = −ẋᵀ(K_D ẋ + f)/Ψ ≤ 0 (eq. 6.64).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import BarrierTerms, ConstraintSet
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.controllers.base import Controller, Evaluation, positive_vector
from cpbc.controllers.linalg import solve_spd
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model.robot_model import ArmState, RobotModel


class RecentredBarrier(Controller):
    """Re-centred barrier law for joint limits, optionally with velocity constraints."""

    type_name = "recentred"

    def __init__(
        self,
        model: RobotModel,
        target: Array,
        constraints: ConstraintSet,
        kp: object,
        kd: object,
    ) -> None:
        super().__init__(model, target, constraints)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        limits = constraints.configuration
        joint_limits = [
            c for c in limits
            if isinstance(c, LinearLimit)
            and np.all(np.count_nonzero(c.rows, axis=1) == 1)
            and np.allclose(np.abs(c.rows).sum(axis=1), 1.0)
        ]
        if not limits or len(joint_limits) != len(limits):
            raise CpbcError(
                "recentred (Cases 2–3) enforces joint position limits (joint_position_limit) "
                "and optionally velocity constraints; obstacle and combination limits need cpbc"
            )
        self.joints = np.concatenate([np.argmax(np.abs(c.rows), axis=1) for c in joint_limits])
        if len(set(self.joints.tolist())) != len(self.joints):
            raise CpbcError("recentred: a joint has more than one position limit")
        self.centre = np.concatenate([c.centre for c in joint_limits])
        self.half_width = np.concatenate([c.half_width for c in joint_limits])
        self._limit_names = [name for c in limits for name in c.names]
        self._velocity = ConstraintSet(model.n, velocity=constraints.velocity)
        self._f_target, self._grad_target = self._barrier_potential(self.target)

    def _barrier_potential(self, x: Array) -> tuple[float, Array]:
        """f(x) and ∇f(x) of (6.54)–(6.55)."""
        z = x[self.joints] - self.centre
        gap = self.half_width**2 - z * z
        if not np.all(gap > 0):
            i = int(np.argmin(gap))
            raise ConstraintViolation(self._limit_names[i], float(gap[i]))
        inv_phi = math.exp(-float(np.sum(np.log(gap / self.half_width**2))))
        kz = np.zeros_like(x)
        kz_sel = self.kp[self.joints] * z
        energy = float(z @ kz_sel)
        kz[self.joints] = kz_sel + energy * z / gap
        return 0.5 * energy * inv_phi, kz * inv_phi

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        f, grad = self._barrier_potential(state.x)  # raises outside the limits
        x, dx = state.x, state.dx
        bar = self._velocity.barrier(state) if self._velocity.velocity else None
        kinetic = 0.5 * float(dx @ state.inertia @ dx)
        tau = self._law(state, grad, kinetic, bar)
        shift = f - self._f_target - float(self._grad_target @ (x - self.target))
        psi = 1.0 if bar is None else math.exp(bar.log_psi)
        found = self.constraints.margins(x, dx, state) if margins else None
        return Evaluation(tau, kinetic / psi + shift, found)

    def _law(self, state: ArmState, grad: Array, kinetic: float, bar: BarrierTerms | None
             ) -> Array:
        """(6.57) without velocity constraints, (6.63) with them (module docstring)."""
        a = -self.kd * state.dx
        if bar is None:
            return state.gravity + a - grad + self._grad_target
        a = a - math.exp(bar.log_psi) * (grad - self._grad_target)
        if bar.gradient is not None:
            a += kinetic * bar.gradient
        c = state.coriolis_force + state.dissipation
        assert bar.weight is not None  # velocity constraints give Π
        y = solve_spd(state.inertia + kinetic * bar.weight, a - c)
        return state.gravity + c + state.inertia @ y
