"""Barrier terms β(z) of the first-step cLf, and Γ(z) = z/β'(z) that the laws use.

A barrier term has β(0) = 0, β > 0 elsewhere on its open interval, and β → ∞ at the interval's
ends (Definition 2.1). The laws of §3.1/§3.4 only need Γ(z) := z/β'(z), which is positive and
finite on the interval (also at z = 0), and its derivative Γ'(z) for α̇. Writing β'(z) = z/Γ(z)
lets any barrier be swapped in (the thesis: "the form of the barrier function has no impact on
the effectiveness of the final control law").
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

from cpbc.backstepping.design_errors import DesignError


def positive(name: str, value: float) -> float:
    """``value`` as a float if finite and > 0, else a :class:`DesignError` naming it."""
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise DesignError(name, value, "must be finite and > 0")
    return v


class Barrier(ABC):
    """β(z) on the open interval (lower, upper) with Γ(z) = z/β'(z)."""

    lower: float
    upper: float

    @abstractmethod
    def value(self, z: float) -> float:
        """β(z); ∞ on and outside the interval's ends."""

    @abstractmethod
    def gamma(self, z: float) -> float:
        """Γ(z) = z/β'(z) > 0."""

    @abstractmethod
    def dgamma(self, z: float) -> float:
        """dΓ/dz."""

    @property
    @abstractmethod
    def gamma_max(self) -> float:
        """sup of Γ over the interval (Lemma 3.12 for the rational barrier)."""

    def contains(self, z: float) -> bool:
        """Whether z lies in the open interval (lower, upper)."""
        return self.lower < z < self.upper


@dataclass(frozen=True)
class RationalBarrier(Barrier):
    """β(z) = k z² / ((a+z)(b−z)) on (−a, b)  (3.11)/(3.40).

    With p = (a+z)(b−z) and N = 2ab + (b−a)z > 0 on the interval,

        β'(z) = k z N / p²,   Γ(z) = p² / (k N)          (3.10), (3.98)

    which equals p/(k y(z)) with y(z) = a/(a+z) + b/(b−z) of Lemma 3.3. Lemma 3.12 bounds
    p/y by Y = ¼(a+b)³/(a+b+2√(ab)), hence Γ ≤ Y/k.

    Args:
        a: lower half-width, z > −a.
        b: upper half-width, z < b.
        k: weight of the barrier.
    """

    a: float
    b: float
    k: float

    def __post_init__(self) -> None:
        for name in ("a", "b", "k"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))
        object.__setattr__(self, "lower", -self.a)
        object.__setattr__(self, "upper", self.b)

    def value(self, z: float) -> float:
        p = (self.a + z) * (self.b - z)
        return self.k * z * z / p if self.contains(z) else math.inf

    def gamma(self, z: float) -> float:
        p = (self.a + z) * (self.b - z)
        return p * p / (self.k * (2.0 * self.a * self.b + (self.b - self.a) * z))

    def dgamma(self, z: float) -> float:
        a, b = self.a, self.b
        p = (a + z) * (b - z)
        dp = b - a - 2.0 * z
        n = 2.0 * a * b + (b - a) * z
        return (2.0 * p * dp * n - p * p * (b - a)) / (self.k * n * n)

    @property
    def gamma_max(self) -> float:
        s = self.a + self.b
        return 0.25 * s**3 / (s + 2.0 * math.sqrt(self.a * self.b)) / self.k


@dataclass(frozen=True)
class LogBarrier(Barrier):
    """β(z) = ½ k log(K² / (K² − z²)) on (−K, K)  (3.75), (3.151).

        β'(z) = k z / (K² − z²),   Γ(z) = (K² − z²)/k,   Γ'(z) = −2z/k,   sup Γ = K²/k.

    Args:
        bound: K, the bound on |z| (the thesis's k2 in §3.3, k4 in §3.5).
        k: weight (the thesis's k3 in both applications).
    """

    bound: float
    k: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "bound", positive("bound", self.bound))
        object.__setattr__(self, "k", positive("k", self.k))
        object.__setattr__(self, "lower", -self.bound)
        object.__setattr__(self, "upper", self.bound)

    def value(self, z: float) -> float:
        kk = self.bound * self.bound
        return 0.5 * self.k * math.log(kk / (kk - z * z)) if self.contains(z) else math.inf

    def gamma(self, z: float) -> float:
        return (self.bound * self.bound - z * z) / self.k

    def dgamma(self, z: float) -> float:
        return -2.0 * z / self.k

    @property
    def gamma_max(self) -> float:
        return self.bound * self.bound / self.k


@dataclass(frozen=True)
class QuadraticTerm(Barrier):
    """β(z) = ½ k z² on ℝ: no barrier at all (Γ ≡ 1/k).

    Standard backstepping, for comparison only: it gives no bound on z. With it, the §3.3
    design becomes the unconstrained baseline of PART1 §4.6 (not Karlsson's controller).
    """

    k: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "k", positive("k", self.k))
        object.__setattr__(self, "lower", -math.inf)
        object.__setattr__(self, "upper", math.inf)

    def value(self, z: float) -> float:
        return 0.5 * self.k * z * z

    def gamma(self, z: float) -> float:
        return 1.0 / self.k

    def dgamma(self, z: float) -> float:
        return 0.0

    @property
    def gamma_max(self) -> float:
        return 1.0 / self.k
