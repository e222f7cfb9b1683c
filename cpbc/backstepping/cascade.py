"""The system class of Chapter 3 and the ingredients of its first backstepping step.

System (3.3):

    ẋ  = f(x, ξ1),             x ∈ ℝⁿ (non-affine in ξ1 allowed)
    ξ̇1 = ξ2 + f1(x, ξ1)
    ξ̇2 = u  + f2(x, ξ1, ξ2)    (m = 2; for m = 1, ξ̇1 = v + f1 and v is the input)

with Assumption 3.1: V(x) positive definite, W(x) ≥ 0, a smooth bounded α1(x) (|α1| ≤ Δ) with
∂V/∂x·f(x, α1(x)) ≤ −W(x), and x ≡ 0 the only solution of ẋ = f(x, α1) along which W ≡ 0.

A :class:`Cascade` supplies, at a point (x, ξ1), the x-dependent quantities of the first step
together with their exact time derivatives along ẋ = f(x, ξ1). Each such quantity g(x, ξ1) comes
as a :class:`Rated` triple (g, ∂g/∂x·f, ∂g/∂ξ1), so that along any trajectory
ġ = ∂g/∂x·f + ∂g/∂ξ1·ξ̇1. The laws build α2 and its analytic derivative α̇2 from these alone.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass


@dataclass(frozen=True)
class Rated:
    """A quantity g(x, ξ1) with its derivative split as ġ = drift + sens·ξ̇1.

    Attributes:
        value: g(x, ξ1).
        drift: ∂g/∂x · f(x, ξ1).
        sens: ∂g/∂ξ1.
    """

    value: float
    drift: float
    sens: float

    def rate(self, xi1_dot: float) -> float:
        """ġ for a given ξ̇1."""
        return self.drift + self.sens * xi1_dot


@dataclass(frozen=True)
class FirstStep:
    """The ingredients of the first backstepping step at (x, ξ1).

    Attributes:
        alpha1: α1(x), the bounded stabilising function of Assumption 3.1.
        alpha1_flow: ∂α1/∂x·f(x, ξ1) (so that ż1 = ξ̇1 − alpha1_flow.value).
        f1: f1(x, ξ1).
        t_over_z: T(x, ξ1)/(ξ1 − α1(x)) with T = ∂V/∂x·[f(x, ξ1) − f(x, α1)]  (3.9), as a
            closed-form divided difference (for f = F(x) + G(x)ξ1 it is ∂V/∂x·G(x)).
    """

    alpha1: float
    alpha1_flow: Rated
    f1: Rated
    t_over_z: Rated


class Cascade(ABC):
    """A system of class (3.3) in its cascade coordinates (x, ξ), with Assumption 3.1 met.

    Subclasses give the first step's ingredients and, for m = 2, f2. ``lyapunov`` returns V(x)
    and W(x); the laws do not need them, the tests check U̇ against the theorems with them.
    """

    #: number of ξ states (1: Prop. 3.2/3.11; 2: Thm 3.6/3.13)
    m: int
    #: Δ of Assumption 3.1: sup |α1(x)|
    delta: float

    @abstractmethod
    def first_step(self, x: tuple[float, ...], xi1: float) -> FirstStep:
        """α1, ∂α1/∂x·f, f1 and T/z1 at (x, ξ1), each with its exact rates."""

    def f2(self, x: tuple[float, ...], xi1: float, xi2: float) -> float:
        """f2(x, ξ1, ξ2) of (3.3); zero unless overridden."""
        return 0.0

    @abstractmethod
    def flow(self, x: tuple[float, ...], xi1: float) -> tuple[float, ...]:
        """f(x, ξ1), the x-subsystem's vector field."""

    @abstractmethod
    def lyapunov(self, x: tuple[float, ...]) -> tuple[float, float]:
        """V(x) and W(x) of Assumption 3.1."""
