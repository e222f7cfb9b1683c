"""A scenario's controller on a robot: the checks that the scenario fits the robot and the
robot's state fits the scenario, the warm-up, one motion (cpbc.hardware.motion), and the
same files as ``cpbc.run`` writes (summary.json, summary.csv, trajectories.h5, view.html).

The scenario's ``cases`` are not used: the motion starts from the state the robot reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.controllers.controller import Controller, SafetyFilter
from cpbc.controllers.safeguard import Safeguard
from cpbc.errors import ConstraintViolation, InadmissibleStateError, ScenarioError
from cpbc.hardware.backend import MeasuredState, RobotBackend, RobotLimits
from cpbc.hardware.cpu_latency import LatencyRequest, cpu_latency
from cpbc.hardware.lockstep import LockstepBackend
from cpbc.hardware.motion import MotionLog, MotionSettings, collected, run_motion
from cpbc.hardware.rules import RuleReport, check_rules
from cpbc.model import RobotModel
from cpbc.reference.tracker import ReferenceTracker
from cpbc.results import ArmLabels, log_file, staged_output, write_summaries, write_trajectory
from cpbc.results.hdf5_log import LOG_FILE, write_signals
from cpbc.results.margin_types import types_of
from cpbc.results.metrics import RunSummary, margin_history, summarise
from cpbc.results.reference_metrics import judged_reference
from cpbc.results.task_metrics import task_errors
from cpbc.scenario.arm_setup import CaseEntry, ControllerEntry, ScenarioSetup
from cpbc.scenario.state_checks import check_admissible, check_stoppable
from cpbc.simulation.trajectory import Trajectory

#: The run's case name in the files: the robot's own start.
CASE = "robot"
#: Evaluations of a spare copy of the controller before the motion, at the start state and
#: at seeded velocities around it (numba's kernels, Pinocchio's and numpy's first calls).
WARM_CALLS = 64
#: The safeguard's rescue budget on a robot (model periods a cycle) when the scenario sets
#: none: a rescue checks its brake while holding it instead of computing for tens of
#: milliseconds while the robot holds the last command (docs/hardware.md's campaign: with it
#: 0 crossings and 1 lost state, without it 2 crossings and 188 lost states).
ROBOT_RESCUE_BUDGET = 8
#: The candidate torques one safeguard step may test on a robot when the scenario sets none
#: (cpbc.controllers.safeguard.step_budget): with the rescue's budget, a bound on the cycle.
ROBOT_TEST_BUDGET = 6
#: The share of a cycle's deadline the safeguard may spend testing torques on a robot: a test
#: begins only where a candidate as long as the cycle's longest so far ends within it, else the
#: cycle holds the last torque that passed or the uniform brake at once
#: (cpbc.controllers.safeguard.step_budget), leaving the rest of the deadline to the state,
#: the law and the command's way out. The law's own torque is always tested, so calm cycles
#: never feel it, and the tightest budget, the law's torque alone, kept every rate-campaign
#: start inside the braking set (docs/reliability.md) — not yet every start of the figure
#: eight's task-space law, which needs the rescue's search that no spent step asks.
ROBOT_TIME_SHARE = 0.15


def on_robot(setup: ScenarioSetup, deadline: float | None = None) -> ScenarioSetup:
    """The set-up as a robot runs it: the safeguard's rescue bounded to ROBOT_RESCUE_BUDGET
    model periods a cycle and its step to ROBOT_TEST_BUDGET tests, each unless the scenario
    sets it itself (``simulation.safeguard_rescue_budget``, ``safeguard_test_budget``,
    ``safeguard_time_budget``: a number, or null for no bound), and, given the cycle's
    ``deadline`` [s], to testing for ROBOT_TIME_SHARE of it. In simulation time costs
    nothing and the defaults are no bound (cpbc.controllers.rescue: a rescue budget keeps
    fewer runs there)."""
    if setup.safeguard is None:
        return setup
    given = setup.scenario.simulation.model_fields_set
    guard = setup.safeguard
    if "safeguard_rescue_budget" not in given:
        guard = replace(guard, rescue_budget=ROBOT_RESCUE_BUDGET)
    if "safeguard_test_budget" not in given:
        guard = replace(guard, test_budget=ROBOT_TEST_BUDGET)
    if deadline is not None and "safeguard_time_budget" not in given:
        guard = replace(guard, time_budget=ROBOT_TIME_SHARE * deadline)
    return replace(setup, safeguard=guard)


def choose_controller(setup: ScenarioSetup, name: str | None) -> ControllerEntry:
    """The scenario's controller called ``name``, or its only one."""
    names = [c.name for c in setup.controllers]
    if name is None:
        if len(names) > 1:
            raise ScenarioError("--controller", f"the scenario has {len(names)} controllers "
                                f"({', '.join(names)}): choose one with --controller NAME")
        return setup.controllers[0]
    for entry in setup.controllers:
        if entry.name == name:
            return entry
    raise ScenarioError("--controller", f"no controller '{name}' in the scenario; it has "
                        f"{', '.join(names)}")


def check_fits(setup: ScenarioSetup, limits: RobotLimits, joints: tuple[str, ...]) -> None:
    """Refuse a scenario that is not for this robot or reaches past its limits, naming the
    field: its joints, coordinates, control period, torque and torque-rate limits and rate
    bounds."""
    model = setup.model
    if model.joint_names != joints:
        raise ScenarioError("robot.model", f"the scenario's joints {list(model.joint_names)} "
                            f"are not the robot's {list(joints)}")
    if not model.coordinates.is_identity:
        raise ScenarioError("robot.coordinates", "a robot is driven in its joint coordinates: "
                            "use coordinates: joint")
    period = setup.loop_settings.bounds.period
    if not math.isclose(period, limits.period, rel_tol=1e-9):
        raise ScenarioError("simulation.control_period", f"{period:g} s, but the robot's "
                            f"control period is {limits.period:g} s: give {limits.period:g}")
    box = setup.loop_settings.bounds.torque
    if box is None or np.any(box > limits.torque * (1 + 1e-9)):
        raise ScenarioError("simulation.torque_limit", "must lie inside the robot's torque "
                            f"limits {limits.torque.tolist()} N m (from_model reads them)")
    rate = setup.loop_settings.bounds.rate
    if rate is None or np.any(rate > limits.torque_rate * (1 + 1e-9)):
        raise ScenarioError("simulation.torque_rate_limit", "must lie inside the robot's "
                            f"torque-rate limits {limits.torque_rate.tolist()} N m/s (give "
                            "from_model): a command may change by no more in a cycle")
    for i, bound in enumerate(setup.rate_bounds):
        if bound is not None and bound > limits.velocity[i] * (1 + 1e-9):
            raise ScenarioError("constraints", f"the rate bound {bound:g} rad/s of "
                                f"{joints[i]} reaches past the robot's "
                                f"{limits.velocity[i]:g} rad/s")


def check_guarded(setup: ScenarioSetup, entry: ControllerEntry) -> None:
    """Refuse a controller that would drive the robot without a safety filter, naming it:
    only a filter (the safeguard around a constrained law, or a peer's) chooses each torque
    within the robot's rate box around what it holds; a bare law steps as far as it likes
    (PD + g stepped 59.6 N·m in one cycle on the lock-step Panda, where the FR3 allows 1)."""
    law = entry.controller
    if isinstance(law, SafetyFilter) or (setup.safeguard is not None
                                         and not law.constraints.empty):
        return
    why = ("it keeps no constraint" if law.constraints.empty
           else "the scenario turns the safeguard off")
    raise ScenarioError("--controller", f"'{entry.name}' would drive the robot without the "
                        f"safeguard ({why}), and nothing else keeps its torque within the "
                        "robot's torque rate: choose a constrained controller of the scenario")


def check_start(setup: ScenarioSetup, state: MeasuredState) -> str | None:
    """Refuse a measured state outside the admissible set, or that no brake within the
    torque (and torque-rate) limits stops; a state outside the braking set that the
    safeguard's rescue brake stops runs, and the note saying so is returned."""
    try:
        check_admissible(setup.monitor, state.position, state.velocity,
                         "the robot's measured state", "robot state")
    except InadmissibleStateError as exc:
        raise ScenarioError("robot state", str(exc)) from None
    loop = setup.loop_settings
    if loop.bounds.torque is None:
        return None
    try:
        notes = check_stoppable([CaseEntry(CASE, state.position, state.velocity)],
                                setup.monitor, setup.model, loop.bounds.torque,
                                loop.bounds.period, loop.bounds.rate)
    except ScenarioError as exc:
        raise ScenarioError("robot state", exc.message) from None
    return notes.get(CASE)


def warm(setup: ScenarioSetup, entry: ControllerEntry, state: MeasuredState,
         backend: RobotBackend, calls: int = WARM_CALLS) -> None:
    """Run every path a cycle can take once before the motion, on a spare copy of the
    controller (the one that drives starts with fresh counts): its evaluation at the start
    and at seeded velocities around it; each path of its safeguard's step — the slide, the
    brakes, the search, the blend, the rescue, the fallback — at the start and moving
    (Safeguard.warm), which the calm start never takes and whose first call costs
    milliseconds; and the robot's own torque."""
    spare = setup.controller(entry)
    rng = np.random.default_rng(0)
    speeds = backend.limits().velocity
    for i in range(calls):
        dq = state.velocity + (0.05 * i / calls) * speeds * rng.uniform(-1, 1, len(speeds))
        try:
            spare.evaluate(state.position, dq)
        except ConstraintViolation:
            continue
    guard = spare.run if isinstance(spare, ReferenceTracker) else spare
    if isinstance(guard, Safeguard):
        for share in (0.0, 0.3):
            try:
                guard.warm(state.position, state.velocity + share * speeds)
            except ConstraintViolation:
                continue
    backend.added_torque(backend.read())


def pack(law: Controller) -> None:
    """Pack the law's terms now (cpbc.controllers.packed_law), not in the first cycle: a
    reference tracker steers the scenario's law in place when it is built, which the next
    step would pack again (0.4-1 ms on a shared machine: past a 1 ms deadline)."""
    packed_law = getattr(law, "packed_law", None)
    if callable(packed_law):
        packed_law()


@dataclass(frozen=True)
class HardwareRun:
    """A motion with what cpbc.run would have made of it."""

    controller: str
    motion: MotionLog
    trajectory: Trajectory
    margins: Array
    summary: RunSummary
    rules: RuleReport
    task_error: Array | None = None
    start_note: str | None = None  # a start outside the braking set that a rescue stops
    latency: LatencyRequest | None = None  # the CPU latency request, if one was asked for


def _trajectory(motion: MotionLog, guard: Controller, period: float) -> Trajectory:
    """The motion as the results layer reads a run: the applied torque is the command
    (gravity excluded: what the robot's torque box and rate limit bound), its peak rate
    counted from the 0 the robot held before the motion."""
    outcome = "constraint_violated" if motion.ending == "constraint_violated" else "completed"
    end_time = float(motion.time[-1]) if motion.time.size else 0.0
    steps = int(motion.controlled.sum())
    wall = float(np.nansum(motion.compute_time))
    safe = guard if isinstance(guard, SafetyFilter) else None
    sent = motion.commanded_torque[np.all(np.isfinite(motion.commanded_torque), axis=1)]
    steps_d = np.abs(np.diff(sent, axis=0, prepend=np.zeros((1, sent.shape[1]))))
    peak_rate = (steps_d.max(axis=0) if len(sent) else np.zeros(sent.shape[1])) / period
    return Trajectory(
        motion.time, motion.position, motion.velocity, motion.torque,
        motion.commanded_torque, motion.lyapunov, outcome, end_time, motion.violated, wall,
        steps, 0, 0, "robot",
        safeguard_steps=safe.acted if safe else 0,
        safeguard_infeasible=safe.infeasible if safe else 0,
        filter_row_steps=safe.row_active_steps if safe else 0,
        rescues=safe.rescues if safe else 0,
        out_of_tests=safe.out_of_tests if safe else 0,
        peak_torque_rate=peak_rate,
    )


def _timing(motion: MotionLog) -> dict[str, float]:
    """The cycle's computation in µs (p50, p99, p99.9, max), on the wall clock and in the
    thread's CPU time, the lost states and the brake's cycles, for the summary."""
    out: dict[str, float] = {}
    for key, times in (("compute_us", motion.compute_time),
                       ("compute_cpu_us", motion.compute_cpu_time)):
        spent = times[np.isfinite(times)] * 1e6
        out.update({f"{key}_{k}": float(np.percentile(spent, p)) if spent.size else math.nan
                    for k, p in (("p50", 50), ("p99", 99), ("p999", 99.9))})
        out[f"{key}_max"] = float(spent.max()) if spent.size else math.nan
    out["lost_states"] = float(motion.lost.sum())
    out["brake_cycles"] = float(motion.braking.sum())
    return out


def run_on_robot(setup: ScenarioSetup, entry: ControllerEntry, backend: RobotBackend,
                 settings: MotionSettings) -> HardwareRun:
    """Check, warm, drive and summarise one motion of ``entry`` on ``backend`` (its safeguard
    as :func:`on_robot` sets it)."""
    setup = on_robot(setup, settings.deadline)
    limits = backend.limits()
    check_fits(setup, limits, backend.joint_names)
    check_guarded(setup, entry)
    state = backend.read()
    note = check_start(setup, state)
    with cpu_latency(settings.cpu_latency) as latency, collected():
        # warmed after the last collection, which leaves the caches cold
        warm(setup, entry, state, backend)
        guard = setup.controller(entry)  # after the spare: a tracker steers the law when built
        pack(entry.controller)
        motion = run_motion(backend, guard, settings, collect=False)
    traj = _trajectory(motion, guard, limits.period)
    margins = margin_history(setup.monitor, traj)
    summary = summarise(entry.name, CASE, entry.controller, setup.monitor, traj,
                        setup.criteria, setup.rate_bounds, margins, limits.torque, None,
                        setup.model.length_coordinates, limits.torque_rate)
    rules = check_rules(motion.commanded_torque, limits, margins, setup.monitor.names,
                        motion.position, motion.velocity)
    cause = None if motion.ending == "completed" else f"{motion.ending}: {motion.detail}"
    kept = setup.safeguard
    budget = None if kept is None else kept.rescue_budget
    tests = None if kept is None else kept.test_budget
    extra = {**summary.extra, **_timing(motion), "steps_over_rate": float(rules.steps_over),
             "velocity_over_limit": float(rules.velocity_over),
             "rescue_budget": math.nan if budget is None else float(budget),
             "test_budget": math.nan if tests is None else float(tests),
             "time_budget_us": math.nan if kept is None or kept.time_budget is None
             else 1e6 * kept.time_budget,
             "cpu_latency_us": float(latency.target_us) if latency is not None
             and latency.held else math.nan}
    summary = replace(summary, extra=extra, cause=cause)
    errors = None
    if isinstance(guard, ReferenceTracker) and setup.goal is not None:
        # judged as cpbc.run judges a reference run: tracked, blocked, stalled, …
        summary, log = judged_reference(setup.model, setup.goal.goal, guard, traj, summary,
                                        setup.monitor, margins, setup.criteria)
        errors = log.task_error
    elif setup.goal is not None:
        errors = task_errors(setup.model, setup.goal.goal, traj.position)
    return HardwareRun(entry.name, motion, traj, margins, summary, rules, errors, note,
                       latency)


def write_run(out: Path, setup: ScenarioSetup, run: HardwareRun) -> None:
    """summary.json, summary.csv, trajectories.h5 and the page (view.html, no figures) into
    ``out`` (staged: all or nothing), the log with ``commanded_torque``, ``compute_time``,
    ``compute_cpu_time``, ``lost`` and ``braking`` too."""
    model = setup.model
    labels = ArmLabels(
        setup.coordinate_names, tuple(bool(v) for v in model.length_coordinates),
        model.joint_names, tuple(bool(v) for v in model.length_joints),
        setup.monitor.names, types_of(setup.monitor, model.length_coordinates))
    motion = run.motion
    with staged_output(out) as scratch:
        with log_file(scratch / LOG_FILE, setup.scenario.name) as log:
            write_trajectory(log, CASE, run.controller, run.trajectory, run.margins,
                             run.trajectory.lyapunov, setup.target, labels,
                             run.summary.as_dict(), run.task_error)
            write_signals(log, CASE, run.controller, {
                "commanded_torque": (motion.commanded_torque, "N m", model.joint_names),
                "compute_time": (motion.compute_time, "s", ()),
                "compute_cpu_time": (motion.compute_cpu_time, "s", ()),
                "lost": (motion.lost, "", ()),
                "read_wait": (motion.read_wait, "s", ()),
                "braking": (motion.braking.astype(np.uint8), "", ()),
            })
        write_summaries(scratch, [run.summary])
        from cpbc.viewer.outputs import write_run_outputs  # the page's modules: after the motion

        write_run_outputs(scratch, setup, plots=False)


def lockstep_for(setup: ScenarioSetup, torque_rate: float = 1000.0) -> LockstepBackend:
    """The scenario's arm as a lock-step robot: its MuJoCo plant started at the first case,
    a separate copy of its model as the robot's own (gravity compensation, mass matrix),
    the model's effort limits as its torque box (the scenario's where it declares none),
    the model's velocity limits (and a named arm's position-dependent ones) and the
    scenario's control period; ``torque_rate``
    [N·m/s] on every joint (the FR3's by default)."""
    model = setup.model
    own_model = pin.Model(model.model)  # not the controller's data
    # its Model as libfranka's (franky-sim's): the links' inertia without the rotors
    own_model.armature[:] = 0.0
    own = RobotModel(own_model, name=model.name)
    effort = np.array(model.model.effortLimit, dtype=float)
    given = setup.loop_settings.bounds.torque
    if not np.all(np.isfinite(effort) & (effort > 0)):
        if given is None:
            raise ScenarioError("simulation.torque_limit", "a robot has a torque box: give "
                                "the motors' limits")
        effort = np.asarray(given, dtype=float)
    limits = RobotLimits(effort, np.full(model.n, float(torque_rate)),
                         np.array(model.model.velocityLimit, dtype=float),
                         setup.loop_settings.bounds.period,
                         None if setup.arm is None else setup.arm.velocity_limits)
    case = setup.cases[0]
    return LockstepBackend(setup.make_plant(), model.joint_names, limits, own.gravity,
                           own.inertia, case.position, case.velocity)
