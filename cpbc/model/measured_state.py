"""The state a caller hands a law, as the compiled kernels take it, or an error naming it.

A law's step runs compiled kernels that take float64 vectors only: a list, a float32 array
from a policy or an int array stopped them with numba's own TypeError, and a vector of the
wrong length with Pinocchio's. The usual call — float64 vectors of the arm's length — passes
one type check (about 0.17 µs). A NaN or an infinity is looked for in the torque, not in
the state (one sum of τ, about 0.15 µs, where products of x and ẋ cost 0.57 µs, a tenth of
a bare Panda step): a state that is not finite makes a torque that is not, and then
:func:`refuse_non_finite` names the argument (NonFiniteState, a ValueError and a
ConstraintViolation). Found before: a law without velocity constraints returned a NaN
torque for a NaN velocity, and its guard under a torque-rate limit a finite ramp of ρh on
every joint, counted as acting, with its held torque moved. The simulation loops end a run
whose state is not finite as diverged before they ask the law.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import NonFiniteState, ParameterError

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
        x, dx = numbers(x, n, "x", _MEANING["x"]), numbers(dx, n, "dx", _MEANING["dx"])
    return x, dx


def numbers(value: object, size: int, name: str, meaning: str, copy: bool = False) -> Array:
    """``value`` as a float64 vector of ``size`` numbers (a new array with ``copy``, else
    ``value`` itself when it is one); ``meaning`` says what they are in the message when it
    is not (cpbc.reference.stream_checks adds that they be finite)."""
    try:
        found = np.array(value, dtype=float) if copy else np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(name, f"{name} must be {size} finite numbers ({meaning}), got "
                                   f"{value!r}") from None
    if found.shape != (size,):
        raise ParameterError(name, f"{name} must be {size} finite numbers ({meaning}), got "
                                   f"shape {found.shape}")
    return found


def finite_vector(value: object, size: int, name: str, meaning: str) -> Array:
    """``value`` as a new float64 vector of ``size`` finite numbers, or a ParameterError
    naming ``name`` (``meaning`` says what they are: units, frame): what builds or steers a
    law takes (a target, a held torque, a streamed target, a policy's action)."""
    found = numbers(value, size, name, meaning, copy=True)
    total = sum(found.tolist())  # NaN or ±∞ only from a NaN or ∞ (or a sum past 1e308)
    said = None if total - total == 0.0 else _not_finite(found, name, meaning)
    if said is not None:
        raise ParameterError(name, said)
    return found


def refuse_non_finite(tau: Array, x: Array, dx: Array) -> None:
    """Raise NonFiniteState naming ``x`` or ``dx`` when the torque ``tau`` is not finite
    because the state is not (a torque that is not finite at a finite state is the law's to
    answer for, and passes here)."""
    total = sum(tau.tolist())  # NaN or ±∞ only from a NaN or ∞ (or a sum past 1e308)
    if total - total == 0.0:  # half a dot product's time
        return
    found = not_finite(x, dx)
    if found is not None:
        raise found


def not_finite(x: Array, dx: Array) -> NonFiniteState | None:
    """The error that names the first of ``x``, ``dx`` that is not finite, or None."""
    for name, value in (("x", x), ("dx", dx)):
        said = _not_finite(value, name, _MEANING[name])
        if said is not None:
            return NonFiniteState(name, said)
    return None


def _not_finite(value: Array, name: str, meaning: str) -> str | None:
    """What is wrong with ``value`` when an entry is not finite (the first), else None."""
    bad = np.flatnonzero(~np.isfinite(value))
    if not bad.size:
        return None
    return (f"{name} must be {len(value)} finite numbers ({meaning}), got {value[bad[0]]} at "
            f"index {bad[0]}")
