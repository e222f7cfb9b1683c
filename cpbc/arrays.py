"""The one array type of the package: float64 NumPy arrays (shapes are in each docstring)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

__all__ = ["Array", "ArrayLike"]  # ArrayLike: what constructors accept and convert
