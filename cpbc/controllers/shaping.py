"""Shaping functions s of the barrier Lyapunov function V = L / s(ΦΨ) (Theorem 6.9 and Remarks).

The law needs only r(x) = x s'(x) / s(x), which multiplies the barrier terms through
ρ = r(ΦΨ)·L (the laws' log-barrier form, cpbc.constraints.constraint_set). Each shaping
also gives log s from log x, so that V can be evaluated without forming the product ΦΨ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from cpbc.errors import ParameterError


class Shaping(Protocol):
    def ratio(self, log_x: float) -> float:
        """r(x) = x s'(x)/s(x) at x = exp(log_x)."""
        ...

    def log_s(self, log_x: float) -> float:
        """log s(x) at x = exp(log_x)."""
        ...


@dataclass(frozen=True)
class Identity:
    """s(x) = x: Theorem 6.9 itself; r = 1."""

    def ratio(self, log_x: float) -> float:
        return 1.0

    def log_s(self, log_x: float) -> float:
        return log_x


@dataclass(frozen=True)
class Power:
    """s(x) = x^α, the thesis's simulations (α = 0.2, eq. 6.70); r = α."""

    alpha: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.alpha) and self.alpha > 0):
            raise ParameterError("alpha", f"shaping alpha must be > 0, got {self.alpha}")

    def ratio(self, log_x: float) -> float:
        return self.alpha

    def log_s(self, log_x: float) -> float:
        return self.alpha * log_x


@dataclass(frozen=True)
class Tanh:
    """s(x) = tanh(σx), barrier effect localised near ∂S (Remark after Corollary 6.11).

    r(x) = 2σx / sinh(2σx), which tends to 1 at the boundary and to 0 far from it.
    """

    sigma: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.sigma) and self.sigma > 0):
            raise ParameterError("sigma", f"shaping sigma must be > 0, got {self.sigma}")

    def ratio(self, log_x: float) -> float:
        y = 2.0 * self.sigma * math.exp(min(log_x, 700.0))
        if y < 1e-8:
            return 1.0
        if y > 700.0:
            return 0.0
        return y / math.sinh(y)

    def log_s(self, log_x: float) -> float:
        y = self.sigma * math.exp(min(log_x, 700.0))
        if y < 1e-8:
            return math.log(self.sigma) + log_x
        return math.log(math.tanh(y)) if y < 20.0 else 0.0
