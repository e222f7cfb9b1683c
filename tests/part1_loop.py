"""A minimal fixed-step driver for the Part-I plants, for tests and tools/ only.

Until the product's loop (cpbc/simulation) takes a :class:`~cpbc.systems.Plant`, this runs a law
u = k(x) on a plant in MuJoCo (zero-order hold at the control period) or on the plant's ODE
(scipy's solve_ivp, piecewise at the plant's breakpoints).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from cpbc.systems import Plant

Law = Callable[[tuple[float, ...], float], float]  # u = k(x, t)
Array = NDArray[np.float64]


@dataclass(frozen=True)
class Trajectory:
    """Samples at the control instants: t (N,), x (N, n), u (N,) (the input applied from t on)."""

    t: Array
    x: Array
    u: Array

    def peak(self, plant: Plant, name: str) -> tuple[float, float]:
        """(min, max) of a constrained quantity over the run."""
        q = next(c for c in plant.constrained if c.name == name)
        v = self.u if q.source == "input" else self.x[:, q.index]
        return float(v.min()), float(v.max())

    def at(self, time: float) -> Array:
        """x at the sample nearest ``time``."""
        return self.x[int(np.argmin(np.abs(self.t - time)))]


def run_mujoco(
    plant: Plant, law: Law, x0: tuple[float, ...], duration: float, substeps: int = 1,
    timestep: float | None = None,
) -> Trajectory:
    """Run ``law`` on the plant's MJCF; the control period is ``substeps`` physics steps."""
    model = plant.load()
    if timestep is not None:
        model.opt.timestep = timestep
    data = mujoco.MjData(model)
    plant.write_state(model, data, x0)
    n = round(duration / (model.opt.timestep * substeps))
    ts, xs, us = np.empty(n + 1), np.empty((n + 1, len(x0))), np.empty(n + 1)
    for k in range(n + 1):
        x = plant.read_state(model, data)
        u = law(x, data.time)
        ts[k], xs[k], us[k] = data.time, x, u
        if k == n:
            break
        plant.write_input(model, data, u)
        for _ in range(substeps):
            plant.before_step(model, data)
            mujoco.mj_step(model, data)
    return Trajectory(ts, xs, us)


def run_ode(
    plant: Plant, law: Law, x0: tuple[float, ...], duration: float, dt: float,
    rtol: float = 1e-10, atol: float = 1e-12, method: str = "DOP853",
) -> Trajectory:
    """Integrate ẋ = f(x, law(x), t) in continuous time; sample every ``dt``."""
    def rhs(t: float, x: Array) -> list[float]:
        state = tuple(float(v) for v in x)
        return list(plant.rhs(state, law(state, t), t))

    grid = np.linspace(0.0, duration, round(duration / dt) + 1)
    cuts = [0.0, *[b for b in plant.breakpoints() if 0.0 < b < duration], duration]
    xs, x = [], np.asarray(x0, dtype=float)
    for lo, hi in itertools.pairwise(cuts):
        last = hi == duration
        sel = grid[(grid >= lo) & ((grid <= hi) if last else (grid < hi))]
        ts = sel if last else np.append(sel, hi)  # the end of a piece starts the next one
        sol = solve_ivp(rhs, (lo, hi), x, method=method, t_eval=ts, rtol=rtol, atol=atol)
        if sol.status != 0:
            raise RuntimeError(f"solve_ivp failed on [{lo}, {hi}]: {sol.message}")
        xs.append(sol.y.T if last else sol.y.T[:-1])
        x = sol.y[:, -1]
    xa = np.vstack(xs)
    ts = grid[: len(xa)]
    ua = np.array([law(tuple(float(v) for v in row), t) for row, t in zip(xa, ts, strict=True)])
    return Trajectory(ts, xa, ua)
