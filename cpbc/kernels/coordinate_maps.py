"""The per-step state's change of coordinates x = T q (cpbc.model.coordinates: the thesis's
planar arm in absolute link angles): D_x = T⁻ᵀ D_q T⁻¹, g_x = T⁻ᵀ g_q, C ẋ = T⁻ᵀ (C q̇),
and the joints' friction f(ẋ) in those coordinates."""

from __future__ import annotations

import math

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, inner, kernel


@kernel(f"void({READ_ONLY_MATRIX}, float64[:], float64[:], float64[:, ::1])")
def to_joint(t_inv: Array, x: Array, dx: Array, joint: Array) -> None:
    """q = T⁻¹ x and q̇ = T⁻¹ ẋ into the rows of ``joint`` (2, n) (one array: each array
    a kernel is handed costs numba about 40 ns to pass)."""
    n = x.shape[0]
    for i in range(n):
        a, b = 0.0, 0.0
        for j in range(n):
            a += t_inv[i, j] * x[j]
            b += t_inv[i, j] * dx[j]
        joint[0, i] = a
        joint[1, i] = b


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
