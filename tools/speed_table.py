"""Write the speed page's table and the README's speed table from one benchmark session.

    python -m tools.speed_table                       # 2-4 min; rewrites the three files
    python -m tools.speed_table --repeats 5 --loop-seconds 1
    python -m tools.speed_table --render-only         # re-render from docs/tables/speed.json

Runs ``python -m cpbc.bench --json`` for the planar arm and for the Panda with ``--peers``, one
after the other in this process, and writes what they print — unchanged — to
docs/tables/speed.json, the Markdown fragment ``cpbc.bench_report.markdown`` makes of them to
docs/tables/speed.md (docs/speed.md includes it) and the short form to the block of README.md
between the speed-table markers. tests/test_docs.py checks that the fragment and the README's
block are what the JSON renders to.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from cpbc import bench
from cpbc.bench_report import README_END, README_START, markdown, readme_table

ROOT = Path(__file__).resolve().parents[1]
TABLES = ROOT / "docs" / "tables"
DATA, FRAGMENT, README = TABLES / "speed.json", TABLES / "speed.md", ROOT / "README.md"
RUNS = (("--robot", "planar_2link"), ("--robot", "panda", "--peers"))
TAIL_REPEATS = 3  # the Panda's tails made three times: each step's least time beside the first's
COMMAND = "python -m tools.speed_table"


def measure(repeats: int, loop_seconds: float, tail_repeats: int = TAIL_REPEATS) -> list[dict]:
    """The benchmark's JSON documents, one per configuration of RUNS."""
    documents = []
    for run in RUNS:
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            code = bench.main([*run, "--json", "--repeats", str(repeats), "--loop-seconds",
                               str(loop_seconds), "--tail-repeats", str(tail_repeats)])
        if code != 0:
            raise SystemExit(f"python -m cpbc.bench {' '.join(run)} exited with {code}")
        documents.append(json.loads(printed.getvalue()))
    return documents


def with_readme_block(readme: str, block: str) -> str:
    """README.md with its speed-table block replaced by ``block``."""
    start, end = readme.find(README_START), readme.find(README_END)
    if start < 0 or end < start:
        raise SystemExit(f"README.md: no block between {README_START!r} and {README_END!r}")
    return readme[:start] + block + readme[end + len(README_END):]


def render(documents: Sequence[dict], command: str) -> tuple[str, str]:
    """The fragment and the README's block of these documents."""
    return markdown(documents, command), readme_table(documents)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog=COMMAND, description=__doc__.split("\n")[0])
    p.add_argument("--repeats", type=int, default=15, help="timed blocks per figure")
    p.add_argument("--loop-seconds", type=float, default=2.0, help="simulated s per loop run")
    p.add_argument("--tail-repeats", type=int, default=TAIL_REPEATS,
                   help="passes of the Panda's closed-loop tails (cpbc.bench --tail-repeats)")
    p.add_argument("--render-only", action="store_true",
                   help="re-render the fragment and the README block from the stored JSON")
    args = p.parse_args(argv)
    if args.render_only:
        stored = json.loads(DATA.read_text(encoding="utf-8"))
        documents, command = stored["documents"], stored["command"]
    else:
        documents = measure(args.repeats, args.loop_seconds, args.tail_repeats)
        command = " ".join([COMMAND, *(argv if argv is not None else sys.argv[1:])])
        TABLES.mkdir(exist_ok=True)
        DATA.write_text(json.dumps({"command": command, "documents": documents}, indent=1)
                        + "\n", encoding="utf-8")
    fragment, block = render(documents, command)
    FRAGMENT.write_text(fragment, encoding="utf-8")
    README.write_text(with_readme_block(README.read_text(encoding="utf-8"), block),
                      encoding="utf-8")
    data = "" if args.render_only else f", {DATA.relative_to(ROOT)}"
    print(f"wrote {FRAGMENT.relative_to(ROOT)}{data} and README.md's speed table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
