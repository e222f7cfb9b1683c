"""The shaped potential U(x̃) and the damping term of the laws (Chapters 6 and 7)."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from cpbc.arrays import Array

_LN2 = float(np.log(2.0))


def log_cosh(x: Array) -> Array:
    """ln cosh x without overflow: ln(eˣ + e⁻ˣ) − ln 2, via logaddexp."""
    return np.logaddexp(x, -x) - _LN2


class Potential(Protocol):
    """U(x̃) ≥ 0 with its minimum at x̃ = 0."""

    def value(self, err: Array) -> float:
        """U(x̃)."""
        ...

    def gradient(self, err: Array) -> Array:
        """∂U/∂x̃, shape (n,)."""
        ...

    def evaluate(self, err: Array) -> tuple[float, Array]:
        """U and ∂U/∂x̃ together."""
        ...


class Damping(Protocol):
    """The damping force of a law, with ẋᵀ force(ẋ) > 0 for ẋ ≠ 0."""

    def force(self, dx: Array) -> Array:
        """The force, shape (n,)."""
        ...


class QuadraticPotential:
    """U = ½ x̃ᵀ K_P x̃ (eq. 6.7), ∂U/∂x̃ = K_P x̃."""

    def __init__(self, kp: Array) -> None:
        self.kp = kp

    def value(self, err: Array) -> float:
        return 0.5 * float(err @ (self.kp * err))

    def gradient(self, err: Array) -> Array:
        return self.kp * err

    def evaluate(self, err: Array) -> tuple[float, Array]:
        grad = self.kp * err
        return 0.5 * float(err @ grad), grad


class LogCoshPotential:
    """U = Σ (K_Pi/ξ_i) ln cosh(ξ_i x̃_i) (eq. 7.18), ∂U/∂x̃ = K_P tanh(Ξ x̃)."""

    def __init__(self, kp: Array, xi: Array) -> None:
        self.kp = kp
        self.xi = xi
        self._weight = kp / xi
        self._offset = float(np.sum(self._weight)) * _LN2

    def value(self, err: Array) -> float:
        y = self.xi * err
        return float(self._weight @ np.logaddexp(y, -y)) - self._offset

    def gradient(self, err: Array) -> Array:
        return self.kp * np.tanh(self.xi * err)

    def evaluate(self, err: Array) -> tuple[float, Array]:
        y = self.xi * err
        return float(self._weight @ np.logaddexp(y, -y)) - self._offset, self.kp * np.tanh(y)


class LinearDamping:
    """K_D ẋ (eq. 6.10)."""

    def __init__(self, kd: Array) -> None:
        self.kd = kd

    def force(self, dx: Array) -> Array:
        return self.kd * dx


class TanhDamping:
    """K_D tanh(Γ ẋ) (eq. 7.17), bounded by K_D."""

    def __init__(self, kd: Array, gamma: Array) -> None:
        self.kd = kd
        self.gamma = gamma

    def force(self, dx: Array) -> Array:
        return self.kd * np.tanh(self.gamma * dx)
