"""Paths of a frame's point with their nominal timing: p(s) and dp/ds over the path
parameter s [s], which equals time when the path is followed at its nominal speed.

    waypoints   p through P_k at times t_k, per segment τ = (s − t_k)/(t_{k+1} − t_k):
                  linear     p = P_k + τ ΔP                                   (ΔP = P_{k+1} − P_k)
                  min_jerk   p = P_k + (10τ³ − 15τ⁴ + 6τ⁵) ΔP      (rest at every waypoint)
                  cubic      the C² cubic spline through every P_k, at rest at both ends
    circle      p = c + r (cos θ u + sin θ w),  θ = θ₀ + (v/r) s,  w = n × u
    lissajous   p_i = c_i + A_i sin(2π f_i s / T + φ_i)
    csv         linear between the rows (t, x, y, z) of a file (cpbc.reference.csv_path)

Every path holds its last point for s beyond its duration (dp/ds = 0 there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ParameterError

INTERPOLATIONS = ("linear", "cubic", "min_jerk")


class Path(Protocol):
    """p(s) and dp/ds, vectorised over s (shape (m,) → (m, 3))."""

    @property
    def duration(self) -> float:
        """The nominal duration [s]."""
        ...

    def sample(self, s: Array) -> tuple[Array, Array]:
        """p(s) [m] and dp/ds [m/s], each (m, 3)."""
        ...


def _clip(s: Array, duration: float) -> tuple[Array, Array]:
    s = np.asarray(s, dtype=float)
    return np.clip(s, 0.0, duration), ((s >= 0.0) & (s <= duration)).astype(float)


@dataclass(frozen=True)
class Waypoints:
    """Through ``points`` (k, 3) at strictly increasing ``times`` (k,), the first 0."""

    times: Array
    points: Array
    interpolation: str = "min_jerk"

    def __post_init__(self) -> None:
        t, p = np.asarray(self.times, float), np.asarray(self.points, float)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2 or t.shape != (len(p),):
            raise ParameterError("waypoints", "need at least 2 waypoints, each a time and "
                                 "3 coordinates")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise ParameterError("waypoints", "times and positions must be finite")
        if t[0] != 0.0 or np.any(np.diff(t) <= 0):
            raise ParameterError("waypoints", f"times must start at 0 and increase strictly, "
                                 f"got {t.tolist()}")
        if self.interpolation not in INTERPOLATIONS:
            raise ParameterError("interpolation", f"one of {', '.join(INTERPOLATIONS)}, got "
                                 f"{self.interpolation!r}")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "points", p)

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, s: Array) -> tuple[Array, Array]:
        s, inside = _clip(s, self.duration)
        if self.interpolation == "cubic":
            from scipy.interpolate import CubicSpline

            spline = CubicSpline(self.times, self.points, bc_type="clamped")
            return spline(s), spline(s, 1) * inside[:, None]
        k = np.clip(np.searchsorted(self.times, s, side="right") - 1, 0, len(self.times) - 2)
        span = self.times[k + 1] - self.times[k]
        tau = (s - self.times[k]) / span
        if self.interpolation == "linear":
            blend, rate = tau, np.ones_like(tau)
        else:
            blend = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
            rate = 30.0 * tau**2 * (1.0 - tau) ** 2
        delta = self.points[k + 1] - self.points[k]
        p = self.points[k] + blend[:, None] * delta
        return p, (rate / span * inside)[:, None] * delta


def _unit(v: object, name: str) -> Array:
    a = np.asarray(v, dtype=float)
    norm = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
    if not norm > 1e-12 or not math.isfinite(norm):
        raise ParameterError(name, f"{name} must be a nonzero direction of 3 numbers")
    return a / norm


@dataclass(frozen=True)
class Circle:
    """A circle of ``radius`` about ``centre`` in the plane normal to ``normal``, at
    ``speed`` [m/s] for ``laps``, starting at the angle ``phase`` from ``start_axis``
    (projected into the plane; default: the world axis least aligned with the normal)."""

    centre: Array
    radius: float
    normal: Array
    speed: float
    laps: float = 1.0
    phase: float = 0.0
    start_axis: Array | None = None

    def __post_init__(self) -> None:
        for name in ("radius", "speed", "laps"):
            value = float(getattr(self, name))
            if not value > 0 or not math.isfinite(value):
                raise ParameterError(name, f"{name} must be > 0, got {value}")
        n = _unit(self.normal, "normal")
        guess = np.eye(3)[int(np.argmin(np.abs(n)))] if self.start_axis is None else (
            _unit(self.start_axis, "start_axis"))
        u = guess - (guess @ n) * n
        if np.linalg.norm(u) < 1e-9:
            raise ParameterError("start_axis", "start_axis must not be along the normal")
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "start_axis", u / np.linalg.norm(u))
        object.__setattr__(self, "centre", np.asarray(self.centre, dtype=float))

    @property
    def duration(self) -> float:
        return self.laps * 2.0 * math.pi * self.radius / self.speed

    def sample(self, s: Array) -> tuple[Array, Array]:
        s, inside = _clip(s, self.duration)
        u = np.asarray(self.start_axis)
        w = np.cross(self.normal, u)
        omega = self.speed / self.radius
        theta = self.phase + omega * s
        c, sn = np.cos(theta)[:, None], np.sin(theta)[:, None]
        p = self.centre + self.radius * (c * u + sn * w)
        dp = (self.speed * inside)[:, None] * (-sn * u + c * w)
        return p, dp


@dataclass(frozen=True)
class Lissajous:
    """p_i = c_i + A_i sin(2π f_i s/T + φ_i) for ``laps`` periods T (a figure-8: f = (1, 2, 0))."""

    centre: Array
    amplitude: Array
    frequency: Array
    period: float
    phase: Array | None = None
    laps: float = 1.0

    def __post_init__(self) -> None:
        for name in ("centre", "amplitude", "frequency"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ParameterError(name, f"{name} must be 3 finite numbers")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "phase", np.zeros(3) if self.phase is None else np.asarray(
            self.phase, dtype=float))
        if not self.period > 0 or not self.laps > 0:
            raise ParameterError("period", "period and laps must be > 0")

    @property
    def duration(self) -> float:
        return self.laps * self.period

    def sample(self, s: Array) -> tuple[Array, Array]:
        s, inside = _clip(s, self.duration)
        omega = 2.0 * math.pi * np.asarray(self.frequency) / self.period
        arg = s[:, None] * omega + np.asarray(self.phase)
        amp = np.asarray(self.amplitude)
        return self.centre + amp * np.sin(arg), inside[:, None] * amp * omega * np.cos(arg)


@dataclass(frozen=True)
class Polyline:
    """Linear between samples (times (k,), points (k, 3)): a CSV reference."""

    times: Array
    points: Array

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, s: Array) -> tuple[Array, Array]:
        return Waypoints(self.times, self.points, "linear").sample(s)


@dataclass(frozen=True)
class Scaled:
    """``path`` run ``factor`` times faster: p(s) = q(k s), dp/ds = k dq/ds(k s)."""

    path: Path
    factor: float

    def __post_init__(self) -> None:
        if not self.factor > 0 or not math.isfinite(self.factor):
            raise ParameterError("speed", f"a speed factor must be > 0, got {self.factor}")

    @property
    def duration(self) -> float:
        return self.path.duration / self.factor

    def sample(self, s: Array) -> tuple[Array, Array]:
        p, dp = self.path.sample(np.asarray(s, dtype=float) * self.factor)
        return p, dp * self.factor
