"""Joint velocity limits that depend on the joint's position: a robot maker's bound that
falls to 0 toward each end of a joint's range, so that the joint can stop before it.

Franka's FR3 publishes one (FCI documentation, "Limits for Franka Research 3"; libfranka's
``rate_limiting.h``, ``computeUpperLimitsJointVelocity`` and its lower twin): per joint i,

    q̇ ≤ U_i(q_i) = min(v_i, max(0, −c_i + √(k_i (a⁺_i − q_i)))) − ε,
    q̇ ≥ L_i(q_i) = −min(v_i, max(0, −c_i + √(k_i (q_i − a⁻_i)))) + ε,

with ε = 10⁻³ rad/s (libfranka's tolerance with no packet lost budgeted). cpbc's rate
constraint has constant bounds |q̇_i| < B_i; :meth:`PositionDependentVelocity.constant_bound`
gives the largest B_i that lies inside both curves on a joint range, and
:meth:`~PositionDependentVelocity.range_for` the range on which a bound does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cpbc.arrays import Array
from cpbc.errors import ParameterError


def _per_joint(value: ArrayLike, name: str, n: int | None) -> Array:
    a = np.array(value, dtype=float)
    if a.ndim != 1 or (n is not None and a.size != n) or not np.all(np.isfinite(a)):
        raise ParameterError(name, f"needs one finite number per joint, got {value!r}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class PositionDependentVelocity:
    """U_i and L_i of the module's formula, per joint.

    Attributes:
        peak: v_i, the bound away from the ends [rad/s].
        offset: c_i [rad/s].
        gain: k_i [rad/s²]: twice the deceleration the bound assumes.
        upper_end, lower_end: a⁺_i and a⁻_i [rad], where the bound toward that end is
            −c_i + √0 < 0, clipped to 0.
        tolerance: ε [rad/s], taken off both bounds.
    """

    peak: Array
    offset: Array
    gain: Array
    upper_end: Array
    lower_end: Array
    tolerance: float = 1e-3

    def __post_init__(self) -> None:
        n = np.size(self.peak)
        for name in ("peak", "offset", "gain", "upper_end", "lower_end"):
            object.__setattr__(self, name, _per_joint(getattr(self, name), name, n))
        if not (np.all(self.peak > 0) and np.all(self.gain > 0) and np.all(self.offset >= 0)):
            raise ParameterError("peak", "peak and gain must be > 0 and offset ≥ 0 per joint")
        if not np.all(self.lower_end < self.upper_end):
            raise ParameterError("lower_end", "each joint's lower end must lie below its upper")
        if not (np.isfinite(self.tolerance) and self.tolerance >= 0):
            raise ParameterError("tolerance", f"must be a number ≥ 0, got {self.tolerance}")

    @property
    def n(self) -> int:
        return int(self.peak.size)

    def _toward(self, room: Array) -> Array:
        """The speed allowed toward an end ``room`` radians away (before ε)."""
        root = np.sqrt(self.gain * np.maximum(room, 0.0))
        return np.minimum(self.peak, np.maximum(0.0, root - self.offset))

    def upper(self, q: ArrayLike) -> Array:
        """U(q): the largest velocity allowed at q [rad/s], shape like q (…, n)."""
        return self._toward(self.upper_end - np.asarray(q, dtype=float)) - self.tolerance

    def lower(self, q: ArrayLike) -> Array:
        """L(q): the smallest (most negative) velocity allowed at q [rad/s]."""
        return self.tolerance - self._toward(np.asarray(q, dtype=float) - self.lower_end)

    def constant_bound(self, lower: ArrayLike, upper: ArrayLike) -> Array:
        """The largest B_i with L_i(q) ≤ −B_i and B_i ≤ U_i(q) for every q in
        [lower_i, upper_i] (0 where none is positive).

        U_i decreases as q_i grows (the room a⁺ − q shrinks, √ and min are monotone) and
        L_i increases, so on the range U_i is smallest at its upper end and −L_i at its
        lower end: B_i = min(U_i(upper_i), −L_i(lower_i)).
        """
        lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        return np.maximum(0.0, np.minimum(self.upper(hi), -self.lower(lo)))

    def range_for(self, bound: ArrayLike) -> tuple[Array, Array]:
        """The widest joint range on which a constant bound B_i holds (the inverse of
        :meth:`constant_bound` for B_i < v_i − ε): −c + √(k d) − ε ≥ B needs the room
        d ≥ (B + ε + c)² / k from each end."""
        room = (np.asarray(bound, dtype=float) + self.tolerance + self.offset) ** 2 / self.gain
        return self.lower_end + room, self.upper_end - room
