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

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

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


@dataclass(frozen=True, eq=False)
class MarginSlopes:
    """How far each margin of a constraint set moves for a small error of the state, at the
    per-step state, read once a step for every error the guard holds (the model's and the
    measurement's): |∂φ_i/∂x| of each configuration margin, and of each velocity margin
    ψ_k = ω_k − ½ẋᵀΠ_k ẋ, |Π_k ẋ| and |Π_k| (``VelocityConstraint.weights``: r rᵀ for a
    rate, D for the kinetic energy).

    Attributes:
        configuration: |∇φ_i| rows, shape (number of φ_i, n).
        push: |Π_k ẋ| rows, shape (number of ψ_k, n).
        weights: |Π_k|, shape (number of ψ_k, n, n).
    """

    configuration: Array
    push: Array
    weights: Array

    @classmethod
    def at(cls, constraints: ConstraintSet, state: ArmState) -> MarginSlopes:
        n = constraints.n
        config = np.abs(constraints.configuration_gradients(state))
        weights = [c.weights(state.x, state) for c in constraints.velocity]  # (k, n, n) each
        if not weights:
            return cls(config, np.zeros((0, n)), np.zeros((0, n, n)))
        pi = np.concatenate(weights)
        return cls(config, np.abs(pi @ state.dx), np.abs(pi))

    def losses(self, end_shift: Array, mid_shift: Array, rate_shift: Array
               ) -> tuple[Array, Array]:
        """What each margin can lose to a position off by at most ``end_shift`` at the
        period's end and ``mid_shift`` at mid-period, per coordinate, and a rate off by at
        most ``rate_shift``: Σ_j |∂φ_i/∂x_j| s_j for a configuration margin, and
        Σ_j |(Π_k ẋ)_j| w_j + ½ wᵀ|Π_k|w for a velocity margin (exact for a constant Π_k).
        (At the period's end, every margin in the order of ``names``; at mid-period, the
        configuration ones.)"""
        velocity = self.push @ rate_shift + 0.5 * np.einsum(
            "kij,i,j->k", self.weights, rate_shift, rate_shift)
        return (np.concatenate((self.configuration @ end_shift, velocity)),
                self.configuration @ mid_shift)


def margin_losses(constraints: ConstraintSet, state: ArmState, bound: Array, period: float,
                  travel: float, slopes: MarginSlopes | None = None) -> tuple[Array, Array]:
    """What an acceleration error |d_j| ≤ ``bound``_j can take off each margin of
    ``constraints`` over one period (the module docstring): the position off by c h² ā at
    the end and ⅛h² ā at mid-period, the rate by h ā (:meth:`MarginSlopes.losses`;
    ``slopes`` at the state when the caller has them)."""
    h = period
    reach = slopes if slopes is not None else MarginSlopes.at(constraints, state)
    return reach.losses(travel * h * h * bound, 0.125 * h * h * bound, h * bound)


@dataclass(frozen=True)
class DeclaredError:
    """What the scenario declares its model and measurements may get wrong besides an
    acceleration bound (``simulation.model_error``), held by the safeguard.

    Attributes:
        inertia: e ∈ [0, 1), the relative error of every link's mass and rotational inertia
            (:class:`InertiaError`); the kinetic-energy limits the laws keep are lowered to
            Ω/(1 + e) by the scenario (the arm's energy ½ẋᵀDẋ ≤ (1 + e) ½ẋᵀD̂ẋ).
        armature, damping, friction: what the plant may add to each joint that the model
            does not have: rotor inertia [0, A] [kg·m²], viscous damping [0, c]
            [N·m·s/rad], dry friction [0, F] [N·m] (joint coordinates), or None.
        position: p̄, a bound on the error of each measured coordinate [rad or m], or None.
        velocity: v̄, a bound on the error of each measured rate [rad/s or m/s], or None
            (:func:`measurement_losses`).
    """

    inertia: float = 0.0
    armature: Array | None = None
    damping: Array | None = None
    friction: Array | None = None
    position: Array | None = None
    velocity: Array | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.inertia) and 0.0 <= self.inertia < 1.0):
            raise ValueError(f"inertia error must be in [0, 1), got {self.inertia}")
        for name in ("armature", "damping", "friction", "position", "velocity"):
            value = getattr(self, name)
            if value is not None and not (np.all(np.isfinite(value)) and np.all(
                    np.asarray(value) >= 0.0)):
                raise ValueError(f"{name} error must be finite and ≥ 0, got {value}")

    @property
    def dynamic(self) -> bool:
        """Whether an error of the dynamics is declared (:class:`InertiaError`)."""
        return bool(self.inertia) or any(
            v is not None for v in (self.armature, self.damping, self.friction))

    def acceleration_bound(self, model: RobotModel) -> InertiaError | None:
        """The bound on the acceleration error it makes, or None when none is declared."""
        if not self.dynamic:
            return None
        return InertiaError(model, self.inertia, self.armature, self.damping, self.friction)

    @property
    def measured(self) -> bool:
        """Whether a measurement error is declared."""
        return self.position is not None or self.velocity is not None


def _contracts(g: Array) -> bool:
    """Whether G ≥ 0 has spectral radius below 1: at once when a row or column sum bound
    says so, else from its eigenvalues."""
    if min(float(g.sum(axis=1).max()), float(g.sum(axis=0).max())) < 1.0:
        return True
    return float(np.max(np.abs(np.linalg.eigvals(g)))) < 1.0


def measurement_losses(constraints: ConstraintSet, state: ArmState, declared: DeclaredError,
                       period: float, slopes: MarginSlopes | None = None
                       ) -> tuple[Array, Array]:
    """What a measured state off by |x̃ − x| ≤ p̄, |ẋ̃ − ẋ| ≤ v̄ can hide of each margin of
    ``constraints`` at the period's end and mid-period (the order of ``margin_losses``).

    The guard predicts from the measured state; the true state's prediction differs by
    p̄ + t v̄ in position at time t into the period and by v̄ in rate. A configuration margin
    φ_i loses Σ_j |∂φ_i/∂x_j| (p̄_j + t v̄_j) to first order; a velocity margin
    ψ_k = ω_k − ½ẋᵀΠ_k ẋ, taken at the measured rate, exceeds the true one by at most
    Σ_j |(Π_k ẋ)_j| v̄_j + ½ v̄ᵀ|Π_k| v̄ (exact for a constant Π_k; the change of ω_k and Π_k
    with the position error is left out). Holding every measured margin at least that much
    above its cushion δ_i (a floor of its own beside (S1)'s, which is taken from the
    measured margin and so cannot carry (S1)'s induction to the true one) keeps the true
    margins above δ_i while the measurement errors stay inside the declared bounds (a
    Gaussian noise does not: declare a few σ and count the rest). ``slopes``: at the state,
    when the caller has them (:meth:`MarginSlopes.losses`)."""
    h, n = period, constraints.n
    p = np.zeros(n) if declared.position is None else np.broadcast_to(declared.position, (n,))
    v = np.zeros(n) if declared.velocity is None else np.broadcast_to(declared.velocity, (n,))
    reach = slopes if slopes is not None else MarginSlopes.at(constraints, state)
    return reach.losses(p + h * v, p + 0.5 * h * v, v)


class InertiaError:
    """The acceleration error of a declared error in the links' inertial parameters and of
    unmodelled joint terms (``simulation.model_error``: ``inertia``, ``armature``,
    ``damping``, ``friction``), at a state and a model acceleration.

    **The bound.** The dynamics are linear in each link's inertial parameters: link k's mass
    m_k (its centre of mass fixed, so its first moment m_k c_k scales with it) and its
    rotational inertia about the centre of mass I_k, each scaled by its own factor 1 + δ,
    |δ| ≤ e. Split link k's parameters into those two pieces p (Pinocchio's joint torque
    regressor Y(q, q̇, a) times the piece's ten parameters): w_p = Y(q, q̇, â) π_p = D_p â + b_p,
    D_p = J_kᵀ I_p J_k ⪰ 0. The plant may add, per joint, rotor inertia α_j ∈ [0, A_j],
    viscous damping up to c_j and dry friction up to F_j. Its D = D̂ + ΔD, b = b̂ + Δb with

        u = ΔD â + Δb = Σ_p δ_p w_p + α ⊙ â + f,     |f_j| ≤ c_j |q̇_j| + F_j,

    and with the same torque the accelerations differ by

        y = a − â = −D⁻¹ u = r − D̂⁻¹ ΔD y,     r = −D̂⁻¹ u,

    so |r| ≤ r̄ = e Σ_p |D̂⁻¹ w_p| + |D̂⁻¹| (A ⊙ |â| + c ⊙ |q̇| + F) and |y| ≤ r̄ + G|y| with
    G = e Σ_p |D̂⁻¹ D_p| + |D̂⁻¹| diag(A) ≥ |D̂⁻¹ΔD| entry by entry (|·| of each entry). When
    G's spectral radius is below 1, |y| ≤ (I − G)⁻¹ r̄ (the series Σ Gᵏ r̄, every term ≥ 0).
    Always, since D ⪰ (1 − e) D̂ (ΔD is the pieces' ±e share of D̂ plus α ≥ 0),
    |y_j| ≤ √(D⁻¹)_jj √(uᵀD⁻¹u) ≤ √(D̂⁻¹)_jj √(ūᵀ|D̂⁻¹|ū) / (1 − e) with ū ≥ |u| the same
    bound in torque; without added rotor inertia also −eD̂ ⪯ ΔD ⪯ eD̂, so in the norm
    ‖y‖ = √(yᵀD̂y): ‖y‖ ≤ ‖r‖/(1 − e) and |(D̂⁻¹ΔD y)_j| ≤ e √(D̂⁻¹)_jj ‖y‖, whence
    |y_j| ≤ r̄_j + e/(1 − e) √(D̂⁻¹)_jj √(r̄ᵀ|D̂|r̄). The smallest of these is ā. Computed in
    joint coordinates and carried to controller coordinates by |T|.

    It holds for the given model acceleration â: the guard takes the law's (the torque it
    keeps unless it must act); a brake's own inertia error only scales its deceleration
    (within ±e in the D̂ norm), which the braking set's share θ absorbs. The model's own
    smooth Coulomb friction is :func:`friction_error`'s; anything else the user bounds is
    ``acceleration``.

    Args:
        model: the controller's model.
        relative: e ∈ [0, 1).
        armature, damping, friction: A [kg·m²], c [N·m·s/rad], F [N·m] per joint (joint
            coordinates), or None.
    """

    def __init__(self, model: RobotModel, relative: float, armature: Array | None = None,
                 damping: Array | None = None, friction: Array | None = None) -> None:
        if not (math.isfinite(relative) and 0.0 <= relative < 1.0):
            raise ValueError(f"inertia error must be in [0, 1), got {relative}")
        self.model, self.relative = model, float(relative)
        n = model.n
        self._joint = [np.zeros(n) if v is None else np.broadcast_to(
            np.asarray(v, dtype=float), (n,)) for v in (armature, damping, friction)]
        pin_model = model.model
        self._data = pin_model.createData()
        bodies = len(pin_model.inertias) - 1
        pieces = np.zeros((10 * bodies, 2 * bodies))  # each link's mass and rotation pieces
        spatial = np.zeros((2 * bodies, 6, 6))  # each piece's spatial inertia, joint frame
        for k in range(bodies):
            link = pin_model.inertias[k + 1]
            mass = pin.Inertia(link.mass, link.lever, np.zeros((3, 3)))
            rotation = pin.Inertia(0.0, link.lever, link.inertia)
            pieces[10 * k:10 * k + 10, 2 * k] = mass.toDynamicParameters()
            pieces[10 * k:10 * k + 10, 2 * k + 1] = rotation.toDynamicParameters()
            spatial[2 * k], spatial[2 * k + 1] = mass.matrix(), rotation.matrix()
        self._pieces = pieces
        self._spatial = spatial
        self._jacobians = np.zeros((2 * bodies, 6, n))  # each piece's link's, joint frame

    def bound(self, state: ArmState, accel: Array) -> Array:
        """ā of the class docstring at ``state`` for the model acceleration ``accel``
        (controller coordinates), per coordinate."""
        e = self.relative
        coords = self.model.coordinates
        if coords.is_identity:
            q, dq, ddq, inertia = state.x, state.dx, accel, state.inertia
        else:
            t, t_inv = coords.matrix, coords.inverse
            q, dq, ddq = t_inv @ state.x, t_inv @ state.dx, t_inv @ accel
            inertia = t.T @ state.inertia @ t
        pin_model, data = self.model.model, self._data
        inv = np.asarray(np.linalg.inv(inertia), dtype=float)
        armature, damping, friction = self._joint
        joint_force = armature * np.abs(ddq) + damping * np.abs(dq) + friction  # ≥ |α â + f|
        first = np.abs(inv) @ joint_force
        spread = np.abs(inv) * armature  # |D̂⁻¹| diag(A)
        force = joint_force.copy()
        if e > 0.0:
            per_piece = pin.computeJointTorqueRegressor(pin_model, data, q, dq, ddq) @ (
                self._pieces)
            first += e * np.abs(inv @ per_piece).sum(axis=1)
            force += e * np.abs(per_piece).sum(axis=1)
            pin.computeJointJacobians(pin_model, data, q)
            jac = self._jacobians
            for k in range(len(jac) // 2):
                jac[2 * k] = jac[2 * k + 1] = pin.getJointJacobian(
                    pin_model, data, k + 1, pin.ReferenceFrame.LOCAL)
            # e Σ_p |D̂⁻¹ D_p|, D_p = J_kᵀ I_p J_k
            pieces = np.transpose(jac, (0, 2, 1)) @ (self._spatial @ jac)
            spread += e * np.abs(np.matmul(inv, pieces)).sum(axis=0)
        diag = np.sqrt(np.diag(inv))
        out = diag * math.sqrt(float(force @ np.abs(inv) @ force)) / (1 - e)
        if not np.any(armature):  # −eD̂ ⪯ ΔD ⪯ eD̂: |(D̂⁻¹ΔD y)_j| ≤ e √(D̂⁻¹)_jj ‖y‖_D̂
            out = np.minimum(out, first + e / (1 - e) * diag * math.sqrt(
                float(first @ np.abs(inertia) @ first)))
        if _contracts(spread):
            out = np.minimum(out, np.linalg.solve(np.eye(len(first)) - spread, first))
        return out if coords.is_identity else np.abs(coords.matrix) @ out
