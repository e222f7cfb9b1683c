"""A set of constraints: the admissible set S (eq. 6.18) and its log-barrier sums."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from cpbc.constraints.base import Array, ConfigurationConstraint, VelocityConstraint
from cpbc.errors import ConstraintViolation, CpbcError, InadmissibleStateError
from cpbc.model.robot_model import DynamicsTerms


def _log_sum(parts: Sequence[Array], owners: Sequence[ConfigurationConstraint | VelocityConstraint]
             ) -> float:
    """Σ log of every margin in ``parts``; ConstraintViolation naming the worst one if any
    margin is ≤ 0 or NaN."""
    values: list[float] = []
    for m in parts:
        values += m.tolist()
    try:
        total = math.fsum(map(math.log, values))
    except ValueError:  # a margin ≤ 0
        total = math.nan
    if total != total:  # a margin ≤ 0 or NaN (math.log(nan) is nan)
        names = [name for c in owners for name in c.names]
        margins = np.asarray(values)
        i = int(np.argmin(np.nan_to_num(margins, nan=-np.inf)))
        raise ConstraintViolation(names[i], float(margins[i]))
    return total


class BarrierTerms(NamedTuple):
    """Log-barrier sums of DESIGN §3 at one state.

    Attributes:
        log_phi: Σ log φ_i = log Φ.
        log_psi: Σ log ψ_j = log Ψ.
        gradient: b_φ + b_ψ = Σ ∇φ_i/φ_i + Σ ∂_xψ_j/ψ_j, shape (n,), or None when zero.
        weight: Π = Σ Q_j/ψ_j, shape (n, n), or None without velocity constraints.
    """

    log_phi: float
    log_psi: float
    gradient: Array | None
    weight: Array | None


class ConstraintSet:
    """Configuration and velocity constraints that together define S."""

    def __init__(
        self,
        n: int,
        configuration: Sequence[ConfigurationConstraint] = (),
        velocity: Sequence[VelocityConstraint] = (),
    ) -> None:
        self.n = n
        self.configuration = tuple(configuration)
        self.velocity = tuple(velocity)
        self.names: tuple[str, ...] = tuple(
            name for c in (*self.configuration, *self.velocity) for name in c.names
        )
        if len(set(self.names)) != len(self.names):
            dup = sorted({x for x in self.names if self.names.count(x) > 1})
            raise CpbcError(f"duplicate constraint names: {dup}; give each constraint its own name")
        self.needs_dynamics = any(c.needs_dynamics for c in self.velocity)
        # the margins found by the last barrier call, where its terms are the margins (a
        # localised barrier such as Clearance's gives the law φ̃, so its margins are redone)
        self._reusable = [c.barrier_is_margin for c in self.configuration] + [True] * len(
            self.velocity)
        self._last_key: bytes = b""
        self._last_parts: list[Array] = []

    def __len__(self) -> int:
        return len(self.names)

    @property
    def empty(self) -> bool:
        return not self.names

    def margins(self, x: Array, dx: Array, dyn: DynamicsTerms | None = None) -> Array:
        """Every φ_i and ψ_j, in the order of ``names``.

        At the state of the last ``barrier`` call the margins it found are reused (a law's
        safeguard asks for them at the sample the law has just evaluated).
        """
        if self._last_parts and self._last_key == x.tobytes() + dx.tobytes():
            parts = [m if keep else c.value(x)  # type: ignore[call-arg]
                     for m, keep, c in zip(self._last_parts, self._reusable,
                                           self.configuration, strict=False)]
            return np.concatenate(parts + self._last_parts[len(self.configuration):])
        parts = [c.value(x) for c in self.configuration]
        parts += [c.value(x, dx, dyn) for c in self.velocity]
        return np.concatenate(parts) if parts else np.zeros(0)

    def margins_along(self, xs: Array, dxs: Array) -> Array:
        """Every margin at every sample, shape (N, m); NaN rows where the state is not finite."""
        out = np.full((len(xs), len(self.names)), np.nan)
        ok = np.all(np.isfinite(xs), axis=1) & np.all(np.isfinite(dxs), axis=1)
        parts = [c.values_along(xs[ok]) for c in self.configuration]
        parts += [c.values_along(xs[ok], dxs[ok]) for c in self.velocity]
        if parts:
            out[ok] = np.concatenate(parts, axis=1)
        return out

    def check_admissible(self, x: Array, dx: Array, what: str) -> None:
        """Raise InadmissibleStateError if (x, ẋ) is not in S (Assumption 6.8)."""
        m = self.margins(x, dx)
        if m.size and not np.all(m > 0):
            i = int(np.argmin(np.where(np.isnan(m), -np.inf, m)))
            raise InadmissibleStateError(what, self.names[i], float(m[i]))

    def barrier(self, x: Array, dx: Array, dyn: DynamicsTerms) -> BarrierTerms:
        """Log-barrier sums at (x, ẋ); raises ConstraintViolation outside S."""
        gradient, weight = None, None
        phis = []
        for c in self.configuration:
            phi, b = c.barrier_terms(x)
            phis.append(phi)
            gradient = b if gradient is None else gradient + b
        psis = []
        for c in self.velocity:
            psi, pi, b = c.barrier_terms(x, dx, dyn)
            psis.append(psi)
            if b is not None:
                gradient = b if gradient is None else gradient + b
            weight = pi if weight is None else weight + pi
        log_phi = _log_sum(phis, self.configuration) if phis else 0.0
        log_psi = _log_sum(psis, self.velocity) if psis else 0.0
        self._last_key, self._last_parts = x.tobytes() + dx.tobytes(), phis + psis
        return BarrierTerms(log_phi, log_psi, gradient, weight)
