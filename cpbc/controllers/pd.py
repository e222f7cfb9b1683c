"""The baselines: PD (the thesis's comparison) and PD + gravity (eq. 6.10)."""

from __future__ import annotations

from cpbc.arrays import Array
from cpbc.controllers.base import Controller, Evaluation, positive_vector
from cpbc.controllers.terms import QuadraticPotential
from cpbc.model.robot_model import ArmState, RobotModel


class PD(Controller):
    """τ = −K_P x̃ − K_D ẋ, as compared against in Sections 6.4 and 7.3."""

    type_name = "pd"

    def __init__(self, model: RobotModel, target: Array, kp: object, kd: object) -> None:
        super().__init__(model, target)
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self._potential = QuadraticPotential(self.kp)

    # torque() and evaluate() skip the per-step state (PD + g needs only g); evaluate_state
    # reads it. Both ask the one feed-forward hook, _bias, so a subclass changes both.
    def torque(self, x: Array, dx: Array) -> Array:
        return self._law(x - self.target, dx, self._bias(x, None))

    def lyapunov(self, x: Array, dx: Array) -> float:
        """L = ½ ẋᵀDẋ + ½ x̃ᵀK_P x̃ (eq. 6.7); non-increasing when gravity does no work."""
        return self.model.kinetic_energy(x, dx) + self._potential.value(x - self.target)

    def evaluate(self, x: Array, dx: Array) -> tuple[Array, float]:
        err = x - self.target
        tau = self._law(err, dx, self._bias(x, None))
        return tau, self.model.kinetic_energy(x, dx) + self._potential.value(err)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        err = state.x - self.target
        dx = state.dx
        tau = self._law(err, dx, self._bias(state.x, state))
        value = 0.5 * float(dx @ state.inertia @ dx) + self._potential.value(err)
        found = self.constraints.margins(state.x, dx, state) if margins else None
        return Evaluation(tau, value, found)

    def _law(self, err: Array, dx: Array, bias: Array | float) -> Array:
        """τ = bias − K_P x̃ − K_D ẋ."""
        return bias - self.kp * err - self.kd * dx

    def _bias(self, x: Array, state: ArmState | None) -> Array | float:
        """The torque's state-only feed-forward at x (read from ``state`` when the caller
        has one): none for PD."""
        return 0.0


class PDGravity(PD):
    """τ = g(x) − K_P x̃ − K_D ẋ (eq. 6.10), with L̇ = −ẋᵀ(K_D ẋ + f) ≤ 0 (eq. 6.11)."""

    type_name = "pd_gravity"

    def _bias(self, x: Array, state: ArmState | None) -> Array:
        return self.model.gravity(x) if state is None else state.gravity
