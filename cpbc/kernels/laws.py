"""The laws' formulas, given the potential's force, the damping and the barrier sums; and
each law's whole step in one call (``cpbc_step``, ``cpbc_ke_step``) from the packed
constants of its constraint set and its terms (cpbc.controllers.packed_law)."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel
from cpbc.kernels.barrier_set import VELOCITY_KINDS, set_barrier
from cpbc.kernels.coordinate_maps import controller_terms
from cpbc.kernels.energy import kinetic_energy
from cpbc.kernels.law_terms import damping_terms, potential_terms, shaped
from cpbc.kernels.small_solves import solve_spd
from cpbc.kernels.tables import KIND
from cpbc.kernels.task import PLACE, frame_on_joints
from cpbc.kernels.views import Ints, float_rows, int_rows


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
# terms' plan and floats, then whether the coordinates are the joints' and whether the arm
# has friction (``COORDINATES``), then the column of the frame's joint in the static
# regressor (−1: the pass reads the frame) — and holds the int tables after it, ``floats``
# the float tables and last the model's T⁻¹, F_d, F_c, its ε and the frame's place on its
# joint (``model_tables``); each table row-major, in that order. One array of each: a kernel
# argument costs numba about 70 ns to pass, whatever its size.
# the header's entries: the margins; the (rows, columns) of each table from its column
MARGINS, SET_PLAN, SET_INTS, SET_FLOATS, TERM_PLAN, TERM_FLOATS = 0, 1, 3, 5, 7, 9
COORDINATES = TERM_FLOATS + 2  # then whether the arm has friction
FRAME_COLUMN = COORDINATES + 2
HEADER = FRAME_COLUMN + 1


def pack_tables(margins: int, plan: Ints, ints: Ints, floats: Array, term_plan: Ints,
                term_floats: Array, t_inv: Array, friction: Array, coulomb: Array,
                smoothing: float, frame: tuple[int, Array] | None = None
                ) -> tuple[Ints, Array]:
    """The law's constant tables in the two arrays ``law_tables`` and ``model_tables`` read;
    ``t_inv`` T⁻¹ of the coordinates x = T q, ``friction`` F_d in x-coordinates,
    ``coulomb`` F_c per joint and ``smoothing`` its ε (cpbc.kernels.coordinate_maps
    .joint_friction) and ``frame`` the column and place of the frame the law reads, when
    the kernel computes it from the joint kinematics (cpbc.kernels.task.frame_on_joints)."""
    n = len(t_inv)
    header = [margins]
    for table in (plan, ints, floats, term_plan, term_floats):
        header += table.shape
    column, local = (-1, np.zeros(PLACE + n)) if frame is None else frame
    header += [int(np.array_equal(t_inv, np.eye(n))),
               int(np.any(friction) or np.any(coulomb)), column]
    packed_ints = np.concatenate([np.array(header, dtype=np.int64), plan.ravel(),
                                  ints.ravel(), term_plan.ravel()]).astype(np.int64)
    return packed_ints, np.concatenate([floats.ravel(), term_floats.ravel(), t_inv.ravel(),
                                        friction.ravel(), coulomb, [smoothing],
                                        local]).astype(float)


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


MODEL = ("Tuple((boolean, boolean, float64[:, :], float64[:, :], float64[::1], float64,"
         " float64[::1]))")


@inner(f"{MODEL}(int64[::1], float64[::1], int64)")
def model_tables(ints: Ints, floats: Array, n: int
                 ) -> tuple[bool, bool, Array, Array, Array, float, Array]:
    """Whether the coordinates are the joints' and whether the arm has friction, T⁻¹, F_d,
    F_c, its ε and the frame's place on its joint (views), packed by ``pack_tables``."""
    at = floats.shape[0] - 2 * n * n - n - 1 - PLACE - n
    friction_at = at + 2 * n * n
    return (ints[COORDINATES] == 1, ints[COORDINATES + 1] == 1,
            float_rows(floats, at, n, n), float_rows(floats, at + n * n, n, n),
            floats[friction_at:friction_at + n], floats[friction_at + n],
            floats[friction_at + n + 1:])


@inner("UniTuple(float64[:, :], 2)(int64[::1], float64[:], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :], float64[::1])")
def pass_frame(ints: Ints, x: Array, placement: Array, frame_jacobian_q: Array, y: Array,
               jac: Array, local: Array) -> tuple[Array, Array]:
    """The frame's placement and Jacobian (joint coordinates): the pass's, or — when the
    tables give its joint's column — from the pass's joint kinematics
    (cpbc.kernels.task.frame_on_joints)."""
    column = ints[FRAME_COLUMN]
    if column < 0:
        return placement, frame_jacobian_q
    work = np.empty(16 + 6 * x.shape[0])
    placement, frame_jacobian_q = float_rows(work, 0, 4, 4), float_rows(work, 16, 6, x.shape[0])
    frame_on_joints(y, jac, column, local, placement, frame_jacobian_q)
    return placement, frame_jacobian_q


# the tables, x, ẋ, D, g, C ẋ, f, C, the frame's placement and Jacobian, the joint
# placements and Jacobians, ``barriers`` [φ̃ (margins) | the margins (or nothing)] and τ
STEP = ("int64[::1], float64[::1], float64[:], float64[:], float64[:, :], float64[:],"
        f" float64[:], {READ_ONLY}, float64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :], float64[::1], float64[:]")


@kernel(f"UniTuple(float64, 3)({STEP})")
def cpbc_step(tables: Ints, table_floats: Array, x: Array, dx: Array, inertia: Array,
              gravity: Array, coriolis_force: Array, dissipation: Array, coriolis: Array,
              placement: Array, frame_jacobian: Array, y: Array, jac: Array, barriers: Array,
              tau: Array) -> tuple[float, float, float]:
    """One CPBC step (cpbc.controllers.cpbc.CPBC): the set's barrier sums (``set_barrier``,
    its tables ``plan``, ``ints``, ``floats``), U and ∂U/∂x, the damping and the shaping of
    the packed terms (cpbc.kernels.law_terms), L = ½ẋᵀDẋ + U, ρ = r(ΦΨ)·L and τ
    (``cpbc_torque``, c = C ẋ + f) into ``tau``. The tables (``law_tables``) are packed
    by ``pack_tables``. The frame: its placement [R p; 0 1] and Jacobian [J_v; J_ω].
    ``barriers``: the barrier values φ̃, then — when it is twice as long — the margins.
    Returns V, log Φ and log Ψ; outside S (a NaN log) V is NaN and τ is not written (the
    caller raises, naming the margin from φ̃)."""
    n = x.shape[0]
    margins, plan, ints, floats, term_plan, term_floats = law_tables(tables, table_floats)
    phi, value = barriers[:margins], barriers[margins:]
    origin, rotation = placement[:3, 3], placement[:3, :3]
    work = np.empty(5 * n + n * n)  # one allocation for the step's arrays
    gradient, grad, damping, bias = work[:n], work[n:2 * n], work[2 * n:3 * n], work[3 * n:4 * n]
    part, weight = work[4 * n:5 * n], float_rows(work, 5 * n, n, n)
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
                 inertia: Array, gravity: Array, coriolis_force: Array, dissipation: Array,
                 coriolis: Array, placement: Array, frame_jacobian: Array, y: Array,
                 jac: Array, barriers: Array, tau: Array) -> tuple[float, float, float]:
    """One CPBC-KE step (cpbc.controllers.cpbc_ke.CPBCKineticEnergy): ψ = Ω − ½ẋᵀDẋ
    (``limit`` Ω), the configuration constraints' barrier sums (``set_barrier``), U, ∂U/∂x,
    the damping and the shaping of the packed terms, ρ = r(Φψ)·L and τ (``cpbc_ke_torque``)
    into ``tau`` (``cpbc_step``'s arguments). Returns V, log Φ and ψ; when ψ ≤ 0 or
    log Φ is NaN, V is NaN and τ is not written (the caller raises)."""
    n = x.shape[0]
    kinetic = kinetic_energy(inertia, dx)
    psi = limit - kinetic
    if not psi > 0.0:
        return math.nan, 0.0, psi
    margins, plan, ints, floats, term_plan, term_floats = law_tables(tables, table_floats)
    phi, value = barriers[:margins], barriers[margins:]
    origin, rotation = placement[:3, 3], placement[:3, :3]
    work = np.empty(4 * n)  # one allocation for the step's arrays (Π is empty)
    gradient, grad, damping, part = work[:n], work[n:2 * n], work[2 * n:3 * n], work[3 * n:]
    weight = float_rows(work, 0, 0, 0)
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


# the tables, x, ẋ, and one Pinocchio pass in joint coordinates (RobotModel.joint_pass): D,
# nle = C q̇ + g, g, C (or empty), the frame's placement and Jacobian, the joint placements
# and Jacobians; then ``barriers`` and τ as in STEP
PASS = ("int64[::1], float64[::1], float64[:], float64[:], float64[:, :], float64[:],"
        " float64[:], float64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :], float64[::1], float64[:]")


FINISHED = ("Tuple((float64[:, :], float64[:, :], float64[:], float64[:], float64[:, :],"
            " float64[:, :], float64[:]))")


@inner(f"{FINISHED}(int64[::1], float64[::1], float64[:], float64[:], float64[:, :],"
        " float64[:], float64[:], float64[:, :], float64[:, :], float64[:, :], float64[:, :],"
        " float64[:, :])")
def finished_state(tables: Ints, table_floats: Array, x: Array, dx: Array,
                   inertia_q: Array, nle: Array, gravity_q: Array, coriolis_q: Array,
                   placement: Array, frame_jacobian_q: Array, y: Array, jac: Array
                   ) -> tuple[Array, Array, Array, Array, Array, Array, Array]:
    """The step's state from the pass itself: the frame's placement (``pass_frame``), then D,
    C ẋ, g, C, the frame's Jacobian and f in controller coordinates
    (cpbc.kernels.coordinate_maps.controller_terms, with the model's tables)."""
    joints, friction, t_inv, friction_matrix, coulomb, smoothing, local = model_tables(
        tables, table_floats, x.shape[0])
    placement, frame_jacobian_q = pass_frame(tables, x, placement, frame_jacobian_q, y, jac,
                                             local)
    inertia, bias, gravity, coriolis, frame_jacobian, dissipation = controller_terms(
        joints, friction, t_inv, friction_matrix, coulomb, smoothing, dx, inertia_q, nle,
        gravity_q, coriolis_q, frame_jacobian_q)
    return placement, inertia, bias, gravity, coriolis, frame_jacobian, dissipation


@kernel(f"UniTuple(float64, 3)({PASS})")
def cpbc_pass_step(tables: Ints, table_floats: Array, x: Array, dx: Array,
                   inertia_q: Array, nle: Array, gravity_q: Array, coriolis_q: Array,
                   placement: Array, frame_jacobian_q: Array, y: Array, jac: Array,
                   barriers: Array, tau: Array) -> tuple[float, float, float]:
    """``cpbc_step`` from the pass itself (``finished_state``)."""
    placement, inertia, bias, gravity, coriolis, frame_jacobian, dissipation = (
        finished_state(tables, table_floats, x, dx, inertia_q, nle, gravity_q, coriolis_q,
                       placement, frame_jacobian_q, y, jac))
    return cpbc_step(tables, table_floats, x, dx, inertia, gravity, bias, dissipation,
                     coriolis, placement, frame_jacobian, y, jac, barriers, tau)


@kernel(f"UniTuple(float64, 3)(float64, {PASS})")
def cpbc_ke_pass_step(limit: float, tables: Ints, table_floats: Array, x: Array, dx: Array,
                      inertia_q: Array, nle: Array, gravity_q: Array, coriolis_q: Array,
                      placement: Array, frame_jacobian_q: Array, y: Array, jac: Array,
                      barriers: Array, tau: Array) -> tuple[float, float, float]:
    """``cpbc_ke_step`` from the pass itself (``finished_state``)."""
    placement, inertia, bias, gravity, coriolis, frame_jacobian, dissipation = (
        finished_state(tables, table_floats, x, dx, inertia_q, nle, gravity_q, coriolis_q,
                       placement, frame_jacobian_q, y, jac))
    return cpbc_ke_step(limit, tables, table_floats, x, dx, inertia, gravity, bias,
                        dissipation, coriolis, placement, frame_jacobian, y, jac, barriers,
                        tau)
