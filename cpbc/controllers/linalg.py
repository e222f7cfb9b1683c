"""Small dense solves for the hot path."""

from __future__ import annotations

from typing import cast

import numpy as np
from scipy.linalg import lapack

from cpbc.arrays import Array


def solve_spd(a: Array, b: Array) -> Array:
    """Solve a y = b for symmetric positive definite a by Cholesky (LAPACK dposv).

    Called directly because numpy.linalg.solve costs ~10 µs of overhead for a 2×2 system here.
    Falls back to LU if a is not numerically positive definite.
    """
    _, y, info = lapack.dposv(a, b)
    if info != 0:
        return cast(Array, np.linalg.solve(a, b))
    return cast(Array, y)
