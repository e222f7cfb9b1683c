"""Truncated Taylor series in time ("jets"): exact higher time derivatives along a flow.

The Chapter 4 laws need α̇_i for every step, hence up to the m-th time derivative of α1(x(t))
and of T/z1 along the nominal dynamics (PART1 §1.2: "analytically along the model vector field,
never by numerical differentiation"). A :class:`Jet` holds the normalised Taylor coefficients

    g(t) = c0 + c1 t + c2 t² + … + cK t^K,   c_k = g^{(k)}(0)/k!

and its arithmetic is the exact algebra of truncated series (Cauchy products, and the standard
recurrences for quotients and elementary functions, derived from g' = h(g)·a' for g = φ(a)).
So a function written once with ``+ − × ÷`` and the functions of this module gives its value
on floats, and all its time derivatives up to K, to rounding error, when fed the jets of its
arguments. Coefficients may be floats or float64 arrays of one shape (grid evaluation).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from typing import Any

import numpy as np

#: a coefficient: a float, or a float64 array (all coefficients of a jet broadcast together)
Coef = Any


class Jet:
    """A truncated Taylor series in t with normalised coefficients c_k = g^{(k)}(0)/k!.

    Args:
        coefficients: (c0, …, cK); K is the order. A result has the order of its
            lowest-order operand (the higher coefficients would be unknown).
    """

    __slots__ = ("c",)

    def __init__(self, coefficients: Sequence[Coef]) -> None:
        if len(coefficients) == 0:
            raise ValueError("a jet needs at least its value")
        self.c: tuple[Coef, ...] = tuple(coefficients)

    @property
    def order(self) -> int:
        """K, the highest derivative the jet carries."""
        return len(self.c) - 1

    @property
    def value(self) -> Coef:
        """g(0)."""
        return self.c[0]

    def __float__(self) -> float:
        """g(0) as a float (scalar jets only)."""
        return float(self.c[0])

    def derivative(self, k: int) -> Coef:
        """g^{(k)}(0) = k!·c_k."""
        return math.factorial(k) * self.c[k]

    def dot(self) -> Jet:
        """The jet of ġ (order K − 1)."""
        if self.order == 0:
            raise ValueError("the derivative of an order-0 jet is unknown")
        return Jet([(k + 1) * self.c[k + 1] for k in range(self.order)])

    # -- arithmetic ---------------------------------------------------------------------------
    # A law calls these some 10⁶ times a run (ch5_aerosonde: 27 jet operations per law
    # evaluation, the law at every stage of the continuous-time integration), so they build
    # results through _jet (no copy, no check) and add a constant to c0 only; the sums run in
    # the order of the series' definitions, so every coefficient is as before to the bit.
    def _pair(self, other: Jet | Coef) -> tuple[tuple[Coef, ...], tuple[Coef, ...]]:
        if isinstance(other, Jet):
            n = min(len(self.c), len(other.c))
            return self.c[:n], other.c[:n]
        return self.c, (other,) + (0.0,) * self.order

    def _operand(self, other: Jet) -> tuple[tuple[Coef, ...], tuple[Coef, ...]]:
        a, b = self.c, other.c
        if len(a) == len(b):
            return a, b
        n = min(len(a), len(b))
        return a[:n], b[:n]

    def __add__(self, other: Jet | Coef) -> Jet:
        if isinstance(other, Jet):
            return _jet(tuple(map(operator.add, *self._operand(other))))
        c = self.c
        return _jet((c[0] + other, *[p + 0.0 for p in c[1:]]))

    __radd__ = __add__

    def __neg__(self) -> Jet:
        return _jet(tuple(map(operator.neg, self.c)))

    def __sub__(self, other: Jet | Coef) -> Jet:
        if isinstance(other, Jet):
            return _jet(tuple(map(operator.sub, *self._operand(other))))
        c = self.c
        return _jet((c[0] - other, *[p - 0.0 for p in c[1:]]))

    def __rsub__(self, other: Coef) -> Jet:
        return (-self) + other

    def __mul__(self, other: Jet | Coef) -> Jet:
        if not isinstance(other, Jet):
            return _jet(tuple([p * other for p in self.c]))
        a, b = self._operand(other)
        if len(a) == 3:  # the order the Chapter 5 laws use, written out
            return _jet((a[0] * b[0], a[0] * b[1] + a[1] * b[0],
                         a[0] * b[2] + a[1] * b[1] + a[2] * b[0]))
        return _jet(tuple([sum(a[j] * b[k - j] for j in range(k + 1)) for k in range(len(a))]))

    __rmul__ = __mul__

    def __truediv__(self, other: Jet | Coef) -> Jet:
        if not isinstance(other, Jet):
            return _jet(tuple(p / other for p in self.c))
        a, b = self._operand(other)
        q: list[Coef] = []
        for k in range(len(a)):
            q.append((a[k] - sum(b[j] * q[k - j] for j in range(1, k + 1))) / b[0])
        return _jet(tuple(q))

    def __rtruediv__(self, other: Coef) -> Jet:
        return Jet([other] + [0.0] * self.order) / self

    def __pow__(self, n: int) -> Jet:
        if not isinstance(n, int) or n < 0:
            raise ValueError("only non-negative integer powers of a jet are defined")
        out = Jet([1.0] + [0.0] * self.order)
        for _ in range(n):
            out = out * self
        return out

    def __repr__(self) -> str:
        return f"Jet({list(self.c)!r})"


def _jet(coefficients: tuple[Coef, ...]) -> Jet:
    """A Jet of a non-empty tuple, taken as it is (the arithmetic's results)."""
    j = object.__new__(Jet)
    j.c = coefficients
    return j


def coefficient(v: Jet | Coef, k: int) -> Coef:
    """c_k of a jet, or of a constant (its value for k = 0, else 0)."""
    if isinstance(v, Jet):
        return v.c[k]
    return v if k == 0 else 0.0 * v


def as_jet(v: Jet | Coef, order: int) -> Jet:
    """A jet as it is, or a constant as the jet of a constant of that order."""
    return v if isinstance(v, Jet) else Jet([v] + [0.0 * v] * order)


def value(v: Jet | Coef) -> Coef:
    """The value of a jet or a constant."""
    return v.c[0] if isinstance(v, Jet) else v


def _scalar(fun_float: Any, fun_array: Any, v: Coef) -> Coef:
    return fun_float(v) if isinstance(v, float | int) else fun_array(v)


def exp(v: Jet | Coef) -> Jet | Coef:
    """e^v: e' = e·a', so c_k = (1/k) Σ_j j a_j e_{k−j}."""
    if not isinstance(v, Jet):
        return _scalar(math.exp, np.exp, v)
    e: list[Coef] = [exp(v.c[0])]
    for k in range(1, len(v.c)):
        e.append(sum(j * v.c[j] * e[k - j] for j in range(1, k + 1)) / k)
    return Jet(e)


def log(v: Jet | Coef) -> Jet | Coef:
    """log v: l' = a'/a."""
    if not isinstance(v, Jet):
        return _scalar(math.log, np.log, v)
    a = v.c
    lg: list[Coef] = [log(a[0])]
    for k in range(1, len(a)):
        lg.append((a[k] - sum(j * lg[j] * a[k - j] for j in range(1, k)) / k) / a[0])
    return Jet(lg)


def sin_cos(v: Jet | Coef) -> tuple[Jet | Coef, Jet | Coef]:
    """(sin v, cos v): s' = c·a', c' = −s·a'."""
    if not isinstance(v, Jet):
        return _scalar(math.sin, np.sin, v), _scalar(math.cos, np.cos, v)
    a = v.c
    s: list[Coef] = [_scalar(math.sin, np.sin, a[0])]
    c: list[Coef] = [_scalar(math.cos, np.cos, a[0])]
    for k in range(1, len(a)):
        s.append(sum(j * a[j] * c[k - j] for j in range(1, k + 1)) / k)
        c.append(-sum(j * a[j] * s[k - j] for j in range(1, k + 1)) / k)
    return Jet(s), Jet(c)


def sin(v: Jet | Coef) -> Jet | Coef:
    """sin v."""
    return sin_cos(v)[0]


def cos(v: Jet | Coef) -> Jet | Coef:
    """cos v."""
    return sin_cos(v)[1]


def tanh(v: Jet | Coef) -> Jet | Coef:
    """tanh v: t' = (1 − t²)·a'."""
    if not isinstance(v, Jet):
        return _scalar(math.tanh, np.tanh, v)
    a = v.c
    t: list[Coef] = [tanh(a[0])]
    w: list[Coef] = [1.0 - t[0] * t[0]]  # the jet of 1 − t², built alongside t
    for k in range(1, len(a)):
        t.append(sum(j * a[j] * w[k - j] for j in range(1, k + 1)) / k)
        w.append(-sum(t[j] * t[k - j] for j in range(k + 1)))
    return Jet(t)


def arctan(v: Jet | Coef) -> Jet | Coef:
    """arctan v: r' = a'/(1 + a²)."""
    if not isinstance(v, Jet):
        return _scalar(math.atan, np.arctan, v)
    if v.order == 0:
        return Jet([arctan(v.c[0])])
    rate = v.dot() / (1.0 + v * v)
    return Jet([arctan(v.c[0])] + [rate.c[k - 1] / k for k in range(1, len(v.c))])


def sqrt(v: Jet | Coef) -> Jet | Coef:
    """√v (v > 0): 2 s s' = a'."""
    if not isinstance(v, Jet):
        return _scalar(math.sqrt, np.sqrt, v)
    a = v.c
    s: list[Coef] = [sqrt(a[0])]
    for k in range(1, len(a)):
        s.append((a[k] - sum(s[j] * s[k - j] for j in range(1, k))) / (2.0 * s[0]))
    return Jet(s)


__all__ = [
    "Coef", "Jet", "arctan", "as_jet", "coefficient", "cos", "exp", "log", "sin", "sin_cos", "sqrt",
    "tanh", "value",
]
