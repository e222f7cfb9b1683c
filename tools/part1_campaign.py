"""Sampled-data campaign for Chapter 3: seeded initial states across the barrier laws'
domains (and near their boundaries), at the thesis's control rate and coarser, violations
counted. Runs the shipped scenarios through the product's builder and loop.

    python tools/part1_campaign.py [--seeds N] [--seed S]

A state is drawn uniformly in a box and kept when the law is defined there and every
constrained state is inside its bounds (the builder's own check); a quarter of them are then
pushed along the ray from the origin to 90–99.9 % of the farthest admissible scaling
(found by bisection; the last admissible point when that one is not). Each state runs in
continuous time (the reference) and at every control period; the physics step stays the
scenario's. A violation is a run whose constrained quantity reached
its bound at a sample, or that left the law's domain, or diverged.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from cpbc.errors import ScenarioError  # noqa: E402
from cpbc.scenario.runner import run_systems  # noqa: E402
from cpbc.scenario.schema import SystemScenario  # noqa: E402
from cpbc.scenario.system_build import build_system  # noqa: E402

State = tuple[float, ...]


def scenario(name: str, **simulation: object) -> dict:
    data = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text())
    data["simulation"].update(simulation)
    return data


def admissible(data: dict, state: State, bump: float | None) -> bool:
    case = {"name": "probe", "state": list(state)}
    if bump is not None:
        case["bump_height"] = bump
    try:
        build_system(SystemScenario.model_validate({**data, "cases": [case]}), ROOT)
    except ScenarioError:
        return False
    return True


def near_boundary(data: dict, state: State, bump: float | None, rng: np.random.Generator) -> State:
    """Scale the state toward the domain's edge: the largest s in [1, 50] still admissible,
    found by bisection, times a factor in [0.9, 0.999]."""
    x = np.asarray(state)
    lo, hi = 1.0, 50.0
    if admissible(data, tuple(hi * x), bump):
        return tuple(hi * x)
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if admissible(data, tuple(mid * x), bump) else (lo, mid)
    near = tuple(float(v) for v in lo * rng.uniform(0.9, 0.999) * x)
    # the domain need not be star-shaped along the ray (an angle is scaled too)
    return near if admissible(data, near, bump) else tuple(float(v) for v in lo * x)


def draw(data: dict, box: np.ndarray, bump_max: float | None, n: int,
         rng: np.random.Generator) -> list[tuple[State, float | None, bool]]:
    out: list[tuple[State, float | None, bool]] = []
    while len(out) < n:
        x = tuple(float(v) for v in rng.uniform(-box, box))
        bump = None if bump_max is None else float(rng.uniform(0.0, bump_max))
        if not admissible(data, x, bump):
            continue
        edge = len(out) % 4 == 3
        out.append((near_boundary(data, x, bump, rng) if edge else x, bump, edge))
    return out


def campaign(name: str, box: list[float], bump_max: float | None, periods: list[float],
             duration: float, n: int, seed: int, law_filter: Callable[[str], bool]) -> None:
    rng = np.random.default_rng(seed)
    base = scenario(name, duration=duration)
    states = draw(base, np.asarray(box), bump_max, n, rng)
    print(f"\n## {name}: {n} seeded states (seed {seed}; every 4th near the domain's edge), "
          f"{duration} s each, physics step {base['simulation']['timestep']} s")
    print("| control period [s] | law | runs | violations | of them near the edge | "
          "worst peak / bound | how |")
    print("|---|---|---|---|---|---|---|")
    for period in [None, *periods]:  # None: the continuous-time reference
        data = scenario(name, duration=duration, control_period=period or periods[0])
        data["cases"] = [{"name": f"s{i}", "state": list(x),
                          **({} if b is None else {"bump_height": b})}
                         for i, (x, b, _) in enumerate(states)]
        setup = build_system(SystemScenario.model_validate(data), ROOT)
        start = time.perf_counter()
        results = run_systems(setup, "reference" if period is None else "mujoco")
        wall = time.perf_counter() - start
        for law in (la.name for la in setup.laws if law_filter(la.name)):
            mine = [(r, states[int(r.case[1:])][2]) for r in results if r.controller == law]
            bad = [(r, edge) for r, edge in mine if r.summary.status in
                   ("constraint_violated", "diverged")]
            outcomes = [r.summary.system for r, _ in mine if r.summary.system is not None]
            worst = max(max(p / o.bounds[k] for k, p in o.peaks.items()) for o in outcomes)
            kinds = sorted({f"{r.summary.status}: {r.summary.violated_constraint}" for r, _ in bad})
            rate = "continuous (reference)" if period is None else f"{period:g}"
            print(f"| {rate} | {law} | {len(mine)} | {len(bad)} | "
                  f"{sum(edge for _, edge in bad)} | {worst:.4f} | {'; '.join(kinds)} |")
        print(f"<!-- {period} s: {wall:.1f} s wall -->")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=40, help="initial states per system")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    campaign("ch3_suspension", [0.05, 5.0, 0.09, 2.0], 0.11, [1e-4, 5e-4, 1e-3, 2e-3], 0.5,
             args.seeds, args.seed, lambda law: law == "barrier")
    campaign("ch3_rwp", [np.pi, 0.9, 50.0], None, [1e-3, 5e-3, 1e-2, 2e-2], 20.0,
             args.seeds, args.seed, lambda law: True)


if __name__ == "__main__":
    main()
