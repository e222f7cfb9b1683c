"""A continuous-time driver for the ODE-only Part-I plants (tests and tools/ only): the law at
every stage of scipy's solve_ivp, no hold, samples every ``dt``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from cpbc.systems.ode_plant import OdePlant

Law = Callable[[tuple[float, ...], float], float]  # u = k(x, t)
Array = NDArray[np.float64]


@dataclass(frozen=True)
class OdeRun:
    """Samples t (N,), x (N, n), u (N,), and the solver's count of right-hand-side calls."""

    t: Array
    x: Array
    u: Array
    nfev: int

    def peak(self, plant: OdePlant, name: str) -> float:
        """max |quantity| over the run."""
        q = next(c for c in plant.constrained if c.name == name)
        return float(np.abs(self.u if q.source == "input" else self.x[:, q.index]).max())


def run_ode(plant: OdePlant, law: Law, x0: tuple[float, ...], duration: float, dt: float,
            method: str = "DOP853", rtol: float = 1e-10, atol: float = 1e-12) -> OdeRun:
    """Integrate ẋ = f(x, law(x, t), t) from x0 over [0, duration]."""
    def rhs(t: float, x: Array) -> list[float]:
        state = tuple(float(v) for v in x)
        return list(plant.rhs(state, law(state, t), t))

    grid = np.linspace(0.0, duration, round(duration / dt) + 1)
    sol = solve_ivp(rhs, (0.0, duration), np.asarray(x0, float), method=method, t_eval=grid,
                    rtol=rtol, atol=atol)
    if sol.status != 0:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    xs = sol.y.T
    us = np.array([law(tuple(float(v) for v in row), t) for row, t in zip(xs, grid, strict=True)])
    return OdeRun(grid, xs, us, int(sol.nfev))
