"""The clearance's sphere pairs (cpbc.constraints.clearance): every sphere primitive against
every obstacle as a rounded box, and in self pairs, and the localised barrier of the pairs.

The tables these read are packed once, when the ``Clearance`` is built
(``Spheres``, cpbc.constraints.clearance.spheres):

- ``sphere_index`` (S,): the first column of the sphere's joint in Pinocchio's static
  regressor Y = [t_1 R_1 … t_m R_m]/M; ``sphere_local`` (S, 4): M·[1, l] with l the
  sphere's centre in its joint's frame, so that the centre is Y[:, j:j+4] @ sphere_local[s];
- ``obstacles`` (O, 12): each obstacle's core (geometry.RoundedBox) as its rotation R,
  row-major, then its centre c;
- ``pair_index`` (P, 4): each pair's obstacle (−1 for a self pair), its sphere, its second
  sphere (−1 against an obstacle) and its reported constraint;
- ``pair_table`` (P, 6): each pair's core half-extents h (3), rsum (sphere radius +
  rounding, or both radii, + margin), rsum_law (rsum, −∞ for a pair that cannot move when
  ℓ is given) and moving (1.0, or 0.0 for a pair that cannot move).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.views import Ints, float_rows


@inner("void(float64[:, :], int64[:], float64[:, :], float64[:, :])")
def sphere_centres(y: Array, sphere_index: Ints, sphere_local: Array, centres: Array) -> None:
    """The sphere centres (3, S) from the static regressor ``y``: s = M (t_j + R_j l)."""
    for s in range(sphere_index.shape[0]):
        j = sphere_index[s]
        a, b, c, e = sphere_local[s, 0], sphere_local[s, 1], sphere_local[s, 2], sphere_local[s, 3]
        for i in range(3):
            centres[i, s] = y[i, j] * a + y[i, j + 1] * b + y[i, j + 2] * c + y[i, j + 3] * e


@kernel("void(float64[:, :], float64[:, :], int64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:])")
def sphere_offsets(centres: Array, obstacles: Array, pair_index: Ints, pair_table: Array,
                   u: Array, outside: Array, d: Array) -> None:
    """Each pair's offset u = Rᵀ(s − c) in its obstacle's frame (s − s₂ for a self pair),
    max(|u| − h, 0) and the core distance d = ‖max(|u| − h, 0)‖ (geometry.RoundedBox: the
    clearance is d − rsum), into ``u``, ``outside`` (3, P) and ``d`` (P,)."""
    for p in range(pair_index.shape[0]):
        o, s = pair_index[p, 0], pair_index[p, 1]
        if o >= 0:
            r0 = centres[0, s] - obstacles[o, 9]
            r1 = centres[1, s] - obstacles[o, 10]
            r2 = centres[2, s] - obstacles[o, 11]
            for k in range(3):
                u[k, p] = obstacles[o, k] * r0 + obstacles[o, 3 + k] * r1 + (
                    obstacles[o, 6 + k] * r2)
        else:
            s2 = pair_index[p, 2]
            for k in range(3):
                u[k, p] = centres[k, s] - centres[k, s2]
        sq = 0.0
        for k in range(3):
            e = abs(u[k, p]) - pair_table[p, k]
            e = e if e > 0.0 else 0.0
            outside[k, p] = e
            sq += e * e
        d[p] = math.sqrt(sq)


@kernel("void(float64[:, :], float64[:], int64[:, :], float64[:, :], float64[:])")
def sphere_values(u: Array, d: Array, pair_index: Ints, pair_table: Array, value: Array
                  ) -> None:
    """The reported clearance of each sphere constraint, the smallest of its pairs' φ_p =
    d_p − rsum_p (a centre inside a core box: its signed depth max_k(|u_k| − h_k) − rsum_p),
    NaN if any is, into ``value`` (its first entries, one per constraint)."""
    filled = -1
    for p in range(pair_index.shape[0]):
        c = pair_index[p, 3]
        if d[p] > 0.0:
            phi = d[p] - pair_table[p, 3]
        else:
            depth = abs(u[0, p]) - pair_table[p, 0]
            for k in range(1, 3):
                e = abs(u[k, p]) - pair_table[p, k]
                if e > depth or e != e:
                    depth = e
            phi = depth - pair_table[p, 3]
        if c > filled:  # the pairs of a constraint are neighbours
            value[c] = phi
            filled = c
        elif phi < value[c] or phi != phi:
            value[c] = phi


@inner("UniTuple(float64, 2)(float64, float64)")
def localised(phi: float, inv_ell: float) -> tuple[float, float]:
    """The localised barrier φ̃ = ℓ σ(φ/ℓ), σ(u) = 1 − (1 − min(u, 1))³
    (cpbc.constraints.clearance.Clearance): returns φ̃/ℓ and (dφ̃/dφ)/φ̃ · ℓ/3, i.e. with
    v = 1 − min(φ/ℓ, 1), 1 − v³ and v²/(1 − v³) (factor 1, slope 0 beyond ℓ)."""
    v = phi * inv_ell
    v = 1.0 - (v if v < 1.0 else 1.0)
    slope = v * v
    factor = 1.0 - slope * v
    return factor, slope / factor


@kernel("void(float64[:], float64, float64[:], float64[:])")
def localised_terms(phi: Array, ell: float, shaped: Array, ratio: Array) -> None:
    """φ̃ and (dφ̃/dφ)/φ̃ of every clearance in ``phi`` (``localised``)."""
    inv_ell = 1.0 / ell
    for p in range(phi.shape[0]):
        factor, slope = localised(phi[p], inv_ell)
        shaped[p] = ell * factor
        ratio[p] = 3.0 * inv_ell * slope


@inner("float64(float64[:], float64[:, :])")
def smallest_law_clearance(d: Array, pair_table: Array) -> float:
    """min_p d_p − rsum_law_p (∞ on a pair that cannot move, ℓ given); NaN if any is."""
    low = math.inf
    for p in range(d.shape[0]):
        phi = d[p] - pair_table[p, 4]
        if phi != phi:
            return phi
        if phi < low:
            low = phi
    return low


@inner("float64(float64[:, :], float64[:, :], float64[:, :], int64, int64, int64)")
def pair_direction(u: Array, outside: Array, obstacles: Array, o: int, p: int, i: int
                   ) -> float:
    """Component i of pair p's direction in the world, R sign(u) max(|u| − h, 0) = d n̂
    (obstacle ``o``; sign(u) max(|u| − h, 0) for a self pair, ``o`` < 0): the unit normal
    n̂ from the obstacle's core to the sphere's centre, times the core distance d."""
    if o < 0:
        return math.copysign(outside[i, p], u[i, p])
    f = 0.0
    for k in range(3):
        f += obstacles[o, 3 * i + k] * math.copysign(outside[k, p], u[k, p])
    return f


@kernel("void(float64[:, :], float64[:, :], float64[:], float64[:, :], int64[:, :],"
        " float64[:, :], float64, float64[:], float64[:, :])")
def pair_forces(u: Array, outside: Array, d: Array, obstacles: Array, pair_index: Ints,
                pair_table: Array, ell: float, phi_out: Array, force: Array) -> None:
    """Each moving pair's factor of φ̃ (φ̃_p/ℓ, ``localised``; φ_p without ℓ, ``ell`` 0)
    multiplied into its constraint's entry of ``phi_out`` (which holds 1 there), and its
    force (dφ̃_p/dφ_p)/φ̃_p n̂_p, n̂_p = R sign(u) max(|u| − h, 0)/d the pair's unit normal
    in the world, added to its sphere's column of ``force`` (3, S) (subtracted from the
    second sphere's for a self pair)."""
    inv_ell = 1.0 / ell if ell > 0.0 else 0.0
    w = 3.0 * inv_ell if ell > 0.0 else 1.0
    for p in range(pair_index.shape[0]):
        if pair_table[p, 5] == 0.0:
            continue  # a pair that cannot move: a constant factor, in far_phi
        phi = d[p] - pair_table[p, 4]
        factor, slope = localised(phi, inv_ell) if ell > 0.0 else (phi, 1.0 / phi)
        phi_out[pair_index[p, 3]] *= factor
        if slope == 0.0:
            continue
        slope *= w / d[p]
        o, s, s2 = pair_index[p, 0], pair_index[p, 1], pair_index[p, 2]
        for i in range(3):
            f = slope * pair_direction(u, outside, obstacles, o, p, i)
            force[i, s] += f
            if o < 0:
                force[i, s2] -= f


@inner("void(float64[:, :], int64, float64, float64, float64, float64[:, :],"
        " float64[:, :], float64, float64[:])")
def force_on_joints(centres: Array, s: int, f0: float, f1: float, f2: float,
                    supports: Array, jac: Array, sign: float, b: Array) -> None:
    """b_k += sign · fᵀ J_k(s) for the joints k that move sphere s: a force f at a point s
    fixed on a link drives joint k by fᵀ(v_k + ω_k × s) = fᵀv_k + (s × f)ᵀω_k, J = [v; ω]
    Pinocchio's world joint Jacobian (6, n). With f = n̂ it is the pair's gradient row
    n̂ᵀ J(s) (envelope theorem)."""
    c0, c1, c2 = centres[0, s], centres[1, s], centres[2, s]
    m0, m1, m2 = c1 * f2 - c2 * f1, c2 * f0 - c0 * f2, c0 * f1 - c1 * f0  # s × f
    for k in range(b.shape[0]):
        if supports[s, k] != 0.0:
            b[k] += sign * (jac[0, k] * f0 + jac[1, k] * f1 + jac[2, k] * f2
                            + jac[3, k] * m0 + jac[4, k] * m1 + jac[5, k] * m2)


@kernel("void(float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:])")
def forces_on_joints(centres: Array, force: Array, supports: Array, jac: Array, b: Array
                     ) -> None:
    """b_k = Σ_s f_sᵀ J_k(s) over the spheres joint k moves (``force_on_joints``). A sphere
    without force (no pair of it within ℓ, the most of them) adds nothing and is skipped."""
    for k in range(b.shape[0]):
        b[k] = 0.0
    for s in range(centres.shape[1]):
        f0, f1, f2 = force[0, s], force[1, s], force[2, s]
        if f0 == 0.0 and f1 == 0.0 and f2 == 0.0:
            continue
        force_on_joints(centres, s, f0, f1, f2, supports, jac, 1.0, b)


@kernel("float64(float64[:, :], float64[:, :], int64[:], float64[:, :], float64[:, :],"
        f" int64[:, :], float64[:, :], float64[:, :], {READ_ONLY}, float64, float64[:],"
        " float64[:], float64[:])")
def sphere_barrier(y: Array, jac: Array, sphere_index: Ints, sphere_local: Array,
                   obstacles: Array, pair_index: Ints, pair_table: Array, supports: Array,
                   far_phi: Array, ell: float, phi_out: Array, b: Array, value: Array
                   ) -> float:
    """The sphere pairs' part of the law's log-barrier terms at the joint placements ``y``
    and joint Jacobians ``jac`` (6, n) (Pinocchio's world J = [v; ω]).

    Returns the smallest law clearance (``smallest_law_clearance``). Only when it is > 0
    and, with an influence distance ℓ (``ell``; 0 for none), < ℓ, are ``phi_out`` and ``b``
    written: φ̃ of every constraint (the sphere constraints' the product of their pairs'
    factors times ``far_phi``, the others ``far_phi``) and b = Σ_p ∇φ̃_p/φ̃_p, the gradient
    by the envelope theorem, ∇φ_p = n̂_pᵀ J(s_p) (minus J(s₂) for a self pair). With a
    non-empty ``value`` the reported clearances are written to it (``sphere_values``)
    whatever the answer.
    """
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    work = np.empty(6 * n_sph + 7 * n_pair)  # one allocation for the five arrays
    centres, force = float_rows(work, 0, 3, n_sph), float_rows(work, 3 * n_sph, 3, n_sph)
    at = 6 * n_sph
    u, outside = float_rows(work, at, 3, n_pair), float_rows(work, at + 3 * n_pair, 3, n_pair)
    d = work[at + 6 * n_pair:]
    sphere_centres(y, sphere_index, sphere_local, centres)
    sphere_offsets(centres, obstacles, pair_index, pair_table, u, outside, d)
    if value.shape[0] > 0:
        sphere_values(u, d, pair_index, pair_table, value)
    low = smallest_law_clearance(d, pair_table)
    if not low > 0.0 or (ell > 0.0 and not low < ell):
        return low
    stop = pair_index[n_pair - 1, 3] + 1  # the sphere constraints come first
    phi_out[:stop] = 1.0
    phi_out[stop:] = far_phi[stop:]
    force[:, :] = 0.0
    pair_forces(u, outside, d, obstacles, pair_index, pair_table, ell, phi_out, force)
    for c in range(stop):
        phi_out[c] *= far_phi[c]
    forces_on_joints(centres, force, supports, jac, b)
    return low


@kernel("void(float64[:, :], int64[:], float64[:, :], float64[:, :], int64[:, :],"
        " float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:])")
def sphere_geometry(y: Array, sphere_index: Ints, sphere_local: Array, obstacles: Array,
                    pair_index: Ints, pair_table: Array, centres: Array, u: Array,
                    outside: Array, d: Array) -> None:
    """The sphere centres, the pairs' u, max(|u| − h, 0) and d at the joint placements ``y``
    (``sphere_centres``, ``sphere_offsets``), for the gradients and the curvature."""
    sphere_centres(y, sphere_index, sphere_local, centres)
    sphere_offsets(centres, obstacles, pair_index, pair_table, u, outside, d)


@kernel("void(float64[:, :], int64[:], float64[:, :], float64[:, :], int64[:, :],"
        " float64[:, :], float64[:])")
def sphere_clearances(y: Array, sphere_index: Ints, sphere_local: Array, obstacles: Array,
                      pair_index: Ints, pair_table: Array, value: Array) -> None:
    """The reported clearances of the sphere constraints at the joint placements ``y``
    (``sphere_values``), into ``value``."""
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    centres = np.empty((3, n_sph))
    u, outside, d = np.empty((3, n_pair)), np.empty((3, n_pair)), np.empty(n_pair)
    sphere_centres(y, sphere_index, sphere_local, centres)
    sphere_offsets(centres, obstacles, pair_index, pair_table, u, outside, d)
    sphere_values(u, d, pair_index, pair_table, value)


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
