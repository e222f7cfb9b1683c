"""Several constrained states with a non-strict cLf: the design of §4.3, Theorem 4.12.

For a :class:`~cpbc.backstepping.strict_feedback.StrictFeedback` system (4.1) with
Assumptions 4.6–4.8, and a log barrier per step (bound K_i = k_{2i}, weight κ_i = k_{2i−1} in the
thesis's body indexing), the law is, step by step (PART1 Ch. 4 §2.3):

    z1 = ξ1 − α1(x)                                                        (4.23)
    α2 = −c1 z1 − f1 + α̇1 − (K1² − z1²)·(T/z1)/κ1                          (4.30)
    z_i = ξ_i − α_i,   α_{i+1} = −c_i z_i − f_i + α̇_i     (2 ≤ i ≤ m−1)    (4.40), (4.46)
    u = −c_m z_m − f_m + α̇_m                                               (4.67), (4.74)

with every α̇_i the exact derivative along the nominal flow (jets). The cross-terms are *not*
cancelled, so u is bounded on D; in closed loop

    ż1 = −c1 z1 − (K1² − z1²)(T/z1)/κ1 + z2,   ż_i = −c_i z_i + z_{i+1},   ż_m = −c_m z_m
                                                                     (4.32), (4.51), (4.75)

and the cLf U = V + Σ_i ½κ_i log(K_i²/(K_i² − z_i²)) (4.27), (4.42), (4.70) has, exactly,

    U̇ = −W − Σ_i κ_i c_i z_i²/(K_i² − z_i²) + Σ_{i<m} κ_i z_i z_{i+1}/(K_i² − z_i²)   (4.52), (4.76)

which is ≤ 0 on D = {|z_i| < K_i} (4.83) only under the domination conditions of §4.3
(see :mod:`cpbc.backstepping.parameter_constraints`). Only c_1 … c_m, K1 and κ1 enter u; the
other barriers give the domain D, the certificate U and the tuning constraints.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import LogBarrier, positive
from cpbc.backstepping.design_errors import DesignError, OutsideDomainError
from cpbc.backstepping.jets import Coef, as_jet
from cpbc.backstepping.strict_feedback import StrictFeedback, nominal_jets


@dataclass(frozen=True)
class LawTerms:
    """The law's intermediate quantities at one state (floats, or arrays on a grid).

    Attributes:
        z: (z1, …, zm).
        alpha: (α1, …, αm), the stabilising functions (ξ_i = z_i + α_i).
        u: the control (4.74).
    """

    z: tuple[Coef, ...]
    alpha: tuple[Coef, ...]
    u: Coef


@dataclass(frozen=True)
class MultipleConstraintLaw:
    """The law of Theorem 4.12 for a system of class (4.1).

    Args:
        system: the system and its first-step ingredients.
        c: the step gains c1 … cm (> 0).
        barriers: one :class:`LogBarrier` per step: bound K_i (the thesis's k_{2i}) and weight
            κ_i (k_{2i−1}).
    """

    system: StrictFeedback
    c: tuple[float, ...]
    barriers: tuple[LogBarrier, ...]

    def __post_init__(self) -> None:
        m = self.system.m
        if len(self.c) != m or len(self.barriers) != m:
            raise DesignError(
                "c/barriers", float(len(self.c)),
                f"the system has m = {m} constrained states: give {m} gains and {m} barriers",
            )
        object.__setattr__(
            self, "c", tuple(positive(f"c{i + 1}", v) for i, v in enumerate(self.c)))

    @property
    def bounds(self) -> tuple[float, ...]:
        """(K1, …, Km): the domain D is |z_i| < K_i (4.83)."""
        return tuple(b.bound for b in self.barriers)

    @property
    def weights(self) -> tuple[float, ...]:
        """(κ1, …, κm), the barrier weights."""
        return tuple(b.k for b in self.barriers)

    def terms(self, x: Sequence[Coef], xi: Sequence[Coef]) -> LawTerms:
        """z, α and u at (x, ξ) (floats, or arrays of one shape)."""
        sys, m = self.system, self.system.m
        xj, yj = nominal_jets(sys, x, xi, m)
        f = sys.drifts(xj, yj)
        a1 = as_jet(sys.alpha1(xj), m)
        k1, w1 = self.barriers[0].bound, self.barriers[0].k
        z = yj[0] - a1
        alpha = (  # (4.30)
            -self.c[0] * z - f[0] + a1.dot() - (k1 * k1 - z * z) * sys.t_over_z(xj, yj[0]) / w1
        )
        zs: list[Coef] = [z.value]
        alphas: list[Coef] = [a1.value]
        for i in range(1, m):
            alphas.append(alpha.value)
            z = yj[i] - alpha
            alpha = -self.c[i] * z - f[i] + alpha.dot()  # (4.46); (4.74) for i = m−1
            zs.append(z.value)
        return LawTerms(tuple(zs), tuple(alphas), alpha.value)

    def control(self, x: Sequence[Coef], xi: Sequence[Coef]) -> Coef:
        """u (4.74) at (x, ξ). Defined everywhere (no cancelled cross-term has a pole); the
        guarantees need (x, ξ) ∈ D, see :meth:`check`."""
        return self.terms(x, xi).u

    def errors(self, x: Sequence[Coef], xi: Sequence[Coef]) -> tuple[Coef, ...]:
        """(z1, …, zm) at (x, ξ)."""
        return self.terms(x, xi).z

    def check(self, x: Sequence[float], xi: Sequence[float]) -> LawTerms:
        """The law's terms at (x, ξ), or :class:`OutsideDomainError` for the first
        |z_i| ≥ K_i (4.83)."""
        terms = self.terms(x, xi)
        for i, (zi, b) in enumerate(zip(terms.z, self.barriers, strict=True)):
            if not b.contains(float(zi)):
                raise OutsideDomainError(
                    f"z{i + 1}", float(zi), -b.bound, b.bound,
                    f"Theorem 4.12 needs every |z_i| < k_{2 * i + 2} (D of (4.83)); there the "
                    "cLf is infinite and neither the state bounds nor stability are guaranteed",
                )
        return terms

    def state_from_errors(self, x: Sequence[Coef], z: Sequence[Coef]) -> tuple[Coef, ...]:
        """The ξ with errors z at x: ξ_i = z_i + α_i(x, ξ1 … ξ_{i−1}), built step by step."""
        xi: list[Coef] = [0.0 * zi for zi in z]
        for i in range(self.system.m):
            xi[i] = z[i] + self.terms(x, xi).alpha[i]
        return tuple(xi)

    def lyapunov(self, x: Sequence[float], xi: Sequence[float]) -> float:
        """U_m (4.70): V + Σ ½κ_i log(K_i²/(K_i² − z_i²)); ∞ outside D."""
        z = self.errors(x, xi)
        v = float(self.system.lyapunov(x)[0])
        return v + sum(b.value(float(zi)) for b, zi in zip(self.barriers, z, strict=True))

    def lyapunov_rate(self, x: Sequence[float], xi: Sequence[float]) -> float:
        """U̇_m in closed loop, the exact identity behind (4.52)/(4.76):

        −W − Σ κ_i c_i z_i²/(K_i² − z_i²) + Σ_{i<m} κ_i z_i z_{i+1}/(K_i² − z_i²).
        """
        z = [float(v) for v in self.errors(x, xi)]
        rate = -float(self.system.lyapunov(x)[1])
        for i, b in enumerate(self.barriers):
            p = b.k / (b.bound * b.bound - z[i] * z[i])
            rate -= self.c[i] * p * z[i] * z[i]
            if i + 1 < len(z):
                rate += p * z[i] * z[i + 1]
        return rate

