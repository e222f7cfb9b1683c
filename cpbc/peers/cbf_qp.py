"""A torque-level CBF-QP safety filter around PD + gravity: the baseline users pick today.

At each sample it solves, with DAQP (a dense active-set solver: the problem has n variables
and one row per scalar constraint),

    min_τ ½‖τ − τ_nom‖²,   τ_nom = g − K_P x̃ − K_D ẋ          (PD + gravity, eq. 6.10)

subject to, with ẍ = D⁻¹(τ − b) and b = C ẋ + g + f (eq. 6.1):

* every configuration constraint φ_i (the law's own objects: joint limits, clearances, …),
  as an exponential CBF of relative degree two with both poles at −k:
      φ̈_i + 2k φ̇_i + k² φ_i ≥ 0,   φ̈_i = ∇φ_i ẍ + ẋᵀ∇²φ_i ẋ
  (the curvature where the constraint knows it, ConfigurationConstraint.curvature);
* every rate bound |aᵀẋ| < B as two first-order rows, d/dt(B ∓ aᵀẋ) ≥ −γ (B ∓ aᵀẋ): one row on
  the side a joint is heading is not enough under a zero-order hold (a held torque can throw
  it past the opposite bound), so both sides are kept in one two-sided row;
* a kinetic-energy limit ψ = Ω − ½ẋᵀDẋ, first order: ψ̇ = −ẋᵀ(τ − g − f) ≥ −γψ
  (skew symmetry of Ḋ − 2C, Property 6.2);
* the actuators' box |Tᵀτ| ≤ L when the scenario has torque limits.

γ defaults to 1/(2h), half the largest first-order gain a held period tolerates.

**Infeasible steps** (the box and the barrier rows cannot all hold) are counted
(``infeasible``): the filter then solves again without the box and returns that torque, which
the actuators clip; when even the barrier rows contradict each other it returns τ_nom. This is
what a practitioner's filter does with a soft box; nothing is hidden from the counts.

Only this module imports a QP solver, and only when a ``cbf_qp`` controller is built.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.rate_limit import RateLimit
from cpbc.controllers.base import Evaluation, SafetyFilter, positive_vector
from cpbc.errors import ConstraintViolation, CpbcError, ParameterError
from cpbc.model.robot_model import ArmState, RobotModel

EXTRA = "pip install 'cpbc[peers]'"


class PeerUnavailable(CpbcError):
    """The optional solver a peer needs is not installed."""


def _daqp() -> Callable[..., Any]:
    try:
        import daqp  # the optional extra cpbc[peers]
    except ImportError:
        raise PeerUnavailable(
            f"the cbf_qp controller needs the DAQP solver, which is not installed: {EXTRA}"
        ) from None
    return daqp.solve


class CBFQP(SafetyFilter):
    """The CBF-QP filter of the module docstring.

    Args:
        model: the controller's robot model (D, C ẋ, g, f).
        target: x_d, (n,).
        constraints: the constraints to enforce — configuration constraints of any kind,
            rate limits and at most one kinetic-energy limit.
        kp, kd: gains of the PD + gravity nominal.
        gain: k of the exponential CBFs [1/s].
        rate_gain: γ of the first-order rows [1/s]; 1/(2·period) when omitted.
        period: the control period h [s].
        torque_limit: L per joint (joint coordinates), or None for no box.
    """

    type_name = "cbf_qp"

    def __init__(
        self, model: RobotModel, target: Array, constraints: ConstraintSet, kp: object,
        kd: object, gain: float = 20.0, rate_gain: float | None = None, period: float = 1e-3,
        torque_limit: Array | float | None = None,
    ) -> None:
        super().__init__(model, target, constraints)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self.gain = float(positive_vector(gain, 1, "gain")[0])
        self._rate_given = rate_gain
        rate = 0.5 / period if rate_gain is None else rate_gain
        self.rate_gain = float(positive_vector(rate, 1, "rate_gain")[0])
        for v in constraints.velocity:
            if not isinstance(v, RateLimit | KineticEnergyLimit):
                raise ParameterError("constraints", f"cbf_qp keeps rate and kinetic-energy "
                                     f"limits only, not {type(v).__name__} {v.names}")
        self.torque_limit = None if torque_limit is None else np.broadcast_to(
            np.asarray(torque_limit, dtype=float), (model.n,))
        coords = model.coordinates
        self._box_rows = None if coords.is_identity else np.ascontiguousarray(coords.matrix.T)
        self._solve = _daqp()
        self.acted = 0
        self.infeasible = 0

    def restarted(self) -> CBFQP:
        out = copy.copy(self)
        out.acted = out.infeasible = 0
        return out

    def at_period(self, period: float) -> CBFQP:
        """The same filter at another control period (its default γ = 1/(2h) follows)."""
        out = self.restarted()
        if self._rate_given is None:
            out.rate_gain = float(positive_vector(0.5 / period, 1, "period")[0])
        return out

    def nominal(self, state: ArmState) -> Array:
        """τ_nom = g − K_P x̃ − K_D ẋ."""
        return state.gravity - self.kp * (state.x - self.target) - self.kd * state.dx

    def rows(self, state: ArmState) -> tuple[Array, Array, Array]:
        """The barrier rows: A (m, n), lower (m,), upper (m,) with lower ≤ A τ ≤ upper."""
        x, dx = state.x, state.dx
        inv = np.linalg.inv(state.inertia)
        drift = inv.dot(state.coriolis_force + state.gravity + state.dissipation)  # ẍ at τ = 0
        a_rows, lower, upper = [], [], []
        k = self.gain
        for c in self.constraints.configuration:
            phi, grad = c.evaluate(x)
            if not np.all(phi > 0):  # outside S, as the laws refuse it
                i = int(np.argmin(np.where(np.isnan(phi), -np.inf, phi)))
                raise ConstraintViolation(c.names[i], float(phi[i]))
            need = grad.dot(drift) - c.curvature(x, dx) - 2 * k * grad.dot(dx) - k * k * phi
            a_rows.append(grad.dot(inv))
            lower.append(need)
            upper.append(np.full(len(phi), np.inf))
        g = self.rate_gain
        for v in self.constraints.velocity:
            if isinstance(v, RateLimit):
                rate = v.rows.dot(dx)
                base = v.rows.dot(drift)
                a_rows.append(v.rows.dot(inv))
                lower.append(base - g * (v.bounds + rate))
                upper.append(base + g * (v.bounds - rate))
            else:  # kinetic energy: ẋᵀτ ≤ ẋᵀ(g + f) + γψ
                psi = v.value(x, dx, state)
                a_rows.append(dx[None, :])
                lower.append(np.array([-np.inf]))
                upper.append(dx.dot(state.gravity + state.dissipation) + g * psi)
        if not a_rows:
            n = self.model.n
            return np.zeros((0, n)), np.zeros(0), np.zeros(0)
        return np.vstack(a_rows), np.concatenate(lower), np.concatenate(upper)

    def _qp(self, nominal: Array, a: Array, lower: Array, upper: Array, box: bool
            ) -> tuple[Array, int]:
        n = self.model.n
        if box and self.torque_limit is not None:
            lim = self.torque_limit * (1 - 1e-9)  # the solver's tolerance inside the box
            if self._box_rows is None:  # simple bounds come first (DAQP's convention)
                lower, upper = np.concatenate([-lim, lower]), np.concatenate([lim, upper])
            else:
                a = np.vstack([self._box_rows, a])
                lower, upper = np.concatenate([-lim, lower]), np.concatenate([lim, upper])
        tau, _, flag, _ = self._solve(np.eye(n), -nominal, np.ascontiguousarray(a),
                                      upper, lower, np.zeros(len(upper), dtype=np.int32))
        return np.asarray(tau), int(flag)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        nominal = self.nominal(state)
        a, lower, upper = self.rows(state)
        tau, flag = self._qp(nominal, a, lower, upper, box=True)
        feasible = flag == 1
        if not feasible:  # counted as a step it acted on, of which it could not meet all
            self.infeasible += 1
            tau, flag = self._qp(nominal, a, lower, upper, box=False)
            if flag != 1:
                tau = nominal
        if not feasible or np.max(np.abs(tau - nominal)) > 1e-9 * (1 + np.max(np.abs(nominal))):
            self.acted += 1
        err = state.x - self.target
        value = 0.5 * float(state.dx @ state.inertia @ state.dx) + 0.5 * float(
            err @ (self.kp * err))
        found = self.constraints.margins(state.x, state.dx, state) if margins else None
        return Evaluation(tau, value, found)
