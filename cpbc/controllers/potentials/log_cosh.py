"""The ln cosh spring Σ (K_i/ξ_i) ln cosh(ξ_i e_i) of eq. 7.18 on an error vector e."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels.law_terms import log_cosh_sum

_LN2 = float(np.log(2.0))


@dataclass(frozen=True)
class LogCoshSum:
    """U(e) = Σ (K_i/ξ_i) ln cosh(ξ_i e_i) (eq. 7.18), ∂U/∂e = K tanh(Ξe), bounded by K.

    ln cosh y is evaluated as ln(eʸ + e⁻ʸ) − ln 2 (logaddexp), which does not overflow.

    Attributes:
        stiffness: K, shape (m,), > 0.
        xi: ξ, shape (m,), > 0: the slope at e = 0 is K, the force saturates at K for
            |e| ≫ 1/ξ.
    """

    stiffness: Array
    xi: Array
    _weight: Array = field(init=False, repr=False)
    _offset: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        weight = self.stiffness / self.xi
        object.__setattr__(self, "_weight", weight)
        object.__setattr__(self, "_offset", float(np.sum(weight)) * _LN2)

    def evaluate(self, err: Array) -> tuple[float, Array]:
        """U(e) and ∂U/∂e (cpbc.kernels.law_terms.log_cosh_sum)."""
        grad = np.empty(err.shape[0])
        return log_cosh_sum(err, self.stiffness, self.xi, self._weight, self._offset, grad), grad

    def tables(self) -> tuple[Array, Array]:
        """[K; ξ; K/ξ] (3, m) and [[Σ K_i/ξ_i · ln 2]] for a law's kernel."""
        return np.vstack([self.stiffness, self.xi, self._weight]), np.array([[self._offset]])
