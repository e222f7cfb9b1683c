"""Issue 12's campaign: every constrained law of a scenario, with the scenario's torque
limits in the plant and the safeguard, from seeded initial states, at several control rates.

Each state is classed before it runs:
  lost     fails the stopping test (cpbc.constraints.stopping.stopping_margins): no torque in
           the box can stop it before some configuration boundary, to first order;
  outside  passes it but lies outside the braking set V (Braking.margins ≤ 0): the brake the
           safeguard has cannot stop it in time (the builder refuses such initial states);
  viable   in V: the safeguard's promise applies, and a violation from here is a defect.
Violations are judged on the true state at every physics step (reliability.campaign).

    python -m tools.torque_limited_campaign SCENARIO [SCENARIO ...] [--states N]
        [--rates 1000,500,100] [--horizon S] [--seed K] [--json FILE]
    python -m tools.torque_limited_campaign --render FILE    # the Markdown table
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.stopping import Braking, stopping_margins
from cpbc.controllers.safeguard import SafeguardSettings
from cpbc.reliability.campaign import (
    RecordingPlant,
    campaign_setup,
    checked_run,
    constrained,
    sample_states,
)
from cpbc.scenario import ScenarioSetup

CLASSES = ("viable", "outside", "lost")


def classify(setup: ScenarioSetup, braking: Braking, limit: Array, x: Array, dx: Array) -> str:
    """The class of an initial state (the module docstring)."""
    lost, _, _ = stopping_margins(setup.monitor, setup.model, x, dx, limit)
    if lost.size and not np.all(lost > 0):
        return "lost"
    sigma, _ = braking.margins(setup.monitor, setup.model, x, dx)
    return "viable" if not sigma.size or np.all(sigma > 0) else "outside"


def campaign(scenario: str, count: int, rates: list[float], horizon: float, seed: int
             ) -> list[dict[str, object]]:
    setup = campaign_setup(scenario)
    limit = setup.loop_settings.torque_limit
    if limit is None:
        raise SystemExit(f"{scenario}: declares no torque limit (simulation.torque_limit)")
    braking = Braking.of(setup.model, limit)
    states = sample_states(setup, count, seed)
    kinds = [classify(setup, braking, limit, s.position, s.velocity) for s in states]
    joint_limit = np.broadcast_to(limit, (setup.model.n,))
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    rows = []
    for entry in constrained(setup):
        for rate in rates:
            settings = replace(setup.loop_settings, duration=horizon, control_period=1 / rate,
                               noise=None)
            start = time.perf_counter()
            bad = dict.fromkeys(CLASSES, 0)
            failures = []
            steps = acted = at_limit = 0
            for i, (s, kind) in enumerate(zip(states, kinds, strict=True)):
                check = checked_run(plant, setup, entry, s.position, s.velocity, settings,
                                    safeguard=SafeguardSettings())
                traj = check.trajectory
                bad[kind] += check.violated
                if check.violated and kind == "viable":
                    failures.append({"state": i, "constraint": check.constraint,
                                     "time": traj.end_time, "min_margin": check.min_margin})
                steps += traj.control_steps
                acted += traj.safeguard_steps
                applied = np.abs(traj.joint_torque[np.all(np.isfinite(traj.joint_torque), 1)])
                at_limit += int(np.sum(np.any(applied >= joint_limit * (1 - 1e-6), axis=1)))
            row = {
                "scenario": setup.scenario.name, "controller": entry.name, "rate": rate,
                "states": count, "seed": seed, "horizon": horizon,
                **{f"{k}_states": kinds.count(k) for k in CLASSES},
                **{f"{k}_violations": bad[k] for k in CLASSES},
                "safeguard_share": acted / max(steps, 1),
                "at_limit_share": at_limit / max(steps, 1),
                "viable_failures": failures, "seconds": time.perf_counter() - start,
            }
            rows.append(row)
            print(f"{row['scenario']} {entry.name} {rate:g} Hz: viable {bad['viable']}/"
                  f"{kinds.count('viable')}, outside V {bad['outside']}/"
                  f"{kinds.count('outside')}, lost {bad['lost']}/{kinds.count('lost')}; "
                  f"safeguard {row['safeguard_share']:.1%} of steps, torque on a limit "
                  f"{row['at_limit_share']:.1%} ({row['seconds']:.0f} s)", flush=True)
    return rows


def table(rows: list[dict[str, object]]) -> str:
    """The README's table: violations / states per class, the safeguard's and the torque
    limit's share of the steps."""
    out = ["| scenario | law | rate | viable | outside V | lost | safeguard acted | torque on a "
           "limit |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        cells = [f"{r[f'{k}_violations']} / {r[f'{k}_states']}" for k in CLASSES]
        cells[0] = f"**{cells[0]}**"
        out.append(f"| {r['scenario']} | {r['controller']} | {float(r['rate']):g} Hz | "
                   + " | ".join(cells)
                   + f" | {float(r['safeguard_share']):.1%} | {float(r['at_limit_share']):.1%} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenarios", nargs="*")
    p.add_argument("--render", help="print the Markdown table of a --json file and stop")
    p.add_argument("--states", type=int, default=1000)
    p.add_argument("--rates", default="1000,500,100")
    p.add_argument("--horizon", type=float, default=1.0)
    p.add_argument("--seed", type=int, default=11)
    p.add_argument("--json")
    a = p.parse_args(argv)
    if a.render:
        with open(a.render) as f:
            print(table(json.load(f)))
        return 0
    rates = [float(r) for r in a.rates.split(",")]
    rows = [r for s in a.scenarios for r in campaign(s, a.states, rates, a.horizon, a.seed)]
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
