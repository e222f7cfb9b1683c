"""A law's potential and damping from its packed constants (cpbc.controllers.packed_law),
for the laws' one kernel call per step (cpbc.kernels.laws): each term by its own kind's row
reader, beside its formula, its code and its tables (``pack_*``) — the joint terms and the
ln cosh position spring (which shares their ln cosh sum) here, the other frame terms in
cpbc.kernels.task, the shaping's formula in cpbc.kernels.barrier_shaping.

The terms are packed like a constraint set (cpbc.kernels.plan_tables). The registry of the kinds
a law's plan holds (a new term with a kernel is its formula, its ``pack_*`` and its row
reader, and two lines here: its code in its list, its row in ``potential_terms``' or
``damping_terms``' dispatch): ``POTENTIAL_KINDS``, ``DAMPING_KINDS``, ``SHAPING``;
``FRAME_KINDS`` read the one frame the caller passes (origin, axes, [J_v; J_ω]).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel
from cpbc.kernels.barrier_shaping import shaping_terms
from cpbc.kernels.plan_tables import KIND, Ints, Packed, float_table
from cpbc.kernels.python_rows import (
    PYTHON_DAMPING,
    PYTHON_POTENTIAL,
    python_damping_row,
    python_potential_row,
)
from cpbc.kernels.task import (
    AXIS_SPRING,
    FRAME,
    ORIENTATION_SPRING,
    POSITION_SPRING,
    ROW,
    TASK_DAMPING,
    TASK_TANH_DAMPING,
    axis_spring_row,
    orientation_spring_row,
    point_on_frame,
    position_spring_row,
    task_damping_row,
    task_tanh_damping_row,
)


@kernel(f"float64({READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def joint_spring(x: Array, goal: Array, stiffness: Array, grad: Array) -> float:
    """U = ½ x̃ᵀ K x̃, x̃ = x − x_d (eq. 6.7), K diagonal: returns U, writes ∂U/∂x = K x̃
    into ``grad``."""
    total = 0.0
    for i in range(x.shape[0]):
        e = x[i] - goal[i]
        g = stiffness[i] * e
        grad[i] = g
        total += e * g
    return 0.5 * total


JOINT_SPRING = 0  # its code; its table: [x_dᵀ; K] (2, n)
JOINT_SPRING_TABLE = 0


def pack_joint_spring(goal: Array, stiffness: Array, moving: bool = False) -> Packed:
    """The joint spring's table (``moving``: x_d read from ``goal`` before each step)."""
    return Packed(JOINT_SPRING, (np.vstack([goal, stiffness]),),
                  live=((JOINT_SPRING_TABLE, goal),) if moving else ())


@inner(f"float64({ROW})")
def joint_spring_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                     rotation: Array, jacobian: Array, grad: Array) -> float:
    """A packed joint spring (``joint_spring``)."""
    table = float_table(plan, floats, row, JOINT_SPRING_TABLE)
    return joint_spring(x, table[0], table[1], grad)


@inner("float64(float64, float64)")
def log_add_exp(a: float, b: float) -> float:
    """ln(eᵃ + eᵇ) without overflow (numpy.logaddexp's formula)."""
    if a == b:
        return a + math.log(2.0)
    t = a - b
    if t > 0.0:
        return a + math.log1p(math.exp(-t))
    if t <= 0.0:
        return b + math.log1p(math.exp(t))
    return t  # NaN


@kernel(f"float64({READ_ONLY}, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64, float64[:])")
def log_cosh_sum(err: Array, stiffness: Array, xi: Array, weight: Array, offset: float,
                 grad: Array) -> float:
    """U(e) = Σ (K_i/ξ_i) ln cosh(ξ_i e_i) (eq. 7.18), with ``weight`` K/ξ and ``offset``
    Σ K_i/ξ_i · ln 2, ln cosh y = ln(eʸ + e⁻ʸ) − ln 2 (no overflow); ∂U/∂e = K tanh(Ξe)
    into ``grad``; returns U."""
    total = 0.0
    for i in range(err.shape[0]):
        y = xi[i] * err[i]
        total += weight[i] * log_add_exp(y, -y)
        grad[i] = stiffness[i] * np.tanh(y)
    return total - offset


LOG_COSH_SPRING = 8  # its code; its tables: [x_dᵀ; K; ξ; K/ξ] (4, n), Σ K_i/ξ_i · ln 2
LOG_COSH_TABLE, LOG_COSH_OFFSET = range(2)


def pack_log_cosh_spring(goal: Array, gains: Array, offset: Array, moving: bool = False
                         ) -> Packed:
    """The joint ln cosh spring's tables, ``gains`` [K; ξ; K/ξ], ``offset`` (1, 1)
    (``moving``: x_d read from ``goal`` before each step)."""
    return Packed(LOG_COSH_SPRING, (np.vstack([goal, gains]), offset),
                  live=((LOG_COSH_TABLE, goal),) if moving else ())


@inner(f"float64({ROW})")
def log_cosh_spring_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                        rotation: Array, jacobian: Array, grad: Array) -> float:
    """A packed joint ln cosh spring (``log_cosh_sum`` on x − x_d, eq. 7.18)."""
    table = float_table(plan, floats, row, LOG_COSH_TABLE)
    err = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        err[i] = x[i] - table[0, i]
    return log_cosh_sum(err, table[1], table[2], table[3],
                        float_table(plan, floats, row, LOG_COSH_OFFSET)[0, 0], grad)


@kernel(f"float64({FRAME}, {READ_ONLY}, {READ_ONLY}, {READ_ONLY_MATRIX}, float64, float64[:])")
def position_log_cosh(origin: Array, rotation: Array, jacobian: Array, offset: Array,
                      goal: Array, gains: Array, log_offset: float, grad: Array) -> float:
    """U = Σ (K_i/ξ_i) ln cosh(ξ_i e_i), e = p − p_d (``log_cosh_sum``, eq. 7.18 on the
    point's position error; ``gains`` [K; ξ; K/ξ] (3, 3), ``log_offset`` Σ K_i/ξ_i · ln 2),
    ∂U/∂x = J_pᵀ K tanh(Ξe) into ``grad``; returns U."""
    n = grad.shape[0]
    point, linear = np.empty(3), np.empty((3, n))
    point_on_frame(origin, rotation, jacobian, offset, point, linear)
    err, force = np.empty(3), np.empty(3)
    for i in range(3):
        err[i] = point[i] - goal[i]
    u = log_cosh_sum(err, gains[0], gains[1], gains[2], log_offset, force)
    for k in range(n):
        grad[k] = linear[0, k] * force[0] + linear[1, k] * force[1] + linear[2, k] * force[2]
    return u


POSITION_LOG_COSH = 9  # its code; its tables: the point (1, 4), p_d (1, 3), [K; ξ; K/ξ]
COSH_POINT, COSH_GOAL, COSH_GAINS, COSH_OFFSET = range(4)  # (3, 3), Σ K_i/ξ_i · ln 2 (1, 1)


def pack_position_log_cosh(point: Array, goal: Array, gains: Array, log_offset: float,
                           frame: int, moving: bool = False) -> Packed:
    """The ln cosh position spring's tables on ``frame`` (``moving``: p_d read from
    ``goal`` before each step)."""
    return Packed(POSITION_LOG_COSH, (point[None, :], goal[None, :], gains,
                                      np.array([[log_offset]])),
                  frame=frame, live=((COSH_GOAL, goal),) if moving else ())


@inner(f"float64({ROW})")
def position_log_cosh_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                          rotation: Array, jacobian: Array, grad: Array) -> float:
    """A packed ln cosh position spring (``position_log_cosh``)."""
    return position_log_cosh(origin, rotation, jacobian,
                             float_table(plan, floats, row, COSH_POINT)[0],
                             float_table(plan, floats, row, COSH_GOAL)[0],
                             float_table(plan, floats, row, COSH_GAINS),
                             float_table(plan, floats, row, COSH_OFFSET)[0, 0], grad)


@kernel(f"void({READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def joint_feedforward(gain: Array, velocity: Array, force: Array) -> None:
    """−K_D ẋ_n,ff, K_D diagonal, into ``force``: the joint damping's share of a posture
    moving at ẋ_n,ff (K_D (ẋ − ẋ_n,ff) in all)."""
    for i in range(velocity.shape[0]):
        force[i] = -gain[i] * velocity[i]


JOINT_FEEDFORWARD = 11  # its code; its tables: K_D (1, n), ẋ_n,ff (1, n)
FEEDFORWARD_GAIN, FEEDFORWARD_VELOCITY = range(2)


def pack_joint_feedforward(gain: Array, velocity: Array) -> Packed:
    """The joint feed-forward's tables, ẋ_n,ff read from ``velocity`` before each step."""
    return Packed(JOINT_FEEDFORWARD, (gain[None, :], velocity[None, :]),
                  live=((FEEDFORWARD_VELOCITY, velocity),))


@inner(f"void({ROW})")
def joint_feedforward_row(plan: Ints, floats: Array, row: int, dx: Array, origin: Array,
                          rotation: Array, jacobian: Array, force: Array) -> None:
    """A packed joint feed-forward (``joint_feedforward``)."""
    joint_feedforward(float_table(plan, floats, row, FEEDFORWARD_GAIN)[0],
                      float_table(plan, floats, row, FEEDFORWARD_VELOCITY)[0], force)


@kernel(f"void({READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def joint_damping(gain: Array, dx: Array, force: Array) -> None:
    """K_D ẋ (eq. 6.10), K_D diagonal, into ``force``."""
    for i in range(dx.shape[0]):
        force[i] = gain[i] * dx[i]


JOINT_DAMPING = 4  # its code; its table: K_D (1, n)
JOINT_DAMPING_GAIN = 0


def pack_joint_damping(gain: Array) -> Packed:
    """The joint damping's table."""
    return Packed(JOINT_DAMPING, (gain[None, :],))


@inner(f"void({ROW})")
def joint_damping_row(plan: Ints, floats: Array, row: int, dx: Array, origin: Array,
                      rotation: Array, jacobian: Array, force: Array) -> None:
    """A packed joint damping (``joint_damping``)."""
    joint_damping(float_table(plan, floats, row, JOINT_DAMPING_GAIN)[0], dx, force)


@kernel(f"void({READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def tanh_damping(gain: Array, gamma: Array, dx: Array, force: Array) -> None:
    """K_D tanh(Γ ẋ) (eq. 7.17), bounded by K_D, into ``force``."""
    for i in range(dx.shape[0]):
        force[i] = gain[i] * np.tanh(gamma[i] * dx[i])


TANH_DAMPING = 5  # its code; its table: [K_D; Γ] (2, n)
TANH_DAMPING_TABLE = 0


def pack_tanh_damping(gain: Array, gamma: Array) -> Packed:
    """The bounded joint damping's table."""
    return Packed(TANH_DAMPING, (np.vstack([gain, gamma]),))


@inner(f"void({ROW})")
def tanh_damping_row(plan: Ints, floats: Array, row: int, dx: Array, origin: Array,
                     rotation: Array, jacobian: Array, force: Array) -> None:
    """A packed bounded joint damping (``tanh_damping``)."""
    table = float_table(plan, floats, row, TANH_DAMPING_TABLE)
    tanh_damping(table[0], table[1], dx, force)


SHAPING = 7  # its code; its table: [kind parameter] (1, 2) (cpbc.kernels.barrier_shaping)
SHAPING_TABLE = 0


def pack_shaping(kind: int, parameter: float) -> Packed:
    """The shaping's table."""
    return Packed(SHAPING, (np.array([[float(kind), float(parameter)]]),))


# -- the registry ---------------------------------------------------------------------------
POTENTIAL_KINDS = (JOINT_SPRING, POSITION_SPRING, AXIS_SPRING, ORIENTATION_SPRING,
                   LOG_COSH_SPRING, POSITION_LOG_COSH, PYTHON_POTENTIAL)
DAMPING_KINDS = (JOINT_DAMPING, TANH_DAMPING, TASK_DAMPING, JOINT_FEEDFORWARD,
                 TASK_TANH_DAMPING, PYTHON_DAMPING)
FRAME_KINDS = (POSITION_SPRING, AXIS_SPRING, ORIENTATION_SPRING, TASK_DAMPING,
               POSITION_LOG_COSH, TASK_TANH_DAMPING)
KINDS = (*POTENTIAL_KINDS, *DAMPING_KINDS, SHAPING)


@inner(f"float64(int64[:, :], float64[:, :], float64[:], {FRAME}, float64[:], float64[:])")
def potential_terms(plan: Ints, floats: Array, x: Array, origin: Array, rotation: Array,
                    jacobian: Array, grad: Array, part: Array) -> float:
    """U = Σ U_k of the packed springs (the other rows are skipped), ∂U/∂x = Σ ∂U_k/∂x into
    ``grad``, added in the plan's order (as cpbc.controllers.potentials.PotentialSum);
    ``part`` (n,) is work space."""
    n = x.shape[0]
    for i in range(n):
        grad[i] = 0.0
    total = 0.0
    for r in range(plan.shape[0]):
        kind = plan[r, KIND]
        if kind == JOINT_SPRING:
            u = joint_spring_row(plan, floats, r, x, origin, rotation, jacobian, part)
        elif kind == POSITION_SPRING:
            u = position_spring_row(plan, floats, r, x, origin, rotation, jacobian, part)
        elif kind == AXIS_SPRING:
            u = axis_spring_row(plan, floats, r, x, origin, rotation, jacobian, part)
        elif kind == LOG_COSH_SPRING:
            u = log_cosh_spring_row(plan, floats, r, x, origin, rotation, jacobian, part)
        elif kind == ORIENTATION_SPRING:
            u = orientation_spring_row(plan, floats, r, x, origin, rotation, jacobian, part)
        elif kind == POSITION_LOG_COSH:
            u = position_log_cosh_row(plan, floats, r, x, origin, rotation, jacobian, part)
        elif kind == PYTHON_POTENTIAL:
            u = python_potential_row(plan, floats, r, x, origin, rotation, jacobian, part)
        else:
            continue
        total += u
        for i in range(n):
            grad[i] += part[i]
    return total


@inner(f"void(int64[:, :], float64[:, :], float64[:], {FRAME}, float64[:], float64[:])")
def damping_terms(plan: Ints, floats: Array, dx: Array, origin: Array, rotation: Array,
                  jacobian: Array, force: Array, part: Array) -> None:
    """The joint damping plus the task damping of the packed terms (the other rows are
    skipped), added in the plan's order, into ``force``; ``part`` (n,) is work space."""
    n = dx.shape[0]
    for i in range(n):
        force[i] = 0.0
    for r in range(plan.shape[0]):
        kind = plan[r, KIND]
        if kind == JOINT_DAMPING:
            joint_damping_row(plan, floats, r, dx, origin, rotation, jacobian, part)
        elif kind == TANH_DAMPING:
            tanh_damping_row(plan, floats, r, dx, origin, rotation, jacobian, part)
        elif kind == TASK_DAMPING:
            task_damping_row(plan, floats, r, dx, origin, rotation, jacobian, part)
        elif kind == JOINT_FEEDFORWARD:
            joint_feedforward_row(plan, floats, r, dx, origin, rotation, jacobian, part)
        elif kind == TASK_TANH_DAMPING:
            task_tanh_damping_row(plan, floats, r, dx, origin, rotation, jacobian, part)
        elif kind == PYTHON_DAMPING:
            python_damping_row(plan, floats, r, dx, origin, rotation, jacobian, part)
        else:
            continue
        for i in range(n):
            force[i] += part[i]


@inner("UniTuple(float64, 2)(int64[:, :], float64[:, :], float64)")
def shaped(plan: Ints, floats: Array, log_x: float) -> tuple[float, float]:
    """r(x) and log s(x) of the packed shaping (cpbc.kernels.barrier_shaping.shaping_terms); those
    of s(x) = x when none is packed."""
    for r in range(plan.shape[0]):
        if plan[r, KIND] == SHAPING:
            row = float_table(plan, floats, r, SHAPING_TABLE)[0]
            return shaping_terms(int(row[0]), row[1], log_x)
    return shaping_terms(0, 0.0, log_x)
