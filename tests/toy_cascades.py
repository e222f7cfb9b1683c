"""Small cascades of class (3.3) for testing the generic laws (not from the thesis).

Non-affine x-subsystem ẋ = φ(ξ1) = ξ1 + ½ξ1³ with V = log cosh x, α1 = −Δ tanh x, so that
W = −tanh x·φ(α1) = Δ tanh²x (1 + ½Δ² tanh²x) ≥ 0, zero only at x = 0 (Assumption 3.1), and
T/z1 = tanh x·(φ(ξ1) − φ(α1))/(ξ1 − α1) = tanh x·(1 + ½(ξ1² + ξ1α1 + α1²)).
f1 = ½ sin x (|f1| ≤ ½), f2 = 0.3 ξ1 ξ2.
"""

from __future__ import annotations

import math

from cpbc.backstepping import Cascade, FirstStep, IssCascade, Rated

State = tuple[float, ...]


def phi(v: float) -> float:
    return v + 0.5 * v**3


class ToyCascade(Cascade):
    def __init__(self, m: int, delta: float = 0.4) -> None:
        self.m = m
        self.delta = delta

    def flow(self, x: State, xi1: float) -> State:
        return (phi(xi1),)

    def first_step(self, x: State, xi1: float) -> FirstStep:
        th = math.tanh(x[0])
        s = 1.0 - th * th
        d = self.delta
        a1 = -d * th
        f = phi(xi1)
        h = 1.0 + 0.5 * (xi1 * xi1 + xi1 * a1 + a1 * a1)
        dtz_dx = s * h + th * 0.5 * (xi1 + 2.0 * a1) * (-d * s)
        return FirstStep(
            alpha1=a1,
            alpha1_flow=Rated(-d * s * f, 2.0 * d * th * s * f * f, -d * s * (1.0 + 1.5 * xi1**2)),
            f1=Rated(0.5 * math.sin(x[0]), 0.5 * math.cos(x[0]) * f, 0.0),
            t_over_z=Rated(th * h, dtz_dx * f, th * 0.5 * (2.0 * xi1 + a1)),
        )

    def f2(self, x: State, xi1: float, xi2: float) -> float:
        return 0.3 * xi1 * xi2

    def lyapunov(self, x: State) -> tuple[float, float]:
        th = math.tanh(x[0])
        return math.log(math.cosh(x[0])), -th * phi(-self.delta * th)


class ToyIssCascade(IssCascade):
    """ẋ = −x + ξ1, ξ̇1 = ξ2, ξ̇2 = u; α1 = −Δ tanh x (ISS: V = ½x², V̇ ≤ −½x² + ½z1²).

    z1 = ξ1 + Δ tanh x, z2 = ż1 = ξ2 + Δ s e (s = 1 − tanh²x, e = ẋ = −x + ξ1),
    ż2 = u + Δ s (ξ2 − e − 2 tanh x · e²).
    """

    m = 2

    def __init__(self, delta: float = 0.3) -> None:
        self.delta = delta

    def z_coordinates(self, x: State, xi: State) -> State:
        th = math.tanh(x[0])
        e = -x[0] + xi[0]
        return xi[0] + self.delta * th, xi[1] + self.delta * (1.0 - th * th) * e

    def drift(self, x: State, xi: State) -> float:
        th = math.tanh(x[0])
        e = -x[0] + xi[0]
        return self.delta * (1.0 - th * th) * (xi[1] - e - 2.0 * th * e * e)
