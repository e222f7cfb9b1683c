"""``python -m cpbc.run SCENARIO [--out DIR]``: run a scenario, print a summary, write results.

Exit codes: 0 when the scenario ran (whatever the controllers did), 2 for bad input
(the message names the field), 130 when interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn
from rich.table import Table

from cpbc.constraints.clearance import Clearance
from cpbc.errors import CpbcError
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
from cpbc.results.metrics import RunSummary
from cpbc.scenario import build
from cpbc.scenario.build import ScenarioSetup, undeclared_efforts
from cpbc.scenario.load import load_any
from cpbc.scenario.preflight import warning
from cpbc.scenario.runner import (
    LazyPool,
    RunProgress,
    RunResult,
    SystemResult,
    default_processes,
    run_all,
    run_shared,
    run_systems,
)
from cpbc.scenario.schema import SystemScenario
from cpbc.scenario.system_build import build_system
from cpbc.scenario.system_setup import check_backend

if TYPE_CHECKING:
    from cpbc.viewer.live import LiveView

STATUS_STYLE = {
    "converged": "green",
    "reached": "green",
    "tracked": "green",
    "blocked": "yellow",
    "unreachable": "yellow",
    "stalled": "yellow",
    "held": "yellow",
    "not_settled": "yellow",
    "constraint_violated": "red",
    "diverged": "red",
}


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


def _fmt(values: Sequence[float | None], digits: int = 3) -> str:
    return ", ".join("-" if v is None else f"{v:.{digits}g}" for v in values)


WIDE = 3  # more coordinates than this: the table shows the one nearest its bound


def _rates(s: RunSummary, names: Sequence[str]) -> str:
    if len(names) > WIDE:
        return _widest_rate(s, names)
    parts = []
    for peak, bound in zip(s.peak_joint_rates, s.rate_bounds, strict=True):
        if bound is None:
            parts.append(f"{peak:.3g}")
        else:
            mark = "≤" if peak < bound else "[red]>[/red]"
            parts.append(f"{peak:.4g}{mark}{bound:.4g}")
    return ", ".join(parts)


def _widest_rate(s: RunSummary, names: Sequence[str]) -> str:
    """For a many-joint arm: the coordinate whose peak rate came nearest its bound (or the
    fastest, without bounds), and how many went past theirs."""
    bounded = [(peak / bound, i, bound) for i, (peak, bound) in
               enumerate(zip(s.peak_joint_rates, s.rate_bounds, strict=True)) if bound]
    if not bounded:
        i = max(range(len(names)), key=lambda k: s.peak_joint_rates[k])
        return f"{s.peak_joint_rates[i]:.3g} ({escape(names[i])})"
    _, i, bound = max(bounded)  # indices differ: ties never compare the bounds
    peak = s.peak_joint_rates[i]
    over = sum(r >= 1.0 for r, _, _ in bounded)
    mark = "≤" if peak < bound else "[red]>[/red]"
    tail = f"; [red]{over} of {len(bounded)} over[/red]" if over else f"; all {len(bounded)} within"
    return f"{peak:.4g}{mark}{bound:.4g} ({escape(names[i])}){tail}"


def _torques(s: RunSummary, names: Sequence[str]) -> str:
    """Peak applied torques; against the plant's limits, per joint, when it has them."""
    limits = s.torque_limits
    if limits is None:
        if len(names) <= WIDE:
            return _fmt(s.peak_torques)
        i = max(range(len(s.peak_torques)), key=lambda k: s.peak_torques[k])
        return f"{s.peak_torques[i]:.3g} ({escape(names[i])})"
    peaks = s.peak_joint_torques
    lims = [math.inf if lim is None else lim for lim in limits]  # None: this joint has none
    at = [k for k, (p, lim) in enumerate(zip(peaks, lims, strict=True)) if p >= lim]
    if len(names) <= WIDE:
        return ", ".join(f"{p:.3g}{'=' if k in at else '<'}{lim:.3g}"
                         for k, (p, lim) in enumerate(zip(peaks, lims, strict=True)))
    i = max(range(len(peaks)), key=lambda k: peaks[k] / lims[k])
    tail = f"; [yellow]{len(at)} of {len(peaks)} at the limit[/yellow]" if at else ""
    return f"{peaks[i]:.3g}{'=' if i in at else '<'}{lims[i]:.3g} (joint {i + 1}){tail}"


def _margins(s: RunSummary) -> str:
    """Per constraint type, the constraint nearest its bound, in the type's unit."""
    parts = []
    for w in s.worst_margins():
        colour = "red" if w.value <= 0 else ("green" if w.constraint in s.enforced_constraints
                                             else "")
        value = f"{w.value:.3g} {w.unit}".strip()
        value = f"[{colour}]{value}[/{colour}]" if colour else value
        parts.append(f"{w.type} {value} {escape(f'({w.constraint})')}")
    return "\n".join(parts) or "-"


def _table(results: Sequence[RunResult], coordinate_names: Sequence[str],
           contacts: bool = False) -> Table:
    t = Table(title="cpbc summary", show_lines=False)
    wide = len(coordinate_names) > WIDE
    rates = ("peak |rate|, nearest its bound" if wide
             else f"peak |rate| ({', '.join(coordinate_names)})")
    columns = ["case", "controller", "status", "final err", "settle [s]", rates,
               "peak |τ| applied (vs limit) / ‖τ‖ asked (bound)",
               "nearest its bound, per type"]
    if contacts:
        columns.append("contacts")
    for col in (*columns, "V rise", "safeguard", "steps/s"):
        t.add_column(col)
    for r in results:
        s = r.summary
        bound = "" if s.torque_bound is None else f" ({s.torque_bound:.4g})"
        style = STATUS_STYLE[s.status]
        cells = [
            escape(s.case), escape(s.controller),
            f"[{style}]{escape(_status(s))}[/{style}]",
            _final_error(s),
            "-" if s.settle_time is None else f"{s.settle_time:.3g}",
            _rates(s, coordinate_names),
            f"{_torques(s, coordinate_names)} / {s.peak_torque_norm:.4g}{bound}", _margins(s),
        ]
        if contacts:
            cells.append(f"[red]{s.max_contacts}[/red]" if s.max_contacts else "0")
        t.add_row(*cells, f"{s.max_lyapunov_increase:.2g}", _safeguard(s),
                  f"{s.steps_per_second:,.0f}")
    return t


def _final_error(s: RunSummary) -> str:
    """The joint error, or a goal run's task error (position, angle) and reach time."""
    if s.task_error_final is None:
        return f"{s.final_error:.3g}"
    e = s.task_error_final
    if s.path_lag_max is not None and s.task_error_rms is not None:  # a reference run
        rms = s.task_error_rms
        return (f"rms {rms['position'] * 1000:.3g} mm, {rms['angle']:.2g} rad; end "
                f"{e['position'] * 1000:.3g} mm; lag ≤ {s.path_lag_max:.3g} s")
    reach = "" if s.reach_time is None else f" @{s.reach_time:.3g}s"
    return f"{e['position'] * 1000:.3g} mm, {e['angle']:.2g} rad{reach}"


def _status(s: RunSummary) -> str:
    status = s.status + (f" ({s.stall_kind})" if s.stall_kind else "") + (
        f" by {s.blocked_by} @{s.blocked_at['time']:.4g}s" if s.status == "blocked"
        and s.blocked_by and s.blocked_at else "") + (
        f" @{s.end_time:.3g}s: {s.violated_constraint}"
                         if s.violated_constraint else "")
    if s.status == "diverged":
        status += f" @{s.end_time:.3g}s"
    return status + _notes(s) + (f"; cause: {s.cause}" if s.cause else "")


#: Above this share of steps, the safeguard, not the law, drove the run: the status says so.
SAFEGUARD_NOTE = 0.5


def _notes(s: RunSummary) -> str:
    """What went on outside the proof: saturated torque, a safeguard that did most of the
    work, refused noisy measurements."""
    notes = []
    if s.saturated_steps:
        notes.append(f"torque saturated in {s.saturated_steps} steps")
    if s.safeguard_share > SAFEGUARD_NOTE:
        notes.append(f"safeguard acted on {s.safeguard_share:.0%} of steps")
    if s.rejected_samples:
        notes.append(f"{s.rejected_samples} noisy samples outside S refused")
    return "".join(f"; {n}" for n in notes)


def _safeguard(s: RunSummary) -> str:
    """Share of the control steps at which the sampled-data safeguard changed the law's
    torque."""
    if not s.safeguard_steps:
        return "-" if s.enforced_constraints else ""
    late = f", {s.safeguard_infeasible} infeasible" if s.safeguard_infeasible else ""
    late += f", {s.rescues} rescued" if s.rescues else ""
    share = f"{s.safeguard_share:.1%}" if s.safeguard_share >= 0.001 else "<0.1%"
    return f"{share} ({s.safeguard_steps} steps{late})"


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


def _system_table(results: Sequence[SystemResult]) -> Table:
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
        steps = "-" if s.steps_per_second is None else f"{s.steps_per_second:,.0f}"
        t.add_row(escape(s.case), escape(s.controller), f"[{style}]{escape(status)}[/{style}]",
                  "-" if s.settle_time is None else f"{s.settle_time:.3g}", _peaks(r),
                  _others(r), steps)
    return t


def _run_system(scenario: SystemScenario, file: Path, args: argparse.Namespace,
                console: Console, err: Console) -> int:
    """A Part I scenario: built (bad input refused before anything is written), run through
    the same loop and runner as an arm's, written as the same files (trajectories.h5,
    summary.json, summary.csv, figures, view.html), summarised in a table of its own
    columns."""
    if args.view:
        raise CpbcError("--view streams arm scenarios only; a Part I run writes its replay "
                        "to view.html in the output folder")
    from cpbc.viewer.outputs import write_system_outputs  # the page's modules: when used

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
                                  _progress(bar, len(setup.cases) * len(setup.laws)))
    with staged_output(out) as scratch:
        with log_file(scratch / LOG_FILE, scenario.name) as log:
            for r in results:
                write_system_trajectory(log, r.case, r.controller, r.trajectory,
                                        setup.state_names, setup.input_name,
                                        r.summary.as_dict())
        write_summaries(scratch, [r.summary for r in results])
        view = write_system_outputs(scratch, setup, results, plots=not args.no_plots)
    console.print(_system_table(results))
    for name, value in setup.view.design_bounds.items():
        console.print(f"a-priori bound {name}: {value:.6g}")
    if view is None:
        console.print("view.html: none (the system is only its ODE, with no body to show; "
                      "<case>/timeseries.png has its time plots)")
    console.print(f"backend: {backend}; results written to {out}/")
    return 0


def _progress(bar: Progress, runs: int) -> RunProgress:
    """A bar per run under way, removed when it ends (a bar per run of hundreds made every
    refresh draw them all), and one for the runs done."""
    tasks: dict[str, TaskID] = {}
    done = bar.add_task(f"runs done (of {runs})", total=runs) if runs > 1 else None

    def progress(label: str, frac: float) -> None:
        if frac >= 1.0:
            if label in tasks:
                bar.remove_task(tasks.pop(label))
            if done is not None:
                bar.advance(done)
            return
        if label not in tasks:
            tasks[label] = bar.add_task(label, total=1.0)
        bar.update(tasks[label], completed=frac)

    return progress


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


def _warn(setup: ScenarioSetup, err: Console) -> None:
    """One line per case whose path to the target leaves a motor no room to brake over
    gravity (cpbc.scenario.preflight), and one when the motors' limits are declared for some
    joints only (the run then has none)."""
    for case, load in setup.gravity_on_path.items():
        err.print(f"[yellow]warning:[/yellow] {escape(warning(case, load))}", highlight=False)
    undeclared = undeclared_efforts(setup)
    if undeclared:
        n = setup.model.n
        err.print(f"[yellow]warning:[/yellow] the model declares effort limits for "
                  f"{n - len(undeclared)} of its {n} joints (none for "
                  f"{escape(', '.join(undeclared[:4]))}{', …' if len(undeclared) > 4 else ''}): "
                  "those run without a torque limit; give simulation.torque_limit to set "
                  "every joint's", highlight=False)
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
                    progress = _progress(bar, len(setup.cases) * len(setup.controllers))
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
    console.print(_table(results, setup.coordinate_names, contacts))
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
