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
  ℓ is given) and moving (1.0, or 0.0 for a pair that cannot move);
- ``group_index`` (G, 5), ``group_table`` (G, 6), the law's broad phase: the pairs of one
  reported constraint form a group, [first pair, one past its last, obstacle (−1: self
  pairs, never skipped), its joint's first column of Y, the first group of the same spheres
  (whose point it reads)] and [M·[1, l_c], r, reach]: l_c in the joint's frame within r of
  the group's sphere centres, reach = r + the largest rsum_law + an allowance for rounding.
  Every pair p of the group has d_p − rsum_law_p ≥ d(c) − reach (triangle inequality), d(c)
  the core distance of the point c: when that is > ℓ, all are beyond ℓ (``near_groups``);
- ``reach`` (C, n): how far each reported constraint's clearance can move per unit of each
  joint (cpbc.constraints.clearance.kinematics), which bounds it near a configuration where
  it is known (``travel``).

In a constraint set's plan (cpbc.kernels.barrier_set) the pairs are the kind ``SPHERES``:
``pack_sphere_pairs`` packs these tables, ``sphere_pairs_row`` reads them back.
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.plan_tables import Packed, float_table, int_table
from cpbc.kernels.views import Bools, Ints, float_rows

SPHERES = 4  # the kind's code in a set's plan (cpbc.kernels.barrier_set's registry)
# its float tables, then its int tables (the module docstring's; ``far`` a column, ``ell``
# ℓ (1, 1), 0 for none; ``sphere_index`` a column)
SPHERE_LOCAL, OBSTACLES, PAIR_TABLE, SUPPORTS, FAR_PHI, ELL, GROUP_TABLE, REACH = range(8)
SPHERE_INDEX, PAIR_INDEX, GROUP_INDEX = range(3)
# [m] the allowance for rounding of a bound by ``travel``: far above that of a clearance
# computed at two configurations (~1e-15 m at an arm's scale), far below any cushion
MOVED_ROUNDING = 1e-9


@inner("UniTuple(float64, 3)(float64[:, :], int64, float64[:, :], int64)")
def link_point(y: Array, j: int, local: Array, row: int) -> tuple[float, float, float]:
    """The point M (t_j + R_j l) fixed on joint j's link, ``local[row, :4]`` = M·[1, l],
    from the static regressor ``y`` (its first column of the joint, j)."""
    a, b, c, e = local[row, 0], local[row, 1], local[row, 2], local[row, 3]
    return (y[0, j] * a + y[0, j + 1] * b + y[0, j + 2] * c + y[0, j + 3] * e,
            y[1, j] * a + y[1, j + 1] * b + y[1, j + 2] * c + y[1, j + 3] * e,
            y[2, j] * a + y[2, j + 1] * b + y[2, j + 2] * c + y[2, j + 3] * e)


@inner("void(float64[:, :], int64[:], float64[:, :], float64[:, :])")
def sphere_centres(y: Array, sphere_index: Ints, sphere_local: Array, centres: Array) -> None:
    """The sphere centres (3, S) from the static regressor ``y``: s = M (t_j + R_j l)."""
    for s in range(sphere_index.shape[0]):
        centres[0, s], centres[1, s], centres[2, s] = link_point(y, sphere_index[s],
                                                                 sphere_local, s)


@inner("UniTuple(float64, 7)(float64, float64, float64, float64[:, :], int64, float64[:, :],"
       " int64)")
def core_offset(r0: float, r1: float, r2: float, obstacles: Array, o: int, pair_table: Array,
                p: int) -> tuple[float, float, float, float, float, float, float]:
    """For r = s − c, a point's offset from obstacle ``o``'s core centre (from the other
    sphere's centre for ``o`` < 0): u = Rᵀr in the obstacle's frame (r for o < 0),
    max(|u| − h, 0) with h pair p's half-extents, and the core distance
    d = ‖max(|u| − h, 0)‖ (geometry.RoundedBox: the clearance is d − rsum)."""
    if o >= 0:
        u0 = obstacles[o, 0] * r0 + obstacles[o, 3] * r1 + obstacles[o, 6] * r2
        u1 = obstacles[o, 1] * r0 + obstacles[o, 4] * r1 + obstacles[o, 7] * r2
        u2 = obstacles[o, 2] * r0 + obstacles[o, 5] * r1 + obstacles[o, 8] * r2
    else:
        u0, u1, u2 = r0, r1, r2
    e0, e1, e2 = abs(u0) - pair_table[p, 0], abs(u1) - pair_table[p, 1], abs(u2) - pair_table[p, 2]
    e0 = e0 if e0 > 0.0 else 0.0
    e1 = e1 if e1 > 0.0 else 0.0
    e2 = e2 if e2 > 0.0 else 0.0
    return u0, u1, u2, e0, e1, e2, math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@inner("void(float64[:, :], float64[:, :], int64[:, :], float64[:, :], float64[:, :],"
       " float64[:, :], float64[:], int64)")
def pair_offset(centres: Array, obstacles: Array, pair_index: Ints, pair_table: Array,
                u: Array, outside: Array, d: Array, p: int) -> None:
    """Pair p's u, max(|u| − h, 0) and d (``core_offset``) into column p of ``u``,
    ``outside`` (3, P) and ``d`` (P,)."""
    o, s = pair_index[p, 0], pair_index[p, 1]
    if o >= 0:
        r0 = centres[0, s] - obstacles[o, 9]
        r1 = centres[1, s] - obstacles[o, 10]
        r2 = centres[2, s] - obstacles[o, 11]
    else:
        s2 = pair_index[p, 2]
        r0 = centres[0, s] - centres[0, s2]
        r1 = centres[1, s] - centres[1, s2]
        r2 = centres[2, s] - centres[2, s2]
    u[0, p], u[1, p], u[2, p], outside[0, p], outside[1, p], outside[2, p], d[p] = (
        core_offset(r0, r1, r2, obstacles, o, pair_table, p))


@kernel("void(float64[:, :], float64[:, :], int64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:])")
def sphere_offsets(centres: Array, obstacles: Array, pair_index: Ints, pair_table: Array,
                   u: Array, outside: Array, d: Array) -> None:
    """Every pair's u, max(|u| − h, 0) and d (``pair_offset``) into ``u``, ``outside``
    (3, P) and ``d`` (P,)."""
    for p in range(pair_index.shape[0]):
        pair_offset(centres, obstacles, pair_index, pair_table, u, outside, d, p)


@kernel("void(float64[:, :], int64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        " float64, float64[:], float64[:, :])", inline=True)
def near_groups(y: Array, group_index: Ints, group_table: Array, obstacles: Array,
                pair_table: Array, limit: float, near: Array, points: Array) -> None:
    """The law's broad phase: ``near[g]`` 0.0 when every pair of group g is beyond ``limit``
    (ℓ) — d(c) − reach > ℓ for its bounding point c (module doc), in column g of ``points``
    (3, G) or of the earlier group it shares it with — else 1.0; 1.0 for every group of
    self pairs, and for all with ``limit`` ∞. A NaN state never skips."""
    for g in range(group_index.shape[0]):
        o, h = group_index[g, 2], group_index[g, 4]
        near[g] = 1.0
        if o < 0 or limit == math.inf:
            continue
        if h == g:
            points[0, g], points[1, g], points[2, g] = link_point(y, group_index[g, 3],
                                                                  group_table, g)
        dist = core_offset(points[0, h] - obstacles[o, 9], points[1, h] - obstacles[o, 10],
                           points[2, h] - obstacles[o, 11], obstacles, o, pair_table,
                           group_index[g, 0])[6]
        if dist - group_table[g, 5] > limit:
            near[g] = 0.0


@inner("float64(float64[:, :], float64[:], float64[:, :], int64)")
def pair_clearance(u: Array, d: Array, pair_table: Array, p: int) -> float:
    """Pair p's reported clearance φ_p = d_p − rsum_p (a centre inside a core box: its
    signed depth max_k(|u_k| − h_k) − rsum_p), from its ``pair_offset``."""
    if d[p] > 0.0:
        return d[p] - pair_table[p, 3]
    depth = abs(u[0, p]) - pair_table[p, 0]
    for k in range(1, 3):
        e = abs(u[k, p]) - pair_table[p, k]
        if e > depth or e != e:
            depth = e
    return depth - pair_table[p, 3]


@kernel("void(float64[:, :], float64[:], int64[:, :], float64[:, :], float64[:])")
def sphere_values(u: Array, d: Array, pair_index: Ints, pair_table: Array, value: Array
                  ) -> None:
    """The reported clearance of each sphere constraint, the smallest of its pairs' φ_p
    (``pair_clearance``), NaN if any is, into ``value`` (its first entries, one per
    constraint)."""
    filled = -1
    for p in range(pair_index.shape[0]):
        c = pair_index[p, 3]
        phi = pair_clearance(u, d, pair_table, p)
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


@inner("float64(float64[:], float64[:, :], int64[:, :], float64[:])")
def smallest_law_clearance(d: Array, pair_table: Array, group_index: Ints, near: Array
                           ) -> float:
    """min_p d_p − rsum_law_p (∞ on a pair that cannot move, ℓ given) over the pairs of the
    near groups (``near_groups``; ∞ when there are none); NaN if any is."""
    low = math.inf
    for g in range(group_index.shape[0]):
        if near[g] == 0.0:
            continue
        for p in range(group_index[g, 0], group_index[g, 1]):
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
        " float64[:, :], int64[:, :], float64[:], float64, float64[:], float64[:, :])", inline=True)
def pair_forces(u: Array, outside: Array, d: Array, obstacles: Array, pair_index: Ints,
                pair_table: Array, group_index: Ints, near: Array, ell: float,
                phi_out: Array, force: Array) -> None:
    """Each moving pair's factor of φ̃ (φ̃_p/ℓ, ``localised``; φ_p without ℓ, ``ell`` 0)
    multiplied into its constraint's entry of ``phi_out`` (which holds 1 there), and its
    force (dφ̃_p/dφ_p)/φ̃_p n̂_p, n̂_p = R sign(u) max(|u| − h, 0)/d the pair's unit normal
    in the world, added to its sphere's column of ``force`` (3, S) (subtracted from the
    second sphere's for a self pair) — over the pairs of the near groups (``near_groups``;
    the others have factor 1 and no force)."""
    inv_ell = 1.0 / ell if ell > 0.0 else 0.0
    w = 3.0 * inv_ell if ell > 0.0 else 1.0
    for g in range(group_index.shape[0]):
        if near[g] == 0.0:
            continue
        for p in range(group_index[g, 0], group_index[g, 1]):
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


@kernel("void(float64[:, :], float64[:, :], float64[:, :], float64[:, :], float64[:])", inline=True)
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


@inner("void(float64[:, :], int64[:], float64[:, :], float64[:, :], int64[:, :],"
       " float64[:, :], int64[:, :], float64[:], float64[:, :], float64[:, :], float64[:, :],"
       " float64[:])")
def near_offsets(y: Array, sphere_index: Ints, sphere_local: Array, obstacles: Array,
                 pair_index: Ints, pair_table: Array, group_index: Ints, near: Array,
                 centres: Array, u: Array, outside: Array, d: Array) -> None:
    """The centres, u, max(|u| − h, 0) and d (``link_point``, ``pair_offset``) of the pairs
    of the near groups only; the other columns are left unwritten. With self pairs (never
    skipped; they come last) or every group near (the reported clearances asked for) every
    centre is computed once, else each pair's sphere with its pair (a sphere near two
    obstacles twice, the same)."""
    n_pair = pair_index.shape[0]
    with_self = pair_index[n_pair - 1, 0] < 0 or near.min() > 0.0
    if with_self:
        sphere_centres(y, sphere_index, sphere_local, centres)
    for g in range(group_index.shape[0]):
        if near[g] == 0.0:
            continue
        for p in range(group_index[g, 0], group_index[g, 1]):
            s = pair_index[p, 1]
            if not with_self:
                centres[0, s], centres[1, s], centres[2, s] = link_point(
                    y, sphere_index[s], sphere_local, s)
            pair_offset(centres, obstacles, pair_index, pair_table, u, outside, d, p)


@kernel("float64(float64[:, :], float64[:, :], int64[:], float64[:, :], float64[:, :],"
        f" int64[:, :], float64[:, :], int64[:, :], float64[:, :], float64[:, :], {READ_ONLY},"
        " float64, float64[:], float64[:], float64[:])", inline=True)  # one compiled caller
def sphere_barrier(y: Array, jac: Array, sphere_index: Ints, sphere_local: Array,
                   obstacles: Array, pair_index: Ints, pair_table: Array, group_index: Ints,
                   group_table: Array, supports: Array, far_phi: Array, ell: float,
                   phi_out: Array, b: Array, value: Array) -> float:
    """The sphere pairs' part of the law's log-barrier terms at the joint placements ``y``
    and joint Jacobians ``jac`` (6, n) (Pinocchio's world J = [v; ω]).

    With an influence distance ℓ (``ell``; 0 for none) and an empty ``value``, the groups
    of pairs that are provably beyond ℓ are skipped (``near_groups``): their factors are
    exactly 1 and their forces 0, so nothing below changes by it. Returns the smallest law
    clearance of the pairs computed (``smallest_law_clearance``): exact when it is < ℓ (or
    without ℓ, or with ``value``), else some value ≥ ℓ, ∞ when every group is skipped; NaN
    on a NaN state (a NaN never skips). Only when it is > 0 and, with ℓ, < ℓ, are
    ``phi_out`` and ``b`` written: φ̃ of every constraint (the sphere constraints' the
    product of their pairs' factors times ``far_phi``, the others ``far_phi``) and
    b = Σ_p ∇φ̃_p/φ̃_p, the gradient by the envelope theorem, ∇φ_p = n̂_pᵀ J(s_p) (minus
    J(s₂) for a self pair). With a non-empty ``value`` the reported clearances are written
    to it (``sphere_values``) whatever the answer.
    """
    n_sph, n_pair, n_grp = sphere_index.shape[0], pair_index.shape[0], group_index.shape[0]
    work = np.empty(6 * n_sph + 7 * n_pair + 4 * n_grp)  # one allocation for seven arrays
    centres, force = float_rows(work, 0, 3, n_sph), float_rows(work, 3 * n_sph, 3, n_sph)
    at = 6 * n_sph
    u, outside = float_rows(work, at, 3, n_pair), float_rows(work, at + 3 * n_pair, 3, n_pair)
    at += 7 * n_pair
    d, near = work[at - n_pair:at], work[at:at + n_grp]
    points = float_rows(work, at + n_grp, 3, n_grp)
    limit = ell if ell > 0.0 and value.shape[0] == 0 else math.inf
    near_groups(y, group_index, group_table, obstacles, pair_table, limit, near, points)
    near_offsets(y, sphere_index, sphere_local, obstacles, pair_index, pair_table, group_index,
                 near, centres, u, outside, d)
    if value.shape[0] > 0:  # every group is near
        sphere_values(u, d, pair_index, pair_table, value)
    low = smallest_law_clearance(d, pair_table, group_index, near)
    if not low > 0.0 or (ell > 0.0 and not low < ell):
        return low
    stop = pair_index[n_pair - 1, 3] + 1  # the sphere constraints come first
    phi_out[:stop] = 1.0
    phi_out[stop:] = far_phi[stop:]
    force[:, :] = 0.0
    pair_forces(u, outside, d, obstacles, pair_index, pair_table, group_index, near, ell,
                phi_out, force)
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


@inner("void(float64[:, :], int64[:], float64[:, :], float64[:, :], int64[:, :],"
       " float64[:, :], float64[:], float64[:])")
def sphere_clearances_in(y: Array, sphere_index: Ints, sphere_local: Array, obstacles: Array,
                         pair_index: Ints, pair_table: Array, work: Array, value: Array
                         ) -> None:
    """``sphere_clearances`` in the caller's ``work`` (3S + 7P floats: the centres, u,
    max(|u| − h, 0) and d), which a caller over many rows allocates once."""
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    centres = float_rows(work, 0, 3, n_sph)
    at = 3 * n_sph
    u, outside = float_rows(work, at, 3, n_pair), float_rows(work, at + 3 * n_pair, 3, n_pair)
    d = work[at + 6 * n_pair:at + 7 * n_pair]
    sphere_centres(y, sphere_index, sphere_local, centres)
    sphere_offsets(centres, obstacles, pair_index, pair_table, u, outside, d)
    sphere_values(u, d, pair_index, pair_table, value)


@inner("void(float64[:, :], int64[:], float64[:, :], float64[:, :], int64[:, :],"
       " float64[:, :], float64[:], boolean[:], float64[:])")
def sphere_clearances_of(y: Array, sphere_index: Ints, sphere_local: Array, obstacles: Array,
                         pair_index: Ints, pair_table: Array, work: Array, need: Bools,
                         value: Array) -> None:
    """``sphere_clearances_in`` for the constraints ``need`` marks only: their pairs alone
    are computed, in the same order, and the other entries of ``value`` are left as they
    are (the guard's test where a bound from its sample settles the rest)."""
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    centres, at = float_rows(work, 0, 3, n_sph), 3 * n_sph
    u, outside = float_rows(work, at, 3, n_pair), float_rows(work, at + 3 * n_pair, 3, n_pair)
    d, filled = work[at + 6 * n_pair:at + 7 * n_pair], -1
    sphere_centres(y, sphere_index, sphere_local, centres)
    for p in range(n_pair):
        c = pair_index[p, 3]
        if not need[c]:
            continue
        pair_offset(centres, obstacles, pair_index, pair_table, u, outside, d, p)
        phi = pair_clearance(u, d, pair_table, p)
        if c > filled:  # as sphere_values
            value[c] = phi
            filled = c
        elif phi < value[c] or phi != phi:
            value[c] = phi


@kernel("void(float64[:, :], int64[:], float64[:, :], float64[:, :], int64[:, :],"
        " float64[:, :], float64[:])")
def sphere_clearances(y: Array, sphere_index: Ints, sphere_local: Array, obstacles: Array,
                      pair_index: Ints, pair_table: Array, value: Array) -> None:
    """The reported clearances of the sphere constraints at the joint placements ``y``
    (``sphere_values``), into ``value``."""
    n_sph, n_pair = sphere_index.shape[0], pair_index.shape[0]
    work = np.empty(3 * n_sph + 7 * n_pair)
    sphere_clearances_in(y, sphere_index, sphere_local, obstacles, pair_index, pair_table,
                         work, value)


@inner("float64(float64[:], float64[:], float64[:])")
def travel(reach: Array, x: Array, q: Array) -> float:
    """Σ_k reach_k |q_k − x_k|: how far a sphere constraint's clearance can move between the
    configurations ``x`` and ``q``, with ``reach`` its row of the kind's ``reach`` table (or
    a row ≥ it); NaN if either configuration is.

    Each pair's clearance is the signed distance of its sphere's centre s to a rounded box
    (less a constant): 1-Lipschitz in s (in s − s₂ for a self pair), and along the segment
    from x to q every centre moves by at most Σ_k reach_sk |q_k − x_k|
    (cpbc.constraints.clearance.kinematics, ``Kinematics._reach``): so does their minimum,
    by at most its pairs' largest ``reach`` (both spheres' of a self pair). A clearance φ
    known at x is therefore ≥ φ − travel − MOVED_ROUNDING at q."""
    moved = 0.0
    for k in range(x.shape[0]):
        moved += reach[k] * abs(q[k] - x[k])
    return moved


def pack_sphere_pairs(sphere_local: Array, obstacles: Array, pair_table: Array,
                      supports: Array, far_phi: Array, ell: float | None, group_table: Array,
                      reach: Array, sphere_index: Ints, pair_index: Ints, group_index: Ints
                      ) -> Packed:
    """The sphere pairs' tables for a set's plan (the names above; ``far_phi`` (C,), ℓ
    None for none)."""
    floats = [np.zeros((0, 0))] * 8
    floats[SPHERE_LOCAL], floats[OBSTACLES], floats[PAIR_TABLE] = (
        sphere_local, obstacles, pair_table)
    floats[SUPPORTS], floats[FAR_PHI], floats[GROUP_TABLE] = (
        supports, far_phi[:, None], group_table)
    floats[REACH] = reach
    floats[ELL] = np.array([[ell or 0.0]])
    ints = [np.zeros((0, 0), dtype=np.int64)] * 3
    ints[SPHERE_INDEX], ints[PAIR_INDEX], ints[GROUP_INDEX] = (
        sphere_index[:, None], pair_index, group_index)
    return Packed(SPHERES, tuple(floats), tuple(ints))


@kernel("void(int64[:, :], int64[:, :], float64[:, :], int64, float64[:, :],"
        " float64[:, :], float64[:], float64[:], float64[:])")
def sphere_pairs_row(plan: Ints, ints: Ints, floats: Array, row: int, y: Array, jac: Array,
                     phi: Array, gradient: Array, shown: Array) -> None:
    """A packed clearance's sphere pairs (``sphere_barrier``): φ̃ into ``phi``, Σ ∇φ̃/φ̃
    into ``gradient`` (zero with no pair within ℓ: φ̃ is then the far values; and outside
    S, where ``phi`` holds the clearances themselves, which the set reports), the reported
    clearances into a non-empty ``shown``."""
    far = float_table(plan, floats, row, FAR_PHI)[:, 0]
    ell = float_table(plan, floats, row, ELL)[0, 0]
    index = int_table(plan, ints, row, SPHERE_INDEX)[:, 0]
    pairs = int_table(plan, ints, row, PAIR_INDEX)
    local = float_table(plan, floats, row, SPHERE_LOCAL)
    obstacles = float_table(plan, floats, row, OBSTACLES)
    table = float_table(plan, floats, row, PAIR_TABLE)
    supports = float_table(plan, floats, row, SUPPORTS)
    groups = int_table(plan, ints, row, GROUP_INDEX)
    bounds = float_table(plan, floats, row, GROUP_TABLE)
    low = sphere_barrier(y, jac, index, local, obstacles, pairs, table, groups, bounds,
                         supports, far, ell, phi, gradient, shown)
    if low > 0.0 and (ell == 0.0 or low < ell):
        return
    gradient[:] = 0.0
    if low > 0.0:  # no pair within ℓ
        phi[:] = far
    else:  # outside S (or NaN): the clearances themselves, the set raises
        sphere_clearances(y, index, local, obstacles, pairs, table, phi)
