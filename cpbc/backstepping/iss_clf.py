"""One constrained state with an ISS-cLf: Theorem 3.8.

For the cascade (3.41) with Assumption 3.7 (the x-subsystem ISS with respect to z1 = ξ1 − α1,
|α1| ≤ Δ) and the symmetric constraint |ξ1| ≤ B (3.42), take the successive derivatives of z1
along the nominal dynamics as coordinates (3.48)

    z1 = ξ1 − α1(x),   z_{i+1} = ż_i   (i = 1 … m−1),   ż_m = u + L_m(x, ξ)

where L_m = f_m + ḟ_{m−1} + … − α1^{(m)}. The law (3.49)

    u = −Σ_i c_i z_i − L_m

makes the z-loop linear, ż = A z with A the companion matrix of (3.54) (last row −c1 … −cm).
With A diagonalisable and Hurwitz the cascade is GAS (Cor. 2.9), and for |z_i(0)| ≤ b_i

    |ξ1(t)| ≤ b1 + ε + Δ                                                    (3.50)

ε is not in closed form in the thesis; here it is the exact overshoot of z1(t) = e1ᵀ e^{At} z(0)
over the box, ε = max_t Σ_i |(e^{At})_{1i}| b_i − b1 (the worst z(0) is a vertex). There is no
barrier: the constraint holds only by tuning (c_i and the box).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cpbc.backstepping.barrier_terms import positive
from cpbc.backstepping.design_errors import DesignError, OutsideDomainError
from cpbc.backstepping.linear_reach import box_reach

State = tuple[float, ...]
Array = NDArray[np.float64]


class IssCascade(ABC):
    """A system of class (3.41) meeting Assumption 3.7, in the coordinates (3.48)."""

    #: number of ξ states
    m: int
    #: Δ = sup |α1(x)|
    delta: float

    @abstractmethod
    def z_coordinates(self, x: State, xi: State) -> State:
        """(z1, …, zm) of (3.48) at (x, ξ)."""

    @abstractmethod
    def drift(self, x: State, xi: State) -> float:
        """L_m(x, ξ), so that ż_m = u + L_m along the nominal dynamics (3.53)."""


def companion(c: State) -> Array:
    """The matrix A of (3.54): ones on the superdiagonal, last row (−c1, …, −cm)."""
    m = len(c)
    a = np.diag(np.ones(m - 1), 1)
    a[-1, :] = -np.asarray(c, dtype=float)
    return a


@dataclass(frozen=True)
class IssClfLaw:
    """u = −Σ c_i z_i − L_m (3.49) for an :class:`IssCascade`.

    Args:
        cascade: the system in the coordinates (3.48).
        c: the gains c1 … cm (> 0). A must have distinct negative real eigenvalues, as
            Theorem 3.8 requires (diagonalisable and Hurwitz).
    """

    cascade: IssCascade
    c: State

    def __post_init__(self) -> None:
        if len(self.c) != self.cascade.m:
            raise DesignError("c", len(self.c), f"needs {self.cascade.m} gains (one per ξ)")
        c = tuple(positive(f"c{i + 1}", v) for i, v in enumerate(self.c))
        object.__setattr__(self, "c", c)
        eig = np.linalg.eigvals(companion(c))
        real = np.sort(eig.real)
        if (
            np.any(np.abs(eig.imag) > 1e-9 * max(1.0, float(np.max(np.abs(eig)))))
            or np.any(real >= 0.0)
            or np.any(np.diff(real) <= 1e-9 * max(1.0, float(np.max(np.abs(real)))))
        ):
            raise DesignError(
                "c", float("nan"),
                f"the companion matrix (3.54) has eigenvalues {np.round(eig, 6).tolist()}; "
                "Theorem 3.8 needs them real, negative and distinct",
            )

    @property
    def eigenvalues(self) -> Array:
        """The eigenvalues s_i of A (3.59), ascending."""
        return np.sort(np.linalg.eigvals(companion(self.c)).real)

    def control(self, x: State, xi: State) -> float:
        """u (3.49) at (x, ξ)."""
        z = self.cascade.z_coordinates(x, xi)
        return -math.fsum(ci * zi for ci, zi in zip(self.c, z, strict=True)) - self.cascade.drift(
            x, xi
        )

    def check(self, x: State, xi: State, box: State) -> State:
        """z at (x, ξ), or :class:`OutsideDomainError` if some |z_i| > b_i: (3.50) assumes it."""
        z = self.cascade.z_coordinates(x, xi)
        for i, (zi, bi) in enumerate(zip(z, box, strict=True)):
            if abs(zi) > bi:
                raise OutsideDomainError(
                    f"z{i + 1}", zi, -bi, bi, "the bound (3.50) holds only for z(0) in the box"
                )
        return z

    def overshoot(self, box: State) -> float:
        """ε of (3.50) for |z_i(0)| ≤ b_i: max_t Σ_i |(e^{At})_{1i}| b_i − b1 (≥ 0)."""
        b = [positive(f"b{i + 1}", v) for i, v in enumerate(box)]
        return max(float(box_reach(companion(self.c), b)[0]) - b[0], 0.0)

    def xi1_bound(self, box: State) -> float:
        """b1 + ε + Δ (3.50)."""
        return float(box[0]) + self.overshoot(box) + self.cascade.delta
