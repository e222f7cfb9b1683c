"""One torque-controlled motion on a robot: per cycle read the state, ask the controller,
command τ_d = τ − (what the robot adds), and log it; then brake to rest and finish. The
first cycle commands 0, as a Franka requires; a controller that limits its torque's rate
(the safeguard under ``simulation.torque_rate_limit``) is told each cycle what the robot
holds, so that its command lies within the robot's rate box around the last.

Nothing clips or filters the controller's torque on its way to the robot: a command that
breaks the robot's rules is the controller's (the checks in cpbc.hardware.rules find it in
the log). The motion ends early, braking, on Ctrl-C, on a state the controller refuses, on
an exception of the controller and on a cycle whose computation overran its deadline; a
fault of the robot ends it at once (the robot has stopped). The garbage collector does not
run inside the loop.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.brakes import TorqueBox, ramped
from cpbc.controllers.controller import Controller, SafetyFilter
from cpbc.errors import ConstraintViolation, ParameterError
from cpbc.hardware.backend import MeasuredState, RobotBackend, RobotFault, RobotLimits
from cpbc.hardware.cpu_latency import latency_target
from cpbc.model.robot_model import RobotModel

#: How a motion ended.
ENDINGS = ("completed", "constraint_violated", "deadline_missed", "controller_error",
           "interrupted", "robot_error")


@dataclass(frozen=True)
class MotionSettings:
    """How long to drive and how to stop.

    Attributes:
        duration: the controller's share of the motion [s] (the brake comes after).
        deadline: the longest computation of one cycle [s]; a cycle that takes longer
            ends the motion (its late command is not sent).
        brake_time: the longest brake [s]; the motion is finished then, at rest or not.
        rest_speed: the joint speed below which the arm counts as at rest [rad/s].
        cpu_latency: the CPU latency request held while the motion runs [µs]
            (cpbc.hardware.cpu_latency: 0 keeps every core awake between the robot's
            states), or None for none.
    """

    duration: float
    deadline: float = 0.001
    brake_time: float = 1.0
    rest_speed: float = 0.01
    cpu_latency: int | None = 0

    def __post_init__(self) -> None:
        for name in ("duration", "deadline", "brake_time", "rest_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ParameterError(name, f"{name} must be a finite number > 0, got {value}")
        if self.cpu_latency is not None:
            latency_target(self.cpu_latency, "cpu_latency")


@dataclass(frozen=True)
class MotionLog:
    """One motion, a row per cycle (the brake's included, ``braking`` set there).

    Attributes:
        time: the robot's clock since the motion's first state [s].
        position, velocity: as measured.
        torque: the controller's τ (NaN while braking or where it gave none).
        commanded_torque: τ_d as sent (gravity excluded); NaN where nothing was sent.
        lyapunov: the controller's V (NaN where undefined).
        compute_time: this computer's time from reading the state to sending [s].
        compute_cpu_time: the controlling thread's CPU time over the same span [s]: where it
            is well below ``compute_time`` the cycle waited for a CPU (other processes, the
            host), not for its own work.
        read_wait: how long the read of the state blocked, from the call to the state in
            hand [s] (NaN on the brake's rows and the first): the rest of the robot's cycle
            as this computer saw it.
        lost: cycles the robot ran since the previous state beyond the one expected.
        braking: whether the row is the brake's.
        ending: one of ENDINGS.
        violated: the constraint the controller refused the state for, if that ended it.
        detail: what ended it, in words ("" when it completed).
        fault: the robot's fault, when one ended it.
    """

    time: Array
    position: Array
    velocity: Array
    torque: Array
    commanded_torque: Array
    lyapunov: Array
    compute_time: Array
    compute_cpu_time: Array
    lost: Array
    read_wait: Array
    braking: Array
    ending: str
    violated: str | None = None
    detail: str = ""
    fault: RobotFault | None = None

    @property
    def controlled(self) -> Array:
        """The rows of the controller's cycles (not the brake's)."""
        return np.logical_not(self.braking)


class _Recorder:
    """Preallocated rows, filled one cycle at a time."""

    def __init__(self, rows: int, n: int) -> None:
        self.time = np.full(rows, np.nan)
        self.position, self.velocity = np.full((rows, n), np.nan), np.full((rows, n), np.nan)
        self.torque, self.command = np.full((rows, n), np.nan), np.full((rows, n), np.nan)
        self.lyapunov, self.compute = np.full(rows, np.nan), np.full(rows, np.nan)
        self.wait, self.cpu = np.full(rows, np.nan), np.full(rows, np.nan)
        self.lost = np.zeros(rows)  # whole numbers
        self.braking = np.zeros(rows, dtype=bool)
        self.k = 0
        self.start: float | None = None

    def state(self, s: MeasuredState, braking: bool = False) -> int:
        """Log a state read; its row."""
        k = self.k
        if self.start is None:
            self.start = s.time
        self.time[k] = s.time - self.start
        self.position[k], self.velocity[k] = s.position, s.velocity
        self.lost[k], self.braking[k] = s.lost, braking
        self.k += 1
        return k

    def log(self, ending: str, violated: str | None = None, detail: str = "",
            fault: RobotFault | None = None) -> MotionLog:
        k = self.k
        return MotionLog(self.time[:k], self.position[:k], self.velocity[:k],
                         self.torque[:k], self.command[:k], self.lyapunov[:k],
                         self.compute[:k], self.cpu[:k], self.lost[:k], self.wait[:k],
                         self.braking[:k],
                         ending, violated, detail, fault)


@dataclass
class _Ending:
    ending: str = "completed"
    violated: str | None = None
    detail: str = ""


def _drive(backend: RobotBackend, controller: Controller, state: MeasuredState, steps: int,
           deadline: float, rec: _Recorder, sent: Array,
           end: _Ending) -> tuple[MeasuredState, int] | None:
    """The motion's ``steps`` cycles from its first ``state``: the first answered with 0 (a
    Franka's first command; its own gravity compensation holds the arm), every later one by
    the controller, told first what the robot holds (:func:`_holder`). Returns the state
    (and its row) that an early end left unanswered, or None. ``sent`` holds the last
    command sent (updated in place)."""
    clock, cpu = time.perf_counter, time.thread_time
    hold = _holder(controller)
    pending = None
    try:
        row = rec.state(state)
        backend.write(sent)  # 0
        rec.command[row] = sent
        _prime(controller, state)
        for k in range(1, steps):
            called = clock()
            state = backend.read()
            read = clock()
            row = rec.state(state)
            rec.wait[row] = read - called
            pending = state, row
            began, began_cpu = clock(), cpu()
            added = backend.added_torque(state)
            if hold is not None:
                hold(sent + added, added)
            try:
                tau, v = controller.evaluate(state.position, state.velocity)
            except ConstraintViolation as exc:
                end.ending, end.violated = "constraint_violated", exc.constraint
                end.detail = str(exc)
                return pending
            except Exception as exc:  # any failure of the controller: brake, then report it
                end.ending, end.detail = "controller_error", f"{type(exc).__name__}: {exc}"
                return pending
            command = tau - added
            spent = clock() - began
            rec.cpu[row] = worked = cpu() - began_cpu
            rec.torque[row], rec.lyapunov[row], rec.compute[row] = tau, v, spent
            if spent > deadline:
                end.ending = "deadline_missed"
                end.detail = (f"cycle {k} computed for {spent * 1e3:.3g} ms ({worked * 1e3:.3g}"
                              f" ms of it on a CPU), beyond the deadline of "
                              f"{deadline * 1e3:.3g} ms")
                return pending
            backend.write(command)
            pending = None  # answered (Python checks for Ctrl-C between the two lines only)
            rec.command[row] = command
            sent[:] = command
    except KeyboardInterrupt:  # the state read, if any, is the brake's to answer
        end.ending, end.detail = "interrupted", "interrupted (Ctrl-C)"
        return pending
    return None


def _holder(controller: Controller) -> Callable[[Array, Array], None] | None:
    """How to tell ``controller`` the torque the robot holds (its own convention: the last
    command plus what the robot adds at the new state) and what the robot adds, when it
    limits the torque's rate of change from it: then each command lies within the rate box
    of the last and within the robot's box, which bounds the command, gravity excluded, as
    the robot's rules ask; None for a controller that does not."""
    if isinstance(controller, SafetyFilter):  # a guarded reference tracker too
        return controller.holding
    return None


def _prime(controller: Controller, state: MeasuredState) -> None:
    """Prime the controller at the first state (Controller.prime) in the first cycle,
    answered already: the set-up before it left the caches cold. Whatever it raises (a
    refused state, a fault) is the first evaluation's to report, which runs the same code
    and ends the motion with the brake; raised here, it would end it without one."""
    with suppress(Exception):
        controller.prime(state.position, state.velocity)


def _brake(backend: RobotBackend, model: RobotModel, limits: RobotLimits,
           settings: MotionSettings, rec: _Recorder, sent: Array,
           pending: tuple[MeasuredState, int] | None) -> int:
    """Brake until the arm rests (or ``brake_time`` has passed), then finish the motion: on
    0 when at rest (then within a step of it), else on the last brake command. ``pending``
    is a state the controller left unanswered, answered first. Returns the Ctrl-C presses it
    outlasted.

    The brake is the safeguard's uniform one (cpbc.constraints.brakes), in the controller's
    model: b − D q̇/h scaled into the robot's torque box, reached from what the robot holds
    as far as one step of its torque rate allows (``brakes.ramped``): every joint slows in
    proportion to its speed, and the command never steps by more than the robot allows.
    It is the brake that defines the safeguard's braking set: from a state the safeguard
    kept in that set it stops the arm before every configuration boundary, in the model.
    (It knows no target: after a deadline the last law's torque is not trusted.)"""
    step, period = limits.torque_step, limits.period
    cycles = max(1, round(settings.brake_time / period))
    command = sent.copy()
    ignored = 0
    for i in range(cycles):
        try:
            if pending is None:
                state = backend.read()
                row = rec.state(state, braking=True)
            else:
                (state, row), pending = pending, None
            added = backend.added_torque(state)
            arm = model.state(state.position, state.velocity)
            bias = arm.coriolis_force + arm.gravity + arm.dissipation
            # the robot's box bounds the command, gravity excluded: τ − added
            box = TorqueBox(limits.torque, lower=added - limits.torque,
                            upper=added + limits.torque)
            stop = box.toward(bias, bias - arm.inertia.dot(arm.dx) / period)
            held = command
            command = ramped(box, stop, step, held + added) - added
            # at rest, and 0 one step from what the robot holds: end on 0
            rests = bool(np.max(np.abs(state.velocity)) < settings.rest_speed
                         and np.all(np.abs(held) <= step))
            if rests or i == cycles - 1:
                final = np.zeros_like(command) if rests else command
                backend.finish(final)
                rec.command[row] = final
                return ignored
            backend.write(command)
            rec.command[row] = command
        except KeyboardInterrupt:  # the brake is the way out: it runs to its end
            ignored += 1
    return ignored


@contextmanager
def collected() -> Iterator[None]:
    """A last garbage collection, then none until the block ends: what exists is frozen
    (never scanned again) and the collector is off. The collection walks every object and
    leaves the caches cold, so warm the controller inside the block, after it (a first cycle
    took 0.7–0.8 ms on the lock-step FR3 warmed before it, 0.21 ms warmed after)."""
    collecting = gc.isenabled()
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        gc.unfreeze()
        if collecting:
            gc.enable()


def run_motion(backend: RobotBackend, controller: Controller, settings: MotionSettings,
               collect: bool = True) -> MotionLog:
    """Drive ``controller`` on ``backend`` for ``settings.duration``, then brake and
    finish (or stop at a robot fault). Positions and torques are the robot's joints', in
    its order; the controller must work in joint coordinates. No garbage is collected in the
    motion (:func:`collected`; ``collect`` False: the caller's block is one already)."""
    if collect:
        with collected():
            return run_motion(backend, controller, settings, collect=False)
    limits = backend.limits()
    n = len(backend.joint_names)
    steps = round(settings.duration / limits.period)
    brake_rows = max(1, round(settings.brake_time / limits.period))
    rec = _Recorder(steps + brake_rows, n)
    sent = np.zeros(n)
    end = _Ending()
    try:
        first = backend.start()
        pending = _drive(backend, controller, first, steps, settings.deadline, rec, sent, end)
        if _brake(backend, controller.model, limits, settings, rec, sent, pending):
            end.detail += "; Ctrl-C pressed again while braking: the brake ran to its end"
    except RobotFault as fault:
        return rec.log("robot_error", end.violated, f"{fault}", fault)
    return rec.log(end.ending, end.violated, end.detail)
