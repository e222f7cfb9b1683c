"""The arm's kinetic energy inside the kernels: the kinetic part of L for the laws and the
kinetic-energy limit's ψ, one formula for both."""

from __future__ import annotations

from cpbc.arrays import Array
from cpbc.kernels import kernel


@kernel("float64(float64[:, :], float64[:])", inline=True)
def kinetic_energy(inertia: Array, dx: Array) -> float:
    """½ ẋᵀ D ẋ, the kinetic part of L (eq. 6.7)."""
    n = dx.shape[0]
    total = 0.0
    for a in range(n):
        s = 0.0
        for b in range(n):
            s += inertia[a, b] * dx[b]
        total += dx[a] * s
    return 0.5 * total
