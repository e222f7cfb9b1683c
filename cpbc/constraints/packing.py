"""A constraint set's constants packed once, at construction, for its barrier kernel
(cpbc.kernels.barrier_set.set_barrier): one call per step for every constraint that packs.

A constraint packs (``packed``) when its kind has a kernel the set kernel calls and its
class keeps that kind's ``barrier_terms``: a subclass that overrides ``barrier_terms``
(its own formula) is asked through its method instead, after the kernel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.kernels.barrier_set import (
    FLOAT_AT,
    FLOAT_TABLES,
    INT_AT,
    INT_TABLES,
    PLAN_WIDTH,
    POINT,
)

Ints = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class Packed:
    """One constraint's share of the set kernel.

    Attributes:
        kind: its kind (cpbc.kernels.barrier_set: LINEAR, RATE, ENERGY, POINT, SPHERES).
        floats: its constant float tables, 2-D, in the order the kind reads them.
        ints: its constant int tables, 2-D.
        frame: the frame whose kinematics the kernel reads (POINT), else −1.
        live: (table, source) pairs: the rows of float table ``table`` mirror the rows of
            ``source`` (a 1-D ``source``: the first row), which its owner rewrites in place
            between steps (a moving goal, cpbc.reference.target); the packed copy is
            refreshed from it before each kernel call (cpbc.controllers.packed_law).
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
    """The tables of the set kernel: ``plan`` (one row per packed constraint), ``ints`` and
    ``floats`` (cpbc.kernels.barrier_set), and the frame of its point constraint (−1: none).

    Built by :meth:`build` from the packed constraints and the first margin of each.
    """

    plan: Ints
    ints: Ints
    floats: Array
    frame: int
    live: tuple[tuple[int, Array], ...] = ()  # (offset in floats.ravel(), source)

    @classmethod
    def build(cls, parts: Sequence[tuple[int, int, Packed]]) -> PackedSet:
        """From (first margin, number of margins, packed) of each packed constraint, in the
        set's order."""
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
            plan[r, :3] = (p.kind, at, k)
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
            if p.kind == POINT:
                frame = p.frame
        stacked = _stack(floats, np.float64)
        width = stacked.shape[1]
        return cls(plan, _stack(ints, np.int64), stacked, frame,
                   tuple((row * width, source) for row, source in live))
