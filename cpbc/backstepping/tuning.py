"""Tuning the constants of Theorem 4.12 by constrained optimisation (§4.3.3, §4.3.4).

The decision vector Z holds the design constants (the thesis's c_i, k_j) and, under the
theorem's rules, the free constants a_i ∈ (0, 1) of the domination conditions (PART1 Ch. 4
§2.5 (a)). The feasible set is

    theorem  (§4.3.3): well-posedness (4.37), (4.66), …, (4.82); domination (4.55), (4.60), …,
                       (4.77), (4.78); state bounds X_i(Z) ≤ Ξ_i (4.89)
    manual   (§4.3.6): the same without domination (stability is then not guaranteed and the
                       admissible starts are found by simulation, :mod:`.admissible_starts`)

with X_i(Z) = K_i + sup_D |α_i| (4.88) searched over D for every Z (:func:`worst_case`). Among
feasible Z the routine minimises the utility (4.91)

    S(Z) = Σ w_i Φ_i(Z),   Φ_i = Ξ_i − X_i (4.90),   w_i = 1/Ξ_i unless given,

i.e. it pushes the worst-case bounds up to the limits (the thesis's goal: use the whole
allowed range), or, with ``objective="domain"``, maximises the size of D, Σ w_i' log K_i.

Two phases, each from several starts (the given constants, "very small values" as §4.3.3
advises, and log-uniform draws): first the least violation Σ min(0, g_j)² of the normalised
conditions g_j ≥ 0 (L-BFGS-B), then, from a feasible point, SLSQP on the objective. The verdict
is the checker's (:func:`check_parameters`) at full resolution, never the optimiser's own.

§4.3.4 gives no algorithm for the infeasible case beyond "adjust the problem formulation to
reduce the influence of the state bounds": :func:`relax` searches the smallest factor s on
every Ξ_i that makes the problem feasible (bisection), and says so when none up to a cap does,
which happens when the conflict does not involve the limits at all (see :func:`conflicts`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize

from cpbc.arrays import Array
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.parameter_constraints import (
    Condition,
    ParameterCheck,
    WorstCase,
    check_parameters,
    domination,
    state_bounds,
    well_posedness,
    worst_case,
)
from cpbc.backstepping.regions import Region

#: The condition kinds each set of rules enforces.
RULES: dict[str, tuple[str, ...]] = {
    "theorem": ("well-posed", "state bound", "domination"),
    "manual": ("well-posed", "state bound"),
}
OBJECTIVES = ("thesis", "domain")
#: Margin on every normalised condition while searching: the coarse grid's sups may fall
#: short of the full-resolution verdict's, and K_i > sup |α_i| is strict.
SEARCH_MARGIN = 1e-3
#: A least violation below this is handed to SLSQP as a start (the verdict stays the checker's).
NEAR_FEASIBLE = 1e-4
#: The domination constants a_i stay in [A_LOW, A_HIGH] ⊂ (0, 1).
A_LOW, A_HIGH = 0.01, 0.99


@dataclass(frozen=True)
class TuningProblem:
    """What to tune.

    Attributes:
        names: every design constant, in the application's own names (e.g. c1 … k7).
        start: their given values (the constants not in ``free`` keep them).
        free: the constants the optimiser may change.
        build: the law for a full set of constants (raises DesignError if they are invalid).
        limits: Ξ_1 … Ξ_m on the constrained states.
        weights: w_i of (4.91); None: 1/Ξ_i (so that each Φ_i counts as a share of its limit).
        box: (lower, upper) of every free constant.
        rename: rewrites the checker's statements into the application's names.
        region: take the sups of X_i (4.88) over this region ∩ D only (§4.3.5's local
            problem, :mod:`.gain_scheduling`); None: over D.
    """

    names: tuple[str, ...]
    start: tuple[float, ...]
    free: tuple[str, ...]
    build: Callable[[dict[str, float]], MultipleConstraintLaw]
    limits: tuple[float, ...]
    weights: tuple[float, ...] | None = None
    box: tuple[float, float] = (1e-3, 1e4)
    rename: Callable[[str], str] | None = None
    region: Region | None = None

    def __post_init__(self) -> None:
        if len(self.start) != len(self.names):
            raise DesignError("start", float(len(self.start)), "needs one value per name")
        unknown = [n for n in self.free if n not in self.names]
        if unknown:
            raise DesignError("free", math.nan, f"unknown constants {unknown}; the constants "
                              f"are {', '.join(self.names)}")
        if self.weights is not None and len(self.weights) != len(self.limits):
            raise DesignError("weights", float(len(self.weights)), "needs one w_i per limit")

    def values(self, free_values: Sequence[float] | None = None) -> dict[str, float]:
        """All constants, with the free ones replaced by ``free_values``."""
        out = dict(zip(self.names, self.start, strict=True))
        if free_values is not None:
            out.update(zip(self.free, (float(v) for v in free_values), strict=True))
        return out

    def scaled(self, factor: float) -> TuningProblem:
        """The same problem with every limit Ξ_i multiplied by ``factor`` (§4.3.4)."""
        return replace(self, limits=tuple(factor * v for v in self.limits))

    @property
    def w(self) -> tuple[float, ...]:
        return self.weights or tuple(1.0 / v for v in self.limits)


def utility(problem: TuningProblem, bounds: Sequence[float]) -> float:
    """S = Σ w_i (Ξ_i − X_i) (4.90)–(4.91) for the worst-case state bounds X."""
    return float(sum(w * (lim - x) for w, lim, x in
                     zip(problem.w, problem.limits, bounds, strict=True)))


def domain_size(problem: TuningProblem, law: MultipleConstraintLaw) -> float:
    """Σ w_i log K_i: the (weighted log) size of D = {|z_i| < K_i} (4.83)."""
    return float(sum(w * math.log(k) for w, k in zip(problem.w, law.bounds, strict=True)))


def conditions(law: MultipleConstraintLaw, worst: WorstCase, limits: Sequence[float],
               rules: str, a: Sequence[float] | None) -> list[Condition]:
    """The conditions ``rules`` enforce, from the worst cases already searched."""
    out = [*well_posedness(law, worst), *state_bounds(worst, limits)]
    return out + (domination(law, a) if "domination" in RULES[rules] else [])


def residuals(conds: Sequence[Condition]) -> Array:
    """g_j ≥ 0 for each condition, normalised to [−2, 1]: (lhs − rhs)/max(|lhs|, |rhs|),
    less :data:`SEARCH_MARGIN`."""
    return np.array([(c.lhs - c.rhs) / max(abs(c.lhs), abs(c.rhs), 1e-12) - SEARCH_MARGIN
                     for c in conds])


@dataclass(frozen=True)
class Conflict:
    """For the pair (z_i, z_{i+1}) of step gains: ρ = sup_D |α_{i+1}| / (c_i K_i).

    With r = K_{i+1}/K_i: if ρ ≥ 1, well-posedness K_{i+1} > sup_D |α_{i+1}| gives r > c_i,
    and the outer domination θ c_i ≥ K_{i+1}²/(K_i a_i)² + ½ (θ ≤ 1, a_i < 1) gives
    c_i > r² + ½; together r > r² + ½, impossible since r² − r + ½ = (r − ½)² + ¼ > 0.
    So a system with ρ ≥ 1 for every Z has no constants meeting Theorem 4.12's rules.
    """

    pair: int
    ratio: float

    @property
    def excludes(self) -> bool:
        return self.ratio >= 1.0


def conflicts(law: MultipleConstraintLaw, worst: WorstCase) -> tuple[Conflict, ...]:
    """ρ_i = sup_D |α_{i+1}|/(c_i K_i) for every pair (see :class:`Conflict`)."""
    return tuple(Conflict(i + 1, worst.alpha[i + 1].value / (law.c[i] * law.bounds[i]))
                 for i in range(law.system.m - 1))


@dataclass(frozen=True)
class Resolution:
    """Grid for the sups while searching (coarse, no climb) and for the verdict (fine)."""

    search: tuple[int, int, int] = (7, 4000, 0)  # points, budget, refine
    verdict: tuple[int, int] = (21, 400_000)


@dataclass(frozen=True)
class TuningResult:
    """What the optimisation found.

    Attributes:
        rules: "theorem" (§4.3.3) or "manual" (§4.3.6).
        objective: "thesis" (minimise S (4.91)) or "domain" (maximise Σ w_i log K_i).
        feasible: every condition of ``rules`` holds at ``values`` (checked at full resolution).
        values: every design constant at the end (the least-violating point if infeasible).
        a: the domination constants a_i (theorem's rules), or None.
        check: every condition of §4.3 at ``values`` (all kinds, for the report).
        utility: S (4.91) at ``values``; ``start_utility`` at the given constants.
        domain: Σ w_i log K_i at ``values``.
        violation: the least Σ min(0, g_j)² found (0 when feasible).
        conflicts: ρ_i per pair at ``values`` (see :class:`Conflict`).
        evaluations: how many parameter sets were evaluated.
    """

    rules: str
    objective: str
    feasible: bool
    values: dict[str, float]
    a: tuple[float, ...] | None
    check: ParameterCheck
    utility: float
    start_utility: float
    domain: float
    violation: float
    conflicts: tuple[Conflict, ...]
    evaluations: int

    @property
    def failed(self) -> list[Condition]:
        """The conditions of the rules that fail at ``values``."""
        return [c for c in self.check.failed() if c.kind in RULES[self.rules]]

    def message(self) -> str:
        """One paragraph: found or not, and why not."""
        if self.feasible:
            return (f"feasible ({self.rules} rules): S = {self.utility:.4g} "
                    f"(given constants: {self.start_utility:.4g})")
        labels = ", ".join(sorted({c.label for c in self.failed}))
        text = (f"INFEASIBLE ({self.rules} rules): no constants found that meet every condition; "
                f"least violation {self.violation:.3g}, still failing there: {labels}.")
        blocking = [c for c in self.conflicts if c.excludes]
        if blocking and self.rules == "theorem":
            text += " " + "; ".join(
                f"pair {c.pair}: sup_D|α{c.pair + 1}|/(c{c.pair}·k{2 * c.pair}) = "
                f"{c.ratio:.4g} ≥ 1, so well-posedness and the outer domination condition "
                "exclude each other"
                for c in blocking)
        return text


class _Search:
    """The map Z ↦ (law, conditions) with a count of evaluations."""

    def __init__(self, problem: TuningProblem, rules: str, res: Resolution) -> None:
        self.problem, self.rules, self.res = problem, rules, res
        self.n_free = len(problem.free)
        self.m = len(problem.limits)
        self.n_a = self.m - 1 if "domination" in RULES[rules] else 0
        self.evaluations = 0

    def split(self, p: Array) -> tuple[dict[str, float], tuple[float, ...] | None]:
        values = self.problem.values([float(v) for v in np.exp(p[: self.n_free])])
        return values, (tuple(float(v) for v in p[self.n_free:]) if self.n_a else None)

    def evaluate(self, p: Array) -> tuple[MultipleConstraintLaw, list[Condition], WorstCase]:
        values, a = self.split(p)
        law = self.problem.build(values)
        points, budget, refine = self.res.search
        self.evaluations += 1
        worst = worst_case(law, points=points, budget=budget, refine=refine,
                           region=self.problem.region)
        return law, conditions(law, worst, self.problem.limits, self.rules, a), worst

    def violation(self, p: Array) -> float:
        try:
            g = residuals(self.evaluate(p)[1])
        except DesignError:
            return 1e6
        return float(np.sum(np.minimum(g, 0.0) ** 2))

    def constraints(self, p: Array) -> Array:
        try:
            return residuals(self.evaluate(p)[1])
        except DesignError:
            return -np.ones(self.count)

    @property
    def count(self) -> int:
        return 2 * self.m + (2 * self.n_a)

    def objective(self, p: Array, objective: str) -> float:
        try:
            law, _, worst = self.evaluate(p)
        except DesignError:
            return 1e6
        if objective == "domain":
            return -domain_size(self.problem, law)
        return utility(self.problem, worst.state_bounds)

    def bounds(self) -> list[tuple[float, float]]:
        lo, hi = self.problem.box
        return [(math.log(lo), math.log(hi))] * self.n_free + [(A_LOW, A_HIGH)] * self.n_a


def _starts(search: _Search, count: int, seed: int) -> list[Array]:
    """The given constants, 'very small values' (§4.3.3), then log-uniform draws."""
    given = np.log([search.problem.values()[n] for n in search.problem.free])
    a0 = [0.7] * search.n_a
    lo, hi = search.problem.box
    small = np.full(search.n_free, math.log(max(lo, 0.05)))
    rng = np.random.default_rng(seed)
    draws = [np.append(rng.uniform(math.log(max(lo, 0.01)), math.log(min(hi, 100.0)),
                                   search.n_free), rng.uniform(0.3, 0.95, search.n_a))
             for _ in range(max(count - 2, 0))]
    return [np.append(given, a0), np.append(small, a0), *draws][:max(count, 1)]


def _least_violation(search: _Search, starts: list[Array], maxiter: int) -> tuple[Array, float]:
    best_p, best_v = starts[0], math.inf
    for p0 in starts:
        v0 = search.violation(p0)
        if v0 == 0.0 or len(p0) == 0:  # feasible, or nothing to move
            return p0, v0
        res = minimize(search.violation, p0, method="L-BFGS-B", bounds=search.bounds(),
                       options={"maxiter": maxiter, "eps": 1e-5})
        v = float(res.fun)
        if v < best_v:
            best_p, best_v = np.asarray(res.x, dtype=float), v
        if v == 0.0:
            break
    return best_p, best_v


def optimise(
    problem: TuningProblem, rules: str = "theorem", objective: str = "thesis", starts: int = 4,
    seed: int = 0, maxiter: int = 60, resolution: Resolution | None = None,
) -> TuningResult:
    """Search constants meeting ``rules`` and optimise ``objective`` among them (see the
    module's docstring); the verdict is the full-resolution check at the end."""
    if rules not in RULES:
        raise DesignError("rules", math.nan, f"unknown rules {rules!r}; use {sorted(RULES)}")
    if objective not in OBJECTIVES:
        raise DesignError("objective", math.nan, f"unknown objective {objective!r}; use "
                          f"{list(OBJECTIVES)}")
    res = resolution or Resolution()
    search = _Search(problem, rules, res)
    p, violation = _least_violation(search, _starts(search, starts, seed), maxiter)
    # near-feasible too: the squared penalty's gradient vanishes at the boundary, so
    # L-BFGS-B may stop just short of it; SLSQP treats the conditions as constraints
    if violation <= NEAR_FEASIBLE and len(p):
        opt = minimize(lambda q: search.objective(q, objective), p, method="SLSQP",
                       bounds=search.bounds(),
                       constraints=[{"type": "ineq", "fun": search.constraints}],
                       options={"maxiter": maxiter, "ftol": 1e-9, "eps": 1e-5})
        q = np.asarray(opt.x, dtype=float)
        # SLSQP ends on the active constraints to its own tolerance, or outside: keep what holds
        if np.all(search.constraints(q) >= -SEARCH_MARGIN / 10):
            p = q
    values, a = search.split(p)
    law = problem.build(values)
    points, budget = res.verdict
    check = check_parameters(law, problem.limits, a, points=points, budget=budget,
                             region=problem.region)
    feasible = check.holds(*RULES[rules])
    start_law = problem.build(problem.values())
    start_worst = worst_case(start_law, points=points, budget=budget, region=problem.region)
    return TuningResult(
        rules, objective, feasible, values, a, check,
        utility(problem, check.worst.state_bounds),
        utility(problem, start_worst.state_bounds), domain_size(problem, law),
        0.0 if feasible else max(violation, 1e-300), conflicts(law, check.worst),
        search.evaluations,
    )


@dataclass(frozen=True)
class Relaxation:
    """§4.3.4: the least factor s on every Ξ_i found to make the problem feasible.

    Attributes:
        factor: s (None: none up to ``cap``).
        cap: the largest factor tried.
        tried: (s, feasible) in the order tried.
        result: the optimisation at ``factor`` (None if none).
    """

    factor: float | None
    cap: float
    tried: tuple[tuple[float, bool], ...]
    result: TuningResult | None

    def message(self) -> str:
        if self.factor is None:
            return (f"no relaxation of the state limits up to ×{self.cap:g} makes the problem "
                    "feasible: the conflict does not involve Ξ (§4.3.4 cannot help)")
        return f"feasible with every Ξ_i multiplied by {self.factor:.4g}"


def relax(problem: TuningProblem, rules: str = "theorem", cap: float = 100.0, steps: int = 6,
          **kwargs: object) -> Relaxation:
    """Bisection on the factor s ∈ [1, cap] of the limits (feasibility is taken as monotone
    in s: larger limits only loosen (4.89))."""
    tried: list[tuple[float, bool]] = []

    def attempt(s: float) -> TuningResult:
        r = optimise(problem.scaled(s), rules, **kwargs)  # type: ignore[arg-type]
        tried.append((s, r.feasible))
        return r

    top = attempt(cap)
    if not top.feasible:
        return Relaxation(None, cap, tuple(tried), None)
    lo, hi, best = 1.0, cap, top
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        r = attempt(mid)
        if r.feasible:
            hi, best = mid, r
        else:
            lo = mid
    return Relaxation(hi, cap, tuple(tried), best)
