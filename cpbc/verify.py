"""``python -m cpbc.verify SCENARIO [SCENARIO ...]``: does every constrained controller keep
every limit, from seeded states across the admissible set and near its boundaries, at each
control rate, with the scenario's torque limits (and optionally model mismatch and measurement
noise)?

    python -m cpbc.verify SCENARIO [SCENARIO ...] [--states N] [--rates 1000,500,100]
        [--horizon S] [--seed K] [--seeds K1,K2] [--mismatch mass=0.1,inertia=0.1,damping=0.05]
        [--noise SX,SV] [--workers N] [--cluster tcp://HOST:PORT] [--json] [--out FILE]

Runs on a local process pool (``--workers``, default: every core) or on a Dask distributed
scheduler (``--cluster``; ``pip install 'cpbc[cluster]'``). Prints a table per scenario
(``--json``: the document; with several scenarios ``{"campaigns": [...]}``) and writes the
report to ``--out`` (JSON for a ``.json`` name, else a Markdown report that states the command,
the version and the conditions of every campaign: the repository's docs/RELIABILITY.md is one;
``--out`` may be given twice, for both). ``python -m tools.verify_table`` renders either into
the tables the documentation pages include.
Exit code 0 when no viable run was violated, 1 when one was, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path
from typing import cast

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TimeRemainingColumn,
)
from rich.table import Table

from cpbc.errors import CpbcError
from cpbc.provenance import provenance
from cpbc.reliability.report import margin_text, markdown, rate_cell, row_share, shown
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
from cpbc.scenario import ScenarioSetup, build
from cpbc.scenario.load import load_any
from cpbc.scenario.schema import SystemScenario
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


def plans_from(a: argparse.Namespace) -> list[Plan]:
    """One plan per scenario named, with the same states, rates and disturbances."""
    rates = _numbers(a.rates, "--rates")
    if any(r <= 0 for r in rates):
        raise UsageError(f"--rates: every rate must be > 0 Hz, got {a.rates!r}")
    if a.states < 1 or a.horizon <= 0 or a.workers < 1 or a.block < 1:
        raise UsageError("--states, --workers and --block must be ≥ 1 and --horizon > 0")
    for out in a.out:
        if not Path(out).resolve().parent.is_dir():
            raise UsageError(f"--out {out}: its folder does not exist")
    seeds = None if a.seeds is None else tuple(int(v) for v in _numbers(a.seeds, "--seeds"))
    mismatch, noise = _mismatch(a.mismatch), _noise(a.noise)
    return [Plan(_scenario(name), a.seed, a.states, tuple(rates), a.horizon, mismatch, noise,
                 seeds, a.disturb) for name in a.scenario]


def conditions(setup: ScenarioSetup) -> Record:
    """What a campaign's guarantee is conditional on: the physics, the actuators' limits and
    whether the laws run with their safeguard, and its step's budgets."""
    limit = setup.loop_settings.bounds.torque
    rate = setup.loop_settings.bounds.rate
    error = setup.loop_settings.model_error
    return {
        "integrator": setup.plant_settings.integrator,
        "timestep": setup.plant_settings.timestep,
        "torque_limit": None if limit is None else [float(v) for v in limit],
        "torque_rate_limit": None if rate is None else [float(v) for v in rate],
        # the declared bound on the model's acceleration error the safeguard holds
        "model_error": None if error is None else [float(v) for v in error],
        "safeguard": setup.safeguard is not None,
        # the monitored constraints the safeguard keeps besides each law's own (judged too)
        "also_kept": sorted({n.split("[")[0] for c in setup.also_keep for n in c.names})
        if setup.safeguard is not None else [],
        # the bounds on the safeguard's step (step_budget.py, rescue.py), None: no bound
        "budgets": None if setup.safeguard is None else {
            "tests": setup.safeguard.test_budget, "rescue": setup.safeguard.rescue_budget,
            "time_us": None if setup.safeguard.time_budget is None
            else 1e6 * setup.safeguard.time_budget},
        "coordinates": list(setup.coordinate_names),
    }


def check_plan(plan: Plan) -> tuple[list[str], Record]:
    """Builds the scenario here once (bad input fails before any worker starts) and returns
    the names of the controllers to check and the campaign's conditions."""
    loaded, file = load_any(plan.scenario)
    if isinstance(loaded, SystemScenario):
        raise UsageError(f"{plan.scenario}: a Part I system scenario; verify checks arm "
                         "scenarios (the repository's tools/part1_campaign.py runs Part I "
                         "campaigns)")
    setup = build(loaded, file)
    if plan.disturb and setup.loop_settings.model_error is None:
        raise UsageError(f"--disturb: {plan.scenario} declares no model error; give "
                         "simulation.model_error: {acceleration: ā} [rad/s²]")
    if plan.disturb and not setup.model.coordinates.is_identity:
        raise UsageError(f"--disturb: {plan.scenario} runs in other than joint coordinates; "
                         "the disturbance is drawn per joint (use robot.coordinates: joint)")
    names = [e.name for e in checked_controllers(setup)]
    if not names:
        raise UsageError(f"{plan.scenario}: no controller enforces a constraint; nothing to "
                         "verify")
    for rate in plan.rates:
        try:
            substeps_per_control(1.0 / rate, setup.plant_settings.timestep)
        except CpbcError as exc:
            raise UsageError(f"--rates {rate:g} Hz: {exc}") from None
    return names, conditions(setup)


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
    """The whole campaign: the document of :func:`summarise`, with its ``conditions``."""
    names, where = check_plan(plan)
    work = blocks(plan, names, block)
    total = sum(len(b.seeds) for b in work)
    runs = _local(work, workers) if cluster is None else _cluster(work, cluster)
    records: list[Record] = []
    for part in runs:
        records.extend(part)
        if progress is not None:
            progress(len(records), total)
    doc = summarise(plan, records)
    doc["conditions"] = where
    return doc


def table(doc: Record) -> Table:
    t = Table(title=f"cpbc verify: {shown(doc['plan']['scenario'])}")  # type: ignore[index]
    for col in ("controller", "rate", "stoppable runs", "violations", "in V (violated)",
                "deeper than 1e-6", "worst depth", "worst margin",
                *(f"{k} (violated)" for k in CLASSES[1:]),
                "filter acted", "rows acted", "infeasible steps", "rescues",
                "torque on a limit", "peak torque rate (clipped)", "failing seeds"):
        t.add_column(col)
    for r in doc["results"]:  # type: ignore[attr-defined]
        nv = r["non_viable"]
        seeds = [str(f["seed"]) for f in r["failures"]]
        t.add_row(r["controller"], f"{r['rate']:g} Hz", str(r["runs"]),
                  f"[red]{r['violations']}[/red]" if r["violations"] else "0",
                  f"{r['in_v']['runs']} ({r['in_v']['violations']})",
                  str(r["deep_violations"]), f"{r['worst_depth']:.2g}", margin_text(r),
                  *(f"{nv[k]['runs']} ({nv[k]['violations']})" for k in CLASSES[1:]),
                  f"{r['filter_share']:.1%}", f"{row_share(r):.1%}", str(r["infeasible_steps"]),
                  str(r.get("rescues", 0)), f"{r['torque_limit_share']:.1%}", rate_cell(r),
                  ",".join(seeds[:8]) + ("…" if len(seeds) > 8 else ""))
    return t


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m cpbc.verify", description=__doc__.split("\n")[0])
    p.add_argument("scenario", nargs="+",
                   help="scenario files or names of shipped ones (each is its own campaign)")
    p.add_argument("--states", type=int, default=100, help="initial states (default 100)")
    p.add_argument("--rates", default="1000,500,100",
                   help="control rates [Hz], separated by commas (default 1000,500,100)")
    p.add_argument("--horizon", type=float, default=0.5, help="seconds per run (default 0.5)")
    p.add_argument("--seed", type=int, default=0, help="state i is drawn with seed + i")
    p.add_argument("--seeds", help="run only these state seeds (to reproduce failures)")
    p.add_argument("--disturb", action="store_true",
                   help="the plant adds an acceleration disturbance at the corners of the "
                        "scenario's declared simulation.model_error")
    p.add_argument("--mismatch", help="plant perturbation per run, e.g. mass=0.1,damping=0.05")
    p.add_argument("--noise", help="measurement noise SIGMA_POSITION,SIGMA_VELOCITY")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--block", type=int, default=8, help="states per unit of work")
    p.add_argument("--cluster", help="a Dask scheduler's address, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--json", action="store_true", help="print the JSON document")
    p.add_argument("--out", action="append", default=[],
                   help="write the report here (.json: the document; else Markdown); may be "
                   "given more than once, e.g. a report and its JSON document")
    return p


def _run_all(a: argparse.Namespace, plans: Sequence[Plan], err: Console) -> list[Record]:
    docs: list[Record] = []
    with Progress("verify", BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                  console=err, transient=True) as bar:
        for plan in plans:
            task = bar.add_task(Path(plan.scenario).stem, total=None)

            def show(done: int, total: int, task: TaskID = task) -> None:
                bar.update(task, completed=done, total=total)

            docs.append(run_campaign(plan, a.workers, a.cluster, a.block, show))
    return docs


def main(argv: Sequence[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)
    a = _parser().parse_args(args)
    err = Console(stderr=True, width=None if sys.stderr.isatty() else 200)
    start = time.perf_counter()
    try:
        docs = _run_all(a, plans_from(a), err)
    except CpbcError as exc:
        err.print(f"[red]error:[/red] {exc}", highlight=False)
        return 2
    document: Record = docs[0] if len(docs) == 1 else {"campaigns": docs}
    command = shlex.join(["python", "-m", "cpbc.verify", *args])
    seconds = time.perf_counter() - start
    document["made"] = {**provenance(command), "seconds": round(seconds, 1)}
    if a.json:
        print(json.dumps(document, indent=1))
    else:
        out = Console(width=None if sys.stdout.isatty() else 200)
        for doc in docs:
            out.print(table(doc))
    made = cast(Record, document["made"])
    for path in map(Path, a.out):
        path.write_text(json.dumps(document, indent=1) if path.suffix == ".json"
                        else markdown(docs, command, seconds, cast(str | None, made["commit"])))
    failed = any(r["violations"] for doc in docs for r in doc["results"])  # type: ignore[attr-defined]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
