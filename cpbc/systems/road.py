"""Prescribed road profiles r(t) and their velocities d(t) = ṙ(t) (§3.3.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cpbc.backstepping.barrier_terms import positive
from cpbc.errors import CpbcError


@dataclass(frozen=True)
class HaversineBump:
    """An isolated haversine bump of height A and length l driven over at speed v.

        r(t) = A/2·[1 − cos(2πv t/l)],   d(t) = (πvA/l)·sin(2πv t/l)   for 0 < t ≤ l/v,
        r = d = 0 otherwise.

    With l = 2 m and v = 25 m/s this is d = 12.5πA sin(25πt) on (0, 0.08] (§3.3.3).

    Args:
        height: A [m] (≥ 0; 0 is a flat road).
        length: l [m].
        speed: v [m/s].
    """

    height: float
    length: float = 2.0
    speed: float = 25.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.height) or self.height < 0.0:
            raise CpbcError(f"bump height must be finite and >= 0, not {self.height}")
        object.__setattr__(self, "length", positive("length", self.length))
        object.__setattr__(self, "speed", positive("speed", self.speed))

    @property
    def duration(self) -> float:
        """l/v [s]."""
        return self.length / self.speed

    def height_at(self, t: float) -> float:
        """r(t) [m]."""
        if not 0.0 < t <= self.duration:
            return 0.0
        return 0.5 * self.height * (1.0 - math.cos(2.0 * math.pi * t / self.duration))

    def velocity_at(self, t: float) -> float:
        """d(t) = ṙ(t) [m/s]."""
        if not 0.0 < t <= self.duration:
            return 0.0
        w = 2.0 * math.pi / self.duration
        return 0.5 * self.height * w * math.sin(w * t)
