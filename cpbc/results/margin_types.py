"""Margins a person can compare: each constraint's distance to its bound, in one unit per type.

The constraint functions themselves are in the units the control law needs: a position limit
φ = (x − lower)(upper − x) is in rad², a rate limit ψ = ½(B² − ẋ²) in rad²/s², the thesis's
obstacle ‖p − c‖² − r² in m², a kinetic-energy bound Ω − ½ẋᵀDẋ in J. Side by side those
numbers say nothing. The results layer reports instead, per constraint type:

============  ===========================================  ======
type          margin reported                              unit
============  ===========================================  ======
position      distance of the coordinate to its nearer     rad
              limit (joint and relative-joint limits)
rate          B − |aᵀẋ|, rate headroom                     rad/s
travel        a position limit on prismatic joints         m
speed         a rate limit on prismatic joints             m/s
clearance     distance between robot and obstacle          m
energy        Ω − ½ẋᵀDẋ, kinetic-energy headroom           J
============  ===========================================  ======

A limit whose row mixes revolute and prismatic coordinates has no one unit: it is "other".
Each is zero exactly where the constraint's own function is (on the boundary of S), positive
inside and negative outside, so its sign tells the same story.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.constraints.base import Array, ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.clearance import Clearance
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.constraints.point_outside_sphere import PointOutsideSphere
from cpbc.constraints.rate_limit import RateLimit


@dataclass(frozen=True)
class MarginType:
    """A family of constraints whose margins share a unit.

    Attributes:
        key: short name used in summary.json and the viewer ("position", "rate", …).
        label: heading of its figure panel and table entry.
        unit: unit of its margins.
    """

    key: str
    label: str
    unit: str


POSITION = MarginType("position", "position limits", "rad")
RATE = MarginType("rate", "rate limits", "rad/s")
TRAVEL = MarginType("travel", "prismatic position limits", "m")
SPEED = MarginType("speed", "prismatic rate limits", "m/s")
CLEARANCE = MarginType("clearance", "clearance", "m")
ENERGY = MarginType("energy", "kinetic energy", "J")
OTHER = MarginType("other", "other constraints", "")
#: Every type, in the order figures and tables show them.
TYPES: tuple[MarginType, ...] = (POSITION, RATE, TRAVEL, SPEED, CLEARANCE, ENERGY, OTHER)
BY_KEY = {t.key: t for t in TYPES}


def margin_type(c: ConfigurationConstraint | VelocityConstraint) -> MarginType:
    """The type of a constraint's margins."""
    if isinstance(c, LinearLimit):
        return POSITION
    if isinstance(c, RateLimit):
        return RATE
    if isinstance(c, (Clearance, PointOutsideSphere)):
        return CLEARANCE
    if isinstance(c, KineticEnergyLimit):
        return ENERGY
    return OTHER


def _headroom(value: Array, half_width: Array) -> Array:
    """w − sqrt(w² − v) for v = w² − u², i.e. w − |u|, written without cancellation."""
    return value / (half_width + np.sqrt(np.maximum(half_width**2 - value, 0.0)))


def physical(c: ConfigurationConstraint | VelocityConstraint, values: Array) -> Array:
    """A constraint's own function values, shape (N, k), as margins in its type's unit."""
    if isinstance(c, LinearLimit):  # φ = w² − (aᵀx − c)²
        return _headroom(values, c.half_width)
    if isinstance(c, RateLimit):  # ψ = ½(B² − (aᵀẋ)²)
        return _headroom(2.0 * values, c.bounds)
    if isinstance(c, PointOutsideSphere):  # φ = d² − r²
        return values / (np.sqrt(np.maximum(values + c.radius**2, 0.0)) + c.radius)
    return values  # clearance [m] and energy [J] already are


def _constraints(
    monitor: ConstraintSet,
) -> tuple[ConfigurationConstraint | VelocityConstraint, ...]:
    """Every monitored constraint, configuration ones first (the order of ``monitor.names``)."""
    return (*monitor.configuration, *monitor.velocity)


def _row_type(kind: MarginType, row: Array, lengths: Array) -> MarginType:
    """A position or rate limit's row on prismatic coordinates only is in m (m/s); on both
    kinds it has no one unit."""
    used = np.abs(row) > 0
    if not np.any(np.logical_and(used, lengths)):
        return kind
    if np.all(lengths[used]):
        return TRAVEL if kind is POSITION else SPEED
    return OTHER


def types_of(monitor: ConstraintSet, lengths: Array | None = None) -> tuple[str, ...]:
    """The type key of every monitored margin, in the order of ``monitor.names``.

    ``lengths`` marks the coordinates that are lengths (prismatic joints,
    :attr:`cpbc.model.RobotModel.length_coordinates`); without it every coordinate is an
    angle."""
    out = []
    for c in _constraints(monitor):
        kind = margin_type(c)
        if lengths is not None and isinstance(c, (LinearLimit, RateLimit)):
            out += [_row_type(kind, row, np.asarray(lengths, dtype=bool)) for row in c.rows]
        else:
            out += [kind] * len(c.names)
    return tuple(t.key for t in out)


def physical_history(monitor: ConstraintSet, values: Array) -> Array:
    """Every monitored constraint's function values along a run, shape (N, m), as margins in
    their types' units (NaN rows stay NaN)."""
    out = np.array(values, dtype=float, copy=True)
    start = 0
    with np.errstate(invalid="ignore"):
        for c in _constraints(monitor):
            k = len(c.names)
            out[:, start:start + k] = physical(c, out[:, start:start + k])
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
