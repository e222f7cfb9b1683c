"""The baselines: PD (the thesis's comparison) and PD + gravity (eq. 6.10)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller, Evaluation, positive_vector
from cpbc.controllers.law_kind import LINEAR, LawInputs, LawKind
from cpbc.controllers.law_specs import LawSpec
from cpbc.controllers.potentials import Configuration, JointSpring, Potential, require_posture
from cpbc.controllers.terms import StateDamping
from cpbc.model.measured_state import measured, refuse_non_finite
from cpbc.model.robot_model import ArmState, RobotModel


class PD(Controller):
    """τ = −∂U/∂x − K_D ẋ with U = ½ x̃ᵀK_P x̃ (eq. 6.7): −K_P x̃ − K_D ẋ, as compared against
    in Sections 6.4 and 7.3. ``potential`` replaces U (a task potential with a posture spring:
    with PD + g, Takegaki and Arimoto's Jacobian-transpose law); ``task_damping`` F is
    subtracted too (L̇ = −ẋᵀ(K_D ẋ + F + f) for PD + g)."""

    type_name = "pd"

    def __init__(self, model: RobotModel, target: Array, kp: object, kd: object,
                 potential: Potential | None = None,
                 task_damping: StateDamping | None = None) -> None:
        super().__init__(model, target)
        self.task_damping = task_damping
        self.kp = positive_vector(kp, model.n, "kp")
        self.kd = positive_vector(kd, model.n, "kd")
        self.potential: Potential = JointSpring(self.target, self.kp) if potential is None else (
            require_posture(potential, self.type_name))

    # torque() and evaluate() skip the per-step state (PD + g needs only g) unless the
    # potential reads frames; evaluate_state reads it. Both ask the one feed-forward hook,
    # _bias, so a subclass changes both.
    def torque(self, x: Array, dx: Array) -> Array:
        x, dx = measured(x, dx, self.model.n)
        if self.frames:
            tau = self.evaluate_state(self.state(x, dx)).torque
        else:
            _, grad = self.potential.evaluate(Configuration(x))
            tau = self._law(grad, dx, self._bias(x, None))
        refuse_non_finite(tau, x, dx)
        return tau

    def lyapunov(self, x: Array, dx: Array) -> float:
        """L = ½ ẋᵀDẋ + U (eq. 6.7); non-increasing when gravity does no work."""
        x, dx = measured(x, dx, self.model.n)
        if self.frames:
            return self.evaluate_state(self.state(x, dx)).lyapunov
        return self.model.kinetic_energy(x, dx) + self.potential.evaluate(Configuration(x))[0]

    def evaluate(self, x: Array, dx: Array) -> tuple[Array, float]:
        x, dx = measured(x, dx, self.model.n)
        if self.frames:
            out = self.evaluate_state(self.state(x, dx))
            tau, value = out.torque, out.lyapunov
        else:
            value, grad = self.potential.evaluate(Configuration(x))
            tau = self._law(grad, dx, self._bias(x, None))
            value += self.model.kinetic_energy(x, dx)
        refuse_non_finite(tau, x, dx)
        return tau, value

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        dx = state.dx
        value, grad = self.potential.evaluate(state)
        tau = self._law(grad, dx, self._bias(state.x, state)) - self.task_damping_force(state)
        value += 0.5 * float(dx @ state.inertia @ dx)
        found = self.constraints.margins(state.x, dx, state) if margins else None
        return Evaluation(tau, value, found)

    def _law(self, grad: Array, dx: Array, bias: Array | float) -> Array:
        """τ = bias − ∂U/∂x − K_D ẋ."""
        return bias - grad - self.kd * dx

    def _bias(self, x: Array, state: ArmState | None) -> Array | float:
        """The torque's state-only feed-forward at x (read from ``state`` when the caller
        has one): none for PD."""
        return 0.0


class PDGravity(PD):
    """τ = g(x) − K_P x̃ − K_D ẋ (eq. 6.10), with L̇ = −ẋᵀ(K_D ẋ + f) ≤ 0 (eq. 6.11); with a
    task potential, g − ∂U/∂x − K_D ẋ and the same L̇."""

    type_name = "pd_gravity"

    def _bias(self, x: Array, state: ArmState | None) -> Array:
        return self.model.gravity(x) if state is None else state.gravity


# -- the scenario's ``type: pd`` and ``pd_gravity`` (cpbc.controllers.law_kind) -------------
class PDSpec(LawSpec):
    type: Literal["pd", "pd_gravity"] = Field(
        description=(
            "pd: −K_P x̃ − K_D ẋ (the thesis's baseline); pd_gravity: g − K_P x̃ − K_D ẋ "
            "(6.10). Constraints are only monitored"))


def build_pd(spec: PDSpec, given: LawInputs) -> Controller:
    law = PD if spec.type == "pd" else PDGravity
    gains: dict[str, Any] = dict(given.gains)
    return law(given.model, given.target, **gains)


KINDS = (LawKind(PDSpec, build_pd, slopes=LINEAR, examples={"pd": {}, "pd_gravity": {}},
                 goal_types=("pd_gravity",)),)
