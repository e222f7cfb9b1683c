"""Run every law of a Part I scenario on every case, and write the results folder."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from cpbc.errors import ScenarioError
from cpbc.results.hdf5_log import LOG_FILE, log_file, write_system_trajectory
from cpbc.results.system_metrics import (
    SystemSummary,
    plot_case,
    plot_path,
    summarise_system,
    write_system_summaries,
)
from cpbc.scenario.system_build import SystemCase, SystemLaw, SystemSetup, check_backend
from cpbc.simulation import SystemTrajectory, run_system_mujoco, run_system_reference
from cpbc.systems.ode_plant import Plant

RunProgress = Callable[[str, float], None]


@dataclass(frozen=True)
class SystemResult:
    case: str
    law: str
    trajectory: SystemTrajectory
    summary: SystemSummary


def run_system_one(setup: SystemSetup, case: SystemCase, law: SystemLaw, backend: str,
                   progress: RunProgress | None = None) -> SystemResult:
    sim = setup.scenario.simulation
    label = f"{case.name} / {law.name}"

    def report(frac: float) -> None:
        if progress is not None:
            progress(label, frac)

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
                               setup.state_names, setup.input_name, sim.tolerance)
    return SystemResult(case.name, law.name, traj, summary)


def run_system_all(setup: SystemSetup, backend: str | None = None,
                   progress: RunProgress | None = None) -> list[SystemResult]:
    """Every (case, law) pair, case-major; ``backend`` overrides the scenario's."""
    check_backend(setup, backend or setup.scenario.simulation.backend,
                  "simulation.backend" if backend is None else "backend")
    backend = backend or setup.scenario.simulation.backend
    return [run_system_one(setup, c, law, backend, progress)
            for c in setup.cases for law in setup.laws]


def write_system_outputs(folder: Path, setup: SystemSetup, results: list[SystemResult],
                         plots: bool = True) -> None:
    """trajectories.h5 (every run's log), summary.json, and <case>/timeseries.png."""
    with log_file(folder / LOG_FILE, setup.scenario.name) as log:
        for r in results:
            write_system_trajectory(log, r.case, r.law, r.trajectory, setup.state_names,
                                    setup.input_name, r.summary.as_dict())
    write_system_summaries(folder, [r.summary for r in results])
    if not plots:
        return
    for case in setup.cases:
        runs = [(r.law, r.trajectory) for r in results if r.case == case.name]
        (folder / case.name).mkdir(exist_ok=True)
        plot_case(folder / case.name / "timeseries.png", case.name, runs, setup.view)
        if setup.view.path is not None:
            plot_path(folder / case.name / "path.png", case.name, runs, setup.view)
