"""The plant's dry friction against the model's smooth one, held over a brake's rollout in
the model (the rescue's checks, cpbc.controllers.rescue); the bound and its conditions are
derived in cpbc.controllers.safeguard.model_error's docstring."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.margin_slopes import MarginSlopes
from cpbc.model.coulomb import MUJOCO_FRICTION, DryFriction
from cpbc.model.robot_model import RobotModel


def joint_inverse(model: RobotModel, inertia: Array) -> tuple[Array, Array]:
    """(D⁻¹ T⁻ᵀ in controller coordinates, T⁻¹ D⁻¹ T⁻ᵀ: the joint accelerations a joint
    torque gives)."""
    inv = np.asarray(np.linalg.inv(inertia), dtype=float)
    coords = model.coordinates
    if coords.is_identity:
        return inv, inv
    to_force = coords.inverse.T
    return inv @ to_force, coords.inverse @ inv @ to_force


class FrictionDrift:
    """The Coulomb friction's error held over a brake's rollout in the model (the rescue's
    checks, cpbc.controllers.rescue): period after period, the bound ā_k = |D⁻¹||T⁻ᵀ| e_k
    of cpbc.controllers.safeguard.model_error.friction_error at the period's model states
    and accelerations, summed into a bound on how far the plant's rate and position can
    have left the model's,

        w_{k+1} = w_k + h ā_k,     p_{k+1} = p_k + h w_k + ½ h² ā_k,

    and what those take off each margin at the period's end (:meth:`MarginSlopes.losses`,
    ∇φ and Π_k ẋ read there; first order, as the guard's own floors). A joint is taken to
    slide only if it does at the model's rate less w (the plant's may be that much lower),
    decelerating as the model's does plus the coarse |D⁻¹|·2F: a rollout whose joints all
    move fast loses nothing, one whose joints rest or turn loses ½ t² ā over the time they
    do. The curvature of φ and the dynamics' own response to the drift are left out."""

    def __init__(self, model: RobotModel, constraints: ConstraintSet, x: Array, dx: Array,
                 period: float, plant: DryFriction = MUJOCO_FRICTION) -> None:
        self.model, self.constraints, self.period, self.plant = model, constraints, period, plant
        self.x, self.dx = x, dx
        n = model.n
        self.rate = np.zeros(n)  # w
        self.position = np.zeros(n)  # p

    def losses(self, xs: Array, dxs: Array) -> Array:
        """Every margin's loss at the end of the period whose rows (model states at its
        sub-steps, its end last) are ``xs``, ``dxs``; the drift moves on to that end."""
        model, h = self.model, self.period
        levels = model.coulomb_friction
        rates = np.vstack((self.dx, dxs))
        dt = h / len(dxs)
        accels = np.diff(rates, axis=0) / dt
        to_accel, joint_inv = joint_inverse(model, model.inertia(self.x))
        w = self.rate if model.coordinates.is_identity else (
            np.abs(model.coordinates.inverse) @ self.rate)
        q_rates = np.array([model.joint_coordinates(v) for v in rates])
        q_accels = np.array([model.joint_coordinates(a) for a in accels])
        speed = np.abs(q_rates)
        sign = np.sign(q_rates[0])
        coarse = np.abs(joint_inv) @ (2.0 * levels)
        alpha = np.maximum(np.max(-sign * q_accels, axis=0), 0.0) + coarse
        e = self.plant.force_error(levels, model.friction_smoothing,
                                   np.min(speed, axis=0) - w - h * coarse,
                                   np.max(speed, axis=0) + w + h * coarse, alpha)
        bound = np.abs(to_accel) @ e
        self.position = self.position + h * self.rate + 0.5 * h * h * bound
        self.rate = self.rate + h * bound
        self.x, self.dx = xs[-1], dxs[-1]
        state = model.state(self.x, self.dx, kinematics=True)
        end, _ = MarginSlopes.at(self.constraints, state).losses(
            self.position, self.position, self.rate)
        return end
