"""The one array type of the package: float64 NumPy arrays (shapes are in each docstring)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
