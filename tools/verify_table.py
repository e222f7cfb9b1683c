"""Write a documentation page's campaign table from what ``python -m cpbc.verify`` wrote.

    python -m tools.verify_table --docs            # every fragment the pages include
    python -m tools.verify_table --docs --check    # exit 1 when one is stale
    python -m tools.verify_table docs/RELIABILITY.md --out docs/tables/reliability.md
    python -m tools.verify_table A.json B.json --layout by-rate --out FRAGMENT.md

Each INPUT is a verify report (Markdown, ``--out X.md``; its tables are read back) or a verify
JSON document (``--out X.json`` or ``--json``, one campaign or ``{"campaigns": [...]}``). The
fragment says where each input came from (its command, date and commit where the input
recorded them; for a JSON document that did not, the command its plan reads as), then one
table of every campaign (``--layout rows``: a row per controller and rate; ``by-rate``: a row
per controller, the rates joined by '/'), then each campaign's conditions. The pages include
the fragments (pymdownx.snippets); nothing in them is copied by hand.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import cast

from cpbc.reliability.report import (
    BOUNDED_COLUMNS,
    LAYOUTS,
    RATE_COLUMNS,
    CampaignTable,
    Record,
    campaign_table,
    duration,
    fragment,
    plan_command,
    read_report,
)

ROOT = Path(__file__).resolve().parents[1]
TASK_SPACE = ("panda_goal_pose", "planar_ch6_taskspace", "ur5_circle", "ur5_circle_joint_limit",
              "panda_pick_place_window", "panda_pick_place_blocked", "panda_figure8_ke")
# the fragments the documentation pages include: fragment -> (inputs, layout)
FRAGMENTS: dict[str, tuple[tuple[str, ...], str]] = {
    "docs/tables/reliability.md": (("docs/RELIABILITY.md",), "rows"),
    "docs/tables/taskspace-campaign.md": (
        tuple(f"docs/tables/taskspace/{name}.json" for name in TASK_SPACE), "by-rate"),
    "docs/tables/peer-campaign.md": (
        tuple(f"docs/tables/peer/{name}.json"
              for name in ("panda_cbf_qp", "panda_cbf_qp_exponential", "ur5_cbf_qp")), "rows"),
    "docs/tables/peer-ke-campaign.md": (("docs/tables/peer/panda_ke_cbf_qp.json",), "rows"),
    "docs/tables/rate-campaign.md": (("docs/tables/rate/campaign.json",), "rows"),
    "docs/tables/rate-robot-campaign.md": (("docs/tables/rate/robot.json",), "rows"),
}
# fragments whose table has columns other than their layout's
COLUMNS: dict[str, tuple[str, ...]] = {"docs/tables/rate-campaign.md": RATE_COLUMNS,
                                       "docs/tables/rate-robot-campaign.md": BOUNDED_COLUMNS}
DOCS_COMMAND = "python -m tools.verify_table --docs"


def _name(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def _made(made: Record) -> str:
    took = duration(cast(float | None, made.get("seconds")))
    return (f"`{made.get('command')}` on {made.get('date')}{took}, commit "
            f"`{made.get('commit') or 'unknown'}` (cpbc {made.get('cpbc')})")


def from_json(path: Path) -> tuple[str, list[CampaignTable]]:
    """A verify JSON document's source line and tables."""
    document = json.loads(path.read_text(encoding="utf-8"))
    docs = document.get("campaigns", [document])
    made = document.get("made")
    if isinstance(made, dict):
        source = f"- `{_name(path)}`: made by {_made(made)}"
    else:
        commands = "; ".join(f"`{plan_command(d)}`" for d in docs)
        source = (f"- `{_name(path)}` (its command, date and commit were not recorded; its "
                  f"plan reads as {commands})")
    return source, [campaign_table(d) for d in docs]


def from_report(path: Path) -> tuple[str, list[CampaignTable]]:
    """A verify Markdown report's source line ("Made by …") and tables."""
    made, tables = read_report(path.read_text(encoding="utf-8"))
    if not tables:
        raise SystemExit(f"{path}: no campaign table found (is it a cpbc.verify report?)")
    said = made.removeprefix("Made by ") or "how it was made is not stated"
    return f"- `{_name(path)}`: made by {said}", tables


def render(inputs: Sequence[Path], layout: str = "rows", columns: Sequence[str] | None = None,
           command: str = "python -m tools.verify_table") -> str:
    """The fragment of these verify outputs, saying it was rendered by ``command``."""
    sources, tables = [], []
    for path in inputs:
        source, found = (from_json if path.suffix == ".json" else from_report)(path)
        sources.append(source)
        tables += found
    head = [f"Rendered by `{command}` from what `python -m cpbc.verify` wrote:", "",
            *sources]
    return fragment(tables, head, layout, columns)


def docs_fragments() -> dict[Path, str]:
    """Each documentation fragment of FRAGMENTS as its inputs render it now (inputs that do
    not exist yet are left out, and said to be missing)."""
    rendered = {}
    for out, (names, layout) in FRAGMENTS.items():
        inputs = [ROOT / n for n in names if (ROOT / n).is_file()]
        missing = [n for n in names if not (ROOT / n).is_file()]
        if not inputs:
            raise SystemExit(f"{out}: none of its inputs exists ({', '.join(names)})")
        text = render(inputs, layout, COLUMNS.get(out), command=DOCS_COMMAND)
        if missing:
            text += ("\nNot yet measured (no input file): "
                     + ", ".join(f"`{n}`" for n in missing) + ".\n")
        rendered[ROOT / out] = text
    return rendered


def _docs(check: bool) -> int:
    stale = []
    for path, text in docs_fragments().items():
        if check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(str(path.relative_to(ROOT)))
        else:
            path.write_text(text, encoding="utf-8")
            print(f"wrote {path.relative_to(ROOT)}")
    for name in stale:
        print(f"stale: {name} ({DOCS_COMMAND})", file=sys.stderr)
    return 1 if stale else 0


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.verify_table",
                                description=__doc__.split("\n")[0])
    p.add_argument("inputs", nargs="*", type=Path, help="verify reports (.md) or documents "
                   "(.json)")
    p.add_argument("--out", type=Path, help="the fragment to write")
    p.add_argument("--docs", action="store_true",
                   help="rewrite every fragment the documentation includes (FRAGMENTS)")
    p.add_argument("--check", action="store_true",
                   help="with --docs: write nothing, exit 1 when a fragment is stale")
    p.add_argument("--layout", choices=sorted(LAYOUTS), default="rows")
    p.add_argument("--columns", help="comma-separated report columns (default: the layout's)")
    a = p.parse_args(argv)
    if a.docs:
        return _docs(a.check)
    if not a.inputs or a.out is None:
        print("error: give INPUT ... --out FRAGMENT, or --docs", file=sys.stderr)
        return 2
    missing = [str(path) for path in a.inputs if not path.is_file()]
    if missing:
        print(f"error: inputs: no such file: {', '.join(missing)}", file=sys.stderr)
        return 2
    columns = [c.strip() for c in a.columns.split(",")] if a.columns else None
    args = sys.argv[1:] if argv is None else list(argv)
    command = shlex.join(["python", "-m", "tools.verify_table", *args])
    a.out.write_text(render(a.inputs, a.layout, columns, command), encoding="utf-8")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
