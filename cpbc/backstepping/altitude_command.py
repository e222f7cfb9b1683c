"""A piecewise-constant altitude command h_d(t) and the law that tracks it, u = k(x, t).

Both Chapter 5 laws regulate to a constant h_d; the thesis's scenarios step h_d at given times
(Figs 5.1–5.8). Each step re-initialises z1 = h − h_d, and for the constrained law that can put
z2 = v_z + c1 tanh(h − h_d) outside the barrier's domain |z2| < k2 although the state itself
satisfies Theorem 5.5's "|v_z| < B" (e.g. v_z = 3.4 m/s, h − h_d = +100 m gives z2 = 4.9).
The theorem needs the check it does not state: a command is admissible at the state where it
arrives only if |z2| < k2 there. :class:`TrackingLaw` refuses an inadmissible command at the
instant it arrives by raising :class:`OutsideDomainError` on the variable ``h_d`` (the run stops
and says so) rather than evaluating the barrier outside its domain; a later |z2| ≥ k2 is a
barrier crossing of the flight (e.g. under elevator saturation) and is reported as ``z2``.
(A command issued in level flight, |v_z| < k2 − c1, is always admissible.)
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from cpbc.backstepping.altitude_law import AltitudeLaw
from cpbc.backstepping.design_errors import OutsideDomainError


@dataclass(frozen=True)
class AltitudeCommand:
    """h_d(t): ``initial`` [m] until the first step, then each (time [s], altitude [m]) of
    ``steps`` from its time on (times strictly increasing)."""

    initial: float
    steps: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        times = [t for t, _ in self.steps]
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError(f"command times must increase strictly, got {times}")
        if not all(math.isfinite(v) for v in (self.initial, *times,
                                               *(h for _, h in self.steps))):
            raise ValueError("command times and altitudes must be finite")

    @property
    def times(self) -> tuple[float, ...]:
        return tuple(t for t, _ in self.steps)

    def index(self, t: float) -> int:
        """How many steps have arrived by time t (a step is active from its time on)."""
        return bisect.bisect_right(self.times, t)

    def at(self, t: float) -> float:
        """h_d(t) [m]."""
        i = self.index(t)
        return self.initial if i == 0 else self.steps[i - 1][1]


@dataclass(frozen=True)
class TrackingLaw:
    """δ_E = k(x, h_d(t)) [rad]: an altitude law following a command schedule."""

    law: AltitudeLaw
    command: AltitudeCommand

    def __call__(self, x: Sequence[float], t: float = 0.0) -> float:
        hd = self.command.at(t)
        i = self.command.index(t)
        arriving = i > 0 and t == self.command.steps[i - 1][0]
        lo, hi = self.law.command_interval(x)
        if arriving and not lo < hd < hi:
            # at the instant the command arrives (both loops evaluate the law exactly there:
            # the reference integrates piecewise at the command times): the command itself is
            # inadmissible, not a barrier crossing of the flight
            raise OutsideDomainError(
                "h_d", hd, lo, hi,
                f"the altitude command h_d = {hd:.6g} m at t = {t:.6g} s is inadmissible at "
                f"h = {x[0]:.6g} m, v_z = {x[1]:.6g} m/s (Theorem 5.5 needs |v_z + c1 "
                "tanh(h − h_d)| < k2 when a command arrives); refused")
        return self.law.elevator(x, hd)
