"""Reach time of task-space CPBC against joint CPBC on the goal's IK posture, by one rule.

For each goal (the shipped ``panda_goal_pose`` and goals on other arms), it runs the goal
scenario's TS-CPBC and a joint-space CPBC whose target is the preflight's IK posture x_n
(same constraints, shaping, torque box and safeguard; joint gains ω_n, ζ equal to the task
gains, K_P = ω_n² D_ii(x_n)). Both reach times are the same rule: the first time from which
the hand stays within the goal's tolerance (1 mm, 0.01 rad) to the end of the run
(cpbc.results.task_metrics.reach_time). Prints per goal both times and their ratio.

    PYTHONPATH=. python scripts/reach_ratio.py [--goals panda,panda_side,ur5,xarm7]
        [--task-omega W] [--posture-omega W] [--rotation-omega W]

(``--*-omega`` override the goal law's gains for every goal, to study their effect.)
"""

from __future__ import annotations

import argparse
import copy
from typing import Any

import numpy as np
import yaml

from cpbc.resources import scenarios_dir
from cpbc.results.task_metrics import reach_time, task_errors
from cpbc.scenario import build
from cpbc.scenario.runner import run_one
from cpbc.scenario.schema import Scenario

DOWN = {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}}


def _shipped() -> dict[str, Any]:
    spec = yaml.safe_load((scenarios_dir() / "panda_goal_pose.yaml").read_text())
    spec["controllers"] = [c for c in spec["controllers"] if c["type"] == "cpbc"]
    return spec


def _panda_side() -> dict[str, Any]:
    """The Panda from the same rest to a goal on the other side of the ball, lower."""
    spec = _shipped()
    spec["goal"]["position"] = [0.35, -0.30, 0.25]
    return spec


def _ur5() -> dict[str, Any]:
    """The UR5 of ur5_circle from its start to a pose 0.2 m out, 0.2 m across, down 0.15 m."""
    circle = yaml.safe_load((scenarios_dir() / "ur5_circle.yaml").read_text())
    spec = {k: circle[k] for k in ("robot", "simulation", "cases", "obstacles", "constraints")}
    spec.update(name="ur5_goal", goal={"frame": "tool0", "position": [0.45, 0.30, 0.28],
                                       "orientation": DOWN,
                                       "tolerance": {"position": 0.001, "angle": 0.01}},
                controllers=[{"type": "cpbc", "name": "TS-CPBC",
                              "task": {"omega_n": 12, "zeta": 1, "rotation_omega_n": 24},
                              "posture": {"omega_n": 2, "zeta": 1},
                              "shaping": {"type": "power", "alpha": 0.2},
                              "constraints": ["joint_limits", "joint_rates"]}])
    spec["simulation"]["duration"] = 8.0
    return spec


def _xarm7() -> dict[str, Any]:
    """The xArm7 (7 DOF) from `python -m cpbc.robot xarm7`'s start to a full pose, at
    ω_t = 8: the joint twin at 12 rad/s fails the zero-order-hold check on this arm (a
    coupled mode through joint 3)."""
    return {
        "name": "xarm7_goal", "robot": {"model": "xarm7"},
        "simulation": {"duration": 8.0, "timestep": 0.001, "control_period": 0.001,
                       "integrator": "implicitfast", "torque_limit": "from_model"},
        "goal": {"frame": "link_eef", "position": [0.35, 0.20, 0.25],
                 "orientation": {"rpy": [3.14159, 0.0, 0.3]},
                 "tolerance": {"position": 0.001, "angle": 0.01}},
        "cases": [{"name": "start",
                   "position": [-0.1, -0.0823, -0.1, 1.9675, -0.1, 0.8243, -0.1]}],
        "obstacles": [{"type": "plane", "name": "floor", "point": [0, 0, 0]}],
        "constraints": [
            {"type": "joint_position_limit", "name": "joint_ranges", "lower": "from_model",
             "upper": "from_model"},
            {"type": "joint_rate_limit", "name": "joint_rates", "bounds": "from_model",
             "scale": 0.5},
            {"type": "clearance", "name": "clearance", "margin": 0.01, "influence": 0.1,
             "links": ["link3", "link4", "link5", "link6", "link7"]}],
        "controllers": [{"type": "cpbc", "name": "TS-CPBC",
                         "task": {"omega_n": 8, "zeta": 1, "rotation_omega_n": 16},
                         "posture": {"omega_n": 2, "zeta": 1},
                         "shaping": {"type": "power", "alpha": 0.2}}],
    }


GOALS = {"panda": _shipped, "panda_side": _panda_side, "ur5": _ur5, "xarm7": _xarm7}


def _joint_twin(spec: dict[str, Any], posture: np.ndarray) -> dict[str, Any]:
    """The same scenario with target x_n and the joint CPBC at the task's ω_n, ζ."""
    law = spec["controllers"][0]
    twin = copy.deepcopy(spec)
    twin.pop("goal")
    twin["name"] += "_joint"
    twin["target"] = posture.tolist()
    joint = {k: v for k, v in law.items() if k not in ("task", "posture", "name")}
    joint.update(name="CPBC", omega_n=law["task"]["omega_n"], zeta=law["task"]["zeta"])
    twin["controllers"] = [joint]
    return twin


def measure(spec: dict[str, Any]) -> dict[str, float | str | None]:
    """Both reach times (hand within the goal's tolerance for good) and the TS status."""
    setup = build(Scenario.model_validate(spec), scenarios_dir() / "x.yaml")
    assert setup.goal is not None
    goal = setup.goal.goal
    ts = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco")
    twin = build(Scenario.model_validate(_joint_twin(spec, setup.goal.posture)),
                 scenarios_dir() / "x.yaml")
    joint = run_one(twin, twin.cases[0], twin.controllers[0], "mujoco")
    tol = np.array(goal.tolerance)
    out: dict[str, float | str | None] = {"status": ts.summary.status,
                                          "preflight": setup.goal.preflight.verdict}
    for name, run in (("task", ts), ("joint", joint)):
        errors = task_errors(setup.model, goal, run.trajectory.position)
        out[name] = reach_time(run.trajectory.time, np.all(errors <= tol, axis=1))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--goals", default=",".join(GOALS))
    p.add_argument("--task-omega", type=float)
    p.add_argument("--rotation-omega", type=float)
    p.add_argument("--posture-omega", type=float)
    args = p.parse_args()
    for name in args.goals.split(","):
        spec = GOALS[name]()
        law = spec["controllers"][0]
        if args.task_omega:
            law["task"]["omega_n"] = args.task_omega
        if args.rotation_omega:
            law["task"]["rotation_omega_n"] = args.rotation_omega
        if args.posture_omega:
            law["posture"]["omega_n"] = args.posture_omega
        r = measure(spec)
        task, joint = r["task"], r["joint"]
        ratio = (task / joint) if isinstance(task, float) and isinstance(joint, float) else None
        print(f"{name}: TS-CPBC {r['status']} reach {task} s, joint CPBC on x_n reach "
              f"{joint} s, ratio {ratio if ratio is None else round(ratio, 3)} "
              f"(preflight {r['preflight']})", flush=True)


if __name__ == "__main__":
    main()
