"""What an error of the state can take off each margin in one period (cpbc.constraints.
margin_slopes.MarginSlopes.losses), in one call a guarded step: the configuration margins'
|∇φ_i| s and the velocity margins' |Π_k ẋ| w + ½ wᵀ|Π_k| w.

The sums run in index order; numpy's products and einsum they replace add the same terms in
an order of their own, so the losses agree to rounding (a few units in the last place).
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, kernel
from cpbc.kernels.friction_error import held_friction_error
from cpbc.kernels.small_solves import inverse_spd

READ_ONLY_STACK = "Array(float64, 3, 'A', readonly=True)"


@kernel(f"void({READ_ONLY_MATRIX}, {READ_ONLY_STACK}, {READ_ONLY}, {READ_ONLY}, {READ_ONLY},"
        f" {READ_ONLY}, float64[:], float64[:])")
def margin_losses(gradients: Array, weights: Array, rates: Array, end_shift: Array,
                  mid_shift: Array, rate_shift: Array, end_out: Array, mid_out: Array) -> None:
    """Into ``end_out`` every margin's loss at the period's end — Σ_j |∂φ_i/∂x_j| s_j for
    each configuration margin (``gradients`` ∇φ_i rows, ``end_shift`` s), then
    Σ_j |(Π_k ẋ)_j| w_j + ½ Σ_ij |Π_k|_ij w_i w_j for each velocity margin
    ψ_k = ω_k − ½ẋᵀΠ_k ẋ (``weights`` Π_k, ``rates`` ẋ, ``rate_shift`` w) — and into
    ``mid_out`` the configuration margins' Σ_j |∂φ_i/∂x_j| s'_j (``mid_shift`` s')."""
    m, n = gradients.shape
    for i in range(m):
        end, mid = 0.0, 0.0
        for j in range(n):
            g = abs(gradients[i, j])
            end += g * end_shift[j]
            mid += g * mid_shift[j]
        end_out[i] = end
        mid_out[i] = mid
    for k in range(weights.shape[0]):
        push, spread = 0.0, 0.0
        for i in range(n):
            p = 0.0
            for j in range(n):
                p += weights[k, i, j] * rates[j]
                spread += abs(weights[k, i, j]) * rate_shift[i] * rate_shift[j]
            push += abs(p) * rate_shift[i]
        end_out[m + k] = push + 0.5 * spread


@kernel(f"void(float64[:, :], {READ_ONLY_MATRIX}, boolean, {READ_ONLY}, float64, float64,"
        f" float64, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, {READ_ONLY}, float64, float64,"
        f" {READ_ONLY_MATRIX}, {READ_ONLY_STACK}, float64[:], float64[:], float64[:])")
def friction_floors(inertia: Array, t_inv: Array, mapped: bool, levels: Array,
                    smoothing: float, build_up: float, creep: float, dx: Array, bias: Array,
                    lower: Array, upper: Array, period: float, travel: float,
                    gradients: Array, weights: Array, floor: Array, mid: Array,
                    error: Array) -> None:
    """A guarded step's floors raised, in place, by what the model's smooth Coulomb friction
    alone can take off each margin in one period, in one call: D⁻¹ (``inverse_spd``), the
    bound ā on the acceleration error of the torques lower ≤ τ_q ≤ upper at the bias b
    (``held_friction_error``, into ``error``), and ``margin_losses`` of the position off by
    c h² ā at the end (c = ``travel``), ⅛h² ā at mid-period and the rate by h ā
    (cpbc.controllers.safeguard.error_floors), added to ``floor`` and ``mid``."""
    n = dx.shape[0]
    inverse = np.empty((n, n))
    inverse_spd(inertia, inverse)
    held_friction_error(inverse, t_inv, mapped, levels, smoothing, build_up, creep, dx, bias,
                        lower, upper, period, error)
    h = period
    shifts = np.empty((3, n))
    for j in range(n):
        shifts[0, j] = travel * h * h * error[j]
        shifts[1, j] = 0.125 * h * h * error[j]
        shifts[2, j] = h * error[j]
    end, mid_loss = np.empty(floor.shape[0]), np.empty(mid.shape[0])
    margin_losses(gradients, weights, dx, shifts[0], shifts[1], shifts[2], end, mid_loss)
    for i in range(floor.shape[0]):
        floor[i] += end[i]
    for i in range(mid.shape[0]):
        mid[i] += mid_loss[i]
