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
from cpbc.kernels import barrier_shaping as kinds
from cpbc.kernels.barrier_shaping import shaping_terms


class Shaping(Protocol):
    """A shaping function; its formulas are cpbc.kernels.barrier_shaping.shaping_terms."""

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
        return shaping_terms(kinds.IDENTITY, 0.0, log_x)[0]

    def log_s(self, log_x: float) -> float:
        return shaping_terms(kinds.IDENTITY, 0.0, log_x)[1]

    def packed(self) -> tuple[int, float] | None:
        """(kind, parameter) of the shaping kernel, unless a subclass overrides a formula."""
        return _packed(self, Identity, kinds.IDENTITY, 0.0)


@dataclass(frozen=True)
class Power:
    """s(x) = x^α, the thesis's simulations (α = 0.2, eq. 6.70); r = α."""

    alpha: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.alpha) and self.alpha > 0):
            raise ParameterError("alpha", f"shaping alpha must be > 0, got {self.alpha}")

    def ratio(self, log_x: float) -> float:
        return shaping_terms(kinds.POWER, self.alpha, log_x)[0]

    def log_s(self, log_x: float) -> float:
        return shaping_terms(kinds.POWER, self.alpha, log_x)[1]

    def packed(self) -> tuple[int, float] | None:
        """(kind, parameter) of the shaping kernel, unless a subclass overrides a formula."""
        return _packed(self, Power, kinds.POWER, self.alpha)


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
        return shaping_terms(kinds.TANH, self.sigma, log_x)[0]

    def log_s(self, log_x: float) -> float:
        return shaping_terms(kinds.TANH, self.sigma, log_x)[1]

    def packed(self) -> tuple[int, float] | None:
        """(kind, parameter) of the shaping kernel, unless a subclass overrides a formula."""
        return _packed(self, Tanh, kinds.TANH, self.sigma)


def _packed(shaping: object, base: type, kind: int, parameter: float) -> tuple[int, float] | None:
    """The kernel's (kind, parameter) when ``shaping``'s class keeps ``base``'s formulas."""
    cls = type(shaping)
    if cls.ratio is not base.ratio or cls.log_s is not base.log_s:  # type: ignore[attr-defined]
        return None
    return kind, parameter
