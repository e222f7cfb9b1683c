"""The CLI's path for a Part I scenario (a ``system:`` block): run, table, results folder."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from cpbc.errors import CpbcError
from cpbc.results import staged_output
from cpbc.scenario.schema import SystemScenario
from cpbc.scenario.system_build import build_system, check_backend
from cpbc.scenario.system_runner import SystemResult, run_system_all, write_system_outputs
from cpbc.viewer.system_page import write_system_view

STATUS_STYLE = {"converged": "green", "not_settled": "yellow",
                "constraint_violated": "red", "diverged": "red"}


def _peaks(r: SystemResult) -> str:
    s = r.summary
    parts = []
    for name, peak in s.peaks.items():
        bound = s.bounds[name]
        mark = "<" if peak < bound else "[red]≥[/red]"
        parts.append(f"{escape(name)} {peak:.4g}{mark}{bound:.4g}")
    return "\n".join(parts)


def _others(r: SystemResult) -> str:
    """The peaks of the components that are not constrained (the wheel's speed, say)."""
    s = r.summary
    return ", ".join(f"{escape(k)} {v:.4g}" for k, v in s.peak_abs.items() if k not in s.peaks)


def system_table(results: Sequence[SystemResult]) -> Table:
    t = Table(title="cpbc summary (Part I system)")
    for col in ("case", "law", "status", "settle [s]", "peak |·| vs bound", "other peaks |·|",
                "steps/s"):
        t.add_column(col)
    for r in results:
        s = r.summary
        style = STATUS_STYLE[s.status]
        at = s.crossed_at if s.crossed_at is not None else s.end_time
        status = s.status + (f" @{at:.3g}s: {s.violated}" if s.violated else "")
        if s.limits_reached:
            status += f"; reached the plant's limit: {', '.join(s.limits_reached)}"
        # the reference's samples are not its steps: its rate says nothing
        mujoco = s.backend == "mujoco" and s.wall_time > 0
        steps = f"{len(r.trajectory.time) / s.wall_time:,.0f}" if mujoco else "-"
        t.add_row(escape(s.case), escape(s.controller), f"[{style}]{escape(status)}[/{style}]",
                  "-" if s.settle_time is None else f"{s.settle_time:.3g}", _peaks(r),
                  _others(r), steps)
    return t


def run_system_cli(scenario: SystemScenario, file: Path, args: argparse.Namespace,
                   console: Console) -> int:
    """Build (refusing bad input before anything is written), run, write, print."""
    if args.view:
        raise CpbcError("--view streams arm scenarios only; a Part I run writes its replay "
                        "to view.html in the output folder")
    setup = build_system(scenario, file)
    out = args.out or Path("runs") / scenario.name
    backend = args.backend or scenario.simulation.backend
    check_backend(setup, backend, "--backend" if args.backend else "simulation.backend")
    results = run_system_all(setup, backend)
    with staged_output(out) as scratch:
        write_system_outputs(scratch, setup, results, plots=not args.no_plots)
        view = write_system_view(scratch, setup, results)
    console.print(system_table(results))
    for name, value in setup.view.design_bounds.items():
        console.print(f"a-priori bound {name}: {value:.6g}")
    if view is None:
        console.print("view.html: none (the system is only its ODE, with no body to show; "
                      "<case>/timeseries.png has its time plots)")
    console.print(f"backend: {backend}; results written to {out}/")
    return 0
