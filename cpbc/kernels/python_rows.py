"""A constraint, potential or damping without a kernel inside a plan: its terms computed in
Python before each kernel call (a constraint's ``barrier_terms``,
cpbc.constraints.python_terms; a potential's ``evaluate``, a damping's ``force``,
cpbc.controllers.python_law_terms) and copied in, so that a law keeps its one kernel call for
every other term (cpbc.kernels.barrier_set and cpbc.kernels.law_terms dispatch these rows like
any kind's).

The tables are rewritten before every call (``Packed.live``): the constraint's barrier
values, its share of b, its margins (configuration) or Π (velocity); the potential's U and
∂U/∂x; the damping's force.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import inner
from cpbc.kernels.plan_tables import Ints, Packed, float_table
from cpbc.kernels.task import ROW

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


PYTHON_POTENTIAL, PYTHON_DAMPING = 12, 13  # the kinds' codes in a law's plan
TERM = 0  # its float table: [U, ∂U/∂x] (1, n + 1) of a potential, the force (1, n) of a damping


def pack_python_term(values: Array, damping: bool) -> Packed:
    """The table of one potential or damping asked in Python: ``values`` [U, ∂U/∂x] (n + 1,)
    or the force (n,), the array its owner rewrites before each call (``Packed.live``)."""
    return Packed(PYTHON_DAMPING if damping else PYTHON_POTENTIAL, (np.array(values[None, :]),),
                  live=((TERM, values),))


@inner(f"float64({ROW})")
def python_potential_row(plan: Ints, floats: Array, row: int, x: Array, origin: Array,
                         rotation: Array, jacobian: Array, grad: Array) -> float:
    """A potential's U and ∂U/∂x (into ``grad``) as its ``evaluate`` gave them."""
    table = float_table(plan, floats, row, TERM)[0]
    for i in range(x.shape[0]):
        grad[i] = table[1 + i]
    return table[0]


@inner(f"void({ROW})")
def python_damping_row(plan: Ints, floats: Array, row: int, dx: Array, origin: Array,
                       rotation: Array, jacobian: Array, force: Array) -> None:
    """A damping's force (into ``force``) as its ``force`` gave it."""
    table = float_table(plan, floats, row, TERM)[0]
    for i in range(dx.shape[0]):
        force[i] = table[i]
