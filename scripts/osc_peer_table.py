"""The side-by-side table of docs/task-space.md: TS-CPBC (guarded, as shipped) beside the
CBF-QP peer around an operational-space nominal (``cbf_qp``, ``nominal: osc``) on the
shipped task-space scenarios.

Each scenario is the shipped one with the peer appended as ``CBF-QP-OSC`` on the same task
and posture gains as its TS-CPBC law (``--write DIR`` writes these files, e.g. for
``python -m cpbc.verify``). Every constrained controller runs the scenario's case in MuJoCo
(the scenario's physics, torque box and safeguard); the script prints per run the status,
the task error (final and RMS), the reach time (a goal) or the largest path lag (a
reference), the smallest margin per constraint type, the crossed constraints, the share of
control steps with a joint torque on its limit, and the per-step cost: the median over
replayed states of the run of one call of the controller as the loop runs it [µs].

    PYTHONPATH=. python scripts/osc_peer_table.py [--scenarios a,b] [--write DIR]
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cpbc.resources import scenarios_dir
from cpbc.scenario import build
from cpbc.scenario.runner import RunResult, run_one
from cpbc.scenario.schema import Scenario

SCENARIOS = ("panda_goal_pose", "ur5_circle", "ur5_circle_joint_limit",
             "panda_pick_place_window", "panda_figure8_ke")
REPLAYED = 1500  # states of a run at which the per-step cost is timed


def with_peer(name: str) -> dict[str, Any]:
    """The shipped scenario with CBF-QP-OSC beside its first TS-CPBC law."""
    spec = yaml.safe_load((scenarios_dir() / f"{name}.yaml").read_text())
    law = next(c for c in spec["controllers"] if c["type"].startswith("cpbc"))
    spec["controllers"].append({"type": "cbf_qp", "name": "CBF-QP-OSC", "nominal": "osc",
                                "task": copy.deepcopy(law["task"]),
                                "posture": copy.deepcopy(law["posture"])})
    return spec


def step_cost(setup: Any, entry: Any, run: RunResult) -> float:
    """Median µs of one call of the controller as the loop runs it, on the run's states."""
    law = setup.controller(entry)
    traj = run.trajectory
    picks = np.linspace(0, len(traj.time) - 1, min(REPLAYED, len(traj.time))).astype(int)
    costs = []
    for k in picks:
        x, dx = traj.position[k], traj.velocity[k]
        start = time.perf_counter()
        law.evaluate(x, dx)
        costs.append((time.perf_counter() - start) * 1e6)
    return statistics.median(costs)


def at_limit_share(run: RunResult, limit: Any) -> float:
    """Share of control steps with some applied joint torque on its limit."""
    if limit is None:
        return 0.0
    tau = np.abs(run.trajectory.joint_torque)
    tau = tau[np.all(np.isfinite(tau), axis=1)]
    return float(np.mean(np.any(tau >= np.asarray(limit) * (1 - 1e-6), axis=1)))


def row(name: str, setup: Any, entry: Any) -> str:
    run = run_one(setup, setup.cases[0], entry, "mujoco")
    s = run.summary
    final, rms = s.task_error_final or {}, s.task_error_rms or {}
    when = f"reach {s.reach_time:.2f} s" if s.reach_time is not None else (
        f"lag ≤ {s.path_lag_max:.3f} s" if s.path_lag_max is not None else "-")
    margins = ", ".join(f"{w.type} {w.value:.3g} {w.unit}" for w in s.worst_margins())
    crossed = ", ".join(s.crossed_constraints) or "0"
    share = at_limit_share(run, setup.loop_settings.torque_limit)
    cost = step_cost(setup, entry, run)
    return (f"| `{name}` | {entry.name} | {s.status} | "
            f"{final.get('position', np.nan) * 1e3:.3g} mm, {final.get('angle', np.nan):.2g} rad | "
            f"{rms.get('position', np.nan) * 1e3:.3g} mm | {when} | {margins} | {crossed} | "
            f"{100 * share:.1f} % | {cost:.0f} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenarios", default=",".join(SCENARIOS))
    p.add_argument("--write", type=Path, help="write the scenarios with the peer here")
    args = p.parse_args()
    print("| scenario | controller | status | task error final | RMS | reach / lag | "
          "min margin per type | crossed | τ on its limit | step [µs] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.scenarios.split(","):
        spec = with_peer(name)
        if args.write is not None:
            args.write.mkdir(parents=True, exist_ok=True)
            (args.write / f"{name}.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
        setup = build(Scenario.model_validate(spec), scenarios_dir() / f"{name}.yaml")
        for entry in setup.controllers:
            if entry.controller.constraints.empty:
                continue  # the barrier-free twin (TS-PD+g)
            print(row(name, setup, entry), flush=True)


if __name__ == "__main__":
    main()
