"""What a policy streams, checked before it is used: a streamed target (a point, a joint
vector) and its velocity, the control period and the state the tracker is asked at. A value
that fails raises :class:`~cpbc.errors.ParameterError` (a ``ValueError``) naming the argument
and what it must be, and nothing is written: the previous target stays in force."""

from __future__ import annotations

import math

from cpbc.arrays import Array
from cpbc.errors import ParameterError
from cpbc.model.measured_state import finite_vector


def positive_period(period: object) -> float:
    """The control period h [s] as a finite float > 0."""
    try:
        h = float(period)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        h = math.nan
    if not (math.isfinite(h) and h > 0):
        raise ParameterError("period", "period must be the control period in seconds, a "
                                       f"finite number > 0, got {period!r}")
    return h


def state_vector(value: Array, size: int, name: str) -> Array:
    """A joint state the tracker is asked at: ``value`` itself when it is an array of ``size``
    finite numbers (one dot product checks finiteness on the hot path), else the checked
    copy; raises when it cannot be."""
    if getattr(value, "shape", None) == (size,) and math.isfinite(float(value @ value)):
        return value
    meaning = "joint positions [rad or m]" if name == "x" else "joint velocities"
    return finite_vector(value, size, name, meaning)
