"""``python -m cpbc.verify SCENARIO``: does every constrained controller keep every limit, from
seeded states across the admissible set and near its boundaries, at each control rate, with the
scenario's torque limits (and optionally model mismatch and measurement noise)?

    python -m cpbc.verify SCENARIO [--states N] [--rates 1000,500,100] [--horizon S] [--seed K]
        [--seeds K1,K2] [--mismatch mass=0.1,inertia=0.1,damping=0.05] [--noise SX,SV]
        [--workers N] [--cluster tcp://HOST:PORT] [--json] [--out FILE]

Runs on a local process pool (``--workers``, default: every core) or on a Dask distributed
scheduler (``--cluster``; ``pip install 'cpbc[cluster]'``). Prints a table (``--json``: the
document) and writes the report to ``--out`` (JSON for a ``.json`` name, else Markdown).
Exit code 0 when no viable run was violated, 1 when one was, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn
from rich.table import Table

from cpbc.errors import CpbcError
from cpbc.reliability.verification import (
    CLASSES,
    Block,
    Mismatch,
    Plan,
    Record,
    blocks,
    checked_controllers,
    run_block,
    summarise,
)
from cpbc.scenario import build, load_scenario
from cpbc.simulation.loop import substeps_per_control

CLUSTER_EXTRA = "pip install 'cpbc[cluster]'"


class UsageError(CpbcError):
    """A bad argument: exit 2 with the message."""


def _numbers(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        raise UsageError(f"{what}: expected finite numbers ≥ 0, got {text!r}")
    return values


def _mismatch(text: str | None) -> Mismatch | None:
    if text is None:
        return None
    fields = set(Mismatch.__dataclass_fields__)
    values: dict[str, float] = {}
    for part in text.split(","):
        key, _, value = part.partition("=")
        if key.strip() not in fields or not value:
            raise UsageError(f"--mismatch: expected KEY=VALUE with KEY in {sorted(fields)}, "
                             f"got {part!r}")
        values[key.strip()] = _numbers(value, f"--mismatch {key}")[0]
    return Mismatch(**values)


def _noise(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    v = _numbers(text, "--noise")
    if len(v) != 2:
        raise UsageError(f"--noise: expected SIGMA_POSITION,SIGMA_VELOCITY, got {text!r}")
    return v[0], v[1]


def _scenario(name: str) -> str:
    """A path every worker can read (absolute), or a shipped scenario's name."""
    path = Path(name)
    return str(path.resolve()) if path.exists() else name


def plan_from(a: argparse.Namespace) -> Plan:
    rates = _numbers(a.rates, "--rates")
    if any(r <= 0 for r in rates):
        raise UsageError(f"--rates: every rate must be > 0 Hz, got {a.rates!r}")
    if a.states < 1 or a.horizon <= 0 or a.workers < 1 or a.block < 1:
        raise UsageError("--states, --workers and --block must be ≥ 1 and --horizon > 0")
    seeds = None if a.seeds is None else tuple(int(v) for v in _numbers(a.seeds, "--seeds"))
    return Plan(_scenario(a.scenario), a.seed, a.states, tuple(rates), a.horizon,
                _mismatch(a.mismatch), _noise(a.noise), seeds)


def check_plan(plan: Plan) -> list[str]:
    """Builds the scenario here once (bad input fails before any worker starts) and returns
    the names of the controllers to check."""
    setup = build(*load_scenario(plan.scenario))
    names = [e.name for e in checked_controllers(setup)]
    if not names:
        raise UsageError(f"{plan.scenario}: no controller enforces a constraint; nothing to "
                         "verify")
    for rate in plan.rates:
        try:
            substeps_per_control(1.0 / rate, setup.plant_settings.timestep)
        except CpbcError as exc:
            raise UsageError(f"--rates {rate:g} Hz: {exc}") from None
    return names


def _local(work: Sequence[Block], workers: int) -> Iterator[list[Record]]:
    if workers == 1:
        yield from map(run_block, work)
        return
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        for done in as_completed([pool.submit(run_block, b) for b in work]):
            yield done.result()


def _cluster(work: Sequence[Block], address: str) -> Iterator[list[Record]]:
    try:
        from distributed import Client
        from distributed import as_completed as finished
    except ImportError:
        raise UsageError(f"--cluster needs Dask distributed: {CLUSTER_EXTRA}") from None
    try:
        client = Client(address, timeout=10)
    except (OSError, TimeoutError, ValueError) as exc:
        raise UsageError(f"--cluster {address}: cannot reach the scheduler ({exc})") from None
    with client:
        futures = client.map(run_block, list(work), pure=False)
        for future in finished(futures):
            yield future.result()


def run_campaign(plan: Plan, workers: int = 1, cluster: str | None = None, block: int = 8,
                 progress: Callable[[int, int], None] | None = None) -> Record:
    """The whole campaign: the document of :func:`summarise`."""
    work = blocks(plan, check_plan(plan), block)
    total = sum(len(b.seeds) for b in work)
    runs = _local(work, workers) if cluster is None else _cluster(work, cluster)
    records: list[Record] = []
    for part in runs:
        records.extend(part)
        if progress is not None:
            progress(len(records), total)
    return summarise(plan, records)


def _margin(row: Record) -> str:
    low = float(row["worst_margin"])  # type: ignore[arg-type]
    return "-" if math.isinf(low) else f"{low:.3g} ({row['worst_constraint']})"


def table(doc: Record) -> Table:
    t = Table(title=f"cpbc verify: {doc['plan']['scenario']}")  # type: ignore[index]
    for col in ("controller", "rate", "viable runs", "violations", "worst margin",
                *(f"{k} (violated)" for k in CLASSES[1:]), "filter acted", "torque on a limit",
                "failing seeds"):
        t.add_column(col)
    for r in doc["results"]:  # type: ignore[attr-defined]
        nv = r["non_viable"]
        seeds = [str(f["seed"]) for f in r["failures"]]
        t.add_row(r["controller"], f"{r['rate']:g} Hz", str(r["runs"]),
                  f"[red]{r['violations']}[/red]" if r["violations"] else "0", _margin(r),
                  *(f"{nv[k]['runs']} ({nv[k]['violations']})" for k in CLASSES[1:]),
                  f"{r['filter_share']:.1%}", f"{r['torque_limit_share']:.1%}",
                  ",".join(seeds[:8]) + ("…" if len(seeds) > 8 else ""))
    return t


def markdown(doc: Record) -> str:
    plan = doc["plan"]
    lines = [f"# cpbc verify: {plan['scenario']}", "",  # type: ignore[index]
             f"States: {len(plan['seeds'])} (seeds {plan['seed']}…), horizon {plan['horizon']} s, "  # type: ignore[index]
             f"mismatch {plan['mismatch']}, noise {plan['noise']}.", "",  # type: ignore[index]
             "| controller | rate | viable runs | violations | worst margin | "
             + " | ".join(CLASSES[1:]) + " | filter acted | torque on a limit | failing seeds |",
             "|---" * (8 + len(CLASSES) - 1) + "|"]
    for r in doc["results"]:  # type: ignore[attr-defined]
        nv = r["non_viable"]
        lines.append(
            f"| {r['controller']} | {r['rate']:g} Hz | {r['runs']} | {r['violations']} | "
            f"{_margin(r)} | " + " | ".join(f"{nv[k]['runs']} ({nv[k]['violations']})"
                                             for k in CLASSES[1:])
            + f" | {r['filter_share']:.1%} | {r['torque_limit_share']:.1%} | "
            + f"{', '.join(str(f['seed']) for f in r['failures'])} |")
    return "\n".join(lines) + "\n"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m cpbc.verify", description=__doc__.split("\n")[0])
    p.add_argument("scenario", help="a scenario file or the name of a shipped one")
    p.add_argument("--states", type=int, default=100, help="initial states (default 100)")
    p.add_argument("--rates", default="1000,500,100", help="control rates [Hz]")
    p.add_argument("--horizon", type=float, default=0.5, help="seconds per run (default 0.5)")
    p.add_argument("--seed", type=int, default=0, help="state i is drawn with seed + i")
    p.add_argument("--seeds", help="run only these state seeds (to reproduce failures)")
    p.add_argument("--mismatch", help="plant perturbation per run, e.g. mass=0.1,damping=0.05")
    p.add_argument("--noise", help="measurement noise SIGMA_POSITION,SIGMA_VELOCITY")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--block", type=int, default=8, help="states per unit of work")
    p.add_argument("--cluster", help="a Dask scheduler's address, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--json", action="store_true", help="print the JSON document")
    p.add_argument("--out", help="write the report here (.json: the document; else Markdown)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    a = _parser().parse_args(argv)
    err = Console(stderr=True)
    try:
        plan = plan_from(a)
        with Progress("verify", BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                      console=err, transient=True) as bar:
            task = bar.add_task("runs", total=None)
            doc = run_campaign(plan, a.workers, a.cluster, a.block,
                               lambda done, total: bar.update(task, completed=done, total=total))
    except CpbcError as exc:
        err.print(f"[red]error:[/red] {exc}", highlight=False)
        return 2
    if a.json:
        print(json.dumps(doc, indent=1))
    else:
        Console().print(table(doc))
    if a.out:
        out = Path(a.out)
        out.write_text(json.dumps(doc, indent=1) if out.suffix == ".json" else markdown(doc))
    return 1 if any(r["violations"] for r in doc["results"]) else 0  # type: ignore[attr-defined]


if __name__ == "__main__":
    sys.exit(main())
