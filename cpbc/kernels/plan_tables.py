"""The packed form of constant tables that the kernels read by row: a constraint set's
(cpbc.kernels.barrier_set) and a law's terms (cpbc.kernels.law_terms) alike.

Each packed item (a constraint, a term) hands over its kind's code and its constant tables
(:class:`Packed`); :class:`PackedSet` stacks them once, at construction: ``floats`` and
``ints`` hold every item's tables one below the other (each at most as wide as the
table), and ``plan`` has one row per item:

    [kind, first margin, number of margins, (row, rows, columns) of each float table …,
     (row, rows, columns) of each int table …]

with the float tables' triples from column ``FLOAT_AT`` and the int tables' from
``INT_AT``. What the tables of a kind hold, and in which order, is written once, beside
that kind's formula: its ``pack_*`` function builds the :class:`Packed` and its ``*_row``
reader (``float_table`` and ``int_table`` with the table's named index) reads it back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.kernels import inner

Ints = NDArray[np.int64]

# the plan's columns: the kind, the item's first margin and its number of margins
KIND, FIRST, COUNT = 0, 1, 2
FLOAT_TABLES, INT_TABLES = 8, 3  # the most tables one item packs
FLOAT_AT = COUNT + 1
INT_AT = FLOAT_AT + 3 * FLOAT_TABLES
PLAN_WIDTH = INT_AT + 3 * INT_TABLES


@dataclass(frozen=True, eq=False)
class Packed:
    """One item's share of a kernel's tables.

    Attributes:
        kind: its kind's code (each kind's module declares it, beside its ``pack_*``).
        floats: its constant float tables, 2-D, in the order the kind reads them.
        ints: its constant int tables, 2-D.
        frame: the frame whose kinematics the kernel reads (a frame kind), else −1.
        live: (table, source) pairs: the rows of float table ``table`` mirror the rows of
            ``source`` (a 1-D ``source``: the first row), which its owner rewrites in place
            between steps (a moving goal, cpbc.reference.target; a constraint without a
            kernel, cpbc.constraints.python_terms); the packed copy is refreshed from it
            before each kernel call (cpbc.controllers.packed_law).
    """

    kind: int
    floats: tuple[Array, ...]
    ints: tuple[Ints, ...] = ()
    frame: int = -1
    live: tuple[tuple[int, Array], ...] = ()


def _stack(tables: Sequence[NDArray[Any]], dtype: type) -> NDArray[Any]:
    """The tables one below the other, as wide as the widest (at least 1 × 1)."""
    rows = max(1, sum(t.shape[0] for t in tables))
    cols = max([1, *(t.shape[1] for t in tables)])
    out = np.zeros((rows, cols), dtype=dtype)
    at = 0
    for t in tables:
        out[at:at + t.shape[0], :t.shape[1]] = t
        at += t.shape[0]
    return out


@dataclass(frozen=True, eq=False)
class PackedSet:
    """The stacked tables: ``plan`` (one row per item), ``ints`` and ``floats``, and the
    frame of its point constraint (−1: none).

    Built by :meth:`build` from the packed items and the first margin of each.
    """

    plan: Ints
    ints: Ints
    floats: Array
    frame: int
    live: tuple[tuple[int, Array], ...] = ()  # (offset in floats.ravel(), source)

    @classmethod
    def build(cls, parts: Sequence[tuple[int, int, Packed]]) -> PackedSet:
        """From (first margin, number of margins, packed) of each item, in order."""
        plan = np.zeros((len(parts), PLAN_WIDTH), dtype=np.int64)
        floats: list[Array] = []
        ints: list[Ints] = []
        frame = -1
        f_row = i_row = 0
        live: list[tuple[int, Array]] = []  # (row in the stacked floats, source)
        table: NDArray[Any]
        for r, (at, k, p) in enumerate(parts):
            if len(p.floats) > FLOAT_TABLES or len(p.ints) > INT_TABLES:
                raise ValueError(f"kind {p.kind} packs too many tables")
            plan[r, [KIND, FIRST, COUNT]] = (p.kind, at, k)
            for i, source in p.live:
                first = f_row + sum(t.shape[0] for t in p.floats[:i])
                rows = source if source.ndim == 2 else source[None, :]
                live += [(first + j, row) for j, row in enumerate(rows)]
            for t, table in enumerate(p.floats):
                plan[r, FLOAT_AT + 3 * t:FLOAT_AT + 3 * t + 3] = (f_row, *table.shape)
                floats.append(table)
                f_row += table.shape[0]
            for t, table in enumerate(p.ints):
                plan[r, INT_AT + 3 * t:INT_AT + 3 * t + 3] = (i_row, *table.shape)
                ints.append(table)
                i_row += table.shape[0]
            if p.frame >= 0:
                frame = p.frame
        stacked = _stack(floats, np.float64)
        width = stacked.shape[1]
        return cls(plan, _stack(ints, np.int64), stacked, frame,
                   tuple((row * width, source) for row, source in live))


@inner("float64[:, :](int64[:, :], float64[:, :], int64, int64)")
def float_table(plan: Ints, floats: Array, row: int, table: int) -> Array:
    """The ``table``-th float table of the ``row``-th packed item (a view)."""
    at = FLOAT_AT + 3 * table
    start, rows, cols = plan[row, at], plan[row, at + 1], plan[row, at + 2]
    return floats[start:start + rows, :cols]


@inner("int64[:, :](int64[:, :], int64[:, :], int64, int64)")
def int_table(plan: Ints, ints: Ints, row: int, table: int) -> Ints:
    """The ``table``-th int table of the ``row``-th packed item (a view)."""
    at = INT_AT + 3 * table
    start, rows, cols = plan[row, at], plan[row, at + 1], plan[row, at + 2]
    return ints[start:start + rows, :cols]
