"""The closed loop: a law at a fixed control rate (zero-order hold) on MuJoCo physics.

One loop (:func:`run_loop`) steps every plant: an arm under a joint-space or task-space law
(:func:`run_mujoco`) and a Part I system under its backstepping law
(:func:`run_system_mujoco`). What differs between them, what a state and an input are and
what is logged, sits behind the small :class:`SampledLoop` protocol; the loop owns the rest:
the control instants, the hold, the physics substeps, the outcome (completed, diverged,
constraint_violated), the progress reports and the wall-clock time.
"""

from __future__ import annotations

import gc
import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, TypeVar

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller, SafetyFilter
from cpbc.controllers.safeguard.model_error import DeclaredError
from cpbc.errors import ConstraintViolation, CpbcError
from cpbc.model.coordinates import LinearCoordinates
from cpbc.model.input_bounds import InputBounds
from cpbc.simulation.disturbances import AccelerationDisturbance, MeasurementNoise, rate_into_set
from cpbc.simulation.plant import INSTABILITY_WARNINGS, MujocoPlant
from cpbc.simulation.trajectory import SystemTrajectory, Trajectory, TrajectoryLog

if TYPE_CHECKING:  # the Part I plants load the backstepping designs (0.5 s): not for an arm
    from cpbc.systems.ode_plant import Plant, State

    SystemLaw = Callable[[State, float], float]  # a Part I law u = k(x, t)

Progress = Callable[[float], None]
S = TypeVar("S")
U = TypeVar("U")


@dataclass(frozen=True)
class LoopSettings:
    """Closed-loop settings.

    Attributes:
        duration: simulated time [s], > 0.
        bounds: the control period (a whole multiple of the physics timestep) and the
            actuators' torque and torque-rate limits (cpbc.model.input_bounds). The plant
            applies them as motors would: a torque beyond the box is clipped, and a command
            that moves faster than the rate limit is clipped and counted; the run's first
            command moves from the torque held before it, the gravity torque at the start
            (an arm held at rest), at most the torque limit.
        log_every: keep every k-th control sample (long runs).
        noise: Gaussian noise on the state the controller sees, or None.
        max_log_samples: the log never holds more samples than this: when full, it drops
            every other sample and halves its rate (memory stays bounded on long runs).
        model_error: the declared bound ā on the controller model's acceleration error per
            coordinate (controller coordinates), which the safeguard holds as a
            disturbance (cpbc.controllers.safeguard.model_error), or None. The plant does
            not read it.
        declared_error: the declared relative inertia error and measurement errors the
            safeguard holds (cpbc.controllers.safeguard.model_error.DeclaredError), or None.
            The plant does not read it.
        disturbance: an acceleration disturbance the plant adds to its own dynamics (a
            plant drawn inside a declared model error, cpbc.simulation.disturbances), or
            None.
    """

    duration: float
    bounds: InputBounds
    log_every: int = 1
    noise: MeasurementNoise | None = None
    max_log_samples: int = 100_000
    model_error: Array | None = None
    declared_error: DeclaredError | None = None
    disturbance: AccelerationDisturbance | None = None

    def __post_init__(self) -> None:
        if not self.duration > 0:
            raise CpbcError(f"duration must be > 0, got {self.duration}")
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

    def __init__(self, controller: Controller, noise: MeasurementNoise | None, n: int,
                 period: float) -> None:
        self.controller = controller
        self.period = period
        self.noise = noise if noise is not None and noise.active else None
        if self.noise is not None:
            self.sigma_x, self.sigma_dx = self.noise.sigmas(n)
            self.rng = np.random.default_rng(self.noise.seed)
        self.n = n
        self.rejected = 0

    def __call__(self, x: Array, dx: Array) -> tuple[Array, float]:
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
            tau = _fallback(ctrl, xm, dxm, self.period)
        return tau, _true_lyapunov(ctrl, x, dx)


class SampledLoop(Protocol[S, U]):
    """A plant and its law as :func:`run_loop` steps them: at each control instant the loop
    observes the state, asks for the input, has the sample recorded, and holds the input
    over the control period."""

    def observe(self) -> S | None:
        """The state the law sees; None when it is not finite (the run diverged)."""

    def control(self, t: float, x: S) -> U | None:
        """The input to hold from ``t`` on; None when it is not finite (the run diverged; the
        sample is logged). Raises ConstraintViolation when the state left the law's domain."""

    def record(self, t: float, x: S, u: U, last: bool) -> None:
        """Log the sample (``last``: the run's final one, always kept)."""

    def refused(self, t: float, x: S) -> None:
        """Log the sample at which the law refused the state."""

    def hold(self, u: U, substeps: int) -> bool:
        """Apply ``u`` and step the physics ``substeps`` times; False when the physics went
        unstable (MuJoCo reset the state or dropped the input and went on)."""


@dataclass(frozen=True)
class LoopEnd:
    """How :func:`run_loop` ended: the outcome, the constraint that was crossed, the last
    control step taken (0-based) and the wall-clock time of the loop [s]."""

    outcome: str
    violated: str | None
    last_step: int
    wall_time: float


def run_loop(loop: SampledLoop[S, U], steps: int, substeps: int, period: float,
             progress: Progress | None = None) -> LoopEnd:
    """Run ``steps`` control periods of ``substeps`` physics steps each (samples at
    0, period, …, steps·period), with Python's cyclic garbage collector off: a collection
    inside the loop is a pause of milliseconds at a random step (a control deadline's
    worst enemy); what the loop allocates is freed by reference counting as it goes."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        return _steps(loop, steps, substeps, period, progress)
    finally:
        if collecting:
            gc.enable()


def _steps(loop: SampledLoop[S, U], steps: int, substeps: int, period: float,
           progress: Progress | None) -> LoopEnd:
    outcome, violated, k = "completed", None, 0
    report_every = max(1, steps // 50)
    # the step's calls bound once (attribute look-ups cost per step)
    observe, control, record, hold = loop.observe, loop.control, loop.record, loop.hold
    start = _time.perf_counter()
    for k in range(steps + 1):
        t = k * period
        x = observe()
        if x is None:
            outcome = "diverged"
            break
        try:
            u = control(t, x)
        except ConstraintViolation as exc:
            outcome, violated = "constraint_violated", exc.constraint
            loop.refused(t, x)
            break
        if u is None:
            outcome = "diverged"
            break
        record(t, x, u, k == steps)
        if k == steps:
            break
        if not hold(u, substeps):
            outcome = "diverged"
            break
        if progress is not None and k % report_every == 0:
            progress(k / steps)
    return LoopEnd(outcome, violated, k, _time.perf_counter() - start)


class ArmLoop:
    """An arm in MuJoCo under a law in controller coordinates x = T q: the state (x, ẋ), the
    law through the measurement noise, the torque mapped to the joints and clipped at the
    plant's limits, the safeguard's steps counted, the largest contact count kept."""

    def __init__(self, plant: MujocoPlant, controller: Controller,
                 coordinates: LinearCoordinates, settings: LoopSettings, steps: int) -> None:
        n = plant.n
        self.plant = plant
        self.t_mat = coordinates.matrix
        self.t_mat_t = np.ascontiguousarray(self.t_mat.T)
        self.identity = coordinates.is_identity
        self.limit = settings.bounds.torque
        self.log = TrajectoryLog(n, steps + 1, settings.log_every, settings.max_log_samples)
        self.sample = _Sampler(controller, settings.noise, n, settings.bounds.period)
        self.qpos, self.qvel = plant.data.qpos, plant.data.qvel
        self.tau: Array | None = None
        self.v = math.nan
        self.tau_q: Array = np.full(n, np.nan)  # the joint torque applied through the last interval
        self.saturated, self.contacts, self.k = 0, 0, 0
        self.guard = controller if isinstance(controller, SafetyFilter) else None
        self.acted = self.guard.acted if self.guard else 0  # the guard's count before this step
        self.guarded_steps = np.zeros(steps + 1 if self.guard else 0, dtype=bool)
        self.period = settings.bounds.period
        step = settings.bounds.step
        self.rate_step = None if step is None else np.broadcast_to(step, (n,))
        # a command that ends on the rate box's edge is within it: held ± ρh computed by the
        # guard and the difference taken here may round apart by an ulp
        self.rate_tolerance = None if self.rate_step is None else self.rate_step * (1 + 1e-9)
        self.rate_limited = 0
        self.held_q: Array | None = None  # the joint torque the motors hold (set by start)
        self.peak_step = np.zeros(n)  # the largest |Δτ_q| between commands
        self.compute_max = 0.0  # the controller's longest call [s] (the loop's deadline)
        self.compute_total = 0.0
        self.disturber = None if settings.disturbance is None else settings.disturbance.drawn()

    def start(self, x0: Array) -> None:
        """Before the first control instant: the motors hold the gravity torque of the
        controller's model at the start — at most their torque limit: where gravity pulls
        harder the arm cannot be held, and a motor held beyond its limit took Baxter's
        shoulder up to 1.6 N·m past it for the first 2-4 steps, the plant clipping the
        commands the guard made within the box — and a guard that knows the rate limit is
        told so."""
        gravity = self.sample.controller.model.gravity(x0)
        held_q = gravity if self.identity else self.t_mat_t.dot(gravity)
        limit = self.limit
        if limit is not None and not (abs(held_q) <= limit).all():
            held_q = held_q.clip(-limit, limit)
            gravity = held_q if self.identity else np.linalg.solve(self.t_mat_t, held_q)
        self.held_q = held_q
        if self.guard is not None and self.rate_step is not None:
            self.guard.holding(gravity)

    def observe(self) -> tuple[Array, Array] | None:
        if self.identity:
            x, dx = self.qpos.copy(), self.qvel.copy()
        else:
            x, dx = self.t_mat.dot(self.qpos), self.t_mat.dot(self.qvel)
        # On 2-vectors numpy's @ and isfinite cost twice a sum of lists here.
        if not math.isfinite(sum(x.tolist()) + sum(dx.tolist())):  # NaN or overflow
            return None
        return x, dx

    def control(self, t: float, state: tuple[Array, Array]) -> Array | None:
        x, dx = state
        rejected = self.sample.rejected
        start = _time.perf_counter()
        tau, v = self.sample(x, dx)
        spent = _time.perf_counter() - start
        self.compute_total += spent
        if spent > self.compute_max:
            self.compute_max = spent
        self.tau, self.v = tau, v
        if not math.isfinite(sum(tau.tolist())):
            self.log.record(t, v, x, dx, tau, np.full(len(tau), np.nan), force=True)
            return None
        guard = self.guard
        if guard is not None and guard.acted != self.acted:
            self.guarded_steps[self.k], self.acted = True, guard.acted
        tau_q = tau if self.identity else self.t_mat_t.dot(tau)
        limit = self.limit
        if limit is not None and not (abs(tau_q) <= limit).all():  # the array methods: the
            tau_q = tau_q.clip(-limit, limit)  # numpy functions cost 2-3 µs a step more
            self.saturated += 1
        held = self.held_q
        if held is not None:
            change = tau_q - held
            step = self.rate_step
            if step is not None and not (abs(change) <= self.rate_tolerance).all():
                tau_q = held + change.clip(-step, step)  # what the motors can do
                self.rate_limited += 1
                change = tau_q - held
            np.maximum(self.peak_step, abs(change), out=self.peak_step)
        self.held_q = tau_q
        self.tau_q = tau_q
        if self.sample.rejected != rejected and guard is not None and self.rate_step is not None:
            # the guard did not choose this torque: it ramps on from what the motors hold
            guard.holding(tau_q if self.identity else np.linalg.solve(self.t_mat_t, tau_q))
        return tau_q

    def record(self, t: float, state: tuple[Array, Array], tau_q: Array, last: bool) -> None:
        assert self.tau is not None  # control() set it
        self.log.record(t, self.v, state[0], state[1], self.tau, tau_q, last)

    def refused(self, t: float, state: tuple[Array, Array]) -> None:
        # V is undefined outside S; the torque is the one held until this instant
        held = np.full(self.plant.n, np.nan) if self.tau is None else self.tau
        self.log.record(t, np.nan, state[0], state[1], held, self.tau_q, force=True)

    def hold(self, tau_q: Array, substeps: int) -> bool:
        plant = self.plant
        disturber = self.disturber
        plant.apply(tau_q if disturber is None else
                    tau_q + disturber.force(plant.model, plant.data))
        plant.step(substeps)
        if plant.unstable():
            return False
        self.contacts = max(self.contacts, plant.data.ncon)
        self.k += 1
        return True


def run_mujoco(
    plant: MujocoPlant,
    controller: Controller,
    coordinates: LinearCoordinates,
    x0: Array,
    dx0: Array,
    settings: LoopSettings,
    progress: Progress | None = None,
) -> Trajectory:
    """Simulate an arm's closed loop from (x0, ẋ0), given in controller coordinates.

    The loop runs ``controller`` as it is given: a law, or a law the scenario builder has
    wrapped in its sampled-data safeguard (cpbc.controllers.safeguard.guarded), whose counts
    the trajectory reports. The controller sees the state through ``settings.noise`` (if
    any). A measured state outside S is refused by the law (ConstraintViolation); the loop
    then asks the plant: if the true state is inside S, the sample is *rejected* and counted
    in ``Trajectory.rejected_samples``: the law is evaluated at the measured rate scaled back
    just inside S (rate_into_set), or, when a configuration margin was measured ≤ 0, the
    model's one-period brake at the measured state — what a real controller, which cannot
    know the true state, can do. If the true state is outside S
    too, the run ends as ``constraint_violated``.
    """
    substeps = substeps_per_control(settings.bounds.period, plant.model.opt.timestep)
    steps = round(settings.duration / settings.bounds.period)
    plant.reset(coordinates.inverse @ x0, coordinates.inverse @ dx0)
    arm = ArmLoop(plant, controller, coordinates, settings, steps)
    arm.start(x0)
    end = run_loop(arm, steps, substeps, settings.bounds.period, progress)
    k, guard = end.last_step, arm.guard
    tt, xs, dxs, taus, tau_qs, vs = arm.log.arrays()
    end_time = float(tt[-1]) if tt.size else 0.0
    if end.outcome == "diverged":
        end_time = k * settings.bounds.period
    return Trajectory(
        tt, xs, dxs, taus, tau_qs, vs, end.outcome, end_time, end.violated, end.wall_time,
        k + 1, arm.saturated, int(arm.contacts), "mujoco",
        safeguard_steps=guard.acted if guard else 0,
        safeguard_infeasible=guard.infeasible if guard else 0,
        filter_row_steps=guard.row_active_steps if guard else 0,
        rescues=guard.rescues if guard else 0,
        out_of_tests=guard.out_of_tests if guard else 0,
        rejected_samples=arm.sample.rejected,
        guarded_steps=arm.guarded_steps[: k + 1] if guard else None,
        rate_limited_steps=arm.rate_limited,
        peak_torque_rate=arm.peak_step / settings.bounds.period,
        controller_time_max=arm.compute_max,
        controller_time_mean=arm.compute_total / max(k + 1, 1),
    )


class _SystemLoop:
    """A Part I system in MuJoCo under its law u = k(x, t): the state read through the
    plant's map (every sample logged as it is read, a non-finite one too), the input written
    to ``ctrl`` and any prescribed exogenous input set before every physics step."""

    def __init__(self, plant: Plant, law: SystemLaw, model: mujoco.MjModel,
                 data: mujoco.MjData, steps: int, period: float, n: int) -> None:
        self.plant, self.law, self.model, self.data = plant, law, model, data
        self.period = period
        self.time, self.input = np.full(steps + 1, np.nan), np.full(steps + 1, np.nan)
        self.state = np.full((steps + 1, n), np.nan)
        self.qpos, self.qvel = np.zeros((steps + 1, model.nq)), np.zeros((steps + 1, model.nv))
        self.k = -1

    def observe(self) -> State | None:
        x = self.plant.read_state(self.model, self.data)
        self.k += 1
        k, data = self.k, self.data
        self.time[k], self.state[k], self.qpos[k], self.qvel[k] = (
            k * self.period, x, data.qpos, data.qvel)
        return x if all(math.isfinite(v) for v in x) else None

    def control(self, t: float, x: State) -> float | None:
        # MuJoCo's clock, which the plant's exogenous input (a road) also reads; outside its
        # domain the law raises OutsideDomainError, a ConstraintViolation
        u = self.law(x, self.data.time)
        self.input[self.k] = u
        return u if math.isfinite(u) else None

    def record(self, t: float, x: State, u: float, last: bool) -> None:
        """Nothing more: observe() and control() logged the sample."""

    def refused(self, t: float, x: State) -> None:
        """Nothing more: the sample is logged with its input undefined (NaN)."""

    def hold(self, u: float, substeps: int) -> bool:
        model, data = self.model, self.data
        self.plant.write_input(model, data, u)
        for _ in range(substeps):
            self.plant.before_step(model, data)
            mujoco.mj_step(model, data)
        return not any(data.warning[w].number for w in INSTABILITY_WARNINGS)


def run_system_mujoco(
    plant: Plant, law: SystemLaw, x0: State, duration: float,
    control_period: float | None = None, timestep: float | None = None,
    integrator: str = "RK4", progress: Progress | None = None,
) -> SystemTrajectory:
    """Run a Part I ``law`` on the plant's MJCF, holding u over each control period
    (``timestep``: the MJCF's own when None; ``control_period``: one physics step when
    None)."""
    model = plant.load()
    model.opt.timestep = timestep or model.opt.timestep
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    data = mujoco.MjData(model)
    plant.write_state(model, data, x0)
    period = control_period or model.opt.timestep
    substeps = substeps_per_control(period, model.opt.timestep)
    steps = round(duration / period)
    system = _SystemLoop(plant, law, model, data, steps, period, len(x0))
    end = run_loop(system, steps, substeps, period, progress)
    n = end.last_step + 1
    return SystemTrajectory(system.time[:n], system.state[:n], system.input[:n], end.outcome,
                            end.last_step * period, end.violated, end.wall_time, "mujoco",
                            system.qpos[:n], system.qvel[:n])


def _fallback(law: Controller, xm: Array, dxm: Array, period: float) -> Array:
    """The torque for a measurement the law refused: the law at the measured rate scaled
    back into S (when only velocity constraints are broken), else the model's brake that
    stops the measured motion in one period, b − D ẋ/h (the plant's torque box and rate
    limit clip it as they clip every command): never the last torque held, which may be
    what drives the arm out."""
    dxp = rate_into_set(law.constraints, xm, dxm)
    if dxp is not None:
        try:
            return law.evaluate(xm, dxp)[0]
        except ConstraintViolation:
            pass
    state = law.model.state(xm, dxm)
    return (state.coriolis_force + state.gravity + state.dissipation
            - state.inertia.dot(dxm) / period)


def _inside(controller: Controller, x: Array, dx: Array) -> bool:
    """Whether the true state is inside the law's admissible set."""
    m = controller.constraints.margins(x, dx)
    return bool(np.all(m > 0))


def _true_lyapunov(controller: Controller, x: Array, dx: Array) -> float:
    try:
        return controller.lyapunov(x, dx)
    except ConstraintViolation:
        return math.nan
