"""The state a caller hands a law, as the compiled kernels take it, or an error naming it.

A law's step runs compiled kernels that take float64 vectors only: a list, a float32 array
from a policy or an int array stopped them with numba's own TypeError, and a vector of the
wrong length with Pinocchio's. The usual call — float64 vectors of the arm's length — passes
one type check (about 0.17 µs). A NaN or an infinity is not looked for in the state on every
call (two dot products cost 0.57 µs, a tenth of a bare Panda step): it makes the law's V (or
a margin) NaN or infinite, which the law's caller reads anyway, and then asks :func:`finite`
which argument it was. (PD + g's ``torque``, which computes no V, returns NaN for it.)
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ParameterError

FLOAT = np.dtype(float)
# what x and dx are, in the messages (the words of cpbc.reference.stream_checks)
_MEANING = {"x": "the configuration, one per coordinate",
            "dx": "the velocity, one per coordinate"}


def measured(x: Array, dx: Array, n: int) -> tuple[Array, Array]:
    """(x, ẋ) as float64 vectors of ``n`` coordinates (the arrays themselves when they
    already are).

    Raises:
        ParameterError: ``x`` or ``dx`` is not ``n`` numbers.
    """
    if not (type(x) is np.ndarray and type(dx) is np.ndarray and x.dtype is FLOAT
            and dx.dtype is FLOAT and x.shape == (n,) and dx.shape == (n,)):
        x, dx = _vector(x, "x", n), _vector(dx, "dx", n)
    return x, dx


def finite(x: Array, dx: Array) -> None:
    """Raises ParameterError naming ``x`` or ``dx`` where one holds a NaN or an infinity."""
    for name, v in (("x", x), ("dx", dx)):
        if not np.isfinite(v).all():
            raise ParameterError(name, f"{name} must be {len(v)} finite numbers "
                                       f"({_MEANING[name]}), got {np.asarray(v).tolist()}")


def _vector(v: object, name: str, n: int) -> Array:
    """``v`` as a float64 vector of ``n`` numbers."""
    try:
        found = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(name, f"{name} must be {n} finite numbers ({_MEANING[name]}), "
                                   f"got {type(v).__name__} {v!r:.60}") from None
    if found.shape != (n,):
        raise ParameterError(name, f"{name} must be {n} finite numbers ({_MEANING[name]}), "
                                   f"got shape {found.shape}")
    return found
