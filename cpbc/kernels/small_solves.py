"""A small dense solve inside the kernels (the laws' (D + ρΠ) y = a − c), and the product
and the NaN-keeping minimum and maximum the guard's kernels share."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import inner, kernel


@kernel("void(float64[:, :], float64[:], float64[:, :], float64[:])")
def solve_lu(a: Array, b: Array, work: Array, y: Array) -> None:
    """y = a⁻¹ b by Gaussian elimination with partial pivoting (``work`` holds the factors)."""
    n = b.shape[0]
    for i in range(n):
        y[i] = b[i]
        for j in range(n):
            work[i, j] = a[i, j]
    for col in range(n):
        p = col
        for i in range(col + 1, n):
            if abs(work[i, col]) > abs(work[p, col]):
                p = i
        if p != col:
            for j in range(n):
                work[col, j], work[p, j] = work[p, j], work[col, j]
            y[col], y[p] = y[p], y[col]
        for i in range(col + 1, n):
            f = work[i, col] / work[col, col]
            for j in range(col, n):
                work[i, j] -= f * work[col, j]
            y[i] -= f * y[col]
    for i in range(n - 1, -1, -1):
        t = y[i]
        for j in range(i + 1, n):
            t -= work[i, j] * y[j]
        y[i] = t / work[i, i]


@inner("boolean(float64[:, :], float64[:, :])")
def cholesky(a: Array, work: Array) -> bool:
    """a = L Lᵀ, L into ``work`` (n, n) for a symmetric positive definite a; False (``work``
    partly written) where a is not numerically positive definite."""
    n = a.shape[0]
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= work[j, k] * work[j, k]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        work[j, j] = d
        for i in range(j + 1, n):
            t = a[i, j]
            for k in range(j):
                t -= work[i, k] * work[j, k]
            work[i, j] = t / d
    return True


@inner("void(float64[:, :], float64[:], float64[:])")
def cholesky_solve(factor: Array, b: Array, y: Array) -> None:
    """y = (L Lᵀ)⁻¹ b from the factor L that :func:`cholesky` left in ``factor``."""
    n = b.shape[0]
    for i in range(n):  # L z = b
        t = b[i]
        for k in range(i):
            t -= factor[i, k] * y[k]
        y[i] = t / factor[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ y = z
        t = y[i]
        for k in range(i + 1, n):
            t -= factor[k, i] * y[k]
        y[i] = t / factor[i, i]


@kernel("void(float64[:, :], float64[:], float64[:, :], float64[:])", inline=True)
def solve_spd(a: Array, b: Array, work: Array, y: Array) -> None:
    """y = a⁻¹ b for a symmetric positive definite a, by Cholesky a = L Lᵀ (L in ``work``,
    shape (n, n)); by Gaussian elimination with partial pivoting when a is not numerically
    positive definite. ``a`` and ``b`` are left as they are."""
    if cholesky(a, work):
        cholesky_solve(work, b, y)
    else:
        solve_lu(a, b, work, y)


@kernel("void(float64[:, :], float64[:, :])")
def inverse_spd(a: Array, out: Array) -> None:
    """a⁻¹ into ``out``, column by column (``solve_spd``'s steps: a factored once by
    Cholesky for every column, else Gaussian elimination for each): for the places that
    need the whole inverse of D (the friction's error bound reads |D⁻¹|, the reach of a
    torque into a box by its acceleration), where numpy's inv costs 10 µs a call on a
    7-joint arm."""
    n = a.shape[0]
    work = np.empty((n, n))
    e = np.zeros(n)
    col = np.empty(n)
    spd = cholesky(a, work)
    for j in range(n):
        e[j] = 1.0
        if spd:
            cholesky_solve(work, e, col)
        else:  # the factor is not read again: its buffer holds the elimination's
            solve_lu(a, e, work, col)
        e[j] = 0.0
        for i in range(n):
            out[i, j] = col[i]


def inverse_inertia(inertia: Array) -> Array:
    """D⁻¹ (:func:`inverse_spd`) as a fresh array: once a step for every reader in Python
    that needs the whole inverse (the error bounds; the kernels that reach a torque into a
    box by its acceleration make theirs, cpbc.kernels.torque_box.acceleration_map), where
    numpy's inv costs 10 µs a call on a 7-joint arm and this 2."""
    inv = np.empty_like(inertia, dtype=float)
    inverse_spd(np.ascontiguousarray(inertia, dtype=float), inv)
    return inv


@kernel("float64(float64, float64)")
def nan_min(low: float, value: float) -> float:
    """The smaller of two, NaN if either is (numpy's min over an array)."""
    if value != value or low != low:
        return math.nan
    return value if value < low else low


@kernel("float64(float64, float64)")
def nan_max(high: float, value: float) -> float:
    """The larger of two, NaN if either is (numpy's maximum)."""
    if value != value or high != high:
        return math.nan
    return value if value > high else high


@kernel("float64[:](float64[:, :], float64[:])")
def times(a: Array, v: Array) -> Array:
    """a v, row by row (numba's dot would load SciPy's BLAS)."""
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        t = 0.0
        for j in range(v.shape[0]):
            t += a[i, j] * v[j]
        out[i] = t
    return out
