"""Continuous-time reference backend: SciPy's solve_ivp on Pinocchio's forward dynamics.

The thesis's results are continuous-time (no zero-order hold); this backend evaluates the
law at every integrator stage, so it checks what MuJoCo's sampled-data loop shows.
"""

from __future__ import annotations

import time as _time

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.base import Controller
from cpbc.errors import ConstraintViolation
from cpbc.model.robot_model import RobotModel
from cpbc.simulation.loop import LoopSettings
from cpbc.simulation.trajectory import Trajectory


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
    limit = settings.torque_limit
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

    steps = round(settings.duration / settings.control_period)
    t_eval = np.arange(steps + 1) * settings.control_period
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
