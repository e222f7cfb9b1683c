"""The constraints' log-barrier terms (the laws' b_φ = Σ ∇φ_i/φ_i, Π = Σ Q_j/ψ_j,
b_ψ = Σ ∂_xψ_j/ψ_j), one kernel per constraint kind — and, beside each, the kind's code in a
set's plan, its tables (``pack_*``, cpbc.kernels.plan_tables) and its row reader (``*_row``, what
cpbc.kernels.barrier_set dispatches to, one line per kind).

A row reader writes every output of its constraint's share: its barrier values into
``phi``, its Σ ∇φ̃/φ̃ (or ∂_xψ/ψ) into ``gradient`` (overwritten, zero where it has none),
Π into ``weight`` (velocity kinds) and, when ``shown`` is not empty, its margins into it.
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, inner, kernel
from cpbc.kernels.clearance_motion import sphere_motion
from cpbc.kernels.energy import kinetic_energy
from cpbc.kernels.plan_tables import Ints, Packed, float_table
from cpbc.kernels.task import point_on_frame
from cpbc.kernels.views import float_rows

# each kind's code in a set's plan (cpbc.kernels.barrier_set's registry), and its tables
LINEAR, RATE, ENERGY, POINT = 0, 1, 2, 3
LINEAR_CONSTANTS = 0  # [a_iᵀ l_i u_i] row by row (k, n + 2)
RATE_CONSTANTS = 0  # [a_jᵀ Ω_j] row by row (k, n + 1)
ENERGY_LIMIT = 0  # Ω (1, 1)
POINT_CONSTANTS = 0  # [c r² o has_offset] (1, 8)


@kernel("void(float64[:, :], float64[:], float64[:], float64[:])",
        inline=True)
def linear_limit_terms(constants: Array, x: Array, phi: Array, gradient: Array) -> None:
    """Two-sided limits lower_i < a_iᵀx < upper_i as φ_i = (a_iᵀx − l_i)(u_i − a_iᵀx) (the
    joint limit of eq. 6.50 up to a constant factor; the relative limit φ₂ of Section 6.4):
    φ into ``phi`` (k,) and Σ ∇φ_i/φ_i = Σ a_i (l_i + u_i − 2a_iᵀx)/φ_i into ``gradient``
    (n,), which is overwritten. ``constants``: [a_iᵀ l_i u_i] row by row, shape (k, n + 2)."""
    k, n = constants.shape[0], constants.shape[1] - 2
    rows = constants[:, :n]
    lower, upper = constants[:, n], constants[:, n + 1]
    for j in range(n):
        gradient[j] = 0.0
    for i in range(k):
        y = 0.0
        for j in range(n):
            if rows[i, j] != 0.0:  # a row's zeros ignore the other coordinates, even NaN
                y += rows[i, j] * x[j]
        p = (y - lower[i]) * (upper[i] - y)
        phi[i] = p
        w = (lower[i] + upper[i] - 2.0 * y) / p
        for j in range(n):
            if rows[i, j] != 0.0:
                gradient[j] += w * rows[i, j]


@kernel(f"void(float64[:, :], {READ_ONLY}, {READ_ONLY}, float64[:], float64[:, :],"
        " float64[:])")
def linear_limit_motion(constants: Array, x: Array, dx: Array, phi: Array, grad: Array,
                        curvature: Array) -> None:
    """The limits' rows one by one, from the same ``constants`` as ``linear_limit_terms``: φ_i
    into ``phi`` (k,), ∇φ_i = (l_i + u_i − 2a_iᵀx) a_i into the rows of ``grad`` (k, n) and
    ẋᵀ∇²φ_i ẋ = −2(a_iᵀẋ)² into ``curvature`` (k,): what the slide, the aimed brake and the
    stopping test read. Every product a_ij x_j is summed, zeros too, in the order of j, and
    each row of ∇φ is the factor times every a_ij (−0 where the factor is negative), as
    numpy's ``rows.dot(x)`` and ``factor[:, None] * rows`` make them for rows of ±1."""
    k, n = constants.shape[0], constants.shape[1] - 2
    for i in range(k):
        y = 0.0
        rate = 0.0
        for j in range(n):
            y += constants[i, j] * x[j]
            rate += constants[i, j] * dx[j]
        lower, upper = constants[i, n], constants[i, n + 1]
        phi[i] = (y - lower) * (upper - y)
        factor = (lower + upper) - 2.0 * y
        for j in range(n):
            grad[i, j] = factor * constants[i, j]
        curvature[i] = -2.0 * rate * rate


def pack_linear_limit(rows: Array, lower: Array, upper: Array) -> Packed:
    """The linear limit's tables: ``LINEAR_CONSTANTS`` [a_iᵀ l_i u_i] (writable: numba's
    typed signature)."""
    return Packed(LINEAR, (np.column_stack([rows, lower, upper]),))


@inner("void(int64[:, :], float64[:, :], int64, float64[:], float64[:], float64[:],"
       " float64[:])")
def linear_limit_row(plan: Ints, floats: Array, row: int, x: Array, phi: Array,
                     gradient: Array, shown: Array) -> None:
    """A packed linear limit's share (``linear_limit_terms``); its margins are φ."""
    linear_limit_terms(float_table(plan, floats, row, LINEAR_CONSTANTS), x, phi, gradient)
    if shown.shape[0] > 0:
        shown[:] = phi


@kernel("void(float64[:, :], float64[:], float64[:])", inline=True)
def rate_limit_margins(constants: Array, dx: Array, psi: Array) -> None:
    """Rate limits |a_jᵀẋ| < B_j as ψ_j = Ω_j − ½(a_jᵀẋ)², Ω_j = B_j²/2 (Remark 6.7,
    eq. 7.9) into ``psi`` (k,); ``constants``: [a_jᵀ Ω_j] row by row, shape (k, n + 1)."""
    k, n = constants.shape[0], constants.shape[1] - 1
    for i in range(k):
        y = 0.0
        for j in range(n):
            if constants[i, j] != 0.0:  # a row's zeros ignore the other rates, even NaN
                y += constants[i, j] * dx[j]
        psi[i] = constants[i, n] - 0.5 * y * y


@kernel("void(float64[:, :], float64[:], float64[:], float64[:, :])",
        inline=True)
def rate_limit_terms(constants: Array, dx: Array, psi: Array, weight: Array) -> None:
    """Rate limits |a_jᵀẋ| < B_j as ψ_j (``rate_limit_margins``), Q_j = a_j a_jᵀ
    (Remark 6.7, eq. 7.9): ψ into ``psi`` (k,) and Π = Σ a_j a_jᵀ/ψ_j into ``weight``
    (n, n), which is overwritten; ∂ψ/∂x = 0. ``constants``: [a_jᵀ Ω_j] row by row, shape
    (k, n + 1)."""
    k, n = constants.shape[0], constants.shape[1] - 1
    rows = constants[:, :n]
    rate_limit_margins(constants, dx, psi)
    for a in range(n):
        for b in range(n):
            weight[a, b] = 0.0
    for i in range(k):
        inv = 1.0 / psi[i]
        for a in range(n):
            ra = rows[i, a]
            if ra != 0.0:
                ra *= inv
                for b in range(n):
                    if rows[i, b] != 0.0:
                        weight[a, b] += ra * rows[i, b]


def pack_rate_limit(rows: Array, omega: Array) -> Packed:
    """The rate limit's tables: ``RATE_CONSTANTS`` [a_jᵀ Ω_j]."""
    return Packed(RATE, (np.column_stack([rows, omega]),))


@inner("void(int64[:, :], float64[:, :], int64, float64[:], float64[:], float64[:, :],"
       " float64[:], float64[:])")
def rate_limit_row(plan: Ints, floats: Array, row: int, dx: Array, psi: Array,
                   weight: Array, gradient: Array, shown: Array) -> None:
    """A packed rate limit's share (``rate_limit_terms``): ∂ψ/∂x = 0."""
    rate_limit_terms(float_table(plan, floats, row, RATE_CONSTANTS), dx, psi, weight)
    gradient[:] = 0.0
    if shown.shape[0] > 0:
        shown[:] = psi


@kernel("float64(float64, float64[:, :], float64[:, :], float64[:], float64[:, :], float64[:])",
        inline=True)
def kinetic_energy_terms(limit: float, inertia: Array, coriolis: Array, dx: Array,
                         weight: Array, gradient: Array) -> float:
    """A kinetic-energy limit ψ = Ω − ½ẋᵀD(x)ẋ (eq. 6.66, 7.33), Q = D, ∂ψ/∂x = −Cᵀẋ with
    C in Christoffel form: returns ψ, writes Π = D/ψ into ``weight`` and b = −Cᵀẋ/ψ into
    ``gradient``."""
    n = dx.shape[0]
    psi = limit - kinetic_energy(inertia, dx)
    for a in range(n):
        s = 0.0
        for b in range(n):
            weight[a, b] = inertia[a, b] / psi
            s += coriolis[b, a] * dx[b]
        gradient[a] = -s / psi
    return psi


def pack_kinetic_energy_limit(limit: float) -> Packed:
    """The energy limit's tables: ``ENERGY_LIMIT`` Ω (1, 1)."""
    return Packed(ENERGY, (np.array([[limit]]),))


@inner("void(int64[:, :], float64[:, :], int64, float64[:, :], float64[:, :], float64[:],"
       " float64[:], float64[:, :], float64[:], float64[:])")
def kinetic_energy_row(plan: Ints, floats: Array, row: int, inertia: Array, coriolis: Array,
                       dx: Array, psi: Array, weight: Array, gradient: Array,
                       shown: Array) -> None:
    """A packed energy limit's share (``kinetic_energy_terms``)."""
    psi[0] = kinetic_energy_terms(float_table(plan, floats, row, ENERGY_LIMIT)[0, 0],
                                  inertia, coriolis, dx, weight, gradient)
    if shown.shape[0] > 0:
        shown[:] = psi


@kernel(f"float64({READ_ONLY})",
        inline=True)
def log_sum(margins: Array) -> float:
    """Σ log m_i of positive margins (log Φ = Σ log φ_i, log Ψ = Σ log ψ_j: the products Φ, Ψ
    are never formed); NaN when a margin is ≤ 0 or NaN."""
    total = 0.0
    for i in range(margins.shape[0]):
        m = margins[i]
        if not m > 0.0:
            return math.nan
        total += math.log(m)
    return total


@inner("float64(float64[:], float64[:], float64[:, :], float64[:, :], float64[:],"
       " float64[:, :], float64[:])")
def point_sphere(constants: Array, origin: Array, rotation: Array, jacobian: Array,
                 point: Array, linear: Array, half_gradient: Array) -> float:
    """A point p kept outside a sphere, φ = ‖p − c‖² − r² (φ₁ of Section 6.4), returned, with
    ∇φ = 2(p − c)ᵀJ_p: p into ``point`` (3,) and half of ∇φ, (p − c)ᵀJ_p, into
    ``half_gradient`` (n,), overwritten; p and J_p of the point at o in the frame
    (cpbc.kernels.task.point_on_frame) into ``point`` and ``linear`` (3, n).
    ``constants``: [c r² o has_offset], shape (8,)."""
    n = half_gradient.shape[0]
    point_on_frame(origin, rotation, jacobian, constants[4:], point, linear)
    d0, d1, d2 = point[0] - constants[0], point[1] - constants[1], point[2] - constants[2]
    for k in range(n):
        half_gradient[k] = d0 * linear[0, k] + d1 * linear[1, k] + d2 * linear[2, k]
    return d0 * d0 + d1 * d1 + d2 * d2 - constants[3]


@kernel("void(float64[:], float64[:], float64[:, :], float64[:, :], float64[:], float64[:])",
        inline=True)
def point_sphere_terms(constants: Array, origin: Array, rotation: Array, jacobian: Array,
                       phi: Array, gradient: Array) -> None:
    """The point's φ (``point_sphere``) into ``phi[0]`` and ∇φ/φ into ``gradient`` (n,),
    overwritten: the laws' log-barrier terms."""
    n = gradient.shape[0]
    work = np.empty(3 + 3 * n)  # one allocation for p and J_p
    p = point_sphere(constants, origin, rotation, jacobian, work[:3],
                     float_rows(work, 3, 3, n), gradient)
    phi[0] = p
    scale = 2.0 / p
    for k in range(gradient.shape[0]):
        gradient[k] *= scale


def pack_point_sphere(centre: Array, radius: float, offset: Array | None, frame: int
                      ) -> Packed:
    """The point constraint's tables: ``POINT_CONSTANTS`` [c r² o has_offset] (1, 8), on
    ``frame``, whose kinematics the set passes."""
    point = np.zeros(4) if offset is None else np.append(offset, 1.0)
    return Packed(POINT, (np.concatenate([centre, [radius**2], point])[None, :],), frame=frame)


@inner("void(int64[:, :], float64[:, :], int64, float64[:], float64[:, :], float64[:, :],"
       " float64[:], float64[:], float64[:])")
def point_sphere_row(plan: Ints, floats: Array, row: int, origin: Array, rotation: Array,
                     jacobian: Array, phi: Array, gradient: Array, shown: Array) -> None:
    """A packed point constraint's share (``point_sphere_terms``) on the set's frame."""
    point_sphere_terms(float_table(plan, floats, row, POINT_CONSTANTS)[0], origin, rotation,
                       jacobian, phi, gradient)
    if shown.shape[0] > 0:
        shown[:] = phi


@kernel("void(float64[:], float64[:], float64[:, :], float64[:, :], float64[:, :],"
        " float64[:], float64[:, :], float64[:, :], float64[:], float64[:], float64[:])")
def point_sphere_motion(constants: Array, origin: Array, rotation: Array, jacobian: Array,
                        joint_jacobians: Array, dq: Array, supports: Array,
                        joint_supports: Array, phi: Array, gradient: Array,
                        curvature: Array) -> None:
    """The point's φ (``point_sphere``) into ``phi[0]``, ∇φ into ``gradient`` (n,) and
    ẋᵀ∇²φ ẋ into ``curvature[0]``: φ̈ at ẍ = 0,

        ẋᵀ∇²φ ẋ = 2‖ṗ‖² + 2 (p − c)·p̈₀,

    with ṗ and p̈₀ the velocity and the acceleration at q̈ = 0 of p, a point fixed on the
    frame's link (cpbc.kernels.clearance_motion.sphere_motion, its eq. 2), from the joint Jacobians
    ``joint_jacobians`` (6, n) and rates ``dq`` in joint coordinates; ``supports`` (1, n) is
    1 on the coordinates that move the frame, ``joint_supports`` (n, n) as in
    ``sphere_motion``. The frame's ``jacobian`` is in the controller's coordinates x = T q,
    and so is ∇φ; the curvature does not depend on them (T is constant: ẍ = 0 is q̈ = 0)."""
    centre = np.empty((3, 1))
    p = point_sphere(constants, origin, rotation, jacobian, centre[:, 0],
                     np.empty((3, gradient.shape[0])), gradient)
    phi[0] = p
    for k in range(gradient.shape[0]):
        gradient[k] *= 2.0
    vel, acc = np.empty((3, 1)), np.empty((3, 1))
    sphere_motion(centre, joint_jacobians, dq, supports, joint_supports, vel, acc)
    bend = 0.0
    for i in range(3):
        bend += vel[i, 0] * vel[i, 0] + (centre[i, 0] - constants[i]) * acc[i, 0]
    curvature[0] = 2.0 * bend
