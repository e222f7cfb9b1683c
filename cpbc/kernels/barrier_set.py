"""A constraint set's log-barrier sums in one kernel call: every constraint the set packed
(cpbc.kernels.plan_tables) in the set's order, each by its own kind's row reader — the formulas,
the tables and their readers are beside each other in the kind's module, not here.

The registry of the kinds a set's plan holds (``KINDS``; a new kind with a kernel is its
kernel module and two lines here: its code in ``KINDS``, its row in ``set_barrier``'s
dispatch):

- ``LINEAR``, ``RATE``, ``ENERGY``, ``POINT``: cpbc.kernels.barriers (the point on the
  frame the caller passes);
- ``SPHERES``: the clearance's sphere pairs, cpbc.kernels.clearance;
- ``PYTHON_CONFIGURATION``, ``PYTHON_VELOCITY``: a constraint without a kernel, its terms
  computed in Python before the call, cpbc.kernels.python_rows.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import kernel
from cpbc.kernels.barriers import (
    ENERGY,
    LINEAR,
    POINT,
    RATE,
    kinetic_energy_row,
    linear_limit_row,
    log_sum,
    point_sphere_row,
    rate_limit_row,
)
from cpbc.kernels.clearance import SPHERES, sphere_pairs_row
from cpbc.kernels.plan_tables import COUNT, FIRST, KIND, float_table, int_table
from cpbc.kernels.python_rows import (
    PYTHON_CONFIGURATION,
    PYTHON_VELOCITY,
    python_configuration_row,
    python_velocity_row,
)
from cpbc.kernels.views import Ints, float_rows

KINDS = (LINEAR, RATE, ENERGY, POINT, SPHERES, PYTHON_CONFIGURATION, PYTHON_VELOCITY)
VELOCITY_KINDS = (RATE, ENERGY, PYTHON_VELOCITY)  # their values are ψ: log Ψ, and Π
# the codes and readers the guard's kernels import from here (cpbc.kernels.sampled_guard)
__all__ = ["ENERGY", "KINDS", "LINEAR", "POINT", "RATE", "SPHERES", "VELOCITY_KINDS",
           "float_table", "int_table", "set_barrier"]


@kernel("UniTuple(float64, 2)(int64[:, :], int64[:, :], float64[:, :], float64[:],"
        " float64[:], float64[:, :], float64[:, :], float64[:], float64[:, :], float64[:, :],"
        " float64[:, :], float64[:, :], float64[:], float64[:], float64[:, :], float64[:])",
        inline=True)
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
        kind, at, k = plan[r, KIND], plan[r, FIRST], plan[r, COUNT]
        seg = phi[at:at + k]
        shown = value[at:at + k] if value.shape[0] > 0 else value
        if kind == LINEAR:
            linear_limit_row(plan, floats, r, x, seg, part, shown)
        elif kind == POINT:
            point_sphere_row(plan, floats, r, point, rotation, frame_jacobian, seg, part, shown)
        elif kind == SPHERES:
            sphere_pairs_row(plan, ints, floats, r, y, jac, seg, part, shown)
        elif kind == RATE:
            rate_limit_row(plan, floats, r, dx, seg, pi, part, shown)
        elif kind == ENERGY:
            kinetic_energy_row(plan, floats, r, inertia, coriolis, dx, seg, pi, part, shown)
        elif kind == PYTHON_CONFIGURATION:
            python_configuration_row(plan, floats, r, seg, part, shown)
        else:  # PYTHON_VELOCITY
            python_velocity_row(plan, floats, r, seg, pi, part, shown)
        if kind in VELOCITY_KINDS:
            log_psi += log_sum(seg)
            for a in range(n):
                for b in range(n):
                    weight[a, b] += pi[a, b]
        else:
            log_phi += log_sum(seg)
        for a in range(n):
            gradient[a] += part[a]
    return log_phi, log_psi
