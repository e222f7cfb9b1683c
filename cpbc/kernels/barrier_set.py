"""A constraint set's log-barrier sums in one kernel call: every constraint the set packed
(cpbc.constraints.packing) in the set's order, each by its own kind's kernel
(cpbc.kernels.barriers, cpbc.kernels.clearance) — the formulas are there, not here.

The set's constants are packed once, at construction, into three tables: ``floats`` and
``ints`` hold every packed constraint's constant tables one below the other (each at most
as wide as the table), and ``plan`` has one row per packed constraint:

    [kind, first margin, number of margins, (row, rows, columns) of each float table …,
     (row, rows, columns) of each int table …]

with the float tables' triples from column ``FLOAT_AT`` and the int tables' from
``INT_AT``. The kinds and their tables:

- ``LINEAR``: the linear limit's [a_iᵀ l_i u_i] (``linear_limit_terms``);
- ``RATE``: the rate limit's [a_jᵀ Ω_j] (``rate_limit_terms``);
- ``ENERGY``: the energy limit Ω, (1, 1) (``kinetic_energy_terms``);
- ``POINT``: a point outside a sphere, [c r² o has_offset] (1, 8) (``point_sphere_terms``),
  on the frame the caller passes;
- ``SPHERES``: the clearance's sphere pairs: sphere_local, obstacles, pair_table, supports,
  far_phi (a column), ℓ (1, 1, 0 for none) and group_table; ints sphere_index (a column),
  pair_index and group_index (``cpbc.kernels.clearance``).
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import inner, kernel
from cpbc.kernels.barriers import (
    kinetic_energy_terms,
    linear_limit_terms,
    log_sum,
    point_sphere_terms,
    rate_limit_terms,
)
from cpbc.kernels.clearance import sphere_barrier, sphere_clearances
from cpbc.kernels.views import Ints, float_rows

LINEAR, RATE, ENERGY, POINT, SPHERES = 0, 1, 2, 3, 4
VELOCITY_KINDS = (RATE, ENERGY)
FLOAT_AT, FLOAT_TABLES, INT_AT, INT_TABLES = 3, 7, 24, 3
PLAN_WIDTH = INT_AT + 3 * INT_TABLES


@inner("float64[:, :](int64[:, :], float64[:, :], int64, int64)")
def float_table(plan: Ints, floats: Array, row: int, table: int) -> Array:
    """The ``table``-th float table of the ``row``-th packed constraint (a view)."""
    at = FLOAT_AT + 3 * table
    start, rows, cols = plan[row, at], plan[row, at + 1], plan[row, at + 2]
    return floats[start:start + rows, :cols]


@inner("int64[:, :](int64[:, :], int64[:, :], int64, int64)")
def int_table(plan: Ints, ints: Ints, row: int, table: int) -> Ints:
    """The ``table``-th int table of the ``row``-th packed constraint (a view)."""
    at = INT_AT + 3 * table
    start, rows, cols = plan[row, at], plan[row, at + 1], plan[row, at + 2]
    return ints[start:start + rows, :cols]


@kernel("float64(int64[:, :], int64[:, :], float64[:, :], int64, float64[:, :], float64[:, :],"
        " float64[:], float64[:], float64[:])")
def _spheres(plan: Ints, ints: Ints, floats: Array, row: int, y: Array, jac: Array,
             phi: Array, part: Array, value: Array) -> float:
    """The clearance's sphere pairs (``sphere_barrier``): φ̃ into ``phi``, Σ ∇φ̃/φ̃ into
    ``part`` (zero with no pair within ℓ: φ̃ is then the far values; and outside S, where
    ``phi`` holds the clearances themselves), the reported clearances into a non-empty
    ``value``; returns the smallest law clearance (exact below ℓ, ``sphere_barrier``)."""
    far = float_table(plan, floats, row, 4)[:, 0]
    ell = float_table(plan, floats, row, 5)[0, 0]
    index = int_table(plan, ints, row, 0)[:, 0]
    pairs = int_table(plan, ints, row, 1)
    local, obstacles = float_table(plan, floats, row, 0), float_table(plan, floats, row, 1)
    table, supports = float_table(plan, floats, row, 2), float_table(plan, floats, row, 3)
    groups, bounds = int_table(plan, ints, row, 2), float_table(plan, floats, row, 6)
    low = sphere_barrier(y, jac, index, local, obstacles, pairs, table, groups, bounds,
                         supports, far, ell, phi, part, value)
    if low > 0.0 and (ell == 0.0 or low < ell):
        return low
    part[:] = 0.0
    if low > 0.0:  # no pair within ℓ
        phi[:] = far
    else:  # outside S (or NaN): the clearances themselves, the set raises
        sphere_clearances(y, index, local, obstacles, pairs, table, phi)
    return low


@kernel("UniTuple(float64, 2)(int64[:, :], int64[:, :], float64[:, :], float64[:],"
        " float64[:], float64[:, :], float64[:, :], float64[:], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :], float64[:], float64[:], float64[:, :], float64[:])")
def set_barrier(plan: Ints, ints: Ints, floats: Array, x: Array, dx: Array, inertia: Array,
                coriolis: Array, point: Array, rotation: Array, frame_jacobian: Array,
                y: Array, jac: Array, phi: Array, gradient: Array, weight: Array,
                value: Array) -> tuple[float, float]:
    """log Φ and log Ψ (``log_sum`` of each constraint's barrier values, added in the set's
    order) of the packed constraints; their barrier values into ``phi`` (at each one's
    margins), b_φ + b_ψ = Σ ∇φ̃_i/φ̃_i + Σ ∂_xψ_j/ψ_j into ``gradient`` and Π = Σ Q_j/ψ_j
    into ``weight`` (both overwritten; each constraint's share summed apart, then added, as
    the set adds them) and, when ``value`` is not empty, every margin into it.

    The state: x, ẋ, D, C (``ENERGY``), the frame's origin, axes and Jacobian [J_v; J_ω]
    (``POINT``), the joint placements and Jacobians (``SPHERES``)."""
    n = x.shape[0]
    work = np.empty(n + n * n)
    part, pi = work[:n], float_rows(work, n, n, n)
    gradient[:] = 0.0
    weight[:] = 0.0
    log_phi, log_psi = 0.0, 0.0
    for r in range(plan.shape[0]):
        kind, at, k = plan[r, 0], plan[r, 1], plan[r, 2]
        seg = phi[at:at + k]
        shown = value[at:at + k] if value.shape[0] > 0 else value
        if kind == LINEAR:
            linear_limit_terms(float_table(plan, floats, r, 0), x, seg, part)
        elif kind == POINT:
            point_sphere_terms(float_table(plan, floats, r, 0)[0], point, rotation,
                               frame_jacobian, seg, part)
        elif kind == SPHERES:
            _spheres(plan, ints, floats, r, y, jac, seg, part, shown)
        elif kind == RATE:
            rate_limit_terms(float_table(plan, floats, r, 0), dx, seg, pi)
        else:  # ENERGY
            seg[0] = kinetic_energy_terms(float_table(plan, floats, r, 0)[0, 0], inertia,
                                          coriolis, dx, pi, part)
        if kind != SPHERES and shown.shape[0] > 0:
            shown[:] = seg
        if kind == RATE or kind == ENERGY:
            log_psi += log_sum(seg)
            for a in range(n):
                for b in range(n):
                    weight[a, b] += pi[a, b]
        else:
            log_phi += log_sum(seg)
        if kind != RATE:
            for a in range(n):
                gradient[a] += part[a]
    return log_phi, log_psi
