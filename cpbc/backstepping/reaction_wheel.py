"""§3.5: the Reaction Wheel Pendulum with rate and torque limits, by Proposition 3.11 (m = 1).

Plant (3.137), q1 the pendulum angle from upright, q2 the wheel angle relative to the pendulum:

    d11 q̈1 + d12 q̈2 − d0 sin q1 = 0,   d21 q̈1 + d22 q̈2 = τ

Cascade coordinates (3.138)–(3.140) (η1 the angular momentum about the pivot):

    η1 = d11 q̇1 + d12 q̇2,  η2 = q1,  ξ = q̇1
    η̇1 = d0 sin η2,  η̇2 = ξ,  ξ̇ = (A + C) sin η2 − Bτ
    A = d0/d11,  B = d12/(d11d22 − d21d12),  C = (d12d21d0/d11)/(d11d22 − d21d12)

With v = −Bτ as the input this is (3.96) with f1 = (A + C) sin η2. The design (thesis names):

    V  = ½k1 log(1 + η1²) + k2 log(2 − cos η2)                             (3.142)
    α1 = −c1 sin η2 − k1d0 η1 (2 − cos η2)/(k2(1 + η1²))                   (3.143)
    W  = c1k2 sin²η2/(2 − cos η2),  z = ξ − α1                              (3.147)
    U  = V + ½k3 log(k4²/(k4² − z²))                                        (3.151)
    τ  = (1/B)[c2 z + (A + C) sin η2 − α̇1 + k2(k4² − z²) sin η2/(k3(2 − cos η2))]   (3.153)
    U̇ = −W − k3c2 z²/(k4² − z²) ≤ 0                                        (3.154)

which is :class:`TwoConstraintLaw` (m = 1) with a :class:`LogBarrier` (bound k4, weight k3) and
step gain c2. :meth:`ReactionWheelController.bounds` evaluates (3.148), (3.157)–(3.159) as
printed and corrected (PART1 §5.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import LogBarrier, positive
from cpbc.backstepping.cascade import Cascade, FirstStep, Rated
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.two_constraints import Growth, TwoConstraintLaw

State = tuple[float, ...]

#: max over x of |(2 − cos x) sin x|, attained at cos x = (1 − √3)/2; (3.158) prints 2
KAPPA = (2.0 - (1.0 - math.sqrt(3.0)) / 2.0) * math.sqrt(1.0 - ((1.0 - math.sqrt(3.0)) / 2.0) ** 2)


@dataclass(frozen=True)
class WheelPendulumConstants:
    """The lumped d's of (3.136) [kg m², N m]; default: the values stated in §3.5.3."""

    d11: float = 4.83e-3
    d12: float = 32e-6
    d22: float = 32e-6
    d0: float = 379.3e-3

    def __post_init__(self) -> None:
        for name in ("d11", "d12", "d22", "d0"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))
        if self.d11 * self.d22 - self.d12**2 <= 0.0:
            raise DesignError("d11", self.d11, "[[d11, d12], [d12, d22]] must be positive definite")

    @property
    def abc(self) -> tuple[float, float, float]:
        """(A, B, C) of (3.140)."""
        det = self.d11 * self.d22 - self.d12 * self.d12
        return (
            self.d0 / self.d11,
            self.d12 / det,
            self.d12 * self.d12 * self.d0 / self.d11 / det,
        )


@dataclass(frozen=True)
class WheelPendulumGains:
    """The design constants of §3.5.3 under the thesis's names (all > 0)."""

    k1: float = 57.5e-3
    k2: float = 2.225
    k3: float = 0.25
    k4: float = 0.501
    c1: float = 0.5
    c2: float = 1.0

    def __post_init__(self) -> None:
        for name in ("k1", "k2", "k3", "k4", "c1", "c2"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))


@dataclass(frozen=True)
class WheelPendulumBounds:
    """The a-priori bounds of §3.5.2, each as printed and as corrected (PART1 §5.3).

    Attributes:
        alpha1: sup |α1| (3.148): printed c1 + k1d0/k2; corrected c1 + (3/2)k1d0/k2.
        rate: the bound on |q̇1| (3.157): k4 + sup |α1|.
        alpha1_dot: sup |α̇1| (3.158) with κ = 2 printed, κ = max|(2 − cos)sin| corrected.
        torque: the bound on |τ| (3.159).
    """

    alpha1: tuple[float, float]
    rate: tuple[float, float]
    alpha1_dot: tuple[float, float]
    torque: tuple[float, float]


class WheelPendulumCascade(Cascade):
    """The η-subsystem of (3.140) with V, α1 of (3.142)/(3.143): Assumption 3.1's ingredients."""

    m = 1

    def __init__(self, constants: WheelPendulumConstants, gains: WheelPendulumGains) -> None:
        self.d0 = constants.d0
        a, self.b, c = constants.abc
        self.ac = a + c
        self.k1, self.k2, self.c1 = gains.k1, gains.k2, gains.c1
        self.kd = gains.k1 * constants.d0 / gains.k2
        self.delta = gains.c1 + 1.5 * self.kd  # corrected (3.148)

    def flow(self, x: State, xi1: float) -> State:
        return self.d0 * math.sin(x[1]), xi1

    def first_step(self, x: State, xi1: float) -> FirstStep:
        eta1, eta2 = x
        sn, cs = math.sin(eta2), math.cos(eta2)
        q = 2.0 - cs
        n = 1.0 + eta1 * eta1
        kd, c1, d0 = self.kd, self.c1, self.d0
        e1 = d0 * sn  # η̇1
        # first and second partial derivatives of α1
        a_1 = -kd * q * (1.0 - eta1 * eta1) / (n * n)
        a_2 = -c1 * cs - kd * eta1 * sn / n
        a_11 = -kd * q * 2.0 * eta1 * (eta1 * eta1 - 3.0) / n**3
        a_12 = -kd * sn * (1.0 - eta1 * eta1) / (n * n)
        a_22 = c1 * sn - kd * eta1 * cs / n
        flow = Rated(
            a_1 * e1 + a_2 * xi1,
            (a_11 * e1 + a_12 * xi1) * e1 + (a_12 * e1 + a_1 * d0 * cs + a_22 * xi1) * xi1,
            a_2,
        )
        return FirstStep(
            alpha1=-c1 * sn - kd * eta1 * q / n,
            alpha1_flow=flow,
            f1=Rated(self.ac * sn, self.ac * cs * xi1, 0.0),
            t_over_z=Rated(
                self.k2 * sn / q, self.k2 * (2.0 * cs - 1.0) / (q * q) * xi1, 0.0
            ),  # ∂V/∂η·(0, 1)
        )

    def lyapunov(self, x: State) -> tuple[float, float]:
        eta1, eta2 = x
        q = 2.0 - math.cos(eta2)
        v = 0.5 * self.k1 * math.log1p(eta1 * eta1) + self.k2 * math.log(q)
        return v, self.c1 * self.k2 * math.sin(eta2) ** 2 / q


class ReactionWheelController:
    """τ(x) of (3.153) for the state x = (q1, q̇1, q̇2) [rad, rad/s, rad/s].

    Args:
        gains: the design constants (default: §3.5.3).
        constants: the lumped d's (default: the stated values of §3.5.3).
    """

    def __init__(
        self,
        gains: WheelPendulumGains | None = None,
        constants: WheelPendulumConstants | None = None,
    ) -> None:
        self.gains = gains or WheelPendulumGains()
        self.constants = constants or WheelPendulumConstants()
        g = self.gains
        self.cascade = WheelPendulumCascade(self.constants, g)
        b = self.bounds()
        # Assumptions 3.9/3.10: Ψ1 = sup|α̇1|, Ψ2 = k2·max sin/(2 − cos) = k2/√3, Ω = A + C
        growth = Growth(b.alpha1_dot[1], g.k2 / math.sqrt(3.0), self.cascade.ac)
        self.law = TwoConstraintLaw(self.cascade, LogBarrier(g.k4, g.k3), c1=g.c2, growth=growth)

    def __call__(self, x: State, t: float = 0.0) -> float:
        """The law as state feedback u = k(x, t) (time-invariant): τ [N m]."""
        return self.control(x)

    def coordinates(self, x: State) -> tuple[State, State]:
        """(η, ξ) of (3.138)–(3.140) from x = (q1, q̇1, q̇2)."""
        q1, dq1, dq2 = x
        c = self.constants
        return (c.d11 * dq1 + c.d12 * dq2, q1), (dq1,)

    def check(self, x: State) -> None:
        """Raise :class:`~cpbc.backstepping.design_errors.OutsideDomainError` unless |z| < k4."""
        self.law.check(*self.coordinates(x))

    def control(self, x: State) -> float:
        """τ [N m] at x (3.153); raises outside the domain."""
        eta, xi = self.coordinates(x)
        return -self.law.control(eta, xi) / self.cascade.b

    def errors(self, x: State) -> State:
        """(z,) at x."""
        return self.law.errors(*self.coordinates(x))

    @staticmethod
    def at_downward_equilibrium(x: State, tol: float = 1e-12) -> bool:
        """q1 ≡ π (mod 2π) within ``tol`` [rad], with q̇ = 0: a closed-loop equilibrium.

        sin q1 = 0 gives α1 = 0, z = 0 and τ ≡ 0, and (3.154)'s LaSalle set contains the point,
        so the thesis's "(π, 0, 0)" run cannot leave it (float64 π is off by 1.2e-16, below
        the ulp of q1, and stays put too). The equilibrium is unstable (eigenvalue ≈ +0.90 s⁻¹).
        """
        q1, dq1, dq2 = x
        return abs(math.sin(q1)) <= tol and math.cos(q1) < 0.0 and dq1 == 0.0 and dq2 == 0.0

    def bounds(self) -> WheelPendulumBounds:
        """(3.148), (3.157), (3.158), (3.159), printed and corrected."""
        g = self.gains
        a, b, c = self.constants.abc
        kd = g.k1 * self.constants.d0 / g.k2
        kd0 = kd * self.constants.d0  # k1 d0²/k2
        out = []
        for factor, kappa in ((1.0, 2.0), (1.5, KAPPA)):
            sup_a1 = g.c1 + factor * kd
            rate = g.k4 + sup_a1
            sup_da1 = g.c1 * rate + kd * rate / 2.0 + kappa * kd0
            torque = (g.c2 * g.k4 + a + c + sup_da1 + g.k2 * g.k4**2 / g.k3) / b
            out.append((sup_a1, rate, sup_da1, torque))
        (pa, pr, pd, pt), (ca, cr, cd, ct) = out
        return WheelPendulumBounds((pa, ca), (pr, cr), (pd, cd), (pt, ct))
