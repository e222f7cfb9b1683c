"""Manual tuning, step 3 (§4.3.6): the admissible starts found by simulation.

Without the domination conditions Theorem 4.12 guarantees nothing, so "the set of allowable
initial conditions is determined by simulating the closed-loop system at various initial
conditions and examining the evolution of the candidate cLf and its time derivative". Here:
every start is integrated at once (classical RK4 at a fixed step, vectorised over the starts;
the thesis used a fixed-step Dormand–Prince with h = 0.005 s), and judged

    outside D      |z_i(0)| ≥ K_i: the law is not defined there (4.83)
    limit crossed  some |ξ_i(t)| ≥ Ξ_i
    left D         some |z_i(t)| ≥ K_i (the limits held)
    diverged       the state stopped being finite
    converged      every |x|, |ξ_i| < tolerance at the end
    not settled    none of the above

with the largest rise of U (4.70) over its start, sampled every ``sample`` seconds, which is
> 0 where the certificate fails (U is not a Lyapunov function without domination).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw

VERDICTS = ("converged", "not settled", "left D", "limit crossed", "diverged", "outside D")


@dataclass(frozen=True)
class StartOutcome:
    """One start (x(0), ξ(0)) and what became of it."""

    start: tuple[float, ...]
    verdict: str
    peaks: tuple[float, ...]  # max |ξ_i| over the run
    u_rise: float  # max U(t) − U(0) on the samples while in D (NaN outside D at the start)


@dataclass(frozen=True)
class AdmissibleStarts:
    outcomes: tuple[StartOutcome, ...]
    limits: tuple[float, ...]
    duration: float

    def counts(self) -> dict[str, int]:
        got = Counter(o.verdict for o in self.outcomes)
        return {v: got.get(v, 0) for v in VERDICTS}

    @property
    def admissible(self) -> tuple[StartOutcome, ...]:
        """The starts that converged with every |ξ_i| < Ξ_i and z in D."""
        return tuple(o for o in self.outcomes if o.verdict == "converged")


def _rhs(law: MultipleConstraintLaw, x: list[Array], xi: list[Array]
         ) -> tuple[list[Array], list[Array], list[Array]]:
    """(ẋ, ξ̇, z) of (4.1) under the law, vectorised over starts."""
    sys = law.system
    terms = law.terms(x, xi)
    f = sys.drifts(x, xi)
    nxt = [*xi[1:], terms.u]
    dx = [np.asarray(v, dtype=float) + 0.0 * x[0] for v in sys.flow(x, xi[0])]
    dxi = [np.asarray(nxt[i] + f[i], dtype=float) + 0.0 * x[0] for i in range(sys.m)]
    return dx, dxi, [np.asarray(z, dtype=float) for z in terms.z]


def simulate_starts(
    law: MultipleConstraintLaw, limits: tuple[float, ...], starts: Array, duration: float,
    step: float = 0.005, tolerance: float = 0.01, sample: float = 0.1,
) -> AdmissibleStarts:
    """Judge every row (x(0), ξ(0)) of ``starts`` (shape (N, n + m)) over ``duration``."""
    sys = law.system
    n, m = sys.n, sys.m
    s = np.array(starts, dtype=float)
    bounds = np.array(law.bounds)[:, None]
    lim = np.array(limits, dtype=float)[:, None]
    _, _, z0 = _rhs(law, [s[:, j] for j in range(n)], [s[:, n + i] for i in range(m)])
    outside = np.any(np.abs(np.array(z0)) >= bounds, axis=0)
    left = np.zeros(len(s), bool)
    crossed = np.any(np.abs(s[:, n:].T) >= lim, axis=0)
    peaks = np.abs(s[:, n:]).copy()
    u0 = np.array([law.lyapunov(tuple(r[:n]), tuple(r[n:])) if not o else math.nan
                   for r, o in zip(s, outside, strict=True)])
    rise = np.zeros(len(s))
    every = max(1, round(sample / step))
    steps = round(duration / step)

    def f(y: Array) -> tuple[Array, Array]:
        dx, dxi, z = _rhs(law, [y[:, j] for j in range(n)], [y[:, n + i] for i in range(m)])
        return np.column_stack([*dx, *dxi]), np.abs(np.array(z))

    y = s.copy()
    with np.errstate(all="ignore"):  # starts outside D or diverging overflow: judged below
        for k in range(1, steps + 1):
            k1, zk = f(y)
            left |= np.any(zk >= bounds, axis=0)
            k2, _ = f(y + 0.5 * step * k1)
            k3, _ = f(y + 0.5 * step * k2)
            k4, _ = f(y + step * k3)
            y = y + step / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            y[~np.all(np.isfinite(y), axis=1)] = np.nan  # a row that broke stays broken
            peaks = np.fmax(peaks, np.abs(y[:, n:]))
            crossed |= np.any(np.abs(y[:, n:]).T >= lim, axis=0)
            if k % every == 0:
                watch = ~(outside | left) & np.all(np.isfinite(y), axis=1)
                for j in np.nonzero(watch)[0]:
                    u = law.lyapunov(tuple(y[j, :n]), tuple(y[j, n:]))
                    rise[j] = max(rise[j], u - u0[j])
    final = np.max(np.abs(y), axis=1)
    outcomes = [
        StartOutcome(tuple(float(v) for v in s[j]),
                     _verdict(outside[j], crossed[j], left[j], final[j], tolerance),
                     tuple(float(v) for v in peaks[j]),
                     math.nan if outside[j] else float(rise[j]))
        for j in range(len(s))]
    return AdmissibleStarts(tuple(outcomes), tuple(float(v) for v in limits), duration)


def _verdict(outside: bool, crossed: bool, left: bool, final: float, tolerance: float) -> str:
    if outside:
        return "outside D"
    if crossed:
        return "limit crossed"
    if left:
        return "left D"
    if not np.isfinite(final):
        return "diverged"
    return "converged" if final < tolerance else "not settled"


def sample_starts(limits: tuple[float, ...], n: int, count: int, spread: float, seed: int = 0,
                  share: float = 0.95) -> Array:
    """``count`` starts: x uniform in [−spread, spread]ⁿ, ξ_i uniform in ±share·Ξ_i."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-spread, spread, (count, n))
    xi = rng.uniform(-1.0, 1.0, (count, len(limits))) * share * np.array(limits)
    return np.hstack([x, xi])
