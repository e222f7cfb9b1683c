"""Small systems of class (4.1) for testing the Chapter 4 laws (not from the thesis).

NonAffine (n = 1): ẋ = φ(ξ1) = ξ1 + ½ξ1³, V = log cosh x, α1 = −Δ tanh x,
T/z1 = tanh x·(φ(ξ1) − φ(α1))/(ξ1 − α1) = tanh x·(1 + ½(ξ1² + ξ1α1 + α1²)), W = −tanh x·φ(α1);
f1 = ½ sin x, f2 = 0.3 sin ξ1 · ξ2, f3 = 0.2 ξ1 ξ3 (for m ≥ 3).

Planar (n = 2): ẋ1 = −x1 + x2, ẋ2 = −x2 + φ(ξ1), V = ½(x1² + x2²), α1 = −Δ tanh x2,
T/z1 = x2·(1 + ½(ξ1² + ξ1α1 + α1²)), W = −x1(−x1 + x2) − x2(−x2 + φ(α1)); f1 = 0.4 cos x1 − 0.4.

Stable (n = 1), for the ISS design: ẋ = −x + ξ1 (ISS w.r.t. z1 with any bounded α1),
α1 = −Δ tanh x, V = ½x², f1 = ½ sin x, f2 = 0.2 sin ξ1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cpbc.backstepping.jets import cos, sin, tanh
from cpbc.backstepping.strict_feedback import StrictFeedback, Value


def phi(v: Value) -> Value:
    return v + 0.5 * v * v * v


def _grid() -> np.ndarray:
    return np.tan(np.linspace(-0.5 * math.pi + 1e-6, 0.5 * math.pi - 1e-6, 401))


class NonAffine(StrictFeedback):
    n = 1

    def __init__(self, m: int = 3, delta: float = 0.4) -> None:
        self.m, self.delta = m, delta

    def flow(self, x: Sequence[Value], xi1: Value) -> tuple[Value, ...]:
        return (phi(xi1),)

    def drifts(self, x: Sequence[Value], xi: Sequence[Value]) -> tuple[Value, ...]:
        out: list[Value] = [0.5 * sin(x[0])]
        if self.m >= 2:
            out.append(0.3 * sin(xi[0]) * xi[1])
        if self.m >= 3:
            out.append(0.2 * xi[0] * xi[2])
        return tuple(out + [0.0] * (self.m - len(out)))

    def alpha1(self, x: Sequence[Value]) -> Value:
        return -self.delta * tanh(x[0])

    def t_over_z(self, x: Sequence[Value], xi1: Value) -> Value:
        a1 = self.alpha1(x)
        return tanh(x[0]) * (1.0 + 0.5 * (xi1 * xi1 + xi1 * a1 + a1 * a1))

    def lyapunov(self, x: Sequence[Value]) -> tuple[Value, Value]:
        v = float(x[0])
        return math.log(math.cosh(v)), -math.tanh(v) * phi(-self.delta * math.tanh(v))

    def x_samples(self) -> np.ndarray:
        return _grid()[:, None]


class Planar(StrictFeedback):
    n = 2

    def __init__(self, m: int = 3, delta: float = 0.3) -> None:
        self.m, self.delta = m, delta

    def flow(self, x: Sequence[Value], xi1: Value) -> tuple[Value, ...]:
        return -x[0] + x[1], -x[1] + phi(xi1)

    def drifts(self, x: Sequence[Value], xi: Sequence[Value]) -> tuple[Value, ...]:
        return (0.4 * cos(x[0]) - 0.4,) + (0.0,) * (self.m - 1)

    def alpha1(self, x: Sequence[Value]) -> Value:
        return -self.delta * tanh(x[1])

    def t_over_z(self, x: Sequence[Value], xi1: Value) -> Value:
        a1 = self.alpha1(x)
        return x[1] * (1.0 + 0.5 * (xi1 * xi1 + xi1 * a1 + a1 * a1))

    def lyapunov(self, x: Sequence[Value]) -> tuple[Value, Value]:
        x1, x2 = float(x[0]), float(x[1])
        a1 = -self.delta * math.tanh(x2)
        return 0.5 * (x1 * x1 + x2 * x2), -x1 * (-x1 + x2) - x2 * (-x2 + phi(a1))

    def x_samples(self) -> np.ndarray:
        g = _grid()[::8]
        return np.array([(a, b) for a in g for b in g])


class Stable(StrictFeedback):
    n = 1

    def __init__(self, m: int = 3, delta: float = 0.3) -> None:
        self.m, self.delta = m, delta

    def flow(self, x: Sequence[Value], xi1: Value) -> tuple[Value, ...]:
        return (-x[0] + xi1,)

    def drifts(self, x: Sequence[Value], xi: Sequence[Value]) -> tuple[Value, ...]:
        out: list[Value] = [0.5 * sin(x[0])]
        if self.m >= 2:
            out.append(0.2 * sin(xi[0]))
        return tuple(out + [0.0] * (self.m - len(out)))

    def alpha1(self, x: Sequence[Value]) -> Value:
        return -self.delta * tanh(x[0])

    def t_over_z(self, x: Sequence[Value], xi1: Value) -> Value:
        return x[0]

    def lyapunov(self, x: Sequence[Value]) -> tuple[Value, Value]:
        v = float(x[0])
        return 0.5 * v * v, -v * (-v - self.delta * math.tanh(v))

    def x_samples(self) -> np.ndarray:
        return _grid()[:, None]
