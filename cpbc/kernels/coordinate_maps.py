"""The per-step state's change of coordinates x = T q (cpbc.model.coordinates: the thesis's
planar arm in absolute link angles): D_x = T⁻ᵀ D_q T⁻¹, g_x = T⁻ᵀ g_q, C ẋ = T⁻ᵀ (C q̇)."""

from __future__ import annotations

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY_MATRIX, kernel


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


@kernel(f"void({READ_ONLY_MATRIX}, float64[:, :], float64[:], float64[:], float64[:, :],"
        " float64[:], float64[:])")
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
        for j in range(n):
            s = 0.0
            for k in range(n):
                row = 0.0
                for m in range(n):
                    row += inertia_q[k, m] * t_inv[m, j]
                s += t_inv[k, i] * row
            inertia[i, j] = s

