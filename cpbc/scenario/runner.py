"""Run every controller of a scenario on every case and collect the results."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from cpbc.constraints.base import Array
from cpbc.results.metrics import RunSummary, margin_history, summarise
from cpbc.scenario.build import ScenarioSetup
from cpbc.simulation import Trajectory, run_mujoco, run_reference

RunProgress = Callable[[str, float], None]


@dataclass(frozen=True)
class RunResult:
    controller: str
    case: str
    trajectory: Trajectory
    margins: Array
    lyapunov: Array
    summary: RunSummary


def run_all(
    setup: ScenarioSetup, backend: str | None = None, progress: RunProgress | None = None
) -> list[RunResult]:
    """Simulate each (case, controller) pair; ``backend`` overrides the scenario's."""
    backend = backend or setup.scenario.simulation.backend
    results = []
    plant = setup.make_plant() if backend == "mujoco" else None
    reference = setup.make_reference_plant() if backend == "reference" else None
    for case in setup.cases:
        for entry in setup.controllers:
            label = f"{case.name} / {entry.name}"

            def report(frac: float, label: str = label) -> None:
                if progress is not None:
                    progress(label, frac)

            if plant is not None:
                traj = run_mujoco(
                    plant, entry.controller, setup.model.coordinates, case.position,
                    case.velocity, setup.loop_settings, report,
                )
            else:
                assert reference is not None
                traj = run_reference(
                    reference, entry.controller, case.position, case.velocity,
                    setup.loop_settings,
                )
            report(1.0)
            margins = margin_history(setup.monitor, traj)
            lyap = traj.lyapunov
            summary = summarise(
                entry.name, case.name, entry.controller, setup.monitor, traj, setup.criteria,
                setup.rate_bounds, margins,
            )
            results.append(RunResult(entry.name, case.name, traj, margins, lyap, summary))
    return results
