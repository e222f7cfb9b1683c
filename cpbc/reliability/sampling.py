"""Seeded samplers of admissible initial states, with a share placed close to ∂S."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.constraints.rate_limit import RateLimit
from cpbc.errors import CpbcError


def _last_above(rel: Callable[[float], float], fraction: float, lo: float, hi: float) -> float:
    """Bisection (sampling only): the largest t in [lo, hi] found with rel(t) > fraction,
    given rel(lo) > fraction ≥ rel(hi)."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if rel(mid) > fraction:
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class SampledState:
    """One initial state and how it was drawn.

    Attributes:
        position, velocity: (n,) in controller coordinates.
        kind: ``interior``, ``near_velocity`` (the closest velocity margin pushed to a small
            fraction of its value at rest), ``near_configuration`` (moved down the gradient
            of one configuration constraint, perturbed, until the closest configuration
            margin is a small fraction of its starting value, with a velocity towards ∂S)
            or ``near_both``.
        closeness: the fraction the margin was pushed to (1.0 for interior states).
    """

    position: Array
    velocity: Array
    kind: str
    closeness: float


class StateSampler:
    """Draws admissible states (x, ẋ) of a ConstraintSet.

    Positions are uniform in a box (centre ± half_width, intersected with any
    ``joint_position_limit``); velocities are uniform in the rate bounds, or scaled to a
    uniform fraction of the kinetic-energy limit, or uniform in ±``speed`` without velocity
    constraints. A fraction ``near`` of the draws is then pushed close to the boundary with a
    log-uniform closeness in [``closest``, ``farthest``] — half of those in a velocity margin,
    half in a configuration margin (both when the set has both kinds, one draw in three of
    those also in both at once). Rejection keeps every draw strictly inside S.

    Args:
        constraints: the admissible set S.
        centre: centre of the position box, (n,) (the target, typically).
        half_width: half-width of the box, scalar or (n,) [rad].
        seed: seed of numpy's generator; the same seed draws the same states.
        near: share of draws placed near ∂S.
        closest, farthest: range of the closeness fraction.
        speed: velocity range without velocity constraints [rad/s].
        reachable: whether the arm can take a position at all (the plant's joint ranges,
            say, where the constraints do not bound a joint); every draw satisfies it.
    """

    def __init__(
        self,
        constraints: ConstraintSet,
        centre: Array,
        half_width: float | Array = np.pi,
        seed: int = 0,
        near: float = 0.6,
        closest: float = 1e-4,
        farthest: float = 0.1,
        speed: float = 1.0,
        reachable: Callable[[Array], bool] | None = None,
    ) -> None:
        self.constraints = constraints
        self.reachable = reachable
        self.n = constraints.n
        self.rng = np.random.default_rng(seed)
        lo = np.asarray(centre, float) - half_width
        hi = np.asarray(centre, float) + half_width
        for c in constraints.configuration:
            if isinstance(c, LinearLimit):
                for row, lower, upper in zip(c.rows, c.lower, c.upper, strict=True):
                    if np.count_nonzero(row) == 1:
                        j = int(np.flatnonzero(row)[0])
                        a, b = sorted((lower / row[j], upper / row[j]))
                        lo[j], hi[j] = max(lo[j], a), min(hi[j], b)
        self.lo, self.hi = lo, hi
        self.near = near
        self.closest, self.farthest = closest, farthest
        self.speed = speed
        self._rates = [c for c in constraints.velocity if isinstance(c, RateLimit)]
        self._energy = [c for c in constraints.velocity if isinstance(c, KineticEnergyLimit)]

    def _margins(self, x: Array, dx: Array) -> Array:
        return self.constraints.margins(x, dx)

    def _velocity(self, x: Array) -> Array:
        n = self.n
        if not self.constraints.velocity:
            return self.rng.uniform(-self.speed, self.speed, n)
        dx = self.rng.uniform(-1.0, 1.0, n)
        if self._rates and not self._energy:
            # Uniform in the box of per-coordinate bounds where the rows are per joint.
            bounds = np.full(n, np.inf)
            for c in self._rates:
                if c.joint_index is not None:
                    bounds[c.joint_index] = np.minimum(bounds[c.joint_index], c.bounds)
            if np.all(np.isfinite(bounds)):
                return dx * bounds
        # Otherwise scale to the largest admissible multiple, then to a uniform fraction.
        top = self._scale_to(x, dx, 0.0)
        return dx * top * self.rng.uniform(0.0, 1.0) ** 0.5

    def _scale_to(self, x: Array, dx: Array, fraction: float) -> float:
        """c ≥ 0 such that the smallest velocity margin at c·ẋ is ``fraction`` of its value
        at rest (bisection: sampling only)."""
        rest = self._velocity_margins(x, np.zeros(self.n))

        def rel(c: float) -> float:
            return float(np.min(self._velocity_margins(x, c * dx) / rest))

        hi = 1.0
        while rel(hi) > fraction and hi < 1e6:
            hi *= 2.0
        return _last_above(rel, fraction, 0.0, hi)

    def _velocity_margins(self, x: Array, dx: Array) -> Array:
        parts = [c.value(x, dx, None) for c in self.constraints.velocity]
        return np.concatenate(parts)

    def _config_margins(self, x: Array) -> Array:
        parts = [c.value(x) for c in self.constraints.configuration]
        return np.concatenate(parts)

    def _push_configuration(self, x: Array, fraction: float) -> tuple[Array, Array] | None:
        """Move x along a random direction until its closest configuration margin is
        ``fraction`` of its starting value; returns the point and the unit direction."""
        start = self._config_margins(x)
        # Head for one configuration constraint chosen at random: down its gradient, with a
        # random component so that the boundary is reached at varied angles.
        grads = np.concatenate([c.gradient(x) for c in self.constraints.configuration])
        g = grads[int(self.rng.integers(len(grads)))]
        d = self.rng.normal(size=self.n)
        d /= np.linalg.norm(d)
        if np.linalg.norm(g) > 0:
            d = -g / np.linalg.norm(g) + self.rng.uniform(0.0, 1.0) * d
            d /= np.linalg.norm(d)

        def rel(t: float) -> float:
            return float(np.min(self._config_margins(x + t * d) / start))

        step, t = 0.05, 0.05
        while rel(t) > 0.0:
            t += step
            if t > 2 * np.pi:
                return None
        return x + _last_above(rel, fraction, t - step, t) * d, d

    def _near_kind(self) -> str:
        """Which boundary a near-boundary state approaches: velocity, configuration or
        both (a third of the time when there are both)."""
        kinds = []
        if self.constraints.velocity:
            kinds.append("near_velocity")
        if self.constraints.configuration:
            kinds.append("near_configuration")
        if len(kinds) == 2 and self.rng.uniform() < 1 / 3:
            kinds = ["near_both"]
        return kinds[int(self.rng.integers(len(kinds)))] if kinds else "interior"

    def draw(self) -> SampledState:
        """One admissible state."""
        for _ in range(10_000):
            x = self.rng.uniform(self.lo, self.hi)
            if self.reachable is not None and not self.reachable(x):
                continue
            if self.constraints.configuration and not np.all(self._config_margins(x) > 0):
                continue
            kind, close = "interior", 1.0
            dx = self._velocity(x)
            if self.rng.uniform() < self.near:
                close = float(np.exp(self.rng.uniform(np.log(self.closest),
                                                      np.log(self.farthest))))
                kind = self._near_kind()
                if kind in ("near_configuration", "near_both"):
                    pushed = self._push_configuration(x, close)
                    if pushed is None:
                        continue
                    x, d = pushed
                    # A velocity with a component towards ∂S (the direction that got there).
                    dx = np.abs(dx) @ np.abs(d) * d + 0.5 * dx
                if kind in ("near_velocity", "near_both") and np.any(dx):
                    dx = dx * self._scale_to(x, dx, close)
                elif self.constraints.velocity and np.any(dx):
                    top = self._scale_to(x, dx, 0.0)
                    dx = dx * min(1.0, 0.999 * top)
            m = self._margins(x, dx)
            if (m.size == 0 or np.all(m > 0)) and (self.reachable is None or self.reachable(x)):
                return SampledState(x, dx, kind, close)
        raise CpbcError("could not draw an admissible state in 10 000 attempts")

    def draw_many(self, count: int) -> list[SampledState]:
        return [self.draw() for _ in range(count)]
