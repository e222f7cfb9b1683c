"""§3.3: the active quarter-car suspension with a travel limit, by Theorem 3.6 (m = 2).

Plant (3.62), with x1 the tire deflection, x2 the wheel velocity, x3 the suspension travel,
x4 the body velocity, u the actuator force per unit sprung mass and d = ṙ the road velocity:

    ẋ1 = x2 − d,   ẋ2 = −ω² x1 + ρ u,   ẋ3 = −x2 + x4,   ẋ4 = −u

Cascade coordinates (3.64) (η1 the height of the centre of mass, η2 its velocity):

    η1 = x1 + ρ/(ρ+1) x3,  η2 = (x2 + ρ x4)/(ρ+1),  ξ1 = x3,  ξ2 = x4 − x2
    η̇1 = η2 − d,  η̇2 = −Aη1 + Bξ1,  ξ̇1 = ξ2,  ξ̇2 = Cη1 − Dξ1 − Eu
    A = ω²/(ρ+1), B = ρω²/(ρ+1)², C = ω², D = ρω²/(ρ+1), E = 1+ρ

Design with d ≡ 0 and the thesis's gain names (k1 tanh slope, c1 amplitude of α1, k2 the bound
on z1, k3 the barrier weight, k4 the weight of ½z2², c2, c3 the step gains):

    V = ½Aη1² + ½η2²,  α1 = −c1 tanh(k1η2),  W = c1Bη2 tanh(k1η2)      (3.65), (3.66), (3.71)
    z1 = ξ1 − α1,  U1 = V + ½k3 log(k2²/(k2² − z1²))                     (3.70), (3.75)
    α2 = −c2 z1 − c1k1(1 − tanh²)(−Aη1 + Bξ1) − (k2² − z1²)Bη2/k3        (3.80)
    u  = −(1/E){−c3 z2 − Cη1 + Dξ1 + α̇2 − k3 z1/(k4(k2² − z1²))}         (3.88), α̇2 (3.89)
    U̇ = −W − c2k3 z1²/(k2² − z1²) − c3k4 z2² ≤ 0                          (3.90)

which is :class:`NonStrictClfLaw` with a :class:`LogBarrier` (bound k2, weight k3), step gains
(c2, c3) and k4. Guarantee: |x3| ≤ |z1| + |α1| < k2 + c1 (3.84), for |z1(0)| < k2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import Barrier, LogBarrier, QuadraticTerm, positive
from cpbc.backstepping.cascade import Cascade, FirstStep, Rated
from cpbc.backstepping.nonstrict_clf import NonStrictClfLaw

State = tuple[float, ...]


@dataclass(frozen=True)
class QuarterCarConstants:
    """ω [rad/s] and ρ = m_s/m_us of (3.62), and the constants A…E of (3.64)."""

    omega: float = 20.0 * math.pi
    rho: float = 10.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "omega", positive("omega", self.omega))
        object.__setattr__(self, "rho", positive("rho", self.rho))

    @property
    def abcde(self) -> tuple[float, float, float, float, float]:
        """(A, B, C, D, E) of (3.64)."""
        w2, r = self.omega**2, self.rho
        return w2 / (r + 1), r * w2 / (r + 1) ** 2, w2, r * w2 / (r + 1), 1.0 + r


@dataclass(frozen=True)
class SuspensionGains:
    """The design constants of §3.3.3, under the thesis's names (all > 0, k2 > c1)."""

    k1: float = 3.5
    k2: float = 0.051
    k3: float = 0.07
    k4: float = 50.0
    c1: float = 0.049
    c2: float = 300.0
    c3: float = 500.0

    def __post_init__(self) -> None:
        for name in ("k1", "k2", "k3", "k4", "c1", "c2", "c3"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))


class SuspensionCascade(Cascade):
    """The η-subsystem of (3.64) with α1 = −c1 tanh(k1η2): Assumption 3.1's ingredients."""

    m = 2

    def __init__(self, constants: QuarterCarConstants, gains: SuspensionGains) -> None:
        self.a, self.b, self.c, self.d, self.e = constants.abcde
        self.k1, self.c1 = gains.k1, gains.c1
        self.delta = gains.c1  # (3.72)

    def flow(self, x: State, xi1: float) -> State:
        return x[1], -self.a * x[0] + self.b * xi1

    def first_step(self, x: State, xi1: float) -> FirstStep:
        eta1, eta2 = x
        th = math.tanh(self.k1 * eta2)
        s = 1.0 - th * th
        g = -self.a * eta1 + self.b * xi1  # η̇2
        ck = self.c1 * self.k1
        flow = Rated(
            -ck * s * g,
            ck * s * self.a * eta2 + 2.0 * ck * self.k1 * th * s * g * g,  # ∂/∂η · (η2, g)
            -ck * s * self.b,
        )
        return FirstStep(
            alpha1=-self.c1 * th,
            alpha1_flow=flow,
            f1=Rated(0.0, 0.0, 0.0),
            t_over_z=Rated(self.b * eta2, self.b * g, 0.0),  # ∂V/∂η·(0, B) = Bη2
        )

    def f2(self, x: State, xi1: float, xi2: float) -> float:
        return self.c * x[0] - self.d * xi1

    def lyapunov(self, x: State) -> tuple[float, float]:
        eta1, eta2 = x
        return (
            0.5 * self.a * eta1 * eta1 + 0.5 * eta2 * eta2,
            self.c1 * self.b * eta2 * math.tanh(self.k1 * eta2),
        )


class SuspensionController:
    """u(x) of (3.88) for the quarter-car state x = (x1, x2, x3, x4).

    Args:
        gains: the design constants (default: §3.3.3).
        constants: ω and ρ (default: §3.3.3).
        barrier: the term on z1; default the log barrier (3.75). ``QuadraticTerm(k3)`` gives
            the unconstrained baseline of PART1 §4.6 (no travel guarantee).
    """

    def __init__(
        self,
        gains: SuspensionGains | None = None,
        constants: QuarterCarConstants | None = None,
        barrier: Barrier | None = None,
    ) -> None:
        self.gains = gains or SuspensionGains()
        self.constants = constants or QuarterCarConstants()
        g = self.gains
        self.cascade = SuspensionCascade(self.constants, g)
        self.law = NonStrictClfLaw(
            self.cascade, barrier or LogBarrier(g.k2, g.k3), c1=g.c2, c2=g.c3, k2=g.k4
        )

    @classmethod
    def baseline(cls, gains: SuspensionGains | None = None) -> SuspensionController:
        """The same law with ½k3 z1² in place of the log barrier (Γ ≡ 1/k3)."""
        g = gains or SuspensionGains()
        return cls(g, barrier=QuadraticTerm(g.k3))

    @property
    def travel_bound(self) -> float:
        """k2 + c1, the bound of (3.84) on |x3| (for the log barrier)."""
        return self.gains.k2 + self.gains.c1

    def __call__(self, x: State, t: float = 0.0) -> float:
        """The law as state feedback u = k(x, t) (time-invariant): u [m/s²]."""
        return self.control(x)

    def coordinates(self, x: State) -> tuple[State, State]:
        """(η, ξ) of (3.64) from x = (x1, x2, x3, x4)."""
        x1, x2, x3, x4 = x
        r = self.constants.rho
        return (x1 + r / (r + 1) * x3, (x2 + r * x4) / (r + 1)), (x3, x4 - x2)

    def check(self, x: State) -> None:
        """Raise :class:`~cpbc.backstepping.design_errors.OutsideDomainError` unless |z1| < k2.

        The literal Fig. 3.7 start (x3 = −0.05 m, x2 = −20 m/s) has z1 = −0.0990 and is refused.
        """
        self.law.check(*self.coordinates(x))

    def control(self, x: State) -> float:
        """u [m/s²] at x (3.88); raises outside the domain."""
        eta, xi = self.coordinates(x)
        return -self.law.control(eta, xi) / self.cascade.e

    def errors(self, x: State) -> State:
        """(z1, z2) at x."""
        return self.law.errors(*self.coordinates(x))
