"""The state a caller hands a law, as the compiled kernels take it, or an error naming it.

A law's step runs compiled kernels that take float64 vectors only: a list, a float32 array
from a policy or an int array stopped them with numba's own TypeError, a vector of the wrong
length with Pinocchio's, and a NaN gave PD + g a NaN torque and the safeguard a "crossed its
boundary (margin nan)" that blamed a constraint. The usual call — float64 vectors of the
arm's length — passes one type check and one dot product (about 0.3 µs).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ParameterError

FLOAT = np.dtype(float)


def measured(x: Array, dx: Array, n: int) -> tuple[Array, Array]:
    """(x, ẋ) as float64 vectors of ``n`` coordinates (the arrays themselves when they
    already are).

    Raises:
        ParameterError: ``x`` or ``dx`` is not ``n`` numbers, or not finite.
    """
    if not (type(x) is np.ndarray and type(dx) is np.ndarray and x.dtype is FLOAT
            and dx.dtype is FLOAT and x.shape == (n,) and dx.shape == (n,)):
        x, dx = _vector(x, "x", n), _vector(dx, "dx", n)
    if not math.isfinite(x.dot(x) + dx.dot(dx)):  # one NaN or inf (or an overflow) in either
        for name, v in (("x", x), ("dx", dx)):
            if not np.isfinite(v).all():
                raise ParameterError(name, f"{name}: every coordinate must be finite, got "
                                           f"{np.array2string(v, precision=4)}")
    return x, dx


def _vector(v: object, name: str, n: int) -> Array:
    """``v`` as a float64 vector of ``n`` numbers."""
    what = "the configuration" if name == "x" else "the velocity"
    try:
        found = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(name, f"{name}: give {what} as {n} numbers, got "
                                   f"{type(v).__name__} {v!r:.60}") from None
    if found.shape != (n,):
        raise ParameterError(name, f"{name}: give {what} as {n} numbers (one per "
                                   f"coordinate), got shape {found.shape}")
    return found
