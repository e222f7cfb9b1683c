"""Views of one flat array as a row-major table, inside the kernels: a kernel keeps its
tables, and its per-step work arrays, in one array each and reads them through these (an
allocation costs numba about 20 ns, a strided view nothing)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from cpbc.arrays import Array
from cpbc.kernels import inner

Ints = NDArray[np.int64]  # the index tables


@inner("int64[:, :](int64[::1], int64, int64, int64)")
def int_rows(flat: Ints, start: int, rows: int, columns: int) -> Ints:
    """flat[start : start + rows·columns] as a (rows, columns) view, row-major (numba's
    reshape calls out to C, about 16 ns; a strided view costs nothing)."""
    return np.lib.stride_tricks.as_strided(flat[start:], shape=(rows, columns),
                                           strides=(columns * flat.itemsize, flat.itemsize))


@inner("float64[:, :](float64[::1], int64, int64, int64)")
def float_rows(flat: Array, start: int, rows: int, columns: int) -> Array:
    """``int_rows`` of a float array."""
    return np.lib.stride_tricks.as_strided(flat[start:], shape=(rows, columns),
                                           strides=(columns * flat.itemsize, flat.itemsize))
