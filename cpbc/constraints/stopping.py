"""Can the actuators stop in time? A first-order stopping test for configuration constraints
under bounded torque (issue 12: viability is part of the admissible set).

With |τ_q| ≤ L the arm can only decelerate so fast, so a state close to a boundary φ_i = 0
and approaching it fast is lost whatever any controller does. For one constraint, with the
dynamics frozen at the state (D, b = C ẋ + g + f) and τ = T⁻ᵀ τ_q in controller coordinates,

    φ̈_i = ∇φ_i · D⁻¹ (τ − b) + ẋᵀ ∇²φ_i ẋ,

and the largest φ̈_i any torque in the box gives is

    a_i = Σ_j |w_j| L_j − ∇φ_i · D⁻¹ b + κ_i,     w = T⁻¹ D⁻¹ ∇φ_iᵀ,

with κ_i = ẋᵀ∇²φ_i ẋ (``ConfigurationConstraint.curvature``; 0 where not given). Approaching
at v_i = −∇φ_i · ẋ > 0 under the largest constant φ̈_i, φ_i falls by v_i² / (2 a_i) before
φ̇_i = 0, so a state with

    s_i = φ_i − v_i² / (2 a_i) ≤ 0      (or a_i ≤ 0 and v_i > 0)

cannot be kept inside φ_i > 0 by any held torque in the box, to first order. This is a
necessary condition for viability, not a sufficient one: it treats each constraint alone
(one torque must stop all of them), freezes D and b over the stop, and leaves out the
curvature of constraints that do not give it (clearance). States that fail it are refused
as initial states; states that pass it may still be lost.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import RobotModel


def stopping_margins(
    constraints: ConstraintSet, model: RobotModel, x: Array, dx: Array, torque_limit: Array
) -> tuple[Array, Array, Array]:
    """s_i of the module docstring for every configuration constraint (in the order of
    their names), with the approach speeds v_i and the largest decelerations a_i.

    Args:
        constraints: the constraints (their configuration part is tested).
        model: the controller's model (D, b at the state).
        x, dx: the state, controller coordinates.
        torque_limit: L, joint coordinates, shape (n,) [N·m].
    """
    if not constraints.configuration:
        empty = np.zeros(0)
        return empty, empty, empty
    state = model.state(x, dx)
    bias = state.coriolis_force + state.gravity + state.dissipation
    values, gradients = zip(*(c.evaluate(x) for c in constraints.configuration), strict=True)
    phi, grads = np.concatenate(values), np.concatenate(gradients)
    curvature = np.concatenate([c.curvature(x, dx) for c in constraints.configuration])
    inv_d_grads = np.linalg.solve(state.inertia, grads.T)  # D⁻¹ ∇φᵀ, (n, k)
    w = model.coordinates.inverse @ inv_d_grads  # T⁻¹ D⁻¹ ∇φᵀ: a torque in joint units
    reach = np.abs(w).T @ np.broadcast_to(torque_limit, (model.n,))
    decel = reach - inv_d_grads.T @ bias + curvature
    speed = -(grads @ dx)
    with np.errstate(divide="ignore", invalid="ignore"):
        lost = np.where(decel > 0, speed * speed / (2.0 * decel), np.inf)
    margins = np.where(speed > 0, phi - lost, phi)
    return margins, speed, decel

