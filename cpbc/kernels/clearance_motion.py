"""The clearance's sphere pairs one by one, with their motion: the CBF-QP peer's rows
(cpbc.peers.cbf_rows) and a point's curvature (cpbc.kernels.barriers.point_sphere_motion),
over the tables of cpbc.kernels.clearance."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import inner, kernel
from cpbc.kernels.clearance import (
    force_on_joints,
    pair_direction,
    sphere_centres,
    sphere_clearances,
    sphere_offsets,
)
from cpbc.kernels.views import Ints

# -- the pairs one by one, with their motion: the CBF-QP peer's rows --------------------------
# Along a motion with q̈ = 0 a sphere centre s, fixed on a link moved by the joints in
# ``supports``, has the twist V = Σ_k q̇_k J_k and the spatial acceleration A = Σ_k q̇_k J̇_k,
# J = [v; ω] Pinocchio's world joint Jacobian (at the world origin) and J̇_k = V_k ×ᵐ J_k
# with V_k the twist of joint k's own link (J_k ×ᵐ J_k = 0, so joint k may be counted in V_k;
# ×ᵐ the motion cross product [v₁; ω₁] ×ᵐ [v₂; ω₂] = [ω₁ × v₂ + v₁ × ω₂; ω₁ × ω₂]). Then
#
#     ṡ = V_v + V_ω × s,   s̈₀ = A_v + A_ω × s + V_ω × ṡ,                               (2)
#
# and with u = Rᵀ(s − c), u̇ = Rᵀṡ, ü = Rᵀs̈₀ (s₁ − s₂ for a self pair, R = I), the core
# distance d = ‖w‖, w = max(|u| − h, 0), has, in the face, edge or corner region u is in
# (A the components with |u_k| > h_k, where the Hessian of d is (I − n̂n̂ᵀ)/d),
#
#     d²φ/dt² = n̂ · ü + (‖u̇_A‖² − (n̂ · u̇)²)/d,   n̂ = sign(u) w / d.                    (1)
#
# φ is C¹ but only piecewise C² (the regions meet on planes): (1) is the curvature of the
# region u is in.


@kernel("void(float64[:, :], float64[:, :], float64[:], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :])")
def sphere_motion(centres: Array, jac: Array, dq: Array, supports: Array,
                  joint_supports: Array, vel: Array, acc: Array) -> None:
    """Each sphere centre's velocity ṡ and acceleration at q̈ = 0, s̈₀ (eq. 2), into ``vel``
    and ``acc`` (3, S), from the joint Jacobians ``jac`` (6, n) and rates ``dq``;
    ``joint_supports`` (n, n): 1 where joint i moves joint k's link (row k)."""
    n = dq.shape[0]
    drift = np.zeros((6, n))  # q̇_k J̇_k
    for k in range(n):
        v0 = v1 = v2 = w0 = w1 = w2 = 0.0  # V_k
        for i in range(n):
            if joint_supports[k, i] != 0.0:
                v0 += dq[i] * jac[0, i]
                v1 += dq[i] * jac[1, i]
                v2 += dq[i] * jac[2, i]
                w0 += dq[i] * jac[3, i]
                w1 += dq[i] * jac[4, i]
                w2 += dq[i] * jac[5, i]
        a0, a1, a2 = jac[0, k], jac[1, k], jac[2, k]
        b0, b1, b2 = jac[3, k], jac[4, k], jac[5, k]
        drift[0, k] = dq[k] * (w1 * a2 - w2 * a1 + v1 * b2 - v2 * b1)
        drift[1, k] = dq[k] * (w2 * a0 - w0 * a2 + v2 * b0 - v0 * b2)
        drift[2, k] = dq[k] * (w0 * a1 - w1 * a0 + v0 * b1 - v1 * b0)
        drift[3, k] = dq[k] * (w1 * b2 - w2 * b1)
        drift[4, k] = dq[k] * (w2 * b0 - w0 * b2)
        drift[5, k] = dq[k] * (w0 * b1 - w1 * b0)
    twist, accel = np.empty(6), np.empty(6)
    for s in range(centres.shape[1]):
        twist[:] = 0.0
        accel[:] = 0.0
        for k in range(n):
            if supports[s, k] != 0.0:
                for r in range(6):
                    twist[r] += dq[k] * jac[r, k]
                    accel[r] += drift[r, k]
        c0, c1, c2 = centres[0, s], centres[1, s], centres[2, s]
        w0, w1, w2 = twist[3], twist[4], twist[5]
        d0 = twist[0] + w1 * c2 - w2 * c1
        d1 = twist[1] + w2 * c0 - w0 * c2
        d2 = twist[2] + w0 * c1 - w1 * c0
        vel[0, s], vel[1, s], vel[2, s] = d0, d1, d2
        acc[0, s] = accel[0] + accel[4] * c2 - accel[5] * c1 + w1 * d2 - w2 * d1
        acc[1, s] = accel[1] + accel[5] * c0 - accel[3] * c2 + w2 * d0 - w0 * d2
        acc[2, s] = accel[2] + accel[3] * c1 - accel[4] * c0 + w0 * d1 - w1 * d0


@kernel("float64(float64[:, :], float64[:, :], float64[:], float64[:, :], int64[:, :], int64,"
        " float64[:, :], float64[:, :])")
def pair_curvature(u: Array, outside: Array, d: Array, obstacles: Array, pair_index: Ints,
                   p: int, vel: Array, acc: Array) -> float:
    """d²φ_p/dt² at q̈ = 0 (eq. 1) of pair p, d_p > 0, from its spheres' ``vel`` and ``acc``
    (``sphere_motion``)."""
    o, s, s2 = pair_index[p, 0], pair_index[p, 1], pair_index[p, 2]
    inv = 1.0 / d[p]
    along = across = normal_acc = 0.0
    for k in range(3):
        if o >= 0:  # u̇ = Rᵀṡ, ü = Rᵀs̈₀
            du = obstacles[o, k] * vel[0, s] + obstacles[o, 3 + k] * vel[1, s] + (
                obstacles[o, 6 + k] * vel[2, s])
            ddu = obstacles[o, k] * acc[0, s] + obstacles[o, 3 + k] * acc[1, s] + (
                obstacles[o, 6 + k] * acc[2, s])
        else:
            du, ddu = vel[k, s] - vel[k, s2], acc[k, s] - acc[k, s2]
        normal = math.copysign(outside[k, p], u[k, p]) * inv
        along += normal * du
        normal_acc += normal * ddu
        if outside[k, p] > 0.0:
            across += du * du
    return normal_acc + (across - along * along) * inv


@inner("int64(float64[:], int64[:], int64)")
def closest_pair(phi: Array, starts: Ints, g: int) -> int:
    """Reported constraint g's closest pair: the first smallest φ_p of its pairs, which start
    at ``starts[g]`` and run to the next start (numpy's argmin: a NaN is the first NaN)."""
    lo = starts[g]
    hi = starts[g + 1] if g + 1 < starts.shape[0] else phi.shape[0]
    best = lo
    for p in range(lo, hi):
        v = phi[p]
        if v != v:
            return p
        if v < phi[best]:
            best = p
    return best


@kernel("void(float64[:, :], float64[:, :], float64[:], int64[:], float64[:, :],"
        " float64[:, :], int64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        " float64[:], float64[:, :], float64[:])")
def sphere_pair_rows(y: Array, jac: Array, dq: Array, sphere_index: Ints, sphere_local: Array,
                     obstacles: Array, pair_index: Ints, pair_table: Array, supports: Array,
                     joint_supports: Array, phi: Array, grad: Array, curv: Array) -> None:
    """Every sphere pair on its own at the joint placements ``y``, joint Jacobians ``jac``
    (6, n) and rates ``dq``: its clearance φ_p = d_p − rsum_p into ``phi`` (P,), its gradient
    ∇φ_p = n̂_pᵀ J(s_p) (minus J(s₂) for a self pair; envelope theorem, ``force_on_joints``)
    into ``grad`` (P, n) and q̇ᵀ∇²φ_p q̇ (eq. 1, ``pair_curvature``) into ``curv`` (P,),
    joint coordinates. A centre inside a core (d_p = 0) has neither: zeros."""
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    centres = np.empty((3, n_sph))
    u, outside, d = np.empty((3, n_pair)), np.empty((3, n_pair)), np.empty(n_pair)
    sphere_centres(y, sphere_index, sphere_local, centres)
    sphere_offsets(centres, obstacles, pair_index, pair_table, u, outside, d)
    vel, acc = np.empty((3, n_sph)), np.empty((3, n_sph))
    sphere_motion(centres, jac, dq, supports, joint_supports, vel, acc)
    grad[:, :] = 0.0
    for p in range(n_pair):
        phi[p] = d[p] - pair_table[p, 3]
        curv[p] = 0.0
        if not d[p] > 0.0:
            continue
        o, s, s2 = pair_index[p, 0], pair_index[p, 1], pair_index[p, 2]
        inv = 1.0 / d[p]
        n0 = pair_direction(u, outside, obstacles, o, p, 0) * inv
        n1 = pair_direction(u, outside, obstacles, o, p, 1) * inv
        n2 = pair_direction(u, outside, obstacles, o, p, 2) * inv
        force_on_joints(centres, s, n0, n1, n2, supports, jac, 1.0, grad[p])
        if o < 0:
            force_on_joints(centres, s2, n0, n1, n2, supports, jac, -1.0, grad[p])
        curv[p] = pair_curvature(u, outside, d, obstacles, pair_index, p, vel, acc)


@kernel("void(float64[:, :], float64[:, :], float64[:], int64[:], float64[:, :],"
        " float64[:, :], int64[:, :], float64[:, :], float64[:, :], float64[:, :], int64[:],"
        " float64[:], float64[:, :], float64[:])")
def sphere_motion_terms(y: Array, jac: Array, dq: Array, sphere_index: Ints,
                        sphere_local: Array, obstacles: Array, pair_index: Ints,
                        pair_table: Array, supports: Array, joint_supports: Array,
                        starts: Ints, value: Array, grad: Array, curv: Array) -> None:
    """The sphere constraints' φ, ∇φ and q̇ᵀ∇²φ q̇ in one call (Clearance.motion_terms
    without capsule groups, joint coordinates): their reported clearances
    (``sphere_clearances``) into ``value``, and each one's closest pair's gradient and
    curvature (``sphere_pair_rows``, ``closest_pair``) into its row of ``grad`` and ``curv``
    — the steps of the calls apart, to the bit, without their ~5 µs of passing arrays
    (the aimed brake reads them at every period it is held)."""
    n_pair, n = pair_index.shape[0], dq.shape[0]
    phi, rows, bend = np.empty(n_pair), np.empty((n_pair, n)), np.empty(n_pair)
    sphere_pair_rows(y, jac, dq, sphere_index, sphere_local, obstacles, pair_index,
                     pair_table, supports, joint_supports, phi, rows, bend)
    for g in range(starts.shape[0]):
        p = closest_pair(phi, starts, g)
        curv[g] = bend[p]
        for j in range(n):
            grad[g, j] = rows[p, j]
    sphere_clearances(y, sphere_index, sphere_local, obstacles, pair_index, pair_table, value)


@kernel("void(float64[:, :], float64[:, :], int64[:], float64[:, :], float64[:, :],"
        " int64[:, :], float64[:, :], float64[:, :], int64[:], float64[:, :])")
def closest_pair_gradients(y: Array, jac: Array, sphere_index: Ints, sphere_local: Array,
                           obstacles: Array, pair_index: Ints, pair_table: Array,
                           supports: Array, starts: Ints, grad: Array) -> None:
    """Each reported sphere constraint's gradient, its closest pair's (``closest_pair``), into
    the rows of ``grad`` (C, n), joint coordinates: the rows of ``sphere_pair_rows`` that
    ``closest_pairs`` picks (the same steps), without every other pair's gradient and the
    curvature. (The pair's steps are written out here as there: a compiled helper taking
    the ten arrays, inlined or called, made both kernels 2.5 times slower.)"""
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    centres = np.empty((3, n_sph))
    u, outside, d = np.empty((3, n_pair)), np.empty((3, n_pair)), np.empty(n_pair)
    sphere_centres(y, sphere_index, sphere_local, centres)
    sphere_offsets(centres, obstacles, pair_index, pair_table, u, outside, d)
    phi = np.empty(n_pair)
    for p in range(n_pair):
        phi[p] = d[p] - pair_table[p, 3]
    grad[:, :] = 0.0
    for c in range(starts.shape[0]):
        p = closest_pair(phi, starts, c)
        if not d[p] > 0.0:
            continue
        o, s, s2 = pair_index[p, 0], pair_index[p, 1], pair_index[p, 2]
        inv = 1.0 / d[p]
        n0 = pair_direction(u, outside, obstacles, o, p, 0) * inv
        n1 = pair_direction(u, outside, obstacles, o, p, 1) * inv
        n2 = pair_direction(u, outside, obstacles, o, p, 2) * inv
        force_on_joints(centres, s, n0, n1, n2, supports, jac, 1.0, grad[c])
        if o < 0:
            force_on_joints(centres, s2, n0, n1, n2, supports, jac, -1.0, grad[c])


@kernel("void(float64[:], int64[:], int64[:])")
def closest_pairs(phi: Array, starts: Ints, out: Ints) -> None:
    """Each reported constraint's closest pair: the first smallest φ_p of its pairs, which
    start at ``starts`` and run to the next start (numpy's argmin per group: a NaN is the
    first NaN)."""
    for g in range(starts.shape[0]):
        out[g] = closest_pair(phi, starts, g)
