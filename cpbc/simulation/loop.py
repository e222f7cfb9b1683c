"""The closed loop: controller at a fixed control rate (zero-order hold) on MuJoCo physics."""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.base import Controller, SafetyFilter
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model.coordinates import LinearCoordinates
from cpbc.simulation.disturbances import MeasurementNoise, rate_into_set
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
        noise: Gaussian noise on the state the controller sees, or None.
        max_log_samples: the log never holds more samples than this: when full, it drops
            every other sample and halves its rate (memory stays bounded on long runs).
    """

    duration: float
    control_period: float
    torque_limit: Array | None = None
    log_every: int = 1
    noise: MeasurementNoise | None = None
    max_log_samples: int = 100_000

    def __post_init__(self) -> None:
        if not self.duration > 0:
            raise CpbcError(f"duration must be > 0, got {self.duration}")
        if not self.control_period > 0:
            raise CpbcError(f"control_period must be > 0, got {self.control_period}")
        if self.max_log_samples < 2:
            raise CpbcError(f"max_log_samples must be ≥ 2, got {self.max_log_samples}")


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


class _Sampler:
    """The controller at one control instant, as it sees the state: through the measurement
    noise, if any; a measured state it refuses while the true one is inside S is a
    *rejected* sample, answered by ``_fallback``."""

    def __init__(self, controller: Controller, noise: MeasurementNoise | None, n: int) -> None:
        self.controller = controller
        self.noise = noise if noise is not None and noise.active else None
        if self.noise is not None:
            self.sigma_x, self.sigma_dx = self.noise.sigmas(n)
            self.rng = np.random.default_rng(self.noise.seed)
        self.n = n
        self.rejected = 0

    def __call__(self, x: Array, dx: Array, held: Array | None) -> tuple[Array, float]:
        """τ and the true V; ConstraintViolation when the true state has left S too."""
        if self.noise is None:
            return self.controller.evaluate(x, dx)
        xm = x + self.sigma_x * self.rng.standard_normal(self.n)
        dxm = dx + self.sigma_dx * self.rng.standard_normal(self.n)
        ctrl = self.controller
        try:
            tau = ctrl.evaluate(xm, dxm)[0]
        except ConstraintViolation:
            if not _inside(ctrl, x, dx):
                raise
            self.rejected += 1  # the measurement left S, the arm did not
            tau = _fallback(ctrl, xm, dxm, ctrl.model.gravity(xm) if held is None else held)
        return tau, _true_lyapunov(ctrl, x, dx)


def run_mujoco(
    plant: MujocoPlant,
    controller: Controller,
    coordinates: LinearCoordinates,
    x0: Array,
    dx0: Array,
    settings: LoopSettings,
    progress: Progress | None = None,
) -> Trajectory:
    """Simulate the closed loop from (x0, ẋ0), given in controller coordinates.

    The loop runs ``controller`` as it is given: a law, or a law the scenario builder has
    wrapped in its sampled-data safeguard (cpbc.controllers.safeguard.guarded), whose counts
    the trajectory reports. The controller sees the state through ``settings.noise`` (if
    any). A measured state outside S is refused by the law (ConstraintViolation); the loop
    then asks the plant: if the true state is inside S, the sample is *rejected* and counted
    in ``Trajectory.rejected_samples``: the law is evaluated at the measured rate scaled back
    just inside S (rate_into_set), or, when a configuration margin was measured ≤ 0, the
    previous torque is held (gravity compensation at the first sample) — what a real
    controller, which cannot know the true state, can do. If the true state is outside S
    too, the run ends as ``constraint_violated``.
    """
    substeps = substeps_per_control(settings.control_period, plant.model.opt.timestep)
    steps = round(settings.duration / settings.control_period)
    n = plant.n
    t_mat, t_inv = coordinates.matrix, coordinates.inverse
    t_mat_t = np.ascontiguousarray(t_mat.T)
    identity = coordinates.is_identity
    limit = settings.torque_limit
    plant.reset(t_inv @ x0, t_inv @ dx0)
    log = TrajectoryLog(n, steps + 1, settings.log_every, settings.max_log_samples)
    sample = _Sampler(controller, settings.noise, n)
    tau: Array | None = None
    tau_q: Array = np.full(n, np.nan)  # the joint torque applied through the last interval
    outcome, violated, saturated, contacts = "completed", None, 0, 0
    report_every = max(1, steps // 50)
    start = _time.perf_counter()
    data, h = plant.data, settings.control_period
    qpos, qvel = data.qpos, data.qvel
    # The step's calls bound once; ndarray.dot and sums of lists: on 2-vectors numpy's @
    # costs twice as much here.
    record, apply, step, unstable = log.record, plant.apply, plant.step, plant.unstable
    guard = controller if isinstance(controller, SafetyFilter) else None
    acted = guard.acted if guard else 0  # the guard's count before this step
    guarded_steps = np.zeros(steps + 1 if guard else 0, dtype=bool)
    for k in range(steps + 1):
        t = k * h
        x = qpos.copy() if identity else t_mat.dot(qpos)
        dx = qvel.copy() if identity else t_mat.dot(qvel)
        if not math.isfinite(sum(x.tolist()) + sum(dx.tolist())):  # NaN or overflow
            outcome = "diverged"
            break
        try:
            tau, v = sample(x, dx, tau)
        except ConstraintViolation as exc:
            outcome, violated = "constraint_violated", exc.constraint
            # V is undefined outside S; the torque is the one held until this instant
            held = np.full(n, np.nan) if tau is None else tau
            log.record(t, np.nan, x, dx, held, tau_q, force=True)
            break
        if not math.isfinite(sum(tau.tolist())):
            outcome = "diverged"
            log.record(t, v, x, dx, tau, np.full(n, np.nan), force=True)
            break
        if guard is not None and guard.acted != acted:
            guarded_steps[k], acted = True, guard.acted
        tau_q = tau if identity else t_mat_t.dot(tau)
        if limit is not None:
            clipped = np.clip(tau_q, -limit, limit)
            saturated += int(np.any(clipped != tau_q))
            tau_q = clipped
        record(t, v, x, dx, tau, tau_q, k == steps)
        if k == steps:
            break
        apply(tau_q)
        step(substeps)
        if unstable():  # MuJoCo reset the state or dropped the control
            outcome = "diverged"
            break
        contacts = max(contacts, data.ncon)
        if progress is not None and k % report_every == 0:
            progress(k / steps)
    wall = _time.perf_counter() - start
    tt, xs, dxs, taus, tau_qs, vs = log.arrays()
    end_time = float(tt[-1]) if tt.size else 0.0
    if outcome == "diverged":
        end_time = k * settings.control_period
    return Trajectory(
        tt, xs, dxs, taus, tau_qs, vs, outcome, end_time, violated, wall, k + 1, saturated,
        int(contacts), "mujoco",
        safeguard_steps=guard.acted if guard else 0,
        safeguard_infeasible=guard.infeasible if guard else 0,
        filter_row_steps=guard.row_active_steps if guard else 0,
        rescues=guard.rescues if guard else 0,
        rejected_samples=sample.rejected,
        guarded_steps=guarded_steps[: k + 1] if guard else None,
    )


def _fallback(law: Controller, xm: Array, dxm: Array, held: Array) -> Array:
    """The torque for a measurement the law refused: the law at the measured rate scaled
    back into S (when only velocity constraints are broken), else the held torque."""
    dxp = rate_into_set(law.constraints, xm, dxm)
    if dxp is None:
        return held
    try:
        return law.evaluate(xm, dxp)[0]
    except ConstraintViolation:
        return held


def _inside(controller: Controller, x: Array, dx: Array) -> bool:
    """Whether the true state is inside the law's admissible set."""
    m = controller.constraints.margins(x, dx)
    return bool(np.all(m > 0))


def _true_lyapunov(controller: Controller, x: Array, dx: Array) -> float:
    try:
        return controller.lyapunov(x, dx)
    except ConstraintViolation:
        return math.nan
