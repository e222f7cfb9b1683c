"""Continuous joints (cpbc.taskspace.posture): a start wound by whole turns of the Kinova
Jaco2's continuous joints 1, 4 and 6 runs to the equivalent set point nearest it — the goal's
posture and a joint ``target:`` alike — instead of unwinding the turns; a position limit the
user puts on a continuous joint keeps the set point as given."""

from __future__ import annotations

import math

import numpy as np

from cpbc.constraints import ConstraintSet
from cpbc.constraints.linear_limit import joint_position_limit
from cpbc.scenario.runner import run_one
from cpbc.taskspace.posture import admissible_turns, nearest_turns

UPRIGHT = [-0.1, 3.0416, 3.0416, -0.1, 3.0416, -0.1]
CONTINUOUS = (0, 3, 5)  # j2s6s200_joint_1, _4, _6
# joint 1 a turn up, joint 4 two turns down, joint 6 a turn down
WOUND = [q + 2 * math.pi * k for q, k in zip(UPRIGHT, (1, 0, 0, -2, 0, -1), strict=True)]


def _kinova(**given: object) -> dict:
    scenario = {
        "name": "kinova_wound", "robot": {"model": "kinova"},
        "simulation": {"duration": 8.0, "timestep": 0.001},
        "cases": [{"name": "upright", "position": UPRIGHT}, {"name": "wound", "position": WOUND}],
        "constraints": [{"type": "joint_position_limit", "name": "ranges", "lower": "from_model",
                         "upper": "from_model",
                         "joints": ["j2s6s200_joint_2", "j2s6s200_joint_3", "j2s6s200_joint_5"]}],
    }
    scenario.update(given)
    return scenario


def test_a_wound_start_reaches_the_goal_without_unwinding(load_dict) -> None:
    # Before: the wound case's posture spring pulled joints 1, 4, 6 back through their turns
    # (joints 1 and 4 travelled −5.7 and +5.0 rad) and the hand was 107 mm off, not settled,
    # at 8 s.
    setup = load_dict(_kinova(
        goal={"frame": "j2s6s200_end_effector", "position": [-0.30, 0.10, 0.45],
              "orientation": {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}}},
        controllers=[{"type": "pd_gravity", "name": "TS-PD+g",
                      "task": {"omega_n": 12, "zeta": 1, "rotation_omega_n": 24},
                      "posture": {"omega_n": 2, "zeta": 1}}]))
    assert setup.goal is not None
    turns = setup.case_targets["wound"] - setup.goal.posture
    assert np.allclose(turns, np.array(WOUND) - UPRIGHT)
    runs = {c.name: run_one(setup, c, setup.controllers[0], "mujoco") for c in setup.cases}
    for name, run in runs.items():
        assert run.summary.status == "reached", (name, run.summary.status)
        travel = run.trajectory.position[-1] - run.trajectory.position[0]
        assert np.all(np.abs(travel[list(CONTINUOUS)]) < math.pi), (name, travel)
    # one configuration, one motion: the same hand path and reach time
    assert runs["wound"].summary.reach_time == runs["upright"].summary.reach_time
    assert np.allclose(runs["wound"].task_error, runs["upright"].task_error, atol=1e-9)


def test_a_joint_target_is_taken_a_turn_away_for_a_wound_start(load_dict) -> None:
    target = [0.3, 2.9, 2.9, 0.2, 2.9, 0.4]
    setup = load_dict(_kinova(target=target, controllers=[
        {"type": "pd_gravity", "name": "PD+g", "omega_n": 6, "zeta": 1}]))
    law = setup.for_case(setup.cases[1], setup.controllers[0]).controller
    assert np.allclose(law.target - target, np.array(WOUND) - UPRIGHT)
    assert setup.for_case(setup.cases[0], setup.controllers[0]) is setup.controllers[0]
    for case in setup.cases:
        run = run_one(setup, case, setup.controllers[0], "mujoco")
        assert run.summary.status == "converged", (case.name, run.summary.status)
        travel = run.trajectory.position[-1] - run.trajectory.position[0]
        assert np.all(np.abs(travel) < 0.6), (case.name, travel)


def test_a_limit_on_a_continuous_joint_keeps_the_set_point() -> None:
    periodic = np.array([True, False])
    x, start = np.array([0.2, 0.0]), np.array([2 * math.pi + 0.3, 0.0])
    assert np.allclose(nearest_turns(x, start, periodic), [0.2 + 2 * math.pi, 0.0])
    assert np.allclose(nearest_turns(x, -start, periodic), [0.2 - 2 * math.pi, 0.0])
    assert np.array_equal(nearest_turns(x, start, None), x)
    free = ConstraintSet(2, [])
    assert np.allclose(admissible_turns(x, start, periodic, free), [0.2 + 2 * math.pi, 0.0])
    limited = ConstraintSet(2, [joint_position_limit([-1.0, -1.0], [7.0, 1.0], ("a", "b"))])
    assert np.allclose(admissible_turns(x, start, periodic, limited), [0.2 + 2 * math.pi, 0])
    tight = ConstraintSet(2, [joint_position_limit([-1.0, -1.0], [1.0, 1.0], ("a", "b"))])
    assert np.allclose(admissible_turns(x, start, periodic, tight), x)


def test_a_reference_s_posture_path_is_turned_for_a_wound_start(load_dict) -> None:
    goal = {"frame": "j2s6s200_end_effector", "position": [-0.30, 0.10, 0.45],
            "orientation": {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}}}
    planned = load_dict(_kinova(goal=goal, controllers=[
        {"type": "pd_gravity", "name": "PD+g", "task": {"omega_n": 12, "zeta": 1},
         "posture": {"omega_n": 2, "zeta": 1}}]))
    assert planned.goal is not None
    x0 = planned.goal.posture
    p0 = planned.model.point_position(planned.goal.goal.frame, x0, None)
    turns = 2 * math.pi * np.array([1, 0, 0, -1, 0, 1])
    p1 = p0 + np.array([0.0, 0.05, 0.0])
    path = {"waypoints": {"points": [{"time": 0, "position": p0.tolist()},
                                     {"time": 2, "position": p1.tolist()}],
                          "interpolation": "min_jerk"}}
    setup = load_dict(_kinova(
        reference={"frame": goal["frame"], "orientation": goal["orientation"], "path": path},
        cases=[{"name": "ik", "position": x0.tolist()},
               {"name": "wound", "position": (x0 + turns).tolist()}],
        simulation={"duration": 3.0, "timestep": 0.001},
        controllers=[{"type": "cpbc", "name": "TS-CPBC",
                      "task": {"omega_n": 12, "zeta": 1, "rotation_omega_n": 24},
                      "posture": {"omega_n": 2, "zeta": 1},
                      "shaping": {"type": "power", "alpha": 0.05}}]))
    assert np.allclose(setup.case_targets["wound"] - setup.target, turns)
    runs = [run_one(setup, c, setup.controllers[0], "mujoco") for c in setup.cases]
    assert [r.summary.status for r in runs] == ["tracked", "tracked"]
    travel = [r.trajectory.position[-1] - r.trajectory.position[0] for r in runs]
    np.testing.assert_allclose(travel[1], travel[0], atol=1e-6)  # no turn unwound
    assert runs[0].task_error is not None and runs[1].task_error is not None
    np.testing.assert_allclose(runs[1].task_error, runs[0].task_error, atol=1e-6)
