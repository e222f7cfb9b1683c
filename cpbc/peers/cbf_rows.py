"""The rows of the CBF-QP peer (cpbc.peers.cbf_qp): lower ≤ A τ ≤ upper, one per barrier.

With ẍ = D⁻¹(τ − b), b = C ẋ + g + f (eq. 6.1), a configuration constraint φ has

    φ̇ = ∇φ ẋ,   φ̈ = r τ − r b + κ,   r = ∇φ D⁻¹,   κ = ẋᵀ∇²φ ẋ                    (1)

(φ, ∇φ and κ from ``ConfigurationConstraint.motion_terms`` at the per-step state; per
sphere pair for a clearance, ``Clearance.sphere_pairs_at``: the compiled kernel
cpbc.kernels.clearance_motion.sphere_pair_rows, from the state's joint placements and Jacobians
with the pair formulas the law's kernels use; for a point outside a sphere the kernel
cpbc.kernels.barriers.point_sphere_motion, from the state's frame and joint Jacobians, which
the peer's state carries (``Controller.reads_motion``) — no Pinocchio pass of the rows'
own). Two variants:

``braking`` (what a practitioner builds today): a high-order CBF with the torque box in mind,

    ψ₁ = φ̇ + α(φ),   α(φ) = √(2ā(φ + ε)) − √(2āε),   ψ̇₁ ≥ −γ ψ₁                   (2)

so that ψ₁ ≥ 0 says "the margin left can still absorb the approach speed at deceleration ā".
ā is a share β of the deceleration of φ the box can produce against the drift,
ā = β (Σ_j |r_j| L_j − |r b|) (floored at β/20 Σ_j |r_j| L_j), frozen over the step; ε =
ā/(2k²) makes α'(0) = k, so near the boundary (2) is the exponential CBF with poles k and γ,
and far from it the braking curve. Without a torque box α(φ) = kφ (the limit ā → ∞).

``exponential`` (the earlier in-project filter): φ̈ + 2kφ̇ + k²φ ≥ 0.

Rate bounds |aᵀẋ| < B, both variants: two first-order rows d/dt(B − c ∓ aᵀẋ) ≥
−γ(B − c ∓ aᵀẋ) with a cushion c (0 in the exponential variant) against the change of the
drift over a held period. A kinetic-energy limit ψ = Ω − ½ẋᵀDẋ: ψ̇ = −ẋᵀ(τ − g − f) ≥ −γψ
(Property 6.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.rate_limit import RateLimit
from cpbc.errors import ConstraintViolation
from cpbc.model.robot_model import ArmState


@dataclass(frozen=True)
class Tuning:
    """The filter's tuning (cpbc.peers.cbf_qp documents the defaults).

    Attributes:
        variant: ``braking`` or ``exponential``.
        gain: k [1/s].
        rate_gain: γ [1/s].
        braking_share: β ∈ (0, 1].
        rate_cushion: c [rad/s or m/s].
        torque_limit: L per joint, or None.
    """

    variant: str
    gain: float
    rate_gain: float
    braking_share: float
    rate_cushion: float
    torque_limit: Array | None


@dataclass(frozen=True)
class Rows:
    """lower ≤ a τ ≤ upper, a (m, n); ``soft`` marks the configuration rows (relative
    degree two), the ones a slack relaxes first."""

    a: Array
    lower: Array
    upper: Array
    soft: NDArray[np.bool_]


def _configuration_rows(c: ConfigurationConstraint, state: ArmState, per_pair: bool
                         ) -> tuple[Array, Array, Array]:
    """φ, ∇φ and κ of a constraint's rows at the per-step state: one per moving sphere pair
    within the influence distance for a clearance (with ``per_pair``), else its reported
    constraints (``motion_terms``)."""
    if per_pair and isinstance(c, Clearance):
        phi, grad, curv, moving = c.sphere_pairs_at(state)
        if phi.size and not phi.min() > 0:
            _violation(c, c.motion_terms(state)[0])
        keep = moving & (phi < (c.influence or np.inf))
        if c.sphere_count == len(c.names):  # spheres only: nothing reported besides
            return phi[keep], grad[keep], curv[keep]
        full_phi, full_grad, full_curv = c.motion_terms(state)
        rest = slice(c.sphere_count, len(c.names))  # capsule primitives, as reported
        return (np.concatenate([phi[keep], full_phi[rest]]),
                np.vstack([grad[keep], full_grad[rest]]),
                np.concatenate([curv[keep], full_curv[rest]]))
    phi, grad, curv = c.motion_terms(state)
    if not np.all(phi > 0):  # outside S, as the laws refuse it
        _violation(c, phi)
    return phi, grad, curv


def _violation(c: ConfigurationConstraint, phi: Array) -> None:
    i = int(np.argmin(np.where(np.isnan(phi), -np.inf, phi)))
    raise ConstraintViolation(c.names[i], float(phi[i]))


def _lower_bound(t: Tuning, phi: Array, rate: Array, r: Array, bias: Array, curv: Array
                 ) -> Array:
    """The least r τ each configuration row allows (module docstring, eqs. 1 and 2)."""
    k = t.gain
    drift = bias - curv  # r τ − φ̈ at this state
    if t.variant == "exponential":
        return drift - 2 * k * rate - k * k * phi
    g = t.rate_gain
    if t.torque_limit is None:
        return drift - k * rate - g * (rate + k * phi)
    reach = np.abs(r) @ t.torque_limit
    decel = t.braking_share * np.maximum(reach - np.abs(bias), 0.05 * reach) + 1e-12
    eps = decel / (2 * k * k)
    root = np.sqrt(2 * decel * (phi + eps))
    alpha = root - np.sqrt(2 * decel * eps)
    slope = decel / root  # α'(φ)
    return drift - slope * rate - g * (rate + alpha)


def barrier_rows(t: Tuning, constraints: ConstraintSet, state: ArmState) -> Rows:
    """Every barrier row at the state (module docstring); rows scaled to unit ‖a_i‖."""
    x, dx = state.x, state.dx
    inv = np.linalg.inv(state.inertia)
    b = state.coriolis_force + state.gravity + state.dissipation
    a_rows, lower, upper = [], [], []
    for c in constraints.configuration:
        phi, grad, curv = _configuration_rows(c, state, t.variant == "braking")
        r = grad @ inv
        a_rows.append(r)
        lower.append(_lower_bound(t, phi, grad @ dx, r, r @ b, curv))
        upper.append(np.full(len(phi), np.inf))
    configuration = sum(len(r) for r in a_rows)
    g = t.rate_gain
    for v in constraints.velocity:
        if isinstance(v, RateLimit):
            rate, r = v.rows @ dx, v.rows @ inv
            room = v.bounds - t.rate_cushion
            a_rows.append(r)
            lower.append(r @ b - g * (room + rate))
            upper.append(r @ b + g * (room - rate))
        else:  # kinetic energy: ẋᵀτ ≤ ẋᵀ(g + f) + γψ
            a_rows.append(dx[None, :])
            lower.append(np.array([-np.inf]))
            upper.append(np.atleast_1d(dx @ (state.gravity + state.dissipation)
                                       + g * v.value(x, dx, state)))
    n = len(x)
    if not a_rows:
        return Rows(np.zeros((0, n)), np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool))
    a = np.vstack(a_rows)
    scale = 1.0 / np.maximum(np.linalg.norm(a, axis=1), 1e-12)
    soft = np.arange(len(a)) < configuration
    return Rows(a * scale[:, None], np.concatenate(lower) * scale,
                np.concatenate(upper) * scale, soft)
