"""Two consecutive constrained states: Proposition 3.11 (m = 1), Theorem 3.13 (m = 2).

Besides Assumption 3.1 the cascade (3.3) must satisfy Assumptions 3.9 and 3.10 (:class:`Growth`):

    |∂α1/∂x·f(x, ξ1)| ≤ Ψ1  (3.93),   |T(x, ξ1)/(ξ1 − α1)| ≤ Ψ2  (3.94),   |f1| ≤ Ω

Then α2 of (3.111) (the same as (3.12)) is bounded on D (3.105), with Γ ≤ sup Γ (Lemma 3.12):

    |α2| < ᾱ2 := c1·max(a1, b1) + Ω + Ψ1 + sup Γ1 · Ψ2

m = 1 (Prop. 3.11): v = α2 is the input, bounded by ᾱ2. The RWP of §3.5 is this case: the
"second constraint" is the input v = −Bτ.

m = 2 (Thm 3.13): with a second barrier term β2 on z2 = ξ2 − α2 ∈ (−a2, b2),

    U  = V + β1(z1) + β2(z2)                                                 (3.106), corrected
    u  = −c2 z2 − f2 + α̇2 − Γ2(z2) z1/Γ1(z1)                                 (3.120)
    U̇ = −W − c1 z1²/Γ1(z1) − c2 z2²/Γ2(z2) ≤ 0                              (3.121)

so −(a1 + Δ) < ξ1 < b1 + Δ and −(a2 + ᾱ2) < ξ2 < b2 + ᾱ2 (3.128). The thesis asks a2, b2 ≥ ᾱ2
(3.129)/(3.130) so that any start with ξ2 = 0 is admissible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import Barrier, positive
from cpbc.backstepping.cascade import Cascade
from cpbc.backstepping.design_errors import DesignError, OutsideDomainError
from cpbc.backstepping.virtual_control import VirtualControl, virtual_control

State = tuple[float, ...]


def _non_negative(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0.0:
        raise DesignError(name, value, "must be finite and >= 0")
    return v


@dataclass(frozen=True)
class Growth:
    """The growth constants of Assumptions 3.9 and 3.10 (all ≥ 0).

    Attributes:
        psi1: Ψ1 ≥ sup |∂α1/∂x·f(x, ξ1)| over the achievable ξ1  (3.93).
        psi2: Ψ2 ≥ sup |T(x, ξ1)/(ξ1 − α1(x))|  (3.94).
        omega: Ω ≥ sup |f1(x, ξ1)|.
    """

    psi1: float
    psi2: float
    omega: float

    def __post_init__(self) -> None:
        for name in ("psi1", "psi2", "omega"):
            object.__setattr__(self, name, _non_negative(name, getattr(self, name)))


@dataclass(frozen=True)
class TwoConstraintLaw:
    """The law of Proposition 3.11 (m = 1) or Theorem 3.13 (m = 2) for a :class:`Cascade`.

    Args:
        cascade: the system and its Assumption-3.1 ingredients.
        barrier1: barrier term on z1 (Γ1 in this module's notation is the thesis's Γ).
        c1: gain of the first step (> 0).
        growth: Ψ1, Ψ2, Ω of Assumptions 3.9/3.10.
        barrier2: barrier term on z2 (m = 2 only; the thesis's Γ1 is our Γ2).
        c2: gain of the second step (> 0; m = 2 only).
    """

    cascade: Cascade
    barrier1: Barrier
    c1: float
    growth: Growth
    barrier2: Barrier | None = None
    c2: float | None = None

    def __post_init__(self) -> None:
        if self.cascade.m not in (1, 2):
            raise DesignError(
                "m", self.cascade.m, "only m = 1 (Prop. 3.11) and m = 2 (Thm 3.13) are built"
            )
        object.__setattr__(self, "c1", positive("c1", self.c1))
        if self.cascade.m == 2:
            if self.barrier2 is None or self.c2 is None:
                raise DesignError("barrier2/c2", float("nan"), "both required when m = 2")
            object.__setattr__(self, "c2", positive("c2", self.c2))

    @property
    def alpha2_bound(self) -> float:
        """ᾱ2 of (3.105)/(3.112): |α2| < ᾱ2 on D (for m = 1, the bound on the input v)."""
        b = self.barrier1
        g = self.growth
        return self.c1 * max(-b.lower, b.upper) + g.omega + g.psi1 + b.gamma_max * g.psi2

    def xi_bounds(self) -> tuple[tuple[float, float], ...]:
        """The achieved bounds on ξ1 (3.104) and, for m = 2, on ξ2 (3.128)."""
        d = self.cascade.delta
        out: tuple[tuple[float, float], ...] = ((self.barrier1.lower - d, self.barrier1.upper + d),)
        if self.barrier2 is not None and self.cascade.m == 2:
            a = self.alpha2_bound
            out += ((self.barrier2.lower - a, self.barrier2.upper + a),)
        return out

    @property
    def conditions_hold(self) -> bool:
        """a1, b1 > Δ and (m = 2) a2, b2 ≥ ᾱ2, the tuning conditions of Thm 3.13."""
        d = self.cascade.delta
        ok = self.barrier1.lower < -d and self.barrier1.upper > d
        if self.barrier2 is not None and self.cascade.m == 2:
            a = self.alpha2_bound
            ok = ok and self.barrier2.lower <= -a and self.barrier2.upper >= a
        return ok

    def _first(self, x: State, xi: State) -> VirtualControl:
        return virtual_control(self.cascade.first_step(x, xi[0]), self.barrier1, self.c1, xi[0])

    def errors(self, x: State, xi: State) -> State:
        """(z1,) or (z1, z2) at (x, ξ)."""
        vc = self._first(x, xi)
        return (vc.z1,) if self.cascade.m == 1 else (vc.z1, xi[1] - vc.alpha2)

    def check(self, x: State, xi: State) -> VirtualControl:
        """The first step at (x, ξ), or :class:`OutsideDomainError` if (x, ξ) ∉ D (3.108)."""
        vc = self._first(x, xi)
        b1 = self.barrier1
        if not b1.contains(vc.z1):
            raise OutsideDomainError(
                "z1", vc.z1, b1.lower, b1.upper,
                "the barrier term on z1 is infinite there, so the law is undefined (3.103)",
            )
        if self.barrier2 is not None and self.cascade.m == 2:
            z2 = xi[1] - vc.alpha2
            if not self.barrier2.contains(z2):
                raise OutsideDomainError(
                    "z2", z2, self.barrier2.lower, self.barrier2.upper,
                    "the barrier term on z2 = ξ2 − α2 is infinite there (3.126)",
                )
        return vc

    def control(self, x: State, xi: State) -> float:
        """v (m = 1) or u (m = 2) at (x, ξ); raises outside D."""
        vc = self.check(x, xi)
        if self.cascade.m == 1:
            return vc.alpha2
        assert self.barrier2 is not None and self.c2 is not None  # checked in __post_init__
        xi1, xi2 = xi
        z2 = xi2 - vc.alpha2
        return (
            -self.c2 * z2
            - self.cascade.f2(x, xi1, xi2)
            + vc.rate(vc.xi1_dot(xi2))
            - self.barrier2.gamma(z2) * vc.z1 / vc.gamma
        )

    def lyapunov(self, x: State, xi: State) -> float:
        """U (3.99) or (3.106)."""
        z = self.errors(x, xi)
        u = self.cascade.lyapunov(x)[0] + self.barrier1.value(z[0])
        if self.barrier2 is not None and self.cascade.m == 2:
            u += self.barrier2.value(z[1])
        return u

    def lyapunov_rate(self, x: State, xi: State) -> float:
        """U̇ in closed loop as the theorem states it: −W − c1 z1²/Γ1 − c2 z2²/Γ2 (3.121)."""
        z = self.errors(x, xi)
        rate = -self.cascade.lyapunov(x)[1] - self.c1 * z[0] ** 2 / self.barrier1.gamma(z[0])
        if self.barrier2 is not None and self.c2 is not None and self.cascade.m == 2:
            rate -= self.c2 * z[1] ** 2 / self.barrier2.gamma(z[1])
        return rate
