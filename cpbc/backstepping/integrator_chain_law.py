"""§4.4: the 4th-order integrator chain under the design of Theorem 4.12 (manual tuning).

Plant (4.92): ξ̇1 = ξ2, ξ̇2 = ξ3, ξ̇3 = ξ4, ξ̇4 = u, with |ξ2| ≤ 2.5, |ξ3| ≤ 12, |ξ4| ≤ 700 (4.93,
read as symmetric bounds, form (4.2)); ξ1 is unconstrained. The thesis gives eleven constants
(c1 … c4, k1 … k7) but neither α1, V nor how the constants map to the steps. PART1 Ch. 4 §2.6
reading H1, used here: x = ξ1 is the x-subsystem (n = 1, f(x, ξ2) = ξ2), the constrained chain is
(ξ2, ξ3, ξ4) (m = 3), and

    α1 = −c1 arctan x            |α1| < c1 π/2 = 0.25
    V  = k1 x tanh x             W = −V'(x) α1(x) = c1 k1 (tanh x + x sech²x) arctan x ≥ 0
    T/z1 = V'(x) = k1 (tanh x + x sech²x)     (f affine in ξ2 with unit gain, so exact)
    step 1: z1 = ξ2 − α1,  bound k2,  weight k3,  gain c2
    step 2: z2 = ξ3 − α2,  bound k4,  weight k5,  gain c3
    step 3: z3 = ξ4 − α3,  bound k6,  weight k7,  gain c4

i.e. :class:`MultipleConstraintLaw` with c = (c2, c3, c4) and barriers (k2, k3), (k4, k5), (k6, k7)
(the pairing of (4.70): weight k_{2i+1} with bound k_{2i}). Only c1 … c4, k1, k2, k3 enter u.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from cpbc.arrays import Array
from cpbc.backstepping.barrier_terms import LogBarrier, positive
from cpbc.backstepping.jets import arctan, tanh
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.regions import Region
from cpbc.backstepping.strict_feedback import StrictFeedback, Value
from cpbc.backstepping.tuning import RULES, TuningProblem

State = tuple[float, ...]


@dataclass(frozen=True)
class ChainGains:
    """The design constants of §4.4 under the thesis's names (all > 0), read as H1."""

    c1: float = 0.5 / math.pi
    c2: float = 1.0
    c3: float = 50.0
    c4: float = 1.0
    k1: float = 1.0
    k2: float = 2.0
    k3: float = 3.0
    k4: float = 5.61
    k5: float = 1.0
    k6: float = 354.5
    k7: float = 10.0

    def __post_init__(self) -> None:
        for name in self.names():
            object.__setattr__(self, name, positive(name, getattr(self, name)))

    @staticmethod
    def names() -> tuple[str, ...]:
        """The constants in the thesis's order."""
        return ("c1", "c2", "c3", "c4", "k1", "k2", "k3", "k4", "k5", "k6", "k7")


def thesis_symbols(statement: str) -> str:
    """Rewrite Theorem 4.12's symbols (the generic law's c_i, k_j, Ξ_i, X_i) in the names §4.4
    gives them under H1: gains c_i → c_{i+1}, bounds k_{2i} unchanged, weights
    k_{2i−1} → k_{2i+1}, and the i-th constrained state is ξ_{i+1} (Ξ_i, X_i → Ξ_{i+1}, X_{i+1});
    α_i, z_i and a_i keep their step numbers."""
    def one(m: re.Match[str]) -> str:
        sym, j = m.group(1), int(m.group(2))
        return f"{sym}{j + 2 if sym == 'k' and j % 2 else j if sym == 'k' else j + 1}"

    return re.sub(r"(?<![A-Za-z0-9_])([ckΞX])(\d+)", one, statement)


class ChainSystem(StrictFeedback):
    """The chain as a system of class (4.1): x = ξ1, constrained (ξ2, …, ξ_{m+1}), no f_i.

    Args:
        amplitude: c1 of α1 = −c1 arctan x.
        weight: k1 of V = k1 x tanh x.
        m: number of constrained states (3 for §4.4).
    """

    n = 1

    def __init__(self, amplitude: float, weight: float, m: int = 3) -> None:
        self.amplitude = positive("c1", amplitude)
        self.weight = positive("k1", weight)
        self.m = m

    def flow(self, x: Sequence[Value], xi1: Value) -> tuple[Value, ...]:
        return (xi1,)

    def alpha1(self, x: Sequence[Value]) -> Value:
        return -self.amplitude * arctan(x[0])

    def t_over_z(self, x: Sequence[Value], xi1: Value) -> Value:
        th = tanh(x[0])
        return self.weight * (th + x[0] * (1.0 - th * th))

    def lyapunov(self, x: Sequence[Value]) -> tuple[Value, Value]:
        th = tanh(x[0])
        v = self.weight * x[0] * th
        return v, self.weight * (th + x[0] * (1.0 - th * th)) * self.amplitude * arctan(x[0])

    def x_samples(self) -> Array:
        theta = np.linspace(-0.5 * math.pi + 1e-7, 0.5 * math.pi - 1e-7, 1601)
        return np.tan(theta)[:, None]


class IntegratorChainController:
    """u(ξ) for the plant state ξ = (ξ1, ξ2, ξ3, ξ4) of (4.92).

    Args:
        gains: the design constants (default: §4.4).
    """

    def __init__(self, gains: ChainGains | None = None) -> None:
        self.gains = g = gains or ChainGains()
        self.system = ChainSystem(g.c1, g.k1)
        self.law = MultipleConstraintLaw(
            self.system, (g.c2, g.c3, g.c4),
            (LogBarrier(g.k2, g.k3), LogBarrier(g.k4, g.k5), LogBarrier(g.k6, g.k7)),
        )

    @staticmethod
    def coordinates(state: Sequence[float]) -> tuple[State, State]:
        """(x, ξ) of the design from the plant state: x = (ξ1,), chain (ξ2, ξ3, ξ4)."""
        return (float(state[0]),), tuple(float(v) for v in state[1:])

    def check(self, state: Sequence[float]) -> State:
        """(z1, z2, z3), or :class:`~cpbc.backstepping.design_errors.OutsideDomainError`
        outside D."""
        return tuple(float(v) for v in self.law.check(*self.coordinates(state)).z)

    def control(self, state: Sequence[float]) -> float:
        """u (4.74) at ξ; raises outside D (there U is infinite and nothing is guaranteed)."""
        return float(self.law.check(*self.coordinates(state)).u)

    def __call__(self, state: Sequence[float], t: float = 0.0) -> float:
        """The law as state feedback u = k(ξ, t) (time-invariant)."""
        return self.control(state)

    def errors(self, state: Sequence[float]) -> State:
        """(z1, z2, z3) at ξ (also outside D)."""
        return tuple(float(v) for v in self.law.errors(*self.coordinates(state)))


#: The constants that enter the manual rules (well-posedness and X_i, (4.88)): c4, k5 and k7
#: appear only in u's last gain and the certificate U, so the manual rules cannot move them.
MANUAL_FREE = ("c1", "c2", "c3", "k1", "k2", "k3", "k4", "k6")


def tuning_problem(gains: ChainGains | None = None,
                   limits: Sequence[float] = (2.5, 12.0, 700.0), rules: str = "theorem",
                   free: Sequence[str] | None = None, region: Region | None = None
                   ) -> TuningProblem:
    """The §4.3.3 tuning problem of the chain (reading H1) from the given constants: every
    constant free under the theorem's rules, :data:`MANUAL_FREE` under the manual ones; with
    a ``region``, its sups over that region only (§4.3.5)."""
    g = gains or ChainGains()
    names = ChainGains.names()
    chosen = tuple(free) if free is not None else (
        names if "domination" in RULES.get(rules, ()) else MANUAL_FREE)
    return TuningProblem(
        names, tuple(getattr(g, n) for n in names), chosen,
        lambda v: IntegratorChainController(ChainGains(**v)).law,
        tuple(float(v) for v in limits), rename=thesis_symbols, region=region)


def local_problems(gains: ChainGains | None = None,
                   limits: Sequence[float] = (2.5, 12.0, 700.0), fixed: Sequence[str] = ()
                   ) -> Callable[[Region, str], TuningProblem]:
    """region, rules ↦ the chain's tuning problem on that region (§4.3.5). Under the theorem's
    rules the search starts with the later weights k5, k7 raised ×1000: they enter neither u nor
    X_i, only the inner domination conditions (4.60), (4.78), which raising them meets (from
    the thesis's k5 = 1, k7 = 10 the search finds no feasible point on the small regions).
    The constants in ``fixed`` keep their given values under both rules."""
    g = gains or ChainGains()

    def make(region: Region, rules: str) -> TuningProblem:
        start = g if rules == "manual" else replace(g, k5=1000 * g.k5, k7=1000 * g.k7)
        free = ChainGains.names() if rules == "theorem" else MANUAL_FREE
        return tuning_problem(start, limits, rules, [n for n in free if n not in fixed], region)

    return make
