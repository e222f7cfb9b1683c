"""cpbc.kernels.small_solves: the small dense solves the compiled paths share."""

from __future__ import annotations

import numpy as np

from cpbc.kernels.small_solves import inverse_spd, solve_spd


def test_the_inverse_is_each_column_s_solve_to_the_bit() -> None:
    """``inverse_spd`` factors a once for all its columns: each column is ``solve_spd``'s
    answer for that unit vector to the bit, on 200 symmetric positive definite matrices
    (Cholesky) and 200 indefinite ones (Gaussian elimination), 2 to 7 rows; and on the
    positive definite ones it is numpy's inverse to rounding."""
    rng = np.random.default_rng(5)
    for case in range(400):
        n = int(rng.integers(2, 8))
        a = rng.normal(size=(n, n))
        a = a @ a.T + 0.1 * np.eye(n) if case % 2 == 0 else a + a.T
        found = np.empty((n, n))
        inverse_spd(a, found)
        work, e, col = np.empty((n, n)), np.zeros(n), np.empty(n)
        for j in range(n):
            e[j] = 1.0
            solve_spd(a, e, work, col)
            e[j] = 0.0
            np.testing.assert_array_equal(found[:, j], col)
        if case % 2 == 0:
            np.testing.assert_allclose(found, np.linalg.inv(a), rtol=1e-9, atol=1e-9)
