"""Continuous-time reference backend: SciPy's solve_ivp (DOP853) on an arm's Pinocchio
forward dynamics (:func:`run_reference`), or on a Part I system's ODE ẋ = f(x, u, t)
(:func:`run_system_reference`).

The thesis's results are continuous-time (no zero-order hold); this backend evaluates the
law at every integrator stage, so it checks what MuJoCo's sampled-data loop
(cpbc.simulation.loop) shows.
"""

from __future__ import annotations

import itertools
import math
import time as _time
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller
from cpbc.errors import ConstraintViolation
from cpbc.model.robot_model import RobotModel
from cpbc.simulation.loop import LoopSettings
from cpbc.simulation.trajectory import SystemTrajectory, Trajectory

if TYPE_CHECKING:
    from cpbc.simulation.loop import SystemLaw
    from cpbc.systems.ode_plant import OdePlant, Plant, State


def run_reference(
    plant: RobotModel,
    controller: Controller,
    x0: Array,
    dx0: Array,
    settings: LoopSettings,
    rtol: float = 1e-9,
    atol: float = 1e-11,
) -> Trajectory:
    """Integrate D ẍ + C ẋ + g + f = k(x, ẋ) with DOP853; samples at the control instants.

    ``plant`` is a separate model object from the controller's (it may differ on purpose).
    """
    n = plant.n
    coords = plant.coordinates
    limit = settings.bounds.torque
    calls = 0
    violation: list[str] = []
    inside: list[Array] = []  # the last state at which the law was defined

    def applied(x: Array, dx: Array) -> tuple[Array, Array]:
        tau = controller.torque(x, dx)
        return tau, saturate(tau)

    def saturate(tau: Array) -> Array:
        tau_q = coords.torque_to_joint(tau)
        return tau_q if limit is None else np.clip(tau_q, -limit, limit)

    def rhs(_t: float, y: Array) -> Array:
        nonlocal calls
        calls += 1
        x, dx = y[:n], y[n:]
        try:
            _, tau_q = applied(x, dx)
        except ConstraintViolation as exc:
            # Outside S the law is undefined: reject the stage so the step shrinks; a true
            # crossing ends the integration with a too-small step size.
            violation[:] = [exc.constraint]
            return np.full(2 * n, np.nan)
        inside[:] = [y]
        return np.concatenate([dx, plant.forward_dynamics(x, dx, coords.torque_from_joint(tau_q))])

    steps = round(settings.duration / settings.bounds.period)
    t_eval = np.arange(steps + 1) * settings.bounds.period
    start = _time.perf_counter()
    from scipy.integrate import solve_ivp  # loaded when used: 0.15 s off every CLI start

    sol = solve_ivp(
        rhs, (0.0, t_eval[-1]), np.concatenate([x0, dx0]), method="DOP853",
        t_eval=t_eval, rtol=rtol, atol=atol,
    )
    wall = _time.perf_counter() - start
    xs, dxs = sol.y[:n].T.copy(), sol.y[n:].T.copy()
    taus = np.full_like(xs, np.nan)
    tau_qs = np.full_like(xs, np.nan)
    vs = np.full(len(sol.t), np.nan)
    for i in range(len(sol.t)):
        try:
            taus[i], vs[i] = controller.evaluate(xs[i], dxs[i])
        except ConstraintViolation:
            continue
        tau_qs[i] = saturate(taus[i])
    if sol.status == 0:
        outcome, violated = "completed", None
    elif violation:
        outcome = "constraint_violated"
        violated = _crossed(controller, inside[0], n) if inside else None
        violated = violated or violation[0]
    else:
        outcome, violated = "diverged", None
    if not np.all(np.isfinite(sol.y)):
        outcome = "diverged"
    end_time = float(sol.t[-1]) if sol.t.size else 0.0
    return Trajectory(
        sol.t.copy(), xs, dxs, taus, tau_qs, vs, outcome, end_time, violated, wall, calls, 0, 0,
        "reference",
    )


def _crossed(controller: Controller, y: Array, n: int) -> str | None:
    """The constraint the trajectory crossed: the nearest its boundary at the last state
    inside S. (Not the one a rejected trial stage named: a stage after a rejected one is
    computed from NaN, and a law names its first constraint there.)"""
    margins = controller.constraints.margins(y[:n], y[n:])
    if not margins.size:
        return None
    return controller.constraints.names[int(np.argmin(np.nan_to_num(margins, nan=np.inf)))]

def _control(law: SystemLaw, x: State, t: float) -> tuple[float, str | None]:
    """u = k(x, t), or NaN and the error variable that left the law's domain (a barrier
    law raises OutsideDomainError, a ConstraintViolation)."""
    try:
        return law(x, t), None
    except ConstraintViolation as exc:
        return math.nan, exc.constraint


def run_system_reference(
    plant: OdePlant, law: SystemLaw, x0: State, duration: float, sample_period: float,
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
    from cpbc.systems.ode_plant import Plant  # the Part I plants: not loaded for an arm

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
