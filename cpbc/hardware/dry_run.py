"""``--dry-run``: everything before a motion, without moving. Connect, read the state, check
it lies inside the admissible set and the braking set, compare cpbc's model with the
robot's own (mass matrix and gravity at the measured state), time the controller on
states recorded from the robot, and try the CPU latency request the motion would hold."""

from __future__ import annotations

import time
from contextlib import suppress
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller
from cpbc.errors import ConstraintViolation, ScenarioError
from cpbc.hardware.backend import MeasuredState, RobotBackend, RobotDynamics
from cpbc.hardware.cpu_latency import LatencyRequest, cpu_latency
from cpbc.hardware.robot_run import check_fits, check_guarded, check_start, warm
from cpbc.scenario.arm_setup import ControllerEntry, ScenarioSetup


@dataclass(frozen=True)
class ModelTolerance:
    """How far cpbc's model may be from the robot's before a run is refused.

    Attributes:
        mass: per joint, |D_ii − M_ii| / M_ii (the diagonal of the mass matrix, the links'
            alone: cpbc's declared armature taken out, as franky-sim's Model leaves its
            rotors out; what a wrong load changes first).
        gravity: per joint, |g_cpbc − g_robot| [N·m] beyond ``gravity_share`` of |g_robot|.
        gravity_share: the part of the robot's gravity torque allowed on top.
    """

    mass: float = 0.15
    gravity: float = 1.0
    gravity_share: float = 0.05


@dataclass(frozen=True)
class DryRunReport:
    """What a dry run found (it raises on what it refuses)."""

    state: MeasuredState
    mass_error: Array
    gravity_error: Array
    compute_us: dict[str, float]
    law_us: dict[str, float]
    samples: int
    start_note: str | None = None
    latency: LatencyRequest | None = None  # the request tried, or None when none is asked

    def describe(self, joints: tuple[str, ...]) -> list[str]:
        worst_m, worst_g = int(np.argmax(self.mass_error)), int(np.argmax(self.gravity_error))
        t, law = self.compute_us, self.law_us
        return [
            "state: q = [" + ", ".join(f"{v:.4f}" for v in self.state.position) + "] rad, "
            f"|q̇| max {np.max(np.abs(self.state.velocity)):.3g} rad/s: "
            + (self.start_note or "inside the admissible set and the braking set"),
            f"model: mass-matrix diagonal within {100 * self.mass_error[worst_m]:.2f} % "
            f"(worst {joints[worst_m]}), gravity within {self.gravity_error[worst_g]:.3f} "
            f"N m (worst {joints[worst_g]})",
            f"on {self.samples} recorded states: the law p50 {law['p50']:.0f} µs, p99 "
            f"{law['p99']:.0f} µs, max {law['max']:.0f} µs; with its safeguard p50 "
            f"{t['p50']:.0f} µs, p99 {t['p99']:.0f} µs, max {t['max']:.0f} µs",
            self._latency(),
        ]

    def _latency(self) -> str:
        request = self.latency
        if request is None:
            return "CPU latency request: none asked for (--no-cpu-latency)"
        if request.held:
            return f"CPU latency request: {request.target_us} µs can be held during a motion"
        return (f"CPU latency request: cannot be held, {request.reason}; a motion runs "
                "without it")


def compare_models(setup: ScenarioSetup, robot: RobotDynamics, q: Array,
                   tolerance: ModelTolerance) -> tuple[Array, Array]:
    """Per joint, the relative error of cpbc's mass-matrix diagonal and the absolute error
    of its gravity torque against the robot's. Raises ScenarioError naming the joint
    beyond ``tolerance``."""
    model = setup.model
    # the links' inertia only: cpbc's D counts the armature the scenario declares
    # (robot.armature), franky-sim's Model leaves the rotors out (a real FR3's: not checked)
    ours_m, ours_g = np.diag(model.inertia(q)) - model.armature, model.gravity(q)
    theirs_m = np.diag(robot.mass)
    mass_error = np.abs(ours_m - theirs_m) / np.abs(theirs_m)
    gravity_error = np.abs(ours_g - robot.gravity)
    allowed = tolerance.gravity + tolerance.gravity_share * np.abs(robot.gravity)
    for i, joint in enumerate(model.joint_names):
        if mass_error[i] > tolerance.mass:
            raise ScenarioError("robot.model", f"{joint}: cpbc's link inertia D_ii = "
                                f"{ours_m[i]:.4g} kg m² differs from the robot's "
                                f"{theirs_m[i]:.4g} by {100 * mass_error[i]:.1f} %, beyond "
                                f"{100 * tolerance.mass:g} %: check the model and its load")
        if gravity_error[i] > allowed[i]:
            raise ScenarioError("robot.model", f"{joint}: cpbc's gravity torque "
                                f"{ours_g[i]:.4g} N m differs from the robot's "
                                f"{robot.gravity[i]:.4g} by {gravity_error[i]:.3g}, beyond "
                                f"{allowed[i]:.3g} N m: check the model and its load")
    return mass_error, gravity_error


def dry_run(setup: ScenarioSetup, entry: ControllerEntry, backend: RobotBackend,
            tolerance: ModelTolerance | None = None, samples: int = 200,
            cpu_latency_us: int | None = 0) -> DryRunReport:
    """Every check before a motion, the controller timed on ``samples`` states read from
    the robot (the robot is not moved), and the motion's CPU latency request
    (``cpu_latency_us``, None for none) held once and let go: whether it can be."""
    check_fits(setup, backend.limits(), backend.joint_names)
    check_guarded(setup, entry)
    state = backend.read()
    note = check_start(setup, state)
    mass_error, gravity_error = compare_models(
        setup, backend.dynamics(state), state.position, tolerance or ModelTolerance())
    recorded = [backend.read() for _ in range(samples)]
    warm(setup, entry, state, backend)
    law = _timed(entry.controller, recorded)
    guarded = _timed(setup.controller(entry), recorded)
    with cpu_latency(cpu_latency_us) as latency:
        pass  # held and let go: whether it can be
    return DryRunReport(state, mass_error, gravity_error, guarded, law, samples, note,
                        latency)


def _timed(controller: Controller, states: list[MeasuredState]) -> dict[str, float]:
    """p50, p99 and max of one evaluation on each state [µs], the controller primed at the
    first as a motion primes it (Controller.prime)."""
    if states:
        with suppress(ConstraintViolation):
            controller.prime(states[0].position, states[0].velocity)
    spent = []
    for s in states:
        began = time.perf_counter()
        try:
            controller.evaluate(s.position, s.velocity)
        except ConstraintViolation:
            pass  # a refusal is timed too: the runner then brakes
        spent.append(time.perf_counter() - began)
    us = np.array(spent) * 1e6
    return {"p50": float(np.percentile(us, 50)), "p99": float(np.percentile(us, 99)),
            "max": float(us.max())}
