"""A region of the state space of (4.1), for the local bounds of gain scheduling (§4.3.5).

§4.3.5 partitions "the constraint admissible state-space into small regions" and computes the
tuning constraints on each "since the system states need only be considered within each local
region". A :class:`Region` is a box in the plant's own coordinates, so that membership does not
depend on any region's gains:

    R = { (x, ξ) : x_low ≤ ‖x‖∞ ≤ x_high,  |ξ_i| ≤ s_i (i = 1 … m) }

Its sups of |α_i| are taken over R ∩ D, D = {|z_j| < K_j} (4.83), on the grid of
:func:`~cpbc.backstepping.worst_case.grid_sup` with the box coordinate v_j ∈ [−1, 1] mapped onto
the interval of z_j allowed at the point, both D's and R's ends included:

    z_j ∈ [max(−K_j, −s_j − α_j), min(K_j, s_j − α_j)],   ξ_j = z_j + α_j(x, ξ_1 … ξ_{j−1})

(empty intervals, and x outside the band, are points outside R ∩ D, where the function is 0).
With no bound on ξ (s_j = ∞) this is the global grid z_j = v_j K_j itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.backstepping.design_errors import DesignError
from cpbc.backstepping.multiple_constraints import MultipleConstraintLaw


@dataclass(frozen=True)
class Region:
    """x_low ≤ ‖x‖∞ ≤ x_high and |ξ_i| ≤ xi_bounds[i] (None: no bound on ξ)."""

    x_low: float = 0.0
    x_high: float = math.inf
    xi_bounds: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not (0.0 <= self.x_low < self.x_high):
            raise DesignError("x_low", self.x_low, f"needs 0 ≤ x_low < x_high = {self.x_high}")
        if self.xi_bounds is not None and any(not s > 0 for s in self.xi_bounds):
            raise DesignError("xi_bounds", math.nan, "every bound on |ξ_i| must be > 0")

    def xi_bound(self, i: int) -> float:
        return math.inf if self.xi_bounds is None else self.xi_bounds[i]

    def contains(self, x: Sequence[float], xi: Sequence[float]) -> bool:
        """Whether (x, ξ) lies in the closed box."""
        r = max(abs(v) for v in x)
        return (self.x_low <= r <= self.x_high
                and all(abs(v) <= self.xi_bound(i) for i, v in enumerate(xi)))

    def x_samples(self, samples: Array) -> Array:
        """The samples of x in the band, with its ends added when x is a scalar."""
        s = np.asarray(samples, dtype=float)
        r = np.max(np.abs(s), axis=1)
        inside = s[(r >= self.x_low) & (r <= self.x_high)]
        if s.shape[1] != 1:
            return inside
        ends = [v for v in (self.x_low, self.x_high) if math.isfinite(v)]
        extra = np.array([[sign * v] for v in ends for sign in (-1.0, 1.0)])
        return np.unique(np.vstack([inside, extra]), axis=0) if len(extra) else inside

    def label(self) -> str:
        hi = "∞" if math.isinf(self.x_high) else f"{self.x_high:g}"
        box = "" if self.xi_bounds is None else ", |ξ| ≤ (" + ", ".join(
            f"{v:.4g}" for v in self.xi_bounds) + ")"
        return f"‖x‖ ∈ [{self.x_low:g}, {hi}]{box}"


def region_states(law: MultipleConstraintLaw, region: Region, x: list[Array],
                  v: list[Array]) -> tuple[list[Array], Array]:
    """(ξ_1 … ξ_m, inside) for the box coordinates v_j ∈ [−1, 1], j < len(v) (the later ξ_j
    are 0): z_j spans the interval allowed by D and R at the point (see the module)."""
    zero = 0.0 * x[0] + 0.0 * (v[0] if v else 0.0)
    xi: list[Array] = [zero] * law.system.m
    r = np.max(np.abs(np.array(np.broadcast_arrays(*x, zero))[:-1]), axis=0)
    inside = (r >= region.x_low) & (r <= region.x_high)  # the local climb may leave the band
    for j, vj in enumerate(v):
        alpha = np.asarray(law.terms(x, xi).alpha[j], dtype=float) + zero
        k, s = law.bounds[j], region.xi_bound(j)
        lo, hi = np.maximum(-k, -s - alpha), np.minimum(k, s - alpha)
        inside &= lo <= hi
        xi[j] = alpha + 0.5 * (lo + hi) + 0.5 * vj * (hi - lo)
    return xi, inside
