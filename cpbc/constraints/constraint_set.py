"""A set of constraints: the admissible set S (eq. 6.18) and its log-barrier sums."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from itertools import groupby
from typing import NamedTuple, TypeVar

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.base import ConfigurationConstraint, VelocityConstraint
from cpbc.errors import ConstraintViolation, CpbcError, InadmissibleStateError
from cpbc.kernels.barriers import log_sum
from cpbc.model.robot_model import ArmState, RobotModel

Constraint = TypeVar("Constraint", ConfigurationConstraint, VelocityConstraint)


def _log_sum(parts: Sequence[Array], names: Sequence[str]) -> float:
    """Σ log of every margin in ``parts`` (cpbc.kernels.barriers.log_sum); ConstraintViolation
    naming the worst one if any margin is ≤ 0 or NaN."""
    total = 0.0
    for m in parts:
        total += log_sum(m)
    if total != total:  # a margin ≤ 0 or NaN
        margins = np.concatenate(parts)
        i = int(np.argmin(np.nan_to_num(margins, nan=-np.inf)))
        raise ConstraintViolation(names[i], float(margins[i]))
    return total


def _stack(items: Sequence[Constraint]) -> tuple[Constraint, ...]:
    """Neighbours of one class that stacks, evaluated as one constraint (the same names in
    the same order); a group that cannot stack (a joint bounded twice) stays as it is."""
    out: list[Constraint] = []
    for _, group in groupby(items, key=type):
        run = list(group)
        if len(run) > 1 and run[0].stacks:
            try:
                out.append(run[0].stacked(run))
                continue
            except CpbcError:
                pass
        out.extend(run)
    return tuple(out)


class BarrierTerms(NamedTuple):
    """The laws' log-barrier sums (Σ ∇φ/φ, never the products Φ, Ψ) at one state.

    Attributes:
        log_phi: Σ log φ̃_i = log Φ.
        log_psi: Σ log ψ_j = log Ψ.
        gradient: b_φ + b_ψ = Σ ∇φ̃_i/φ̃_i + Σ ∂_xψ_j/ψ_j, shape (n,), or None when zero.
        weight: Π = Σ Q_j/ψ_j, shape (n, n), or None without velocity constraints.
        margins: every φ_i and ψ_j in the order of ``ConstraintSet.names`` when asked for,
            else None.
    """

    log_phi: float
    log_psi: float
    gradient: Array | None
    weight: Array | None
    margins: Array | None = None


class ConstraintSet:
    """Configuration and velocity constraints that together define S.

    Neighbouring constraints of a kind that stacks (linear limits, rate limits) are
    evaluated together, as one constraint with all their rows.
    """

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
            [name for c in self.configuration for name in c.names]
            + [name for v in self.velocity for name in v.names])
        if len(set(self.names)) != len(self.names):
            dup = sorted({x for x in self.names if self.names.count(x) > 1})
            raise CpbcError(f"duplicate constraint names: {dup}; give each constraint its own name")
        self.needs_dynamics = any(c.needs_dynamics for c in self.velocity)
        self.needs_kinematics = any(c.needs_kinematics for c in self.configuration)
        self.needs_coriolis = any(c.needs_coriolis for c in self.velocity)
        self.frames: tuple[int, ...] = tuple(
            dict.fromkeys(f for c in self.configuration for f in c.frames))
        self._config = _stack(self.configuration)
        self._velocity = _stack(self.velocity)
        self.n_configuration = sum(len(c.names) for c in self.configuration)

    def __len__(self) -> int:
        return len(self.names)

    @property
    def empty(self) -> bool:
        return not self.names

    def state(self, model: RobotModel, x: Array, dx: Array, frames: Iterable[int] = ()
              ) -> ArmState:
        """The per-step state these constraints read (with ``frames`` besides, e.g. a
        potential's), from one call of ``model.state``."""
        wanted = tuple(dict.fromkeys((*self.frames, *frames))) if frames else self.frames
        return model.state(x, dx, kinematics=self.needs_kinematics, frames=wanted,
                           coriolis=self.needs_coriolis)

    def margins(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        """Every φ_i and ψ_j at (x, ẋ), in the order of ``names``."""
        parts = [c.value(x) for c in self._config]
        parts += [c.value(x, dx, state) for c in self._velocity]
        return np.concatenate(parts) if parts else np.zeros(0)

    def configuration_margins(self, x: Array) -> Array:
        """Every φ_i at x, in the order of ``names``."""
        parts = [c.value(x) for c in self._config]
        return np.concatenate(parts) if parts else np.zeros(0)

    def velocity_margins(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        """Every ψ_j at (x, ẋ), in the order of ``names``."""
        parts = [c.value(x, dx, state) for c in self._velocity]
        return np.concatenate(parts) if parts else np.zeros(0)

    def configuration_margins_along(self, xs: Array) -> Array:
        """Every φ_i at every row of xs, shape (N, number of φ_i)."""
        parts = [c.values_along(xs) for c in self._config]
        return np.concatenate(parts, axis=1) if parts else np.zeros((len(xs), 0))

    def velocity_margins_along(self, xs: Array, dxs: Array) -> Array:
        """Every ψ_j at every row of (xs, dxs), shape (N, number of ψ_j)."""
        parts = [c.values_along(xs, dxs) for c in self._velocity]
        return np.concatenate(parts, axis=1) if parts else np.zeros((len(xs), 0))

    def margins_along(self, xs: Array, dxs: Array) -> Array:
        """Every margin at every sample, shape (N, m); NaN rows where the state is not finite."""
        out = np.full((len(xs), len(self.names)), np.nan)
        ok = np.all(np.isfinite(xs), axis=1) & np.all(np.isfinite(dxs), axis=1)
        parts = [c.values_along(xs[ok]) for c in self._config]
        parts += [c.values_along(xs[ok], dxs[ok]) for c in self._velocity]
        if parts:
            out[ok] = np.concatenate(parts, axis=1)
        return out

    def check_admissible(self, x: Array, dx: Array, what: str) -> None:
        """Raise InadmissibleStateError if (x, ẋ) is not in S (Assumption 6.8)."""
        m = self.margins(x, dx)
        if m.size and not np.all(m > 0):
            i = int(np.argmin(np.where(np.isnan(m), -np.inf, m)))
            raise InadmissibleStateError(what, self.names[i], float(m[i]))

    def barrier(self, state: ArmState, margins: bool = False) -> BarrierTerms:
        """Log-barrier sums at the per-step state (with ``margins``, every margin too);
        raises ConstraintViolation outside S."""
        gradient, weight = None, None
        phis, values = [], []
        for c in self._config:
            phi, b, value = c.barrier_terms(state, margins)
            phis.append(phi)
            values.append(value)
            gradient = b if gradient is None else gradient + b
        psis = []
        for v in self._velocity:
            psi, pi, b_psi = v.barrier_terms(state)
            psis.append(psi)
            if b_psi is not None:
                gradient = b_psi if gradient is None else gradient + b_psi
            weight = pi if weight is None else weight + pi
        nc = self.n_configuration
        log_phi = _log_sum(phis, self.names[:nc]) if phis else 0.0
        log_psi = _log_sum(psis, self.names[nc:]) if psis else 0.0
        found = None
        if margins:
            parts = values + psis
            found = np.concatenate(parts) if parts else np.zeros(0)  # type: ignore[arg-type]
        return BarrierTerms(log_phi, log_psi, gradient, weight, found)
