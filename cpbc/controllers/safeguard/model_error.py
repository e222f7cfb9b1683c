"""A declared model error, held by the safeguard as a disturbance: the floors of (S1) raised by
what an acceleration error within the declared bound can take off each margin in one period.

The guard predicts with the controller's model. Where the arm's acceleration differs from the
model's by d, |d_j| ≤ ā_j (``simulation.model_error.acceleration``: friction the model does
not know, a mass off by some per cent, an unmodelled payload — whatever the user bounds), the
period's end moves by c h² d (c of the prediction's end, ``travel``: ½ in continuous time) and
its mid-point by ⅛ h² d, and the rates by h d. To first order a margin loses at most

    configuration φ_i:   c h² Σ_j |∂φ_i/∂x_j| ā_j        at the end,   ⅛ h² (…) at mid-period,
    velocity ψ_k = ω_k − ½ ẋᵀΠ_k ẋ:   h Σ_j |(Π_k ẋ)_j| ā_j + ½ h² āᵀ|Π_k| ā   at the end

(Π_k: ``VelocityConstraint.weights``: r rᵀ for a rate, D for the kinetic energy; the second
term is exact for a constant Π). Holding every predicted margin that much above the floor of
(S1) makes the true margin keep (S1) whatever d within the bound does: by induction it never
falls below its cushion δ_i > 0. The rescue's rollouts and the braking set are the model's;
the braking set's deceleration is lowered by the error's share along the motion
(:class:`cpbc.constraints.stopping.Braking`, ``disturbance``). The curvature of φ and the
change of Π_k over the period are left out (second order in h).

**The Coulomb friction's own error.** The model's Coulomb friction is smooth, F_c tanh(q̇/ε);
a real joint's is set-valued at rest and has its own shape at low speed (MuJoCo's
``frictionloss`` is a soft constraint that builds up over a speed of its own; a real drive
has stiction and a Stribeck dip). Both lie in [−F_c, F_c] and agree in sign once the joint
moves, so they differ by at most F_c,j at joint j, and through D⁻¹ that force error moves
every coordinate's acceleration (:func:`friction_error`, added to the declared bound whenever
the model has Coulomb friction). Measured on the FR3 (franky-sim's friction, 1000 N·m/s,
1 kHz): as a wrist joint's rate passed through zero, the arm's acceleration left the model's
by 0.8–1.2 rad/s² on joints 2 and 4 and pushed joint 1 through its rate bound; 18 of 185 runs
from stoppable starts crossed a rate bound before the guard held this error. A bound that
credited the smooth model near F_c at speed (F_c (1 − tanh(|q̇|/ε))) left the UR5's shoulder
0.7 rad/s² short where MuJoCo's friction was still building up at 0.1 rad/s.

This is why the bare guard let velocity margins break under a ±20 % mass error (docs/
ROBUSTNESS.md, "Model mismatch"): a law that rides a velocity bound cancels the *model's*
acceleration there, and the model error alone pushes through; the raised floor keeps the
rate h ā_j (1 kHz, 10 rad/s²: 0.01 rad/s) inside its bound instead.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import ArmState, RobotModel


def friction_error(model: RobotModel, state: ArmState) -> Array | None:
    """The bound on the acceleration error of the model's smooth Coulomb friction (the module
    docstring): |D⁻¹| |T⁻ᵀ| F_c per coordinate, or None for a model without Coulomb
    friction."""
    levels = model.coulomb_friction
    if not np.any(levels):
        return None
    coords = model.coordinates
    force = levels if coords.is_identity else np.abs(coords.inverse.T) @ levels
    return np.abs(np.linalg.inv(state.inertia)) @ force


def margin_losses(constraints: ConstraintSet, state: ArmState, bound: Array, period: float,
                  travel: float) -> tuple[Array, Array]:
    """What an acceleration error |d_j| ≤ ``bound``_j can take off each margin of
    ``constraints`` over one period (the module docstring): (at the period's end, every
    margin in the order of ``names``; at mid-period, the configuration ones)."""
    h = period
    x, dx = state.x, state.dx
    parts, mid = [], np.zeros(constraints.n_configuration)
    if constraints.configuration:
        grads = constraints.configuration_gradients(state)
        reach = np.abs(grads) @ bound
        parts.append(travel * h * h * reach)
        mid = 0.125 * h * h * reach
    for c in constraints.velocity:
        weights = c.weights(x, state)  # (k, n, n)
        push = np.abs(weights @ dx) @ bound
        drift = 0.5 * h * h * np.einsum("kij,i,j->k", np.abs(weights), bound, bound)
        parts.append(h * push + drift)
    end = np.concatenate(parts) if parts else np.zeros(0)
    return end, mid
