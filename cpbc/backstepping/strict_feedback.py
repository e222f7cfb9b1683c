"""The system class of Chapter 4 and its exact time derivatives along the nominal flow.

System (4.1) (the OCR's ``f_m(x, ξ1, …, x_m)`` read as ξ_m):

    ẋ   = f(x, ξ1)                                x ∈ ℝⁿ
    ξ̇1  = ξ2 + f1(x, ξ1)
     ⋮
    ξ̇m  = u + f_m(x, ξ1, …, ξm)                   u ∈ ℝ
    f(0, 0) = 0, f_i(0, …, 0) = 0,   constraints |ξ_i(t)| ≤ Ξ_i   (4.2)

A :class:`StrictFeedback` supplies f, f_1 … f_m and the first-step ingredients of
Assumptions 4.1/4.6–4.8: a bounded α1(x) with bounded derivatives, the cLf V(x) with
W(x) := −∂V/∂x·f(x, α1(x)) (the equality case of (4.5)), and T/z1 (4.20)–(4.21) as the closed-form
divided difference ∂V/∂x·[f(x, ξ1) − f(x, α1)]/(ξ1 − α1) (PART1 §2.3: never divide by z1).
Each is written once with the arithmetic of :mod:`cpbc.backstepping.jets`, so it evaluates on
floats, on float arrays (grids) and on jets (exact derivatives along the flow).

:func:`nominal_jets` gives the Taylor jets of (x, ξ) along the nominal dynamics with u = 0. The
laws only read the coefficients in which u cannot appear (α_i depends on x, ξ1 … ξ_{i−1}, and
its (m−i+1)-th derivative on ξ_m at most), so the u = 0 choice never enters a law.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

from cpbc.arrays import Array
from cpbc.backstepping.jets import Coef, Jet, coefficient

#: a value the ingredients accept and return: a float, a float array, or a jet of either
Value = Jet | Coef


class StrictFeedback(ABC):
    """A system of class (4.1) with the ingredients of Assumptions 4.6–4.8 (and 4.1).

    Attributes:
        n: dimension of x.
        m: number of ξ states (the constrained chain).
    """

    n: int
    m: int

    @abstractmethod
    def flow(self, x: Sequence[Value], xi1: Value) -> tuple[Value, ...]:
        """f(x, ξ1), the x-subsystem's vector field (n components)."""

    def drifts(self, x: Sequence[Value], xi: Sequence[Value]) -> tuple[Value, ...]:
        """(f_1, …, f_m) at (x, ξ); f_i may read ξ_1 … ξ_i only. Zero unless overridden."""
        return (0.0,) * self.m

    @abstractmethod
    def alpha1(self, x: Sequence[Value]) -> Value:
        """α1(x), bounded with bounded derivatives, α1(0) = 0."""

    @abstractmethod
    def t_over_z(self, x: Sequence[Value], xi1: Value) -> Value:
        """T(x, ξ1)/(ξ1 − α1(x)) in closed form (4.20)–(4.21)."""

    @abstractmethod
    def lyapunov(self, x: Sequence[Value]) -> tuple[Value, Value]:
        """V(x) and W(x) = −∂V/∂x·f(x, α1(x)) ≥ 0."""

    def dynamics(
        self, x: Sequence[float], xi: Sequence[float], u: float
    ) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(ẋ, ξ̇) of (4.1) at (x, ξ) under the input u."""
        f = self.drifts(x, xi)
        nxt = [*xi[1:], u]
        return (
            tuple(float(v) for v in self.flow(x, xi[0])),
            tuple(float(nxt[i] + f[i]) for i in range(self.m)),
        )

    @abstractmethod
    def x_samples(self) -> Array:
        """(N, n) points of x covering ℝⁿ for worst-case searches (sup over x of a bounded
        function); e.g. a grid through tan θ for an unbounded coordinate."""


def nominal_jets(
    system: StrictFeedback, x: Sequence[Coef], xi: Sequence[Coef], order: int
) -> tuple[tuple[Jet, ...], tuple[Jet, ...]]:
    """Jets of x(t) and ξ(t) to ``order`` along (4.1) with u = 0, from (x, ξ) at t = 0.

    Order by order: the coefficient k+1 of a state is the coefficient k of its right-hand side
    evaluated on the jets of order k (Picard's recursion for Taylor series).
    """
    xs: list[list[Coef]] = [[v] for v in x]
    ys: list[list[Coef]] = [[v] for v in xi]
    m = system.m
    for k in range(order):
        xj = [Jet(c) for c in xs]
        yj = [Jet(c) for c in ys]
        fx = system.flow(xj, yj[0])
        fi = system.drifts(xj, yj)
        for i in range(system.n):
            xs[i].append(coefficient(fx[i], k) / (k + 1))
        for i in range(m):
            nxt = coefficient(yj[i + 1], k) if i + 1 < m else 0.0 * ys[i][0]
            ys[i].append((nxt + coefficient(fi[i], k)) / (k + 1))
    return tuple(Jet(c) for c in xs), tuple(Jet(c) for c in ys)

