"""The constraints on the controller parameters of §4.3 (Theorem 4.12), as a checker.

For a :class:`~cpbc.backstepping.multiple_constraints.MultipleConstraintLaw` with gains c_i,
barrier bounds K_i = k_{2i} and weights κ_i = k_{2i−1} (the thesis's body indexing), and state
limits Ξ_i, the checker evaluates every condition and says which holds:

* well-posedness of the zero start, K_i > sup |α_i| over D: (4.37) for i = 1, (4.66) for i = 2,
  (4.82) for i = m. The thesis bounds sup |α2| by the triangle inequality (4.38); here the sup is
  searched over D = {|z_j| < K_j} itself (:func:`worst_case`), which is smaller and exact up to
  the search's resolution.
* worst-case state bounds X_i = K_i + sup_D |α_i| (4.88) against the limits, X_i ≤ Ξ_i (4.89).
* cross-term domination, needed for U̇ ≤ 0 (Lyapunov stability), with free constants
  a_i ∈ (0, 1) (PART1 Ch. 4 §2.4: the thesis's (0, √2) breaks the case split). For the pair
  (z_i, z_{i+1}), with θ_i the share of c_i's damping still unused (1 for i = 1, ½ after) and
  φ the share of c_{i+1}'s offered to it (½, or 1 at the last step):

      outer  θ_i c_i ≥ K_{i+1}²/(K_i a_i)² + ½                 (4.55) i = 1;  (4.77) i = m−1
      inner  φ κ_{i+1} c_{i+1}/K_{i+1}² ≥ κ_i/(2 K_i²(1 − a_i²))  (4.60) φ = ½;  (4.78) φ = 1

  (4.77) as printed (c_{m−1} ≥ …, θ = 1) is not enough for m ≥ 3: half of c_{m−1}'s term was
  already spent in the previous pair's (4.60). The weights κ_{i≥2} enter neither u nor X, so
  the inner conditions can always be met by raising them; the outer ones cannot.
* invariance of D without domination (not in the thesis): in closed loop z2 … zm obey the
  linear cascade ż_i = −c_i z_i + z_{i+1}, ż_m = −c_m z_m, and at |z1| = K1 the barrier term of
  (4.32) vanishes, ż1 = −c1 z1 + z2. So D is forward invariant (and the bounds X_i hold for all
  time from every start in D) if the cascade's reach from the box stays within it,
  R_i ≤ K_i (i ≥ 2), and R_2 ≤ c1 K1.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.linear_reach import box_reach
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.regions import Region, region_states
from cpbc.backstepping.worst_case import Sup, grid_sup


@dataclass(frozen=True)
class Condition:
    """One condition on the parameters, lhs ≥ rhs (or > when strict).

    Attributes:
        label: the thesis's equation number, e.g. "(4.55)".
        kind: "well-posed", "state bound", "domination" or "invariance".
        statement: the condition in the thesis's symbols.
        lhs, rhs: its two sides, evaluated.
        strict: whether it needs lhs > rhs.
        note: how it departs from the printed condition, if it does.
    """

    label: str
    kind: str
    statement: str
    lhs: float
    rhs: float
    strict: bool = False
    note: str = ""

    @property
    def holds(self) -> bool:
        return self.lhs > self.rhs if self.strict else self.lhs >= self.rhs


@dataclass(frozen=True)
class WorstCase:
    """sup_D |α_i| and the state bounds X_i = K_i + sup_D |α_i| (4.88).

    Attributes:
        alpha: per step, the largest |α_i| found on D and where (x; z_1 … z_{i−1}).
        state_bounds: X_1 … X_m.
    """

    alpha: tuple[Sup, ...]
    state_bounds: tuple[float, ...]


def worst_case(law: MultipleConstraintLaw, points: int = 21, budget: int = 400_000,
               x_samples: Array | None = None, refine: int = 3,
               region: Region | None = None) -> WorstCase:
    """sup over D of |α_i| for every step, by grid and local search (x over ``x_samples``,
    default the system's; z_j over [−K_j, K_j]; ``refine`` local climbs per step). With a
    ``region`` (§4.3.5), over R ∩ D only: x in its band, z_j over the part of [−K_j, K_j]
    where |ξ_j| ≤ s_j (:mod:`cpbc.backstepping.regions`)."""
    sys = law.system
    xs = sys.x_samples() if x_samples is None else x_samples
    if region is not None:
        return _region_worst_case(law, region, region.x_samples(xs), points, budget, refine)
    sups: list[Sup] = []
    for i in range(sys.m):
        def alpha_i(xcols: list[Array], z: list[Array], i: int = i) -> Array:
            zero = 0.0 * xcols[0]
            zz = [*z, *[zero] * (sys.m - len(z))]
            xi = law.state_from_errors(xcols, zz)
            return np.asarray(law.terms(xcols, xi).alpha[i], dtype=float)

        sups.append(grid_sup(alpha_i, xs, law.bounds[:i], points=points, budget=budget,
                             refine=refine))
    return WorstCase(tuple(sups), tuple(k + s.value for k, s in zip(law.bounds, sups,
                                                                      strict=False)))


def _region_worst_case(law: MultipleConstraintLaw, region: Region, xs: Array, points: int,
                       budget: int, refine: int) -> WorstCase:
    sups: list[Sup] = []
    for i in range(law.system.m):
        def alpha_i(xcols: list[Array], v: list[Array], i: int = i) -> Array:
            xi, inside = region_states(law, region, xcols, v)
            alpha = np.asarray(law.terms(xcols, xi).alpha[i], dtype=float)
            return np.where(inside, alpha, 0.0)

        sups.append(grid_sup(alpha_i, xs, (1.0,) * i, points=points, budget=budget,
                             refine=refine))
    return WorstCase(tuple(sups), tuple(k + s.value for k, s in zip(law.bounds, sups,
                                                                      strict=False)))


def _k(j: int) -> str:
    return f"k{j}"


def well_posedness(law: MultipleConstraintLaw, wc: WorstCase) -> list[Condition]:
    """K_i > sup_D |α_i|: (4.37), (4.66), …, (4.82)."""
    m = law.system.m
    out = []
    for i in range(m):
        labels = ["(4.37)"] if i == 0 else []
        labels += ["(4.66)"] if i == 1 else [f"(4.66), step {i + 1}"] if 1 < i < m - 1 else []
        labels += ["(4.82)"] if i == m - 1 and i > 0 else []
        label = "/".join(labels)
        out.append(Condition(
            label, "well-posed", f"{_k(2 * i + 2)} > sup_D |α{i + 1}|",
            law.bounds[i], wc.alpha[i].value, strict=True,
            note="" if i == 0 else "sup searched over D, not the triangle bound (4.38)/(4.50)",
        ))
    return out


def state_bounds(wc: WorstCase, limits: Sequence[float]) -> list[Condition]:
    """X_i ≤ Ξ_i (4.89), X_i = K_i + sup_D |α_i| (4.88)."""
    return [
        Condition("(4.89)", "state bound", f"Ξ{i + 1} ≥ X{i + 1} = k{2 * i + 2} + sup_D |α{i + 1}|",
                  float(lim), x)
        for i, (lim, x) in enumerate(zip(limits, wc.state_bounds, strict=True))
    ]


def _shares(i: int, m: int) -> tuple[float, float]:
    """(θ_i, φ_{i+1}) for the pair (z_i, z_{i+1}), i counted from 0."""
    return (1.0 if i == 0 else 0.5), (1.0 if i + 2 == m else 0.5)


def pair_terms(law: MultipleConstraintLaw, i: int) -> tuple[float, float]:
    """(A, B) for the pair (z_{i+1}, z_{i+2}) (i from 0): outer holds iff a² ≥ A, inner iff
    1 − a² ≥ B; some a ∈ (0, 1) meets both iff A + B ≤ 1 (and A < 1)."""
    c, k, w = law.c, law.bounds, law.weights
    theta, phi = _shares(i, law.system.m)
    excess = theta * c[i] - 0.5
    big_a = k[i + 1] ** 2 / (k[i] ** 2 * excess) if excess > 0 else math.inf
    big_b = w[i] * k[i + 1] ** 2 / (2.0 * phi * c[i + 1] * w[i + 1] * k[i] ** 2)
    return big_a, big_b


def _best_a2(big_a: float, big_b: float) -> float:
    """a² in the middle of [A, 1 − B] if it is not empty; else A (the outer condition holds
    and the inner one, which larger later weights can always repair, fails); else 1 − B."""
    if big_a + big_b <= 1.0:
        return 0.5 * (big_a + 1.0 - big_b)
    if big_a < 1.0:
        return big_a
    return min(max(1.0 - big_b, 1e-6), 1.0 - 1e-6)


def domination(law: MultipleConstraintLaw, a: Sequence[float] | None = None) -> list[Condition]:
    """(4.55), (4.60), …, (4.77), (4.78) at the a_i given, or at the a_i of :func:`_best_a2`."""
    m = law.system.m
    if a is not None and len(a) != m - 1:
        raise DesignError("a", float(len(a)), f"needs m − 1 = {m - 1} constants a_i")
    c, k, w = law.c, law.bounds, law.weights
    out: list[Condition] = []
    for i in range(m - 1):
        big_a, big_b = pair_terms(law, i)
        if a is None:
            a2 = _best_a2(big_a, big_b)
        else:
            a2 = float(a[i]) ** 2
            if not 0.0 < a2 < 1.0:
                raise DesignError(f"a{i + 1}", float(a[i]), "must lie in (0, 1)")
        theta, phi = _shares(i, m)
        j = 2 * i + 2  # K_i is k_j
        last = i + 2 == m
        outer = "(4.55)" if i == 0 else "(4.77)" if last else f"(4.55), pair {i + 1}"
        note = ("" if i == 0 else "half of c's term went to the previous pair; "
                "(4.77) prints the full c, insufficient for m ≥ 3")
        out.append(Condition(
            outer, "domination",
            f"{'' if theta == 1 else '½'}c{i + 1} ≥ {_k(j + 2)}²/({_k(j)}·a{i + 1})² + ½",
            theta * c[i], k[i + 1] ** 2 / (k[i] ** 2 * a2) + 0.5, note=note,
        ))
        inner = "(4.78)" if last else "(4.60)" if i == 0 else f"(4.60), pair {i + 1}"
        out.append(Condition(
            inner, "domination",
            f"{'2·' if phi == 1 else ''}{_k(j + 1)}·c{i + 2}/{_k(j + 2)}² ≥ "
            f"{_k(j - 1)}/({_k(j)}²(1 − a{i + 1}²))",
            2.0 * phi * w[i + 1] * c[i + 1] / k[i + 1] ** 2, w[i] / (k[i] ** 2 * (1.0 - a2)),
            note=f"a{i + 1} = {math.sqrt(a2):.6g}; A + B = {big_a + big_b:.6g} (≤ 1 iff some a "
                 "meets both)",
        ))
    return out


def tail_matrix(c: Sequence[float]) -> Array:
    """The closed-loop matrix of (z2, …, zm): ż_i = −c_i z_i + z_{i+1}, ż_m = −c_m z_m."""
    n = len(c) - 1
    return np.diag(-np.asarray(c[1:], dtype=float)) + np.diag(np.ones(n - 1), 1)


def invariance(law: MultipleConstraintLaw) -> list[Condition]:
    """R_i ≤ K_i for i ≥ 2 and R_2 ≤ c1 K1 (see the module's docstring); m ≥ 2."""
    k = law.bounds
    if len(k) < 2:
        return []
    reach = box_reach(tail_matrix(law.c), k[1:])
    out = [Condition("[invariance]", "invariance", f"{_k(2 * i + 2)} ≥ reach of z{i + 1}",
                     k[i], float(reach[i - 1]) * (1 - 1e-9))
           for i in range(1, len(k) - 1)]
    out.append(Condition("[invariance]", "invariance", "c1·k2 ≥ reach of z2",
                         law.c[0] * k[0], float(reach[0]) * (1 - 1e-9)))
    return out


@dataclass(frozen=True)
class ParameterCheck:
    """Every condition of §4.3 for one law and set of limits.

    Attributes:
        conditions: in order: well-posedness, state bounds, domination, invariance.
        worst: sup_D |α_i| and the state bounds X_i.
        limits: Ξ_i.
    """

    conditions: tuple[Condition, ...]
    worst: WorstCase
    limits: tuple[float, ...]

    def failed(self, kind: str | None = None) -> list[Condition]:
        """The conditions that fail (of one kind, or all)."""
        return [c for c in self.conditions if not c.holds and kind in (None, c.kind)]

    def holds(self, *kinds: str) -> bool:
        """Whether every condition of these kinds holds."""
        return not any(self.failed(k) for k in kinds)

    @property
    def theorem_holds(self) -> bool:
        """Theorem 4.12's hypotheses (4.37) … (4.82) and (4.89): well-posed, bounded, dominated."""
        return self.holds("well-posed", "state bound", "domination")

    def table(self, rename: Callable[[str], str] | None = None) -> str:
        """A Markdown table of every condition; ``rename`` rewrites the statements' symbols
        (an application's own names for c_i, k_j)."""
        rows = ["| eq. | kind | condition | lhs | rhs | holds |", "|---|---|---|---|---|---|"]
        for c in self.conditions:
            text = rename(c.statement) if rename else c.statement
            rows.append(f"| {c.label} | {c.kind} | {text} | {c.lhs:.6g} | {c.rhs:.6g} | "
                        f"{'yes' if c.holds else '**no**'} |")
        return "\n".join(rows)


def check_parameters(
    law: MultipleConstraintLaw, limits: Sequence[float], a: Sequence[float] | None = None,
    points: int = 21, budget: int = 400_000, region: Region | None = None,
) -> ParameterCheck:
    """Evaluate every condition of §4.3 for ``law`` and the state limits Ξ (with the sups over
    ``region`` ∩ D only, if given: §4.3.5's local conditions)."""
    if len(limits) != law.system.m:
        raise DesignError("limits", float(len(limits)), f"needs one Ξ_i per step "
                          f"(m = {law.system.m})")
    wc = worst_case(law, points=points, budget=budget, region=region)
    conds = [*well_posedness(law, wc), *state_bounds(wc, limits), *domination(law, a),
             *invariance(law)]
    return ParameterCheck(tuple(conds), wc, tuple(float(v) for v in limits))
