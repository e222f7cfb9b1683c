"""The benchmark's documents (``python -m cpbc.bench --json``) as Markdown: the speed page's
tables are rendered from them, never copied by hand.

Rendering is generic over what a document holds, so a figure added to the benchmark appears
without a change here: ``torque_us`` (µs per ``torque`` call, median over blocks) becomes the
main table, with its ``torque_us_range`` (min–max over the blocks), the ratio to PD + g of the
same run and the closed-loop rates of the controllers that have them; every other entry is
listed after it — a number as a line, a mapping of numbers as a small table (with its
``<name>_range`` beside it when there is one).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

Document = Mapping[str, object]

BASE = "pd_gravity"  # the ratios' denominator: PD + gravity of the same run
MAIN = "torque_us"
LOOP = "closed_loop_steps_per_second"
BARE = "closed_loop_bare_law_steps_per_second"
SHOWN = {"robot", MAIN, f"{MAIN}_range", LOOP, BARE, "notes", "made",
         "cpbc_over_pd_gravity"}  # the last is the table's CPBC ratio
LABELS = {
    "governor_us": "reference governor, one step (`cpbc.reference.governor`)",
}
UNITS = {"_us": "µs", "_steps_per_second": "steps/s", "_s": "s"}
README_START = "<!-- speed-table: written by python -m tools.speed_table; do not edit -->"
README_END = "<!-- /speed-table -->"


def _unit(key: str) -> str:
    return next((u for suffix, u in UNITS.items() if key.endswith(suffix)), "")


def _label(key: str) -> str:
    return LABELS.get(key, f"`{key}`")


def _number(value: float) -> str:
    """Three significant figures, no exponent for the sizes a benchmark meets."""
    if abs(value) >= 1000:
        return f"{value:,.0f}".replace(",", " ")
    return f"{value:.3g}" if abs(value) >= 1 else f"{value:.2g}"


def _numbers(value: object) -> dict[str, float] | None:
    """A mapping of names to numbers, or None."""
    if not isinstance(value, Mapping) or not value:
        return None
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value.values()):
        return None
    return {str(k): float(v) for k, v in value.items()}


def _span(ranges: object, key: str) -> str:
    if isinstance(ranges, Mapping) and key in ranges:
        low, high = ranges[key]
        return f"{_number(low)}–{_number(high)}"
    return "–"


def head(documents: Sequence[Document], command: str | None = None) -> list[str]:
    """Where the figures come from: the command, the date, the commit and the load."""
    lines = [f"Made by `{command}`, which runs:" if command else "How these figures were made:",
             ""]
    for doc in documents:
        made = doc.get("made")
        if not isinstance(made, Mapping):
            lines.append(f"- `{doc.get('robot', '?')}`: how it was made is not recorded")
            continue
        load = made.get("load_average")
        load_text = ", ".join(f"{v:.2f}" for v in load) if isinstance(load, list) else "unknown"
        notes = f" ({doc['notes']})" if doc.get("notes") else ""
        lines.append(
            f"- `{doc.get('robot', '?')}`{notes}: `{made.get('command')}` on "
            f"{made.get('date')}, commit "
            f"`{made.get('commit') or 'unknown'}` (cpbc {made.get('cpbc')}, Python "
            f"{made.get('python')}, {made.get('cores')} cores); load average {load_text} "
            f"(1, 5, 15 min) at its end; each figure the median of {made.get('blocks')} "
            f"blocks of {made.get('calls_per_block')} calls")
    return [*lines, ""]


def torque_table(documents: Sequence[Document]) -> list[str]:
    """µs per torque call, its range over the blocks, the ratio to PD + g of the same run and
    the closed-loop rates, for every controller each document timed."""
    lines = ["| arm | controller | µs per `torque` call (median) | range over blocks | "
             "× PD + g (same run) | closed loop [steps/s] | bare law loop [steps/s] |",
             "|---|---|---|---|---|---|---|"]
    for doc in documents:
        times = _numbers(doc.get(MAIN)) or {}
        loop, bare = _numbers(doc.get(LOOP)) or {}, _numbers(doc.get(BARE)) or {}
        base = times.get(BASE)
        for name, us in times.items():
            ratio = f"{us / base:.2f}×" if base else "–"
            lines.append(
                f"| {doc.get('robot', '?')} | {name} | {_number(us)} | "
                f"{_span(doc.get(f'{MAIN}_range'), name)} | {ratio} | "
                f"{_number(loop[name]) if name in loop else '–'} | "
                f"{_number(bare[name]) if name in bare else '–'} |")
    return [*lines, ""]


def _small_table(doc: Document, key: str, numbers: Mapping[str, float]) -> list[str]:
    unit = _unit(key)
    ranges = doc.get(f"{key}_range")
    return [f"{_label(key)} on `{doc.get('robot', '?')}`:", "",
            f"| | {unit or 'value'} (median) | range |", "|---|---|---|",
            *(f"| {k} | {_number(v)} | {_span(ranges, k)} |" for k, v in numbers.items()), ""]


def _others(doc: Document) -> list[tuple[str, object]]:
    return [(k, v) for k, v in doc.items() if k not in SHOWN and not k.endswith("_range")]


def other_tables(doc: Document) -> list[str]:
    """Every mapping of numbers the main table does not show, each as a small table."""
    lines: list[str] = []
    for key, value in _others(doc):
        numbers = _numbers(value)
        if numbers is not None:
            lines += _small_table(doc, key, numbers)
    return lines


def other_figures(doc: Document) -> list[str]:
    """Every entry the main table does not show: a number or text as a line, a mapping of
    numbers as a small table."""
    lines = []
    for key, value in _others(doc):
        if isinstance(value, int | float) and not isinstance(value, bool):
            lines.append(f"- {_label(key)}: {_number(float(value))} {_unit(key)}".rstrip())
        elif _numbers(value) is None:
            lines.append(f"- {_label(key)}: {value}")
    lines = [f"On `{doc.get('robot', '?')}`:", "", *lines, ""] if lines else []
    return lines + other_tables(doc)


def markdown(documents: Sequence[Document], command: str | None = None) -> str:
    """The fragment: how it was made, the torque table, then every other figure."""
    lines = [*head(documents, command), *torque_table(documents)]
    for doc in documents:
        lines += other_figures(doc)
    return "\n".join(lines).rstrip() + "\n"


def readme_table(documents: Sequence[Document]) -> str:
    """The README's short form: per arm PD + g, CPBC and every line the arm's own controller
    set does not have (the peers and any added figure), with the ratio to PD + g — the one
    table; the breakdowns and added figures (task space, streams, the guarded tail) are on
    the speed page (:func:`markdown`)."""
    lines = ["| arm | controller | µs per call (median) | × PD + g |", "|---|---|---|---|"]
    for doc in documents:
        times = _numbers(doc.get(MAIN)) or {}
        own = _numbers(doc.get(LOOP)) or {}
        base = times.get(BASE)
        for name, us in times.items():
            if name in own and name not in (BASE, "cpbc"):
                continue
            ratio = f"{us / base:.2f}×" if base else "–"
            lines.append(f"| {doc.get('robot', '?')} | {name} | {_number(us)} | {ratio} |")
    lines.append("")
    return "\n".join([README_START, "", *lines, README_END])
