"""Bounded least squares for the brakes (cpbc.constraints.brakes): min ‖A z − t‖ over a box.

The least-squares and aimed brakes solve, at every period of a rescue's rollout, one problem
with n ≤ 7 unknowns and n or n + 1 rows. SciPy's ``lsq_linear(method="bvls")`` solves it in
about 1 ms of interpreter work (and loads SciPy's optimiser on first use); this is the same
problem by a primal active-set method (Lawson and Hanson's NNLS, with two bounds per
variable, as in Stark and Parker's BVLS) over the normal equations AᵀA z = Aᵀt, compiled:

1. start from the unconstrained solution clipped into the box; a variable that was clipped
   is *bound*, the others *free*;
2. solve for the free variables with the bound ones held; if that point leaves the box,
   move from the present (feasible) point toward it as far as the box allows, bind the
   variables that reach a bound, and solve again;
3. at the feasible minimiser over the free set, w = Aᵀ(t − A z) is minus the gradient; a
   bound variable whose w points into the box (w_j > 0 at its lower bound, < 0 at its
   upper) is freed — the one with the largest |w_j| — and step 2 runs again; none: optimal
   (the Karush–Kuhn–Tucker conditions hold).

Each pass of step 2 binds at least one variable, so it ends in at most n solves; the number of
freeing steps is capped at 3n + 4 (the solution is then the last feasible point: feasible,
not proven optimal). A must have full column rank (the brakes' A = D⁻¹T⁻ᵀ does).
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import kernel
from cpbc.kernels.small_solves import solve_lu


@kernel("void(float64[:, :], float64[:], float64[:], boolean[:], float64[:], int64[:])",
        inline=True)
def _free_solve(gram: Array, rhs: Array, z: Array, free: np.ndarray, y: Array,
                idx: np.ndarray) -> None:
    """The minimiser over the free variables (indices ``idx``) with the bound ones held at z:
    their rows of AᵀA z = Aᵀt, into y."""
    n, k = z.shape[0], idx.shape[0]
    sub = np.empty((k, k))
    b = np.empty(k)
    for p in range(k):
        i = idx[p]
        b[p] = rhs[i]
        for j in range(n):
            if not free[j]:
                b[p] -= gram[i, j] * z[j]
        for q in range(k):
            sub[p, q] = gram[i, idx[q]]
    solve_lu(sub, b, np.empty((k, k)), y)


@kernel("void(float64[:], float64[:], float64[:], boolean[:], float64[:], int64[:])",
        inline=True)
def _step_toward(lower: Array, upper: Array, z: Array, free: np.ndarray, y: Array,
                 idx: np.ndarray) -> None:
    """z moved toward y (free variables ``idx``) as far as the box allows, binding the
    variable that sets the step and any other the step carries onto a bound."""
    k = idx.shape[0]
    step, hit = 1.0, 0
    for p in range(k):
        i = idx[p]
        reach = 1.0
        if y[p] < lower[i]:
            reach = (lower[i] - z[i]) / (y[p] - z[i])
        elif y[p] > upper[i]:
            reach = (upper[i] - z[i]) / (y[p] - z[i])
        if reach < step:
            step, hit = reach, p
    step = max(step, 0.0)
    for p in range(k):
        i = idx[p]
        z[i] += step * (y[p] - z[i])
        at_lower = y[p] < lower[i] and z[i] <= lower[i] + 1e-14 * (1.0 + abs(lower[i]))
        at_upper = y[p] > upper[i] and z[i] >= upper[i] - 1e-14 * (1.0 + abs(upper[i]))
        if p == hit or at_lower or at_upper:
            z[i] = lower[i] if y[p] < lower[i] else upper[i]
            free[i] = False


@kernel("void(float64[:, :], float64[:], float64[:], float64[:], boolean[:], float64[:])",
        inline=True)
def _free_minimiser(gram: Array, rhs: Array, lower: Array, upper: Array, free: np.ndarray,
                    z: Array) -> None:
    """Step 2 of the module docstring: z (feasible, updated in place) moved to the minimiser
    over the free variables with the bound ones held, or as far toward it as the box allows,
    binding the variables that reach a bound, until the minimiser lies inside."""
    for _ in range(z.shape[0] + 1):
        idx = np.flatnonzero(free)
        if idx.shape[0] == 0:
            return
        y = np.empty(idx.shape[0])
        _free_solve(gram, rhs, z, free, y, idx)
        inside = True
        for p in range(idx.shape[0]):
            if not lower[idx[p]] <= y[p] <= upper[idx[p]]:
                inside = False
        if inside:
            for p in range(idx.shape[0]):
                z[idx[p]] = y[p]
            return
        _step_toward(lower, upper, z, free, y, idx)


@kernel("int64(float64[:, :], float64[:], float64[:], boolean[:], float64[:], float64)",
        inline=True)
def _most_downhill(gram: Array, rhs: Array, z: Array, free: np.ndarray, lower: Array,
                   scale: float) -> int:
    """Step 3: the bound variable whose w_j = (Aᵀ(t − A z))_j points furthest into the box
    (beyond ``scale``), or −1 when none does (optimal)."""
    n = z.shape[0]
    best, pick = scale, -1
    for j in range(n):
        if free[j]:
            continue
        w = rhs[j]
        for i in range(n):
            w -= gram[j, i] * z[i]
        into = w if z[j] <= lower[j] else -w  # > 0: the box lets z_j move downhill
        if into > best:
            best, pick = into, j
    return pick


@kernel("int64(float64[:, :], float64[:], float64[:], float64[:], float64[:])")
def bounded_least_squares(a: Array, target: Array, lower: Array, upper: Array,
                          out: Array) -> int:
    """z = argmin ‖a z − target‖ subject to lower ≤ z ≤ upper, into ``out`` (the module
    docstring); returns the number of freeing steps, or −1 when it stopped at their cap."""
    m, n = a.shape
    gram = np.zeros((n, n))
    rhs = np.zeros(n)
    for r in range(m):
        for i in range(n):
            rhs[i] += a[r, i] * target[r]
            for j in range(n):
                gram[i, j] += a[r, i] * a[r, j]
    z = np.empty(n)
    solve_lu(gram, rhs, np.empty((n, n)), z)  # step 1: unconstrained, then clipped
    free = np.ones(n, dtype=np.bool_)
    for j in range(n):
        if not lower[j] <= z[j] <= upper[j]:
            z[j], free[j] = (lower[j] if z[j] < lower[j] else upper[j]), False
    scale = 1e-12 * (np.abs(rhs).max() + 1e-300)
    for freed in range(3 * n + 4):
        _free_minimiser(gram, rhs, lower, upper, free, z)
        pick = _most_downhill(gram, rhs, z, free, lower, scale)
        if pick < 0:
            out[:] = z
            return freed
        free[pick] = True
    out[:] = z
    return -1
