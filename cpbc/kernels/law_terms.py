"""A law's potential and damping from its packed constants (cpbc.controllers.packed_law),
for the laws' one kernel call per step (cpbc.kernels.laws): each term by its own kind's
kernel (the joint terms here, and the ln cosh position spring, which shares their ln cosh
sum; the other frame terms in cpbc.kernels.task; the shaping in cpbc.kernels.barrier_shaping).

The terms are packed like a constraint set (cpbc.constraints.packing): ``plan`` has one row
per term, [kind, 0, 0, (row, rows, columns) of each float table …], the tables stacked in
``floats``. The kinds and their tables:

- ``JOINT_SPRING``: [x_dᵀ; K] (2, n) (``joint_spring``, eq. 6.7);
- ``POSITION_SPRING``: [o has_offset] (1, 4), p_d (1, 3), K (3, 3) (``position_spring``);
- ``AXIS_SPRING``: [a_bᵀ; a_wᵀ] (2, 3), k (1, 1) (``axis_spring``);
- ``ORIENTATION_SPRING``: R_d (3, 3), k (1, 1) (``orientation_spring``);
- ``LOG_COSH_SPRING``: [x_dᵀ; K; ξ; K/ξ] (4, n), Σ K_i/ξ_i · ln 2 (1, 1) (``log_cosh_sum``
  on x − x_d, eq. 7.18);
- ``POSITION_LOG_COSH``: [o has_offset] (1, 4), p_d (1, 3), [K; ξ; K/ξ] (3, 3),
  Σ K_i/ξ_i · ln 2 (1, 1) (``position_log_cosh``, eq. 7.18 on p − p_d);
- ``JOINT_DAMPING``: K_D (1, n) (``joint_damping``, eq. 6.10);
- ``TANH_DAMPING``: [K_D; Γ] (2, n) (``tanh_damping``, eq. 7.17);
- ``TASK_DAMPING``: [o has_offset] (1, 4), G (6, 6), ṗ_ff (1, 3) or [ṗ_ffᵀ ω_ffᵀ] (1, 6)
  (``task_damping``);
- ``JOINT_FEEDFORWARD``: K_D (1, n), ẋ_n,ff (1, n) (``joint_feedforward``: a moving
  posture's share of the damping, cpbc.reference.target.SteeredDamping);
- ``TASK_TANH_DAMPING``: [o has_offset] (1, 4), [diag D_x; diag Γ_x] (2, 3), ṗ_ff (1, 3)
  (``task_tanh_damping``);
- ``SHAPING``: [kind parameter] (1, 2) (cpbc.kernels.barrier_shaping).

Every frame term reads the one frame the caller passes (origin, axes, [J_v; J_ω]).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel
from cpbc.kernels.barrier_set import float_table
from cpbc.kernels.barrier_shaping import shaping_terms
from cpbc.kernels.clearance import Ints
from cpbc.kernels.task import (
    axis_spring,
    orientation_spring,
    point_on_frame,
    position_spring,
    task_damping,
    task_tanh_damping,
)

JOINT_SPRING, POSITION_SPRING, AXIS_SPRING, ORIENTATION_SPRING = 0, 1, 2, 3
JOINT_DAMPING, TANH_DAMPING, TASK_DAMPING, SHAPING = 4, 5, 6, 7
LOG_COSH_SPRING, POSITION_LOG_COSH, TASK_TANH_DAMPING, JOINT_FEEDFORWARD = 8, 9, 10, 11
FRAME_KINDS = (POSITION_SPRING, AXIS_SPRING, ORIENTATION_SPRING, TASK_DAMPING,
               POSITION_LOG_COSH, TASK_TANH_DAMPING)
FRAME = f"{READ_ONLY}, {READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}"


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


@kernel(f"void({READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def joint_feedforward(gain: Array, velocity: Array, force: Array) -> None:
    """−K_D ẋ_n,ff, K_D diagonal, into ``force``: the joint damping's share of a posture
    moving at ẋ_n,ff (K_D (ẋ − ẋ_n,ff) in all)."""
    for i in range(velocity.shape[0]):
        force[i] = -gain[i] * velocity[i]


@kernel(f"void({READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def joint_damping(gain: Array, dx: Array, force: Array) -> None:
    """K_D ẋ (eq. 6.10), K_D diagonal, into ``force``."""
    for i in range(dx.shape[0]):
        force[i] = gain[i] * dx[i]


@kernel(f"void({READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64[:])", inline=True)
def tanh_damping(gain: Array, gamma: Array, dx: Array, force: Array) -> None:
    """K_D tanh(Γ ẋ) (eq. 7.17), bounded by K_D, into ``force``."""
    for i in range(dx.shape[0]):
        force[i] = gain[i] * np.tanh(gamma[i] * dx[i])


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
        kind = plan[r, 0]
        first = float_table(plan, floats, r, 0)
        if kind == JOINT_SPRING:
            u = joint_spring(x, first[0], first[1], part)
        elif kind == POSITION_SPRING:
            u = position_spring(origin, rotation, jacobian, first[0],
                                float_table(plan, floats, r, 1)[0],
                                float_table(plan, floats, r, 2), part)
        elif kind == AXIS_SPRING:
            u = axis_spring(rotation, jacobian, first[0], first[1],
                            float_table(plan, floats, r, 1)[0, 0], part)
        elif kind == LOG_COSH_SPRING:
            err = np.empty(n)
            for i in range(n):
                err[i] = x[i] - first[0, i]
            u = log_cosh_sum(err, first[1], first[2], first[3],
                             float_table(plan, floats, r, 1)[0, 0], part)
        elif kind == ORIENTATION_SPRING:
            u = orientation_spring(rotation, jacobian, first,
                                   float_table(plan, floats, r, 1)[0, 0], part)
        elif kind == POSITION_LOG_COSH:
            u = position_log_cosh(origin, rotation, jacobian, first[0],
                                  float_table(plan, floats, r, 1)[0],
                                  float_table(plan, floats, r, 2),
                                  float_table(plan, floats, r, 3)[0, 0], part)
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
        kind = plan[r, 0]
        first = float_table(plan, floats, r, 0)
        if kind == JOINT_DAMPING:
            joint_damping(first[0], dx, part)
        elif kind == TANH_DAMPING:
            tanh_damping(first[0], first[1], dx, part)
        elif kind == TASK_DAMPING:
            task_damping(origin, rotation, jacobian, first[0], float_table(plan, floats, r, 1),
                         float_table(plan, floats, r, 2)[0], dx, part)
        elif kind == JOINT_FEEDFORWARD:
            joint_feedforward(first[0], float_table(plan, floats, r, 1)[0], part)
        elif kind == TASK_TANH_DAMPING:
            task_tanh_damping(origin, rotation, jacobian, first[0],
                              float_table(plan, floats, r, 1),
                              float_table(plan, floats, r, 2)[0], dx, part)
        else:
            continue
        for i in range(n):
            force[i] += part[i]


@inner("UniTuple(float64, 2)(int64[:, :], float64[:, :], float64)")
def shaped(plan: Ints, floats: Array, log_x: float) -> tuple[float, float]:
    """r(x) and log s(x) of the packed shaping (cpbc.kernels.barrier_shaping.shaping_terms); those
    of s(x) = x when none is packed."""
    for r in range(plan.shape[0]):
        if plan[r, 0] == SHAPING:
            row = float_table(plan, floats, r, 0)[0]
            return shaping_terms(int(row[0]), row[1], log_x)
    return shaping_terms(0, 0.0, log_x)
