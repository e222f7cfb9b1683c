"""Drawing a run's figures, here or in helper processes forked for it.

Figures are matplotlib's, and matplotlib takes about 0.3 s to load: a process that leaves the
figures to others never loads it, and helpers forked at the start of a run load it while the
run simulates (:func:`figure_helper`).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from pathlib import Path

from cpbc.results.saved_run import load_run

#: One figure to draw: (case, figure name of cpbc.results.saved_run.FIGURES).
Job = tuple[str, str]


def draw(folder: Path, only: Sequence[Job] | None = None) -> list[Path]:
    """Read a run folder back and draw its figures ((case, figure) pairs; all when None)."""
    from cpbc.results.plots import write_plots

    return write_plots(load_run(folder), only=only)


def figure_weight(figure: str, coordinates: int, margin_types: int) -> int:
    """Rough cost of drawing one figure of :mod:`cpbc.results.plots`: its panels (one per
    coordinate, the torques' norm, one per margin type) plus one for the figure itself (title,
    PNG). Measured on the UR5: about 30 ms per panel."""
    panels = {"positions": coordinates, "rates": coordinates, "torques": coordinates + 1,
              "margins": margin_types}.get(figure, 1)
    return panels + 1


def share_out(jobs: Sequence[Job], weights: Sequence[float], shares: Sequence[float]
              ) -> list[list[Job]]:
    """Jobs for processes that should each carry the given share of the total weight:
    heaviest first, each to the process furthest below its share (so two helpers drawing a
    case's five figures end together, where halving the list by count left one with two
    thirds of the work)."""
    parts: list[list[Job]] = [[] for _ in shares]
    load = [0.0] * len(shares)
    for i in sorted(range(len(jobs)), key=lambda i: -weights[i]):
        k = min(range(len(shares)), key=lambda k: (load[k] + weights[i]) / shares[k])
        parts[k].append(jobs[i])
        load[k] += weights[i]
    return parts


def quiet_on_interrupt() -> None:
    """Worker initialiser: Ctrl-C (the terminal's SIGINT reaches every process of the group)
    or SIGTERM ends a helper at once, without a traceback of its own; the main process
    reports the interruption and removes what the run had written."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _warm() -> None:
    """Load the plotting modules in a helper before it is needed."""
    import cpbc.results.plots  # noqa: F401


@contextlib.contextmanager
def figure_helper() -> Iterator[Executor | None]:
    """Two processes forked from this one at the start of a run, to draw the figures (half
    each) while this one writes the page. A fork has every module of this process loaded
    already and starts in milliseconds (a spawned worker spends seconds importing); they then
    load matplotlib while this process simulates. None where there is one core, or no safe
    fork (Windows has none; macOS's system libraries are not fork-safe). Fork them before any
    simulator or thread runs here."""
    if (os.cpu_count() or 1) < 2 or sys.platform != "linux":
        yield None
        return
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork"),
                             initializer=quiet_on_interrupt) as pool:
        for _ in range(2):
            pool.submit(_warm)
        yield pool
