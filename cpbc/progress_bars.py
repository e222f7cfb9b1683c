"""The progress bars of a scenario run on the terminal (rich), fed by the runner's
RunProgress reports (cpbc.scenario.runner)."""

from __future__ import annotations

from rich.progress import Progress, TaskID

from cpbc.scenario.runner import RunProgress


def run_progress(bar: Progress, runs: int) -> RunProgress:
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
