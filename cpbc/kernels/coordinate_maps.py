"""The per-step state's change of coordinates x = T q (cpbc.model.coordinates: the thesis's
planar arm in absolute link angles): D_x = T⁻ᵀ D_q T⁻¹, g_x = T⁻ᵀ g_q, C ẋ = T⁻ᵀ (C q̇),
and the joints' friction f(ẋ) in those coordinates."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel
from cpbc.kernels.views import float_rows


@kernel(f"void({READ_ONLY_MATRIX}, float64[:], float64[:], float64[:], float64[:])")
def to_joint(t_inv: Array, x: Array, dx: Array, q: Array, dq: Array) -> None:
    """q = T⁻¹ x and q̇ = T⁻¹ ẋ into ``q``, ``dq``."""
    n = x.shape[0]
    for i in range(n):
        a, b = 0.0, 0.0
        for j in range(n):
            a += t_inv[i, j] * x[j]
            b += t_inv[i, j] * dx[j]
        q[i] = a
        dq[i] = b


@inner(f"void({READ_ONLY_MATRIX}, float64[:, :], float64[:, :])")
def congruence(t_inv: Array, matrix_q: Array, matrix: Array) -> None:
    """M_x = T⁻ᵀ M_q T⁻¹ into ``matrix`` (a matrix of the joints' generalised forces)."""
    n = matrix_q.shape[0]
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                row = 0.0
                for m in range(n):
                    row += matrix_q[k, m] * t_inv[m, j]
                s += t_inv[k, i] * row
            matrix[i, j] = s


@kernel(f"void({READ_ONLY_MATRIX}, float64[:, :], float64[:], float64[:], float64[:, :],"
        " float64[:], float64[:])", inline=True)
def to_controller(t_inv: Array, inertia_q: Array, nle: Array, gravity_q: Array,
                  inertia: Array, bias: Array, gravity: Array) -> None:
    """D_x = T⁻ᵀ D_q T⁻¹ into ``inertia``, C ẋ = T⁻ᵀ (nle − g_q) into ``bias`` and
    g_x = T⁻ᵀ g_q into ``gravity``, from Pinocchio's D_q, nle = C q̇ + g_q and g_q."""
    n = nle.shape[0]
    for i in range(n):
        b, g = 0.0, 0.0
        for k in range(n):
            b += t_inv[k, i] * (nle[k] - gravity_q[k])
            g += t_inv[k, i] * gravity_q[k]
        bias[i] = b
        gravity[i] = g
    congruence(t_inv, inertia_q, inertia)


@kernel(f"void(boolean, {READ_ONLY_MATRIX}, {READ_ONLY_MATRIX}, {READ_ONLY}, float64,"
        f" {READ_ONLY}, float64[:])", inline=True)
def joint_friction(joints: bool, t_inv: Array, friction_matrix: Array, coulomb: Array,
                   smoothing: float, dx: Array, dissipation: Array) -> None:
    """f(ẋ) = F_d ẋ + T⁻ᵀ F_c tanh(T⁻¹ẋ / ε) into ``dissipation`` (eq. 6.1's f): viscous
    friction F_d (x-coordinates, ``friction_matrix``) and each joint's Coulomb friction F_c
    (``coulomb``, joint coordinates) with its sign smoothed over ε (``smoothing``, rad/s).
    Dissipative, as Theorems 6.9 and 7.7 ask (ẋᵀf ≥ 0): ẋᵀ F_d ẋ ≥ 0 and
    ẋᵀ T⁻ᵀ F_c tanh(q̇/ε) = Σ F_c,i q̇_i tanh(q̇_i/ε) ≥ 0."""
    n = dx.shape[0]
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += friction_matrix[i, j] * dx[j]
        dissipation[i] = s
    for k in range(n):
        if coulomb[k] == 0.0:
            continue
        rate = dx[k]
        if not joints:
            rate = 0.0
            for j in range(n):
                rate += t_inv[k, j] * dx[j]
        force = coulomb[k] * math.tanh(rate / smoothing)
        if joints:
            dissipation[k] += force
        else:
            for i in range(n):
                dissipation[i] += t_inv[k, i] * force


TERMS = ("Tuple((float64[:, :], float64[:], float64[:], float64[:, :], float64[:, :],"
         " float64[:]))")


@inner(f"{TERMS}(boolean, boolean, float64[:, :], float64[:, :], float64[:], float64,"
        " float64[:], float64[:, :], float64[:], float64[:], float64[:, :], float64[:, :])")
def controller_terms(joints: bool, friction: bool, t_inv: Array, friction_matrix: Array,
                     coulomb: Array, smoothing: float, dx: Array, inertia_q: Array,
                     nle: Array, gravity_q: Array, coriolis_q: Array,
                     frame_jacobian_q: Array
                     ) -> tuple[Array, Array, Array, Array, Array, Array]:
    """The per-step state's terms from one Pinocchio pass in joint coordinates
    (cpbc.model.robot_model.RobotModel.joint_pass), as ``RobotModel.state`` gives them: D,
    C ẋ and g (``to_controller``), the matrix C = T⁻ᵀ C_q T⁻¹ (empty when not asked for),
    the frame's Jacobian J_q T⁻¹ and f (``joint_friction``; zero without ``friction``).
    With the joints as coordinates (``joints``) D, g, C and the Jacobian are the pass's own
    arrays."""
    n = dx.shape[0]
    c_rows, (rows, columns) = coriolis_q.shape[0], frame_jacobian_q.shape
    # one allocation for the terms this makes
    work = np.empty(2 * n if joints else 3 * n + n * n + c_rows * c_rows + rows * columns)
    dissipation, bias = work[:n], work[n:2 * n]
    if friction:
        joint_friction(joints, t_inv, friction_matrix, coulomb, smoothing, dx, dissipation)
    else:
        dissipation[:] = 0.0
    if joints:
        for i in range(n):
            bias[i] = nle[i] - gravity_q[i]
        return inertia_q, bias, gravity_q, coriolis_q, frame_jacobian_q, dissipation
    gravity = work[2 * n:3 * n]
    at = 3 * n
    inertia = float_rows(work, at, n, n)
    at += n * n
    coriolis = float_rows(work, at, c_rows, c_rows)
    at += c_rows * c_rows
    frame_jacobian = float_rows(work, at, rows, columns)
    to_controller(t_inv, inertia_q, nle, gravity_q, inertia, bias, gravity)
    if c_rows > 0:
        congruence(t_inv, coriolis_q, coriolis)
    for r in range(rows):
        for j in range(columns):
            s = 0.0
            for k in range(n):
                s += frame_jacobian_q[r, k] * t_inv[k, j]
            frame_jacobian[r, j] = s
    return inertia, bias, gravity, coriolis, frame_jacobian, dissipation
