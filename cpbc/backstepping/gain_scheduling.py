"""Gain scheduling (§4.3.5): local tuning problems on a partition, and the switched law.

**No stability guarantee.** The thesis describes the scheme in words only and leaves the
stability "across the boundaries of the partitioned regions" open; nothing here closes it. A
region whose constants meet the theorem's rules has U̇ ≤ 0 on its own D while the state stays
in the region; at a switch the certificate changes (the composite U jumps, and the state may lie
outside the new region's D) and no argument bounds what follows. The simulation reports it.

Partition (§4.3.5: "partition the constraint admissible state-space into small regions"): bands
of ‖x‖ (edges 0 = b_0 < b_1 < … ≤ ∞) × nested boxes |ξ_i| ≤ q_k Ξ_i (shares q_1 < … ≤ 1). A state
belongs to the first region that holds it, boxes inner first, so the cells are band × (box_k
minus box_{k−1}); each cell's problem takes its sups over its whole box (a superset of the cell:
conservative). Per region the optimisation of :mod:`.tuning` is solved twice, under the theorem's
rules and under the manual ones, with the sups of (4.88) over the region ∩ D
(:mod:`.regions`): "a subset of (4.89) depending on the local region". The switched law uses a
region's theorem constants if found, else its manual ones, else the fallback (single-gain)
constants.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from itertools import pairwise

import numpy as np

from cpbc.arrays import Array
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw
from cpbc.backstepping.regions import Region
from cpbc.backstepping.tuning import Resolution, TuningProblem, TuningResult, optimise
from cpbc.backstepping.worst_case import grid_sup

NO_GUARANTEE = ("gain scheduling (§4.3.5): NO STABILITY GUARANTEE - the thesis leaves stability "
                "across switches open and nothing here closes it")


@dataclass(frozen=True)
class Partition:
    """Bands of ‖x‖ × nested boxes of the constrained states (see the module).

    Attributes:
        limits: Ξ_1 … Ξ_m.
        bands: the band edges, from 0, strictly increasing (the last may be ∞).
        shares: q_k ∈ (0, 1], strictly increasing: box k is |ξ_i| ≤ q_k Ξ_i.
    """

    limits: tuple[float, ...]
    bands: tuple[float, ...] = (0.0, 1.0, math.inf)
    shares: tuple[float, ...] = (0.03, 0.3, 1.0)

    def __post_init__(self) -> None:
        b, q = self.bands, self.shares
        if len(b) < 2 or b[0] != 0.0 or any(not hi > lo for lo, hi in pairwise(b)):
            raise DesignError("bands", math.nan, f"needs edges 0 < b1 < … (got {list(b)})")
        if not q or any(not 0.0 < v <= 1.0 for v in q) or any(
                not hi > lo for lo, hi in pairwise(q)):
            raise DesignError("shares", math.nan, f"needs 0 < q1 < … ≤ 1 (got {list(q)})")
        if any(not v > 0 for v in self.limits):
            raise DesignError("limits", math.nan, "every Ξ_i must be > 0")

    def regions(self) -> tuple[Region, ...]:
        """Boxes inner first, bands in order within each box."""
        return tuple(Region(lo, hi, tuple(q * v for v in self.limits))
                     for q in self.shares for lo, hi in pairwise(self.bands))

    def locate(self, x: Sequence[float], xi: Sequence[float]) -> int | None:
        """The index of the region holding (x, ξ) (bands half-open [b_j, b_{j+1}), the last
        closed), or None outside every band or every box (some |ξ_i| > q_last Ξ_i)."""
        r = max(abs(float(v)) for v in x)
        if r > self.bands[-1]:
            return None
        band = int(np.searchsorted(self.bands, r, side="right")) - 1
        band = min(band, len(self.bands) - 2)  # r on the last edge: the last band
        ratio = max(abs(float(v)) / lim for v, lim in zip(xi, self.limits, strict=True))
        for k, q in enumerate(self.shares):
            if ratio <= q:
                return k * (len(self.bands) - 1) + band
        return None


def coverage(law: MultipleConstraintLaw, region: Region, points: int = 9,
             budget: int = 200_000) -> tuple[float, ...]:
    """max |z_i|/K_i over the region's box (grid over the band's x samples × the box): ≥ 1
    means part of the region lies outside the law's D, where its local guarantees say nothing
    and its sups were not taken (they are over R ∩ D)."""
    if region.xi_bounds is None:
        return (math.inf,) * law.system.m
    xs = region.x_samples(law.system.x_samples())
    out = []
    for i, k in enumerate(law.bounds):
        def z_i(x: list[Array], xi: list[Array], i: int = i, k: float = k) -> Array:
            return np.asarray(law.terms(x, xi).z[i], dtype=float) / k

        out.append(grid_sup(z_i, xs, region.xi_bounds, points=points, budget=budget,
                            refine=0).value)
    return tuple(out)


@dataclass(frozen=True)
class RegionTuning:
    """One region's local problems and what the switched law uses there.

    Attributes:
        region: the box.
        theorem: the optimisation under the theorem's rules (§4.3.3 locally).
        manual: under the manual rules (§4.3.6 locally).
        used: "theorem", "manual" or "fallback": whose constants the switched law uses.
        values: those constants.
        coverage: :func:`coverage` of the law with those constants (None if not computed).
    """

    region: Region
    theorem: TuningResult
    manual: TuningResult
    used: str
    values: dict[str, float]
    coverage: tuple[float, ...] | None = None


@dataclass(frozen=True)
class Schedule:
    """The partition, its regions' tunings, and the fallback (single-gain) constants."""

    partition: Partition
    regions: tuple[RegionTuning, ...]
    fallback: dict[str, float]

    @property
    def any_theorem_feasible(self) -> bool:
        return any(r.theorem.feasible for r in self.regions)


#: make(region, rules) → the local tuning problem (the application's constants and limits)
ProblemMaker = Callable[[Region, str], TuningProblem]


def schedule(make: ProblemMaker, partition: Partition, fallback: dict[str, float],
             starts: int = 2, maxiter: int = 40, seed: int = 0,
             resolution: Resolution | None = None, with_coverage: bool = True) -> Schedule:
    """Solve every region's problem under both rules (see the module). A region found
    infeasible under the theorem's rules is searched again from the constants of the last
    region found feasible (the starts of :func:`.tuning.optimise` are local)."""
    out: list[RegionTuning] = []
    kw = {"starts": starts, "maxiter": maxiter, "seed": seed, "resolution": resolution}
    for region in partition.regions():
        problem = make(region, "theorem")
        th = optimise(problem, "theorem", **kw)  # type: ignore[arg-type]
        # continuation: an inner region's theorem constants as a second start
        found = next((r.theorem for r in reversed(out) if r.theorem.feasible), None)
        if not th.feasible and found is not None:
            warm = replace(problem, start=tuple(found.values[n] for n in problem.names))
            th = optimise(warm, "theorem", **kw)  # type: ignore[arg-type]
        ma = optimise(make(region, "manual"), "manual", **kw)  # type: ignore[arg-type]
        used, values = (("theorem", th.values) if th.feasible else
                        ("manual", ma.values) if ma.feasible else ("fallback", fallback))
        cover = coverage(problem.build(dict(values)), region) if with_coverage else None
        out.append(RegionTuning(region, th, ma, used, dict(values), cover))
    return Schedule(partition, tuple(out), dict(fallback))


class SwitchedLaw:
    """u = u_R(x, ξ) with R the region holding the state: gain scheduling of §4.3.5.

    NO STABILITY GUARANTEE: each region's law is certified (if at all) only on its own D and
    while the state stays in its region; the switches are not analysed (the thesis leaves them
    open). Outside every box (a limit crossed) the last region's law is kept.

    Args:
        partition: the regions.
        laws: one law per region, in the partition's order.
    """

    def __init__(self, partition: Partition, laws: Sequence[MultipleConstraintLaw]) -> None:
        if len(laws) != len(partition.regions()):
            raise DesignError("laws", float(len(laws)), "needs one law per region")
        self.partition = partition
        self.laws = tuple(laws)

    def select(self, x: Sequence[float], xi: Sequence[float], active: int) -> int:
        """The region's index at (x, ξ); ``active`` if the state lies in none."""
        found = self.partition.locate(x, xi)
        return active if found is None else found

    def control(self, x: Sequence[float], xi: Sequence[float], active: int = 0) -> float:
        """u of the region holding (x, ξ)."""
        law = self.laws[self.select(x, xi, active)]
        return float(law.control(x, xi))


@dataclass(frozen=True)
class SwitchedRun:
    """One start under the switched law (fixed-step RK4, gains held over each step).

    Attributes:
        start: (x(0), ξ(0)).
        peaks: max |ξ_i| over the run.
        crossed: some |ξ_i| reached Ξ_i.
        left_domain: some |z_i| ≥ K_i of the active region's law at a step's start.
        settle_time: the time after which every |state| < tolerance (None: not settled).
        switches: how many times the region changed.
        u_jumps: U_new − U_old at each switch (∞: outside the new region's D).
        regions: the regions visited, in order.
    """

    start: tuple[float, ...]
    peaks: tuple[float, ...]
    crossed: bool
    left_domain: bool
    settle_time: float | None
    switches: int
    u_jumps: tuple[float, ...]
    regions: tuple[int, ...]

    @property
    def u_rises_at_switches(self) -> int:
        return sum(1 for j in self.u_jumps if j > 0)


def _rhs(law: MultipleConstraintLaw, y: Array, n: int) -> tuple[Array, Array]:
    """(ẏ, |z|) of (4.1) in closed loop at y = (x, ξ)."""
    sys, x, xi = law.system, list(y[:n]), list(y[n:])
    terms = law.terms(x, xi)
    f = sys.drifts(x, xi)
    nxt = [*xi[1:], terms.u]
    dy = [*(float(v) for v in sys.flow(x, xi[0])),
          *(float(nxt[i] + f[i]) for i in range(sys.m))]
    return np.array(dy), np.abs(np.array([float(z) for z in terms.z]))


def simulate_switched(switched: SwitchedLaw, start: Sequence[float], duration: float,
                      step: float = 0.005, tolerance: float = 0.01) -> SwitchedRun:
    """Integrate one start; the region is chosen at each step's start and held over the step
    (the right-hand side is discontinuous at region boundaries, so no stage straddles one)."""
    n = switched.laws[0].system.n
    limits = np.array(switched.partition.limits)
    y = np.array(start, dtype=float)
    active = switched.select(tuple(y[:n]), tuple(y[n:]), 0)
    visited, jumps = [active], []
    peaks, crossed, left, last_out = np.abs(y[n:]), False, False, 0.0
    for k in range(round(duration / step)):
        now = switched.select(tuple(y[:n]), tuple(y[n:]), active)
        if now != active:
            old, new = switched.laws[active], switched.laws[now]
            jumps.append(new.lyapunov(tuple(y[:n]), tuple(y[n:]))
                         - old.lyapunov(tuple(y[:n]), tuple(y[n:])))
            active = now
            visited.append(now)
        law = switched.laws[active]
        k1, z = _rhs(law, y, n)
        left |= bool(np.any(z >= np.array(law.bounds)))
        k2, _ = _rhs(law, y + 0.5 * step * k1, n)
        k3, _ = _rhs(law, y + 0.5 * step * k2, n)
        k4, _ = _rhs(law, y + step * k3, n)
        y = y + step / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.all(np.isfinite(y)):
            break
        peaks = np.fmax(peaks, np.abs(y[n:]))
        crossed |= bool(np.any(np.abs(y[n:]) >= limits))
        if np.max(np.abs(y)) >= tolerance:
            last_out = (k + 1) * step
    settled = bool(np.all(np.isfinite(y)) and np.max(np.abs(y)) < tolerance)
    return SwitchedRun(tuple(float(v) for v in start), tuple(float(v) for v in peaks), crossed,
                       left, last_out if settled else None, len(jumps),
                       tuple(float(j) for j in jumps), tuple(visited))


def switched_law(sched: Schedule, build: Callable[[dict[str, float]], MultipleConstraintLaw]
                 ) -> SwitchedLaw:
    """The switched law of a schedule: each region's used constants through ``build``."""
    return SwitchedLaw(sched.partition, [build(r.values) for r in sched.regions])


def single_gain(partition_limits: Sequence[float], law: MultipleConstraintLaw) -> SwitchedLaw:
    """One region covering everything: the unscheduled law, through the same simulator."""
    whole = Partition(tuple(float(v) for v in partition_limits), (0.0, math.inf), (1.0,))
    return SwitchedLaw(whole, [law])
