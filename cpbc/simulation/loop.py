"""The closed loop: controller at a fixed control rate (zero-order hold) on MuJoCo physics."""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cpbc.constraints.base import Array
from cpbc.controllers.base import Controller
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model.coordinates import LinearCoordinates
from cpbc.simulation.plant import MujocoPlant
from cpbc.simulation.trajectory import Trajectory, TrajectoryLog

Progress = Callable[[float], None]


@dataclass(frozen=True)
class LoopSettings:
    """Closed-loop settings.

    Attributes:
        duration: simulated time [s], > 0.
        control_period: controller period [s]; a whole multiple of the physics timestep.
        torque_limit: symmetric joint torque limits |τ_q,i| ≤ limit_i [N·m], or None.
        log_every: keep every k-th control sample (long runs).
    """

    duration: float
    control_period: float
    torque_limit: Array | None = None
    log_every: int = 1

    def __post_init__(self) -> None:
        if not self.duration > 0:
            raise CpbcError(f"duration must be > 0, got {self.duration}")
        if not self.control_period > 0:
            raise CpbcError(f"control_period must be > 0, got {self.control_period}")


def substeps_per_control(control_period: float, timestep: float) -> int:
    """Physics steps per control period; the period must be a whole multiple of the timestep."""
    ratio = control_period / timestep
    k = round(ratio)
    if k < 1 or abs(ratio - k) > 1e-9 * max(1.0, ratio):
        raise CpbcError(
            f"control_period {control_period} s is not a whole multiple of the timestep "
            f"{timestep} s; choose e.g. control_period = {max(k, 1) * timestep:g}"
        )
    return k


def run_mujoco(
    plant: MujocoPlant,
    controller: Controller,
    coordinates: LinearCoordinates,
    x0: Array,
    dx0: Array,
    settings: LoopSettings,
    progress: Progress | None = None,
) -> Trajectory:
    """Simulate the closed loop from (x0, ẋ0), given in controller coordinates."""
    substeps = substeps_per_control(settings.control_period, plant.model.opt.timestep)
    steps = round(settings.duration / settings.control_period)
    n = plant.n
    t_mat, t_inv = coordinates.matrix, coordinates.inverse
    t_mat_t = np.ascontiguousarray(t_mat.T)
    identity = coordinates.is_identity
    limit = settings.torque_limit
    plant.reset(t_inv @ x0, t_inv @ dx0)
    log = TrajectoryLog(n, steps + 1, settings.log_every)
    outcome, violated, saturated, contacts = "completed", None, 0, 0
    report_every = max(1, steps // 50)
    start = _time.perf_counter()
    calls = 0
    qpos, qvel = plant.data.qpos, plant.data.qvel
    for k in range(steps + 1):
        t = k * settings.control_period
        x = qpos.copy() if identity else t_mat @ qpos
        dx = qvel.copy() if identity else t_mat @ qvel
        if not math.isfinite(x @ x + dx @ dx):  # NaN or overflow in the state
            outcome = "diverged"
            break
        try:
            calls += 1
            tau, v = controller.evaluate(x, dx)
        except ConstraintViolation as exc:
            outcome, violated = "constraint_violated", exc.constraint
            log.record(t, np.nan, x, dx, np.full(n, np.nan), np.full(n, np.nan), force=True)
            break
        if not math.isfinite(tau @ tau):
            outcome = "diverged"
            log.record(t, v, x, dx, tau, np.full(n, np.nan), force=True)
            break
        tau_q = tau if identity else t_mat_t @ tau
        if limit is not None:
            clipped = np.clip(tau_q, -limit, limit)
            saturated += int(np.any(clipped != tau_q))
            tau_q = clipped
        log.record(t, v, x, dx, tau, tau_q, force=(k == steps))
        if k == steps:
            break
        plant.apply(tau_q)
        plant.step(substeps)
        if plant.unstable():  # MuJoCo reset the state or dropped the control
            outcome = "diverged"
            break
        contacts = max(contacts, plant.data.ncon)
        if progress is not None and k % report_every == 0:
            progress(k / steps)
    wall = _time.perf_counter() - start
    tt, xs, dxs, taus, tau_qs, vs = log.arrays()
    end_time = float(tt[-1]) if tt.size else 0.0
    if outcome == "diverged":
        end_time = k * settings.control_period
    return Trajectory(
        tt, xs, dxs, taus, tau_qs, vs, outcome, end_time, violated, wall, calls, saturated,
        int(contacts), "mujoco",
    )
