"""Scenario ``goal:`` (cpbc.scenario.goal_build, cpbc.taskspace): refusals naming the field, the
task gains from the task-space inertia and their zero-order-hold check, and the IK
preflight's three verdicts on the thesis's arm."""

from __future__ import annotations

import copy
import math
from collections.abc import Callable

import numpy as np
import pytest
import yaml

from cpbc.constraints import ConstraintSet
from cpbc.errors import CpbcError
from cpbc.resources import scenarios_dir
from cpbc.scenario import ScenarioSetup
from cpbc.taskspace.goal import FrameGoal
from cpbc.taskspace.ik import preflight

SCENARIO = scenarios_dir() / "planar_ch6_taskspace.yaml"


@pytest.fixture
def data() -> dict:
    return yaml.safe_load(SCENARIO.read_text())


def _refused(load_dict: Callable[[dict], ScenarioSetup], d: dict, field: str, word: str) -> None:
    with pytest.raises(CpbcError) as err:  # a ScenarioError, or an inadmissible state's
        load_dict(d)
    assert getattr(err.value, "field", None) == field, str(err.value)
    assert word in str(err.value)


@pytest.mark.parametrize(("edit", "field", "word"), [
    (lambda d: d.update(target=[1.0, 2.0]), "goal", "not both"),
    (lambda d: d["goal"].update(frame="no_such_frame"), "goal.frame", "end_point"),
    (lambda d: d["goal"].update(position=[1.0, 2.0]), "goal.position", "3 numbers"),
    (lambda d: d["goal"].update(position=[0.1, 1.8, 0.0]), "goal.position", "obstacle"),
    (lambda d: d["goal"].update(orientation={"rpy": [0, 0, 1], "quat": [1, 0, 0, 0]}),
     "goal.orientation", "exactly one"),
    (lambda d: d["goal"].update(orientation={"quat": [1, 0, 0]}), "goal.orientation.quat",
     "needs 4 numbers [w, x, y, z], got 3"),
    (lambda d: d["goal"].update(orientation={"quat": [1, 0, 0, 1]}), "goal.orientation.quat",
     "norm 1.41421, not 1"),
    (lambda d: d["goal"].update(orientation={"quat": [0, 0, 0, 0]}), "goal.orientation.quat",
     "the identity is [1, 0, 0, 0]"),
    (lambda d: d["goal"].update(posture=[0.0, 3.1]), "goal.posture", ""),
    (lambda d: d["controllers"][0].update(type="pd", shaping=None) or d["controllers"][0].pop(
        "shaping"), "controllers[0].type", "pd_gravity"),
    (lambda d: d["controllers"][0].update(task={"omega_n": 5000.0}),
     "controllers[0]", "zero-order hold"),
])
def test_bad_goals_are_refused_naming_the_field(load_dict, data, edit, field, word) -> None:
    d = copy.deepcopy(data)
    edit(d)
    _refused(load_dict, d, field, word)


def test_a_quaternion_written_to_four_digits_is_taken(load_dict, data) -> None:
    d = copy.deepcopy(data)
    d["goal"]["orientation"] = {"quat": [0.7071, 0, 0, 0.7071]}  # norm 0.99999
    setup = load_dict(d)
    assert setup.goal is not None
    rotation = setup.goal.goal.rotation
    assert isinstance(rotation, np.ndarray)
    assert np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)


def test_task_gains_without_a_goal_are_refused(load_dict, data) -> None:
    d = copy.deepcopy(data)
    d.pop("goal")
    d["target"] = [math.pi, 2 * math.pi / 3]
    _refused(load_dict, d, "controllers[0].task", "need a goal")


def test_goal_scenario_builds_with_task_stiffness_from_the_task_inertia(load_dict, data) -> None:
    setup = load_dict(data)
    assert setup.goal is not None and setup.goal.preflight.verdict == "reachable"
    assert np.allclose(setup.target, [math.pi, 2 * math.pi / 3], atol=1e-4)
    law = setup.controllers[0].controller
    state = law.state(setup.target, np.zeros(2))
    jv = state.frames[setup.goal.goal.frame].linear[:2]
    lam = np.linalg.inv(jv @ np.linalg.solve(state.inertia, jv.T))
    spring = law.potential.parts[0]  # type: ignore[union-attr]
    # ω_t² − ω_n² (task 2, posture 0.5): the posture spring acts along the task too
    assert np.allclose(spring.stiffness[:2, :2], (4.0 - 0.25) * lam)
    assert np.allclose(law.kp, 0.25 * np.diag(state.inertia))  # posture ω_n = 0.5


def _planar(load_dict, data) -> tuple[ScenarioSetup, ConstraintSet]:
    setup = load_dict(data)
    return setup, ConstraintSet(2, setup.monitor.configuration)


@pytest.mark.parametrize(("position", "verdict", "named"), [
    ([-1.5, 0.8660254, 0.0], "reachable", None),
    ([3.0, 1.0, 0.0], "unreachable", None),
    ([0.08, 0.0, 0.0], "blocked", "relative_angle"),
])
def test_preflight_verdicts(load_dict, data, position, verdict, named) -> None:
    setup, config = _planar(load_dict, data)
    assert setup.goal is not None
    goal = FrameGoal(setup.goal.goal.frame, "end_point", np.array(position))
    start = np.array([0.5, 1.2])
    found = preflight(setup.model, config, goal, start)
    assert found.verdict == verdict, found.describe()
    assert found.blocked_by == named
    if verdict == "unreachable":  # the outstretched arm: |p| − 2 from the goal
        assert found.error.position == pytest.approx(math.hypot(3.0, 1.0) - 2.0, abs=1e-3)
    assert np.all(config.configuration_margins(found.posture) > 0)


def test_a_blocked_goal_keeps_the_posture_of_the_descent_from_the_start(
        load_dict, ur10_under_ball) -> None:
    # UR10 tool just under a ball: no seed reaches it. A seed on the far branch (pan −2.6 rad)
    # misses by less, but the law descends from the start: taking that branch's posture sent
    # the posture spring across the workspace and the arm wandered for 8 s.
    scenario = ur10_under_ball(1.0)
    start = scenario["cases"][0]["position"]
    plan = load_dict(scenario).goal
    assert plan is not None
    assert plan.preflight.verdict == "blocked", plan.preflight.describe()
    assert (plan.preflight.blocked_by or "").startswith("clearance[")
    assert np.max(np.abs(plan.posture - np.array(start))) < 0.5, plan.posture


def test_the_hold_check_pairs_each_state_s_jacobian_with_its_inertia(
        load_dict, kinova_behind_base) -> None:
    # Kinova Jaco2 from the upright start (its wrist all but singular: joint 4 alone weighs
    # 3e-4 kg·m²) to a goal behind the base. The check once put the task springs through the
    # posture's Jacobian against the start's inertia — a law that never exists — and refused
    # ω_n = 12 (spectral radius 4.2); through the start's own Jacobian the held loop is
    # stable, and the plant agrees: PD + g with those gains reaches the goal.
    from cpbc.scenario.runner import run_one

    scenario = kinova_behind_base(8.0, type="pd_gravity", name="TS-PD+g")
    setup = load_dict(scenario)
    summary = run_one(setup, setup.cases[0], setup.controllers[0], "mujoco").summary
    assert summary.status == "reached", (summary.status, summary.task_error_final)
