"""Margins a person can compare: each constraint's distance to its bound, in one unit per type.

The constraint functions themselves are in the units the control law needs: a position limit
φ = (x − lower)(upper − x) is in rad², a rate limit ψ = ½(B² − ẋ²) in rad²/s², the thesis's
obstacle ‖p − c‖² − r² in m², a kinetic-energy bound Ω − ½ẋᵀDẋ in J. Side by side those
numbers say nothing. Every constraint class therefore declares, beside its formula, the type
of its margins (``margin_type``, one of the types of cpbc.margin_kinds, re-exported here,
where the table of types and units is) and, where φ is not already in that unit, how φ
becomes a margin (``margins``).

Each margin is zero exactly where the constraint's own function is (on the boundary of S),
positive inside and negative outside, so its sign tells the same story. The results layer
(cpbc.results.margin_types) reads these declarations; it names no constraint class.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from cpbc.arrays import Array
from cpbc.margin_kinds import (
    BY_KEY,
    CLEARANCE,
    ENERGY,
    OTHER,
    POSITION,
    RATE,
    SPEED,
    TRAVEL,
    TYPES,
    MarginType,
)

__all__ = ["BY_KEY", "CLEARANCE", "ENERGY", "ON_LENGTHS", "OTHER", "POSITION", "RATE", "SPEED",
           "TRAVEL", "TYPES", "HasMargins", "MarginType", "headroom", "row_types"]


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
