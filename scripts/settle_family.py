"""Settle time of guarded CPBC beside the CBF-QP peer on a family of Panda reaches.

The shipped reach of ``panda_cbf_qp`` and its reversal, each with its start and target shifted
by a seeded offset (uniform in ±``--shift`` rad per joint): pair k is start_k → target_k and
target_k → start_k. Every controller of the scenario runs every reach (MuJoCo, the scenario's
physics, torque limits and safeguard); the script prints per controller the median, the
quartiles and the range of the settle time, its ratio to the CBF-QP's on the same reach, and
the reaches that did not converge.

    PYTHONPATH=. python scripts/settle_family.py [--pairs 20] [--shift 0.1] [--seed 0]
        [--out docs/tables/settle_family.md]

``--out`` writes the table as the Markdown fragment the reliability page includes, headed by
the command, date, commit and run time.

(``PYTHONPATH=.``: a script's own folder, not the checkout, heads Python's path, so without
it an installed copy of cpbc would be measured instead of this one.)
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from cpbc.provenance import commit
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import run_one
from cpbc.scenario.schema import Scenario


def reaches(spec: Scenario, pairs: int, shift: float, seed: int) -> list[tuple[list, list]]:
    """(start, target) of every reach: pairs shifted copies of the shipped one, both ways."""
    rng = np.random.default_rng(seed)
    start, target = np.array(spec.cases[0].position), np.array(spec.target)
    out = []
    for k in range(pairs):
        a = start + (rng.uniform(-shift, shift, start.size) if k else 0.0)
        b = target + (rng.uniform(-shift, shift, target.size) if k else 0.0)
        out += [(a.tolist(), b.tolist()), (b.tolist(), a.tolist())]
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=20)
    p.add_argument("--shift", type=float, default=0.1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", help="also write the table here as a Markdown fragment")
    args = p.parse_args()
    spec, file = load_scenario("panda_cbf_qp")
    settle: dict[str, list[float]] = {}
    failed: dict[str, list[int]] = {}
    began = time.time()
    for i, (a, b) in enumerate(reaches(spec, args.pairs, args.shift, args.seed)):
        case = spec.cases[0].model_copy(update={"position": a})
        setup = build(spec.model_copy(update={"target": b, "cases": [case]}), file)
        for entry in setup.controllers:
            s = run_one(setup, setup.cases[0], entry, "mujoco").summary
            if s.status == "converged" and s.settle_time is not None:
                settle.setdefault(entry.name, []).append(s.settle_time)
            else:
                settle.setdefault(entry.name, []).append(np.nan)
                failed.setdefault(entry.name, []).append(i)
        print(f"reach {i}: " + ", ".join(f"{n} {v[-1]:.3f} s" for n, v in settle.items()),
              flush=True)
    took = time.time() - began
    head = (f"{len(settle.get('CBF-QP', []))} reaches ({args.pairs} pairs, shift ±{args.shift} "
            f"rad, seed {args.seed}), {time.strftime('%Y-%m-%d')}, {took:.0f} s")
    print("\n" + head)
    lines = table(settle, failed)
    print("\n".join(lines))
    if args.out:
        command = "PYTHONPATH=. python " + shlex.join(["scripts/settle_family.py", *sys.argv[1:]])
        Path(args.out).write_text(
            f"Written by `{command}` at commit `{commit() or 'unknown'}`: {head}.\n\n"
            + "\n".join(lines) + "\n", encoding="utf-8")


def table(settle: dict[str, list[float]], failed: dict[str, list[int]]) -> list[str]:
    """Per controller: settle time median (quartiles; range), its ratio to the CBF-QP's on the
    same reach, and the reaches that did not converge, as Markdown rows."""
    peer = np.array(settle.get("CBF-QP", []))
    lines = ["| controller | settle [s] | ratio to CBF-QP | not converged |",
             "|---|---|---|---|"]
    for name, values in settle.items():
        v = np.array(values)
        ratio = v / peer if peer.size == v.size else np.full(v.size, np.nan)
        q = np.nanpercentile(v, [0, 25, 50, 75, 100])
        r = np.nanpercentile(ratio, [0, 25, 50, 75, 100])
        missed = failed.get(name, [])
        which = f" (reaches {missed})" if missed else ""
        lines.append(f"| {name} | {q[2]:.3f} ({q[1]:.3f}–{q[3]:.3f}; {q[0]:.3f}–{q[4]:.3f}) | "
                     f"{r[2]:.3f} ({r[1]:.3f}–{r[3]:.3f}; {r[0]:.3f}–{r[4]:.3f}) | "
                     f"{len(missed)} / {v.size}{which} |")
    return lines

if __name__ == "__main__":
    main()
