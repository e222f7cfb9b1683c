"""One constrained state with a non-strict cLf: Proposition 3.2 (m = 1), Theorem 3.6 (m = 2).

For the cascade (3.3) with Assumption 3.1 and the constraint −B_L < ξ1 < B_U (3.4), the cLf

    U = V(x) + β(z1) + ½ k2 z2²                        (3.11), (3.31) with the ½ of PART1 §0

with a barrier term β on z1 ∈ (lower, upper) and the control

    m = 1:  v = α2                                                        (3.12)
    m = 2:  z2 = ξ2 − α2,  u = −c2 z2 − f2 + α̇2 − z1/(k2 Γ(z1))            (3.38), corrected

give, on the domain D = {z1 ∈ (lower, upper)},

    U̇ = −W(x) − c1 z1²/Γ(z1) − c2 k2 z2² ≤ 0                              (3.18), (3.39)

so z1 never leaves its interval, −(a1 + Δ) < ξ1 < b1 + Δ (3.26), and the origin is D-DGAS.
(3.38) prints the cross-term k1 z1/k2; the ½-storage and the barrier step make it z1/(k2 Γ(z1)).
"""

from __future__ import annotations

from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import Barrier, positive
from cpbc.backstepping.cascade import Cascade
from cpbc.backstepping.design_errors import DesignError, OutsideDomainError
from cpbc.backstepping.virtual_control import VirtualControl, virtual_control

State = tuple[float, ...]


@dataclass(frozen=True)
class NonStrictClfLaw:
    """The barrier backstepping law of Theorem 3.6 for a :class:`Cascade` with m ∈ {1, 2}.

    Args:
        cascade: the system and its Assumption-3.1 ingredients.
        barrier: the barrier term on z1 (rational (3.11) or log (3.75)).
        c1: gain of the first step (> 0).
        c2: gain of the second step (> 0; m = 2 only).
        k2: weight of ½ z2² in U (> 0; m = 2 only).
    """

    cascade: Cascade
    barrier: Barrier
    c1: float
    c2: float | None = None
    k2: float | None = None

    def __post_init__(self) -> None:
        if self.cascade.m not in (1, 2):
            raise DesignError(
                "m", self.cascade.m, "only m = 1 (Prop. 3.2) and m = 2 (Thm 3.6) are built; "
                "a larger m needs higher derivatives of α2 than a Cascade supplies"
            )
        object.__setattr__(self, "c1", positive("c1", self.c1))
        if self.cascade.m == 2:
            for name in ("c2", "k2"):
                value = getattr(self, name)
                if value is None:
                    raise DesignError(name, float("nan"), "required when m = 2")
                object.__setattr__(self, name, positive(name, value))

    @property
    def zero_start_admissible(self) -> bool:
        """a1 > Δ and b1 > Δ (Prop. 3.2): then every state with ξ1 = 0 lies in D."""
        return self.barrier.lower < -self.cascade.delta and self.barrier.upper > self.cascade.delta

    def xi1_bounds(self) -> tuple[float, float]:
        """The achieved bound on ξ1 (3.26): (lower − Δ, upper + Δ)."""
        return self.barrier.lower - self.cascade.delta, self.barrier.upper + self.cascade.delta

    def _first(self, x: State, xi: State) -> VirtualControl:
        return virtual_control(self.cascade.first_step(x, xi[0]), self.barrier, self.c1, xi[0])

    def check(self, x: State, xi: State) -> VirtualControl:
        """The first step at (x, ξ), or :class:`OutsideDomainError` if z1 ∉ (lower, upper)."""
        vc = self._first(x, xi)
        if not self.barrier.contains(vc.z1):
            raise OutsideDomainError(
                "z1", vc.z1, self.barrier.lower, self.barrier.upper,
                "the barrier term of U is infinite there, so the law is undefined; a start "
                "needs z1(0) = ξ1(0) − α1(x(0)) inside the interval (Thm 3.6, (3.25))",
            )
        return vc

    def errors(self, x: State, xi: State) -> State:
        """(z1,) or (z1, z2) at (x, ξ) (3.8), (3.30)."""
        vc = self._first(x, xi)
        return (vc.z1,) if self.cascade.m == 1 else (vc.z1, xi[1] - vc.alpha2)

    def control(self, x: State, xi: State) -> float:
        """v (m = 1) or u (m = 2) at (x, ξ); raises outside D."""
        vc = self.check(x, xi)
        if self.cascade.m == 1:
            return vc.alpha2
        assert self.c2 is not None and self.k2 is not None  # checked in __post_init__
        xi1, xi2 = xi
        z2 = xi2 - vc.alpha2
        return (
            -self.c2 * z2
            - self.cascade.f2(x, xi1, xi2)
            + vc.rate(vc.xi1_dot(xi2))
            - vc.z1 / (self.k2 * vc.gamma)
        )

    def lyapunov(self, x: State, xi: State) -> float:
        """U(x, z) (3.31)."""
        z = self.errors(x, xi)
        u = self.cascade.lyapunov(x)[0] + self.barrier.value(z[0])
        if self.cascade.m == 2:
            assert self.k2 is not None
            u += 0.5 * self.k2 * z[1] ** 2
        return u

    def lyapunov_rate(self, x: State, xi: State) -> float:
        """U̇ in closed loop as Theorem 3.6 states it (3.39): −W − c1 z1²/Γ(z1) − c2 k2 z2²."""
        z = self.errors(x, xi)
        rate = -self.cascade.lyapunov(x)[1] - self.c1 * z[0] ** 2 / self.barrier.gamma(z[0])
        if self.cascade.m == 2:
            assert self.c2 is not None and self.k2 is not None
            rate -= self.c2 * self.k2 * z[1] ** 2
        return rate
