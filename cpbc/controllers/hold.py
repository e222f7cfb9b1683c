"""The law's torque corrected for the zero-order hold (first order).

A controller that holds τ over a period h does not hold the acceleration it asked for: with
the arm moving, D(x), C(x, ẋ)ẋ and g(x) change within the period, and the acceleration under
the held τ drifts from a₀ = D⁻¹(τ − b) at the sample to a₀ + Δa at the end. Holding instead

    τ_h = τ − ½ D Δa,     Δa = D(x₁)⁻¹(τ − b(x₁, ẋ₁)) − a₀,

with (x₁, ẋ₁) the frozen prediction of the period's end, keeps a₀ on average over the period
to first order: the continuous-time law's acceleration, which its theorem is about, instead
of one that is off by ½Δa. It matters where the law's authority is small: the CPBC laws near
a velocity bound (their shaped inertia D + ρΠ grows as 1/ψ, so the acceleration they can ask
for shrinks with the margin), where the hold error alone, not the law, would wear the margin
down (README, "A law that rides a rate bound").
"""

from __future__ import annotations

from cpbc.arrays import Array
from cpbc.controllers.linalg import solve_spd
from cpbc.model.robot_model import ArmState, RobotModel


def hold_corrected(model: RobotModel, state: ArmState, bias: Array, tau: Array,
                   period: float) -> Array:
    """τ − ½ D Δa: the torque whose hold keeps the acceleration of τ at the sample on average
    over ``period``, to first order. ``bias`` is C ẋ + g (+ f) at the sample."""
    h = period
    acc = solve_spd(state.inertia, tau - bias)
    end = state.x + h * state.dx + (0.5 * h * h) * acc
    drift = model.forward_dynamics(end, state.dx + h * acc, tau) - acc
    return tau - 0.5 * state.inertia.dot(drift)
