"""Run every controller of a scenario on every case and collect the results: an arm's
scenario, or a Part I system's (``system:``), whose laws run on its cases through the same
closed loop (cpbc.simulation.loop) and are summarised for the same files.

An arm's runs are independent, so with ``workers > 1`` they go to separate processes; each
process rebuilds the setup from the scenario (Pinocchio and MuJoCo objects are not shared).
A Part I scenario's runs are short and run in this process.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace
from pathlib import Path

from cpbc.constraints.constraint_types import Array
from cpbc.errors import ScenarioError
from cpbc.reference.tracker import ReferenceTracker
from cpbc.results.drawing import quiet_on_interrupt
from cpbc.results.metrics import RunSummary, margin_history, summarise
from cpbc.results.reference_metrics import judged_reference
from cpbc.results.system_metrics import summarise_system
from cpbc.results.task_metrics import task_errors, task_outcome
from cpbc.scenario.build import CaseEntry, ControllerEntry, ScenarioSetup, build
from cpbc.scenario.schema import Scenario
from cpbc.scenario.system_setup import SystemCase, SystemLaw, SystemSetup, check_backend
from cpbc.simulation import (
    MujocoPlant,
    SystemTrajectory,
    Trajectory,
    run_mujoco,
    run_reference,
    run_system_mujoco,
    run_system_reference,
)

RunProgress = Callable[[str, float], None]


@dataclass(frozen=True)
class RunResult:
    controller: str
    case: str
    trajectory: Trajectory
    margins: Array
    lyapunov: Array
    summary: RunSummary
    task_error: Array | None = None  # a goal run's (position m, angle rad) per sample
    # a reference run's per-sample path_time, applied, requested and blocked
    reference: dict[str, Array] | None = None


def run_one(
    setup: ScenarioSetup,
    case: CaseEntry,
    entry: ControllerEntry,
    backend: str,
    plant: MujocoPlant | None = None,
    progress: RunProgress | None = None,
) -> RunResult:
    """One controller on one case."""
    label = f"{case.name} / {entry.name}"

    def report(frac: float) -> None:
        if progress is not None:
            progress(label, frac)

    entry = setup.for_case(case, entry)  # its own set point when its start is wound
    law = setup.controller(entry, case) if backend == "mujoco" else entry.controller
    if backend == "mujoco":
        traj = run_mujoco(
            plant or setup.make_plant(), law, setup.model.coordinates,
            case.position, case.velocity, setup.loop_settings, report,
        )
    else:
        traj = run_reference(
            setup.make_reference_plant(), entry.controller, case.position, case.velocity,
            setup.loop_settings,
        )
    report(1.0)
    margins = margin_history(setup.monitor, traj)
    summary = summarise(
        entry.name, case.name, entry.controller, setup.monitor, traj, setup.criteria,
        setup.rate_bounds, margins, setup.loop_settings.bounds.torque,
        setup.model.coordinates.matrix, setup.model.length_coordinates,
        setup.loop_settings.bounds.rate,
    )
    errors, logged = None, None
    if isinstance(law, ReferenceTracker) and setup.goal is not None:
        summary, log = judged_reference(setup.model, setup.goal.goal, law, traj, summary,
                                        setup.monitor, margins, setup.criteria)
        errors = log.task_error
        logged = {"path_time": log.path_time, "applied": log.applied,
                  "requested": log.requested, "blocked": log.blocked, "path_lag": log.path_lag}
    elif setup.goal is not None:
        errors = task_errors(setup.model, setup.goal.goal, traj.position)
        outcome = task_outcome(setup.model, setup.goal.goal, setup.goal.preflight.verdict,
                               traj, summary.status, setup.monitor, margins, setup.criteria,
                               errors, entry.controller,
                               beyond_reach=setup.goal.preflight.beyond_reach is not None)
        # a goal run settles when it enters the goal's band for good, not at the posture
        summary = replace(summary, **outcome.__dict__, settle_time=outcome.reach_time)
    joints = setup.joint_dynamics.summary()
    summary = replace(summary, armature=joints.pop("armature"), friction={
        **joints, "smoothing": setup.model.friction_smoothing,
        "compensation": entry.friction_compensation})
    load = setup.gravity_on_path.get(case.name)
    if load is not None and summary.failed:
        summary = replace(summary, cause=load.describe())
    return RunResult(entry.name, case.name, traj, margins, traj.lyapunov, summary, errors,
                     logged)


@dataclass(frozen=True)
class SystemResult:
    """One law of a Part I scenario on one case."""

    case: str
    controller: str
    trajectory: SystemTrajectory
    summary: RunSummary


def run_system_one(setup: SystemSetup, case: SystemCase, law: SystemLaw, backend: str,
                   progress: RunProgress | None = None) -> SystemResult:
    """One law of a Part I scenario on one case."""
    sim = setup.scenario.simulation
    label = f"{case.name} / {law.name}"

    def report(frac: float) -> None:
        if progress is not None:
            progress(label, frac)

    from cpbc.systems.ode_plant import Plant  # with a Part I scenario only

    k = law.for_case(case.name)
    if backend == "mujoco":
        if not isinstance(case.plant, Plant):  # check_backend refuses it first
            raise ScenarioError("simulation.backend", "this system has no MuJoCo model")
        traj = run_system_mujoco(case.plant, k, case.state, sim.duration,
                                 setup.control_period, sim.timestep, sim.integrator, report)
    else:
        traj = run_system_reference(case.plant, k, case.state, sim.duration,
                                    setup.control_period)
    report(1.0)
    summary = summarise_system(case.name, law.name, traj, case.plant.constrained, setup.view,
                               setup.state_names, setup.input_name, sim.tolerance,
                               law.barrier)
    return SystemResult(case.name, law.name, traj, summary)


def run_systems(setup: SystemSetup, backend: str | None = None,
                progress: RunProgress | None = None) -> list[SystemResult]:
    """Every (case, law) pair of a Part I scenario, case-major; ``backend`` overrides the
    scenario's."""
    check_backend(setup, backend or setup.scenario.simulation.backend,
                  "simulation.backend" if backend is None else "backend")
    backend = backend or setup.scenario.simulation.backend
    return [run_system_one(setup, c, law, backend, progress)
            for c in setup.cases for law in setup.laws]


def worker_payload(scenario: Scenario) -> str:
    """The scenario as a worker receives it: only the keys the user gave (``exclude_unset``),
    so that the rebuilt scenario has the same values *and* the same record of what was given;
    a default that depends on "was it given?" then resolves in the worker as it did here."""
    return scenario.model_dump_json(exclude_unset=True)


def scenario_in_worker(payload: str) -> Scenario:
    """The scenario a worker rebuilds from :func:`worker_payload`."""
    return Scenario.model_validate_json(payload)


@functools.lru_cache(maxsize=1)
def _setup_in_worker(payload: str, source: Path) -> ScenarioSetup:
    """The setup of a scenario, built once per worker process (a worker runs several pairs)."""
    return build(scenario_in_worker(payload), source)


def setups_built() -> int:
    """How many scenario setups this process has built for worker runs (a check that a
    worker took part)."""
    return _setup_in_worker.cache_info().misses


def _run_in_worker(
    scenario: Scenario, source: Path, case: str, controller: str, backend: str
) -> RunResult:
    """Worker entry: the setup from its scenario (built once per process), then one pair."""
    setup = _setup_in_worker(worker_payload(scenario), source)
    case_entry = next(c for c in setup.cases if c.name == case)
    entry = next(c for c in setup.controllers if c.name == controller)
    return run_one(setup, case_entry, entry, backend)


def default_workers(runs: int) -> int:
    """One process per run, at most one per core (serial for a single run)."""
    return max(1, min(runs, os.cpu_count() or 1))


def default_processes() -> int:
    """Processes a scenario run may use, this one included: one per core."""
    return max(1, os.cpu_count() or 1)


def _warm_up() -> None:
    """Worker initialiser: import what its tasks need (figures, runs) while the main
    process is busy, so that the first task does not wait for it."""
    quiet_on_interrupt()
    import cpbc.results.plots  # noqa: F401


def worker_pool(workers: int, warm: bool = False) -> ProcessPoolExecutor:
    """Processes for independent runs (and figures): spawned, so no simulator state is
    inherited; each builds its own Pinocchio and MuJoCo objects. With ``warm`` each starts
    importing at once (a pool is otherwise started lazily, by its first task)."""
    pool = ProcessPoolExecutor(max_workers=workers,
                               initializer=_warm_up if warm else quiet_on_interrupt,
                               mp_context=multiprocessing.get_context("spawn"))
    if warm:
        for _ in range(workers):
            pool.submit(int)  # starts the processes now
    return pool


def _expected_cost(entry: ControllerEntry) -> int:
    """A rough relative cost of a run, to start the longest first: a step costs more the
    more constraints the law (and its safeguard) evaluates; a baseline enforces none."""
    return len(entry.controller.constraints.names)


#: Estimated seconds of simulation left after the first run above which the rest is shared
#: with worker processes: a worker first spends 1.5–3 s here importing and building the
#: setup, and on a shared machine the second core may be busy anyway.
OFFLOAD_AFTER = 2.5


class LazyPool:
    """Worker processes started only when first asked for (``get``); a context manager
    that shuts them down if they were started. A short scenario never starts any."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.started: ProcessPoolExecutor | None = None

    def get(self) -> ProcessPoolExecutor:
        if self.started is None:
            self.started = worker_pool(self.workers, warm=True)
        return self.started

    def __enter__(self) -> LazyPool:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.started is not None:
            self.started.shutdown()


class _FirstRun:
    """Watches the first run's progress and, as soon as the rest of the scenario looks
    longer than OFFLOAD_AFTER seconds, starts the helpers (once); decides at the end of the
    first run at the latest (a backend that reports no progress)."""

    _EARLIEST = 0.1  # fraction of the first run after which its pace is trusted

    def __init__(self, pending: list[tuple[CaseEntry, ControllerEntry]],
                 progress: RunProgress | None, start: Callable[[], None]) -> None:
        self.pending, self.progress, self.start = pending, progress, start
        self.decided = False
        self.began = 0.0
        self.weight = 1.0

    def watch(self, entry: ControllerEntry) -> RunProgress:
        self.began = time.perf_counter()
        rest = sum(_expected_cost(e) + 1 for _, e in self.pending)
        self.weight = rest / (_expected_cost(entry) + 1)

        def report(label: str, frac: float) -> None:
            if not self.decided and frac >= self._EARLIEST:
                self._decide(frac)
            if self.progress is not None:
                self.progress(label, frac)

        return report

    def _decide(self, frac: float) -> None:
        self.decided = True
        whole = (time.perf_counter() - self.began) / frac
        if self.pending and whole * self.weight > OFFLOAD_AFTER:
            self.start()

    def done(self) -> None:
        if not self.decided:
            self._decide(1.0)


def run_shared(
    setup: ScenarioSetup,
    pool: Callable[[], Executor],
    workers: int,
    backend: str | None = None,
    progress: RunProgress | None = None,
) -> list[RunResult]:
    """Every pair, this process running them and ``workers`` processes of ``pool()`` (called
    only then) helping when the rest looks long enough to repay starting them.

    The first pair runs here; from its pace (once a tenth of it has run) and the pairs'
    relative costs the rest is estimated. Below OFFLOAD_AFTER seconds everything stays in
    this process. Above, one feeder thread per worker hands its worker the cheapest pair
    left whenever the worker is free, while this process takes the dearest: a pair is
    committed to a process only when that process starts it, so neither waits while the
    other has work. Results come in case-major order.
    """
    backend = backend or setup.scenario.simulation.backend
    pairs = [(case, entry) for case in setup.cases for entry in setup.controllers]
    pending = sorted(pairs, key=lambda p: -_expected_cost(p[1]))
    plant = setup.make_plant() if backend == "mujoco" else None
    results: dict[tuple[str, str], RunResult] = {}
    lock = threading.Lock()
    failures: list[BaseException] = []

    def feed() -> None:
        while not failures:
            with lock:
                if not pending:
                    return
                c, e = pending.pop()
            try:
                r = executor.submit(_run_in_worker, setup.scenario, setup.source, c.name, e.name,
                                backend).result()
            except BaseException as exc:  # handed to the main thread, which raises it
                failures.append(exc)
                return
            results[c.name, e.name] = r
            if progress is not None:
                progress(f"{c.name} / {e.name}", 1.0)

    feeders: list[threading.Thread] = []
    executor: Executor

    def start_feeders() -> None:
        nonlocal executor
        executor = pool()
        feeders.extend(threading.Thread(target=feed, daemon=True) for _ in range(workers))
        for f in feeders:
            f.start()

    first = _FirstRun(pending, progress, start_feeders)
    while not failures:
        with lock:
            if not pending:
                break
            case, entry = pending.pop(0)
        report = first.watch(entry) if not results else progress
        results[case.name, entry.name] = run_one(setup, case, entry, backend, plant, report)
        first.done()
    for f in feeders:
        f.join()
    if failures:
        raise failures[0]
    return [results[c.name, e.name] for c, e in pairs]


def run_all(
    setup: ScenarioSetup,
    backend: str | None = None,
    progress: RunProgress | None = None,
    workers: int = 1,
    pool: Executor | None = None,
) -> list[RunResult]:
    """Simulate each (case, controller) pair; ``backend`` overrides the scenario's.

    With ``workers > 1`` (or a ``pool`` to reuse) the pairs run in separate processes,
    the most expensive first. Results come in case-major order whatever the number of
    workers.
    """
    backend = backend or setup.scenario.simulation.backend
    pairs = [(case, entry) for case in setup.cases for entry in setup.controllers]
    if pool is None and (workers <= 1 or len(pairs) <= 1):
        plant = setup.make_plant() if backend == "mujoco" else None
        return [run_one(setup, c, e, backend, plant, progress) for c, e in pairs]
    with contextlib.ExitStack() as stack:
        if pool is None:
            pool = stack.enter_context(worker_pool(workers))
        # Ship only the validated scenario and its file; each worker builds its own objects.
        order = sorted(pairs, key=lambda p: -_expected_cost(p[1]))
        futures = {
            pool.submit(
                _run_in_worker, setup.scenario, setup.source, c.name, e.name, backend
            ): (c.name, e.name)
            for c, e in order
        }
        if progress is not None:
            for c, e in pairs:
                progress(f"{c.name} / {e.name}", 0.0)
        results: dict[tuple[str, str], RunResult] = {}
        for done in as_completed(futures):
            case, name = futures[done]
            results[case, name] = done.result()
            if progress is not None:
                progress(f"{case} / {name}", 1.0)
    return [results[c.name, e.name] for c, e in pairs]
