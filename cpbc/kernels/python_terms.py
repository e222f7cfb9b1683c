"""A constraint without a kernel inside a set's plan: its log-barrier terms computed in
Python before each kernel call (its ``barrier_terms``, cpbc.constraints.python_terms) and
copied in, so that a law keeps its one kernel call for every other term
(cpbc.kernels.barrier_set dispatches these rows like any kind's).

The tables are rewritten before every call (``Packed.live``): the constraint's barrier
values, its share of b, its margins (configuration) or Π (velocity).
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import inner
from cpbc.kernels.tables import Ints, Packed, float_table

PYTHON_CONFIGURATION, PYTHON_VELOCITY = 5, 6  # the kinds' codes in a set's plan
VALUES, GRADIENT, MARGINS, WEIGHT = 0, 1, 2, 2  # its float tables: (1, k), (1, n), …


def pack_python_terms(values: Array, gradient: Array, last: Array, velocity: bool
                      ) -> Packed:
    """The tables of one constraint asked in Python: ``values`` (k,) its barrier values,
    ``gradient`` (n,) its share of b, ``last`` its margins (k,) (``MARGINS``,
    configuration) or Π (n, n) (``WEIGHT``, velocity): the arrays its owner rewrites
    before each call, read again then (``Packed.live``)."""
    tables = (values[None, :], gradient[None, :], last if velocity else last[None, :])
    return Packed(PYTHON_VELOCITY if velocity else PYTHON_CONFIGURATION,
                  tuple(np.array(t) for t in tables),
                  live=((VALUES, values), (GRADIENT, gradient),
                        (WEIGHT if velocity else MARGINS, last)))


@inner("void(int64[:, :], float64[:, :], int64, float64[:], float64[:], float64[:])")
def python_configuration_row(plan: Ints, floats: Array, row: int, phi: Array,
                             gradient: Array, shown: Array) -> None:
    """A configuration constraint's terms as its ``barrier_terms`` gave them."""
    phi[:] = float_table(plan, floats, row, VALUES)[0]
    gradient[:] = float_table(plan, floats, row, GRADIENT)[0]
    if shown.shape[0] > 0:
        shown[:] = float_table(plan, floats, row, MARGINS)[0]


@inner("void(int64[:, :], float64[:, :], int64, float64[:], float64[:, :], float64[:],"
       " float64[:])")
def python_velocity_row(plan: Ints, floats: Array, row: int, psi: Array, weight: Array,
                        gradient: Array, shown: Array) -> None:
    """A velocity constraint's terms as its ``barrier_terms`` gave them; its margins are ψ."""
    psi[:] = float_table(plan, floats, row, VALUES)[0]
    gradient[:] = float_table(plan, floats, row, GRADIENT)[0]
    weight[:, :] = float_table(plan, floats, row, WEIGHT)
    if shown.shape[0] > 0:
        shown[:] = psi
