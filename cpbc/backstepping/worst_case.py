"""Worst cases of bounded functions over x ∈ ℝⁿ and a box of other coordinates.

The bounds of Chapter 4 ((4.19), (4.38), (4.88)) are suprema of |α_i| or of |ξ_i − z_i| over all x
and over a box of errors or states. They are found here by evaluating the function on a grid
(the system's x samples, which cover ℝⁿ, times a uniform grid of the box, ends included) and
then climbing from the best grid points with a bounded quasi-Newton search. The result is the
largest value *found*: a lower estimate of the true supremum that converges with the grid.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from cpbc.arrays import Array

#: fun(x columns, box coordinates) evaluated elementwise on arrays of one shape
GridFunction = Callable[[list[Array], list[Array]], Array]


@dataclass(frozen=True)
class Sup:
    """sup |fun| found, and where.

    Attributes:
        value: the largest |fun| found.
        x: the x where it was found.
        point: the box coordinates where it was found.
    """

    value: float
    x: tuple[float, ...]
    point: tuple[float, ...]


def grid_sup(
    fun: GridFunction, x_samples: Array, half_widths: Sequence[float], points: int = 21,
    budget: int = 400_000, refine: int = 3,
) -> Sup:
    """sup over x ∈ samples and |v_j| ≤ half_widths_j of |fun(x, v)|, grid then local climb.

    Args:
        fun: the function, vectorised.
        x_samples: (N, n) points of x; thinned evenly if the grid would exceed ``budget``.
        half_widths: the box.
        points: grid points per box coordinate (odd, so that 0 is on the grid).
        budget: the largest number of grid evaluations.
        refine: how many of the best grid points to climb from (0: grid only).
    """
    xs = np.asarray(x_samples, dtype=float)
    k = len(half_widths)
    per_x = points**k
    if len(xs) * per_x > budget:
        xs = xs[np.linspace(0, len(xs) - 1, max(budget // per_x, 1)).round().astype(int)]
    axes = [np.linspace(-h, h, points) for h in half_widths]
    mesh = np.meshgrid(np.arange(len(xs)), *axes, indexing="ij")
    rows = mesh[0].ravel()
    xcols = [xs[rows, j] for j in range(xs.shape[1])]
    vcols = [np.asarray(g.ravel(), dtype=float) for g in mesh[1:]]
    vals = np.abs(np.broadcast_to(fun(xcols, vcols), rows.shape))
    order = np.argsort(vals)[::-1]
    best = _at(vals, order[0], xcols, vcols)
    n = xs.shape[1]
    for idx in order[:refine]:
        start = np.array([*(c[idx] for c in xcols), *(c[idx] for c in vcols)])
        res = minimize(
            lambda p: -abs(float(fun([np.array([p[j]]) for j in range(n)],
                                     [np.array([p[n + j]]) for j in range(k)])[0])),
            start, method="L-BFGS-B",
            bounds=[(None, None)] * n + [(-h, h) for h in half_widths],
        )
        if -res.fun > best.value and np.all(np.isfinite(res.x)):
            best = Sup(float(-res.fun), tuple(float(v) for v in res.x[:n]),
                       tuple(float(v) for v in res.x[n:]))
    return best


def _at(vals: Array, idx: int, xcols: list[Array], vcols: list[Array]) -> Sup:
    return Sup(float(vals[idx]), tuple(float(c[idx]) for c in xcols),
               tuple(float(c[idx]) for c in vcols))
