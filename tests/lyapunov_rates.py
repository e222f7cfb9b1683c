"""V̇ along a law's closed loop, measured and as each theorem states it: the helpers the
task-space tests (potentials, task damping) share."""

from __future__ import annotations

import math

import numpy as np

from cpbc.controllers.controller import Controller
from cpbc.model.robot_model import RobotModel


def measured_rate(law: Controller, model: RobotModel, x: np.ndarray, dx: np.ndarray,
                  h: float = 1e-5) -> float:
    """V̇ = ∂V/∂x ẋ + ∂V/∂ẋ ẍ, ẍ = D⁻¹(τ − Cẋ − g − f) under the law (five-point stencil)."""
    ddx = model.forward_dynamics(x, dx, law.torque(x, dx))

    def v(step: float) -> float:
        return law.lyapunov(x + step * dx, dx + step * ddx)

    return (-v(2 * h) + 8 * v(h) - 8 * v(-h) + v(-2 * h)) / (12 * h)


def stated_rate(name: str, law: Controller, x: np.ndarray, dx: np.ndarray) -> float:
    """The V̇ each theorem states: −ẋᵀ(K_D ẋ + F + f)/s (6.11, 6.32, 7.22), the KE laws'
    (1 + ρ/ψ) on f (Corollaries 6.11, 7.8), with F the law's task damping if it has one."""
    # every constraint's terms, the energy limit's included (CPBC-KE's own state leaves C out)
    state = law.constraints.state(law.model, x, dx, law.frames)
    f = state.dissipation
    damping = law.damping.force(dx) if hasattr(law, "damping") else law.kd * dx  # type: ignore
    if law.task_damping is not None:
        task = law.task_damping.force(state, dx)
        assert float(dx @ task) >= 0
        damping = damping + task
    if name == "pd_gravity":
        return float(-dx @ (damping + f))
    bar = law.constraints.barrier(state)
    log_x = bar.log_phi + bar.log_psi
    s = math.exp(law.shaping.log_s(log_x))  # type: ignore[attr-defined]
    if not name.endswith("_ke"):
        return float(-dx @ (damping + f) / s)
    kinetic = 0.5 * float(dx @ state.inertia @ dx)
    assert law.potential is not None
    lag = kinetic + law.potential.evaluate(state)[0]
    psi = law.energy.limit - kinetic  # type: ignore[attr-defined]
    rho = law.shaping.ratio(log_x) * lag  # type: ignore[attr-defined]
    return float(-(dx @ damping + (1 + rho / psi) * dx @ f) / s)
