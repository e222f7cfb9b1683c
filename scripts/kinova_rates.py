"""TS-CPBC on the Kinova Jaco2 to a goal behind its base (tests/test_goal_scenario.py), with
joint rate limits at 0.5x the model's (0.31-0.42 rad/s) and without, from the upright start
and a bent one, without shaping (Theorem 6.9 as stated) and with s = (PhiPsi)^alpha for
alpha = 0.2, 0.05, 0.01 (docs/task-space.md, "Tight rate limits").

Per run: the status, the final task error, the reach time (1 mm, 0.01 rad) and, at the start
(at rest), the largest ratio of the rate barriers' weight rho*Pi_jj (the law's D + rho*Pi,
rho = r*L) to the arm's D_jj.

    PYTHONPATH=. python scripts/kinova_rates.py [--duration 30]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cpbc.results.task_metrics import reach_time
from cpbc.scenario import build, load_scenario
from cpbc.scenario.runner import RunResult, run_one

STARTS = {"upright": [-0.1, 3.0416, 3.0416, -0.1, 3.0416, -0.1],
          "bent": [0.6, 2.6, 2.2, 0.4, 2.6, 0.3]}
RANGES = {"type": "joint_position_limit", "name": "ranges", "lower": "from_model",
          "upper": "from_model",
          "joints": ["j2s6s200_joint_2", "j2s6s200_joint_3", "j2s6s200_joint_5"]}
RATES = {"type": "joint_rate_limit", "name": "rates", "bounds": "from_model", "scale": 0.5}


def scenario(alpha: float | None, rates: bool, duration: float) -> dict[str, Any]:
    law: dict[str, Any] = {"type": "cpbc", "name": "TS-CPBC",
                           "task": {"omega_n": 12, "zeta": 1, "rotation_omega_n": 24},
                           "posture": {"omega_n": 2, "zeta": 1}}
    if alpha is not None:
        law["shaping"] = {"type": "power", "alpha": alpha}
    return {
        "name": "kinova_behind", "robot": {"model": "kinova"},
        "simulation": {"duration": duration, "timestep": 0.001},
        "goal": {"frame": "j2s6s200_end_effector", "position": [-0.30, 0.10, 0.45],
                 "tolerance": {"position": 0.001, "angle": 0.01},
                 "orientation": {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}}},
        "cases": [{"name": k, "position": v} for k, v in STARTS.items()],
        "constraints": [RANGES, RATES] if rates else [RANGES],
        "controllers": [law],
    }


def weight_ratio(setup: Any, run: RunResult, t: float) -> float:
    """max_j rho Pi_jj / D_jj at time t of the run (at rest: L = U)."""
    law = setup.controllers[0].controller
    k = int(np.argmin(np.abs(run.trajectory.time - t)))
    x, dx = run.trajectory.position[k], run.trajectory.velocity[k]
    state = law.state(x, dx)
    bar = law.constraints.barrier(state)
    if bar.weight is None:
        return 0.0
    lag = 0.5 * float(dx @ state.inertia @ dx) + law.potential.evaluate(state)[0]
    rho = law.shaping.ratio(bar.log_phi + bar.log_psi) * lag
    return float(np.max(rho * np.diag(bar.weight) / np.diag(state.inertia)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp())
    print("| rates | alpha | start | status | final error | reach [s] | max rho*Pi/D at start |")
    print("|---|---|---|---|---|---|---|")
    for rates in (True, False):
        for alpha in (None, 0.2, 0.05, 0.01):
            path = folder / f"kinova_{rates}_{alpha}.yaml"
            path.write_text(yaml.safe_dump(scenario(alpha, rates, args.duration)))
            setup = build(*load_scenario(path))
            for case in setup.cases:
                run = run_one(setup, case, setup.controllers[0], "mujoco")
                s = run.summary
                assert run.task_error is not None and s.task_error_final is not None
                inside = np.all(run.task_error <= [0.001, 0.01], axis=1)
                reach = reach_time(run.trajectory.time, inside)
                status = s.status + (f" ({s.stall_kind})" if s.stall_kind else "")
                err = s.task_error_final
                print(f"| {'0.5x' if rates else 'none'} | {alpha or 'none'} | {case.name} | "
                      f"{status} | "
                      f"{err['position'] * 1000:.3g} mm, {err['angle']:.3g} rad | "
                      f"{'-' if reach is None else f'{reach:.2f}'} | "
                      f"{weight_ratio(setup, run, 0.0):.3g} |")


if __name__ == "__main__":
    main()
