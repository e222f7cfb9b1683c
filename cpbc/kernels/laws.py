"""The laws' formulas, given the potential's force, the damping and the barrier sums; and
each law's whole step in one call (``cpbc_step``, ``cpbc_ke_step``) on the per-step state
(cpbc.kernels.state_terms), from the packed constants of its constraint set and its terms
(cpbc.controllers.packed_law)."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel
from cpbc.kernels.barrier_set import VELOCITY_KINDS, set_barrier
from cpbc.kernels.energy import kinetic_energy
from cpbc.kernels.law_terms import damping_terms, potential_terms, shaped
from cpbc.kernels.plan_tables import KIND
from cpbc.kernels.small_solves import solve_spd
from cpbc.kernels.state_terms import finish_into, frame_views, state_views
from cpbc.kernels.views import Ints, borrowed, float_rows, int_rows


def zero_terms(n: int) -> tuple[Array, Array]:
    """Read-only zero barrier sums b (n,) and Π (n, n), for a law whose constraints give none
    (a law keeps them: nothing constant is allocated per call)."""
    b, weight = np.zeros(n), np.zeros((n, n))
    b.setflags(write=False)
    weight.setflags(write=False)
    return b, weight


@kernel("void(float64[:, :], float64[:], float64[:], float64[:], float64[:], "
        f"{READ_ONLY}, {READ_ONLY_MATRIX}, boolean, float64, float64[:])", inline=True)
def cpbc_torque(inertia: Array, gravity: Array, bias: Array, grad: Array, damping: Array,
                gradient: Array, weight: Array, constrained_rate: bool, rho: float, tau: Array
                ) -> None:
    """CPBC (Theorem 6.9, eq. 6.24) in log-barrier form:

        a = −∂U/∂x − (K_D ẋ + F) + ρ (b_φ + b_ψ),   τ = g + c + D (D + ρΠ)⁻¹ (a − c)

    with ``grad`` ∂U/∂x, ``damping`` K_D ẋ + F, ``bias`` c = C ẋ + f, ``gradient``
    b_φ + b_ψ and ``weight`` Π. Without velocity constraints (``constrained_rate`` False,
    Π = 0) this is τ = g + a. τ into ``tau``."""
    n = gravity.shape[0]
    for i in range(n):
        tau[i] = -grad[i] - damping[i] + rho * gradient[i]  # a
    if not constrained_rate:
        for i in range(n):
            tau[i] += gravity[i]
        return
    work = np.empty((n, 2 * n + 1))
    m = work[:, :n]
    factor = work[:, n:2 * n]
    rhs = work[:, 2 * n]
    for i in range(n):
        rhs[i] = tau[i] - bias[i]
        for j in range(n):
            m[i, j] = inertia[i, j] + rho * weight[i, j]
    solve_spd(m, rhs, factor, tau)  # tau holds y = (D + ρΠ)⁻¹ (a − c)
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += inertia[i, j] * tau[j]
        rhs[i] = gravity[i] + bias[i] + s
    for i in range(n):
        tau[i] = rhs[i]


@kernel(f"void(float64[:], float64[:], float64[:], {READ_ONLY}, float64, float64, float64[:])",
        inline=True)
def cpbc_ke_torque(gravity: Array, grad: Array, damping: Array, gradient: Array, rho: float,
                   psi: float, tau: Array) -> None:
    """CPBC-KE (Corollary 6.11, eq. 6.67) with shaping, in log-barrier form:

        τ = g + (−∂U/∂x − (K_D ẋ + F) + ρ b_φ) / (1 + ρ/ψ)

    with ``grad`` ∂U/∂x and ``damping`` K_D ẋ + F (BPBC-KE, eq. 7.34, with the ln cosh
    spring and tanh damping)."""
    scale = 1.0 + rho / psi
    for i in range(gravity.shape[0]):
        tau[i] = gravity[i] + (-grad[i] - damping[i] + rho * gradient[i]) / scale


@kernel("float64(float64, float64)",
        inline=True)
def shaped_value(lag: float, log_s: float) -> float:
    """V = L / s(ΦΨ), evaluated in logs (log s from cpbc.kernels.barrier_shaping); 0 when L ≤ 0."""
    if lag <= 0.0:
        return 0.0
    return math.exp(math.log(lag) - log_s)


# the law's constant tables, packed once (``pack_tables``): ``ints`` starts with HEADER
# entries — the margins, then (rows, columns) of the set's plan, ints and floats and of the
# terms' plan and floats, then where the state's tables start in the ints and in the floats
# (cpbc.kernels.state_terms: the law's per-step state, packed after the law's own) and which
# of the state's frames the law reads (−1: none) — and holds the int tables after it,
# ``floats`` the float tables; each table row-major, in that order. One array of each: a
# kernel argument costs numba about 45 ns to pass, whatever its size.
# the header's entries: the margins; the (rows, columns) of each table from its column
MARGINS, SET_PLAN, SET_INTS, SET_FLOATS, TERM_PLAN, TERM_FLOATS = 0, 1, 3, 5, 7, 9
STATE_INTS, STATE_FLOATS, FRAME = 11, 12, 13
HEADER = FRAME + 1


def pack_tables(margins: int, plan: Ints, ints: Ints, floats: Array, term_plan: Ints,
                term_floats: Array, state: tuple[Ints, Array], frame: int
                ) -> tuple[Ints, Array]:
    """The law's constant tables in the two arrays ``law_tables`` reads, with its per-step
    state's (``state``: cpbc.kernels.state_terms.pack_state) after them; ``frame``: the
    place of the frame the law reads among the state's frames (−1: none)."""
    header = [margins]
    for table in (plan, ints, floats, term_plan, term_floats):
        header += table.shape
    state_ints, state_floats = state
    header += [HEADER + plan.size + ints.size + term_plan.size, floats.size + term_floats.size,
               frame]
    packed_ints = np.concatenate([np.array(header, dtype=np.int64), plan.ravel(),
                                  ints.ravel(), term_plan.ravel(), state_ints]).astype(np.int64)
    return packed_ints, np.concatenate([floats.ravel(), term_floats.ravel(),
                                        state_floats]).astype(float)


TABLES = ("Tuple((int64, int64[:, :], int64[:, :], float64[:, :], int64[:, :],"
          " float64[:, :]))")


@inner(f"{TABLES}(int64[::1], float64[::1])")
def law_tables(ints: Ints, floats: Array) -> tuple[int, Ints, Ints, Array, Ints, Array]:
    """The margins and the tables packed by ``pack_tables`` (views): the set's plan, ints
    and floats (cpbc.kernels.barrier_set), the terms' plan and floats
    (cpbc.kernels.law_terms)."""
    at = HEADER
    plan = int_rows(ints, at, ints[SET_PLAN], ints[SET_PLAN + 1])
    at += ints[SET_PLAN] * ints[SET_PLAN + 1]
    set_ints = int_rows(ints, at, ints[SET_INTS], ints[SET_INTS + 1])
    at += ints[SET_INTS] * ints[SET_INTS + 1]
    term_plan = int_rows(ints, at, ints[TERM_PLAN], ints[TERM_PLAN + 1])
    set_floats = float_rows(floats, 0, ints[SET_FLOATS], ints[SET_FLOATS + 1])
    term_floats = float_rows(floats, ints[SET_FLOATS] * ints[SET_FLOATS + 1],
                             ints[TERM_FLOATS], ints[TERM_FLOATS + 1])
    return ints[MARGINS], plan, set_ints, set_floats, term_plan, term_floats


@inner("void(int64[::1], float64[::1], float64[:], float64[:, :], float64[:], float64[:],"
       " float64[:, :], float64[:, :], float64[:, :], float64[::1])")
def finished(tables: Ints, table_floats: Array, dx: Array, inertia_q: Array, nle: Array,
             gravity_q: Array, coriolis_q: Array, y: Array, jac: Array, terms: Array) -> None:
    """The state's terms: ``terms`` as they are when the pass comes finished (``inertia_q``
    empty), else finished here into ``terms`` (cpbc.kernels.state_terms.finish_into), which
    the caller sizes (``terms_size``): the state's own when it keeps them, else the law's
    one array for a step that keeps none (cpbc.controllers.packed_law)."""
    if inertia_q.shape[0] > 0:
        finish_into(tables, table_floats, tables[STATE_INTS], tables[STATE_FLOATS], dx,
                    inertia_q, nle, gravity_q, coriolis_q, y, jac, terms)


# the tables, x, ẋ, the state's one Pinocchio pass in joint coordinates (cpbc.model
# .state_pass: D_q, nle = C q̇ + g_q, g_q, C_q (or empty), the joint placements and
# Jacobians (or empty); all empty when the state comes finished), the state's terms
# (cpbc.kernels.state_terms, ``terms_size`` long), ``barriers``
# [φ̃ (margins) | the margins (or nothing)] and τ
STEP = ("int64[::1], float64[::1], float64[:], float64[:], float64[:, :], float64[:],"
        " float64[:], float64[:, :], float64[:, :], float64[:, :], float64[::1], float64[:],"
        " float64[:]")


@inner("UniTuple(float64[:, :], 2)(int64[::1], float64[::1], float64[::1])")
def law_frame(tables: Ints, terms: Array, work: Array) -> tuple[Array, Array]:
    """The placement and Jacobian of the frame the law reads, views of the state's terms;
    without one, the identity placement and an empty Jacobian in ``work`` (16 entries)."""
    frame = tables[FRAME]
    if frame >= 0:
        return frame_views(tables, tables[STATE_INTS], terms, frame)
    placement = float_rows(work, 0, 4, 4)
    placement[:, :] = 0.0
    for i in range(4):
        placement[i, i] = 1.0
    return placement, float_rows(work, 16, 6, 0)


@kernel(f"UniTuple(float64, 3)({STEP})")
def cpbc_step(tables: Ints, table_floats: Array, x: Array, dx: Array, inertia_q: Array,
              nle: Array, gravity_q: Array, coriolis_q: Array, y_q: Array, jac_q: Array,
              terms: Array, barriers: Array, tau: Array) -> tuple[float, float, float]:
    """One CPBC step (cpbc.controllers.cpbc.CPBC) on the per-step state (``finished``; D,
    C ẋ, g, f, C, the frame's placement [R p; 0 1] and Jacobian [J_v; J_ω], the joint
    placements and Jacobians read from its terms): the set's barrier sums (``set_barrier``,
    its tables ``plan``, ``ints``, ``floats``), U and ∂U/∂x, the damping and the shaping of
    the packed terms (cpbc.kernels.law_terms), L = ½ẋᵀDẋ + U, ρ = r(ΦΨ)·L and τ
    (``cpbc_torque``, c = C ẋ + f) into ``tau``. The tables (``law_tables``) are packed by
    ``pack_tables``. ``barriers``: the barrier values φ̃, then — when it is twice as long —
    the margins. Returns V, log Φ and log Ψ; outside S (a NaN log) V is NaN and τ is not
    written (the caller raises, naming the margin from φ̃)."""
    n = x.shape[0]
    # the arguments uncounted (``borrowed``): the caller holds them for the call
    tables, table_floats, terms = borrowed(tables), borrowed(table_floats), borrowed(terms)
    x, dx, barriers, tau = borrowed(x), borrowed(dx), borrowed(barriers), borrowed(tau)
    inertia_q, nle, gravity_q = borrowed(inertia_q), borrowed(nle), borrowed(gravity_q)
    coriolis_q, y_q, jac_q = borrowed(coriolis_q), borrowed(y_q), borrowed(jac_q)
    finished(tables, table_floats, dx, inertia_q, nle, gravity_q, coriolis_q, y_q, jac_q,
             terms)
    inertia, coriolis_force, gravity, dissipation, coriolis, y, jac = state_views(
        tables, tables[STATE_INTS], terms)
    margins, plan, ints, floats, term_plan, term_floats = law_tables(tables, table_floats)
    phi, value = barriers[:margins], barriers[margins:]
    work = np.empty(5 * n + n * n + 16)  # one allocation for the step's arrays
    gradient, grad, damping, bias = work[:n], work[n:2 * n], work[2 * n:3 * n], work[3 * n:4 * n]
    part, weight = work[4 * n:5 * n], float_rows(work, 5 * n, n, n)
    placement, frame_jacobian = law_frame(tables, terms, work[5 * n + n * n:])
    origin, rotation = placement[:3, 3], placement[:3, :3]
    log_phi, log_psi = set_barrier(plan, ints, floats, x, dx, inertia, coriolis, origin,
                                   rotation, frame_jacobian, y, jac, phi, gradient, weight,
                                   value)
    if log_phi != log_phi or log_psi != log_psi:
        return math.nan, log_phi, log_psi
    potential = potential_terms(term_plan, term_floats, x, origin, rotation, frame_jacobian,
                                grad, part)
    lag = kinetic_energy(inertia, dx) + potential
    damping_terms(term_plan, term_floats, dx, origin, rotation, frame_jacobian, damping, part)
    ratio, log_s = shaped(term_plan, term_floats, log_phi + log_psi)
    for i in range(n):
        bias[i] = coriolis_force[i] + dissipation[i]
    constrained_rate = False
    for r in range(plan.shape[0]):
        if plan[r, KIND] in VELOCITY_KINDS:
            constrained_rate = True
    cpbc_torque(inertia, gravity, bias, grad, damping, gradient, weight, constrained_rate,
                ratio * lag, tau)
    return shaped_value(lag, log_s), log_phi, log_psi


@kernel(f"UniTuple(float64, 3)(float64, {STEP})")
def cpbc_ke_step(limit: float, tables: Ints, table_floats: Array, x: Array, dx: Array,
                 inertia_q: Array, nle: Array, gravity_q: Array, coriolis_q: Array,
                 y_q: Array, jac_q: Array, terms: Array, barriers: Array, tau: Array
                 ) -> tuple[float, float, float]:
    """One CPBC-KE step (cpbc.controllers.cpbc_ke.CPBCKineticEnergy): ψ = Ω − ½ẋᵀDẋ
    (``limit`` Ω), the configuration constraints' barrier sums (``set_barrier``), U, ∂U/∂x,
    the damping and the shaping of the packed terms, ρ = r(Φψ)·L and τ (``cpbc_ke_torque``)
    into ``tau`` (``cpbc_step``'s arguments). Returns V, log Φ and ψ; when ψ ≤ 0 or
    log Φ is NaN, V is NaN and τ is not written (the caller raises)."""
    n = x.shape[0]
    # the arguments uncounted (``borrowed``): the caller holds them for the call
    tables, table_floats, terms = borrowed(tables), borrowed(table_floats), borrowed(terms)
    x, dx, barriers, tau = borrowed(x), borrowed(dx), borrowed(barriers), borrowed(tau)
    inertia_q, nle, gravity_q = borrowed(inertia_q), borrowed(nle), borrowed(gravity_q)
    coriolis_q, y_q, jac_q = borrowed(coriolis_q), borrowed(y_q), borrowed(jac_q)
    finished(tables, table_floats, dx, inertia_q, nle, gravity_q, coriolis_q, y_q, jac_q,
             terms)
    inertia, _, gravity, _, coriolis, y, jac = state_views(tables, tables[STATE_INTS], terms)
    kinetic = kinetic_energy(inertia, dx)
    psi = limit - kinetic
    if not psi > 0.0:
        return math.nan, 0.0, psi
    margins, plan, ints, floats, term_plan, term_floats = law_tables(tables, table_floats)
    phi, value = barriers[:margins], barriers[margins:]
    work = np.empty(4 * n + 16)  # one allocation for the step's arrays (Π is empty)
    gradient, grad, damping, part = work[:n], work[n:2 * n], work[2 * n:3 * n], work[3 * n:4 * n]
    weight = float_rows(work, 0, 0, 0)
    placement, frame_jacobian = law_frame(tables, terms, work[4 * n:])
    origin, rotation = placement[:3, 3], placement[:3, :3]
    log_phi, _ = set_barrier(plan, ints, floats, x, dx, inertia, coriolis, origin, rotation,
                             frame_jacobian, y, jac, phi, gradient, weight, value)
    if log_phi != log_phi:
        return math.nan, log_phi, psi
    lag = kinetic + potential_terms(term_plan, term_floats, x, origin, rotation,
                                    frame_jacobian, grad, part)
    ratio, log_s = shaped(term_plan, term_floats, log_phi + math.log(psi))
    damping_terms(term_plan, term_floats, dx, origin, rotation, frame_jacobian, damping, part)
    cpbc_ke_torque(gravity, grad, damping, gradient, ratio * lag, psi, tau)
    return shaped_value(lag, log_s), log_phi, psi
