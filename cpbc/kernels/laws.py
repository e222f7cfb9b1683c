"""The laws' formulas, given the potential's force, the damping and the barrier sums."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, kernel
from cpbc.kernels.small_solves import solve_spd


def zero_terms(n: int) -> tuple[Array, Array]:
    """Read-only zero barrier sums b (n,) and Π (n, n), for a law whose constraints give none
    (a law keeps them: nothing constant is allocated per call)."""
    b, weight = np.zeros(n), np.zeros((n, n))
    b.setflags(write=False)
    weight.setflags(write=False)
    return b, weight


@kernel(f"float64({READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64[:])")
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


@kernel("void(float64[:, :], float64[:], float64[:], float64[:], float64[:], "
        f"{READ_ONLY}, {READ_ONLY_MATRIX}, boolean, float64, float64[:])")
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


@kernel(f"void(float64[:], float64[:], float64[:], {READ_ONLY}, float64, float64, float64[:])")
def cpbc_ke_torque(gravity: Array, grad: Array, damping: Array, gradient: Array, rho: float,
                   psi: float, tau: Array) -> None:
    """CPBC-KE (Corollary 6.11, eq. 6.67) with shaping, in log-barrier form:

        τ = g + (−∂U/∂x − (K_D ẋ + F) + ρ b_φ) / (1 + ρ/ψ)

    with ``grad`` ∂U/∂x and ``damping`` K_D ẋ + F (BPBC-KE, eq. 7.34, with the ln cosh
    spring and tanh damping)."""
    scale = 1.0 + rho / psi
    for i in range(gravity.shape[0]):
        tau[i] = gravity[i] + (-grad[i] - damping[i] + rho * gradient[i]) / scale
