"""Second-order motion of clearance pairs: the drift term ẋᵀ∇²φ ẋ of a sphere pair.

For a pair of a sphere (centre s, fixed on its link) and an obstacle seen as a rounded box
(centre c, rotation R, core half-extents h), u = Rᵀ(s − c) and the core distance is
d(u) = ‖w‖, w = max(|u| − h, 0) (cpbc.constraints.clearance). Along a motion with q̈ = 0,

    d²φ/dt² = n̂ · ü + u̇ᵀ ∇²d u̇,   n̂ = sign(u) w / d,   ü = Rᵀ s̈₀,
    u̇ᵀ ∇²d u̇ = (‖u̇_A‖² − (n̂ · u̇)²) / d                                    (1)

with A the components where |u_k| > h_k (on the box's face, edge or corner region d is the
norm of those components only, whose Hessian is (I − n̂n̂ᵀ)/d there) and s̈₀ the sphere
centre's acceleration at q̈ = 0. Since φ is C¹ but only piecewise C² (the regions meet on
planes), (1) is the curvature of the region u is in. A self pair is the same with u = s₁ − s₂
(R = I, h = 0).

The centre's motion comes from Pinocchio's world joint Jacobian J = [v; ω] and its time
variation J̇ (both at the world origin): a link moved by the joints in ``supports`` has the
twist V = J (supports ∘ q̇) and, at q̈ = 0, the spatial acceleration A = J̇ (supports ∘ q̇), so
that a point s on it moves with

    ṡ = V_v + V_ω × s,   s̈₀ = A_v + A_ω × s + V_ω × ṡ.                          (2)
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array


def point_motion(jac: Array, djac: Array, supports: Array, dq: Array, points: Array
                 ) -> tuple[Array, Array]:
    """Velocities ṡ and drift accelerations s̈₀ (eq. 2) of points fixed on links.

    Args:
        jac, djac: Pinocchio's world joint Jacobian and its time variation, (6, n).
        supports: (S, n), 1 where joint k moves point s's link.
        dq: joint velocities (n,).
        points: world positions (S, 3).

    Returns:
        ṡ and s̈₀, each (S, 3).
    """
    moving = supports * dq  # (S, n)
    twist = moving @ jac.T  # (S, 6)
    accel = moving @ djac.T
    omega = twist[:, 3:]
    vel = twist[:, :3] + np.cross(omega, points)
    acc = accel[:, :3] + np.cross(accel[:, 3:], points) + np.cross(omega, vel)
    return vel, acc


def rounded_box_curvature(u: Array, du: Array, ddu: Array, half: Array) -> Array:
    """d²d/dt² of the core distance at q̈ = 0 (eq. 1), per pair; 0 where u is inside a core.

    Args:
        u, du, ddu: the pairs' offsets in the obstacles' frames and their first and (drift)
            second time derivatives, each (3, P).
        half: core half-extents (3, P).
    """
    outside = np.maximum(np.abs(u) - half, 0.0)
    d = np.sqrt(np.sum(outside * outside, axis=0))
    safe = np.where(d > 0.0, d, 1.0)
    normal = np.copysign(outside, u) / safe
    active = outside > 0.0
    along = np.sum(normal * du, axis=0)
    across = np.sum(np.where(active, du * du, 0.0), axis=0) - along * along
    out = np.sum(normal * ddu, axis=0) + across / safe
    return np.where(d > 0.0, out, 0.0)
