"""``python -m cpbc.run SCENARIO [--out DIR]``: run a scenario, print a summary, write results.

Exit codes: 0 when the scenario ran (whatever the controllers did), 2 for bad input
(the message names the field), 130 when interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from cpbc.constraints.clearance import Clearance
from cpbc.constraints.clearance.unclearable import SLACK
from cpbc.controllers.packed_law import python_path_notes
from cpbc.errors import CpbcError
from cpbc.progress_bars import run_progress
from cpbc.results import (
    LOG_FILE,
    ArmLabels,
    log_file,
    staged_output,
    write_summaries,
    write_system_trajectory,
    write_trajectory,
)
from cpbc.results.drawing import figure_helper
from cpbc.results.margin_types import types_of
from cpbc.results.summary_table import summary_table
from cpbc.scenario import build
from cpbc.scenario.build import ScenarioSetup, undeclared_efforts
from cpbc.scenario.load import load_any
from cpbc.scenario.preflight import warning
from cpbc.scenario.reference import approach_notes
from cpbc.scenario.runner import (
    LazyPool,
    RunProgress,
    RunResult,
    default_processes,
    run_all,
    run_shared,
    run_systems,
)
from cpbc.scenario.schema import SystemScenario

if TYPE_CHECKING:
    from cpbc.viewer.live import LiveView

def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m cpbc.run",
        description="Run a cpbc scenario: every controller on every case, in MuJoCo.",
    )
    p.add_argument("scenario", help="scenario YAML file, or the name of a shipped scenario")
    p.add_argument("--out", type=Path, help="output folder (default: runs/<scenario name>)")
    p.add_argument(
        "--backend", choices=("mujoco", "reference"),
        help="override the scenario's backend: MuJoCo, or the continuous-time reference",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--workers", type=int, default=None,
        help="processes, this one included, for the runs and figures (default: one per "
        "core; the others are started only when the scenario is long enough to repay it)",
    )
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")
    p.add_argument(
        "--view", action="store_true",
        help="stream the simulation to a meshcat viewer on 127.0.0.1 and print its URL "
        "(runs serially; keeps serving the replay until Ctrl-C)",
    )
    p.add_argument(
        "--view-speed", type=float, default=1.0, metavar="X",
        help="with --view: simulated seconds per wall-clock second (0: as fast as possible)",
    )
    return p


def _run_system(scenario: SystemScenario, file: Path, args: argparse.Namespace,
                console: Console, err: Console) -> int:
    """A Part I scenario: built (bad input refused before anything is written), run through
    the same loop and runner as an arm's, written as the same files (trajectories.h5,
    summary.json, summary.csv, figures, view.html), summarised in the same table."""
    if args.view:
        raise CpbcError("--view streams arm scenarios only; a Part I run writes its replay "
                        "to view.html in the output folder")
    # a Part I system's modules (its laws, the page's) only when one runs
    from cpbc.scenario.system_build import build_system
    from cpbc.scenario.system_setup import check_backend
    from cpbc.viewer.system_outputs import write_system_outputs

    setup = build_system(scenario, file)
    out = args.out or Path("runs") / scenario.name
    backend = args.backend or scenario.simulation.backend
    check_backend(setup, backend, "--backend" if args.backend else "simulation.backend")
    if args.quiet:
        results = run_systems(setup, backend)
    else:
        with Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                      console=err, transient=True) as bar:
            results = run_systems(setup, backend,
                                  run_progress(bar, len(setup.cases) * len(setup.laws)))
    with staged_output(out) as scratch:
        with log_file(scratch / LOG_FILE, scenario.name) as log:
            for r in results:
                write_system_trajectory(log, r.case, r.controller, r.trajectory,
                                        setup.state_names, setup.input_name,
                                        r.summary.as_dict())
        write_summaries(scratch, [r.summary for r in results])
        write_system_outputs(scratch, setup, results, plots=not args.no_plots)
    console.print(summary_table([r.summary for r in results]))
    for name, value in setup.view.design_bounds.items():
        console.print(f"a-priori bound {name}: {value:.6g}")
    console.print(f"backend: {backend}; results written to {out}/")
    return 0


def _simulate(setup: ScenarioSetup, backend: str | None, progress: RunProgress | None,
              pool: LazyPool | None, workers: int) -> list[RunResult]:
    if pool is None:
        return run_all(setup, backend, progress)
    return run_shared(setup, pool.get, workers - 1, backend, progress)


def write_logs(folder: Path, setup: ScenarioSetup, results: Sequence[RunResult]) -> None:
    """Every run's signals into the run folder's trajectories.h5."""
    model = setup.model
    labels = ArmLabels(
        setup.coordinate_names, tuple(bool(v) for v in model.length_coordinates),
        model.joint_names, tuple(bool(v) for v in model.length_joints),
        setup.monitor.names, types_of(setup.monitor, model.length_coordinates))
    with log_file(folder / LOG_FILE, setup.scenario.name) as log:
        for r in results:
            write_trajectory(log, r.case, r.controller, r.trajectory, r.margins, r.lyapunov,
                             setup.target, labels, r.summary.as_dict(), r.task_error,
                             r.reference)


def left_out_pairs(setup: ScenarioSetup) -> list[str]:
    """One line per default clearance that left out cover primitives no configuration takes
    clear of an obstacle (cpbc.constraints.clearance.unclearable)."""
    lines = []
    for c in setup.monitor.configuration:
        pairs = c.left_out if isinstance(c, Clearance) else ()
        if pairs:
            names = ", ".join(f"{p} in {o}" for p, o in pairs)
            lines.append(f"clearance '{c.names[0].split('[')[0]}' leaves out {names}: within "
                         f"{SLACK * 100:g} cm of the obstacle or inside it at every sampled "
                         "configuration, no motion clears them; give clearance.links to "
                         "choose the covered links yourself")
    return lines


def uncovered_links(setup: ScenarioSetup) -> list[str]:
    """One line per link whose declared clearance primitives leave part of its collision
    geometry outside (cpbc.constraints.covering.uncovered)."""
    lines = []
    for c in setup.monitor.configuration:
        for link, gap in c.uncovered if isinstance(c, Clearance) else ():
            lines.append(f"clearance '{c.names[0].split('[')[0]}': the primitives declared "
                         f"on '{link}' leave its collision geometry up to {gap * 1000:.3g} mm "
                         "outside them, so its clearance may read that much more than the "
                         "link has; grow them, or leave the link to the automatic cover")
    return lines


def _approaches(setup: ScenarioSetup) -> list[str]:
    """The cases that start away from the reference's first sample (approached first)."""
    ref, spec = setup.reference, setup.scenario.reference
    if ref is None or spec is None:
        return []
    return approach_notes(ref.goal, ref.path, setup.model, spec.tolerance.position,
                          [(c.name, c.position) for c in setup.cases])


def _warn(setup: ScenarioSetup, err: Console) -> None:
    """One line per case whose path to the target leaves a motor no room to brake over
    gravity (cpbc.scenario.preflight), one when the motors' limits are declared for some
    joints only (the run then has none), and the cover primitives a default clearance left
    out."""
    for case, load in setup.gravity_on_path.items():
        err.print(f"[yellow]warning:[/yellow] {escape(warning(case, load))}", highlight=False)
    for note in setup.outside_braking_set.values():
        err.print(f"[yellow]note:[/yellow] {escape(note)}", highlight=False)
    undeclared = undeclared_efforts(setup)
    if undeclared:
        n = setup.model.n
        err.print(f"[yellow]warning:[/yellow] the model declares effort limits for "
                  f"{n - len(undeclared)} of its {n} joints (none for "
                  f"{escape(', '.join(undeclared[:4]))}{', …' if len(undeclared) > 4 else ''}): "
                  "those run without a torque limit; give simulation.torque_limit to set "
                  "every joint's", highlight=False)
    for entry in setup.controllers:  # a constraint without a kernel, said once, here
        for line in python_path_notes(entry.controller):
            err.print(f"[yellow]note:[/yellow] {escape(line)}", highlight=False)
    for line in left_out_pairs(setup) + _approaches(setup):
        err.print(f"[yellow]note:[/yellow] {escape(line)}", highlight=False)
    for line in uncovered_links(setup):
        err.print(f"[yellow]warning:[/yellow] {escape(line)}", highlight=False)
    if setup.goal is not None:
        goal = setup.goal
        err.print(f"goal preflight ({goal.goal.frame_name}): "
                  f"{escape(goal.preflight.describe())}", highlight=False)


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    console = Console(stderr=False, width=None if sys.stdout.isatty() else 200)
    err = Console(stderr=True, width=None if sys.stderr.isatty() else 200)
    live: LiveView | None = None
    try:
        loaded, file = load_any(args.scenario)
        if isinstance(loaded, SystemScenario):  # a Part I system: runs serially, no live view
            return _run_system(loaded, file, args, console, err)
        scenario = loaded
        setup = build(scenario, file)
        _warn(setup, err)
        out = args.out or Path("runs") / scenario.name
        if args.view:
            from cpbc.viewer.live import start_live_view  # meshcat only when asked for

            live = start_live_view(setup, args.view_speed)
            console.print(f"meshcat viewer (live): {live.url}")
        workers = args.workers or default_processes()
        # Worker processes only for a scenario long enough to repay starting them
        # (run_shared decides); once started, they draw most figures too. Otherwise a
        # process forked now (before any simulator runs here) draws them.
        pool = LazyPool(workers - 1) if workers > 1 and not live else None
        drawer = (figure_helper() if workers > 1 and not args.no_plots and not live
                  else contextlib.nullcontext())
        with staged_output(out) as scratch, pool or contextlib.nullcontext(), \
                drawer as figures:
            if args.quiet:
                results = (live.run(setup, args.backend) if live else
                           _simulate(setup, args.backend, None, pool, workers))
            else:
                with Progress(
                    TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                    console=err, transient=True,
                ) as bar:
                    progress = run_progress(bar, len(setup.cases) * len(setup.controllers))
                    results = (live.run(setup, args.backend, progress) if live else
                               _simulate(setup, args.backend, progress, pool, workers))
            write_logs(scratch, setup, results)
            write_summaries(scratch, [r.summary for r in results])
            spawned = pool.started if pool else None
            # the page's modules (meshcat) load while the helpers draw
            from cpbc.viewer.outputs import write_run_outputs

            write_run_outputs(scratch, setup, plots=not args.no_plots,
                              pool=spawned or figures, figures_only=spawned is None)
    except CpbcError as exc:
        if live:
            live.close()
        err.print(f"[bold red]error:[/bold red] {escape(str(exc))}", highlight=False,
                  soft_wrap=True)
        return 2
    except KeyboardInterrupt:
        if live:
            live.close()
        err.print("interrupted; nothing written")
        return 130
    contacts = any(isinstance(c, Clearance) for c in setup.monitor.configuration)
    console.print(summary_table([r.summary for r in results], setup.coordinate_names, contacts))
    backend = args.backend or scenario.simulation.backend
    console.print(f"backend: {backend}; results written to {out}/")
    if live:
        live.hold(out)
    return 0


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def cli() -> None:
    """``python -m cpbc.run`` and ``cpbc-run``: :func:`main` in a process that ends with it.

    Two costs of a short run are the interpreter's, not the work's (panda_cpbc_sphere, 2.7 s
    from the shell, 13 % together): the collector walking the 1300 modules' objects, here
    and in every forked figure helper, where walking them also copies the pages they share
    (so they are frozen first, as the gc documentation advises before a fork); and tearing
    those modules down one by one at exit (0.2 s; skipped: every file is closed, every
    helper and server has stopped, the output streams are flushed here).
    """
    gc.freeze()
    signal.signal(signal.SIGTERM, _interrupt)  # as Ctrl-C: the scratch folder is removed
    code = main()
    with contextlib.suppress(OSError):  # a reader that went away (| head) is no error here
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    cli()
