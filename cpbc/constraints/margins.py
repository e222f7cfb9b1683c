"""Margins a person can compare: each constraint's distance to its bound, in one unit per type.

The constraint functions themselves are in the units the control law needs: a position limit
φ = (x − lower)(upper − x) is in rad², a rate limit ψ = ½(B² − ẋ²) in rad²/s², the thesis's
obstacle ‖p − c‖² − r² in m², a kinetic-energy bound Ω − ½ẋᵀDẋ in J. Side by side those
numbers say nothing. Every constraint class therefore declares, beside its formula, the type
of its margins (``margin_type``, one of :data:`TYPES`) and, where φ is not already in that
unit, how φ becomes a margin (``margins``):

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
Each margin is zero exactly where the constraint's own function is (on the boundary of S),
positive inside and negative outside, so its sign tells the same story. The results layer
(cpbc.results.margin_types) reads these declarations; it names no constraint class.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from cpbc.arrays import Array


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
#: The type of a joint-coordinate limit's row that acts on prismatic joints only.
ON_LENGTHS = {POSITION: TRAVEL, RATE: SPEED}


def headroom(value: Array, half_width: Array) -> Array:
    """w − |u| from v = w² − u², written without cancellation: v / (w + sqrt(w² − v))."""
    return value / (half_width + np.sqrt(np.maximum(half_width**2 - value, 0.0)))


def row_types(kind: MarginType, rows: Array, lengths: Array | None) -> tuple[MarginType, ...]:
    """The type of each row a of a limit on aᵀx (or aᵀẋ) of type ``kind``: ``kind`` on
    angles, its length variant (:data:`ON_LENGTHS`) on prismatic coordinates only, OTHER on
    both. ``lengths`` marks the coordinates that are lengths (None: all are angles)."""
    if lengths is None:
        return (kind,) * len(rows)
    is_length = np.asarray(lengths, dtype=bool)
    out = []
    for row in rows:
        used = np.abs(row) > 0
        if not np.any(used & is_length):
            out.append(kind)
        else:
            out.append(ON_LENGTHS[kind] if np.all(is_length[used]) else OTHER)
    return tuple(out)


class HasMargins:
    """What every constraint class says of its margins (a base of both constraint kinds).

    A concrete class sets ``margin_type``; one whose φ is not in that type's unit overrides
    ``margins``, and a limit on joint coordinates overrides ``margin_types`` with
    :func:`row_types`.
    """

    names: tuple[str, ...]
    margin_type: ClassVar[MarginType]

    def margins(self, values: Array) -> Array:
        """The constraint's function values, shape (N, k), as margins in the unit of its
        type: the values themselves unless a class says otherwise."""
        return values

    def margin_types(self, lengths: Array | None = None) -> tuple[MarginType, ...]:
        """The type of each scalar constraint's margin (``lengths``: see :func:`row_types`)."""
        return (self.margin_type,) * len(self.names)
