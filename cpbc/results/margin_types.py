"""Margins a person can compare, read from what each constraint class declares.

Every constraint class declares the type and unit of its margins and how its function values
become margins (cpbc.constraints.margins, where the table of types is); this module reads
those declarations for a whole monitor — the type key of every margin, the margins along a
run, the worst margin per type — and orders them for figures and tables. It names no
constraint class, so a new constraint shows up in the results as the type it declares.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import Array, ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.margins import TYPES, MarginType


def _constraints(
    monitor: ConstraintSet,
) -> tuple[ConfigurationConstraint | VelocityConstraint, ...]:
    """Every monitored constraint, configuration ones first (the order of ``monitor.names``)."""
    return (*monitor.configuration, *monitor.velocity)


def types_of(monitor: ConstraintSet, lengths: Array | None = None) -> tuple[str, ...]:
    """The type key of every monitored margin, in the order of ``monitor.names``.

    ``lengths`` marks the coordinates that are lengths (prismatic joints,
    :attr:`cpbc.model.RobotModel.length_coordinates`); without it every coordinate is an
    angle."""
    return tuple(t.key for c in _constraints(monitor) for t in c.margin_types(lengths))


def physical_history(monitor: ConstraintSet, values: Array) -> Array:
    """Every monitored constraint's function values along a run, shape (N, m), as margins in
    their types' units (NaN rows stay NaN)."""
    out = np.array(values, dtype=float, copy=True)
    start = 0
    with np.errstate(invalid="ignore"):
        for c in _constraints(monitor):
            k = len(c.names)
            out[:, start:start + k] = c.margins(out[:, start:start + k])
            start += k
    return out


@dataclass(frozen=True)
class WorstMargin:
    """The constraint of a type that came nearest its bound in a run."""

    type: str
    unit: str
    constraint: str
    value: float


def worst_by_type(
    min_margins: dict[str, float], types: dict[str, str]
) -> list[WorstMargin]:
    """Per type (in TYPES order), the constraint with the smallest minimum margin; NaN
    margins (a run that diverged before the first sample) are left out."""
    out = []
    for t in TYPES:
        finite = {n: v for n, v in min_margins.items() if types.get(n) == t.key and v == v}
        if finite:
            name = min(finite, key=finite.__getitem__)
            out.append(WorstMargin(t.key, t.unit, name, finite[name]))
    return out


def grouped(names: Sequence[str], types: Sequence[str]) -> list[tuple[MarginType, list[int]]]:
    """Column indices of each type present, in TYPES order."""
    return [(t, idx) for t in TYPES
            if (idx := [i for i, k in enumerate(types) if k == t.key])
            and len(names) == len(types)]


def nearest_columns(runs: Sequence[Array], columns: Sequence[int], count: int) -> list[int]:
    """The ``count`` of ``columns`` whose margins came nearest their bounds in any of the
    runs' margin histories (each (N, m)), nearest first."""
    def lowest(i: int) -> float:
        values = [float(np.nanmin(m[:, i])) for m in runs if np.any(np.isfinite(m[:, i]))]
        return min(values, default=np.inf)

    return sorted(columns, key=lowest)[:count]
