"""Shared oracles for the Part-I tests: finite differences of a cascade's rates, and the
closed loop of a barrier law in its cascade coordinates (x, ξ)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from cpbc.backstepping import Cascade, Rated
from cpbc.simulation.trajectory import SystemTrajectory
from cpbc.systems import Plant

State = tuple[float, ...]


class CascadeLaw(Protocol):
    @property
    def cascade(self) -> Cascade: ...

    def control(self, x: State, xi: State) -> float: ...
    def lyapunov(self, x: State, xi: State) -> float: ...


def split(s: Sequence[float] | np.ndarray, n: int) -> tuple[State, State]:
    """(x, ξ) from a stacked state."""
    return tuple(float(v) for v in s[:n]), tuple(float(v) for v in s[n:])


def closed_loop(law: CascadeLaw, n: int) -> Callable[[float, np.ndarray], np.ndarray]:
    """ṡ for s = (x, ξ) under the law: ẋ = f, ξ̇1 = ξ2 + f1 (or v + f1), ξ̇2 = u + f2."""
    cas = law.cascade

    def rhs(t: float, s: np.ndarray) -> np.ndarray:
        x, xi = split(s, n)
        step = cas.first_step(x, xi[0])
        u = law.control(x, xi)
        if cas.m == 1:
            return np.array([*cas.flow(x, xi[0]), u + step.f1.value])
        return np.array(
            [*cas.flow(x, xi[0]), xi[1] + step.f1.value, u + cas.f2(x, xi[0], xi[1])]
        )

    return rhs


def numeric_rate(fun: Callable[[np.ndarray], float], s: np.ndarray, sdot: np.ndarray,
                 h: float = 1e-6) -> float:
    """d/dt fun(s(t)) by a central difference along ṡ."""
    return (fun(s + h * sdot) - fun(s - h * sdot)) / (2.0 * h)


def assert_rates(cascade: Cascade, x: State, xi1: float, xi1_dot: float, rtol: float = 1e-6,
                 atol: float = 1e-7) -> None:
    """Every Rated field of the first step against a finite difference along (f, ξ̇1)."""
    n = len(x)
    s = np.array([*x, xi1])
    sdot = np.array([*cascade.flow(x, xi1), xi1_dot])
    step = cascade.first_step(x, xi1)
    for name in ("alpha1_flow", "f1", "t_over_z"):
        rated: Rated = getattr(step, name)

        def g(p: np.ndarray, name: str = name) -> float:
            xx, xx1 = split(p, n)
            return float(getattr(cascade.first_step(xx, xx1[0]), name).value)

        want = numeric_rate(g, s, sdot)
        got = rated.rate(xi1_dot)
        assert np.isclose(got, want, rtol=rtol, atol=atol), (name, got, want)
    # α1's own rate is alpha1_flow: ∂α1/∂x·f
    a1 = numeric_rate(lambda p: cascade.first_step(split(p, n)[0], p[n]).alpha1, s, sdot)
    assert np.isclose(step.alpha1_flow.value, a1, rtol=rtol, atol=atol)


def peak(run: SystemTrajectory, plant: Plant, name: str) -> tuple[float, float]:
    """(min, max) of a constrained quantity over a run."""
    q = next(c for c in plant.constrained if c.name == name)
    v = run.input if q.source == "input" else run.state[:, q.index]
    return float(v.min()), float(v.max())
