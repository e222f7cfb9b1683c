"""The verification campaign's documents as Markdown: the report ``python -m cpbc.verify --out
X.md`` writes (docs/RELIABILITY.md is one), and the fragments the documentation pages include
(``python -m tools.verify_table``), made from the documents or read back from a report.

Both go through :class:`CampaignTable`, one campaign's table as the report prints it (its
cells are text), so a fragment read back from a report says what the report says.
"""

from __future__ import annotations

import math
import os
import platform
import re
import shlex
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from cpbc import __version__

Record = dict[str, object]

RATE = "rate"
RUNS = "stoppable runs"
VIOLATIONS = "violations"
IN_V = "in V (violated)"  # stoppable starts in the uniform brake's braking set
VIOLATED_OF_RUNS = "violations / runs"  # a fragment's column: violations of stoppable runs
EXPLAINED = (
    "Each state is classed per rate before it runs: *stoppable* (some brake within "
    "the torque box — uniform, least-squares, or aimed at the nearest constraint — "
    "held at the control rate in the true plant brings it to rest with every margin "
    "positive: the *stoppable runs* column counts these, and a violation from here "
    "is a defect), *not_stoppable* (none of those brakes does; counted apart, as "
    "runs (violated)). One rule for every controller: *violations* are stoppable "
    "runs with a margin ≤ 0 at some physics step, *deeper than 1e-6* those whose "
    "smallest margin fell below −1e-6 in the constraint's own units (rad², m, "
    "rad/s: the rest are crossings of rounding size), *worst depth* the largest "
    "such depth (0 when none crossed). *Filter acted*: the share of control steps "
    "(all runs) at which the safeguard (or a peer's filter) changed the nominal "
    "torque; *rows acted*: the share at which its own conditions changed it, not "
    "the torque box alone (a peer clips its PD nominal to the box, which *filter "
    "acted* counts too; every step the guard acts is its own); *infeasible steps*: "
    "steps at which it could not meet every row within the box (the guard's "
    "fallback, the peer's slack); *rescues*: steps at which the guard held its "
    "rescue's brake (`cpbc.controllers.rescue`); *torque on a limit*: the share of "
    "steps with a joint torque on its actuator limit; *peak torque rate (clipped)*, under "
    "a torque-rate limit, the largest joint torque rate of any run as a share of its limit "
    "and the steps at which the plant had to clip a command the controller asked for. "
    "Under a torque-rate limit every brake of the classification ramps from the gravity "
    "torque at the start, at most the torque limit, at the rate limit "
    "(`cpbc.constraints.brakes.ramped`). "
    "A violation is judged on the true state at every physics step, for every constraint the "
    "controller keeps: "
    "the law's own and, with the safeguard, the scenario's monitored constraints it "
    "keeps besides (`simulation.safeguard_monitored`). Reproduce one failure with "
    "`--seeds K --rates R`.")


@dataclass(frozen=True)
class CampaignTable:
    """One campaign as the report prints it: its scenario, its conditions, its table."""

    scenario: str  # as the reader would name it (cpbc.verify's shown)
    conditions: str  # the report's "States: …" line
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]

    def cells(self) -> list[dict[str, str]]:
        return [dict(zip(self.columns, row, strict=True)) for row in self.rows]


def markdown_cell(text: str) -> str:
    """Text for a Markdown table cell: a clearance pair's name (``link|obstacle``) holds a
    bar, which would split the cell."""
    return text.replace("|", "\\|")


def margin_text(row: Record) -> str:
    low = float(row["worst_margin"])  # type: ignore[arg-type]
    return "-" if math.isinf(low) else f"{low:.3g} ({row['worst_constraint']})"


def row_share(row: Record) -> float:
    """The share of steps the filter's own rows or conditions changed the torque (the whole
    filter share in documents written before it was counted apart)."""
    return float(row.get("row_share", row["filter_share"]))  # type: ignore[arg-type]


def shown(scenario: str) -> str:
    """A scenario file as the reader would name it: relative to here when it is below."""
    path = Path(scenario)
    if not path.is_absolute():
        return scenario
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return scenario


def _also(where: Record) -> str:
    kept = cast(list, where.get("also_kept") or [])
    return (f" (it also keeps every monitored {' and '.join(kept)} constraint, judged too)"
            if kept else "")


def _budgets(where: Record) -> str:
    """The safeguard's bounds on its step, where a campaign had any."""
    budgets = cast(Record | None, where.get("budgets"))
    if not budgets or all(v is None for v in budgets.values()):
        return ""
    parts = [f"{budgets['tests']} tests" if budgets.get("tests") is not None else "",
             f"{budgets['rescue']} model periods of rescue"
             if budgets.get("rescue") is not None else "",
             f"{float(cast(float, budgets['time_us'])):g} µs"
             if budgets.get("time_us") is not None else ""]
    return ", its step bounded to " + ", ".join(p for p in parts if p)


def _limits(limit: object) -> str:
    if limit is None:
        return "none"
    values = sorted({float(v) for v in limit})  # type: ignore[attr-defined]
    return " / ".join(f"{v:g}" for v in values) + " N·m"


def _rate_limits(rate: object) -> str:
    if rate is None:
        return ""
    values = sorted({float(v) for v in rate})  # type: ignore[attr-defined]
    return ", torque-rate limits " + " / ".join(f"{v:g}" for v in values) + " N·m/s"


def _conditions(doc: Record) -> str:
    plan = cast(Record, doc["plan"])
    where = cast(Record, doc.get("conditions", {}))
    return (f"States: {len(cast(list, plan['seeds']))} (seeds {plan['seed']}…), horizon "
            f"{plan['horizon']} s; physics {where.get('integrator', '?')} at "
            f"{where.get('timestep', '?')} s; torque limits {_limits(where.get('torque_limit'))}"
            f"{_rate_limits(where.get('torque_rate_limit'))}"
            f"; safeguard {'on' if where.get('safeguard', True) else 'off'}{_also(where)}"
            f"{_budgets(where)}"
            f"{_model_error(where, plan)}; "
            f"mismatch {plan['mismatch'] or 'none'}, noise {plan['noise'] or 'none'}.")


def _model_error(where: Record, plan: Record) -> str:
    """The declared model error the safeguard holds, and whether the plant was disturbed
    inside it."""
    error = where.get("model_error")
    if not error:
        return ""
    values = sorted({float(v) for v in cast(list, error)})
    drawn = ", the plant disturbed at its corners" if plan.get("disturb") else ""
    return (", declared model error " + " / ".join(f"{v:g}" for v in values)
            + f" rad/s²{drawn}")


def _row(r: Mapping) -> dict[str, str]:
    cells = {"controller": str(r["controller"]), RATE: f"{r['rate']:g} Hz",
             RUNS: str(r["runs"]), VIOLATIONS: str(r["violations"]),
             "deeper than 1e-6": str(r["deep_violations"]),
             "worst depth": f"{r['worst_depth']:.2g}",
             "worst margin": markdown_cell(margin_text(cast(Record, r)))}
    in_v = r.get("in_v")  # documents written before it was counted have none
    cells[IN_V] = "-" if in_v is None else f"{in_v['runs']} ({in_v['violations']})"
    for kind, counts in r["non_viable"].items():
        cells[f"{kind} (violated)"] = f"{counts['runs']} ({counts['violations']})"
    cells.update({
        "filter acted": f"{r['filter_share']:.1%}", "rows acted": f"{row_share(dict(r)):.1%}",
        "infeasible steps": str(r["infeasible_steps"]), "rescues": str(r.get("rescues", 0)),
        "torque on a limit": f"{r['torque_limit_share']:.1%}"})
    if r.get("peak_rate_share") is not None:  # a campaign under a torque-rate limit
        cells["peak torque rate (clipped)"] = rate_cell(r)
    cells["failing seeds"] = ", ".join(str(f["seed"]) for f in r["failures"])
    return cells


def rate_cell(r: Mapping) -> str:
    """Under a torque-rate limit, the largest peak joint torque rate of any run as a share of
    its limit, and (in brackets) the steps at which the plant had to clip a command; "-"
    without a limit."""
    share = r.get("peak_rate_share")
    if share is None:
        return "-"
    return f"{float(share):.0%} ({int(r.get('rate_clipped_steps', 0))})"


def campaign_table(doc: Record) -> CampaignTable:
    """The table of one campaign's document (cpbc.reliability.verification.summarise)."""
    rows = [_row(r) for r in cast(list, doc["results"])]
    columns = tuple(rows[0]) if rows else ("controller", RATE, RUNS, VIOLATIONS)
    return CampaignTable(shown(str(cast(Record, doc["plan"])["scenario"])), _conditions(doc),
                         columns, tuple(tuple(r[c] for c in columns) for r in rows))


def _section(table: CampaignTable) -> list[str]:
    return [f"## {table.scenario}", "", table.conditions, "",
            "| " + " | ".join(table.columns) + " |", "|---" * len(table.columns) + "|",
            *("| " + " | ".join(row) + " |" for row in table.rows)]


def duration(seconds: float | None) -> str:
    """" in 1.5 min" or " in 42 s" for a run's length; "" when it is not known."""
    if seconds is None or seconds < 0:
        return ""
    return f" in {seconds / 60:.1f} min" if seconds >= 60 else f" in {seconds:.0f} s"


def made_line(command: str, seconds: float | None, commit: str | None = None) -> str:
    """The report's first paragraph: the command, the version, the machine and the date."""
    took = duration(seconds)
    at = f" (commit {commit})" if commit else ""
    return (f"Made by `{command or 'python -m cpbc.verify'}` with cpbc {__version__}{at}, "
            f"Python {platform.python_version()}, {os.cpu_count()} cores, on "
            f"{time.strftime('%Y-%m-%d', time.gmtime())}{took}.")


def markdown(docs: Sequence[Record], command: str = "", seconds: float | None = None,
             commit: str | None = None) -> str:
    """The report: how it was made (command, version, machine, date), what the columns mean,
    then one table per scenario."""
    lines = ["# cpbc verify", "", made_line(command, seconds, commit), "", EXPLAINED, ""]
    for doc in docs:
        lines += [*_section(campaign_table(doc)), ""]
    return "\n".join(lines)


def _cells(line: str) -> list[str]:
    """A Markdown table row's cells; an escaped bar stays inside its cell."""
    parts = re.split(r"(?<!\\)\|", line.strip())
    return [p.strip() for p in parts[1:-1]]


def read_report(text: str) -> tuple[str, list[CampaignTable]]:
    """A report that :func:`markdown` wrote, read back: its "Made by" line and its tables."""
    made = next((line for line in text.splitlines() if line.startswith("Made by ")), "")
    tables = []
    for block in re.split(r"^## ", text, flags=re.MULTILINE)[1:]:
        lines = block.splitlines()
        rows = [line for line in lines if line.startswith("|")]
        conditions = next((line for line in lines if line.startswith("States: ")), "")
        if len(rows) < 2:
            continue
        columns = tuple(_cells(rows[0]))
        tables.append(CampaignTable(lines[0].strip(), conditions, columns,
                                    tuple(tuple(_cells(r)) for r in rows[2:])))
    return made, tables


def plan_command(doc: Record) -> str:
    """The verify command a document's plan reads as (for documents that did not record
    theirs); ``--workers`` does not change the results and is left out."""
    plan = cast(Record, doc["plan"])
    seeds = [int(s) for s in cast(list, plan["seeds"])]
    start = int(cast(int, plan["seed"]))
    args = ["python", "-m", "cpbc.verify", shown(str(plan["scenario"]))]
    if seeds == list(range(start, start + len(seeds))):
        args += ["--states", str(len(seeds))] + (["--seed", str(start)] if start else [])
    else:
        args += ["--seeds", ",".join(map(str, seeds))]
    args += ["--rates", ",".join(f"{float(r):g}" for r in cast(list, plan["rates"])),
             "--horizon", f"{plan['horizon']:g}"]
    if plan.get("mismatch"):
        mismatch = cast(dict, plan["mismatch"])
        args += ["--mismatch", ",".join(f"{k}={v:g}" for k, v in mismatch.items())]
    if plan.get("noise"):
        args += ["--noise", ",".join(f"{v:g}" for v in cast(list, plan["noise"]))]
    if plan.get("disturb"):
        args.append("--disturb")
    return shlex.join(args)


SETUP = "set-up"
ROWS_COLUMNS = ("controller", RATE, VIOLATED_OF_RUNS, "deeper than 1e-6",
                "not_stoppable (violated)", "filter acted", "infeasible steps", "rescues",
                "torque on a limit")
BY_RATE_COLUMNS = ("controller", RUNS, VIOLATIONS, "deeper than 1e-6", "filter acted",
                   "rescues", "not_stoppable (violated)")
# a campaign under a torque-rate limit: the rows and the peak rate against its limit
RATE_COLUMNS = (*ROWS_COLUMNS, "peak torque rate (clipped)")
# a campaign of a step bounded as on a robot: the starts in V, which the bound keeps, apart
BOUNDED_COLUMNS = (*ROWS_COLUMNS[:3], IN_V, *ROWS_COLUMNS[3:], "peak torque rate (clipped)")
LAYOUTS = {"rows": ROWS_COLUMNS, "by-rate": BY_RATE_COLUMNS}


def _setup(scenario: str) -> str:
    return Path(scenario).stem if scenario.endswith((".yaml", ".yml")) else scenario


def _cell(row: Mapping[str, str], column: str) -> str:
    if column == VIOLATED_OF_RUNS:
        text = f"{row[VIOLATIONS]} / {row[RUNS]}"
        return f"**{text}**" if row[VIOLATIONS] == "0" else text
    return row.get(column, "–")


def _rows_layout(tables: Sequence[CampaignTable], columns: Sequence[str]) -> list[str]:
    lines = ["| " + " | ".join((SETUP, *columns)) + " |", "|---" * (len(columns) + 1) + "|"]
    for table in tables:
        for row in table.cells():
            lines.append("| " + " | ".join((_setup(table.scenario),
                                            *(_cell(row, c) for c in columns))) + " |")
    return lines


def _rates(table: CampaignTable) -> list[str]:
    return list(dict.fromkeys(row[RATE] for row in table.cells()))


def _by_rate_layout(tables: Sequence[CampaignTable], columns: Sequence[str]) -> list[str]:
    """One row per set-up and controller, each cell its values at each rate joined by '/'."""
    rate_sets = {tuple(_rates(t)) for t in tables}
    same = len(rate_sets) == 1
    lines = [("Each cell gives " + " / ".join(next(iter(rate_sets))) + ", in that order.")
             if same else "Each value is followed by its rate.", "",
             "| " + " | ".join((SETUP, *columns)) + " |", "|---" * (len(columns) + 1) + "|"]
    for table in tables:
        cells = table.cells()
        for name in dict.fromkeys(row["controller"] for row in cells):
            mine = [row for row in cells if row["controller"] == name]
            joined = []
            for c in columns:
                if c == "controller":
                    joined.append(name)
                    continue
                values = [_cell(row, c) if same else f"{_cell(row, c)} ({row[RATE]})"
                          for row in mine]
                text = " / ".join(values)
                bold = c == VIOLATIONS and all(row[VIOLATIONS] == "0" for row in mine)
                joined.append(f"**{text}**" if bold else text)
            lines.append("| " + " | ".join((_setup(table.scenario), *joined)) + " |")
    return lines


def fragment(tables: Sequence[CampaignTable], sources: Sequence[str], layout: str = "rows",
             columns: Sequence[str] | None = None) -> str:
    """A table for a documentation page: where it comes from (``sources``, one line each),
    the campaigns' rows in one table (``rows``: one per controller and rate; ``by-rate``: one
    per controller, rates joined), then each campaign's conditions."""
    chosen = tuple(columns) if columns else LAYOUTS[layout]
    body = (_rows_layout if layout == "rows" else _by_rate_layout)(tables, chosen)
    lines = [*sources, "", *body, "", "Conditions of each set-up:", ""]
    lines += [f"- `{_setup(t.scenario)}`: {t.conditions}" for t in tables]
    return "\n".join(lines) + "\n"
