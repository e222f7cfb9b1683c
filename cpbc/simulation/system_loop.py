"""The closed loop of a Part I system (cpbc.systems.Plant) under a state-feedback law
u = k(x): in MuJoCo at a fixed control period (zero-order hold), or as the plant's ODE in
continuous time (the reference backend)."""

from __future__ import annotations

import itertools
import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.backstepping.design_errors import OutsideDomainError
from cpbc.simulation.loop import Progress, substeps_per_control
from cpbc.simulation.plant import INSTABILITY_WARNINGS
from cpbc.systems.ode_plant import OdePlant, Plant, State

Law = Callable[[State, float], float]  # u = k(x, t)


@dataclass(frozen=True)
class SystemTrajectory:
    """Samples at the control instants.

    Attributes:
        time: (N,) [s].
        state: (N, n) the law's state x.
        input: (N,) the input u applied from each sample on (NaN where the law is undefined).
        outcome: "completed", "diverged" or "constraint_violated" (the state left the law's
            domain: ``violated`` names the error variable).
        end_time: simulated time at the end [s].
        wall_time: wall-clock time of the loop [s].
        backend: "mujoco" or "reference".
        qpos, qvel: (N, nq), (N, nv) MuJoCo's coordinates at the samples (for the 3-D view);
            the reference backend sets them from x (a coordinate x omits stays at zero), or
            leaves them None for a plant that is only its ODE (no MJCF, nothing to show).
    """

    time: Array
    state: Array
    input: Array
    outcome: str
    end_time: float
    violated: str | None
    wall_time: float
    backend: str
    qpos: Array | None = None
    qvel: Array | None = None


def _control(law: Law, x: State, t: float) -> tuple[float, str | None]:
    try:
        return law(x, t), None
    except OutsideDomainError as exc:
        return math.nan, exc.variable


def run_system_mujoco(
    plant: Plant, law: Law, x0: State, duration: float, control_period: float | None = None,
    timestep: float | None = None, integrator: str = "RK4", progress: Progress | None = None,
) -> SystemTrajectory:
    """Run ``law`` on the plant's MJCF, holding u over each control period (``timestep``:
    the MJCF's own when None; ``control_period``: one physics step when None)."""
    model = plant.load()
    model.opt.timestep = timestep or model.opt.timestep
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    data = mujoco.MjData(model)
    plant.write_state(model, data, x0)
    control_period = control_period or model.opt.timestep
    substeps = substeps_per_control(control_period, model.opt.timestep)
    steps = round(duration / control_period)
    ts, xs, us = np.full(steps + 1, np.nan), np.full((steps + 1, len(x0)), np.nan), \
        np.full(steps + 1, np.nan)
    qs, vs = np.zeros((steps + 1, model.nq)), np.zeros((steps + 1, model.nv))
    outcome, violated, k = "completed", None, 0
    report_every = max(1, steps // 50)
    start = _time.perf_counter()
    for k in range(steps + 1):
        x = plant.read_state(model, data)
        ts[k], xs[k], qs[k], vs[k] = k * control_period, x, data.qpos, data.qvel
        if not all(math.isfinite(v) for v in x):
            outcome = "diverged"
            break
        u, violated = _control(law, x, data.time)
        if violated is not None:
            outcome = "constraint_violated"
            break
        us[k] = u
        if k == steps:
            break
        plant.write_input(model, data, u)
        for _ in range(substeps):
            plant.before_step(model, data)
            mujoco.mj_step(model, data)
        if any(data.warning[w].number for w in INSTABILITY_WARNINGS):
            outcome = "diverged"  # MuJoCo reset the state or dropped the input and went on
            break
        if progress is not None and k % report_every == 0:
            progress(k / steps)
    wall = _time.perf_counter() - start
    n = k + 1
    return SystemTrajectory(ts[:n], xs[:n], us[:n], outcome, k * control_period, violated,
                            wall, "mujoco", qs[:n], vs[:n])


def run_system_reference(
    plant: OdePlant, law: Law, x0: State, duration: float, sample_period: float,
    rtol: float = 1e-10, atol: float = 1e-12,
) -> SystemTrajectory:
    """Integrate ẋ = f(x, k(x), t) with DOP853 (the law at every stage, no hold), piecewise
    at the plant's breakpoints; samples every ``sample_period``."""
    domain: list[str] = []

    def rhs(t: float, y: Array) -> list[float]:
        x = tuple(float(v) for v in y)
        u, violated = _control(law, x, t)
        if violated is not None:  # reject the stage: a true crossing ends the integration
            if not domain:  # the first: the solver's later stages start from the NaN
                domain.append(violated)
            return [math.nan] * len(x)
        return list(plant.rhs(x, u, t))

    grid = np.arange(round(duration / sample_period) + 1, dtype=float) * sample_period
    cuts = [0.0, *[b for b in plant.breakpoints() if 0.0 < b < grid[-1]], float(grid[-1])]
    pieces, x, outcome = [], np.asarray(x0, dtype=float), "completed"
    start = _time.perf_counter()
    for lo, hi in itertools.pairwise(cuts):
        last = hi == cuts[-1]
        sel = grid[(grid >= lo) & ((grid <= hi) if last else (grid < hi))]
        t_eval = sel if last else np.append(sel, hi)  # the end of a piece starts the next one
        from scipy.integrate import solve_ivp  # loaded when used (CLI start-up)

        sol = solve_ivp(rhs, (lo, hi), x, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol)
        got = sol.y.T if last or sol.status != 0 else sol.y.T[:-1]
        pieces.append(got)
        if sol.status != 0 or not np.all(np.isfinite(sol.y)):
            outcome = "constraint_violated" if domain else "diverged"
            break
        x = sol.y[:, -1]
    wall = _time.perf_counter() - start
    xs = np.vstack(pieces)
    ts = grid[: len(xs)]
    us = np.array([_control(law, tuple(float(v) for v in row), float(t))[0]
                   for row, t in zip(xs, ts, strict=True)])
    end = float(ts[-1]) if len(ts) else 0.0
    qpos, qvel = _coordinates(plant, ts, xs) if isinstance(plant, Plant) else (None, None)
    return SystemTrajectory(ts, xs, us, outcome, end, domain[0] if domain else None, wall,
                            "reference", qpos, qvel)


def _coordinates(plant: Plant, ts: Array, xs: Array) -> tuple[Array, Array]:
    """MuJoCo's qpos and qvel for the states x at the times t, through the plant's map."""
    model = plant.load()
    data = mujoco.MjData(model)
    qpos, qvel = np.zeros((len(ts), model.nq)), np.zeros((len(ts), model.nv))
    for k, (t, x) in enumerate(zip(ts, xs, strict=True)):
        data.time = float(t)
        plant.write_state(model, data, tuple(float(v) for v in x))
        qpos[k], qvel[k] = data.qpos, data.qvel
    return qpos, qvel
