"""What an error of the state can take off each margin in one period (cpbc.constraints.
margin_slopes.MarginSlopes.losses), in one call a guarded step: the configuration margins'
|∇φ_i| s and the velocity margins' |Π_k ẋ| w + ½ wᵀ|Π_k| w.

The sums run in index order; numpy's products and einsum they replace add the same terms in
an order of their own, so the losses agree to rounding (a few units in the last place).
"""

from __future__ import annotations

from cpbc.arrays import Array
from cpbc.kernels import READ_ONLY, READ_ONLY_MATRIX, kernel

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
