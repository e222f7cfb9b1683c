"""The one array type of the package: float64 NumPy arrays (shapes are in each docstring)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

__all__ = ["Array", "ArrayLike", "unfinite_rows"]  # ArrayLike: what constructors accept


def unfinite_rows(xs: Array, dxs: Array) -> NDArray[np.bool_] | None:
    """The rows where (x, ẋ) is not finite, or None where every row is: one sum of each
    tells the usual case (NaN or ±inf where an entry is, or where the sum overflows)
    without a mask."""
    total = float(xs.sum()) + float(dxs.sum())
    if total - total == 0.0:
        return None
    return ~(np.all(np.isfinite(xs), axis=1) & np.all(np.isfinite(dxs), axis=1))
